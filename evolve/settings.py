"""The evolution settings, one record each: what :class:`~skillcompose.evolve.EvolutionConfig`
checks, what ``skillcompose evolve`` offers and what the reference says, from one table.

Each :class:`Setting` names a field of the config, the kind of value it takes and its bounds,
its command-line option (or none), what its default and its special values (0, None) mean,
and what it does. From :data:`SETTINGS`:

- ``EvolutionConfig.__post_init__`` checks every field with :meth:`Setting.problem`;
- the command line builds each option with a ``type=`` from the same bounds, so an option
  takes exactly what the config takes;
- the reference's presets page lists each preset's settings with their meanings.

A test keeps the table and the config's fields one to one.
"""

from __future__ import annotations

import enum
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from skillcompose.checks import real_in, whole_in
from skillcompose.limits import MAX_TRIALS  # the command line's bound, for files too

__all__ = ["FLAGGED", "MOST", "SETTINGS", "TOPOLOGIES", "Kind", "Setting"]

MOST = 10**9
"""The bound of the counts (generations and the other budgets, intervals, jobs): far beyond
any real run."""

TOPOLOGIES = ("ring", "complete")


class Kind(enum.Enum):
    """What a setting takes, each with its own check."""

    WHOLE = "a whole number within bounds"
    PROBABILITY = "a probability, in [0, 1]"
    RATE = "a rate strictly between 0 and 1"
    REAL = "a finite number within bounds, each end open or closed"
    SWITCH = "true or false"
    CHOICE = "one of a few names"


@dataclass(frozen=True)
class Setting:
    """One field of the config: its check, its option and its meaning.

    ``low``/``high`` (and ``low_open``/``high_open``) bound a whole number or a real one;
    ``none`` says what None means (empty: None is refused), ``zero`` what 0 means when it
    is more than a count of nothing. ``flag`` is the command-line option (empty: none), whose
    value lands in the argparse field named after the setting; ``flag_zero_is_none``: the
    option's 0 gives None (``--eval-time-limit 0``: no limit). ``source`` says where the
    default comes from (the paper's table 1); ``help`` is what the setting does (the option's
    help and the reference), ``more`` what the reference adds to it.
    """

    name: str
    kind: Kind
    help: str
    low: float = 0
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    choices: tuple[str, ...] = ()
    unit: str = "a finite number"
    none: str = ""
    zero: str = ""
    flag: str = ""
    metavar: str | None = None
    flag_zero_is_none: bool = False
    source: str = ""
    more: str = ""

    def accepts(self, value: Any) -> bool:
        """Whether the config takes ``value`` for this setting."""
        if value is None:
            return bool(self.none)
        kind = self.kind
        if kind is Kind.WHOLE:
            return whole_in(value, int(self.low), int(self.high))
        if kind is Kind.SWITCH:
            return isinstance(value, bool)
        if kind is Kind.CHOICE:
            return isinstance(value, str) and value in self.choices
        low, high, low_open, high_open = self.bounds()
        return real_in(value, low, high, low_open=low_open, high_open=high_open)

    def bounds(self) -> tuple[float, float, bool, bool]:
        """``(low, high, low_open, high_open)`` of a number (a probability's [0, 1], a
        rate's (0, 1)); an infinite end is always open: every value is finite."""
        if self.kind is Kind.PROBABILITY:
            return 0.0, 1.0, False, False
        if self.kind is Kind.RATE:
            return 0.0, 1.0, True, True
        return self.low, self.high, self.low_open, self.high_open or math.isinf(self.high)

    def expected(self) -> str:
        """What the setting takes, in words: ``a whole number from 2 to 1,000,000``."""
        kind = self.kind
        if kind is Kind.WHOLE:
            return f"a whole number from {int(self.low)} to {int(self.high):,}"
        if kind is Kind.PROBABILITY:
            return "a probability in [0, 1]"
        if kind is Kind.RATE:
            return "a rate between 0 and 1 (exclusive)"
        if kind is Kind.SWITCH:
            return "true or false"
        if kind is Kind.CHOICE:
            return "one of " + ", ".join(self.choices)
        if math.isinf(self.high):
            return f"{self.unit} {'>' if self.low_open else '>='} {self.low:g}"
        return (f"a number from {'above ' if self.low_open else ''}{self.low:g} to "
                f"{'below ' if self.high_open else ''}{self.high:g}")

    def problem(self, value: Any) -> str | None:
        """What is wrong with ``value`` for this setting, naming both, or None."""
        if self.accepts(value):
            return None
        if self.kind is Kind.CHOICE:
            return f"{self.name} = {value!r}: choose one of {', '.join(self.choices)}"
        return f"{self.name} = {value!r}: expected {self.takes()}"

    def takes(self) -> str:
        """Every value the setting takes, in words: :meth:`expected`, then None's and 0's
        meanings."""
        return (self.expected() + (f", or None for {self.none}" if self.none else "")
                + (f" (0: {self.zero})" if self.zero else ""))

    def describe(self, value: Any) -> str:
        """``value`` of this setting in words: ``300``, ``0: never``, ``the task's``."""
        if value is None:
            return self.none
        if isinstance(value, bool):
            return "on" if value else "off"
        if value == 0 and self.zero:
            return f"0: {self.zero}"
        return f"{value:g}" if isinstance(value, float) else str(value)

    def describe_default(self, default: Any) -> str:
        """The default in words, where it comes from, and what 0 would mean."""
        said = self.describe(default) + (f", {self.source}" if self.source else "")
        return said + (f"; 0: {self.zero}" if self.zero and default != 0 else "")

    def text(self, refer: Callable[[Setting], str], *, more: bool = False) -> str:
        """What the setting does (with ``more``, and what the reference adds), each
        ``{name}`` in it written as ``refer(the setting name)``: an option or a field."""
        said = self.help + (". " + self.more if more and self.more else "")
        return _REFERENCE.sub(lambda m: refer(_BY_NAME[m.group(1)]), said)

    def option_help(self, default: Any) -> str:
        """The option's help: what the setting does, and its default (the config's)."""
        said = self.text(lambda s: s.flag or s.name)
        if self.kind is Kind.SWITCH:
            return said
        return (f"{said} (default{':' if default is None else ''} "
                f"{self.describe_default(default)}"
                f"{f'; 0: {self.none}' if self.flag_zero_is_none else ''})")


