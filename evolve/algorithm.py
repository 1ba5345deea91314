"""Algorithm 1: evolve FSAs for a task, against the runtime that will run them.

::

    result = evolve(task, EvolutionConfig(population=100), seed=0, out_dir="runs/toy")
    result.best_fsa        # skillcompose.FSA, states named Skill_N, simplified
    save_fsa(result.best_fsa, "toy.yaml", task.registry)

Randomness: the breeding generator is ``SeedSequence(seed, spawn_key=(0,))``; the worlds
of individual ``i`` in generation ``g`` come from ``SeedSequence(seed, spawn_key=(1, g, i))``
(``(1, g)`` for every individual with common random numbers). Nothing depends on which
worker evaluates what, so a run is the same on any backend and number of workers, and a run
resumed from a checkpoint is the same as one never interrupted.
"""

from __future__ import annotations

import math
import os
import statistics
import sys
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from skillcompose import FSA, load_fsa
from skillcompose.executor import trial_rngs
from skillcompose.task import Task

from .config import EvolutionConfig
from .errors import CheckpointError, EvolutionError
from .evaluation import (
    BACKENDS,
    TIMED_OUT,
    EvalLimits,
    Faults,
    Guard,
    Job,
    evaluate_episode,
    evaluate_job,
    make_evaluator,
)
from .genome import Genome, GenomeCompiler, SkillSet
from .operators import crossover, initialize, mutate
from .rundir import RunDir
from .simplify import simplify

__all__ = ["EvolutionResult", "GenerationRecord", "check_fresh", "evolve"]

_PLOT_EVERY_S = 30.0  # redraw best.png / fitness.png at checkpoints at most this often
_BREED = 0
_EVAL = 1
_CONFIRM = 2
_FRESH = 3


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
    faults: Faults = field(default_factory=Faults)  # over the whole run
    fresh: dict[str, Any] = field(default_factory=dict)  # see check_fresh (empty: not run)

    @property
    def nothing_succeeded(self) -> bool:
        """Every evaluation of the run failed (raised in every episode, timed out, or killed
        its worker): nothing was learnt about the task."""
        return self.faults.jobs > 0 and self.faults.failed == self.faults.jobs


def _nan_safe(f: float, minimize: bool) -> float:
    return (math.inf if minimize else -math.inf) if math.isnan(f) else f


