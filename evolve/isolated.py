"""A run's checks in a process of their own, so that a task that ends its process cannot
end the run.

Evaluations run in worker processes (``backend="process"`` or ``"ray"``), where a job that
kills its worker (``os._exit``, a crash in C code) costs that job alone. The checks of a
candidate solution (its confirmation, the holds test, the simplification of the FSA the
run would write and the final fresh-episode check) run the task too, and in the evolving
process they would take the whole run down with them, without a word, and again on every
resume. On those backends they run here instead: one child process, started with the run,
holding the task (rebuilt from its module and settings, as a pool worker does) and its
genome compiler. A check that kills the child returns ``None``: its caller scores it as
failed and counts it as ``lost``, and the next check starts a new child. So does a check
whose episode runs past the evaluation time limit where no signal stops it (code that
blocks ``SIGALRM``, a wait in C): the child notes when each episode started
(:attr:`~.evaluation.Guard.watch`), and the parent kills it once an episode is past the
limit and a grace (:func:`check_kill_after`), as the pool kills a worker; that check counts
as a time-out.

The checks are the same functions on every backend (the serial backend calls them in the
evolving process), drawing the same worlds from the same seeds, so a run is the same
wherever they run. A process pool of one worker from the standard library does the work;
the child ignores Ctrl-C (the parent answers it) and dies with the parent.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from skillcompose.task import Task, TaskRef

from .evaluation import Guard
from .genome import SkillSet
from .pool import _die_with_parent, _init_worker

__all__ = ["IsolatedChecks", "check_kill_after"]

T = TypeVar("T")

_CHILD: dict[str, Any] = {}
"""The child's task and compiler: a process pool's initializer can leave them nowhere else."""


def _start(source: TaskRef | Task, shape: tuple[tuple[str, ...], bool], parent: int,
           watch: Any) -> None:
    """The child's initializer: ignore Ctrl-C, die with the parent, note each episode's
    start in ``watch``, build the task."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(parent, ())
    Guard.watch = watch
    _CHILD["task"], _CHILD["compiler"] = _init_worker(source, shape)


def _call(fn: Callable[..., T], args: tuple[Any, ...]) -> T:
    """Run ``fn(task, compiler, *args)`` in the child."""
    return fn(_CHILD["task"], _CHILD["compiler"], *args)


def check_kill_after(time_limit: float | None) -> float | None:
    """When the parent kills the checks' child whose episode has been armed that long [s]:
    the limit plus max(5 s, half the limit). More grace than the pool gives a worker: an
    episode that times out in the child scores worst alone, while a killed child fails its
    whole check, so the child's own alarm (a tick after the limit at most) must come
    first, even on a loaded machine. None: no limit."""
    return None if time_limit is None else time_limit + max(5.0, 0.5 * time_limit)


class IsolatedChecks:
    """Runs ``fn(task, compiler, *args)`` in a child process (module docstring); kills it
    when an episode has been armed for longer than ``kill_after`` seconds (None: never)."""

    def __init__(self, task: Task, skills: SkillSet, kill_after: float | None = None) -> None:
        methods = multiprocessing.get_all_start_methods()
        # the first child is forked (fast, and a task built in Python needs it); one that
        # replaces a dead child is spawned when the task can be rebuilt from its module,
        # because the run's threads are running by then, and a child forked while another
        # thread holds a lock can wait for it for ever
        self._ctx: Any = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
        self._again: Any = multiprocessing.get_context(
            "spawn" if task.ref is not None or "fork" not in methods else "fork")
        self._source: TaskRef | Task = task.ref if task.ref is not None else task
        self._shape = skills.shape
        self._pool: ProcessPoolExecutor | None = None
        self._pid = 0
        self._watch: Any = self._ctx.RawValue("d", -1.0)
        self.kill_after = kill_after
        self.deaths = 0  # checks that killed the child
        self.overran = 0  # checks killed because an episode ran past the limit
        self.last_overran = False  # whether the last call that returned None was one

    def _open(self) -> ProcessPoolExecutor:
        if self._pool is None:
            self._watch.value = -1.0
            self._pool = ProcessPoolExecutor(
                1, mp_context=self._again if self.deaths else self._ctx, initializer=_start,
                initargs=(self._source, self._shape, os.getpid(), self._watch))
            self._pid = self._pool.submit(os.getpid).result()
        return self._pool

    def start(self) -> None:
        """Start the child now, before the run starts any thread (a progress bar's, a
        pool's); :meth:`call` starts one otherwise."""
        self._open()

    def call(self, fn: Callable[..., T], *args: Any) -> T | None:
        """``fn(task, compiler, *args)`` in the child; None when the child died running it,
        or was killed because an episode ran past the limit (:attr:`last_overran`; a new
        child starts for the next call). ``fn`` must be a module-level function and catch
        its own episodes' faults, as :func:`~.evaluation.iter_episodes` does."""
        pool = self._open()
        tick = None if self.kill_after is None else min(1.0, self.kill_after / 4)
        killed = False
        try:
            future = pool.submit(_call, fn, args)
            while True:
                try:
                    got = future.result(timeout=tick)
                    if killed:  # it finished as it was killed: a new child for the next
                        self.close()
                    return got
                except FutureTimeout:
                    started = self._watch.value
                    if not killed and self.kill_after is not None and started >= 0 and \
                            time.monotonic() - started > self.kill_after:
                        killed = True
                        with contextlib.suppress(ProcessLookupError):
                            os.kill(self._pid, signal.SIGKILL)
        except BrokenProcessPool:
            self.deaths += 1
            self.overran += killed
            self.last_overran = killed
            self.close()
            return None
        except BaseException:  # interrupted while the child works: it may never finish
            with contextlib.suppress(ProcessLookupError):
                os.kill(self._pid, signal.SIGKILL)
            self.close()
            raise

    def close(self) -> None:
        """End the child (if any)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
