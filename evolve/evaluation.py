"""Evaluating genomes: serially, in a local process pool, or on Ray.

An evaluation is a :class:`Job`: a genome, the seed of its worlds and a number of trials.
The seed comes from the run seed and the job's place in the run (generation, individual),
never from the worker, so a run gives the same fitnesses on any backend and any number of
workers. A fault costs that evaluation (it scores the task's worst fitness), not the run,
and is counted in the evaluator's :class:`Faults`, identically on every backend:

- a skill, the task's world setup or its fitness raises (any exception, ``SystemExit``
  included; only a real Ctrl-C stops the run): that episode scores worst;
- the evaluation runs longer than its wall-clock limit: it scores worst (a pool or Ray
  worker stuck where the limit cannot reach it is killed by the parent);
- the job kills its worker process by itself (a segfault, ``os._exit``): it scores worst;
  the other jobs the dead worker had not finished are run again, one by one.

Pool workers and Ray actors are replaced after ``max_jobs`` jobs or once their memory has
grown by more than ``max_growth_mb`` (a leaking skill), between two chunks of jobs: results
do not change.
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import functools
import math
import multiprocessing
import os
import pickle
import secrets
import signal
import sys
import threading
import time
import traceback
import warnings
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from multiprocessing.reduction import ForkingPickler
from pathlib import Path
from types import FrameType
from typing import Any, NamedTuple, Protocol, cast

import numpy as np

from skillcompose.errors import one_line
from skillcompose.executor import CompiledFSA, error_summary
from skillcompose.task import Task, TaskRef

from .channel import HANDSHAKE_S, JobServer, connect, messages
from .config import EVALUATION_BACKENDS
from .errors import EvolutionError
from .genome import Genome, GenomeCompiler, SkillSet

__all__ = [
    "BACKENDS",
    "EvalLimits",
    "Evaluator",
    "Faults",
    "Guard",
    "Job",
    "ProcessEvaluator",
    "RayEvaluator",
    "SerialEvaluator",
    "evaluate_episodes",
    "evaluate_genome",
    "evaluate_job",
    "iter_episodes",
    "make_evaluator",
    "ray_runtime_env",
]

BACKENDS = EVALUATION_BACKENDS  # where evaluations run (defined with the settings)

# a job's fault code: (episodes that raised) << 2 | flags
TIMED_OUT = 1
LOST = 2
_FLAGS = 2
_MIN_CHUNK_S = 0.08
"""The least work [s] in one call to a Ray actor once jobs have been timed. On a local
cluster a call costs about 1.2 ms of the driver's CPU (taken from the workers when they
share its cores) and, when it is not queued behind a running one, about 2 ms of an idle
actor: some 3 ms in all, so 80 ms keeps a call under 4 % of its work. A generation with
less than this per actor is split evenly, one call each. Measured on two nodes of a
two-core machine (median speed-up over serial of 10 rounds): with 9,000-episode
generations a 20 ms floor made 8 or 9 calls and gave 1.69-1.72x, 80 ms 4 calls and
1.77-1.81x; with 900-episode generations 4 calls gave 1.39-1.42x, 2 calls 1.40-1.47x."""


@dataclass(frozen=True)
class EvalLimits:
    """Bounds on one evaluation and on a worker.

    - ``time_limit``: wall-clock seconds one evaluation (all its trials) may take; over it,
      it scores the task's worst fitness and counts as a time-out. ``None``: no limit.
    - ``max_jobs``: a pool worker or Ray actor is replaced after this many jobs (0: never).
    - ``max_growth_mb``: ... or once its resident memory has grown by more than this many
      MB since it started (0: never).
    """

    time_limit: float | None = None
    max_jobs: int = 0
    max_growth_mb: float = 0.0

    @property
    def kill_after(self) -> float | None:
        """When the parent kills a worker whose job ignored the limit [s]."""
        if self.time_limit is None:
            return None
        return self.time_limit + max(1.0, 0.1 * self.time_limit)


@dataclass
class Faults:
    """What went wrong in some evaluations (one generation, or a whole run).

    ``raised`` counts episodes, the others evaluations; ``worker_deaths`` counts worker
    processes (or Ray actors) that died and were replaced, which depends on how jobs were
    spread over workers (a job that kills its worker may kill another one when it is run
    again alone); the rest are the same on every backend and number of workers.
    """

    jobs: int = 0  # evaluations run
    failed: int = 0  # evaluations that scored worst in every episode because of faults
    raised: int = 0  # episodes in which a skill, the world setup or the fitness raised
    timeouts: int = 0  # evaluations stopped at the wall-clock limit
    lost: int = 0  # evaluations that killed their worker by themselves
    worker_deaths: int = 0
    recycled: int = 0  # workers replaced on purpose (max_jobs, max_growth_mb): not a fault
    first_error: str | None = None  # the first exception, summarised (job order)

    COUNTS = ("raised", "timeouts", "lost", "worker_deaths")

    @property
    def total(self) -> int:
        return self.raised + self.timeouts + self.lost + self.worker_deaths

    def add(self, other: Faults) -> None:
        for name in ("jobs", "failed", "raised", "timeouts", "lost", "worker_deaths",
                     "recycled"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        if self.first_error is None:
            self.first_error = other.first_error

    def count(self, code: int, trials: int) -> None:
        """Add one job's fault code."""
        self.jobs += 1
        raised = code >> _FLAGS
        self.raised += raised
        if code & TIMED_OUT:
            self.timeouts += 1
        if code & LOST:
            self.lost += 1
        if code & (TIMED_OUT | LOST) or raised >= trials:
            self.failed += 1

    def to_dict(self) -> dict[str, Any]:
        return {
            "jobs": self.jobs, "failed": self.failed, "raised": self.raised,
            "timeouts": self.timeouts, "lost": self.lost, "worker_deaths": self.worker_deaths,
            "recycled": self.recycled,
        }

    def describe(self) -> str:
        """``3 raised, 1 time-out`` (empty when there were none)."""
        words = (("raised", "raised", "raised"), ("timeouts", "time-out", "time-outs"),
                 ("lost", "lost", "lost"), ("worker_deaths", "worker death", "worker deaths"))
        parts = []
        for name, one, many in words:
            n = getattr(self, name)
            if n:
                parts.append(f"{n} {one if n == 1 else many}")
        return ", ".join(parts)


