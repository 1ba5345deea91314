"""Settings of an evolution run: the paper's table 1 as defaults, options beyond it off.

Every field of :class:`EvolutionConfig` is a plain value, so a config is saved in run
directories and checkpoints as it is and a resumed run checks it has the same one.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from .errors import EvolutionConfigError
from .settings import MOST, SETTINGS, TOPOLOGIES

__all__ = ["DEFAULT_PRESET", "ISLAND_LEAST", "MOST", "NOISY_DEFAULT", "PRESETS", "PRESET_ABOUT",
           "PRESET_NAMES", "TOPOLOGIES", "EvolutionConfig", "default_islands", "preset_help",
           "preset_settings"]


@dataclass(frozen=True)
class EvolutionConfig:
    """How to evolve FSAs (sections 3.2-3.7 of the paper; table 1 gives the defaults).

    What each field means, what it takes and its command-line option are in one table,
    :data:`skillcompose.evolve.settings.SETTINGS` (listed in the reference's presets page),
    from which the config checks every field: a wrong one raises
    :class:`~skillcompose.evolve.EvolutionConfigError` naming it, the value and what it takes,
    every problem in the one error. The fields are the paper's algorithm (``population``,
    ``initial_nodes``, ``p_mut``, ``p_cross``, ``p_add``, ``p_del``; ``tournament`` and
    ``param_sigma`` are PyEvolve's), its budgets, and options beyond it, all off by default.

    Budgets (``generations``, ``max_evaluations``, ``max_episodes``; None: none; see
    docs/evolve.md, "Budgets") hold at once: the run stops at whichever comes first, or when
    it solves the task. A generation is evaluated whole or not at all: when the next one
    would overrun a budget the run stops before it, and a generation's confirmations and
    holds tests run only if the episodes they may take at most fit (else the run stops
    before them, unsolved, and an extended run runs them first). The first generation must
    fit.

    What "solved" means: with ``require_holds`` (see :mod:`skillcompose.evolve.holds`), the
    FSA the run would export must hold on fresh episodes at ``success_rate`` (the task's
    when None); without it (the paper), the best evaluation reaching the target solves the
    task. Either way, ``confirm_trials`` > 0 first asks the best to reach the target again
    on that many fresh worlds.

    Beyond the fields' own bounds: ``elitism`` is smaller than ``population``; with
    ``islands`` > 1 the population splits into islands of equal size (2 or more), each
    larger than ``elitism`` and ``migrants``.
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
    p_split: float = 0.0
    islands: int = 1
    migration_interval: int = 10
    migrants: int = 2
    topology: str = "ring"
    restart_after: int = 0
    restart_patience: int = 0
    restart_growth: int = 1
    population_max: int | None = None
    restart_keep: int | None = None
    drift_patience: int = 0
    unique_children: bool = False
    neutral: bool = False
    pairs: bool = False
    pairs_only: bool = False
    skill_bias: float = 0.0
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

    def __post_init__(self) -> None:
        problems = [p for s in SETTINGS if (p := s.problem(getattr(self, s.name))) is not None]
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
        problems += self._restart_problems() if not problems else []
        if self.pairs_only and not self.pairs:
            problems.append("pairs_only = True draws pairs in place of the actions they "
                            "cover, and pairs = False places none; give pairs = True")
        if problems:
            raise EvolutionConfigError(
                "invalid evolution settings: " + "; ".join(problems)
            )

    def _restart_problems(self) -> list[str]:
        """What is wrong with the restarts of the whole population (``restart_patience``)."""
        if self.restart_patience == 0:
            return [f"drift_patience = {self.drift_patience} needs restart_patience (the "
                    "growing stages it alternates with)"] if self.drift_patience else []
        problems = []
        if self.islands > 1:
            problems.append(f"restart_patience = {self.restart_patience} restarts the whole "
                            f"population, which islands = {self.islands} split; give "
                            "restart_after for islands, or islands = 1")
        if self.restart_after:
            problems.append(f"restart_patience = {self.restart_patience} and restart_after = "
                            f"{self.restart_after} are two kinds of restart; give one of them")
        if self.restart_keep is not None and self.restart_keep >= self.population:
            problems.append(f"restart_keep = {self.restart_keep} must be smaller than "
                            f"population = {self.population}")
        if self.drift_patience and self.restart_growth == 1:
            problems.append(f"drift_patience = {self.drift_patience} alternates drift with "
                            "growing stages, and restart_growth = 1 grows nothing; give "
                            "restart_growth of 2 or more")
        if self.population_max is not None and self.population_max < self.population:
            problems.append(f"population_max = {self.population_max} must be at least "
                            f"population = {self.population}")
        return problems

    def drifting(self, restarts: int) -> bool:
        """Whether the stage after ``restarts`` restarts of the whole population is a drift
        stage (``drift_patience``: every second stage, the first one never)."""
        return self.drift_patience > 0 and restarts % 2 == 1

    def patience_after(self, restarts: int) -> int:
        """The generations without a better best after which the stage after ``restarts``
        restarts ends in a restart: ``drift_patience`` in a drift stage, else
        ``restart_patience``."""
        return self.drift_patience if self.drifting(restarts) else self.restart_patience

    def population_after(self, restarts: int) -> int:
        """The population after ``restarts`` restarts of the whole population: ``population``
        times ``restart_growth`` each time, at most ``population_max`` (and 1,000,000). With
        ``drift_patience`` every second stage is a drift stage of ``population``, and only the
        others grow."""
        most = min(self.population_max or _POPULATION_MOST, _POPULATION_MOST)
        size = self.population
        if self.restart_growth == 1 or self.drifting(restarts):
            return size
        if self.drift_patience:
            restarts //= 2
        for _ in range(restarts):
            if size * self.restart_growth >= most:
                return max(size, most)
            size *= self.restart_growth
        return size

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


_POPULATION_MOST = 10**6  # the population setting's bound

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

_DETERMINISTIC: dict[str, Any] = {
    "population": 30,
    "elitism": 2,
    "tournament": 5,
    "initial_nodes": 12,
    "param_sigma": 0.1,
    "cache": True,
    "unique_children": True,
    **_HOLDS,
}

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
    "deterministic": _DETERMINISTIC,
    "adaptive": {  # the deterministic preset, restarted larger whenever it stalls
        **_DETERMINISTIC,
        "restart_patience": 100,
        "restart_growth": 4,
        "population_max": 1920,
        "drift_patience": 400,
        "pairs": True,
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
"""Named settings: ``paper`` is table 1 as it is; ``robust`` was our best options, chosen on
an earlier pour-water world (see docs/results/pour_water.md), and the default for noisy
tasks until :data:`NOISY_DEFAULT` replaced it: 600 individuals, each evaluation
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

``adaptive`` is the deterministic preset restarted with a larger population whenever it
stalls, as IPOP-CMA-ES restarts (Auger and Hansen 2005): it starts with 30 individuals, and
when the best has not improved for 100 generations (``restart_patience``) it restarts
from fresh random FSAs around its two best, four times larger (30, 120, 480, then 1920, the
cap, at every later restart). A small population solves the easy representations of a task
cheaply; a hard one stalls and gets the large population it needs. Between two growing
stages is a drift stage (``drift_patience``, as BIPOP-CMA-ES alternates its regimes): 30
individuals with neutral drift from the elites so far, until the best has not improved for
400 generations, for tasks whose plateaus are long (the John Muir trail). It also places pairs
(``pairs``: each action that only reports ``done`` followed by each sensing decision, as one
skill), so that a task written with sensing skills apart from its actions (the Santa Fe ant
with ``FoodAhead``) is searched as one whose actions report what they sense; a task with no
such skills runs as without. Chosen with ``benchmarks/bench_search.py`` on the tuning tasks
and seeds of issue 31 (docs/evolve.md, "One default that adapts").

Every preset but ``paper`` has ``require_holds``: a run is solved when its exported FSA holds
on fresh episodes at the required success rate (see :mod:`skillcompose.evolve.holds`).
``default`` (the command line's when no preset is given, and :func:`evolve`'s when given no
config) is not a fixed table: it is ``adaptive`` for a task whose episodes are all the same
(``Task.deterministic``), ``push`` for a noisy task with a skill that takes a vector (a
network's weights: ``skillcompose.evolve.plan.takes_vectors``), else :data:`NOISY_DEFAULT`
(:func:`preset_settings`)."""

NOISY_DEFAULT: dict[str, Any] = {**_ISLANDS, "p_param": 0.3, **_HOLDS}
"""What ``default`` is for a noisy task: the island preset with each node of a mutated child
given parameter noise with probability 0.3. One population of 600 (``robust``) follows one
lineage, and on pouring water's measured world that lineage is often caught where a small
change no longer helps (a jug tipped just short of pouring before it was grasped; a pose
whose pour the PR2 cannot take); islands keep four lineages, and the parameter noise moves
a near miss across. ``noisy``'s refreshed cache is left out: with it, stacking solved 5 of
9 calibration seeds where ``robust`` solved 8. See docs/evolve.md, "The default for noisy
tasks"."""

DEFAULT_PRESET = "default"


def preset_settings(name: str, deterministic: bool, vectors: bool = False) -> dict[str, Any]:
    """The settings of preset ``name`` for a task that is ``deterministic`` or not, and
    whose skills take a vector parameter (``vectors``: a network's weights) or not:
    ``default`` resolves to ``adaptive`` (deterministic), ``push`` (noisy, with vectors) or
    :data:`NOISY_DEFAULT`; the others are as listed."""
    if name == DEFAULT_PRESET:
        if deterministic:
            return dict(PRESETS["adaptive"])
        return dict(PRESETS["push"]) if vectors else dict(NOISY_DEFAULT)
    return dict(PRESETS[name])


DEFAULT_KINDS = ((False, False), (False, True), (True, False))
"""The tasks ``default`` tells apart, as :func:`preset_settings`'s ``(deterministic,
vectors)``: noisy, noisy with a vector parameter, deterministic (a deterministic task runs
``adaptive`` whatever its parameters)."""


def default_islands(population: int, most: int) -> int:
    """How many islands the default preset splits a ``population`` given on its own into:
    the most, up to ``most``, that split it evenly into islands of at least
    :data:`ISLAND_LEAST` individuals; 1 (one population) when none does. So
    ``skillcompose evolve TASK --population 50`` runs 2 islands of 25, and ``--population
    30`` one population, where a fixed 4 islands would refuse both."""
    for k in range(min(most, population // ISLAND_LEAST), 1, -1):
        if population % k == 0:
            return k
    return 1


ISLAND_LEAST = 20
"""The smallest island :func:`default_islands` makes."""

PRESET_NAMES = (DEFAULT_PRESET, *PRESETS)
"""Every name ``--preset`` takes."""

PRESET_ABOUT = {
    DEFAULT_PRESET: "islands with parameter noise; push for a noisy task whose skills take a "
                    "vector (a network's weights); adaptive for a task whose episodes are all "
                    "the same",
    "paper": "table 1 exactly, solved on one evaluation",
    "robust": "one population for noisy tasks, chosen on an earlier pour world (the "
              "noisy default before the islands)",
    "islands": "robust on 4 islands with ring migration and unique children",
    "noisy": "islands, each genome's trials kept, a strict confirmation",
    "deterministic": "a small population that evolves long, for tasks whose fitness never "
                     "changes",
    "adaptive": "the deterministic preset, restarted with a population four times larger "
                "whenever its best stalls, with drift stages of 30 between, each action "
                "followed by a decision offered as one skill",
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
