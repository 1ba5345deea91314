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
failed and counts it as ``lost``, and the next check starts a new child.

The checks are the same functions on every backend (the serial backend calls them in the
evolving process), drawing the same worlds from the same seeds, so a run is the same
wherever they run. A process pool of one worker from the standard library does the work;
the child ignores Ctrl-C (the parent answers it) and dies with the parent.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from skillcompose.task import Task, TaskRef

from .genome import SkillSet
from .pool import _die_with_parent, _init_worker

__all__ = ["IsolatedChecks"]

T = TypeVar("T")

_CHILD: dict[str, Any] = {}
"""The child's task and compiler: a process pool's initializer can leave them nowhere else."""


def _start(source: TaskRef | Task, shape: tuple[tuple[str, ...], bool], parent: int) -> None:
    """The child's initializer: ignore Ctrl-C, die with the parent, build the task."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(parent, ())
    _CHILD["task"], _CHILD["compiler"] = _init_worker(source, shape)


def _call(fn: Callable[..., T], args: tuple[Any, ...]) -> T:
    """Run ``fn(task, compiler, *args)`` in the child."""
    return fn(_CHILD["task"], _CHILD["compiler"], *args)


class IsolatedChecks:
    """Runs ``fn(task, compiler, *args)`` in a child process (module docstring)."""

    def __init__(self, task: Task, skills: SkillSet) -> None:
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
        self.deaths = 0  # checks that killed the child

    def _open(self) -> ProcessPoolExecutor:
        if self._pool is None:
            self._pool = ProcessPoolExecutor(
                1, mp_context=self._again if self.deaths else self._ctx, initializer=_start,
                initargs=(self._source, self._shape, os.getpid()))
        return self._pool

    def start(self) -> None:
        """Start the child now, before the run starts any thread (a progress bar's, a
        pool's); :meth:`call` starts one otherwise."""
        self._open().submit(int).result()

    def call(self, fn: Callable[..., T], *args: Any) -> T | None:
        """``fn(task, compiler, *args)`` in the child; None when the child died running it
        (a new one starts for the next call). ``fn`` must be a module-level function and
        catch its own episodes' faults, as :func:`~.evaluation.iter_episodes` does."""
        pool = self._open()
        try:
            return pool.submit(_call, fn, args).result()
        except BrokenProcessPool:
            self.deaths += 1
            self.close()
            return None

    def close(self) -> None:
        """End the child (if any)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