class _Run:
    """The state of one run; everything in :meth:`state` goes into a checkpoint."""

    def __init__(
        self, task: Task, cfg: EvolutionConfig, seed: int, skills: SkillSet,
        evaluator: Any, rundir: RunDir | None, progress: TextIO | None,
        trials: int, simplify_trials: int,
    ) -> None:
        self.task = task
        self.cfg = cfg
        self.seed = seed
        self.skills = skills
        self.evaluator = evaluator
        self.rundir = rundir
        self.progress = progress
        self._tty = bool(getattr(progress, "isatty", lambda: False)())
        self._last_line = -math.inf  # wall time of the last progress line (not a terminal)
        self.trials = trials
        self.simplify_trials = simplify_trials
        self.compiler = GenomeCompiler(task, skills)
        self.rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_BREED,)))
        self.generation = 0
        self.population: list[Genome] = []
        self.best: tuple[Genome, float, int] | None = None  # genome, fitness, generation
        self.history: list[GenerationRecord] = []
        self.cache: dict[tuple[Any, ...], tuple[float, int]] = {}
        self.evaluations = 0
        self.wall_before = 0.0
        self.next_uid = 0
        self.elite_fitness: dict[int, float] = {}
        self.first_error: str | None = None  # the run's first exception, summarised
        self.gen_faults = Faults()
        self.fault_totals = Faults()  # over the run so far, for the progress line
        self.t0 = time.perf_counter()

    # -- checkpoint ------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        return {
            "seed": self.seed,
            "config": self.cfg.to_dict(),
            "generation": self.generation,
            "population": self.population,
            "rng": self.rng.bit_generator.state,
            "best": self.best,
            "history": [r.to_dict() for r in self.history],
            "cache": self.cache,
            "evaluations": self.evaluations,
            "wall_time": self.wall(),
            "next_uid": self.next_uid,
            "elite_fitness": self.elite_fitness,
            "first_error": self.first_error,
        }

    def restore(self, st: Mapping[str, Any]) -> None:
        self.generation = st["generation"]
        self.population = st["population"]
        self.rng.bit_generator.state = st["rng"]
        self.best = st["best"]
        self.history = [GenerationRecord(**r) for r in st["history"]]
        self.cache = st["cache"]
        self.evaluations = st["evaluations"]
        self.wall_before = st["wall_time"]
        self.next_uid = st["next_uid"]
        self.elite_fitness = st["elite_fitness"]
        self.first_error = st.get("first_error")
        self.fault_totals = self.faults()
        self.t0 = time.perf_counter()

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
                total, count = self.cache.get(key, (0.0, 0))
                if math.isinf(f) or math.isinf(total):
                    total, count = f, 1
                else:
                    total, count = total + f * job.trials, count + job.trials
                self.cache[key] = (total, count)
                f = total / count
            for i in idx:
                fitness[i] = f
        return [float(f) for f in fitness if f is not None], episodes

    def breed(
        self, fitness: list[float], bred: Callable[[], None] | None = None
    ) -> Iterator[Genome]:
        """Algorithm 1's next generation, child by child; once all are born it becomes the
        population and ``bred`` is called (to save a checkpoint)."""
        cfg, rng, n = self.cfg, self.rng, len(self.population)
        sizes = [len(g) for g in self.population]
        order = sorted(range(n), key=lambda i: (*self.rank_key(fitness[i], sizes[i]), i))
        rank = [0] * n
        for r, i in enumerate(order):
            rank[i] = r
        nxt: list[Genome] = []
        self.elite_fitness = {}
        for i in order[:cfg.elitism]:
            e = self.population[i].copy()
            e.origin = {**e.origin, "elite": True}
            self.elite_fitness[e.origin["uid"]] = fitness[i]
            nxt.append(e)
            yield e

        def pick() -> Genome:
            cands = rng.integers(n, size=cfg.tournament)
            return self.population[min(cands, key=lambda c: rank[int(c)])]

        g = self.generation + 1
        while len(nxt) < cfg.population:
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
                parents = [parent.origin["uid"]]
                if "crossover" in ops:
                    parents.append(mate.origin["uid"])
                c.origin = {"uid": self.uid(), "born": g, "parents": parents, "ops": ops}
                nxt.append(c)
            yield from nxt[len(nxt) - 2:cfg.population]
        self.population = nxt[:cfg.population]
        self.generation = g
        if bred is not None:
            bred()

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
        self.history.append(rec)
        if self.rundir is not None:
            self.rundir.append_history(rec.to_dict())
            if improved:
                self.rundir.write_best(self.best_fsa(), self.task.registry, self.header())
        return rec

    def confirm(self) -> bool:
        """Re-run the best genome on ``confirm_trials`` fresh worlds; it stays the best (and
        the task solved) only if it reaches the target there too, else its fitness becomes
        that measured mean and evolution goes on."""
        assert self.best is not None
        g, _, gen = self.best
        trials = 1 if self.task.deterministic else self.cfg.confirm_trials
        job = Job.of(g, self.seed, (_CONFIRM, self.generation), trials)
        with Guard(self.cfg.eval_time_limit) as guard:
            mean, _, _ = evaluate_job(self.task, self.compiler, job, guard, False)
        self.evaluations += trials
        if self.task.solved(mean):
            return True
        self.best = (g, mean, gen)
        return False

    # -- export ----------------------------------------------------------------------------
    def best_fsa(self, simplified: dict[str, Any] | None = None) -> FSA:
        assert self.best is not None
        g, f, gen = self.best
        meta: dict[str, Any] = {
            "evolved": {
                "task": self.task.name,
                "task_settings": dict(self.task.settings),
                "fitness": f,
                "solved": self.task.solved(f),
                "found_in_generation": gen,
                "seed": self.seed,
                "lineage": dict(g.origin),
            }
        }
        if simplified:
            meta["simplified"] = simplified
        return self.compiler.fsa(g, name=f"{self.task.name}_evolved", meta=meta)

    def header(self) -> str:
        assert self.best is not None
        _, f, gen = self.best
        return (
            f"Evolved by skillcompose for task {self.task.name} (seed {self.seed}): fitness "
            f"{f:g} in generation {gen}.\nEdit freely: rename states, change parameters (in "
            "the skills' units), re-route outcomes.\nRun it with `skillcompose run FILE`, or "
            "evolve from it with `--seed-fsa FILE`."
        )

    def faults(self) -> Faults:
        """The run's faults so far, from its history."""
        total = Faults()
        for r in self.history:
            gen = Faults()
            for k, v in r.faults.items():
                if k in _FAULT_FIELDS:
                    setattr(gen, k, int(v))
            total.add(gen)
        total.first_error = self.first_error
        return total

    def show_progress(self, rec: GenerationRecord) -> None:
        if self.progress is None:
            return
        total = self.cfg.generations
        done = rec.generation + 1
        width = 24
        filled = int(width * min(done, total + 1) / (total + 1))
        per_gen = rec.wall_time / max(1, len(self.history))
        eta = per_gen * max(0, total - rec.generation)
        text = (
            f"[{'#' * filled}{'.' * (width - filled)}] gen {rec.generation}/{total} "
            f"best {rec.best:.4g} size {rec.best_size} {rec.evals_per_s:,.0f} evals/s "
            f"ETA {_hms(eta)}"
        )
        faults = self.fault_totals.describe()
        if faults:
            text += f" faults: {faults}"
        if self._tty:  # one line, redrawn in place
            self.progress.write(f"\r{text}   ")
        elif rec.wall_time - self._last_line >= 5.0:  # a log: a line every 5 s at most
            self._last_line = rec.wall_time
            self.progress.write(text + "\n")
        self.progress.flush()


