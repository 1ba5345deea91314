"""Algorithm 1: evolve FSAs for a task, against the runtime that will run them.

::

    result = evolve(task, EvolutionConfig(population=100), seed=0, out_dir="runs/toy")
    result.best_fsa        # skillcompose.FSA, states named Skill_N, simplified
    save_fsa(result.best_fsa, "toy.yaml", task.registry)

Randomness: the breeding generator is ``SeedSequence(seed, spawn_key=(0,))``; the worlds
of individual ``i`` in generation ``g`` come from ``SeedSequence(seed, spawn_key=(1, g, i))``
(``(1, g)`` for every individual with common random numbers). Nothing depends on which
worker evaluates what, so a run is the same on any backend and number of workers, and a run
resumed from a checkpoint is the same as one never interrupted. Islands (``islands`` > 1)
change none of this: they are slices of the one population, bred one after the other from
the same breeding generator, and migration draws nothing at random.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import os
import shlex
import statistics
import sys
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from skillcompose import FSA, dumps_fsa, load_fsa, loads_fsa
from skillcompose.fsafile import in_layout_of
from skillcompose.limits import MAX_WORKERS
from skillcompose.task import Task

from .config import DEFAULT_PRESET, EvolutionConfig, preset_settings
from .errors import CheckpointError, EvolutionError
from .evaluation import (
    BACKENDS,
    EvalLimits,
    Faults,
    Guard,
    Job,
    evaluate_job,
    make_evaluator,
)
from .genome import Genome, GenomeCompiler, SkillSet
from .holds import FreshCheck, holds_test, measure_fresh, required_rate
from .operators import crossover, initialize, mutate
from .resume import (
    FREE_SETTINGS,
    MEANING,
    check_record,
    differences,
    normalise,
    run_record,
    without_free,
)
from .rundir import RunDir
from .simplify import simplify

__all__ = ["EvolutionResult", "GenerationRecord", "check_fresh", "describe_fresh", "evolve"]

_RETRIES = 8  # at most this many extra mutations make a duplicate child new
_PLOT_EVERY_S = 30.0  # redraw best.png / fitness.png at checkpoints at most this often
_BREED = 0
_EVAL = 1
_CONFIRM = 2
_FRESH = 3
_HOLDS_CANDIDATES = 3  # genomes at the target whose FSA is tested for holding, a generation


@dataclass(frozen=True)
class GenerationRecord:
    """One generation: fitness statistics, the best's size, evaluations and timing."""

    generation: int
    best: float
    mean: float
    median: float
    best_size: int
    evaluations: int  # episodes run in this generation
    total_evaluations: int
    evals_per_s: float
    wall_time: float  # seconds since the run started, across resumes
    faults: dict[str, int] = field(default_factory=dict)  # Faults.to_dict() of the generation

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass
class EvolutionResult:
    """What :func:`evolve` found."""

    best_fsa: FSA  # simplified unless config.simplify is off; states named Skill_N
    best_fitness: float  # as measured during evolution
    solved: bool
    generations: int  # the index of the last generation evaluated (0: the initial one)
    evaluations: int  # episodes run during evolution
    wall_time: float
    history: list[GenerationRecord]
    evolved_fsa: FSA  # the best FSA as evolved, before simplification
    best_genome: Genome
    seed: int
    out_dir: Path | None = None
    files: list[Path] = field(default_factory=list)
    unchanged: bool = False  # a resumed run that had finished: nothing done (``files``: the
    # exported FSAs it found deleted and wrote again)
    budget: int = 0  # the generation budget
    run_command: str = ""  # a command line that runs the exported FSA on its task
    faults: Faults = field(default_factory=Faults)  # over the whole run
    fresh: dict[str, Any] = field(default_factory=dict)  # see check_fresh (empty: not run)
    # "holds": solved means the exported FSA held on fresh episodes (``fresh``, kind
    # "holds"); "evaluation": solved when an evaluation reached the target (the paper)
    solved_by: str = "evaluation"

    def _repr_html_(self) -> str:
        """In a notebook: the summary, the fitness per generation and the best FSA."""
        from skillcompose.display import html_table
        from skillcompose.draw import to_svg

        from .rundir import history_svg

        rows = [
            ("solved", self.solved), ("best fitness", f"{self.best_fitness:g}"),
            ("generations", f"{self.generations} of {self.budget}"),
            ("evaluations", self.evaluations), ("wall time", f"{self.wall_time:.1f} s"),
            ("states (evolved)", f"{len(self.best_fsa.states)} "
                                 f"({len(self.evolved_fsa.states)})"),
            ("seed", self.seed),
        ]
        if self.fresh:
            rows.append(("fresh episodes", describe_fresh(self.fresh)))
            rows.append(("solved means", "it holds on fresh episodes"
                         if self.solved_by == "holds" else
                         "an evaluation reached the target (the paper's criterion)"))
        if self.faults.total:
            rows.append(("faults", self.faults.describe()))
        if self.out_dir is not None:
            rows.append(("run directory", self.out_dir))
        return (html_table(("", ""), rows) + history_svg([r.to_dict() for r in self.history])
                + to_svg(self.best_fsa))

    @property
    def nothing_succeeded(self) -> bool:
        """Every evaluation of the run failed (raised in every episode, timed out, or killed
        its worker): nothing was learnt about the task."""
        return self.faults.jobs > 0 and self.faults.failed == self.faults.jobs


def _nan_safe(f: float, minimize: bool) -> float:
    return (math.inf if minimize else -math.inf) if math.isnan(f) else f


def _fold(total: float, count: int, mean: float, trials: int) -> tuple[float, int]:
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
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise TypeError(f"expected a number, found {type(x).__name__}")
    return x


def _whole(x: Any) -> int:
    if isinstance(x, bool) or not isinstance(x, int) or x < 0:
        raise TypeError(f"expected a whole number, found {x!r}")
    return x


def _generation_record(r: Any) -> GenerationRecord:
    """A checkpoint's history entry, checked field by field."""
    if not isinstance(r, dict):
        raise TypeError(f"a history entry is {type(r).__name__}, not an object")
    faults = r.get("faults", {})
    if not isinstance(faults, dict) or not all(
            isinstance(k, str) and isinstance(v, int) and not isinstance(v, bool)
            for k, v in faults.items()):
        raise TypeError("a history entry's faults are not counts")
    record = GenerationRecord(**r)
    for name in ("generation", "best_size", "evaluations", "total_evaluations"):
        _whole(getattr(record, name))
    for name in ("best", "mean", "median", "evals_per_s", "wall_time"):
        _number(getattr(record, name))
    return record


