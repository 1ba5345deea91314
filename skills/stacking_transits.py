"""The stacking arm's joint-space motions in the simulated scene: checks and detours.

What :mod:`skillcompose.skills.stacking_dynamic` moves between its waypoints is the
servo's straight line in joint space (:func:`~skillcompose.skills.dynamic_world.execute`);
here it is checked against the simulated table and objects at sample points
(:func:`line_touches_table`, by
:func:`~skillcompose.skills.dynamic_world.arm_touches_table`), and a motion that would touch
them goes round: over them with the shoulder lifted (:func:`over`), else with the torso
raised (:func:`hop`; :func:`clear_transits`). A tucked arm unfolds the first clear of a few
ways (:func:`unfold_route`). Nothing here moves the robot: it poses copies of the
simulation's state.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from itertools import pairwise

import numpy as np

from skillcompose.robots.model import Arm
from skillcompose.robots.physics import PhysicsWorld
from skillcompose.skills.dynamic_world import TABLE_GAP_M, arm_touches_table
from skillcompose.skills.kinematic_world import TORSO_RANGE_M, RobotState

__all__ = [
    "CONTINUOUS",
    "RAISE_RAD",
    "TRANSIT_SAMPLES",
    "UNFOLD_GAP_M",
    "UNFOLD_PAN_RAD",
    "clear_transits",
    "hop",
    "line_touches_table",
    "over",
    "touches",
    "unfold_route",
    "with_arm",
    "wrap",
]

TRANSIT_SAMPLES = 10
"""A joint-space motion between waypoints is checked against the simulated table at this
many points along it."""
RAISE_RAD = (0.0, 0.3, 0.6)
"""A motion whose joint-space line touches the table goes first to its goal with the
shoulder lifted: by these amounts above the higher of its two ends [rad], the first clear."""
SHOULDER_PAN = 0
"""The shoulder pan's index among an arm's joints (positive: to the robot's left)."""
UNFOLD_PAN_RAD = (0.8, 1.2)
"""An arm whose unfolding would sweep the table may unfold with its shoulder panned this far
out [rad] (:func:`unfold_route`) ..."""
UNFOLD_GAP_M = 0.02
"""... each way checked to keep the arm this far from the table and the objects first [m]
(the unfolding is fast, and the servos lag its joint-space line) ..."""
UNFOLD_SAMPLES = 20
"""... at this many points along each of its motions."""
WRIST = 4
"""The first wrist joint's index among an arm's joints (forearm roll; then wrist flex and
roll)."""
SHOULDER_LIFT = 1
"""The shoulder lift's index among an arm's joints (larger: lower)."""
SHOULDER_LIFT_MIN_RAD = -0.5
HOP_TORSO_M = TORSO_RANGE_M[1]
"""A motion that cannot pass over the table with the shoulder lifted passes with the torso
raised this high [m] (:func:`hop`) ..."""
HOP_MIN_M = 0.05
"""... when that is at least this much above both its ends [m]."""
CONTINUOUS = (4, 6)
"""The continuous joints' indices among an arm's joints (forearm and wrist roll), which
turn the short way round."""


def with_arm(state: RobotState, arm: Arm, q: Sequence[float]) -> RobotState:
    """``state`` with ``arm``'s joints at ``q``."""
    return RobotState(state.base_pose_world, state.torso_height_m,
                      {**state.q_arm_rad, arm: tuple(q)}, state.held, state.arm_in_use)


def line_touches_table(physics: PhysicsWorld, a: RobotState, b: RobotState, arm: Arm, *,
                       samples: int = TRANSIT_SAMPLES, objects: Sequence[str] = (),
                       carried: str | None = None, gap_m: float = TABLE_GAP_M) -> bool:
    """Whether ``arm`` touches the simulated table (or one of ``objects``) somewhere on the
    motion from ``a`` to ``b`` as :func:`~skillcompose.skills.dynamic_world.execute` makes
    it (at ``b``'s base; the ends excluded): the servo's straight line in joint space, at
    ``b``'s torso when the torso rises (it rises first) and at ``a``'s when it lowers (it
    lowers last), and the torso's own vertical motion, each checked at ``samples`` points;
    with ``carried``, the object the arm holds is checked against ``objects`` too; "touches":
    comes within ``gap_m``."""
    qa, qb = a.q_arm_rad[arm], b.q_arm_rad[arm]
    delta = [wrap(y - x) if j in CONTINUOUS else y - x
             for j, (x, y) in enumerate(zip(qa, qb, strict=True))]
    za, zb = a.torso_height_m, b.torso_height_m
    lowers = zb < za
    inner = [k / samples for k in range(1, samples)]

    def at(q: Sequence[float], z: float) -> RobotState:
        return dataclasses.replace(with_arm(b, arm, q), torso_height_m=z)

    arm_line = [at([x + t * d for x, d in zip(qa, delta, strict=True)], za if lowers else zb)
                for t in inner] if any(abs(d) > 1e-9 for d in delta) else []
    torso_line = [at(qb if lowers else qa, za + t * (zb - za)) for t in inner] \
        if abs(zb - za) > 1e-9 else []
    corner = [at(qb, za) if lowers else at(qa, zb)] if arm_line and torso_line else []
    poses = [*arm_line, *corner, *torso_line] if lowers else \
        [*torso_line, *corner, *arm_line]
    return any(touches(physics, s, arm, objects, carried, gap_m) for s in poses)


def wrap(angle: float) -> float:
    """``angle`` wrapped to [-pi, pi) [rad]."""
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def clear_transits(physics: PhysicsWorld, arm: Arm, start: RobotState,
                   waypoints: Sequence[RobotState], *, objects: Sequence[str] = (),
                   carried: str | None = None) -> list[RobotState]:
    """``waypoints`` (from ``start``), with configurations inserted before each whose motion
    touches the simulated table or one of ``objects`` (the arm, or the object it has
    ``carried``): over it with the shoulder lifted
    (:func:`over`), else over it with the torso raised (:func:`hop`); the waypoint left as
    it is when there are none."""
    out: list[RobotState] = []
    at = start
    for goal in waypoints:
        if line_touches_table(physics, at, goal, arm, objects=objects, carried=carried):
            out.extend(over(physics, arm, at, goal, objects, carried)
                       or hop(physics, arm, at, goal, objects, carried))
        out.append(goal)
        at = goal
    return out


def touches(physics: PhysicsWorld, state: RobotState, arm: Arm,
             objects: Sequence[str], carried: str | None = None,
             gap_m: float = TABLE_GAP_M) -> bool:
    """Whether ``arm`` at ``state`` comes within ``gap_m`` of the simulated table or
    ``objects`` (or ``carried`` of ``objects``)."""
    return bool(arm_touches_table(physics, state, arm, objects=objects, carried=carried,
                                  gap_m=gap_m))


def over(physics: PhysicsWorld, arm: Arm, start: RobotState, goal: RobotState,
          objects: Sequence[str] = (), carried: str | None = None) -> list[RobotState]:
    """The configurations to pass from ``start`` to ``goal`` over the table: ``goal``'s
    joints with the shoulder lifted (:data:`RAISE_RAD`), else ``start``'s lifted and then
    ``goal``'s, the first whose motions are all clear of the simulated table and
    ``objects`` (but for lifting off it, when ``start`` touches it); none when there is no
    such."""
    for extra in RAISE_RAD:
        lift = max(SHOULDER_LIFT_MIN_RAD, min(start.q_arm_rad[arm][SHOULDER_LIFT],
                                              goal.q_arm_rad[arm][SHOULDER_LIFT]) - extra)
        raised = []
        for end in (start, goal):
            q = list(end.q_arm_rad[arm])
            q[SHOULDER_LIFT] = lift
            raised.append(with_arm(goal, arm, q))
        for via in ([raised[1]], raised):
            if any(touches(physics, s, arm, objects, carried) for s in via):
                continue
            legs = list(pairwise([start, *via, goal]))
            if len(via) == 2 and touches(physics, start, arm, objects, carried):
                legs = legs[1:]  # lifting off the table it touches already
            if not any(line_touches_table(physics, a, b, arm, objects=objects,
                                          carried=carried) for a, b in legs):
                return via
    return []


def hop(physics: PhysicsWorld, arm: Arm, start: RobotState, goal: RobotState,
         objects: Sequence[str] = (), carried: str | None = None) -> list[RobotState]:
    """The configurations to pass from ``start`` to ``goal`` with the torso raised to the
    top (:data:`HOP_TORSO_M`): the torso rises (the whole arm straight up), the arm moves up
    there, and the torso comes down onto ``goal`` (straight down); none when the torso is
    not :data:`HOP_MIN_M` higher so, or a motion on the way touches the simulated table or
    ``objects`` (lifting off what ``start`` touches aside)."""
    top = HOP_TORSO_M
    if top - max(start.torso_height_m, goal.torso_height_m) < HOP_MIN_M:
        return []
    up = dataclasses.replace(with_arm(goal, arm, start.q_arm_rad[arm]), torso_height_m=top)
    across = dataclasses.replace(goal, torso_height_m=top)
    if touches(physics, up, arm, objects, carried) or \
            touches(physics, across, arm, objects, carried):
        return []
    if line_touches_table(physics, up, across, arm, objects=objects, carried=carried) or \
            line_touches_table(physics, across, goal, arm, objects=objects, carried=carried):
        return []
    return [up, across]


def unfold_route(physics: PhysicsWorld, arm: Arm, start: RobotState, goal: RobotState,
                  objects: Sequence[str]) -> list[RobotState]:
    """The arm's configurations from tucked (``start``) to unfolded (``goal``), ``goal``
    last: the first of these ways whose every configuration and joint-space line stays
    :data:`UNFOLD_GAP_M` (else :data:`~skillcompose.skills.dynamic_world.TABLE_GAP_M`) clear
    of the simulated table and ``objects`` (checked at :data:`UNFOLD_SAMPLES` points): straight
    in joint space; the wrist first (forearm roll, wrist flex and roll to their unfolded
    angles, then the rest); with the shoulder panned out by one of :data:`UNFOLD_PAN_RAD`
    (the arm turns out, unfolds beside the robot, and turns back in level); else over them
    with the shoulder lifted (:func:`over`), else straight. With the base near the table,
    the straight unfolding swept the elbow through the table's edge, or the hand through an
    object, which it knocked over; the arm then stayed jammed on the table."""
    wrist = list(start.q_arm_rad[arm])
    wrist[WRIST:] = goal.q_arm_rad[arm][WRIST:]
    ways: list[list[RobotState]] = [[], [with_arm(goal, arm, wrist)]]
    outward = 1.0 if arm == "left" else -1.0
    for pan in UNFOLD_PAN_RAD:
        out = []
        for end in (start, goal):
            q = list(end.q_arm_rad[arm])
            q[SHOULDER_PAN] = outward * pan
            out.append(with_arm(goal, arm, q))
        ways.append(out)
    for gap in (UNFOLD_GAP_M, TABLE_GAP_M):
        for via in ways:
            if any(touches(physics, s, arm, objects, gap_m=gap) for s in via):
                continue
            if not any(line_touches_table(physics, a, b, arm, objects=objects, gap_m=gap,
                                          samples=UNFOLD_SAMPLES)
                       for a, b in pairwise([start, *via, goal])):
                return [*via, goal]
    return [*over(physics, arm, start, goal, objects), goal]
