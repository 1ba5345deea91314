"""Evaluating genomes: serially, in a local process pool, or on Ray.

An evaluation is a :class:`Job`: a genome, the seed of its worlds and a number of trials.
The seed comes from the run seed and the job's place in the run (generation, individual),
never from the worker, so a run gives the same fitnesses on any backend and any number of
workers. A skill that raises, a task whose setup or fitness raises, or a worker that dies
costs that evaluation (it scores the task's worst fitness), not the run.
"""

from __future__ import annotations

import contextlib
import ctypes
import math
import multiprocessing
import os
import pickle
import signal
import sys
import threading
import time
import traceback
from collections.abc import Iterable, Iterator, Sequence
from multiprocessing.connection import Connection, wait
from multiprocessing.reduction import ForkingPickler
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
    """Evaluates jobs, returning their fitnesses in order.

    ``jobs`` may be a list or any iterable, such as a generator that breeds the jobs as it
    goes: a pool starts evaluating the first ones while the rest are still being made.
    ``expected`` is how many jobs an iterable will give, if known (for chunk sizes).
    """

    workers: int

    def evaluate(self, jobs: Iterable[Job], expected: int | None = None) -> list[float]: ...

    def close(self) -> None: ...


class SerialEvaluator:
    """Evaluates in this process."""

    def __init__(self, task: Task, skills: SkillSet) -> None:
        self.task = task
        self.compiler = GenomeCompiler(task, skills)
        self.workers = 1

    def evaluate(self, jobs: Iterable[Job], expected: int | None = None) -> list[float]:
        # all jobs first, then all evaluations: interleaving them in one process measured
        # slower (about 10 %) (the two loops evict each other's code and data from the caches)
        jobs = list(jobs)
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


