"""The state of one run, and its checkpoint: to plain JSON data and back, every value checked.

:class:`RunState` holds what a run knows between generations (the population, the breeding
generator, the best so far, the history, the cache, what confirmations and holds tests
found, ...); :meth:`RunState.state` is everything a checkpoint keeps and
:meth:`RunState.restore` reads it back from a file, which may come from someone else.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from skillcompose.checks import is_real, is_whole, whole_in
from skillcompose.task import Task

from .config import EvolutionConfig
from .errors import CheckpointError
from .evaluation import Faults
from .genome import Genome, GenomeCompiler, SkillSet
from .result import GenerationRecord

if TYPE_CHECKING:
    from .export import ExportSettings, SeedNames
    from .isolated import IsolatedChecks
    from .rundir import RunDir

__all__ = ["BREED_STREAM", "CONFIRM_STREAM", "EVAL_STREAM", "RunState", "fold"]

T = TypeVar("T")

# The streams of the run's seed, ``SeedSequence(seed, spawn_key=(stream, ...))``; the final
# fresh check and the holds test draw from streams 3 and 4 (see holds.py).
BREED_STREAM = 0  # the breeding generator
EVAL_STREAM = 1  # the worlds of evaluations
CONFIRM_STREAM = 2  # the worlds of confirmations

_FAULT_FIELDS = frozenset(Faults().to_dict())


def fold(total: float, count: int, mean: float, trials: int) -> tuple[float, int]:
    """A genome's running (total, episodes) with ``trials`` more episodes of ``mean``
    fitness; a worst (infinite) score on either side stands alone."""
    if math.isinf(mean) or math.isinf(total):
        return mean, 1
    return total + mean * trials, count + trials


def _tuples(data: Any) -> Any:
    """JSON lists back to the tuples a genome's code and key are made of; only numbers."""
    if isinstance(data, list):
        return tuple(_tuples(x) for x in data)
    return _number(data)


def _number(x: Any) -> float | int:
    if not is_real(x):
        raise TypeError(f"expected a number, found {type(x).__name__}")
    return x


def _whole(x: Any) -> int:
    if not whole_in(x, 0):
        raise TypeError(f"expected a whole number, found {x!r}")
    return x


def _generation_record(r: Any) -> GenerationRecord:
    """A checkpoint's history entry, checked field by field."""
    if not isinstance(r, dict):
        raise TypeError(f"a history entry is {type(r).__name__}, not an object")
    faults = r.get("faults", {})
    if not isinstance(faults, dict) or not all(
            isinstance(k, str) and is_whole(v)
            for k, v in faults.items()):
        raise TypeError("a history entry's faults are not counts")
    record = GenerationRecord(**r)
    for name in ("generation", "best_size", "evaluations", "total_evaluations"):
        _whole(getattr(record, name))
    for name in ("best", "mean", "median", "evals_per_s", "wall_time"):
        _number(getattr(record, name))
    return record


