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
import traceback
from collections import deque
from collections.abc import Sequence
from multiprocessing.connection import Connection, wait
from typing import Any, NamedTuple, Protocol, cast

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


def _guided_chunks(jobs: Sequence[Job], workers: int) -> list[list[Job]]:
    """Chunks that shrink as the work runs out (guided scheduling): each takes half of an
    even share of what is left, down to a small floor, so workers start with large chunks
    (few messages) and finish together (no worker waits long on another's last chunk)."""
    floor = max(1, len(jobs) // (16 * max(1, workers)))
    out: list[list[Job]] = []
    i = 0
    while i < len(jobs):
        size = max(floor, math.ceil((len(jobs) - i) / (2 * max(1, workers))))
        out.append(list(jobs[i:i + size]))
        i += size
    return out


def _worker_main(
    conn: Connection, source: TaskRef | Task, terminals: tuple[str, ...], cpu: int | None
) -> None:
    """A worker process: build the task, say so, then evaluate chunks until told to stop."""
    if cpu is not None:  # one worker per core: measured 1.2x -> 1.4x on 2 cores
        with contextlib.suppress(OSError, AttributeError):
            os.sched_setaffinity(0, {cpu})
    try:
        _init_worker(source, terminals)
    except BaseException:
        conn.send(("failed", traceback.format_exc()))
        return
    conn.send(("ready", None))
    while True:
        try:
            chunk = conn.recv()
        except (EOFError, OSError):
            return
        if chunk is None:
            return
        conn.send(_run_chunk(chunk))


class _Worker(NamedTuple):
    process: Any
    conn: Connection


class ProcessEvaluator:
    """A pool of worker processes, each holding the task built once.

    Each worker has its own pipe and, where the platform allows, its own core (round robin
    over the cores this process may use); the parent hands out chunks that shrink as the work
    runs out (guided scheduling), the next one to whichever worker answers first, so traffic
    is one message each way per chunk and the workers finish together. A task loaded with
    :func:`~skillcompose.task.load_task` is rebuilt in each worker from its module and
    settings; a task built in Python (no ``ref``) is handed to forked workers as it is.

    A worker that dies (a simulator that segfaults, ``os._exit``) is replaced, and the jobs
    of its chunk are run again one by one in fresh workers: only a job that kills its worker
    by itself scores the task's worst fitness, so results never depend on how jobs were
    chunked or on how many workers there are. ``lost`` counts such jobs.
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
        self._ctx: Any = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
        self._source: TaskRef | Task = task.ref if task.ref is not None else task
        self._pool: list[_Worker] = []
        self.lost = 0  # jobs that killed their worker process
        try:
            self._cpus: list[int] = sorted(os.sched_getaffinity(0))
        except AttributeError:  # pragma: no cover - platforms without CPU affinity
            self._cpus = []
        self._spawned = 0

    def _spawn(self) -> _Worker:
        parent, child = self._ctx.Pipe()
        cpu = self._cpus[self._spawned % len(self._cpus)] if self._cpus else None
        self._spawned += 1
        proc = self._ctx.Process(
            target=_worker_main, args=(child, self._source, self.terminals, cpu), daemon=True
        )
        proc.start()
        child.close()
        try:
            status, detail = parent.recv()
        except (EOFError, OSError):
            status, detail = "failed", f"the worker exited with code {proc.exitcode}"
        if status != "ready":
            proc.join(timeout=5)
            raise EvolutionError(
                f"an evaluation worker could not build task {self.task.name}:\n{detail}"
            )
        return _Worker(proc, parent)

    def _workers(self) -> list[_Worker]:
        self._pool = [w for w in self._pool if w.process.is_alive()]
        while len(self._pool) < self.workers:
            self._pool.append(self._spawn())
        return self._pool

    def evaluate(self, jobs: Sequence[Job]) -> list[float]:
        if not jobs:
            return []
        chunks = _guided_chunks(jobs, self.workers)
        starts = [0]
        for c in chunks:
            starts.append(starts[-1] + len(c))
        out: list[float] = [math.nan] * len(jobs)
        # (position of the first job, jobs, run alone?) in the order they are handed out
        todo: deque[tuple[int, list[Job], bool]] = deque(
            (starts[k], c, False) for k, c in enumerate(chunks)
        )
        idle = deque(self._workers())
        busy: dict[Connection, tuple[_Worker, tuple[int, list[Job], bool]]] = {}
        while todo or busy:
            while todo and idle:
                worker = idle.popleft()
                item = todo.popleft()
                try:
                    worker.conn.send(item[1])
                except (BrokenPipeError, OSError):  # it died between two chunks
                    todo.appendleft(item)
                    self._discard(worker)
                    idle.append(self._replace(worker))
                    continue
                busy[worker.conn] = (worker, item)
            for ready in wait(list(busy)):
                conn = cast(Connection, ready)
                worker, (at, chunk, alone) = busy.pop(conn)
                try:
                    values = conn.recv()
                except (EOFError, OSError):  # the worker died running this chunk
                    self._discard(worker)
                    idle.append(self._replace(worker))
                    if alone:
                        out[at] = self.task.worst
                        self.lost += 1
                    else:  # find the job that kills: run each one on its own
                        todo.extendleft(
                            (at + i, [job], True) for i, job in reversed(list(enumerate(chunk)))
                        )
                    continue
                out[at:at + len(values)] = values
                idle.append(worker)
        return out

    def _replace(self, dead: _Worker) -> _Worker:
        fresh = self._spawn()
        self._pool = [fresh if w is dead else w for w in self._pool]
        return fresh

    @staticmethod
    def _discard(worker: _Worker) -> None:
        with contextlib.suppress(Exception):
            worker.conn.close()
        worker.process.join(timeout=5)

    def close(self) -> None:
        for w in self._pool:
            with contextlib.suppress(Exception):
                w.conn.send(None)
        for w in self._pool:
            w.process.join(timeout=5)
            if w.process.is_alive():  # pragma: no cover - a worker stuck in a skill
                w.process.terminate()
                w.process.join(timeout=5)
            with contextlib.suppress(Exception):
                w.conn.close()
        self._pool = []


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
