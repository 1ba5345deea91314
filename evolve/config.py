"""Settings of an evolution run: the paper's table 1 as defaults, options beyond it off.

Every field of :class:`EvolutionConfig` is a plain value, so a config is saved in run
directories and checkpoints as it is and a resumed run checks it has the same one.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from skillcompose.checks import real_in, whole_in
from skillcompose.limits import MAX_TRIALS  # the command line's bound, for files too

from .errors import EvolutionConfigError

__all__ = ["DEFAULT_PRESET", "MOST", "PRESETS", "PRESET_ABOUT", "PRESET_NAMES", "TOPOLOGIES",
           "EvolutionConfig", "preset_help", "preset_settings"]

MOST = 10**9
"""The bound of the counts (generations and the other budgets, intervals, jobs): far beyond
any real run. The command line's options check the same bound."""

TOPOLOGIES = ("ring", "complete")


@dataclass(frozen=True)
class EvolutionConfig:
    """How to evolve FSAs (sections 3.2-3.7 of the paper; table 1 gives the defaults).

    The paper's algorithm:

    - ``population`` (N): individuals per generation.
    - ``p_mut``: per-node probability of a node mutation (reroute one outgoing edge and add
      Gaussian noise to each parameter with probability ``p_mut``); a node's skill changes
      with probability ``p_mut**2``; the start state changes with probability ``p_mut``.
    - ``p_cross``: probability that two selected parents are crossed (algorithm 2).
    - ``p_add`` / ``p_del``: probability of adding / deleting a node per mutated genome.
    - ``initial_nodes`` (S): nodes of each initial random genome, before pruning.
    - ``tournament``: tournament size of the selection (PyEvolve's default, 2).
    - ``param_sigma``: standard deviation of the parameter noise, in units of [0, 1]
      (PyEvolve's real Gaussian mutator used 0.05).
    - ``generations``: the budget; the run stops earlier when the task is solved.

    Budgets beyond the paper's (None: none; see docs/evolve.md, "Budgets"). Every budget
    holds at once: the run stops at whichever comes first, or when it solves the task.

    - ``max_evaluations``: genome evaluations, never more. An evaluation is a genome run on
      its trials to rank it in a generation; what costs no run is free (an elite kept, a
      cache hit, a genome's second copy in a generation), a cache refresh counts.
    - ``max_episodes``: episodes, never more: those of evaluations, confirmations and
      holds tests. Simplification and the final fresh check of the exported FSA, which
      come after the search, are outside it.

    A generation is evaluated whole or not at all: when the next one would overrun a budget
    the run stops before it, and a generation's confirmations and holds tests run only if
    the episodes they may take at most fit (else the run stops before them, unsolved, and an
    extended run runs them first). The first generation must fit.

    Options beyond the paper (all off by default):

    - ``elitism``: the best ``elitism`` individuals are copied unchanged into the next
      generation (and, with ``cache``, not evaluated again).
    - ``trials``: episodes per evaluation (default: the task's ``trials``); fitness is their mean.
    - ``common_random_numbers``: every individual of a generation meets the same worlds
      (the same trial seeds), so differences in fitness come from the FSAs, not the dice.
    - ``cache``: a genome identical to one already evaluated reuses its fitness.
      ``cache_refresh`` > 0 runs that many fresh trials each time it reappears and folds them
      into its running mean (for noisy tasks); 0 reuses the cached mean as it is.
    - ``parsimony``: at equal fitness the genome with fewer states wins (selection, elites
      and the reported best).
    - ``p_param``: probability that each node of a mutated child also gets parameter noise
      (the node mutation's Gaussian rule, without re-routing an edge). The paper's node
      mutation touches a node with probability ``p_mut``, so a network's weights change in
      about one child in ten; tasks whose work is in the parameters (MoveBase's network)
      need more. 0 (default) is the paper.
    - ``confirm_trials``: when the best genome reaches the task's target, it is run again on
      this many fresh worlds; the task counts as solved only if it reaches the target there
      too (otherwise its fitness becomes that mean and evolution goes on). Guards against a
      lucky solve on few trials. ``confirm_rate`` > 0 asks instead that at least this share
      of those episodes reach the target one by one (for tasks whose mean mixes rare large
      scores with small ones, such as stacking's 50 for a run that never grasped); its
      confirmations all use the same worlds, drawn once per run, so that an FSA confirmed
      again generation after generation cannot pass by a lucky draw at last.
      ``confirm_feedback``: a genome that fails its confirmation also takes, in the
      population (and in the cache), the mean fitness of its evaluation and its
      confirmation episodes, so that it loses its place among the best and the next
      candidate is confirmed instead of it (without it, only the run's record of the best
      changes, and the same genome, still scoring the target in the population, is confirmed
      again).
    - ``confirm_candidates``: confirm up to this many genomes at the target each generation,
      the most tested first (the most episodes in the cache), each on fresh worlds of its
      own (with ``confirm_rate``, too: never the run's fixed ones), until one passes; a
      genome that failed a confirmation is never confirmed again (it stays in the
      population unless ``confirm_feedback``). Several candidates a
      generation let a strict confirmation cost episodes rather than generations, and the
      memory keeps a genome from passing by luck on a later draw (or a later generation's
      candidates from being the same ones). 0 (default): the run's best alone, confirmed
      again each generation it stays the best.

    What "solved" means (see :mod:`skillcompose.evolve.holds`):

    - ``require_holds``: the task counts as solved only when the FSA the run would export
      (simplified, as written) reaches the task's target on fresh episodes, never used for
      selection, with a one-sided lower confidence bound of at least ``success_rate`` (the
      task's ``success_rate`` when None) at confidence ``holds_confidence``; a sequential
      test of at most ``holds_max_episodes`` episodes decides (one on a deterministic task).
      An FSA that fails is demoted to the mean fitness of those episodes and never tested
      again, and evolution goes on. Off (the paper): solved when the best evaluation
      reaches the target; the run still measures the exported FSA on fresh episodes and
      reports that rate with its bounds.

    Islands and diversity (all off by default; see docs/evolve.md, "Islands"):

    - ``islands``: the population is split into this many islands of equal size
      (``population`` is the total and must divide evenly), each bred on its own (its own
      tournaments, its own ``elitism`` best kept), as the paper's authors ran PyEvolve's
      islands over MPI.
    - ``migration_interval``: every this many generations each island receives copies of
      the ``migrants`` best individuals of its neighbours, which replace its worst;
      ``topology`` says who the neighbours are: ``ring`` (island k receives from island
      k - 1, as PyEvolve's MPI migrator) or ``complete`` (from every other island).
      Migration draws no random numbers.
    - ``restart_after``: an island whose best has not improved for this many generations is
      restarted: its elites (at least its best) stay, the rest become fresh random FSAs
      (0: never).
    - ``unique_children``: a child whose genome equals one already met (in this generation,
      or evaluated before when ``cache`` is on) is mutated again (up to 8 times) until it
      is new, so a generation spends its evaluations on new genomes.
    - ``neutral``: at equal fitness (and size, with ``parsimony``) the newer genome ranks
      first in its island's elites and tournaments, so a child as good as an elite takes
      its place: the search drifts across genomes of equal fitness instead of keeping the
      first one found (neutral drift, as in the (1 + lambda) evolution strategy of Cartesian
      genetic programming).

    Faults and limits (see docs/evolve.md, "Faults and limits"):

    - ``eval_time_limit``: wall-clock seconds one evaluation (all its trials) may take; past
      it the evaluation scores the task's worst fitness and counts as a time-out. ``None``:
      no limit. Set it well above a normal evaluation's time, so that only a hanging skill
      reaches it and the run stays the same on every machine.
    - ``worker_max_jobs``: a pool worker (or Ray actor) is replaced by a fresh one after this
      many evaluations (0: never); ``worker_max_growth_mb``: ... or once its resident memory
      has grown by more than this many MB since it started (0: never). Replacing a worker
      never changes results.

    Run bookkeeping: ``checkpoint_every`` generations between checkpoints of a run directory,
    ``terminal_weight`` the weight of each terminal outcome against one state when an edge
    target is drawn at random (see docs/evolve.md), ``chunks_per_worker`` the sizes of
    the chunks sent to Ray actors (each takes ``1 / (chunks_per_worker * actors)`` of what is
    left; a process pool's workers claim guided chunks from a shared counter instead).
    """

    population: int = 300
    p_mut: float = 0.1
    p_cross: float = 0.1
    p_add: float = 0.2
    p_del: float = 0.01
    initial_nodes: int = 50
    tournament: int = 2
    param_sigma: float = 0.05
    generations: int = 1000
    max_evaluations: int | None = None
    max_episodes: int | None = None
    elitism: int = 0
    trials: int | None = None
    common_random_numbers: bool = False
    cache: bool = False
    cache_refresh: int = 0
    parsimony: bool = False
    confirm_trials: int = 0
    confirm_rate: float = 0.0
    confirm_feedback: bool = False
    confirm_candidates: int = 0
    p_param: float = 0.0
    islands: int = 1
    migration_interval: int = 10
    migrants: int = 2
    topology: str = "ring"
    restart_after: int = 0
    unique_children: bool = False
    neutral: bool = False
    terminal_weight: float = 1.0
    checkpoint_every: int = 10
    chunks_per_worker: int = 2
    eval_time_limit: float | None = 60.0
    worker_max_jobs: int = 0
    worker_max_growth_mb: float = 1024.0
    require_holds: bool = False
    success_rate: float | None = None
    holds_confidence: float = 0.95
    holds_max_episodes: int = 100_000

    # long: one check per setting, every problem reported in the one error
    def __post_init__(self) -> None:
        problems: list[str] = []

        def whole(name: str, low: int, high: int = MOST) -> None:
            v = getattr(self, name)
            if not whole_in(v, low, high):
                problems.append(f"{name} = {v!r}: expected a whole number from {low} to "
                                f"{high:,}")

        def prob(name: str) -> None:
            v = getattr(self, name)
            if not real_in(v, 0.0, 1.0):
                problems.append(f"{name} = {v!r}: expected a probability in [0, 1]")

        whole("population", 2, 10**6)
        whole("initial_nodes", 1, 10_000)
        whole("tournament", 1, 10**6)
        whole("generations", 0)
        for name in ("max_evaluations", "max_episodes"):
            v = getattr(self, name)
            if v is not None and not whole_in(v, 1, MOST):
                problems.append(f"{name} = {v!r}: expected a whole number from 1 to "
                                f"{MOST:,}, or None for no budget")
        whole("elitism", 0, 10**6)
        whole("cache_refresh", 0, MAX_TRIALS)
        whole("confirm_trials", 0, MAX_TRIALS)
        whole("confirm_candidates", 0, 10_000)
        whole("checkpoint_every", 1)
        whole("chunks_per_worker", 1)
        whole("islands", 1, 10_000)
        whole("migration_interval", 1)
        whole("migrants", 0, 10**6)
        whole("restart_after", 0)
        if self.topology not in TOPOLOGIES:
            problems.append(f"topology = {self.topology!r}: choose one of "
                            f"{', '.join(TOPOLOGIES)}")
        whole("holds_max_episodes", 1, 10**7)
        rate = self.success_rate
        if rate is not None and not real_in(rate, 0.0, 1.0, low_open=True, high_open=True):
            problems.append(f"success_rate = {rate!r}: expected a rate between 0 and 1 "
                            "(exclusive), or None for the task's")
        conf = self.holds_confidence
        if not real_in(conf, 0.5, 1.0, high_open=True):
            problems.append(f"holds_confidence = {conf!r}: expected a number from 0.5 to "
                            "below 1, e.g. 0.95")
        for name in ("unique_children", "confirm_feedback", "neutral", "cache", "parsimony",
                     "common_random_numbers", "require_holds"):
            if not isinstance(getattr(self, name), bool):
                problems.append(f"{name} = {getattr(self, name)!r}: expected true or false")
        for name in ("p_mut", "p_cross", "p_add", "p_del", "p_param", "confirm_rate"):
            prob(name)
        if self.trials is not None:
            whole("trials", 1, MAX_TRIALS)
        for name in ("param_sigma", "terminal_weight"):
            v = getattr(self, name)
            if not real_in(v, 0.0, math.inf, high_open=True):
                problems.append(f"{name} = {v!r}: expected a finite number >= 0")
        limit = self.eval_time_limit
        if limit is not None and not real_in(limit, 0.0, math.inf, low_open=True,
                                             high_open=True):
            problems.append(
                f"eval_time_limit = {limit!r}: expected seconds > 0, or None for no limit"
            )
        whole("worker_max_jobs", 0)
        growth = self.worker_max_growth_mb
        if not real_in(growth, 0.0, math.inf, high_open=True):
            problems.append(
                f"worker_max_growth_mb = {growth!r}: expected MB >= 0 (0: no limit)"
            )
        if isinstance(self.elitism, int) and isinstance(self.population, int) and \
                self.elitism >= self.population:
            problems.append(
                f"elitism = {self.elitism} must be smaller than population = {self.population}"
            )
        if not problems and self.islands > 1:
            size, rest = divmod(self.population, self.islands)
            if rest or size < 2:
                problems.append(
                    f"population = {self.population} cannot be split into {self.islands} "
                    "equal islands of 2 or more; give a multiple of islands"
                )
            elif self.elitism >= size:
                problems.append(f"elitism = {self.elitism} must be smaller than an island "
                                f"({size} individuals)")
            elif self.migrants >= size:
                problems.append(f"migrants = {self.migrants} must be smaller than an island "
                                f"({size} individuals)")
        if problems:
            raise EvolutionConfigError(
                "invalid evolution settings: " + "; ".join(problems)
            )

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EvolutionConfig:
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise EvolutionConfigError(
                f"unknown evolution settings {unknown}; valid ones are {sorted(names)}"
            )
        return cls(**data)

    def replace(self, **changes: Any) -> EvolutionConfig:
        return dataclasses.replace(self, **changes)


