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

from skillcompose import Blackboard, Param

__all__ = [
    "APPROACH_OFFSET_M",
    "APPROACH_TOLERANCE_M",
    "GLASS_HALF_EXTENTS_M",
    "JUG_GRASP_ABOVE_CENTRE_M",
    "JUG_HALF_EXTENTS_M",
    "POUR_HEIGHT_MAX_M",
    "POUR_HEIGHT_MIN_M",
    "POUR_POINT_ABOVE_RIM_M",
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
    "glass_at",
    "held_jug_hits_glass",
    "pour_point",
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
JUG_HALF_EXTENTS_M = (0.035, 0.035, 0.038)
"""The jug's outside: 7 x 7 x 7.6 cm (half extents) [m]."""
JUG_GRASP_ABOVE_CENTRE_M = 0.026
"""Its grasp point (``jug_position_world``, held at the tool frame, the jug's axes along the
tool's) lies this far above its centre: 1.2 cm under the rim [m]."""
GLASS_HALF_EXTENTS_M = (0.045, 0.045, 0.06)
"""The glass's outside: 9 x 9 x 12 cm, its rim (``glass_position_world``) on top [m]."""
POUR_POINT_ABOVE_RIM_M = JUG_GRASP_ABOVE_CENTRE_M + JUG_HALF_EXTENTS_M[2]
"""Where an upright held jug comes closest to the glass from above: its spout this far over
the rim's centre (6.4 cm), the jug's bottom level with the rim [m]."""
JUG_GLASS_TOLERANCE_M = 0.001
"""A held jug may touch the glass by this much: it hits it when deeper [m]."""
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


def _rpy_matrix(rotation: Sequence[float]) -> tuple[tuple[float, float, float], ...]:
    """Roll, pitch, yaw about the fixed x, y, z axes: ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    cr, sr = math.cos(rotation[0]), math.sin(rotation[0])
    cp, sp = math.cos(rotation[1]), math.sin(rotation[1])
    cy, sy = math.cos(rotation[2]), math.sin(rotation[2])
    return ((cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
            (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
            (-sp, cp * sr, cp * cr))


def glass_at(bb: Blackboard) -> Sequence[float] | None:
    """Where a pour-water blackboard's glass is (``glass_position_world``), if it has one."""
    glass = bb.get("glass_position_world")
    return None if glass is None else tuple(float(v) for v in glass)


def held_jug_hits_glass(grasp_world: Sequence[float], rotation: Sequence[float],
                        glass_world: Sequence[float] | None) -> bool:
    """Whether the jug, held at ``grasp_world`` with the gripper at roll-pitch-yaw
    ``rotation``, would reach into the glass whose rim centre is at ``glass_world`` (both in
    the world frame [m]): the jug's box, turned with the gripper, against the glass's, as
    axis-aligned bounds. The spout of the abstract skills is the grasp point, so a pour with
    the spout less than the jug's own height above the rim puts the jug into the glass. No
    glass (``None``): nothing to hit."""
    if glass_world is None:
        return False
    # the turned box's bounds in closed form (this runs at every move of the held jug, on
    # the abstract skills' hot path): centre = grasp + R (0, 0, -G), half extent along
    # world axis i = sum over j of |R_ij| h_j; the same bounds as its eight corners give
    r = _rpy_matrix(rotation)
    h = JUG_HALF_EXTENTS_M
    g = GLASS_HALF_EXTENTS_M
    glass_low = (glass_world[0] - g[0], glass_world[1] - g[1], glass_world[2] - 2 * g[2])
    glass_high = (glass_world[0] + g[0], glass_world[1] + g[1], glass_world[2])
    for i in (2, 0, 1):  # height first: a jug carried above the rim is decided at once
        row = r[i]
        centre = grasp_world[i] - row[2] * JUG_GRASP_ABOVE_CENTRE_M
        extent = abs(row[0]) * h[0] + abs(row[1]) * h[1] + abs(row[2]) * h[2]
        if min(centre + extent, glass_high[i]) - max(centre - extent, glass_low[i]) \
                <= JUG_GLASS_TOLERANCE_M:
            return False
    return True


def pour_point(glass_world: Sequence[float]) -> tuple[float, float, float]:
    """The spout's place closest to the glass from which the jug pours:
    :data:`POUR_POINT_ABOVE_RIM_M` above the rim's centre ``glass_world`` [m]."""
    return (float(glass_world[0]), float(glass_world[1]),
            float(glass_world[2]) + POUR_POINT_ABOVE_RIM_M)