class RunState:
    """The state of one run; everything in :meth:`state` goes into a checkpoint."""

    def __init__(
        self, task: Task, cfg: EvolutionConfig, seed: int, skills: SkillSet,
        rundir: RunDir | None, trials: int, record_info: Mapping[str, Any],
        seed_text: str | None = None,
    ) -> None:
        self.task = task
        self.cfg = cfg
        self.seed = seed
        self.skills = skills
        self.rundir = rundir
        self.trials = trials
        self.record_info = dict(record_info)
        self.seed_text = seed_text  # the seed FSA file's text, kept with each checkpoint
        self.exported = False
        self.seed_names: SeedNames | None = None
        self.compiler = GenomeCompiler(task, skills)
        self.rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(BREED_STREAM,)))
        self.generation = 0
        self.population: list[Genome] = []
        self.best: tuple[Genome, float, int] | None = None  # genome, fitness, generation
        self.history: list[GenerationRecord] = []
        self.cache: dict[tuple[Any, ...], tuple[float, int]] = {}
        # confirm_candidates: genomes that failed a confirmation, and its mean
        self.confirm_failed: dict[tuple[Any, ...], float] = {}
        # require_holds: genomes whose FSA did not hold, with the mean of those episodes, and
        # the one that held (its key, the generation, and the check of its exported FSA)
        self.holds_failed: dict[tuple[Any, ...], float] = {}
        self.holds_passed: dict[str, Any] | None = None
        # the last generation reached the target, but its confirmations and holds tests did
        # not fit in the episode budget: an extended run runs them first
        self.checks_pending = False
        self.stopped_by = ""  # what ended the run: "solved" or a budget's name (budgets.py)
        # what the run would write for an evolved FSA (export.make_export's settings)
        self.export_settings: ExportSettings = (False, seed, 0, None)
        # where the checks run the task: a child process (process and Ray backends), so
        # that a task ending its process cannot end the run; None: this process
        self.isolated: IsolatedChecks | None = None
        self.evaluations = 0  # episodes: evaluations', confirmations' and holds tests'
        self.wall_before = 0.0
        self.next_uid = 0
        self.elite_fitness: dict[int, float] = {}
        # per island: its best rank key so far and the generation it was reached (restarts)
        self.island_best: list[tuple[float, int]] = []
        # restart_patience: restarts of the whole population so far, each growing it
        self.restarts = 0
        self.first_error: str | None = None  # the run's first exception, summarised
        self.gen_faults = Faults()
        self.fault_totals = Faults()  # over the run so far, for the progress line
        # the episodes of confirmations and holds tests that raised or ran past the limit
        self.check_faults = Faults()
        self.t0 = time.perf_counter()

    # -- checkpoint ------------------------------------------------------------------------
    def state(self, fitness: list[float] | None = None) -> dict[str, Any]:
        """Everything needed to continue, as plain JSON data. ``fitness``: the population
        has been evaluated (the run ended), these are its fitnesses."""
        def genome(g: Genome) -> list[Any]:
            return [g.encode(), g.origin]

        return {
            "run": dict(self.record_info),
            "seed": self.seed,
            "config": self.cfg.to_dict(),
            "generation": self.generation,
            "population": [genome(g) for g in self.population],
            "fitness": fitness,
            "rng": self.rng.bit_generator.state,
            "best": None if self.best is None else [
                genome(self.best[0]), self.best[1], self.best[2]],
            "history": [r.to_dict() for r in self.history],
            "cache": [[list(k), total, count] for k, (total, count) in self.cache.items()],
            "confirm_failed": [[list(k), mean] for k, mean in self.confirm_failed.items()],
            "holds_failed": [[list(k), mean] for k, mean in self.holds_failed.items()],
            "holds_passed": self.holds_passed,
            "checks_pending": self.checks_pending,
            "evaluations": self.evaluations,
            "wall_time": self.wall(),
            "next_uid": self.next_uid,
            "elite_fitness": [[uid, f] for uid, f in self.elite_fitness.items()],
            "island_best": [[f, since] for f, since in self.island_best],
            "restarts": self.restarts,
            "first_error": self.first_error,
            "check_faults": {"raised": self.check_faults.raised,
                             "timeouts": self.check_faults.timeouts},
            "exported": self.exported,
        }

    def checkpoint(self, fitness: list[float] | None = None) -> dict[str, Any]:
        """What a checkpoint holds: :meth:`state`, and the seed FSA file's text."""
        return {**self.state(fitness), "seed_fsa_text": self.seed_text}

    def restore(self, st: Mapping[str, Any], where: str) -> list[float] | None:
        """Continue from a checkpoint's state, checking every value (a checkpoint is data
        from a file); returns the fitnesses of an evaluated population, else None."""
        try:
            self.generation = _whole(st["generation"])
            self.population = [self._genome(g) for g in st["population"]]
            self.restarts = _whole(st.get("restarts", 0))  # none in older checkpoints
            if len(self.population) != self.cfg.population_after(self.restarts):
                raise ValueError(f"population size {len(self.population)} after "
                                 f"{self.restarts} restarts")
            fitness = st.get("fitness")
            if fitness is not None:
                fitness = [_number(f) for f in fitness]
                if len(fitness) != len(self.population):
                    raise ValueError("fitness")
            rng = st["rng"]
            if not isinstance(rng, dict) or rng.get("bit_generator") != "PCG64":
                raise ValueError("rng is not a PCG64 generator's state")
            self.rng.bit_generator.state = rng
            best = st["best"]
            self.best = None if best is None else (
                self._genome(best[0]), _number(best[1]), _whole(best[2]))
            self.history = [_generation_record(r) for r in st["history"]]
            self.cache = {
                _tuples(k): (_number(total), _whole(count)) for k, total, count in st["cache"]
            }
            self.confirm_failed = {
                _tuples(k): _number(mean) for k, mean in st.get("confirm_failed", [])
            }
            self.holds_failed = {
                _tuples(k): _number(mean) for k, mean in st.get("holds_failed", [])
            }
            passed = st.get("holds_passed")
            if passed is not None and not (isinstance(passed, dict)
                                           and isinstance(passed.get("fresh"), dict)):
                raise TypeError("holds_passed is not an object with its fresh check")
            self.holds_passed = passed
            pending = st.get("checks_pending", False)
            if not isinstance(pending, bool):
                raise TypeError("checks_pending is not true or false")
            self.checks_pending = pending
            self.evaluations = _whole(st["evaluations"])
            self.wall_before = _number(st["wall_time"])
            self.next_uid = _whole(st["next_uid"])
            self.elite_fitness = {_whole(uid): _number(f) for uid, f in st["elite_fitness"]}
            self.island_best = [(float(_number(f)), _whole(since))
                                for f, since in st.get("island_best", [])]
            self.exported = bool(st.get("exported", False))
            first_error = st.get("first_error")
            if first_error is not None and not isinstance(first_error, str):
                raise TypeError("first_error is not text")
            self.first_error = first_error
            checks = st.get("check_faults", {})  # none in older checkpoints
            if not isinstance(checks, dict):
                raise TypeError("check_faults is not an object")
            self.check_faults = Faults(raised=_whole(checks.get("raised", 0)),
                                       timeouts=_whole(checks.get("timeouts", 0)))
            self.fault_totals = self.faults()  # checks each generation's fault counts
        except CheckpointError:
            raise
        except (KeyError, TypeError, ValueError, IndexError, AttributeError, OverflowError,
                RecursionError) as exc:
            raise CheckpointError(
                f"{where} is malformed ({type(exc).__name__}: {exc}); restore it from a copy "
                "or start afresh"
            ) from None
        self.t0 = time.perf_counter()
        return fitness

    def _genome(self, data: Any) -> Genome:
        code, origin = data
        if not isinstance(origin, dict):
            raise TypeError("a genome's origin is not an object")
        g = Genome.decode(_tuples(code), origin)
        problems = g.problems(self.skills)
        if problems:
            raise ValueError(f"a genome of the checkpoint is not one of this task: {problems[0]}")
        return g

    # -- what the rest of the run asks -----------------------------------------------------
    def wall(self) -> float:
        return self.wall_before + time.perf_counter() - self.t0

    def uid(self) -> int:
        self.next_uid += 1
        return self.next_uid - 1

    def rank_key(self, fitness: float, size: int) -> tuple[float, int]:
        f = fitness if self.task.minimize else -fitness
        return (f, size if self.cfg.parsimony else 0)

    @property
    def genome_evaluations(self) -> int:
        """Genomes evaluated so far (what ``max_evaluations`` bounds): the jobs of every
        recorded generation, the same on every backend."""
        return self.fault_totals.jobs

    def budget_use(self) -> dict[str, dict[str, int | None]]:
        """Each budget's limit (None: none) and what the run has used of it."""
        return {
            "generations": {"limit": self.cfg.generations, "used": self.generation},
            "evaluations": {"limit": self.cfg.max_evaluations,
                            "used": self.genome_evaluations},
            "episodes": {"limit": self.cfg.max_episodes, "used": self.evaluations},
        }

    def faults(self) -> Faults:
        """The run's faults so far, from its history."""
        total = Faults()
        for r in self.history:
            if not isinstance(r.faults, dict):
                raise TypeError("a generation's faults are not an object")
            gen = Faults()
            for k, v in r.faults.items():
                if k in _FAULT_FIELDS:
                    setattr(gen, k, _whole(v))
            total.add(gen)
        total.add(self.check_faults)
        total.first_error = self.first_error
        return total

    def check(self, fn: Callable[..., T], *args: Any) -> T | None:
        """``fn(task, compiler, *args)``, a check of a candidate: in the checks' child
        process when there is one (:mod:`.isolated`), else here. None when it killed the
        child (counted as a lost job of the checks) or the child was killed because an
        episode ran past the time limit where no signal stopped it (a time-out)."""
        if self.isolated is None:
            return fn(self.task, self.compiler, *args)
        got = self.isolated.call(fn, *args)
        if got is None:
            overran = self.isolated.last_overran
            self.note_check_faults(Faults(jobs=1, failed=1, lost=int(not overran),
                                          timeouts=int(overran)))
        return got

    def note_check_faults(self, faults: Faults) -> None:
        """Count the faults of a confirmation's or a holds test's episodes in the run's."""
        self.check_faults.add(faults)
        self.fault_totals.add(faults)
        if self.first_error is None and faults.first_error is not None:
            self.first_error = f"in generation {self.generation}'s checks: {faults.first_error}"