EVALUATION_BACKENDS = ("serial", "process", "ray")
"""Where evaluations run: in the calling process, a local process pool, or Ray."""

_ROBUST: dict[str, Any] = {
    "population": 600,
    "trials": 3,
    "common_random_numbers": True,
    "elitism": 2,
    "tournament": 3,
    "initial_nodes": 12,
    "param_sigma": 0.1,
    "confirm_trials": 20,
}

_ISLANDS: dict[str, Any] = {  # the robust preset, its population on islands
    **_ROBUST,
    "islands": 4,
    "migration_interval": 10,
    "migrants": 2,
    "unique_children": True,
}

_HOLDS: dict[str, Any] = {"require_holds": True}  # "solved" is the statement of holds.py

PRESETS: dict[str, dict[str, Any]] = {
    "paper": {},
    "robust": {**_ROBUST, **_HOLDS},
    "islands": {**_ISLANDS, **_HOLDS},
    "noisy": {  # the island preset, each genome's trials kept, a strict confirmation
        **_ISLANDS,
        "cache": True,
        "cache_refresh": 3,
        "p_param": 0.3,
        "confirm_trials": 100,
        "confirm_rate": 1.0,
        "confirm_candidates": 5,
        **_HOLDS,
    },
    "deterministic": {
        "population": 30,
        "elitism": 2,
        "tournament": 5,
        "initial_nodes": 12,
        "param_sigma": 0.1,
        "cache": True,
        "unique_children": True,
        **_HOLDS,
    },
    "push": {
        "population": 150,
        "trials": 20,
        "common_random_numbers": True,
        "elitism": 2,
        "tournament": 3,
        "initial_nodes": 12,
        "param_sigma": 0.05,
        "p_param": 1.0,
        "confirm_trials": 200,
        **_HOLDS,
    },
}
"""Named settings: ``paper`` is table 1 as it is; ``robust`` is our best options, chosen on
the pour-water task (see docs/results/pour_water.md): 600 individuals, each evaluation
averaging 3 episodes that a whole generation shares, the two best surviving, tournaments of
3, initial FSAs of 12 nodes, parameter noise 0.1, and a solution confirmed on 20 fresh
episodes before the run stops. It selects FSAs that retry their failing skills rather than
ones that won a lucky episode.

``push`` is for tasks whose work is in a skill's many parameters, such as the network of
moving to push (see docs/results/move_to_push.md): 150 individuals, 20 episodes per
evaluation shared by the generation (a success rate near 0.95 must be told from one near
0.85), the two best surviving, tournaments of 3, initial FSAs of 12 nodes, every mutated
node's parameters perturbed (``p_param`` 1, noise 0.05), and a solution confirmed on 200
fresh episodes.

``noisy`` is for noisy tasks where a solution must hold on nearly every episode, chosen on
the pour-water task (see docs/results/search.md): the island preset, with the cache keeping
every trial a genome has had (3 more each time it reappears, folded into its mean), each
node of a mutated child given parameter noise with probability 0.3, and a strict
confirmation: up to 5 genomes at the target a generation, the most tested first, each on
100 fresh worlds of its own, every one of which it must solve; a genome that failed is
never confirmed again.

``deterministic`` is for tasks whose fitness never changes from one episode to the next
(``Task.deterministic``: the classic FSA benchmarks in ``benchmarks/``, chosen there with
``benchmarks/bench_search.py``, see docs/results/search.md): a small population of 30 that
evolves for many generations, the cache on (a genome met again costs nothing) and unique
children (each generation spends its evaluations on genomes not met before), the two best
surviving, tournaments of 5, initial FSAs of 12 nodes, parameter noise 0.1. One trial per
evaluation: a deterministic task runs one whatever ``trials`` says.

Every preset but ``paper`` has ``require_holds``: a run is solved when its exported FSA holds
on fresh episodes at the required success rate (see :mod:`skillcompose.evolve.holds`).
``default`` (the command line's when no preset is given, and :func:`evolve`'s when given no
config) is not a fixed table: it is ``deterministic`` for a task whose episodes are all the
same (``Task.deterministic``), else ``robust`` (:func:`preset_settings`)."""