def _chunk_size(left: int, total: int, workers: int, streaming: bool) -> int:
    """How many jobs the next chunk takes. Jobs all at hand: guided scheduling, half of an
    even share of what is left down to a small floor, so chunks start large (few claims)
    and workers finish together. Jobs still being made: small even chunks, so workers start
    early and keep up with what the parent makes."""
    w = max(1, workers)
    floor = max(1, total // (32 * w))
    if streaming:
        return max(floor, math.ceil(total / (16 * w))) if total else 8
    return max(floor, math.ceil(left / (2 * w)))


def _pack(jobs: Sequence[Job]) -> bytes:
    return pickle.dumps([tuple(j) for j in jobs], protocol=pickle.HIGHEST_PROTOCOL)


def _run_packed(
    task: Task, compiler: GenomeCompiler, at: int, payload: bytes, results: Any
) -> None:
    for i, job in enumerate(pickle.loads(payload)):
        results[at + i] = evaluate_genome(task, compiler, Job._make(job))


def _die_with_parent(parent_pid: int, inherited: Sequence[int]) -> None:
    """Make this worker end when the process that started it ends, however it ends
    (``kill -9`` included), even in the middle of a skill that never returns.

    Linux: the kernel kills it (``PR_SET_PDEATHSIG``). Elsewhere a thread watches for the
    parent to go. Either way the worker also closes its copies of the parent's ends of the
    pipes (its own and those of the workers forked before it), so a worker waiting for a
    message sees the end of the file when the parent is gone.
    """
    if inherited:  # /dev/null over them: the numbers stay taken until their objects close
        null = os.open(os.devnull, os.O_RDWR)
        for fd in inherited:
            with contextlib.suppress(OSError):
                os.dup2(null, fd)
        os.close(null)
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL(None, use_errno=True)
            if libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0:
                if os.getppid() != parent_pid:  # the parent died before the call
                    os._exit(1)
                return

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


_PR_SET_PDEATHSIG = 1  # from <linux/prctl.h>


def _worker_main(
    conn: Connection, source: TaskRef | Task, terminals: tuple[str, ...], cpu: int | None,
    counter: Any, results: Any, parent_pid: int = 0, inherited: Sequence[int] = (),
) -> None:
    """A worker process: build the task, say so, then serve batches until told to stop.

    Every worker gets every message of a batch, in order: ``("batch", id)``, then chunks
    ``(k, position of its first job, packed jobs)`` as the parent makes them, then
    ``("end", number of chunks)``. A worker claims chunk numbers from the shared
    ``counter`` (reading messages until its chunk has come), writes each fitness into the
    shared ``results`` at its job's position as soon as it has it (so a worker that dies
    keeps what it finished), and answers ``id`` once it claims a number past the end.
    """
    if parent_pid:
        _die_with_parent(parent_pid, inherited)
    if cpu is not None:  # one worker per core: measured 1.2x -> 1.4x on 2 cores
        with contextlib.suppress(OSError, AttributeError):
            os.sched_setaffinity(0, {cpu})
    with contextlib.suppress(OSError, AttributeError):
        os.nice(10)
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
        batch = message[1]
        chunks: list[tuple[int, int, bytes]] = []
        ended = False
        while True:
            with lock:
                k = counter.value
                counter.value = k + 1
            while k >= len(chunks) and not ended:
                message = conn.recv()
                if message[0] == "end":
                    ended = True
                else:
                    chunks.append(message)
            if k >= len(chunks):
                break
            _, at, payload = chunks[k]
            _run_packed(task, compiler, at, payload, results)
        conn.send(batch)


class _Worker(NamedTuple):
    process: Any
    conn: Connection


class ProcessEvaluator:
    """A pool of worker processes, each holding the task built once.

    Each worker has its own pipe and, where the platform allows, its own core (round robin
    over the cores this process may use). The parent is out of the workers' loop: it sends
    every worker each chunk of jobs as soon as the chunk is packed, and the workers claim
    chunks from a shared counter and write fitnesses into shared memory, so no worker waits
    on the parent while work is there, the workers finish together, and the parent wakes
    once per worker and batch. Jobs given as a generator stream: the workers evaluate the
    first chunks while the parent still makes (breeds) the rest. A task loaded with
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
        # with fork, the worker inherits the parent's ends of all pipes: it closes them
        inherited = [parent.fileno(), *(w.conn.fileno() for w in self._pool
                                        if not w.conn.closed)]
        proc = self._ctx.Process(
            target=_worker_main,
            args=(child, self._source, self.terminals, cpu, self._counter, self._results,
                  os.getpid(), inherited if self._ctx.get_start_method() == "fork" else []),
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

    def _workers(self, capacity: int) -> list[_Worker]:
        if len(self._results) < capacity:  # shared memory is handed to workers as they start
            self.close()
            old = self._results
            self._results = self._ctx.RawArray("d", max(1024, 2 * capacity))
            self._results[:len(old)] = old[:]
        self._pool = [w for w in self._pool if w.process.is_alive()]
        while len(self._pool) < self.workers:
            self._pool.append(self._spawn())
        return self._pool

    def evaluate(self, jobs: Iterable[Job], expected: int | None = None) -> list[float]:
        streaming = not isinstance(jobs, Sequence)
        total = len(jobs) if isinstance(jobs, Sequence) else (expected or 0)
        source = iter(jobs)
        kept: list[Job] = []
        left: list[int] = []
        while True:  # a batch per size of shared memory: more than one only if it grows
            self._workers(max(total, len(kept) + 1))
            room = len(self._results)
            first = next(source, None)
            if first is None:
                break
            start = len(kept)
            kept.append(first)

            def chunks(start: int = start, room: int = room) -> Iterator[tuple[int, list[Job]]]:
                at, chunk = start, [kept[start]]
                size = _chunk_size(total - at, total, self.workers, streaming)
                while len(kept) < room:
                    job = next(source, None)
                    if job is None:
                        break
                    kept.append(job)
                    chunk.append(job)
                    if len(chunk) >= size:
                        yield at, chunk
                        at, chunk = len(kept), []
                        size = _chunk_size(total - at, total, self.workers, streaming)
                if chunk:
                    yield at, chunk

            left += self._run_batch(chunks())
            if len(kept) < room:  # the jobs ran out, not the room
                break
        if left:  # what a dead worker did not finish, each job on its own
            left = self._run_batch(iter([(p, [kept[p]]) for p in left]))
        out: list[float] = self._results[:len(kept)]
        for p in left:  # these killed their worker by themselves
            out[p] = self.task.worst
        self.lost += len(left)
        return out

    def _run_batch(self, chunks: Iterator[tuple[int, list[Job]]]) -> list[int]:
        """Run the (position, jobs) chunks as one batch, sending each to every worker as it
        comes; the positions of the jobs no worker finished."""
        results = self._results
        self._batch += 1
        with self._counter.get_lock():
            self._counter.value = 0
        # each message pickled once for all workers, and kept for one that joins half-way
        sent: list[memoryview] = [ForkingPickler.dumps(("batch", self._batch))]
        active: dict[Connection, _Worker] = {}
        spans: list[tuple[int, int]] = []
        try:
            for worker in list(self._pool):
                worker = self._join(worker, sent)
                active[worker.conn] = worker
            for k, (at, chunk) in enumerate(chunks):
                results[at:at + len(chunk)] = [math.nan] * len(chunk)
                spans.append((at, len(chunk)))
                self._broadcast((k, at, _pack(chunk)), sent, active)
            self._broadcast(("end", len(spans)), sent, active)
            while active:
                for ready in wait(list(active)):
                    conn = cast(Connection, ready)
                    worker = active.pop(conn)
                    try:
                        answer = conn.recv()
                    except (EOFError, OSError):  # it died: a fresh one joins the batch
                        fresh = self._join(self._replace(worker), sent)
                        active[fresh.conn] = fresh
                        continue
                    if answer != self._batch:  # pragma: no cover - a protocol error
                        raise EvolutionError(f"worker answered batch {answer}, not {self._batch}")
        except BaseException:  # interrupted: no worker may be left half-way through a batch
            self._terminate()
            raise
        return [p for at, n in spans for p in range(at, at + n) if math.isnan(results[p])]

    def _broadcast(
        self, message: Any, sent: list[memoryview], active: dict[Connection, _Worker]
    ) -> None:
        """Send ``message`` to every worker of the batch; one that has died is replaced by a
        fresh one that gets the whole batch so far."""
        data = ForkingPickler.dumps(message)
        sent.append(data)
        for conn, worker in list(active.items()):
            if not self._send(worker, data):
                del active[conn]
                fresh = self._join(self._replace(worker), sent)
                active[fresh.conn] = fresh

    def _join(self, worker: _Worker, sent: list[memoryview]) -> _Worker:
        """Have ``worker`` (or a fresh one, if it dies) join the running batch: send it every
        message of the batch so far."""
        while not all(self._send(worker, m) for m in sent):
            worker = self._replace(worker)
        return worker

    @staticmethod
    def _send(worker: _Worker, data: memoryview) -> bool:
        try:
            worker.conn.send_bytes(data)
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

    def evaluate(self, jobs: Iterable[Job], expected: int | None = None) -> list[float]:
        jobs = list(jobs)
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
