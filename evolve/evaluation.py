"""Evaluating genomes: serially, in a local process pool, or on Ray.

An evaluation is a :class:`Job`: a genome, the seed of its worlds and a number of trials.
The seed comes from the run seed and the job's place in the run (generation, individual),
never from the worker, so a run gives the same fitnesses on any backend and any number of
workers. A skill that raises, a task whose setup or fitness raises, or a worker that dies
costs that evaluation (it scores the task's worst fitness), not the run.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import os
from collections.abc import Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, NamedTuple, Protocol

import numpy as np

from skillcompose.executor import trial_rngs
from skillcompose.task import Task, TaskRef

from .errors import EvolutionError
from .genome import Genome, GenomeCompiler, SkillSet

__all__ = [
    "BACKENDS",
    "Evaluator",
    "Job",
    "ProcessEvaluator",
    "RayEvaluator",
    "SerialEvaluator",
    "evaluate_genome",
    "make_evaluator",
]

BACKENDS = ("serial", "process", "ray")


class Job(NamedTuple):
    """Evaluate a genome on ``trials`` worlds drawn from ``SeedSequence(seed, spawn_key)``.

    ``genome`` is :meth:`Genome.encode`'s compact form, cheap to send to a worker.
    """

    genome: tuple[Any, ...]
    seed: int
    spawn_key: tuple[int, ...]
    trials: int

    @classmethod
    def of(cls, genome: Genome, seed: int, spawn_key: tuple[int, ...], trials: int) -> Job:
        return cls(genome.encode(), seed, spawn_key, trials)


def evaluate_genome(task: Task, compiler: GenomeCompiler, job: Job) -> float:
    """Mean fitness of one job; a failure of any kind scores the task's worst fitness."""
    try:
        compiled = compiler.compile(Genome.decode(job.genome))
    except Exception:
        return task.worst
    seq = np.random.SeedSequence(job.seed, spawn_key=job.spawn_key)
    total = 0.0
    for rng in trial_rngs(seq, job.trials):
        try:
            bb = task.setup(rng)
            res = compiled.run(bb, rng)
            f = task.score(res, bb)
        except Exception:
            f = task.worst
        if math.isnan(f):
            f = task.worst
        total += f
    return total / job.trials


class Evaluator(Protocol):
    """Evaluates jobs, returning their fitnesses in order."""

    workers: int

    def evaluate(self, jobs: Sequence[Job]) -> list[float]: ...

    def close(self) -> None: ...


class SerialEvaluator:
    """Evaluates in this process."""

    def __init__(self, task: Task, skills: SkillSet) -> None:
        self.task = task
        self.compiler = GenomeCompiler(task, skills)
        self.workers = 1

    def evaluate(self, jobs: Sequence[Job]) -> list[float]:
        return [evaluate_genome(self.task, self.compiler, j) for j in jobs]

    def close(self) -> None:
        pass


# -- process pool ------------------------------------------------------------------------
_WORKER: tuple[Task, GenomeCompiler] | None = None


def _init_worker(source: TaskRef | Task, terminals: tuple[str, ...]) -> None:
    """Build the task once per worker process, from its module and settings."""
    global _WORKER
    task = source.build() if isinstance(source, TaskRef) else source
    _WORKER = (task, GenomeCompiler(task, SkillSet.from_task(task, terminals)))


def _run_chunk(jobs: list[Job]) -> list[float]:
    if _WORKER is None:  # pragma: no cover - the initializer always ran
        raise EvolutionError("evaluation worker was not initialised")
    task, compiler = _WORKER
    return [evaluate_genome(task, compiler, j) for j in jobs]


def _chunks(jobs: Sequence[Job], n: int) -> list[list[Job]]:
    n = max(1, min(n, len(jobs)))
    size = math.ceil(len(jobs) / n)
    return [list(jobs[i:i + size]) for i in range(0, len(jobs), size)]


