"""One episode run step by step for the replay page: the trace, the blackboard after each
step, and, on a kinematic task, the robot and the world at each step.

The episode is the first trial of ``seed``: the world and the run ``skillcompose run FILE
--task T --seed N --trace`` prints, advanced one step at a time by the tick-wise engine
(``CompiledFSA.start``), so each frame holds the blackboard exactly as its step left it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from skillcompose import RUNNING, Blackboard, load_fsa, load_task
from skillcompose.blackboard import DELETED
from skillcompose.executor import trial_rngs
from skillcompose.fsa import FSA
from skillcompose.registry import check_backend

__all__ = ["KINEMATIC_KEYS", "MAX_STEPS", "Episode", "Frame", "run_episode", "short"]

MAX_STEPS = 2000  # an episode longer than this is cut (a step limit set very high)
KINEMATIC_KEYS = ("base_pose_world", "q_left_arm_rad", "q_right_arm_rad")


def short(value: Any, n: int = 80) -> str:
    """A value as the pages show it: its repr, cut to ``n`` characters."""
    if value is DELETED:
        return "∅ (deleted)"
    text = repr(value)
    return text if len(text) <= n else text[: n - 3] + "..."


@dataclass(frozen=True)
class Frame:
    """The world after ``number`` steps (0: before the first)."""

    number: int
    state: str | None  # the state that ran in this step
    skill: str | None
    outcome: str | None
    target: str | None  # the next state or terminal outcome
    changes: Mapping[str, tuple[str, str]]  # key -> (before, after), shown
    blackboard: Mapping[str, str]  # every key after the step, shown
    robot: Mapping[str, Any] | None = None  # robot3d.frame(), on a kinematic task


@dataclass(frozen=True)
class Episode:
    fsa: FSA
    path: Path
    task: str
    backend: str
    seed: int
    frames: tuple[Frame, ...]
    outcome: str
    steps: int
    kinematic: bool


def _shown(bb: Blackboard) -> dict[str, str]:
    return {k: short(v) for k, v in sorted(bb.to_dict().items())}


def run_episode(path: Path, task_target: str, seed: int = 0,
                settings: Mapping[str, Any] | None = None, *, backend: str | None = None,
                robot: bool | None = None, fsa: FSA | None = None) -> Episode:
    """Run the FSA file at ``path`` once on task ``task_target`` (on ``backend``, default
    the task's); ``robot`` (default: when
    the blackboard holds the kinematic skills' robot keys) adds the PR2 at each step.
    ``fsa``: the file's FSA, read already (the viewer reads files only inside its folder);
    then ``path`` only names it.
    Raises ``SkillcomposeError`` (one line) for a file, task or setting that is wrong."""
    fsa = load_fsa(path) if fsa is None else fsa
    task = load_task(task_target, **dict(settings or {}))
    if backend:
        check_backend(task.registry, backend)  # as `skillcompose run --backend` does
    compiled = task.compile(fsa, backend or None)
    rng = next(iter(trial_rngs(seed, 1)))
    bb = task.setup(rng) if task.setup is not None else Blackboard()
    kinematic = robot if robot is not None else (
        compiled.backend == "kinematic" or any(k in bb for k in KINEMATIC_KEYS))
    place: Callable[[Blackboard], dict[str, Any]] | None = None
    if kinematic:
        from .robot3d import frame  # loads Pinocchio

        place = frame

    frames = [Frame(0, None, None, None, fsa.start, {}, _shown(bb),
                    place(bb) if place else None)]
    run = compiled.start(bb, rng, trace=True)
    status = RUNNING
    seen = 0
    while status == RUNNING and seen < MAX_STEPS:
        try:
            status = run.tick()
        except KeyboardInterrupt:
            raise
        except BaseException:  # sys.exit() in a skill: the run has ended in error, and its
            status = run.result.outcome  # last step says where; the viewer goes on
        trace = run.trace or ()
        for ev in trace[seen:]:
            frames.append(Frame(
                ev.step, ev.state, ev.skill, ev.outcome, ev.target,
                {k: (short(old), short(new)) for k, (old, new) in ev.changes.items()},
                _shown(bb), place(bb) if place else None))
        seen = len(trace)
    if not run.done:
        run.preempt()
    result = run.result
    return Episode(fsa, Path(path), task.name, compiled.backend, seed, tuple(frames),
                   result.outcome, result.steps, bool(kinematic))