class _TimeUp(BaseException):
    """Raised into a running evaluation when its wall-clock limit passes."""


class Guard:
    """Enforces the wall-clock limit of an evaluation, and tells a real Ctrl-C from a
    ``KeyboardInterrupt`` that a skill raised.

    Works through ``SIGALRM`` and ``SIGINT`` handlers, so only in the main thread of a
    process (elsewhere :meth:`install` leaves it inactive: no limit). When the process
    ignores ``SIGINT`` (started in the background) no Ctrl-C can arrive, so every
    ``KeyboardInterrupt`` is a skill's; under a handler of someone else's (an IDE's, say)
    it is taken for the person's. While installed, an
    interval timer ticks every quarter of the limit (at most every second); a tick that
    finds the armed evaluation past its limit raises into it, and so does every later tick
    until it is disarmed (a skill that catches the first one gets the next). Arming and
    disarming an evaluation only note the time: no system call per evaluation.
    """

    def __init__(self, time_limit: float | None) -> None:
        self.time_limit = time_limit
        self.active = False
        self.armed = False
        self.started = 0.0
        self.interrupted = False
        self.tracks_interrupts = False
        self._old: list[tuple[int, Any]] = []

    def install(self) -> Guard:
        if threading.current_thread() is not threading.main_thread():
            return self
        self.interrupted = False
        handler = signal.getsignal(signal.SIGINT)
        if handler is signal.default_int_handler:
            self._old = [(signal.SIGINT, signal.signal(signal.SIGINT, self._on_interrupt))]
            self.tracks_interrupts = True
        elif handler == signal.SIG_IGN:  # started in the background (nohup, `&` in a
            self.tracks_interrupts = True  # script): no Ctrl-C arrives, a skill raised it
        if self.time_limit is not None and hasattr(signal, "setitimer"):
            self._old.append((signal.SIGALRM, signal.signal(signal.SIGALRM, self._on_alarm)))
            tick = min(1.0, self.time_limit / 4)
            signal.setitimer(signal.ITIMER_REAL, tick, tick)
            self.active = True
        return self

    def uninstall(self) -> None:
        self.armed = False
        if self.active:
            signal.setitimer(signal.ITIMER_REAL, 0.0)
        self.active = self.tracks_interrupts = False
        for sig, handler in reversed(self._old):
            signal.signal(sig, handler)
        self._old = []

    def __enter__(self) -> Guard:
        return self.install()

    def __exit__(self, *exc: object) -> None:
        self.uninstall()

    def arm(self) -> None:
        self.started = time.monotonic()
        self.armed = self.active

    def disarm(self) -> None:
        self.armed = False

    @contextlib.contextmanager
    def episode(self) -> Iterator[None]:
        """Armed while the block runs, and disarmed after it however it ends."""
        self.arm()
        try:
            yield
        finally:
            try:
                self.disarm()
            except _TimeUp:  # the alarm came as the block ended: it still ran too long
                self.disarm()
                raise

    def _on_alarm(self, signum: int, frame: FrameType | None) -> None:
        if self.armed and self.time_limit is not None and \
                time.monotonic() - self.started > self.time_limit:
            raise _TimeUp

    def _on_interrupt(self, signum: int, frame: FrameType | None) -> None:
        self.interrupted = True
        raise KeyboardInterrupt


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


def _user_interrupt(exc: BaseException, guard: Guard | None) -> bool:
    """A Ctrl-C of the person running evolution (not a skill raising KeyboardInterrupt)."""
    return isinstance(exc, KeyboardInterrupt) and (
        guard is None or guard.interrupted or not guard.tracks_interrupts
    )


def _fault(exc: BaseException, guard: Guard | None) -> bool:
    """Whether ``exc``, raised in an episode, is the FSA's fault (it scores the worst
    fitness) rather than the job's time-out or the user's Ctrl-C (they end the job)."""
    return not isinstance(exc, _TimeUp) and not _user_interrupt(exc, guard)