DEFAULT_PRESET = "default"


def preset_settings(name: str, deterministic: bool) -> dict[str, Any]:
    """The settings of preset ``name`` for a task that is ``deterministic`` or not:
    ``default`` resolves to ``deterministic`` or ``robust``, the others are as listed."""
    if name == DEFAULT_PRESET:
        return dict(PRESETS["deterministic" if deterministic else "robust"])
    return dict(PRESETS[name])


PRESET_NAMES = (DEFAULT_PRESET, *PRESETS)
"""Every name ``--preset`` takes."""

PRESET_ABOUT = {
    DEFAULT_PRESET: "robust, or deterministic for a task whose episodes are all the same",
    "paper": "table 1 exactly, solved on one evaluation",
    "robust": "our best options for noisy tasks, chosen on pouring water",
    "islands": "robust on 4 islands with ring migration and unique children",
    "noisy": "islands, each genome's trials kept, a strict confirmation",
    "deterministic": "a small population that evolves long, for tasks whose fitness never "
                     "changes",
    "push": "for many parameters, such as a network's weights",
}
"""What each preset is for, in one line; its settings are :data:`PRESETS`'."""


def preset_help() -> str:
    """The command line's description of the presets, written from :data:`PRESETS` and
    :data:`PRESET_ABOUT`: what each is for and what it sets."""
    parts = []
    for name in PRESET_NAMES:
        sets = ", ".join(f"{k}={v}" for k, v in PRESETS.get(name, {}).items())
        parts.append(f"{name}: {PRESET_ABOUT[name]}" + (f" ({sets})" if sets else ""))
    return ("starting settings, which the flags below override; every preset but paper "
            "calls a run solved when its exported FSA holds on fresh episodes. "
            + "; ".join(parts))
