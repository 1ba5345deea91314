"""One episode run step by step for the replay page: the trace, the blackboard after each
step, and, on a kinematic task, the robot and the world at each step; on the dynamic
backend also the simulation at sub-steps of each step (every :data:`SUBSTEP_S` of
simulated time), so that a push or a topple is seen as it happened.

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

__all__ = ["KINEMATIC_KEYS", "MAX_STEPS", "SUBSTEP_S", "Episode", "Frame", "run_episode",
           "short"]

MAX_STEPS = 2000  # an episode longer than this is cut (a step limit set very high)
KINEMATIC_KEYS = ("base_pose_world", "q_left_arm_rad", "q_right_arm_rad")
SUBSTEP_S = 0.25
"""Simulated seconds between the sub-step frames of a dynamic episode."""


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
    # on the dynamic backend: (simulated time [s], robot3d.frame_at()) during this step
    substeps: tuple[tuple[float, Mapping[str, Any]], ...] = ()


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
    the task's); ``robot`` (default: on the kinematic and dynamic backends, or when the
    blackboard holds the kinematic skills' robot keys) adds the PR2 at each step, and on the
    dynamic backend the simulation's samples within each step (``Frame.substeps``).
    ``fsa``: the file's FSA, read already (the viewer reads files only inside its folder);
    then ``path`` only names it.
    Raises ``SkillcomposeError`` (one line) for a file, task or setting that is wrong."""
    fsa = load_fsa(path) if fsa is None else fsa
    task = load_task(task_target, **dict(settings or {}))
    if backend:
        check_backend(task.registry, backend)  # as `skillcompose run --backend` does
    compiled = task.compile(fsa, backend or None)
    rng = next(iter(trial_rngs(seed, 1)))

    rec = _Recording.of(task) if compiled.backend == "dynamic" and robot is not False \
        else None
    if rec is not None:
        rec.start()  # before the setup, which starts the simulated episode
    try:
        bb = task.setup(rng) if task.setup is not None else Blackboard()
        kinematic = robot if robot is not None else (
            compiled.backend in ("kinematic", "dynamic")
            or any(k in bb for k in KINEMATIC_KEYS))
        place: Callable[[Blackboard], dict[str, Any]] | None = None
        if kinematic:
            from .robot3d import frame  # loads Pinocchio

            place = frame
        frames = [Frame(0, None, None, None, fsa.start, {}, _shown(bb),
                        place(bb) if place else None, rec.take() if rec else ())]
        run = compiled.start(bb, rng, trace=True)
        status = RUNNING
        seen = 0
        while status == RUNNING and seen < MAX_STEPS:
            try:
                status = run.tick()
            except KeyboardInterrupt:
                raise
            except BaseException:  # sys.exit() in a skill: the run has ended in error, and
                status = run.result.outcome  # its last step says where; the viewer goes on
            trace = run.trace or ()
            for ev in trace[seen:]:
                frames.append(Frame(
                    ev.step, ev.state, ev.skill, ev.outcome, ev.target,
                    {k: (short(old), short(new)) for k, (old, new) in ev.changes.items()},
                    _shown(bb), place(bb) if place else None, rec.take() if rec else ()))
            seen = len(trace)
        if not run.done:
            run.preempt()
    finally:
        if rec is not None:
            rec.stop()
    result = run.result
    return Episode(fsa, Path(path), task.name, compiled.backend, seed, tuple(frames),
                   result.outcome, result.steps, bool(kinematic))


class _Recording:
    """The simulation's recording of a dynamic episode, taken step by step as sub-frames."""

    def __init__(self, world: Any) -> None:
        from skillcompose.robots.physics import PoseRecorder

        self.world = world
        self.recorder = PoseRecorder(every_s=SUBSTEP_S)
        self.taken = 0

    @classmethod
    def of(cls, task: Any) -> _Recording | None:
        from skillcompose.skills.dynamic_world import world_of

        world = world_of(task.registry)
        return None if world is None else cls(world)

    def start(self) -> None:
        self.world.recorder = self.recorder

    def stop(self) -> None:
        self.world.recorder = None

    def take(self) -> tuple[tuple[float, Mapping[str, Any]], ...]:
        """The samples recorded since the last call, as 3D frames."""
        from skillcompose.skills.replay import _recorded_scene

        from .robot3d import frame_at

        rec, out = self.recorder, []
        for k in range(self.taken, len(rec.times_s)):
            scene, particles = _recorded_scene(self.world, rec, k)
            out.append((rec.times_s[k], frame_at(rec.robot[k], scene, particles)))
        self.taken = len(rec.times_s)
        return tuple(out)