def evaluate_job(
    task: Task, compiler: GenomeCompiler, job: Job, guard: Guard | None = None,
    explain: bool = True, scores: list[float] | None = None,
) -> tuple[float, int, str | None]:
    """Mean fitness of one job, its fault code, and (when ``explain``) a summary of its
    first exception. Any fault costs the episode (a time-out: the whole job) the task's
    worst fitness. Each episode's fitness is appended to ``scores`` when given."""
    worst = task.worst
    raised = 0
    first: str | None = None
    total = 0.0
    try:
        try:
            if guard is not None:
                guard.arm()
            try:
                compiled = compiler.compile(Genome.decode(job.genome))
            except _TimeUp:
                raise
            except BaseException as exc:
                if _user_interrupt(exc, guard):
                    raise
                return worst, job.trials << _FLAGS, error_summary(exc) if explain else None
            seq = np.random.SeedSequence(job.seed, spawn_key=job.spawn_key)
            for trial in task.each_trial(compiled, seq, job.trials,
                                         catch=lambda exc: _fault(exc, guard)):
                error = trial.result.error
                if error is not None:
                    raised += 1
                    if explain and first is None:
                        first = error_summary(error)
                f = worst if math.isnan(trial.fitness) else trial.fitness
                total += f
                if scores is not None:
                    scores.append(f)
        finally:
            if guard is not None:
                guard.disarm()
    except _TimeUp:
        if guard is not None:
            guard.disarm()
        return worst, TIMED_OUT | raised << _FLAGS, first
    return total / job.trials, raised << _FLAGS, first


def iter_episodes(
    task: Task, compiled: CompiledFSA, seed: int | np.random.SeedSequence, trials: int,
    guard: Guard,
) -> Iterator[tuple[float, int]]:
    """Episodes of a compiled FSA on up to ``trials`` worlds from ``seed``, one at a time
    (a caller may stop early), each under ``guard``'s time limit: each one's fitness and
    fault code (as :func:`evaluate_job`'s)."""
    for trial in task.each_trial(compiled, seed, trials, each=guard.episode,
                                 catch=lambda exc: not _user_interrupt(exc, guard)):
        error = trial.result.error
        if isinstance(error, _TimeUp):
            yield task.worst, TIMED_OUT
        elif error is not None:
            yield task.worst, 1 << _FLAGS
        else:
            yield task.worst if math.isnan(trial.fitness) else trial.fitness, 0


def evaluate_episodes(
    task: Task, compiled: CompiledFSA, seed: int | np.random.SeedSequence, trials: int,
    guard: Guard,
) -> list[tuple[float, int]]:
    """:func:`iter_episodes`, all ``trials`` of them."""
    return list(iter_episodes(task, compiled, seed, trials, guard))


def evaluate_genome(task: Task, compiler: GenomeCompiler, job: Job) -> float:
    """Mean fitness of one job; a failure of any kind scores the task's worst fitness."""
    return evaluate_job(task, compiler, job, explain=False)[0]


class Evaluator(Protocol):
    """Evaluates jobs, returning their fitnesses in order.

    ``jobs`` may be a list or any iterable, such as a generator that breeds the jobs as it
    goes: a pool starts evaluating the first ones while the rest are still being made.
    ``expected`` is how many jobs an iterable will give, if known (for chunk sizes).
    ``faults`` describes the last call's jobs.
    """

    workers: int
    faults: Faults

    def evaluate(self, jobs: Iterable[Job], expected: int | None = None) -> list[float]: ...

    def close(self) -> None: ...


class SerialEvaluator:
    """Evaluates in this process (the wall-clock limit needs its main thread)."""

    def __init__(
        self, task: Task, skills: SkillSet, limits: EvalLimits | None = None
    ) -> None:
        self.task = task
        self.compiler = GenomeCompiler(task, skills)
        self.workers = 1
        self.limits = limits or EvalLimits()
        self.faults = Faults()

    def evaluate(self, jobs: Iterable[Job], expected: int | None = None) -> list[float]:
        # all jobs first, then all evaluations: interleaving them in one process measured
        # slower (about 10 %) (the two loops evict each other's code and data from the caches)
        jobs = list(jobs)
        faults = Faults()
        out: list[float] = []
        task, compiler = self.task, self.compiler
        with Guard(self.limits.time_limit) as guard:
            for j in jobs:
                f, code, error = evaluate_job(task, compiler, j, guard,
                                              faults.first_error is None)
                out.append(f)
                faults.count(code, j.trials)
                if error is not None and faults.first_error is None:
                    faults.first_error = error
        self.faults = faults
        return out

    def close(self) -> None:
        pass


# -- process pool ------------------------------------------------------------------------
_RECYCLE = "recycle"


def _init_worker(
    source: TaskRef | Task, terminals: tuple[str, ...]
) -> tuple[Task, GenomeCompiler]:
    """The task and its genome compiler, built once per worker process from the task's
    module and settings, and held by the worker's loop (no module global)."""
    task = source.build() if isinstance(source, TaskRef) else source
    return task, GenomeCompiler(task, SkillSet.from_task(task, terminals))


def _rss_mb() -> float:
    """This process's resident memory [MB] (0 where it cannot be read)."""
    try:
        with open("/proc/self/statm", "rb") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError, IndexError, AttributeError):
        try:
            import resource

            return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        except ImportError:  # pragma: no cover - platforms without resource
            return 0.0


class _Recycler:
    """Counts a worker's jobs and memory; says when it should be replaced."""

    def __init__(self, limits: EvalLimits) -> None:
        self.max_jobs = limits.max_jobs
        self.max_growth_mb = limits.max_growth_mb
        self.jobs = 0
        self.base_mb = _rss_mb() if limits.max_growth_mb else 0.0

    def worn(self, jobs: int) -> bool:
        self.jobs += jobs
        if self.max_jobs and self.jobs >= self.max_jobs:
            return True
        return bool(self.max_growth_mb) and _rss_mb() - self.base_mb > self.max_growth_mb


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


