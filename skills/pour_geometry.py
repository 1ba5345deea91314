"""The pour-water world's geometry and the pouring skills' parameters, shared by the
abstract skills (:mod:`skillcompose.skills.pour_water`), their kinematic and dynamic twins and
the robot check (:mod:`skillcompose.skills.pour_robot`): what "the water is in the glass"
means and the ranges every backend declares alike. The rule is explained in
:mod:`skillcompose.skills.pour_water`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Annotated

from skillcompose import Param

__all__ = [
    "APPROACH_OFFSET_M",
    "APPROACH_TOLERANCE_M",
    "POUR_HEIGHT_MAX_M",
    "POUR_HEIGHT_MIN_M",
    "POUR_RADIUS_M",
    "POUR_TILT_MAX_RAD",
    "POUR_TILT_MIN_RAD",
    "WORKSPACE_WORLD",
    "GripperX",
    "GripperY",
    "GripperZ",
    "Pitch",
    "Roll",
    "Vec3",
    "Yaw",
    "distance",
    "pours_into_glass",
    "tilt",
]

Vec3 = tuple[float, float, float]

APPROACH_TOLERANCE_M = 0.10
"""GraspObject needs the gripper this close to the jug (the paper's 10 cm)."""
APPROACH_OFFSET_M = 0.06
"""MoveToObject stops this far in front of the jug (−x of the world), inside the tolerance."""
POUR_RADIUS_M = 0.04
"""Horizontal distance from the spout to the rim's centre that still hits the glass."""
POUR_HEIGHT_MIN_M = 0.0
"""The spout must not be below the rim (level with it pours; see the module docstring)."""
POUR_HEIGHT_MAX_M = 0.15
"""From higher than this above the rim the water splashes out."""
POUR_TILT_MIN_RAD = math.pi / 3
"""A held jug starts pouring at this tilt from upright."""
POUR_TILT_MAX_RAD = 2 * math.pi / 3
"""Beyond this tilt the water leaves through the whole mouth and misses the glass."""
WORKSPACE_WORLD = ((0.20, 1.00), (-0.60, 0.60), (0.75, 1.50))
"""Where MoveGripperToParam may send the gripper: (x, y, z) ranges in the world frame [m].
The table top is at z = 0.75 m."""

_X_M, _Y_M, _Z_M = WORKSPACE_WORLD
_PI = math.pi

# The parameter declarations of MoveGripperToParam and RotateGripperToParam, shared with
# their twins on other backends (which must declare exactly the same ranges).
GripperX = Annotated[float, Param(_X_M[0], _X_M[1], unit="m", doc="gripper x, world frame")]
GripperY = Annotated[float, Param(_Y_M[0], _Y_M[1], unit="m", doc="gripper y, world frame")]
GripperZ = Annotated[float, Param(_Z_M[0], _Z_M[1], unit="m", doc="gripper z, world frame")]
Roll = Annotated[float, Param(-_PI, _PI, unit="rad", doc="roll about world x")]
Pitch = Annotated[float, Param(-_PI, _PI, unit="rad", doc="pitch about world y")]
Yaw = Annotated[float, Param(-_PI, _PI, unit="rad", doc="yaw about world z")]


def distance(a: Sequence[float], b: Sequence[float]) -> float:
    """Euclidean distance between two points [m]."""
    return math.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)


def tilt(rotation: Sequence[float]) -> float:
    """Angle between the gripper's z axis and the vertical for roll-pitch-yaw ``rotation``
    [rad]: ``arccos(cos ρ · cos φ)``, in [0, π]."""
    c = math.cos(rotation[0]) * math.cos(rotation[1])
    return math.acos(-1.0 if c < -1.0 else 1.0 if c > 1.0 else c)


def pours_into_glass(spout_world: Sequence[float], glass_world: Sequence[float]) -> bool:
    """True when water leaving a spout at ``spout_world`` lands in the glass at
    ``glass_world`` (both in the world frame [m])."""
    dx = spout_world[0] - glass_world[0]
    dy = spout_world[1] - glass_world[1]
    dz = spout_world[2] - glass_world[2]
    return dx * dx + dy * dy <= POUR_RADIUS_M**2 and POUR_HEIGHT_MIN_M <= dz <= POUR_HEIGHT_MAX_M