_REFERENCE = re.compile(r"\{(\w+)\}")
"""A setting named in another's text, ``{cache}``."""

_PAPER = "table 1"

# The order is the reference's and the command line's --help.
SETTINGS: tuple[Setting, ...] = (
    # -- the paper's algorithm (sections 3.2-3.7; table 1) --------------------------------
    Setting("population", Kind.WHOLE, "individuals per generation, N; with {islands}, all "
            "of them together", low=2, high=10**6, flag="--population", source=_PAPER),
    Setting("initial_nodes", Kind.WHOLE, "nodes of each initial random FSA, S, before "
            "pruning", low=1, high=10_000, flag="--initial-nodes", source=_PAPER),
    Setting("p_mut", Kind.PROBABILITY, "per-node probability of a node mutation",
            source=_PAPER, more="A node mutation reroutes one outgoing edge and adds "
            "Gaussian noise to each parameter with probability {p_mut}; a node's skill "
            "changes with probability {p_mut} squared, the start state with probability "
            "{p_mut} (section 3.6)."),
    Setting("p_cross", Kind.PROBABILITY, "probability that two selected parents are "
            "crossed (algorithm 2)", source=_PAPER),
    Setting("p_add", Kind.PROBABILITY, "probability of adding a node to a mutated FSA",
            source=_PAPER),
    Setting("p_del", Kind.PROBABILITY, "probability of deleting a node from a mutated FSA",
            source=_PAPER),
    Setting("tournament", Kind.WHOLE, "tournament size of the selection", low=1,
            high=10**6, flag="--tournament", metavar="K", source="PyEvolve's"),
    Setting("param_sigma", Kind.REAL, "standard deviation of the parameter noise, in units "
            "of each parameter's range [0, 1]", flag="--param-sigma", metavar="S",
            source="PyEvolve's real Gaussian mutator"),
    # -- budgets: each holds, the run stops at the first reached (or when solved) --------
    Setting("generations", Kind.WHOLE, "generation budget; the run stops earlier when it "
            "solves the task", low=0, high=MOST, flag="--generations",
            more="The paper ran until solved; this is the budget."),
    Setting("max_evaluations", Kind.WHOLE, "evaluation budget: at most this many genomes "
            "evaluated (elites kept and cache hits are free); the run stops before a "
            "generation that would overrun it", low=1, high=MOST, none="no budget",
            flag="--max-evaluations", metavar="N",
            more="An evaluation is a genome run on its trials to rank it in a generation; "
            "what costs no run is free (an elite kept, a cache hit, a genome's second copy "
            "in a generation), a cache refresh counts."),
    Setting("max_episodes", Kind.WHOLE, "episode budget: at most this many episodes of "
            "evaluations, confirmations and holds tests (the final check of the exported FSA "
            "is outside it); the run stops before a generation or check that could overrun "
            "it", low=1, high=MOST, none="no budget", flag="--max-episodes", metavar="N",
            more="Simplification and the final fresh check of the exported FSA, which come "
            "after the search, are outside it. A generation's confirmations and holds tests "
            "run only if the episodes they may take at most fit."),
    # -- options beyond the paper (off by default) ----------------------------------------
    Setting("trials", Kind.WHOLE, "episodes per evaluation; fitness is their mean", low=1,
            none="the task's", flag="--trials", metavar="T", high=MAX_TRIALS),
    Setting("elitism", Kind.WHOLE, "this many of the best are copied unchanged into the "
            "next generation; with {cache}, they are not evaluated again", low=0,
            high=10**6, flag="--elitism", metavar="K"),
    Setting("common_random_numbers", Kind.SWITCH, "common random numbers: a generation's "
            "individuals meet the same worlds (the same trial seeds), so differences in "
            "fitness come from the FSAs", flag="--crn"),
    Setting("cache", Kind.SWITCH, "do not evaluate again a genome identical to one already "
            "evaluated: it reuses its fitness", flag="--cache"),
    Setting("cache_refresh", Kind.WHOLE, "with {cache}, fresh trials run each time a genome "
            "reappears, folded into its running mean: for noisy tasks", low=0,
            zero="the cached mean as it is", flag="--cache-refresh", metavar="R", high=MAX_TRIALS),
    Setting("parsimony", Kind.SWITCH, "at equal fitness the FSA with fewer states wins "
            "(selection, elites and the reported best)", flag="--parsimony"),
    Setting("p_param", Kind.PROBABILITY, "probability that each node of a mutated child also "
            "gets parameter noise, by the node mutation's Gaussian rule without rerouting an "
            "edge", flag="--p-param", source="the paper",
            more="The paper's node mutation touches a node with probability {p_mut}, so a "
            "network's weights change in about one child in ten; tasks whose work is in the "
            "parameters (moving to push's network) need more: the push preset uses 1."),
    Setting("p_split", Kind.PROBABILITY, "probability that a node added by mutation splits "
            "the edge it takes over, its outcomes all leading where that edge led, rather "
            "than to random targets", flag="--p-split", source="the paper",
            zero="random edges (the paper's figure 3)",
            more="A split, as NEAT adds a node, changes the FSA only by the new node's own "
            "step (nothing, for a sensing skill), so a new branch can form by one later edge "
            "mutation instead of by luck in all of the node's edges at once."),
    Setting("confirm_trials", Kind.WHOLE, "fresh trials on which a solution must reach the "
            "target too before the run stops; else its fitness becomes their mean and "
            "evolution goes on", low=0, zero="no confirmation", flag="--confirm", metavar="N",
            more="Guards against a lucky solve on few trials.", high=MAX_TRIALS),
    Setting("confirm_rate", Kind.PROBABILITY, "with {confirm_trials}, the share of those "
            "trials that must each reach the target", zero="their mean must",
            flag="--confirm-rate",
            more="For tasks whose mean mixes rare large scores with small ones (stacking's "
            "50 for a run that never grasped). Its confirmations all use the same worlds, "
            "drawn once per run, so that an FSA confirmed again generation after generation "
            "cannot pass by a lucky draw at last."),
    Setting("confirm_feedback", Kind.SWITCH, "with {confirm_trials}, a solution that fails its "
            "confirmation also takes that fitness in the population (and the cache), so the "
            "next candidate is confirmed instead of it", flag="--confirm-feedback",
            more="The fitness it takes is the mean of its evaluation and its confirmation "
            "episodes. Without it only the run's record of the best changes, and the same "
            "genome, still scoring the target in the population, is confirmed again."),
    Setting("confirm_candidates", Kind.WHOLE, "with {confirm_trials}, confirm up to this many "
            "genomes at the target each generation, the most tested first, until one "
            "passes; one that failed is never confirmed again", low=0, high=10_000,
            zero="the best alone", flag="--confirm-candidates",
            more="Each is confirmed on fresh worlds of its own (with {confirm_rate} too: "
            "never the run's fixed ones). Several candidates a generation let a strict "
            "confirmation cost episodes rather than generations. With 0 the run's best is "
            "confirmed again each generation it stays the best."),
    # -- what "solved" means (holds.py) ----------------------------------------------------
    Setting("require_holds", Kind.SWITCH, "solved only when the FSA the run would export "
            "reaches the target on fresh episodes at the required success rate, by a "
            "sequential test", more="The rate is a one-sided lower confidence bound (at "
            "{holds_confidence}) of at least {success_rate}; the test takes at most "
            "{holds_max_episodes} episodes (one on a deterministic task). An FSA that fails "
            "is demoted to the mean fitness of those episodes and never tested again. Off "
            "(the paper): solved when the best evaluation reaches the target; the run still "
            "measures the exported FSA on fresh episodes and reports its rate."),
    Setting("success_rate", Kind.RATE, "with {require_holds}, solved means the exported FSA "
            "reaches the target on at least this share of fresh episodes, by a one-sided "
            "lower confidence bound at {holds_confidence}; the task's is 0.95 unless it says "
            "otherwise", none="the task's", flag="--success-rate", metavar="RATE"),
    Setting("holds_confidence", Kind.REAL, "confidence of the lower bound of the holds test",
            low=0.5, high=1.0, high_open=True),
    Setting("holds_max_episodes", Kind.WHOLE, "episodes the holds test may take at most",
            low=1, high=10**7),
    # -- islands and diversity ------------------------------------------------------------
    Setting("islands", Kind.WHOLE, "split the population into this many islands of equal "
            "size bred apart, with migration; {population} is the total and must divide "
            "evenly", low=1, high=10_000, flag="--islands",
            more="Each island has its own tournaments and keeps its own {elitism} best, as "
            "the paper's authors ran PyEvolve's islands over MPI."),
    Setting("migration_interval", Kind.WHOLE, "generations between migrations between "
            "islands", low=1, high=MOST, flag="--migration-interval",
            more="Each island receives copies of the {migrants} best individuals of its "
            "neighbours, which replace its worst. Migration draws no random numbers."),
    Setting("migrants", Kind.WHOLE, "best individuals each island sends its neighbours",
            low=0, high=10**6, flag="--migrants"),
    Setting("topology", Kind.CHOICE, "who receives migrants: ring, island k from island "
            "k - 1 (as PyEvolve's MPI migrator), or complete, every other island",
            choices=TOPOLOGIES, flag="--topology"),
    Setting("restart_after", Kind.WHOLE, "restart an island whose best has not improved for "
            "this many generations: its elites (at least its best) stay, the rest become "
            "fresh random FSAs", low=0, high=MOST, zero="never", flag="--restart-after"),
    Setting("restart_patience", Kind.WHOLE, "restart the whole population when the run's "
            "best has not improved for this many generations: its elites (at least its best) "
            "stay, the rest become fresh random FSAs, and the population grows by "
            "{restart_growth}, up to {population_max}", low=0, high=MOST, zero="never",
            flag="--restart-patience", metavar="R",
            more="Restarts with a growing population, as IPOP-CMA-ES (Auger and Hansen 2005): "
            "a small population first, which solves easy tasks cheaply, and a larger one each "
            "time the search stalls. Not with {islands} (each island restarts with "
            "{restart_after}); the restart count and the population's size are checkpointed."),
    Setting("restart_growth", Kind.WHOLE, "with {restart_patience}, the factor by which the "
            "population grows at each restart", low=1, high=1000, flag="--restart-growth",
            metavar="F"),
    Setting("population_max", Kind.WHOLE, "with {restart_patience}, the population grows to "
            "at most this many individuals; restarts at the cap keep its size", low=2,
            high=10**6, none="no cap below 1,000,000", flag="--population-max", metavar="N"),
    Setting("restart_keep", Kind.WHOLE, "with {restart_patience}, how many of the best a "
            "restart of the whole population keeps; the run's best so far is reported "
            "whatever it keeps", low=0, high=10**6, none="the elites, at least the best",
            flag="--restart-keep", metavar="K",
            more="0 makes each restart an independent run, as IPOP-CMA-ES's are."),
    Setting("drift_patience", Kind.WHOLE, "with {restart_patience}, every second stage is a "
            "drift stage: {population} individuals with neutral drift, restarted when the "
            "best has not improved for this many generations; the other stages grow",
            low=0, high=MOST, zero="no drift stages", flag="--drift-patience", metavar="D",
            more="Two regimes in turn, as BIPOP-CMA-ES alternates its large and small "
            "populations (Hansen 2009): growing populations serve tasks that need many "
            "individuals at once, a small drifting one tasks whose plateaus are long (see "
            "{neutral}). A drift stage starts from the elites of the stage before it."),
    Setting("unique_children", Kind.SWITCH, "mutate a child again, up to 8 times, until its "
            "genome is new to the generation (and, with {cache}, to the run)",
            flag="--unique-children"),
    Setting("neutral", Kind.SWITCH, "at equal fitness (and size, with {parsimony}) the newer "
            "genome ranks first in its island's elites and tournaments: a child as good as "
            "an elite replaces it (neutral drift)", flag="--neutral",
            more="The search drifts across genomes of equal fitness instead of keeping the "
            "first one found, as in the (1 + lambda) evolution strategy of Cartesian genetic "
            "programming."),
    Setting("pairs", Kind.SWITCH, "each action (a skill with one outcome that goes on) "
            "followed by each decision (a skill without parameters with two or more) is one "
            "more skill evolution may place, exported as the two plain states",
            flag="--pairs",
            more="A task written with sensing skills apart from actions that only report "
            "done gets the building block that a task whose actions report what they sense "
            "has in every state."),
    Setting("pairs_only", Kind.SWITCH, "with {pairs}, an action that a pair covers is not "
            "placed alone: a pair whose decision's outcomes all lead to one state acts as "
            "the action",
            flag="--pairs-only",
            more="The skills evolution draws then differ from a task whose actions report "
            "what they sense by the plain decisions alone."),
    Setting("skill_bias", Kind.REAL, "share of a random node's skill drawn as often as the "
            "skills of the best quarter of its island's genomes are used, the rest uniform "
            "(0: uniform, the paper's)", low=0.0, high=1.0, high_open=True,
            flag="--skill-bias", metavar="A",
            more="Learned afresh each generation from the population, as an estimation-of-"
            "distribution algorithm learns its model, so a resumed run draws as the first "
            "would: skills the best FSAs use (a sensing form's pairs, say) are placed more "
            "often, and every skill keeps at least 1 - A of its uniform share."),
    # -- faults and limits ----------------------------------------------------------------
    Setting("eval_time_limit", Kind.REAL, "wall-clock limit of one evaluation (all its "
            "trials); past it, it scores the task's worst and counts as a time-out",
            low_open=True, high_open=True, unit="seconds", none="no limit",
            flag="--eval-time-limit", metavar="SECONDS", flag_zero_is_none=True,
            more="Set it well above a normal evaluation's time, so that only a hanging skill "
            "reaches it and the run stays the same on every machine."),
    Setting("worker_max_jobs", Kind.WHOLE, "replace a pool worker (or Ray actor) after this many "
            "evaluations", low=0, high=MOST, zero="never", flag="--worker-max-jobs",
            metavar="N", more="Replacing a worker never changes results."),
    Setting("worker_max_growth_mb", Kind.REAL, "replace a worker whose resident memory has grown "
            "by more than this many MB since it started", unit="MB", zero="no limit",
            flag="--worker-max-growth-mb", metavar="MB"),
    # -- run bookkeeping ------------------------------------------------------------------
    Setting("checkpoint_every", Kind.WHOLE, "generations between checkpoints of a run "
            "directory", low=1, high=MOST, flag="--checkpoint-every"),
    Setting("chunks_per_worker", Kind.WHOLE, "chunk sizes of the Ray evaluator: each chunk "
            "takes 1 / (chunks_per_worker * actors) of what is left", low=1, high=MOST,
            more="A process pool's workers claim guided chunks from a shared counter "
            "instead."),
    Setting("terminal_weight", Kind.REAL, "weight of each terminal outcome against one node "
            "when an edge target is drawn at random",
            more="Only for tasks that name no terminating skills (docs/evolve.md)."),
)
"""Every evolution setting, once, in the order of the reference and of ``--help``."""

_BY_NAME = {s.name: s for s in SETTINGS}

FLAGGED: tuple[Setting, ...] = tuple(s for s in SETTINGS if s.flag)
"""The settings the command line offers, each as its ``flag``."""
