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
import pickle
import traceback
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


def _chunks(jobs: Sequence[Job], n: int) -> list[list[Job]]:
    n = max(1, min(n, len(jobs)))
    size = math.ceil(len(jobs) / n)
    return [list(jobs[i:i + size]) for i in range(0, len(jobs), size)]


def _guided_chunks(jobs: Sequence[Job], workers: int) -> list[list[Job]]:
    """Chunks that shrink as the work runs out (guided scheduling): each takes half of an
    even share of what is left, down to a small floor, so workers start with large chunks
    (few claims) and finish together (no worker waits long on another's last chunk)."""
    floor = max(1, len(jobs) // (32 * max(1, workers)))
    out: list[list[Job]] = []
    i = 0
    while i < len(jobs):
        size = max(floor, math.ceil((len(jobs) - i) / (2 * max(1, workers))))
        out.append(list(jobs[i:i + size]))
        i += size
    return out


def _pack(jobs: Sequence[Job]) -> bytes:
    return pickle.dumps([tuple(j) for j in jobs], protocol=pickle.HIGHEST_PROTOCOL)


def _run_packed(
    task: Task, compiler: GenomeCompiler, at: int, payload: bytes, results: Any
) -> None:
    for i, job in enumerate(pickle.loads(payload)):
        results[at + i] = evaluate_genome(task, compiler, Job._make(job))


def _worker_main(
    conn: Connection, source: TaskRef | Task, terminals: tuple[str, ...], cpu: int | None,
    counter: Any, results: Any,
) -> None:
    """A worker process: build the task, say so, then serve batches until told to stop.

    A batch comes in two messages. First ``(batch, at, jobs)``: this worker's own first
    chunk, sent as soon as it is packed so the worker starts at once (``jobs`` is None for a
    worker that has none). Then ``chunks``, every chunk of the batch as (position of its
    first job, packed jobs), which arrives while the first one runs. The worker then claims
    chunk after chunk from the shared ``counter``, writes each fitness into the shared
    ``results`` at its job's position as soon as it has it (so a worker that dies keeps what
    it finished), and answers ``batch`` once no chunk is left.
    """
    if cpu is not None:  # one worker per core: measured 1.2x -> 1.4x on 2 cores
        with contextlib.suppress(OSError, AttributeError):
            os.sched_setaffinity(0, {cpu})
    try:
        _init_worker(source, terminals)
    except BaseException:
        conn.send(("failed", traceback.format_exc()))
        return
    if _WORKER is None:  # pragma: no cover - the initializer always sets it
        return
    task, compiler = _WORKER
    conn.send(("ready", None))
    lock = counter.get_lock()
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            return
        if message is None:
            return
        batch, at, payload = message
        if payload is not None:
            _run_packed(task, compiler, at, payload, results)
        chunks = conn.recv()
        while True:
            with lock:
                k = counter.value
                counter.value = k + 1
            if k >= len(chunks):
                break
            at, payload = chunks[k]
            _run_packed(task, compiler, at, payload, results)
        conn.send(batch)


class _Worker(NamedTuple):
    process: Any
    conn: Connection


class ProcessEvaluator:
    """A pool of worker processes, each holding the task built once.

    Each worker has its own pipe and, where the platform allows, its own core (round robin
    over the cores this process may use). The parent is out of the loop while a batch runs:
    it sends every worker the whole batch at once, in chunks that shrink as the work runs out
    (guided scheduling), and each worker starts on a chunk of its own, then claims the next
    free chunk from a shared counter and writes each fitness into shared memory. So a worker
    never waits on the parent, the workers finish together, and the only traffic is one
    message each way per worker and batch. A task loaded with
    :func:`~skillcompose.task.load_task` is rebuilt in each worker from its module and
    settings; a task built in Python (no ``ref``) is handed to forked workers as it is.

    A worker that dies (a simulator that segfaults, ``os._exit``) is replaced at once and the
    batch goes on; the jobs it had not finished are run again one by one: only a job that
    kills its worker by itself scores the task's worst fitness, so results never depend on
    how jobs were chunked or on how many workers there are. ``lost`` counts such jobs.
    """

    def __init__(
        self, task: Task, skills: SkillSet, workers: int | None = None, chunks_per_worker: int = 4
    ) -> None:
        self.task = task
        self.workers = workers or os.cpu_count() or 1
        self.chunks_per_worker = chunks_per_worker  # kept for the API; chunks are guided
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
        self._batch = 0
        self._counter: Any = self._ctx.Value("q", 0)
        self._results: Any = self._ctx.RawArray("d", 0)

    def _spawn(self) -> _Worker:
        parent, child = self._ctx.Pipe()
        cpu = self._cpus[self._spawned % len(self._cpus)] if self._cpus else None
        self._spawned += 1
        proc = self._ctx.Process(
            target=_worker_main,
            args=(child, self._source, self.terminals, cpu, self._counter, self._results),
            daemon=True,
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

    def _workers(self, jobs: int) -> list[_Worker]:
        if len(self._results) < jobs:  # shared memory is handed to workers when they start
            self.close()
            self._results = self._ctx.RawArray("d", max(1024, 2 * jobs))
        self._pool = [w for w in self._pool if w.process.is_alive()]
        while len(self._pool) < self.workers:
            self._pool.append(self._spawn())
        return self._pool

    def evaluate(self, jobs: Sequence[Job]) -> list[float]:
        if not jobs:
            return []
        chunks, at = [], 0
        for chunk in _guided_chunks(jobs, self.workers):
            chunks.append((at, chunk))
            at += len(chunk)
        left = self._run_batch(chunks)
        if left:  # what a dead worker did not finish, each job on its own
            left = self._run_batch([(p, [jobs[p]]) for p in left])
        out: list[float] = self._results[:len(jobs)]
        for p in left:  # these killed their worker by themselves
            out[p] = self.task.worst
        self.lost += len(left)
        return out

    def _run_batch(self, chunks: list[tuple[int, list[Job]]]) -> list[int]:
        """Run one batch of (position, jobs) chunks; the positions no worker finished."""
        pool = self._workers(max(at + len(c) for at, c in chunks))
        results = self._results
        for at, c in chunks:
            results[at:at + len(c)] = [math.nan] * len(c)
        self._batch += 1
        firsts = min(len(pool), len(chunks))  # chunk k < firsts is worker k's own
        with self._counter.get_lock():
            self._counter.value = firsts
        waiting: dict[Connection, _Worker] = {}
        packed: list[tuple[int, bytes]] = []
        try:
            started: list[_Worker] = []
            for k, worker in enumerate(list(pool)):
                if k < firsts:
                    packed.append((chunks[k][0], _pack(chunks[k][1])))
                first = (self._batch, *packed[k]) if k < firsts else (self._batch, 0, None)
                while not self._send(worker, first):  # it died between two batches
                    worker = self._replace(worker)
                started.append(worker)
            packed += [(at, _pack(c)) for at, c in chunks[firsts:]]
            for worker in started:
                if not self._send(worker, packed):  # it died on its own chunk already
                    worker = self._join(self._replace(worker), packed)
                waiting[worker.conn] = worker
            while waiting:
                for ready in wait(list(waiting)):
                    conn = cast(Connection, ready)
                    worker = waiting.pop(conn)
                    try:
                        answer = conn.recv()
                    except (EOFError, OSError):  # it died: a fresh one joins the batch
                        fresh = self._join(self._replace(worker), packed)
                        waiting[fresh.conn] = fresh
                        continue
                    if answer != self._batch:  # pragma: no cover - a protocol error
                        raise EvolutionError(f"worker answered batch {answer}, not {self._batch}")
        except BaseException:  # interrupted: no worker may be left half-way through a batch
            self._terminate()
            raise
        return [p for at, c in chunks for p in range(at, at + len(c)) if math.isnan(results[p])]

    def _join(self, worker: _Worker, packed: list[tuple[int, bytes]]) -> _Worker:
        """Have ``worker`` (or a fresh one, if it dies) join the running batch: it has no
        chunk of its own and only claims."""
        while not (self._send(worker, (self._batch, 0, None)) and self._send(worker, packed)):
            worker = self._replace(worker)
        return worker

    @staticmethod
    def _send(worker: _Worker, message: Any) -> bool:
        try:
            worker.conn.send(message)
            return True
        except (BrokenPipeError, OSError):
            return False

    def _replace(self, dead: _Worker) -> _Worker:
        self._discard(dead)
        fresh = self._spawn()
        self._pool = [fresh if w is dead else w for w in self._pool]
        return fresh

    @staticmethod
    def _discard(worker: _Worker) -> None:
        with contextlib.suppress(Exception):
            worker.conn.close()
        worker.process.join(timeout=5)

    def _terminate(self) -> None:
        for w in self._pool:
            w.process.terminate()
        for w in self._pool:
            self._discard(w)
        self._pool = []

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
