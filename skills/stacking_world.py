"""The stacking world (section 4.3) as both backends' skills see it: the objects, what a
gripper holds, when one object stands on another, where MoveToReach aims, and the parameter
declarations GraspParam and MoveGripperToStack share on both backends.

The ``sim`` skills (:mod:`skillcompose.skills.stacking`) and their kinematic twins
(:mod:`skillcompose.skills.kinematic`, :mod:`skillcompose.skills.stacking_kinematic`) import
this module; it imports none of them, so the backends' modules form no circle.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Annotated, Literal

from skillcompose import Blackboard, Param
from skillcompose.robots.collision import Box
from skillcompose.skills.move_to_push import classifier_label

__all__ = [
    "ARMS",
    "DEFAULT_HALF_EXTENTS_M",
    "HELD_KEYS",
    "STACK_TOLERANCE_M",
    "TOUCH_M",
    "Arm",
    "StackDX",
    "StackDY",
    "StackDZ",
    "Vec3",
    "Which",
    "as_vec3",
    "held",
    "landing_z",
    "object_boxes",
    "reach_arms",
    "reach_goal",
    "reach_label",
    "reach_target",
    "stacked",
    "supports",
    "which_name",
]

Vec3 = tuple[float, float, float]
Arm = Literal["left", "right"]

HELD_KEYS: dict[Arm, str] = {"left": "held_object_left", "right": "held_object_right"}
DEFAULT_HALF_EXTENTS_M: Vec3 = (0.03, 0.03, 0.06)
"""Half sizes of an object that ``object_half_extents_m`` does not list [m]."""
STACK_TOLERANCE_M = 0.01
"""An object stands on another when its bottom is this close to the other's top [m]."""
TOUCH_M = 0.002
"""Boxes may touch (stand stacked) within this much overlap [m]."""
ARMS: tuple[Arm, Arm] = ("left", "right")
"""Both arms, left first."""

Which = Annotated[float, Param(0.0, 1.0, doc="> 0.5: the first object, else the second")]
StackDX = Annotated[float, Param(-0.2, 0.2, unit="m", doc="x offset from the object")]
StackDY = Annotated[float, Param(-0.2, 0.2, unit="m", doc="y offset from the object")]
StackDZ = Annotated[float, Param(0.0, 0.3, unit="m", doc="z offset from the object")]
"""GraspParam's and MoveGripperToStack's parameters, declared once for both backends."""


def as_vec3(values: Sequence[float]) -> Vec3:
    return (float(values[0]), float(values[1]), float(values[2]))


def held(bb: Blackboard) -> tuple[Arm, str] | None:
    """(arm, object) of the gripper holding an object, or None."""
    for arm in ARMS:
        name = bb.get(HELD_KEYS[arm])
        if name is not None:
            return arm, str(name)
    return None


def object_boxes(bb: Blackboard) -> dict[str, Box]:
    """Each object as an upright box at its current position."""
    sizes: Mapping[str, Sequence[float]] = bb.get("object_half_extents_m") or {}
    return {
        name: Box(as_vec3(p), as_vec3(sizes.get(name, DEFAULT_HALF_EXTENTS_M)), 0.0, name)
        for name, p in bb["object_positions_world"].items()
    }


def which_name(bb: Blackboard, which: float) -> str | None:
    names = list(bb.get("object_positions_world") or {})
    if len(names) < 2:
        return None
    return str(names[0] if which > 0.5 else names[1])


def supports(lower: Box, upper: Box) -> bool:
    """Whether ``upper`` stands on ``lower``: bottom on top, centre over the top face."""
    gap = (upper.center_m[2] - upper.half_extents_m[2]) - (
        lower.center_m[2] + lower.half_extents_m[2])
    return abs(gap) <= STACK_TOLERANCE_M and all(
        abs(upper.center_m[i] - lower.center_m[i]) <= lower.half_extents_m[i] for i in (0, 1)
    )


def stacked(bb: Blackboard) -> bool:
    """Whether one object stands on another and no gripper holds either."""
    if held(bb) is not None:
        return False
    boxes = list(object_boxes(bb).values())
    return any(supports(a, b) for a in boxes for b in boxes if a is not b)


def reach_target(bb: Blackboard) -> tuple[str, Vec3] | None:
    """What MoveToReach moves the robot to: with an object held, the other object (where it
    will be stacked); empty-handed, the object GraspParam last tried to grasp
    (``grasp_target``), else the first. None without two objects."""
    positions = bb.get("object_positions_world") or {}
    names = list(positions)
    if len(names) < 2:
        return None
    holding = held(bb)
    if holding is None:
        tried = bb.get("grasp_target")
        name = tried if tried in positions else names[0]
    else:
        name = names[1] if holding[1] == names[0] else names[0]
    return str(name), as_vec3(positions[name])


def reach_label(bb: Blackboard, position: Sequence[float]) -> int:
    base = bb.get("base_pose_world") or (0.0, 0.0, 0.0)
    return classifier_label(base, float(bb.get("torso_height_m", 0.0)), position)


def landing_z(box: Box, others: Sequence[Box]) -> float:
    """Centre height of ``box`` dropped straight down onto the highest surface under it
    (the floor at z = 0 else): OpenGripper's rule on both backends."""
    bottom = box.center_m[2] - box.half_extents_m[2]
    surfaces = [0.0]
    for other in others:
        overlap = all(abs(box.center_m[i] - other.center_m[i])
                      < box.half_extents_m[i] + other.half_extents_m[i] for i in (0, 1))
        top = other.center_m[2] + other.half_extents_m[2]
        if overlap and top <= bottom + TOUCH_M:
            surfaces.append(top)
    return max(surfaces) + box.half_extents_m[2]


def reach_goal(bb: Blackboard) -> tuple[str, Vec3] | None:
    """Where MoveToReach must bring the gripper into reach: empty-handed, the centre of the
    object of :func:`reach_target`; with an object held, the point above that object where the
    held object's centre stands when it stands on it. None without two objects."""
    target = reach_target(bb)
    if target is None:
        return None
    name, position = target
    holding = held(bb)
    if holding is None:
        return target
    boxes = object_boxes(bb)
    rise = boxes[name].half_extents_m[2] + boxes[holding[1]].half_extents_m[2]
    return name, (position[0], position[1], position[2] + rise)


def reach_arms(bb: Blackboard) -> tuple[Arm, ...]:
    """The arms that may do the reaching: the one holding an object, else either."""
    holding = held(bb)
    return (holding[0],) if holding is not None else ARMS