_FAULT_FIELDS = frozenset(Faults().to_dict())


def check_fresh(
    task: Task, fsa: FSA, seed: int, trials: int, time_limit: float | None = None
) -> dict[str, Any]:
    """How ``fsa`` does on ``trials`` fresh episodes (worlds from ``SeedSequence(seed,
    spawn_key=(3,))``, never seen during evolution or simplification): the share that
    reach the task's target, the mean fitness, and the episodes that raised or ran past
    ``time_limit`` [s] (each scores worst)."""
    compiled = task.compile(fsa)
    scores: list[float] = []
    raised = timeouts = 0
    seq = np.random.SeedSequence(seed, spawn_key=(_FRESH,))
    with Guard(time_limit) as guard:
        for rng in trial_rngs(seq, trials):
            f, code = evaluate_episode(task, compiled, rng, guard)
            raised += code >> 2
            timeouts += code & TIMED_OUT
            scores.append(f)
    n = len(scores)
    return {
        "episodes": n,
        "success_rate": sum(map(task.solved, scores)) / n if n else 0.0,
        "mean_fitness": float(statistics.fmean(scores)) if n else math.nan,
        "raised": raised,
        "timeouts": timeouts,
        "seed": seed,
    }


def fresh_differs(task: Task, evolved: float, fresh: float) -> bool:
    """Whether the fitness on fresh episodes tells another story than the evolved one: the
    task counts one as solved and not the other, or they differ by more than 10 %."""
    if task.solved(evolved) != task.solved(fresh):
        return True
    if math.isinf(evolved) or math.isinf(fresh) or math.isnan(fresh):
        return evolved != fresh
    return abs(fresh - evolved) > 0.1 * max(abs(fresh), abs(evolved))


def _hms(s: float) -> str:
    s = int(s)
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


