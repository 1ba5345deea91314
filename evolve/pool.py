"""The process pool: :class:`ProcessEvaluator` and its transport.

Worker processes each build the task once; the parent sends every worker each chunk of
jobs, the workers claim chunks from a shared counter and write fitnesses and fault codes
into shared memory (:class:`_Shared`), and a worker ends with the process that started it,
however that ends (:func:`_die_with_parent`: the kernel's parent-death signal on Linux,
a watching thread elsewhere).
"""

from __future__ import annotations

import contextlib
import ctypes
import math
import multiprocessing
import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Iterable, Iterator, Sequence
from multiprocessing.connection import Connection, wait
from multiprocessing.reduction import ForkingPickler
from typing import Any, NamedTuple, cast

from skillcompose.task import Task, TaskRef

from .errors import EvolutionError
from .evaluation import (
    LOST,
    TIMED_OUT,
    EvalLimits,
    Faults,
    Guard,
    Job,
    _pack,
    _Recycler,
    _unpack,
    evaluate_job,
)
from .genome import GenomeCompiler, SkillSet

__all__ = ["ProcessEvaluator"]

_RECYCLE = "recycle"


def _init_worker(
    source: TaskRef | Task, shape: tuple[tuple[str, ...], bool]
) -> tuple[Task, GenomeCompiler]:
    """The task and its genome compiler, built once per worker process from the task's
    module and settings, and held by the worker's loop (no module global)."""
    task = source.build() if isinstance(source, TaskRef) else source
    return task, GenomeCompiler(task, SkillSet.from_task(task, *shape))


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


class _Shared(NamedTuple):
    """Shared memory of a pool: per job position its fitness and fault code; per worker
    slot the position of the job it runs (-1: none) and when that job started
    (``time.monotonic``, the same clock in every process)."""

    results: Any
    codes: Any
    running: Any
    since: Any


def _run_packed(
    task: Task, compiler: GenomeCompiler, at: int, payload: bytes, shared: _Shared, slot: int,
    guard: Guard, first: list[tuple[int, str]],
) -> int:
    """Run a chunk, writing each fitness and fault code as soon as it is known; note the
    first exception (``first``: empty until one is found). Returns the chunk's length."""
    results, codes, running, since = shared
    jobs = _unpack(payload)
    for i, job in enumerate(jobs):
        since[slot] = time.monotonic()
        running[slot] = at + i
        f, code, error = evaluate_job(task, compiler, job, guard, not first)
        results[at + i] = f
        codes[at + i] = code
        running[slot] = -1
        if error is not None and not first:
            first.append((at + i, error))
    return len(jobs)


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
    conn: Connection, source: TaskRef | Task, shape: tuple[tuple[str, ...], bool],
    cpu: int | None,
    counter: Any, shared: _Shared, slot: int, limits: EvalLimits, parent_pid: int = 0,
    inherited: Sequence[int] = (), nice: int = 0,
) -> None:
    """A worker process: build the task, say so, then serve batches until told to stop.

    Every worker gets every message of a batch, in order: ``("batch", id)``, then chunks
    ``(k, position of its first job, packed jobs)`` as the parent makes them, then
    ``("end", number of chunks)``. A worker claims chunk numbers from the shared
    ``counter`` (reading messages until its chunk has come), writes each fitness and fault
    code into ``shared`` at its job's position as soon as it has it (so a worker that dies
    keeps what it finished), and answers ``(id, first exception)`` once it claims a number
    past the end. A worker that has served its ``limits`` answers ``"recycle"`` between two
    chunks instead, and exits: the parent puts a fresh one in its place.
    """
    # Ctrl-C reaches the whole process group: the parent answers it (and ends its workers);
    # a worker that took it too would print its own traceback before the parent's one line
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if parent_pid:
        _die_with_parent(parent_pid, inherited)
    if cpu is not None:
        with contextlib.suppress(OSError, AttributeError):
            os.sched_setaffinity(0, {cpu})
    if nice:
        with contextlib.suppress(OSError, AttributeError):
            os.nice(nice)
    try:
        task, compiler = _init_worker(source, shape)
    except BaseException:
        conn.send(("failed", traceback.format_exc()))
        return
    guard = Guard(limits.time_limit).install()
    recycler = _Recycler(limits)
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
        first: list[tuple[int, str]] = []
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
            done = _run_packed(task, compiler, at, payload, shared, slot, guard, first)
            if recycler.worn(done):
                conn.send((_RECYCLE, first[0] if first else None))
                return
        conn.send((batch, first[0] if first else None))