class ProcessEvaluator:
    """A local pool of worker processes, each holding the task built once.

    Jobs go out in ``workers * chunks_per_worker`` chunks per call to amortise the
    inter-process traffic. A task loaded with :func:`~skillcompose.task.load_task` is rebuilt
    in each worker from its module and settings; a task built in Python (no ``ref``) is
    handed to forked workers as it is.
    """

    def __init__(
        self, task: Task, skills: SkillSet, workers: int | None = None, chunks_per_worker: int = 4
    ) -> None:
        self.task = task
        self.workers = workers or os.cpu_count() or 1
        self.chunks_per_worker = chunks_per_worker
        self.terminals = skills.terminals
        methods = multiprocessing.get_all_start_methods()
        if task.ref is None and "fork" not in methods:
            raise EvolutionError(
                f"task {task.name} was built in Python, and this platform cannot fork: "
                "load it with skillcompose.task.load_task(module, **settings) so worker "
                "processes can rebuild it"
            )
        self._ctx = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
        self._source: TaskRef | Task = task.ref if task.ref is not None else task
        self._pool: ProcessPoolExecutor | None = None
        self.lost = 0  # evaluations lost to dead workers

    def _get_pool(self) -> ProcessPoolExecutor:
        if self._pool is None:
            self._pool = ProcessPoolExecutor(
                max_workers=self.workers, mp_context=self._ctx,
                initializer=_init_worker, initargs=(self._source, self.terminals),
            )
        return self._pool

    def evaluate(self, jobs: Sequence[Job]) -> list[float]:
        if not jobs:
            return []
        chunks = _chunks(jobs, self.workers * self.chunks_per_worker)
        pool = self._get_pool()
        futures: list[Future[list[float]] | None] = []
        for c in chunks:
            try:
                futures.append(pool.submit(_run_chunk, c))
            except BrokenProcessPool:  # a worker died while we were still submitting
                futures.append(None)
        out: list[float] = []
        broken = False
        for chunk, fut in zip(chunks, futures, strict=True):
            try:
                if fut is None:
                    raise BrokenProcessPool("the pool broke before this chunk was submitted")
                out.extend(fut.result())
            except BrokenProcessPool:
                broken = True
                self.lost += len(chunk)
                out.extend([self.task.worst] * len(chunk))
        if broken:  # a worker died: start a fresh pool for the next call
            self.close()
        return out

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


# -- Ray -----------------------------------------------------------------------------------
class RayEvaluator:
    """Ray actors, each holding the task built once from its module and settings.

    Needs the optional extra: ``pip install skillcompose[ray]``. Connects to a running
    cluster when ``RAY_ADDRESS`` is set, else starts a local one.
    """

    def __init__(
        self, task: Task, skills: SkillSet, workers: int | None = None, chunks_per_worker: int = 4
    ) -> None:
        try:
            import ray
        except ImportError as exc:
            raise EvolutionError(
                "backend 'ray' needs Ray: pip install skillcompose[ray] "
                "(or use --backend process)"
            ) from exc
        if task.ref is None:
            raise EvolutionError(
                f"backend 'ray' rebuilds task {task.name} in each actor from its module: "
                "load the task with skillcompose.task.load_task(module, **settings)"
            )
        self._ray: Any = ray
        if not ray.is_initialized():
            ray.init(ignore_reinit_error=True, log_to_driver=False)
        self.task = task
        self.workers = workers or int(ray.available_resources().get("CPU", 1)) or 1
        self.chunks_per_worker = chunks_per_worker
        self._actor_cls = ray.remote(_RayWorker)
        self._ref = task.ref
        self._terminals = skills.terminals
        self._actors = [self._new_actor() for _ in range(self.workers)]
        self.lost = 0

    def _new_actor(self) -> Any:
        return self._actor_cls.remote(self._ref, self._terminals)

    def evaluate(self, jobs: Sequence[Job]) -> list[float]:
        if not jobs:
            return []
        chunks = _chunks(jobs, self.workers * self.chunks_per_worker)
        refs = [
            (k % len(self._actors), self._actors[k % len(self._actors)].run.remote(c))
            for k, c in enumerate(chunks)
        ]
        out: list[float] = []
        for chunk, (a, ref) in zip(chunks, refs, strict=True):
            try:
                out.extend(self._ray.get(ref))
            except Exception:  # the actor died (RayActorError) or the task raised
                self.lost += len(chunk)
                out.extend([self.task.worst] * len(chunk))
                self._actors[a] = self._new_actor()
        return out

    def close(self) -> None:
        for a in self._actors:
            with contextlib.suppress(Exception):  # an actor that died already
                self._ray.kill(a)
        self._actors = []


class _RayWorker:
    def __init__(self, ref: TaskRef, terminals: tuple[str, ...]) -> None:
        self.task = ref.build()
        self.compiler = GenomeCompiler(self.task, SkillSet.from_task(self.task, terminals))

    def run(self, jobs: list[Job]) -> list[float]:
        return [evaluate_genome(self.task, self.compiler, j) for j in jobs]


def make_evaluator(
    backend: str, task: Task, skills: SkillSet, workers: int | None, chunks_per_worker: int = 4
) -> SerialEvaluator | ProcessEvaluator | RayEvaluator:
    if backend == "serial":
        return SerialEvaluator(task, skills)
    if backend == "process":
        return ProcessEvaluator(task, skills, workers, chunks_per_worker)
    if backend == "ray":
        return RayEvaluator(task, skills, workers, chunks_per_worker)
    raise EvolutionError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