def evolve(
    task: Task,
    cfg: EvolutionConfig | None = None,
    seed: int | None = 0,
    workers: int | None = 1,
    backend: str = "serial",
    out_dir: str | os.PathLike[str] | None = None,
    seed_fsa: FSA | str | os.PathLike[str] | None = None,
    progress: bool | TextIO = False,
    *,
    resume: str | os.PathLike[str] | None = None,
    simplify_result: bool = True,
    simplify_trials: int = 200,
    check_trials: int = 200,
    on_generation: Callable[[GenerationRecord], None] | None = None,
) -> EvolutionResult:
    """Evolve an FSA for ``task`` (algorithm 1), stopping when solved or out of generations.

    - ``seed``: the run's seed (``None`` draws one, recorded in the result and files).
    - ``backend``: ``"serial"``, ``"process"`` (``workers`` processes, default all cores) or
      ``"ray"``; the result does not depend on it.
    - ``out_dir``: write the run directory (see :mod:`evolve.rundir`) as the run goes.
    - ``resume``: a run directory to continue from its last checkpoint (``task`` must be
      the same task; ``cfg`` and ``seed`` come from the checkpoint).
    - ``seed_fsa``: an FSA (or file) placed in the first population, the rest random.
    - ``simplify_result``: simplify the best FSA at the end with ``simplify_trials`` fresh
      trials (see :func:`evolve.simplify`).
    - ``check_trials``: fresh episodes on which the exported FSA is measured at the end
      (:func:`check_fresh`; ``result.fresh``, ``run.json``); 0 skips it. A deterministic
      task (``Task.deterministic``) uses one trial for evaluations, simplification and
      this check.
    - ``progress``: a live progress line on stderr (or on the given stream).
    """
    if backend not in BACKENDS:
        raise EvolutionError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    rundir: RunDir | None = None
    checkpoint: dict[str, Any] | None = None
    if resume is not None:
        rundir = RunDir(resume)
        checkpoint = rundir.load_checkpoint()
        cfg = EvolutionConfig.from_dict(checkpoint["config"])
        seed = checkpoint["seed"]
        info = rundir.load_run_info()
        if info.get("task") != task.name:
            raise CheckpointError(
                f"{rundir.path} is a run of task {info.get('task')!r}, not {task.name!r}"
            )
    cfg = cfg or EvolutionConfig()
    if seed is None:
        seed = int(np.random.SeedSequence().generate_state(2, np.uint64)[0] >> 1)
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise EvolutionError(f"seed must be a whole number >= 0, got {seed!r}")
    seed = int(seed)
    skills = SkillSet.from_task(task)
    trials = cfg.trials or task.trials
    if task.deterministic:  # every episode is the same: one says it all
        trials = 1
        simplify_trials = min(simplify_trials, 1)
        check_trials = min(check_trials, 1)
    stream: TextIO | None = sys.stderr if progress is True else (progress or None)
    if backend == "process" and workers is None:
        workers = os.cpu_count() or 1
    seed_genome: Genome | None = None
    if seed_fsa is not None and checkpoint is None:
        fsa = seed_fsa if isinstance(seed_fsa, FSA) else load_fsa(seed_fsa)
        seed_genome = Genome.from_fsa(fsa, skills, str(seed_fsa) if not isinstance(
            seed_fsa, FSA) else (fsa.path or ""))
    if out_dir is not None and rundir is None:
        rundir = RunDir(out_dir)
        rundir.create({
            "task": task.name,
            "task_module": task.ref.module if task.ref else None,
            "task_settings": dict(task.ref.settings) if task.ref else dict(task.settings),
            "seed": seed,
            "backend": backend,
            "workers": workers,
            "seed_fsa": str(seed_fsa) if seed_fsa is not None and not isinstance(
                seed_fsa, FSA) else None,
            "config": cfg.to_dict(),
        })
    limits = EvalLimits(cfg.eval_time_limit, cfg.worker_max_jobs, cfg.worker_max_growth_mb)
    evaluator = make_evaluator(backend, task, skills, workers, cfg.chunks_per_worker, limits)
    run = _Run(task, cfg, seed, skills, evaluator, rundir, stream, trials, simplify_trials)
    try:
        if checkpoint is not None:
            assert rundir is not None
            run.restore(checkpoint)
            rundir.rewrite_history([r.to_dict() for r in run.history])
        else:
            for i in range(cfg.population):
                g = initialize(skills, run.rng, cfg.initial_nodes, cfg.terminal_weight)
                if i == 0 and seed_genome is not None:
                    g = seed_genome.copy()
                g.origin = {**g.origin, "uid": run.uid(), "born": 0, "parents": [], "ops": [
                    "seed_fsa" if (i == 0 and seed_genome is not None) else "init"]}
                run.population.append(g)
        solved = run.best is not None and task.solved(run.best[1])
        last_plot = time.perf_counter()

        def bred() -> None:  # runs as the last child is born, while the pool evaluates
            nonlocal last_plot
            if rundir is not None and run.generation % cfg.checkpoint_every == 0:
                rundir.save_checkpoint(run.state())
                if time.perf_counter() - last_plot > _PLOT_EVERY_S:  # drawing is slow
                    rundir.plots([r.to_dict() for r in run.history], run.best_fsa())
                    last_plot = time.perf_counter()

        children: Iterator[Genome] | None = None
        while not solved and run.generation <= cfg.generations:
            t = time.perf_counter()
            fitness, episodes = run.evaluate(children)
            rec = run.record(fitness, episodes, time.perf_counter() - t)
            run.show_progress(rec)
            if on_generation is not None:
                on_generation(rec)
            assert run.best is not None
            solved = task.solved(run.best[1])
            if solved and cfg.confirm_trials:
                solved = run.confirm()
            if solved or run.generation >= cfg.generations:
                break
            children = run.breed(fitness, bred)
    finally:
        evaluator.close()
        if stream is not None:
            stream.write("\n")
            stream.flush()
    assert run.best is not None
    best_genome, best_f, _ = run.best
    evolved = run.best_fsa()
    best = evolved
    if simplify_result:
        best = simplify(task, evolved, seed=seed, trials=simplify_trials,
                        time_limit=cfg.eval_time_limit)
        best = best.replace(meta={**evolved.meta, **best.meta}, name=evolved.name)
    fresh: dict[str, Any] = {}
    if check_trials > 0:
        fresh = check_fresh(task, best, seed, check_trials, cfg.eval_time_limit)
        fresh["differs"] = fresh_differs(task, best_f, fresh["mean_fitness"])
    faults = run.faults()
    files: list[Path] = []
    if rundir is not None:
        rundir.save_checkpoint(run.state())
        rundir.write_best(evolved, task.registry, run.header(), rundir.best_evolved_yaml)
        rundir.write_best(best, task.registry, run.header())
        rundir.plots([r.to_dict() for r in run.history], best)
        rundir.update_run_info({"result": {
            "solved": task.solved(best_f),
            "best_fitness": best_f,
            "generations": run.generation,
            "evaluations": run.evaluations,
            "fresh": fresh,
            "faults": faults.to_dict(),
            "first_error": faults.first_error,
        }})
        files = [rundir.best_yaml, rundir.best_evolved_yaml, rundir.best_dot, rundir.best_png,
                 rundir.history, rundir.fitness_png, rundir.checkpoint, rundir.run_json]
    return EvolutionResult(
        best_fsa=best,
        best_fitness=best_f,
        solved=task.solved(best_f),
        generations=run.generation,
        evaluations=run.evaluations,
        wall_time=run.wall(),
        history=run.history,
        evolved_fsa=evolved,
        best_genome=best_genome,
        seed=seed,
        out_dir=rundir.path if rundir is not None else None,
        files=files,
        faults=faults,
        fresh=fresh,
    )