class _Worker(NamedTuple):
    process: Any
    conn: Connection
    slot: int


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

    With a wall-clock limit, each worker stops its own evaluations at the limit; a worker
    whose job runs past it anyway (stuck where signals cannot reach) is killed by the
    parent, that job scores worst as a time-out, and the rest go on as after a death.
    """

    def __init__(
        self, task: Task, skills: SkillSet, workers: int | None = None,
        limits: EvalLimits | None = None, pin: bool = True, nice: int = 0,
    ) -> None:
        self.task = task
        self.workers = workers or os.cpu_count() or 1
        self.shape = skills.shape
        self.limits = limits or EvalLimits()
        self.pin = pin
        self.nice = nice
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
        self.lost = 0  # jobs that killed their worker process, over the evaluator's life
        self.faults = Faults()
        try:
            self._cpus: list[int] = sorted(os.sched_getaffinity(0))
        except AttributeError:  # pragma: no cover - platforms without CPU affinity
            self._cpus = []
        self._spawned = 0
        self._batch = 0
        self._counter: Any = self._ctx.Value("q", 0)
        self._shared = self._allocate(0)
        self._killed: set[int] = set()  # pids the parent killed for running over time
        self._dead_since_check = False  # a worker died since the counter's lock was checked
        self._errors: list[tuple[int, str]] = []
        self._deaths = 0
        self._recycled = 0

    def _allocate(self, capacity: int) -> _Shared:
        slots = self.workers
        running = self._ctx.RawArray("q", slots)
        running[:] = [-1] * slots
        return _Shared(self._ctx.RawArray("d", capacity), self._ctx.RawArray("q", capacity),
                       running, self._ctx.RawArray("d", slots))

    def _spawn(self, slot: int) -> _Worker:
        parent, child = self._ctx.Pipe()
        cpu = self._cpus[self._spawned % len(self._cpus)] if self._cpus and self.pin else None
        self._spawned += 1
        self._shared.running[slot] = -1
        # with fork, the worker inherits the parent's ends of all pipes: it closes them
        inherited = [parent.fileno(), *(w.conn.fileno() for w in self._pool
                                        if not w.conn.closed)]
        proc = self._ctx.Process(
            target=_worker_main,
            args=(child, self._source, self.shape, cpu, self._counter, self._shared,
                  slot, self.limits, os.getpid(),
                  inherited if self._ctx.get_start_method() == "fork" else [], self.nice),
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
        return _Worker(proc, parent, slot)

    def _workers(self, capacity: int) -> list[_Worker]:
        if len(self._shared.results) < capacity:  # shared memory goes to workers at start
            self.close()
            old = self._shared
            self._shared = self._allocate(max(1024, 2 * capacity))
            self._shared.results[:len(old.results)] = old.results[:]
            self._shared.codes[:len(old.codes)] = old.codes[:]
        self._pool = [w for w in self._pool if w.process.is_alive()]
        used = {w.slot for w in self._pool}
        for slot in range(self.workers):
            if slot not in used:
                self._pool.append(self._spawn(slot))
        return self._pool

    def evaluate(self, jobs: Iterable[Job], expected: int | None = None) -> list[float]:
        streaming = not isinstance(jobs, Sequence)
        total = len(jobs) if isinstance(jobs, Sequence) else (expected or 0)
        source = iter(jobs)
        kept: list[Job] = []
        left: list[int] = []
        self._errors = []
        self._deaths = self._recycled = 0
        while True:  # a batch per size of shared memory: more than one only if it grows
            self._workers(max(total, len(kept) + 1))
            room = len(self._shared.results)
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
        results, codes = self._shared.results, self._shared.codes
        out: list[float] = results[:len(kept)]
        for p in left:  # these killed their worker by themselves
            out[p] = self.task.worst
            codes[p] = LOST
        self.lost += len(left)
        faults = Faults(worker_deaths=self._deaths, recycled=self._recycled)
        for p, job in enumerate(kept):
            faults.count(codes[p], job.trials)
        if self._errors:
            faults.first_error = min(self._errors)[1]
        self.faults = faults
        return out

    def _run_batch(self, chunks: Iterator[tuple[int, list[Job]]]) -> list[int]:
        """Run the (position, jobs) chunks as one batch, sending each to every worker as it
        comes; the positions of the jobs no worker finished."""
        results, codes = self._shared.results, self._shared.codes
        self._batch += 1
        self._dead_since_check = False
        if not self._counter_free():  # a worker died claiming a chunk, holding its lock
            self._terminate()
            self._workers(0)
        with self._counter.get_lock():
            self._counter.value = 0
        # each message pickled once for all workers, and kept for one that joins half-way
        sent: list[memoryview] = [ForkingPickler.dumps(("batch", self._batch))]
        active: dict[Connection, _Worker] = {}
        spans: list[tuple[int, int]] = []
        kill_after = self.limits.kill_after
        tick = None if kill_after is None else min(1.0, kill_after / 4)
        try:
            for worker in list(self._pool):
                worker = self._join(worker, sent)
                active[worker.conn] = worker
            for k, (at, chunk) in enumerate(chunks):
                results[at:at + len(chunk)] = [math.nan] * len(chunk)
                codes[at:at + len(chunk)] = [0] * len(chunk)
                spans.append((at, len(chunk)))
                self._broadcast((k, at, _pack(chunk)), sent, active)
            self._broadcast(("end", len(spans)), sent, active)
            while active:
                if self._dead_since_check:  # one that died claiming a chunk holds the
                    self._dead_since_check = False  # counter's lock: the others would
                    if not self._counter_free():  # wait for it for ever
                        self._restart(active, sent)
                ready_now = wait(list(active), tick)
                if not ready_now and kill_after is not None:
                    self._kill_overdue(active.values(), kill_after)
                for ready in ready_now:
                    conn = cast(Connection, ready)
                    worker = active.pop(conn)
                    try:
                        answer, error = conn.recv()
                    except (EOFError, OSError):  # it died: a fresh one joins the batch
                        self._buried(worker)
                        fresh = self._join(self._replace(worker), sent)
                        active[fresh.conn] = fresh
                        continue
                    if error is not None:
                        self._errors.append(error)
                    if answer == _RECYCLE:  # it has served its jobs or memory
                        self._recycled += 1
                        fresh = self._join(self._replace(worker), sent)
                        active[fresh.conn] = fresh
                    elif answer != self._batch:  # pragma: no cover - a protocol error
                        raise EvolutionError(f"worker answered batch {answer}, not {self._batch}")
        except BaseException:  # interrupted: no worker may be left half-way through a batch
            self._terminate()
            raise
        return [p for at, n in spans for p in range(at, at + n) if math.isnan(results[p])]

    def _counter_free(self, timeout: float = 1.0) -> bool:
        """Whether the chunk counter's lock can be taken (a claim holds it for microseconds;
        a worker killed while claiming holds it for good)."""
        lock = self._counter.get_lock()
        if not lock.acquire(timeout=timeout):
            return False
        lock.release()
        return True

    def _restart(self, active: dict[Connection, _Worker], sent: list[memoryview]) -> None:
        """Replace every worker (they share a fresh counter) and have them run the batch
        again from its first chunk: what was finished is evaluated again, to the same
        results; only a job that overran its limit costs its time again."""
        self._terminate()
        active.clear()
        for worker in self._workers(0):
            worker = self._join(worker, sent)
            active[worker.conn] = worker

    def _kill_overdue(self, workers: Iterable[_Worker], kill_after: float) -> None:
        """Kill each worker whose job has run past the limit without stopping: that job
        scores worst as a time-out; the worker's death is then handled as any other."""
        shared = self._shared
        now = time.monotonic()
        for w in workers:
            p = shared.running[w.slot]
            if p >= 0 and now - shared.since[w.slot] > kill_after and \
                    w.process.pid not in self._killed:
                self._killed.add(w.process.pid)
                w.process.kill()
                shared.results[p] = self.task.worst
                shared.codes[p] = TIMED_OUT

    def _buried(self, worker: _Worker) -> None:
        """Count a worker found dead (one the parent killed for time is no death)."""
        self._dead_since_check = True
        if worker.process.pid in self._killed:
            self._killed.discard(worker.process.pid)
        else:
            self._deaths += 1

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
                self._buried(worker)
                fresh = self._join(self._replace(worker), sent)
                active[fresh.conn] = fresh

    def _join(self, worker: _Worker, sent: list[memoryview]) -> _Worker:
        """Have ``worker`` (or a fresh one, if it dies) join the running batch: send it every
        message of the batch so far."""
        while not all(self._send(worker, m) for m in sent):
            self._buried(worker)
            worker = self._replace(worker)
        return worker

    @staticmethod
    def _send(worker: _Worker, data: memoryview) -> bool:
        try:
            worker.conn.send_bytes(data)
            return True
        except (BrokenPipeError, OSError):
            return False

    def _replace(self, old: _Worker) -> _Worker:
        self._discard(old)
        fresh = self._spawn(old.slot)
        self._pool = [fresh if w is old else w for w in self._pool]
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
        # a worker stopped while claiming a chunk holds the counter's lock for good: the
        # workers spawned next share a fresh counter
        self._counter = self._ctx.Value("q", 0)

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