def _unpack(packed: bytes) -> list[Job]:
    return [Job._make(j) for j in pickle.loads(packed)]


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
    conn: Connection, source: TaskRef | Task, terminals: tuple[str, ...], cpu: int | None,
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
    if parent_pid:
        _die_with_parent(parent_pid, inherited)
    if cpu is not None:
        with contextlib.suppress(OSError, AttributeError):
            os.sched_setaffinity(0, {cpu})
    if nice:
        with contextlib.suppress(OSError, AttributeError):
            os.nice(nice)
    try:
        task, compiler = _init_worker(source, terminals)
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
        self.terminals = skills.terminals
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
            args=(child, self._source, self.terminals, cpu, self._counter, self._shared,
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


_PROJECT_PACKAGES = ("skillcompose",)


@functools.lru_cache(maxsize=1)
def _project_package() -> str:
    """The folder of the ``skillcompose`` package as it installs, to ship to a cluster: the
    package's own folder when its subpackages lie inside it (an installed wheel); else (a
    source checkout, whose ``evolve/``, ``robots/`` and ``skills/`` are mapped into the
    package by ``package-dir``) a copy laid out as installed, kept until the process ends
    (Ray hashes the folder again for each actor it starts)."""
    import importlib.util
    import shutil
    import tempfile

    root = Path(str(sys.modules["skillcompose"].__file__)).resolve().parent
    outside: dict[str, Path] = {}
    for sub in ("evolve", "robots", "skills", "view"):
        spec = importlib.util.find_spec(f"skillcompose.{sub}")
        if spec is not None and spec.submodule_search_locations:
            where = Path(next(iter(spec.submodule_search_locations))).resolve()
            if not where.is_relative_to(root):
                outside[sub] = where
    if not outside:
        return str(root)
    stage = Path(tempfile.mkdtemp(prefix="skillcompose-ship-"))
    atexit.register(shutil.rmtree, stage, True)
    skip = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(root, stage / "skillcompose", ignore=skip)
    for sub, where in outside.items():
        shutil.copytree(where, stage / "skillcompose" / sub, ignore=skip)
    return str(stage / "skillcompose")


def _installed(path: str) -> bool:
    """Whether a module at ``path`` comes with the interpreter or an installed distribution
    (which a cluster's nodes are expected to have, like numpy), not from user code."""
    import sysconfig

    parts = Path(path).resolve().parts
    if "site-packages" in parts or "dist-packages" in parts:
        return True
    stdlib = Path(sysconfig.get_paths()["stdlib"]).resolve()
    return Path(path).resolve().is_relative_to(stdlib)


def ray_runtime_env(task: Task) -> tuple[dict[str, Any], TaskRef]:
    """What a Ray cluster's workers need to rebuild ``task``, shipped through Ray's runtime
    environment rather than installed on the nodes: this project's packages, the task's
    module and the modules its skills come from (each top-level package, or a single-file
    module, that is not part of an installed distribution), as ``py_modules``. A task
    loaded from a ``.py`` path ships that file's directory as the ``working_dir`` and is
    rebuilt there by module name. Returns the runtime environment and the reference the
    workers rebuild the task from."""
    if task.ref is None:
        raise EvolutionError(
            f"backend 'ray' rebuilds task {task.name} in each actor from its module: "
            "load the task with skillcompose.task.load_task(module, **settings)"
        )
    ref = task.ref
    env: dict[str, Any] = {}
    names: list[str] = list(_PROJECT_PACKAGES)
    module = ref.module
    if module.endswith(".py") or "/" in module or "\\" in module:
        path = Path(module).resolve()
        env["working_dir"] = str(path.parent)
        ref = TaskRef(path.stem, dict(ref.settings))
    else:
        names.append(module.split(".", 1)[0])
    for name in task.registry:
        for backend in task.registry.backends(name):
            impl = getattr(task.registry.resolve(name, backend), "impl", None)
            owner = getattr(impl, "__module__", None) or ""
            if owner and not owner.startswith("_skillcompose_user_"):
                names.append(owner.split(".", 1)[0])
    modules: list[str] = []
    for top in dict.fromkeys(names):
        found = sys.modules.get(top)
        if found is None:
            continue
        if top in _PROJECT_PACKAGES:
            modules.append(_project_package())
            continue
        paths = list(getattr(found, "__path__", []))
        where = paths[0] if len(paths) == 1 else getattr(found, "__file__", None)
        if where and not _installed(where):
            modules.append(where)
    env["py_modules"] = modules
    return env, ref


class _Unreachable(EvolutionError):
    """A Ray actor lives, but the driver cannot connect to it for its jobs."""


class _Actor:
    """A Ray actor of a :class:`RayEvaluator`, the node it runs on, and its calls in flight
    (oldest first: the first one is running, the others wait behind it)."""

    def __init__(self, handle: Any, node: str) -> None:
        self.handle = handle
        self.node = node
        self.calls: list[tuple[Any, int, list[Job], bool]] = []  # ref, position, jobs, alone
        self.conn: Connection | None = None  # the direct connection its jobs take, if any
        self.watch: Any = None  # the ref of its serving loop, which ends when it dies
        self.since = 0.0  # when its first call in flight started (roughly: sent or freed)
        self.retiring = False  # served its jobs or memory: replaced once its calls are done


class RayEvaluator:
    """Ray actors, each holding the task built once from its module and settings.

    Needs the optional extra: ``pip install skillcompose[ray]``. Connects to the cluster at
    ``RAY_ADDRESS`` when it is set, else starts a local one (without a dashboard; its
    servers listen on every interface, which Ray offers no setting to change), and ships
    the task's code to the workers through Ray's runtime environment
    (:func:`ray_runtime_env`; pass ``runtime_env`` to give your own), and disconnects on
    :meth:`close`. When Ray is already initialised, the caller's connection and runtime
    environment stand.

    Each actor takes one CPU of the cluster (``workers``: by default every CPU), spread
    over the nodes. Jobs go out in batches of one chunk per actor (factoring: each chunk a
    ``1 / chunks_per_worker`` share of what is left per actor, so large first and small
    last, but none under ``_MIN_CHUNK_S`` of work once a generation has timed the jobs,
    except that what is left is split evenly when it is less) to whichever actor is free,
    every actor given a first chunk before any a second, each holding at most two (one
    near the end), so a slow or busy node simply does less.
    ``nodes`` gives, for the last call, the node each job was evaluated on. With ``groups``
    set to k > 1 (islands: the population in k equal runs), group i's jobs go to the actors
    of the i-th node (mod the number of nodes) first, and to others only when those have
    nothing left (which runs where never changes a result).

    An actor that dies (its job crashed it, or its node went down) is replaced, and the
    jobs of the chunk it was running are run again one by one; only a job that kills the
    actor it runs on alone, twice, scores worst (``lost``): so a node lost in the middle of
    a run costs the run no result. An actor that cannot be placed (no free CPU left) is
    waited for while the others go on. With a wall-clock limit, an actor whose chunk
    overruns what its jobs' limits allow is killed and that chunk run again job by job,
    each job given the limit (a job that overruns it alone scores worst as a time-out).
    Actors are replaced after ``max_jobs`` jobs or ``max_growth_mb`` of memory growth.

    With ``direct`` (the default) the chunks and their results go over a connection of
    :mod:`skillcompose.evolve.channel` from the driver to each actor, not through Ray's calls, which
    cost a tenth of a small generation; when the driver cannot connect to the first
    actors (a firewall that opens Ray's ports only, say), it warns once and uses Ray's
    calls (``direct=False``).
    """

    def __init__(
        self, task: Task, skills: SkillSet, workers: int | None = None,
        chunks_per_worker: int = 2, limits: EvalLimits | None = None,
        runtime_env: dict[str, Any] | None = None, start_timeout: float = 120.0,
        direct: bool = True,
    ) -> None:
        try:
            import ray
        except ImportError as exc:
            raise EvolutionError(
                "backend 'ray' needs Ray: pip install skillcompose[ray] "
                "(or use --backend process)"
            ) from exc
        env, self._ref = ray_runtime_env(task)
        self._ray: Any = ray
        self._owns_ray = not ray.is_initialized()  # then closed with this evaluator
        if self._owns_ray:
            ray.init(ignore_reinit_error=True, log_to_driver=False, include_dashboard=False,
                     runtime_env=env if runtime_env is None else runtime_env)
        self.task = task
        self.workers = workers or int(ray.cluster_resources().get("CPU", 1)) or 1
        self.chunks_per_worker = chunks_per_worker
        self.limits = limits or EvalLimits()
        self.start_timeout = start_timeout
        self._actor_cls = ray.remote(num_cpus=1, scheduling_strategy="SPREAD")(_RayWorker)
        self._terminals = skills.terminals
        self._actors: list[_Actor] = []
        self._starting: dict[Any, Any] = {}  # ready ref -> actor handle
        self.lost = 0
        self.faults = Faults()
        self.nodes: list[str] = []
        self.groups = 1
        self._job_s: float | None = None  # seconds per job, as the last generation ran
        self.direct = direct
        self._key = secrets.token_bytes(32)  # proves the driver to its actors, and back
        try:  # the driver's node, where actors listen on 127.0.0.1 only
            self._home = str(ray.get_runtime_context().get_node_id())
        except Exception:  # a driver on no node (Ray Client): every actor on its address
            self._home = ""
        try:
            try:
                self._start_all()
            except _Unreachable as exc:
                warnings.warn(f"{exc}; the jobs go through Ray's calls instead, slower",
                              RuntimeWarning, stacklevel=2)
                self.close(keep_ray=True)
                self.direct = False
                self._start_all()
        except BaseException:
            self.close()
            raise

    def _start_all(self) -> None:
        for _ in range(self.workers):
            self._start_actor()
        self._await_actors(wait_all=True)

    def _start_actor(self) -> None:
        handle: Any = self._actor_cls.remote(
            self._ref, self._terminals, self.limits, self._key if self.direct else None,
            self._home)
        self._starting[handle.ready.remote()] = handle

    def _await_actors(self, wait_all: bool = False, timeout: float = 0.0) -> None:
        """Take in the actors that have started: all of them, up to ``start_timeout``, when
        ``wait_all``; else the first within ``timeout`` (0: those there now). Having waited,
        fail when there is none."""
        ray = self._ray
        waits = wait_all or timeout > 0
        deadline = time.monotonic() + (self.start_timeout if wait_all else timeout)
        while self._starting:
            left = max(0.0, deadline - time.monotonic())
            done, _ = ray.wait(list(self._starting), num_returns=1, timeout=left)
            if not done:
                break
            handle = self._starting.pop(done[0])
            try:
                node, address = ray.get(done[0])
            except ray.exceptions.RuntimeEnvSetupError as exc:
                self._discard_starting()
                raise EvolutionError(
                    f"Ray could not set up the workers' runtime environment for task "
                    f"{self.task.name}: {str(exc).strip().splitlines()[-1]}"
                ) from exc
            except Exception as exc:
                self._discard_starting()
                raise EvolutionError(
                    f"a Ray actor could not build task {self.task.name}: "
                    f"{str(exc).strip()[-800:]}"
                ) from exc
            actor = _Actor(handle, node)
            if address is not None and not self._connect(actor, tuple(address)):
                self._start_actor()  # it died on the way: another
                continue
            self._actors.append(actor)
            if not wait_all:
                deadline = time.monotonic()  # take what has started, without waiting more
        if not self._actors and waits:
            self._discard_starting()
            raise EvolutionError(
                f"no Ray actor started in {self.start_timeout:g} s: the cluster has no free "
                "CPU (see `ray status`), or use fewer --workers"
            )

    def _connect(self, actor: _Actor, address: tuple[str, int]) -> bool:
        """Start ``actor``'s serving loop and connect to it: False if it died meanwhile;
        raises :class:`_Unreachable` when it lives but cannot be reached."""
        ray = self._ray
        actor.watch = actor.handle.serve.remote()
        try:
            actor.conn = connect(address, self._key)
            return True
        except Exception as exc:
            done, _ = ray.wait([actor.watch], timeout=1.0)
            with contextlib.suppress(Exception):
                ray.kill(actor.handle)
            if done:
                return False
            self._discard_starting()
            raise _Unreachable(
                f"the driver could not connect to a Ray actor at {address[0]}:{address[1]} for "
                f"its jobs ({one_line(str(exc)) or type(exc).__name__}): open TCP from the "
                "driver to the nodes' ephemeral ports, or use RayEvaluator(direct=False)"
            ) from exc

    def _discard_starting(self) -> None:
        for handle in self._starting.values():
            with contextlib.suppress(Exception):
                self._ray.kill(handle)
        self._starting = {}

    def _drop(self, actor: _Actor) -> None:
        """Take ``actor`` out of the pool (killing it, if it lives) and start a replacement."""
        self._kill(actor)
        self._actors.remove(actor)
        self._start_actor()

    def _kill(self, actor: _Actor) -> None:
        if actor.conn is not None:
            actor.conn.close()
            actor.conn = None
        with contextlib.suppress(Exception):  # an actor that died already
            self._ray.kill(actor.handle)

    def evaluate(self, jobs: Iterable[Job], expected: int | None = None) -> list[float]:
        ray = self._ray
        faults = Faults()
        self.faults = faults
        self.nodes = []
        for actor in [a for a in self._actors if a.calls]:  # a generation ended by an
            self._drop(actor)  # exception (its jobs' breeding raised, Ctrl-C)
        # a generation handed over as it is bred (an iterator, with its expected size) goes
        # out as it comes, so the actors evaluate while the driver breeds the rest; islands
        # need the whole generation first, to cut it into runs at home on their nodes
        stream: Iterator[Job] | None = None
        if not isinstance(jobs, Sequence) and expected and self.groups <= 1:
            stream = iter(jobs)
            jobs = []
        else:
            jobs = list(jobs)
            if not jobs:
                return []
        n = len(jobs)
        out = [math.nan] * n
        codes = [0] * n
        nodes = [""] * n
        errors: list[tuple[int, str]] = []
        singles: list[int] = []  # positions to run alone, after their actor died
        crashed: dict[int, int] = {}  # position -> actors it killed running alone
        again: list[tuple[int, list[Job]]] = []  # chunks sent to an actor that died first
        per_job = self.limits.kill_after
        tick = 1.0 if per_job is None else min(1.0, per_job / 4)

        # the jobs in ``groups`` equal runs (islands), group k at home on the k-th node (mod
        # their number): an actor takes from its own node's groups first, then from any
        homes = sorted({a.node for a in self._actors})
        groups = max(1, min(self.groups, n))
        spans = [[k * n // groups, (k + 1) * n // groups] for k in range(groups)]  # next, end
        home = [homes[k % len(homes)] if groups > 1 and homes else "" for k in range(groups)]
        batches = [[0, 0] for _ in range(groups)]  # chunk size, chunks left in the batch

        def next_work(actor: _Actor) -> tuple[int, list[Job], bool] | None:
            if singles:
                p = singles.pop(0)
                return p, [jobs[p]], True
            if again:
                return (*again.pop(0), False)
            if stream is not None:  # chunks of a fixed size while the jobs come
                start, end = spans[0]
                if end - start < streamed:
                    return None
                spans[0][0] = start + streamed
                return start, jobs[start:start + streamed], False
            own = [k for k in range(groups) if home[k] in ("", actor.node)]
            for k in own + [k for k in range(groups) if k not in own]:
                start, end = spans[k]
                if start < end:
                    workers = sum(a.node == home[k] for a in self._actors) if home[k] else \
                        len(self._actors)
                    share = self.chunks_per_worker * max(1, workers)
                    left = end - start
                    if batches[k][1] <= 0:  # a new batch: one chunk for each actor
                        batches[k] = [max(math.ceil(left / share), min(
                            least(end - k * n // groups, share),
                            math.ceil(left / max(1, workers)))), max(1, workers)]
                    size = batches[k][0]
                    batches[k][1] -= 1
                    spans[k][0] = min(end, start + size)
                    return start, jobs[start:spans[k][0]], False
            return None

        def least(jobs_in: int, share: int) -> int:
            """The smallest chunk of a run of ``jobs_in`` jobs cut in ``share`` shares: an
            eighth of a share, and (once a generation has timed the jobs) at least
            ``_MIN_CHUNK_S`` of work."""
            timed = 1 if self._job_s is None else math.ceil(_MIN_CHUNK_S / self._job_s)
            return max(1, jobs_in // (8 * share), timed)

        tail = least(n, self.chunks_per_worker * max(1, len(self._actors)))
        busy = [0.0, 0]  # seconds the actors spent on jobs, and jobs, this generation
        # while streaming: chunks of a quarter of each actor's share of the expected jobs
        # (an eighth of them on two actors; never under a tenth of the time floor once
        # timed), each actor holding two
        streamed = max(math.ceil((expected or 1) / (self.chunks_per_worker * 2 * max(
            1, len(self._actors)))), 1 if self._job_s is None else
            math.ceil(_MIN_CHUNK_S / 10 / self._job_s))

        def pull() -> None:
            """Take a chunk's worth more jobs from the stream (bred meanwhile); at its end,
            the generation is whole and what is left goes out by factoring."""
            nonlocal stream, n, tail
            assert stream is not None
            for _ in range(streamed):
                job = next(stream, None)
                if job is None:
                    stream = None
                    break
                jobs.append(job)
                out.append(math.nan)
                codes.append(0)
                nodes.append("")
            n = len(jobs)
            spans[0][1] = n
            if stream is None:
                tail = least(n, self.chunks_per_worker * max(1, len(self._actors)))

        def feed(actor: _Actor, most: int = 2) -> None:
            # a second call waits behind the running one (hiding the round trip) only while
            # more than a chunk per actor is left: at the end of a generation a queued chunk
            # would keep its actor busy while another, free, has nothing to take
            while not actor.retiring and len(actor.calls) < min(most, (
                    2 if stream is not None or sum(e - s for s, e in spans) >
                    tail * len(self._actors) else 1)):
                work = next_work(actor)
                if work is None:
                    return
                p, chunk, alone = work
                if not actor.calls:
                    actor.since = time.monotonic()
                if actor.conn is None:
                    actor.calls.append(
                        (actor.handle.run.remote(_pack(chunk), p), p, chunk, alone))
                    continue
                actor.calls.append((None, p, chunk, alone))
                try:
                    actor.conn.send((_pack(chunk), p))
                except Exception:  # it died: what it had goes again
                    died(actor, killed=False)
                    return

        def died(actor: _Actor, killed: bool) -> None:
            """The actor is gone (or ``killed`` by us for time): keep what it finished,
            run again what it had not."""
            unfinished = []
            if actor.conn is not None:  # what it sent back before it went
                with contextlib.suppress(Exception):
                    while actor.calls and actor.conn.poll(0):
                        result = actor.conn.recv()
                        record(actor, actor.calls.pop(0)[1], result)
            for ref, p, chunk, alone in actor.calls:
                try:
                    if ref is None:
                        raise EOFError
                    record(actor, p, ray.get(ref, timeout=0))
                except Exception:
                    unfinished.append((p, chunk, alone))
            actor.calls = []
            if not killed:
                faults.worker_deaths += 1
            for k, (p, chunk, alone) in enumerate(unfinished):
                if k:  # never started: as they were
                    if alone:
                        singles.insert(0, p)
                    else:
                        again.insert(0, (p, chunk))
                elif alone and killed:
                    out[p], codes[p], nodes[p] = self.task.worst, TIMED_OUT, actor.node
                elif alone and crashed.get(p, 0) >= 1:  # it killed a second actor alone
                    out[p], codes[p], nodes[p] = self.task.worst, LOST, actor.node
                    self.lost += 1
                elif alone:
                    crashed[p] = crashed.get(p, 0) + 1
                    singles.insert(0, p)
                else:
                    singles[:0] = range(p, p + len(chunk))
            self._drop(actor)

        def record(actor: _Actor, p: int, result: Any) -> None:
            fitness, chunk_codes, error, worn, seconds = result
            busy[0] += seconds
            busy[1] += len(fitness)
            out[p:p + len(fitness)] = fitness
            codes[p:p + len(fitness)] = chunk_codes
            nodes[p:p + len(fitness)] = [actor.node] * len(fitness)
            if error is not None:
                errors.append(error)
            if worn and not actor.retiring:
                actor.retiring = True
                faults.recycled += 1

        def feed_all() -> None:
            for most in (1, 2):  # a first chunk to every actor before a second to any
                for actor in list(self._actors):
                    if actor in self._actors:
                        feed(actor, most)

        def finished(actor: _Actor, result: Any, k: int = 0) -> None:
            _, p, _, _ = actor.calls.pop(k)
            actor.since = time.monotonic()
            record(actor, p, result)
            if actor.retiring and not actor.calls:
                self._drop(actor)

        watched = time.monotonic()  # when dead actors were last looked for

        def take_direct(timeout: float) -> None:
            """Take the results that come back over the actors' connections within
            ``timeout``; when none came, look for actors Ray knows died without closing
            their connection (a node cut off)."""
            nonlocal watched
            conns = {a.conn: a for a in self._actors if a.calls and a.conn is not None}
            ready = wait(list(conns), timeout)
            for conn in ready:
                actor = conns[cast(Connection, conn)]
                if actor not in self._actors:
                    continue
                try:
                    result = actor.conn.recv() if actor.conn is not None else None
                except Exception:  # it died (its process, or its node)
                    died(actor, killed=False)
                    continue
                finished(actor, result)
            if ready or time.monotonic() - watched < tick:
                return
            watched = time.monotonic()
            watches = {a.watch: a for a in self._actors if a.calls}
            if watches:
                gone, _ = ray.wait(list(watches), num_returns=len(watches), timeout=0)
                for ref in gone:
                    if watches[ref] in self._actors:
                        died(watches[ref], killed=False)


        feed_all()
        while True:
            if stream is not None:
                pull()
            self._await_actors()
            feed_all()
            if not any(a.calls for a in self._actors):
                if stream is None and all(a >= b for a, b in spans) and not singles \
                        and not again:
                    break
                if not self._actors:  # every actor died: wait for a replacement
                    self._await_actors(timeout=self.start_timeout)
                continue
            # while jobs come, only what is back now: then on to take (breed) more
            timeout = 0.0 if stream is not None else tick
            if self.direct:
                take_direct(timeout)
            else:
                calls = {c[0]: a for a in self._actors for c in a.calls}
                done, _ = ray.wait(list(calls), num_returns=1, timeout=timeout)
                for ref in done:
                    actor = calls[ref]
                    if actor not in self._actors:  # already handled as dead in this round
                        continue
                    try:
                        result = ray.get(ref)
                    except Exception:  # the actor died (RayActorError), or its node did
                        died(actor, killed=False)
                        continue
                    finished(actor, result,
                             next(i for i, c in enumerate(actor.calls) if c[0] == ref))
            if per_job is not None:
                now = time.monotonic()
                for actor in list(self._actors):
                    if actor.calls and now - actor.since > len(actor.calls[0][2]) * per_job:
                        with contextlib.suppress(Exception):
                            ray.kill(actor.handle)
                        died(actor, killed=True)
        for p, job in enumerate(jobs):
            faults.count(codes[p], job.trials)
        if errors:
            faults.first_error = min(errors)[1]
        if busy[1]:
            self._job_s = busy[0] / busy[1]
        self.nodes = nodes
        return out

    def close(self, keep_ray: bool = False) -> None:
        for a in self._actors:
            self._kill(a)
        self._actors = []
        self._discard_starting()
        # its runtime environment was this task's: the next starts anew
        if self._owns_ray and not keep_ray:
            self._ray.shutdown()
            self._owns_ray = False


class _RayWorker:
    def __init__(
        self, ref: TaskRef, terminals: tuple[str, ...], limits: EvalLimits, key: bytes | None,
        home: str,
    ) -> None:
        self.task = ref.build()
        self.compiler = GenomeCompiler(self.task, SkillSet.from_task(self.task, terminals))
        self.guard = Guard(limits.time_limit).install()
        self.recycler = _Recycler(limits)
        self._key = key
        self._home = home  # the node of the evaluator
        self._jobs: JobServer | None = None

    def ready(self) -> tuple[str, tuple[str, int] | None]:
        """The id of the node this actor runs on, and, when the evaluator gave a key, the
        address where it takes its jobs (127.0.0.1 on the evaluator's own node)."""
        import ray

        node = str(ray.get_runtime_context().get_node_id())
        if self._key is None:
            return node, None
        host = "127.0.0.1" if node == self._home else ray.util.get_node_ip_address()
        self._jobs = JobServer(host, self._key)
        return node, self._jobs.address

    def serve(self) -> None:
        """Run the chunks that come over the evaluator's connection (each ``(packed, at)``
        as :meth:`run` takes them), sending back each one's results, until it closes.
        Runs on the actor's main thread, as Ray's calls do, so the time limit works."""
        assert self._jobs is not None, "ready() first"
        with self._jobs.accept(3 * HANDSHAKE_S) as conn:
            for packed, at in messages(conn):
                conn.send(self.run(packed, at))

    def run(
        self, packed: bytes, at: int
    ) -> tuple[list[float], list[int], tuple[int, str] | None, bool, float]:
        """Fitnesses, fault codes, the first exception (position, summary), whether this
        actor should now be replaced, and the seconds the jobs took, for the jobs
        ``packed`` by :func:`_pack` (one
        bytes argument: Ray passes it as it is, at a fraction of the cost of serialising
        the jobs' nested tuples itself)."""
        t0 = time.perf_counter()
        jobs = _unpack(packed)
        fitness: list[float] = []
        codes: list[int] = []
        first: tuple[int, str] | None = None
        for i, job in enumerate(jobs):
            f, code, error = evaluate_job(self.task, self.compiler, job, self.guard,
                                          first is None)
            fitness.append(f)
            codes.append(code)
            if error is not None and first is None:
                first = (at + i, error)
        return fitness, codes, first, self.recycler.worn(len(jobs)), time.perf_counter() - t0


def make_evaluator(
    backend: str, task: Task, skills: SkillSet, workers: int | None, chunks_per_worker: int = 2,
    limits: EvalLimits | None = None, islands: int = 1,
) -> SerialEvaluator | ProcessEvaluator | RayEvaluator:
    """The evaluator of ``backend``; on Ray, island k's jobs run on the k-th node first."""
    if backend == "serial":
        return SerialEvaluator(task, skills, limits)
    if backend == "process":
        return ProcessEvaluator(task, skills, workers, limits)
    if backend == "ray":
        ray_evaluator = RayEvaluator(task, skills, workers, chunks_per_worker, limits)
        ray_evaluator.groups = islands
        return ray_evaluator
    raise EvolutionError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
