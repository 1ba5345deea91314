"""A task's runner: the checks of :mod:`skillcompose.testing` bound to one task and backend,
as the pytest fixture ``skillcompose_runner`` gives them."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from ..blackboard import Blackboard
from ..task import Task
from .assertions import RateCheck, assert_outcome, assert_success_rate
from .episodes import Episode, FSALike, episode_world, run_episode, run_episodes

__all__ = ["TaskRunner"]


class TaskRunner:
    """Runs FSAs (objects or files) on ``task``'s seeded worlds with ``backend`` (default:
    the task's); each method takes another ``backend`` for one call."""

    def __init__(self, task: Task, backend: str | None = None) -> None:
        self.task = task
        self.backend = backend

    def __call__(self, fsa: FSALike, seeds: int | Iterable[int] = 0, *,
                 backend: str | None = None, trace: bool = True) -> list[Episode]:
        """The episodes of ``seeds`` (one seed or several), traced unless ``trace=False``,
        each with its final blackboard."""
        chosen = (seeds,) if isinstance(seeds, int) else seeds
        return list(run_episodes(fsa, self.task, chosen, backend=backend or self.backend,
                                 trace=trace, keep_blackboard=True))

    def episode(self, fsa: FSALike, seed: int = 0, *, backend: str | None = None) -> Episode:
        """The episode of ``seed``, traced, with its final blackboard."""
        return run_episode(fsa, self.task, seed, backend=backend or self.backend)

    def world(self, seed: int = 0) -> Blackboard:
        """The world the episode of ``seed`` starts from."""
        return episode_world(self.task, seed)

    def assert_success_rate(self, fsa: FSALike, at_least: float | None = None,
                            confidence: float = 0.95, **options: Any) -> RateCheck:
        """:func:`~skillcompose.testing.assert_success_rate` on this task."""
        __tracebackhide__ = True
        options.setdefault("backend", self.backend)
        return assert_success_rate(fsa, self.task, at_least, confidence, **options)

    def assert_outcome(self, fsa: FSALike, seed: int, outcome: str, *,
                       backend: str | None = None) -> Episode:
        """:func:`~skillcompose.testing.assert_outcome` on this task."""
        __tracebackhide__ = True
        return assert_outcome(fsa, self.task, seed, outcome, backend=backend or self.backend)

    def __repr__(self) -> str:
        return f"<TaskRunner task={self.task.name} backend={self.backend or self.task.backend}>"
