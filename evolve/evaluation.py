"""Evaluating genomes: what every evaluator shares, and the protocol they keep.

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

Each evaluator lives in its own module with its transport, behind :class:`Evaluator`:
:mod:`~skillcompose.evolve.serial` (this process), :mod:`~skillcompose.evolve.pool` (a local
process pool) and :mod:`~skillcompose.evolve.ray_backend` (Ray actors);
:func:`~skillcompose.evolve.backends.make_evaluator` picks one by name.
"""

from __future__ import annotations

import contextlib
import math
import os
import pickle
import signal
import threading
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from types import FrameType
from typing import Any, ClassVar, NamedTuple, Protocol

import numpy as np

from skillcompose.executor import CompiledFSA, error_summary
from skillcompose.task import Task

from .genome import Genome, GenomeCompiler

__all__ = [
    "EvalLimits",
    "Evaluator",
    "Faults",
    "Guard",
    "Job",
    "evaluate_episodes",
    "evaluate_genome",
    "evaluate_job",
    "iter_episodes",
]

# a job's fault code: (episodes that raised) << 2 | flags
TIMED_OUT = 1
LOST = 2
_FLAGS = 2


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

    def add_episode(self, code: int) -> None:
        """Count one episode's fault code, as :func:`iter_episodes` gives it: an episode
        that raised, or one that ran past the limit (counted among ``timeouts``)."""
        self.raised += code >> _FLAGS
        self.timeouts += code & TIMED_OUT

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

    watch: ClassVar[Any] = None
    """Where a process that another one watches notes when its armed evaluation started (a
    shared double: ``time.monotonic()``, which is the machine's, or -1 when none is armed):
    the checks' child (:mod:`.isolated`), whose parent kills it when an episode runs past the
    limit where no signal reaches it (code that blocks ``SIGALRM``, a wait in C)."""

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
        if Guard.watch is not None and self.active:
            Guard.watch.value = self.started

    def disarm(self) -> None:
        self.armed = False
        if Guard.watch is not None:
            Guard.watch.value = -1.0

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


# -- what the pool's workers and Ray's actors share --------------------------------------


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


def _pack(jobs: Sequence[Job]) -> bytes:
    return pickle.dumps([tuple(j) for j in jobs], protocol=pickle.HIGHEST_PROTOCOL)


def _unpack(packed: bytes) -> list[Job]:
    return [Job._make(j) for j in pickle.loads(packed)]