class _Run:
    """The state of one run; everything in :meth:`state` goes into a checkpoint."""

    def __init__(
        self, task: Task, cfg: EvolutionConfig, seed: int, skills: SkillSet,
        evaluator: Any, rundir: RunDir | None, progress: TextIO | None,
        trials: int, record_info: Mapping[str, Any],
    ) -> None:
        self.task = task
        self.cfg = cfg
        self.seed = seed
        self.skills = skills
        self.evaluator = evaluator
        self.rundir = rundir
        self.progress = progress
        self._bar: Any = None  # a tqdm bar on a terminal
        self._last_line = -math.inf  # wall time of the last progress line (not a terminal)
        self.trials = trials
        self.record_info = dict(record_info)
        self.exported = False
        self.seed_names: _SeedNames | None = None
        self.compiler = GenomeCompiler(task, skills)
        self.rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_BREED,)))
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
        self.export: Callable[[FSA], FSA] = lambda fsa: fsa  # what the run would write
        self.evaluations = 0
        self.wall_before = 0.0
        self.next_uid = 0
        self.elite_fitness: dict[int, float] = {}
        # per island: its best rank key so far and the generation it was reached (restarts)
        self.island_best: list[tuple[float, int]] = []
        self.first_error: str | None = None  # the run's first exception, summarised
        self.gen_faults = Faults()
        self.fault_totals = Faults()  # over the run so far, for the progress line
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
            "evaluations": self.evaluations,
            "wall_time": self.wall(),
            "next_uid": self.next_uid,
            "elite_fitness": [[uid, f] for uid, f in self.elite_fitness.items()],
            "island_best": [[f, since] for f, since in self.island_best],
            "first_error": self.first_error,
            "exported": self.exported,
        }

    def restore(self, st: Mapping[str, Any], where: str) -> list[float] | None:
        """Continue from a checkpoint's state, checking every value (a checkpoint is data
        from a file); returns the fitnesses of an evaluated population, else None."""
        try:
            self.generation = _whole(st["generation"])
            self.population = [self._genome(g) for g in st["population"]]
            if len(self.population) != self.cfg.population:
                raise ValueError("population size")
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

    def wall(self) -> float:
        return self.wall_before + time.perf_counter() - self.t0

    def uid(self) -> int:
        self.next_uid += 1
        return self.next_uid - 1

    # -- ranking ---------------------------------------------------------------------------
    def rank_key(self, fitness: float, size: int) -> tuple[float, int]:
        f = fitness if self.task.minimize else -fitness
        return (f, size if self.cfg.parsimony else 0)

    # -- one generation --------------------------------------------------------------------
    def evaluate(self, bred: Iterator[Genome] | None = None) -> tuple[list[float], int]:
        """Fitness of every individual of this generation; episodes run. ``bred`` is the
        next generation as :meth:`breed` makes it: each child is handed to the evaluator as
        soon as it is born, so a pool evaluates while the rest are bred."""
        cfg = self.cfg
        g = self.generation + 1 if bred is not None else self.generation
        fitness: list[float | None] = []
        jobs: list[Job] = []
        slots: list[list[int]] = []
        by_key: dict[tuple[Any, ...], int] = {}
        keys: list[tuple[Any, ...] | None] = []

        def new_jobs() -> Iterator[Job]:
            for i, ind in enumerate(bred if bred is not None else self.population):
                fitness.append(None)
                keys.append(None)
                uid = ind.origin.get("uid")
                if uid in self.elite_fitness and cfg.cache and cfg.cache_refresh == 0:
                    fitness[i] = self.elite_fitness[uid]
                    continue
                spawn = (_EVAL, g) if cfg.common_random_numbers else (_EVAL, g, i)
                trials = self.trials
                if cfg.cache:
                    k = ind.key()
                    keys[i] = k
                    if k in by_key:  # the same genome twice in this generation
                        slots[by_key[k]].append(i)
                        continue
                    if k in self.cache:
                        if cfg.cache_refresh == 0:
                            total, count = self.cache[k]
                            fitness[i] = total / count
                            continue
                        trials = cfg.cache_refresh
                    by_key[k] = len(jobs)
                jobs.append(Job.of(ind, self.seed, spawn, trials))
                slots.append([i])
                yield jobs[-1]

        results = self.evaluator.evaluate(new_jobs(), expected=cfg.population)
        assert self.generation == g and len(fitness) == len(self.population)
        self.gen_faults = self.evaluator.faults
        if self.first_error is None and self.gen_faults.first_error is not None:
            self.first_error = f"in generation {g}: {self.gen_faults.first_error}"
        episodes = sum(j.trials for j in jobs)
        for job, idx, f in zip(jobs, slots, results, strict=True):
            f = _nan_safe(float(f), self.task.minimize)
            if cfg.cache:
                key = keys[idx[0]]
                assert key is not None
                total, count = _fold(*self.cache.get(key, (0.0, 0)), f, job.trials)
                self.cache[key] = (total, count)
                f = total / count
            for i in idx:
                fitness[i] = f
        return [float(f) for f in fitness if f is not None], episodes

    def breed(
        self, fitness: list[float], bred: Callable[[], None] | None = None
    ) -> Iterator[Genome]:
        """Algorithm 1's next generation, child by child, island by island (one island
        unless ``islands`` says more); once all are born it becomes the population and
        ``bred`` is called (to save a checkpoint)."""
        population, fitness = self.migrate(self.population, fitness)
        nxt: list[Genome] = []
        self.elite_fitness = {}
        seen: set[tuple[Any, ...]] = set()
        g = self.generation + 1
        restarts = self.stagnant()
        for k, (lo, hi) in enumerate(self.island_bounds()):
            yield from self._breed_island(population[lo:hi], fitness[lo:hi], nxt, hi, g,
                                          seen, k in restarts)
        self.population = nxt
        self.generation = g
        for k in restarts:
            self.island_best[k] = (self.island_best[k][0], g)
        if bred is not None:
            bred()

    def _breed_island(
        self, population: list[Genome], fitness: list[float], nxt: list[Genome], end: int,
        g: int, seen: set[tuple[Any, ...]], restart: bool,
    ) -> Iterator[Genome]:
        """One island's children, appended to ``nxt`` until it holds ``end`` individuals."""
        cfg, rng, n = self.cfg, self.rng, len(population)
        sizes = [len(x) for x in population]
        # neutral: at equal rank the newer genome (higher uid) goes first, so a child as good
        # as the elite takes its place (neutral drift)
        newer = [-x.origin["uid"] if cfg.neutral else 0 for x in population]
        order = sorted(range(n),
                       key=lambda i: (*self.rank_key(fitness[i], sizes[i]), newer[i], i))
        rank = [0] * n
        for r, i in enumerate(order):
            rank[i] = r
        for i in order[:max(cfg.elitism, 1) if restart else cfg.elitism]:
            e = population[i].copy()
            e.origin = {**e.origin, "elite": True}
            self.elite_fitness[e.origin["uid"]] = fitness[i]
            nxt.append(e)
            if cfg.unique_children:
                seen.add(e.key())
            yield e
        if restart:  # a stagnant island starts afresh around its best
            while len(nxt) < end:
                c = initialize(self.skills, rng, cfg.initial_nodes, cfg.terminal_weight)
                c.origin = {"uid": self.uid(), "born": g, "parents": [], "ops": ["restart"]}
                nxt.append(c)
                yield c
            return

        def pick() -> Genome:
            cands = rng.integers(n, size=cfg.tournament)
            return population[min(cands, key=lambda c: rank[int(c)])]

        while len(nxt) < end:
            p1, p2 = pick(), pick()
            c1, c2 = p1.copy(), p2.copy()
            ops1: list[str] = []
            ops2: list[str] = []
            if rng.random() < cfg.p_cross:
                crossover(c1, c2, self.skills, rng, cfg.terminal_weight)
                ops1.append("crossover")
                ops2.append("crossover")
            ops1 += mutate(c1, self.skills, rng, cfg)
            ops2 += mutate(c2, self.skills, rng, cfg)
            for c, ops, parent, mate in ((c1, ops1, p1, p2), (c2, ops2, p2, p1)):
                if cfg.unique_children:
                    ops += self._made_new(c, seen)
                parents = [parent.origin["uid"]]
                if "crossover" in ops:
                    parents.append(mate.origin["uid"])
                c.origin = {"uid": self.uid(), "born": g, "parents": parents, "ops": ops}
                nxt.append(c)
            yield from nxt[len(nxt) - 2:end]
        del nxt[end:]

    def _made_new(self, child: Genome, seen: set[tuple[Any, ...]]) -> list[str]:
        """Mutate a child met before again until it is new (up to 8 times); the operators
        applied. A new child's key joins ``seen``."""
        ops: list[str] = []
        key = child.key()
        for _ in range(_RETRIES):
            if key not in seen and key not in self.cache:
                break
            ops += mutate(child, self.skills, self.rng, self.cfg)
            key = child.key()
        seen.add(key)
        return ops

    # -- islands ---------------------------------------------------------------------------
    def island_bounds(self) -> list[tuple[int, int]]:
        """Each island's slice ``[lo, hi)`` of the population."""
        size = self.cfg.population // self.cfg.islands
        return [(k * size, (k + 1) * size) for k in range(self.cfg.islands)]

    def migrate(
        self, population: list[Genome], fitness: list[float]
    ) -> tuple[list[Genome], list[float]]:
        """The population after this generation's migration (copies; the same lists when
        none is due): each island's worst are replaced by its neighbours' best, with their
        fitness. Only ranks decide, so it draws no random numbers."""
        cfg = self.cfg
        if cfg.islands < 2 or cfg.migrants == 0 or self.generation == 0 or \
                self.generation % cfg.migration_interval:
            return population, fitness
        bounds = self.island_bounds()
        sizes = [len(x) for x in population]

        def ranked(lo: int, hi: int) -> list[int]:
            return sorted(range(lo, hi),
                          key=lambda i: (*self.rank_key(fitness[i], sizes[i]), i))

        best = [ranked(lo, hi)[:cfg.migrants] for lo, hi in bounds]
        worst = [ranked(lo, hi)[::-1] for lo, hi in bounds]
        before, fitness_before = population, fitness
        population, fitness = list(population), list(fitness)
        k_all = len(bounds)
        for k, (lo, hi) in enumerate(bounds):
            sources = [(k - 1) % k_all] if cfg.topology == "ring" else \
                [j for j in range(k_all) if j != k]
            incoming = [i for j in sources for i in best[j]][:(hi - lo) // 2]
            for dest, src in zip(worst[k], incoming, strict=False):
                m = before[src].copy()
                m.origin = {**m.origin, "migrant_from": src // (hi - lo)}
                population[dest], fitness[dest] = m, fitness_before[src]
        return population, fitness

    def stagnant(self) -> set[int]:
        """The islands to restart this generation: no better best for ``restart_after``
        generations."""
        after = self.cfg.restart_after
        if after == 0:
            return set()
        return {k for k, (_, since) in enumerate(self.island_best)
                if self.generation - since >= after}

    def note_islands(self, fitness: list[float]) -> None:
        """Track each island's best and the generation it last improved (for restarts)."""
        if self.cfg.restart_after == 0:
            return
        sizes = [len(x) for x in self.population]
        bounds = self.island_bounds()
        for k, (lo, hi) in enumerate(bounds):
            key = min(self.rank_key(fitness[i], sizes[i])[0] for i in range(lo, hi))
            if k >= len(self.island_best):
                self.island_best.append((key, self.generation))
            elif key < self.island_best[k][0]:
                self.island_best[k] = (key, self.generation)

    def record(self, fitness: list[float], episodes: int, gen_time: float) -> GenerationRecord:
        sizes = [len(g) for g in self.population]
        bi = min(range(len(fitness)), key=lambda i: (*self.rank_key(fitness[i], sizes[i]), i))
        bf = fitness[bi]
        improved = self.best is None or self.rank_key(bf, sizes[bi]) < self.rank_key(
            self.best[1], len(self.best[0])
        )
        if improved:
            self.best = (self.population[bi].copy(), bf, self.generation)
        self.evaluations += episodes
        finite = [f for f in fitness if math.isfinite(f)] or [math.inf]
        rec = GenerationRecord(
            generation=self.generation,
            best=float(bf),
            mean=float(statistics.fmean(finite)),
            median=float(statistics.median(finite)),
            best_size=sizes[bi],
            evaluations=episodes,
            total_evaluations=self.evaluations,
            evals_per_s=episodes / gen_time if gen_time > 0 else 0.0,
            wall_time=self.wall(),
            faults=self.gen_faults.to_dict(),
        )
        self.fault_totals.add(self.gen_faults)
        self.note_islands(fitness)
        self.history.append(rec)
        if self.rundir is not None:
            self.rundir.append_history(rec.to_dict())
            if improved:
                self.rundir.write_best(self.named(self.best_fsa()), self.task.registry,
                                       self.header())
        return rec

    def confirm(self, fitness: list[float]) -> bool:
        """Re-run the best genome on ``confirm_trials`` fresh worlds; it stays the best (and
        the task solved) only if it reaches the target there too (its mean, or, with
        ``confirm_rate``, that share of the episodes), else its fitness becomes that measured
        mean and evolution goes on. With ``confirm_feedback`` a genome that fails also takes,
        in ``fitness`` (this generation's, which breeds the next) and in the cache, the mean
        of its evaluation's and its confirmation's episodes, wherever it is in the
        population."""
        assert self.best is not None
        if self.cfg.confirm_candidates:
            return self.confirm_candidates(fitness)
        g, evaluated, gen = self.best
        # By share: the same worlds for every confirmation of the run, so that an FSA (or a
        # neutral variant of it) re-confirmed generation after generation cannot pass by
        # drawing a lucky sample at last. By mean: fresh worlds each generation (as before).
        passed, mean, trials = self.confirmation(
            g, (_CONFIRM,) if self.cfg.confirm_rate > 0.0 else (_CONFIRM, self.generation))
        if passed:
            return True
        self.best = (g, mean, gen)
        if self.cfg.confirm_feedback:
            self.demote(g, fitness, evaluated, mean, trials)
        return False

    def confirmation(self, g: Genome, worlds: tuple[int, ...]) -> tuple[bool, float, int]:
        """Run ``g`` on the ``confirm_trials`` worlds drawn from ``worlds`` (one world on a
        deterministic task): whether it passes (its mean at the target, or, with
        ``confirm_rate``, that share of the episodes), its mean, and the episodes run."""
        task, rate = self.task, self.cfg.confirm_rate
        trials = 1 if task.deterministic else self.cfg.confirm_trials
        scores: list[float] = []
        with Guard(self.cfg.eval_time_limit) as guard:
            mean, _, _ = evaluate_job(task, self.compiler, Job.of(g, self.seed, worlds, trials),
                                      guard, False, scores)
        self.evaluations += trials
        if rate > 0.0 and not task.deterministic:
            return sum(map(task.solved, scores)) >= rate * trials, mean, trials
        return task.solved(mean), mean, trials

    def confirm_candidates(self, fitness: list[float]) -> bool:
        """``confirm_candidates``: confirm up to that many genomes of the population at the
        target, the most tested first, each on fresh worlds of its own, skipping those that
        failed before, until one passes; it becomes the best. Else the run's best takes the
        last failed confirmation's mean (evolution goes on)."""
        assert self.best is not None
        cfg, task = self.cfg, self.task
        sizes = [len(x) for x in self.population]
        keys = [x.key() for x in self.population]

        def tested(i: int) -> int:
            return self.cache.get(keys[i], (0.0, 0))[1]

        order = sorted((i for i, f in enumerate(fitness) if task.solved(f)),
                       key=lambda i: (*self.rank_key(fitness[i], sizes[i]), -tested(i), i))
        tried: set[tuple[Any, ...]] = set()
        for i in order:
            key = keys[i]
            if key in self.confirm_failed or key in tried:
                continue
            if len(tried) == cfg.confirm_candidates:
                break
            g = self.population[i]
            passed, mean, trials = self.confirmation(
                g, (_CONFIRM, self.generation, len(tried)))
            tried.add(key)
            if passed:
                self.best = (g.copy(), fitness[i], self.generation)
                return True
            self.confirm_failed[key] = mean
            self.best = (g.copy(), mean, self.generation)
            if cfg.confirm_feedback:
                self.demote(g, fitness, fitness[i], mean, trials)
        if not tried:  # every genome at the target failed a confirmation before
            g, _, gen = self.best
            self.best = (g, self.confirm_failed.get(g.key(), task.worst), gen)
        return False

    def holds(self, fitness: list[float]) -> bool:
        """``require_holds``: test the genomes at the target (the run's best first, then the
        population's by rank), skipping those that failed before, up to
        ``_HOLDS_CANDIDATES`` a generation, until one holds; it becomes the best. A genome
        that fails is demoted to the mean of its test's episodes and never tested again."""
        assert self.best is not None
        task = self.task
        sizes = [len(x) for x in self.population]
        order = sorted((i for i, f in enumerate(fitness) if task.solved(f)),
                       key=lambda i: (*self.rank_key(fitness[i], sizes[i]), i))
        candidates = [self.best] + [(self.population[i], fitness[i], self.generation)
                                    for i in order]
        tried: set[tuple[Any, ...]] = set()
        for g, f, gen in candidates:
            key = g.key()
            if not task.solved(f) or key in tried or key in self.holds_failed:
                continue
            if len(tried) == _HOLDS_CANDIDATES:
                break
            check = self.holds_check(g, len(tried))
            tried.add(key)
            if check.passed:
                self.best = (g.copy(), f, gen)
                self.holds_passed = {"generation": self.generation,
                                     "fresh": check.to_dict()}
                return True
            self.holds_failed[key] = check.mean_fitness
            self.demote(g, fitness, f, check.mean_fitness, check.episodes)
        g, _, gen = self.best
        if g.key() in self.holds_failed:  # not taken for solved, by resume either
            self.best = (g, self.holds_failed[g.key()], gen)
        return False

    def holds_check(self, g: Genome, k: int) -> FreshCheck:
        """Whether ``g`` holds: its FSA as evolved first (an FSA far below the bar fails in
        a few episodes), then, if it held, the FSA the run would export, on other worlds:
        that second check is the statement."""
        cfg = self.cfg

        def test(fsa: FSA, stream: int) -> FreshCheck:
            return holds_test(self.task, fsa, self.seed, (self.generation, stream),
                              required_rate(self.task, cfg), confidence=cfg.holds_confidence,
                              max_episodes=cfg.holds_max_episodes,
                              time_limit=cfg.eval_time_limit)

        evolved = self.compiler.fsa(g, name=f"{self.task.name}_evolved")
        first = test(evolved, 2 * k)
        self.evaluations += first.episodes
        if not first.passed:
            return first
        second = test(self.export(evolved), 2 * k + 1)
        self.evaluations += second.episodes
        return second

    def demote(self, g: Genome, fitness: list[float], evaluated: float, mean: float,
               trials: int) -> None:
        """Fold a failed confirmation (``mean`` over ``trials``) into the fitness of ``g``
        (every copy of it in the population; ``evaluated`` is the fitness its evaluation
        gave it) and into the cache."""
        key = g.key()
        if self.cfg.cache and key in self.cache:
            total, count = self.cache[key]
        else:
            total, count = evaluated * self.trials, self.trials
        total, count = _fold(total, count, mean, trials)
        if self.cfg.cache:
            self.cache[key] = (total, count)
        for i, ind in enumerate(self.population):
            if ind.key() == key:
                fitness[i] = total / count

    # -- export ----------------------------------------------------------------------------
    def best_fsa(self, simplified: dict[str, Any] | None = None) -> FSA:
        """The best genome as an FSA, states named ``Skill_N``."""
        assert self.best is not None
        g, f, gen = self.best
        info = self.record_info
        meta: dict[str, Any] = {
            "evolved": {
                "task": self.task.name,
                "task_module": info.get("task_module"),
                "task_settings": dict(info.get("task_settings") or self.task.settings),
                "fitness": f,
                "solved": self.task.solved(f),
                "found_in_generation": gen,
                "seed": self.seed,
                "config": self.cfg.to_dict(),
                "lineage": dict(g.origin),
            }
        }
        if simplified:
            meta["simplified"] = simplified
        return self.compiler.fsa(g, name=f"{self.task.name}_evolved", meta=meta)

    def named(self, fsa: FSA) -> FSA:
        """``fsa`` with the seed file's state names (and comments) where they survive."""
        return self.seed_names.apply(fsa, self.header()) if self.seed_names else fsa

    def header(self) -> str:
        assert self.best is not None
        _, f, gen = self.best
        return (
            f"Evolved by skillcompose for task {self.task.name} (seed {self.seed}): fitness "
            f"{f:g} in generation {gen}.\nEdit freely: rename states, change parameters (in "
            "the skills' units), re-route outcomes.\nRun it with `"
            f"{run_command('FILE', self.record_info)}`,\nor evolve from it with "
            "`--seed-fsa FILE`."
        )

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
        total.first_error = self.first_error
        return total

    def show_progress(self, rec: GenerationRecord, final: bool = False) -> None:
        """What is known: generations done (of the budget), their rate, the best fitness and
        size, evaluations/s, and the faults so far. No time to the end: a run stops when it
        solves the task, which nobody can foresee (the budget only bounds it)."""
        if self.progress is None or (final and self._last_line == rec.wall_time):
            return
        from tqdm import tqdm

        done = len(self.history)
        so_far = self.best[1] if self.best is not None else rec.best
        postfix = (f"best {so_far:.4g} (this generation {rec.best:.4g}, size "
                   f"{rec.best_size}), {rec.evals_per_s:,.0f} evals/s")
        faults = self.fault_totals.describe()
        if faults:
            postfix += f", faults: {faults}"
        desc = f"gen {rec.generation}/{self.cfg.generations}"
        if getattr(self.progress, "isatty", lambda: False)():
            if self._bar is None:
                self._bar = tqdm(
                    total=None, initial=done, unit="gen", file=self.progress,
                    dynamic_ncols=True, leave=True, desc=desc, postfix=postfix,
                    bar_format="{desc}: {elapsed}, {rate_fmt}{postfix}",
                )
            else:
                self._bar.set_description_str(desc, refresh=False)
                self._bar.set_postfix_str(postfix, refresh=False)
                self._bar.update(1)
        elif rec.wall_time - self._last_line >= 5.0 or final:  # a log: a line per 5 s
            self._last_line = rec.wall_time
            rate = done / rec.wall_time if rec.wall_time > 0 else 0.0
            line = tqdm.format_meter(
                done, None, rec.wall_time, prefix=desc, unit="gen", rate=rate,
                bar_format="{desc}: {elapsed}, {rate_fmt}{postfix}", postfix=postfix,
            )
            self.progress.write(line + "\n")
            self.progress.flush()

    def close_progress(self) -> None:
        if self._bar is None and self.history:  # a log ends with the last generation
            self.show_progress(self.history[-1], final=True)
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def run_command(path: str, info: Mapping[str, Any]) -> str:
    """A ``skillcompose run`` command line that runs an exported FSA on its task."""
    module = info.get("task_module")
    if not module:
        return f"skillcompose run {shlex.quote(path)} --task TASK"
    words = ["skillcompose", "run", path, "--task", str(module)]
    for k, v in dict(info.get("task_settings") or {}).items():
        words += ["--set", f"{k}={v}"]
    return " ".join(shlex.quote(w) for w in words)


class _SeedNames:
    """The state names of a seed FSA file, given back to the states that survive evolution.

    A state of an exported FSA is the seed's state when it comes from the same genome node
    (its number) and runs the same skill with the same parameters: it takes the seed's name.
    When its transitions are the same as well, it keeps the seed file's entry, comments
    included; the rest of the file (the header, the other states) is written afresh.
    """

    def __init__(self, seed: FSA, genome: Genome, compiler: GenomeCompiler) -> None:
        self.seed = seed
        self.generated = compiler.fsa(genome)  # the seed as a genome exports it: Skill_N
        self.names: dict[str, str] = {}  # Skill_N -> the seed's name
        queue = [(self.generated.start, seed.start)]
        while queue:  # the two are the same graph: walk both from the start
            gen, own = queue.pop()
            if gen in self.names:
                continue
            self.names[gen] = own
            for outcome, target in self.generated.states[gen].transitions.items():
                if target in self.generated.states:
                    queue.append((target, seed.states[own].transitions[outcome]))

    def apply(self, fsa: FSA, header: str) -> FSA:
        rename: dict[str, str] = {}
        unchanged: set[str] = set()
        for name, st in fsa.states.items():
            was = self.generated.states.get(name)
            if name not in self.names or was is None or (st.skill, dict(st.params)) != (
                    was.skill, dict(was.params)):
                continue
            rename[name] = self.names[name]
            if dict(st.transitions) == dict(was.transitions):
                unchanged.add(self.names[name])
        taken = set(fsa.states) - set(rename)
        rename = {k: v for k, v in rename.items() if v not in taken}

        def to(n: str) -> str:
            return rename.get(n, n)

        states = {
            to(n): dataclasses.replace(st, transitions={o: to(t) for o, t in
                                                        st.transitions.items()})
            for n, st in fsa.states.items()
        }
        named = fsa.replace(states=states, start=to(fsa.start))
        return in_layout_of(named, self.seed, unchanged & set(rename.values()), header)


_FAULT_FIELDS = frozenset(Faults().to_dict())


def check_fresh(
    task: Task, fsa: FSA, seed: int, trials: int, time_limit: float | None = None,
    required: float | None = None, confidence: float = 0.95,
) -> dict[str, Any]:
    """How ``fsa`` does on ``trials`` fresh episodes (worlds from ``SeedSequence(seed,
    spawn_key=(3,))``, never seen during evolution or simplification): the share that
    reach the task's target (``success_rate``) with its one-sided bounds at ``confidence``
    (``lower``, ``upper``; Clopper–Pearson), whether the lower one reaches ``required``
    (``holds``, None when no rate is required), the mean fitness, and the episodes that
    raised or ran past ``time_limit`` [s] (each scores worst)."""
    seq = np.random.SeedSequence(seed, spawn_key=(_FRESH,))
    return measure_fresh(task, fsa, seq, trials, seed, required=required,
                         confidence=confidence, time_limit=time_limit).to_dict()


def describe_fresh(fresh: Mapping[str, Any]) -> str:
    """One line for a fresh check of ``run.json`` or a result: the rate, its bounds and,
    when a rate was required, whether it holds (older runs: the rate alone)."""
    rate, episodes = fresh.get("success_rate"), fresh.get("episodes")
    if not isinstance(rate, (int, float)) or not isinstance(episodes, int):
        return "not measured"
    text = f"{100 * rate:.1f} % of {episodes:,} fresh episodes reach the target"
    lower, upper = fresh.get("lower"), fresh.get("upper")
    if isinstance(lower, (int, float)) and isinstance(upper, (int, float)):
        conf = fresh.get("confidence", 0.95)
        text += f" ({100 * conf:g} % bounds {100 * lower:.1f}–{100 * upper:.1f} %)"
    required, holds = fresh.get("required_rate"), fresh.get("holds")
    if isinstance(required, (int, float)) and isinstance(holds, bool):
        text += (f"; holds at the required {100 * required:g} %" if holds else
                 f"; does not hold at the required {100 * required:g} %")
    return text


def fresh_differs(task: Task, evolved: float, fresh: float) -> bool:
    """Whether the fitness on fresh episodes tells another story than the evolved one: the
    task counts one as solved and not the other, or they differ by more than 10 %."""
    if task.solved(evolved) != task.solved(fresh):
        return True
    if math.isinf(evolved) or math.isinf(fresh) or math.isnan(fresh):
        return evolved != fresh
    return abs(fresh - evolved) > 0.1 * max(abs(fresh), abs(evolved))


def evolve(
    task: Task,
    cfg: EvolutionConfig | None = None,
    seed: int | None = 0,
    workers: int | None = None,
    backend: str = "serial",
    out_dir: str | os.PathLike[str] | None = None,
    seed_fsa: FSA | str | os.PathLike[str] | None = None,
    progress: bool | TextIO = False,
    *,
    resume: str | os.PathLike[str] | None = None,
    simplify_result: bool | None = None,
    simplify_trials: int | None = None,
    check_trials: int | None = None,
    on_generation: Callable[[GenerationRecord], None] | None = None,
) -> EvolutionResult:
    """Evolve an FSA for ``task`` (algorithm 1), stopping when solved or out of generations.

    - ``cfg``: the settings (default: the ``default`` preset for this task,
      :func:`~skillcompose.evolve.config.preset_settings`: solved means the exported FSA
      holds on fresh episodes at the task's ``success_rate``; ``EvolutionConfig()`` is the
      paper's table 1, solved on one evaluation).
    - ``seed``: the run's seed (``None`` draws one, recorded in the result and files).
    - ``backend``: ``"serial"``, ``"process"`` (``workers`` processes, default all cores) or
      ``"ray"`` (``workers`` actors, default one per CPU of the cluster); the result does not
      depend on it.
    - ``out_dir``: write the run directory (see :mod:`skillcompose.evolve.rundir`) as the run goes.
    - ``resume``: a run directory to continue from its last checkpoint (see
      :mod:`skillcompose.evolve.resume`). ``task`` must be the run's task; the seed, the
      settings, the simplification and the fresh-episode check are the run's. ``cfg``, when
      given, may differ from the run's only in ``generations`` (to extend a run: the result
      is the run an uninterrupted run to that budget would have given), ``checkpoint_every``,
      ``chunks_per_worker``, ``worker_max_jobs`` and ``worker_max_growth_mb``. A finished
      run is not touched (``result.unchanged``), but for its exported FSAs, written again
      when they were deleted.
    - ``seed_fsa``: an FSA (or file) placed in the first population, the rest random; the
      states that survive evolution keep their names (and, from a file, their comments).
    - ``simplify_result``: simplify the best FSA at the end (default on) with
      ``simplify_trials`` fresh trials (default 200; see :func:`skillcompose.evolve.simplify`).
    - ``check_trials``: fresh episodes on which the exported FSA is measured at the end
      (default 200; :func:`check_fresh`; ``result.fresh``, ``run.json``), unless the run was
      solved by its holds test, whose episodes are then the measure; 0 skips it. A
      deterministic task (``Task.deterministic``) uses one trial for evaluations,
      simplification and this check.
    - ``progress``: progress on stderr (or on the given stream): a live line on a
      terminal, a line every 5 s otherwise; both show the faults so far.
    """
    _check_arguments(task, cfg, workers, progress, on_generation, resume, out_dir)
    workers = None if workers is None else int(workers)  # numpy's: Python's, for run.json
    if backend not in BACKENDS:
        raise EvolutionError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    rundir: RunDir | None = None
    checkpoint: dict[str, Any] | None = None
    record: dict[str, Any] | None = None
    if resume is not None:
        if seed_fsa is not None:
            raise EvolutionError("seed_fsa starts a new run; a resumed run has its own already")
        rundir = RunDir(resume)
        rundir.lock()
        try:
            checkpoint = rundir.load_checkpoint()
            record, cfg = _resumed(task, cfg, rundir, checkpoint, simplify_result,
                                   simplify_trials, check_trials)
        except BaseException:
            rundir.unlock()
            raise
        seed = record["seed"]
        simplify_result, simplify_trials = record["simplify"], record["simplify_trials"]
        check_trials = record["check_trials"]
    elif out_dir is not None:
        rundir = RunDir(out_dir)  # created (and locked) once the run's record is known
    try:
        return _evolve(task, cfg, seed, workers, backend, seed_fsa, progress,
                       rundir, checkpoint, record, simplify_result, simplify_trials,
                       check_trials, on_generation)
    finally:
        if rundir is not None:
            rundir.unlock()


def _resumed(
    task: Task, cfg: EvolutionConfig | None, rundir: RunDir, checkpoint: Mapping[str, Any],
    simplify_result: bool | None, simplify_trials: int | None, check_trials: int | None,
) -> tuple[dict[str, Any], EvolutionConfig]:
    """The run's record and settings, checked against ``run.json`` and what was given."""
    where = str(rundir.checkpoint)
    record = check_record(checkpoint.get("run"), where)
    info = rundir.load_run_info()
    def meaning(k: str, v: Any) -> Any:
        return without_free(normalise(v)) if k == "config" else normalise(v)

    edited = [k for k in MEANING if meaning(k, info.get(k)) != meaning(k, record[k])]
    if edited:
        found = differences({k: meaning(k, record[k]) for k in edited},
                            {k: meaning(k, info.get(k)) for k in edited})
        raise CheckpointError(
            f"{rundir.run_json} differs from the run's checkpoint in {', '.join(found)}; "
            "a run cannot change its meaning on resume: restore run.json, or start a new run "
            "with the settings you want"
        )
    recorded_cfg = EvolutionConfig.from_dict(record["config"])
    given: dict[str, Any] = {"task": task.name}
    if task.ref is not None:
        given["task_settings"] = dict(task.ref.settings)
    if simplify_result is not None:
        given["simplify"] = simplify_result
    if simplify_trials is not None:
        given["simplify_trials"] = simplify_trials
    if check_trials is not None:
        given["check_trials"] = check_trials
    problems = differences(record, given)
    if cfg is not None:
        mine = recorded_cfg.to_dict()
        problems += differences(mine, {
            k: v for k, v in cfg.to_dict().items() if k not in FREE_SETTINGS})
        recorded_cfg = recorded_cfg.replace(**{k: getattr(cfg, k) for k in FREE_SETTINGS})
    if problems:
        raise CheckpointError(
            f"{rundir.path}: resuming with {'; '.join(problems)} would change the run; leave "
            "them out (a resume may change only the generation budget, the backend, the "
            "workers, when workers are replaced and how often it checkpoints)"
        )
    return record, recorded_cfg


def _check_arguments(
    task: Any, cfg: Any, workers: Any, progress: Any, on_generation: Any, resume: Any,
    out_dir: Any,
) -> None:
    """The kinds of :func:`evolve`'s arguments, refused in one line naming the fix (else
    they fail deep inside, or after a generation has run)."""
    if not isinstance(task, Task):
        raise TypeError(f"evolve() takes a Task, got {type(task).__name__}; load one with "
                        "skillcompose.task.load_task('examples.toy_task', ...)")
    if cfg is not None and not isinstance(cfg, EvolutionConfig):
        raise TypeError(f"evolve(cfg=...) takes an EvolutionConfig, got {type(cfg).__name__}"
                        "; write EvolutionConfig(**PRESETS['robust']), say")
    if workers is not None and (isinstance(workers, bool) or
                                not isinstance(workers, numbers.Integral) or
                                not 1 <= int(workers) <= MAX_WORKERS):
        raise EvolutionError(f"workers = {workers!r}: expected a whole number from 1 to "
                             f"{MAX_WORKERS} (or None: every core)")
    if progress is not None and not isinstance(progress, (bool, int)) and \
            not callable(getattr(progress, "write", None)):
        raise TypeError(f"evolve(progress=...) takes True, False or a stream, got "
                        f"{type(progress).__name__}")
    if on_generation is not None and not callable(on_generation):
        raise TypeError(f"evolve(on_generation=...) takes a function, got "
                        f"{type(on_generation).__name__}")
    for name, path in (("resume", resume), ("out_dir", out_dir)):
        if path is not None and not isinstance(path, (str, os.PathLike)):
            raise TypeError(f"evolve({name}=...) takes a folder's path, got "
                            f"{type(path).__name__}")
        if path is not None and not os.fspath(path):
            raise EvolutionError(f"evolve({name}='') names no folder; give the run's folder")
        if path is not None and Path(path).is_symlink() and not Path(path).exists():
            raise EvolutionError(f"{name}={os.fspath(path)!r} is a link to nothing; give a "
                                 "folder")
        if path is not None and Path(path).exists() and not Path(path).is_dir():
            raise EvolutionError(f"{name}={os.fspath(path)!r} is not a folder; give the run's "
                                 "folder" if name == "resume" else
                                 f"{name}={os.fspath(path)!r} is not a folder; give a new "
                                 "folder for the run")


def _evolve(
    task: Task, cfg: EvolutionConfig | None, seed: int | None, workers: int | None,
    backend: str, seed_fsa: FSA | str | os.PathLike[str] | None, progress: bool | TextIO,
    rundir: RunDir | None, checkpoint: dict[str, Any] | None, record: dict[str, Any] | None,
    simplify_result: bool | None, simplify_trials: int | None, check_trials: int | None,
    on_generation: Callable[[GenerationRecord], None] | None,
) -> EvolutionResult:
    if cfg is None:  # the honest default: "solved" means the exported FSA holds
        cfg = EvolutionConfig(**preset_settings(DEFAULT_PRESET, task.deterministic))
    simplify_result = True if simplify_result is None else simplify_result
    simplify_trials = 200 if simplify_trials is None else simplify_trials
    if isinstance(simplify_trials, bool) or not isinstance(simplify_trials, int) or \
            simplify_trials < 1:
        raise EvolutionError(f"simplify_trials must be a whole number >= 1, got "
                             f"{simplify_trials!r}")
    check_trials = 200 if check_trials is None else check_trials
    if isinstance(check_trials, bool) or not isinstance(check_trials, int) or check_trials < 0:
        raise EvolutionError(f"check_trials must be a whole number >= 0, got {check_trials!r}")
    if seed is None:
        seed = int(np.random.SeedSequence().generate_state(2, np.uint64)[0] >> 1)
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise EvolutionError(f"seed must be a whole number >= 0, got {seed!r}")
    seed = int(seed)
    skills = SkillSet.from_task(task)
    trials = cfg.trials or task.trials
    # the run records the trials asked for; a deterministic task uses one: every episode is
    # the same, one says it all
    simplify_used, check_used = simplify_trials, check_trials
    if task.deterministic:
        trials = 1
        simplify_used, check_used = min(simplify_used, 1), min(check_used, 1)
    stream: TextIO | None = sys.stderr if progress is True else (progress or None)
    if backend == "process" and workers is None:
        workers = os.cpu_count() or 1
    seed_text: str | None = None
    seed_source: FSA | None = None
    seed_path: str | None = None
    if checkpoint is not None:
        seed_text = checkpoint.get("seed_fsa_text")
        if seed_text is not None:
            if not isinstance(seed_text, str):
                raise CheckpointError(f"{rundir and rundir.checkpoint}: seed_fsa_text is not text")
            seed_source = loads_fsa(seed_text, "the run's seed FSA")
    elif seed_fsa is not None:
        if isinstance(seed_fsa, FSA):
            seed_source = seed_fsa
        else:
            seed_path = str(seed_fsa)
            seed_source = load_fsa(seed_fsa)
            seed_text = Path(seed_fsa).read_text(encoding="utf-8")
    seed_genome: Genome | None = None
    if seed_source is not None:
        seed_genome = Genome.from_fsa(seed_source, skills, seed_path or seed_source.path or "")
        limited = [f"{name} ({st.time_limit:g} s)" for name, st in seed_source.states.items()
                   if st.time_limit is not None]
        if limited and checkpoint is None:  # said once, as the run starts
            print(f"warning: {seed_path or 'the seed FSA'}: the time_limit of "
                  f"{', '.join(limited)} is not part of what evolves: evolution runs the "
                  "states without it and the evolved FSA has none; put it back in the "
                  "exported file (or bound whole evaluations with --eval-time-limit)",
                  file=sys.stderr)
    if record is None:
        record = run_record(task, seed, cfg, seed_path, simplify_result, simplify_trials,
                            check_trials)
    else:
        record = {**record, "config": cfg.to_dict()}  # a resume may extend the budget
    info = {**record, "backend": backend, "workers": workers}
    if rundir is not None and checkpoint is None:
        rundir.create(info)
    run = _Run(task, cfg, seed, skills, None, rundir, stream, trials, record)

    def export(fsa: FSA) -> FSA:
        """The FSA the run writes for ``fsa``: simplified (unless asked not to)."""
        if not simplify_result:
            return fsa
        out = simplify(task, fsa, seed=seed, trials=simplify_used,
                       time_limit=cfg.eval_time_limit)
        return out.replace(meta={**fsa.meta, **out.meta}, name=fsa.name)

    run.export = export
    if seed_source is not None and seed_genome is not None:
        run.seed_names = _SeedNames(seed_source, seed_genome, run.compiler)
    fitness: list[float] | None = None
    if checkpoint is not None:
        assert rundir is not None
        fitness = run.restore(checkpoint, str(rundir.checkpoint))
        if cfg.generations < run.generation:  # finished or not: a budget cannot shrink
            raise CheckpointError(
                f"{rundir.path} has reached generation {run.generation} already; give "
                f"--generations {run.generation} or more"
            )
        ended = fitness is not None and (
            (run.best is not None and task.solved(run.best[1]))
            or run.generation >= cfg.generations)
        if ended and run.exported:
            return _unchanged(run, checkpoint, rundir)
        rundir.write_run_info(info)
        rundir.rewrite_history([r.to_dict() for r in run.history])
    else:
        for i in range(cfg.population):
            g = initialize(skills, run.rng, cfg.initial_nodes, cfg.terminal_weight)
            if i == 0 and seed_genome is not None:
                g = seed_genome.copy()
            g.origin = {**g.origin, "uid": run.uid(), "born": 0, "parents": [], "ops": [
                "seed_fsa" if (i == 0 and seed_genome is not None) else "init"]}
            run.population.append(g)
        if rundir is not None:
            rundir.save_checkpoint({**run.state(), "seed_fsa_text": seed_text})
    run.exported = False
    last_plot = time.perf_counter()

    def save(fitness: list[float] | None = None) -> None:
        assert rundir is not None
        rundir.save_checkpoint({**run.state(fitness), "seed_fsa_text": seed_text})

    def bred() -> None:  # runs as the last child is born, while the pool evaluates
        nonlocal last_plot
        if rundir is not None and run.generation % cfg.checkpoint_every == 0:
            save()
            if time.perf_counter() - last_plot > _PLOT_EVERY_S:  # drawing is slow
                rundir.plots([r.to_dict() for r in run.history], run.named(run.best_fsa()))
                last_plot = time.perf_counter()

    solved = run.best is not None and task.solved(run.best[1])
    if not solved and (fitness is None or run.generation < cfg.generations):
        limits = EvalLimits(cfg.eval_time_limit, cfg.worker_max_jobs, cfg.worker_max_growth_mb)
        run.evaluator = make_evaluator(backend, task, skills, workers, cfg.chunks_per_worker,
                                       limits, islands=cfg.islands)
        try:
            while not solved and (fitness is None or run.generation < cfg.generations):
                children = run.breed(fitness, bred) if fitness is not None else None
                t = time.perf_counter()
                fitness, episodes = run.evaluate(children)
                _check_not_all_lost(run, rundir)
                rec = run.record(fitness, episodes, time.perf_counter() - t)
                run.show_progress(rec)
                if on_generation is not None:
                    on_generation(rec)
                assert run.best is not None
                solved = task.solved(run.best[1])
                if solved and cfg.confirm_trials:
                    solved = run.confirm(fitness)
                if solved and cfg.require_holds and not run.faults().lost:
                    solved = run.holds(fitness)
        finally:
            run.evaluator.close()
            run.close_progress()
    assert run.best is not None and fitness is not None
    if rundir is not None:  # the evolution is over: a kill from here on only redoes exports
        save(fitness)
    best_genome, best_f, _ = run.best
    evolved = run.best_fsa()
    best = evolved
    lost = run.faults().lost
    if lost and (simplify_result or check_used > 0):
        # simplification and the fresh check run the task here, in the evolving process,
        # which a task that kills its worker would end without a word (and again on resume)
        print(f"warning: {lost} evaluation(s) of this run killed the worker process running "
              f"them (os._exit in task {task.name} or a skill, a crash in C code): "
              "simplification and the fresh-episode check, which would run the task in this "
              "process, are skipped; best.yaml is the evolved FSA", file=sys.stderr)
        simplify_result, check_used = False, 0
    if simplify_result:
        best = export(evolved)
    evolved, best = run.named(evolved), run.named(best)
    # with require_holds, solved is the statement of the holds test (unless a worker was
    # killed: then the test, which runs the task in this process, was not run)
    solved_by = "holds" if cfg.require_holds and not lost else "evaluation"
    solved = task.solved(best_f) and (solved_by == "evaluation" or run.holds_passed is not None)
    fresh: dict[str, Any] = {}
    if solved and solved_by == "holds":
        assert run.holds_passed is not None
        fresh = {**run.holds_passed["fresh"], "differs": False}
    elif check_used > 0:
        fresh = check_fresh(task, best, seed, check_used, cfg.eval_time_limit,
                            required=required_rate(task, cfg),
                            confidence=cfg.holds_confidence)
        fresh["differs"] = fresh_differs(task, best_f, fresh["mean_fitness"])
    faults = run.faults()
    files: list[Path] = []
    if rundir is not None:
        rundir.write_best(evolved, task.registry, run.header(), rundir.best_evolved_yaml)
        rundir.write_best(best, task.registry, run.header())
        rundir.plots([r.to_dict() for r in run.history], best)
        rundir.update_run_info({"result": {
            "solved": solved,
            "solved_by": solved_by,
            "best_fitness": best_f,
            "generations": run.generation,
            "evaluations": run.evaluations,
            "fresh": fresh,
            "faults": faults.to_dict(),
            "first_error": faults.first_error,
        }})
        run.exported = True  # last: a kill before this redoes only the exports
        rundir.save_checkpoint({**run.state(fitness), "seed_fsa_text": seed_text,
                                "best_yaml": dumps_fsa(best, task.registry, header=run.header()),
                                "fresh": fresh})
        files = [rundir.best_yaml, rundir.best_evolved_yaml, rundir.best_dot, rundir.best_png,
                 rundir.history, rundir.fitness_png, rundir.checkpoint, rundir.run_json]
    return EvolutionResult(
        best_fsa=best,
        best_fitness=best_f,
        solved=solved,
        generations=run.generation,
        evaluations=run.evaluations,
        wall_time=run.wall(),
        history=run.history,
        evolved_fsa=evolved,
        best_genome=best_genome,
        seed=seed,
        out_dir=rundir.path if rundir is not None else None,
        files=files,
        budget=cfg.generations,
        run_command=run_command(str(rundir.best_yaml) if rundir else "FILE", record),
        faults=faults,
        fresh=fresh,
        solved_by=solved_by,
    )


def _check_not_all_lost(run: _Run, rundir: RunDir | None) -> None:
    """Stop the run when every evaluation of the generation killed the worker running it:
    the task does that (and would kill this process too, simplifying or checking the
    result), so going on would only count deaths."""
    faults = run.gen_faults
    if faults.jobs == 0 or faults.lost < faults.jobs:
        return
    again = ""
    if rundir is not None:
        again = (f"; fix it, then go on with: skillcompose evolve --resume "
                 f"{shlex.quote(str(rundir.path))}")
    raise EvolutionError(
        f"every evaluation of generation {run.generation} ({faults.jobs}) killed the worker "
        f"process running it: os._exit in task {run.task.name} or a skill, a crash in C code, "
        f"or the out-of-memory killer; the run stops without recording it{again}"
    )


def _unchanged(run: _Run, checkpoint: Mapping[str, Any], rundir: RunDir) -> EvolutionResult:
    """The result of a run that had finished: read from its checkpoint. Nothing is written
    but the exported FSAs found missing (deleted), written again as the run wrote them;
    ``files`` names those."""
    assert run.best is not None
    text = checkpoint.get("best_yaml")
    evolved = run.named(run.best_fsa())
    best = loads_fsa(text, str(rundir.checkpoint)) if isinstance(text, str) else evolved
    fresh = checkpoint.get("fresh")
    g, f, _ = run.best
    solved_by = "holds" if run.cfg.require_holds and not run.faults().lost else "evaluation"
    solved = run.task.solved(f) and (solved_by == "evaluation" or run.holds_passed is not None)
    restored: list[Path] = []
    for path, again in ((rundir.best_yaml, text if isinstance(text, str) else None),
                        (rundir.best_evolved_yaml, None)):
        if not os.path.lexists(path):
            again = again or dumps_fsa(evolved, run.task.registry, header=run.header())
            rundir.write_editable(path, again.encode("utf-8"))
            restored.append(path)
    return EvolutionResult(
        best_fsa=best, best_fitness=f, solved=solved, generations=run.generation,
        evaluations=run.evaluations, wall_time=run.wall_before, history=run.history,
        evolved_fsa=evolved, best_genome=g, seed=run.seed, out_dir=rundir.path,
        files=restored,
        unchanged=True, budget=run.cfg.generations,
        run_command=run_command(str(rundir.best_yaml), run.record_info),
        faults=run.faults(), fresh=fresh if isinstance(fresh, dict) else {},
        solved_by=solved_by,
    )
