"""The pour-water world's geometry and the pouring skills' parameters, shared by the
abstract skills (:mod:`skillcompose.skills.pour_water`), their kinematic and dynamic twins and
the robot check (:mod:`skillcompose.skills.pour_robot`): what "the water is in the glass"
means and the ranges every backend declares alike. The rule is explained in
:mod:`skillcompose.skills.pour_water`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Annotated, Any

from skillcompose import Blackboard, Param

__all__ = [
    "APPROACH_OFFSET_M",
    "APPROACH_TOLERANCE_M",
    "GLASS_HALF_EXTENTS_M",
    "JUG_GRASP_ABOVE_CENTRE_M",
    "JUG_HALF_EXTENTS_M",
    "JUG_MOUTH_RADIUS_M",
    "JUG_SLIP_M",
    "POUR_HEIGHT_MAX_M",
    "POUR_HEIGHT_MIN_M",
    "POUR_MOUTH_ABOVE_GRASP_M",
    "POUR_POINT_ABOVE_RIM_M",
    "POUR_RADIUS_M",
    "POUR_TILT_MAX_RAD",
    "POUR_TILT_MIN_RAD",
    "WORKSPACE_WORLD",
    "GripperX",
    "GripperY",
    "GripperZ",
    "Matrix3",
    "Pitch",
    "Roll",
    "Vec3",
    "Yaw",
    "distance",
    "distance_to_pour",
    "glass_at",
    "held_jug_hits_glass",
    "held_jug_turns_into_glass",
    "lip_at",
    "move_held_water",
    "pour_lip",
    "pour_point",
    "pours_into_glass",
    "rpy_matrix",
    "tilt",
    "water_after_motion",
    "water_leaves",
]

Vec3 = tuple[float, float, float]
Matrix3 = tuple[Vec3, Vec3, Vec3]

APPROACH_TOLERANCE_M = 0.10
"""GraspObject needs the gripper this close to the jug (the paper's 10 cm)."""
APPROACH_OFFSET_M = 0.06
"""MoveToObject stops this far in front of the jug (−x of the world), inside the tolerance."""
POUR_RADIUS_M = 0.02
"""Horizontal distance from the point where the water leaves the jug (the lowest point of
its mouth, :func:`pour_lip`) to the rim's centre that still lands it in the glass: the
glass's mouth is 3.9 cm across half its width, less the stream's spread (measured in MuJoCo)
[m]."""
POUR_HEIGHT_MIN_M = 0.0
"""The water must leave the jug above the rim, not below it [m]."""
POUR_HEIGHT_MAX_M = 0.12
"""From higher than this above the rim the stream splashes out [m]."""
POUR_TILT_MIN_RAD = math.pi / 2
"""A held jug starts pouring at this tilt from upright: tipped past level, its water (80 g
in a 7 x 7 x 7.6 cm jug) reaches the lip (in MuJoCo no water left the jug below about
85°)."""
POUR_TILT_MAX_RAD = 2 * math.pi / 3
"""Beyond this tilt the water leaves through the whole mouth and misses the glass."""
JUG_HALF_EXTENTS_M = (0.035, 0.035, 0.038)
"""The jug's outside: 7 x 7 x 7.6 cm (half extents) [m]."""
JUG_GRASP_ABOVE_CENTRE_M = 0.026
"""Its grasp point (``jug_position_world``, held at the tool frame, the jug's axes along the
tool's) lies this far above its centre: 1.2 cm under the rim [m]."""
JUG_SLIP_M = 0.016
"""How far a tipped jug slides in the fingers along its axis, towards its mouth: in MuJoCo,
where the fingers hold it by friction alone, the jug sits 1.6 to 1.65 cm further out on
average once tipped 75° to 120° (``benchmarks/pour_rule.py``, docs/results/pour_rule.md)
[m]."""
JUG_MOUTH_RADIUS_M = 0.035
"""The jug's mouth, as a circle: the water leaves over its lowest point [m]."""
POUR_MOUTH_ABOVE_GRASP_M = JUG_HALF_EXTENTS_M[2] - JUG_GRASP_ABOVE_CENTRE_M + JUG_SLIP_M
"""The centre of a tipped jug's mouth, this far from the grasp point along the jug's axis
(1.2 cm under the rim, plus :data:`JUG_SLIP_M`) [m]."""
GLASS_HALF_EXTENTS_M = (0.045, 0.045, 0.06)
"""The glass's outside: 9 x 9 x 12 cm, its rim (``glass_position_world``) on top [m]."""
POUR_POINT_ABOVE_RIM_M = 0.05
"""Where the pour task's fitness leads the jug's lip (:func:`pour_point`): this far over the
rim's centre, a height from which the lip of a jug tipped past level pours with the jug
clear of the glass (its spout 8.5 cm over the rim) [m]."""
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


def pours_into_glass(lip_world: Sequence[float], glass_world: Sequence[float]) -> bool:
    """True when water leaving the jug at ``lip_world`` (:func:`pour_lip`) lands in the
    glass whose rim's centre is ``glass_world`` (both in the world frame [m])."""
    dx = lip_world[0] - glass_world[0]
    dy = lip_world[1] - glass_world[1]
    dz = lip_world[2] - glass_world[2]
    return dx * dx + dy * dy <= POUR_RADIUS_M**2 and POUR_HEIGHT_MIN_M <= dz <= POUR_HEIGHT_MAX_M


def pour_lip(grasp_world: Sequence[float], axis: Sequence[float]) -> Vec3:
    """Where the water leaves a held jug whose grasp point is ``grasp_world`` and whose axis
    (its upright direction, the tool's z) is the unit vector ``axis``, both in the world
    frame: the lowest point of its mouth, a circle of :data:`JUG_MOUTH_RADIUS_M` around a
    centre :data:`POUR_MOUTH_ABOVE_GRASP_M` along the axis [m]."""
    c = axis[2]  # cos(tilt)
    s = math.sqrt(max(0.0, 1.0 - c * c))
    m = POUR_MOUTH_ABOVE_GRASP_M
    if s < 1e-9:  # upright or upside down: no lowest point; the mouth's centre
        return (grasp_world[0] + m * axis[0], grasp_world[1] + m * axis[1],
                grasp_world[2] + m * axis[2])
    k = JUG_MOUTH_RADIUS_M / s  # downhill in the mouth's plane: (-e_z + c axis) / s
    return (grasp_world[0] + (m + k * c) * axis[0],
            grasp_world[1] + (m + k * c) * axis[1],
            grasp_world[2] + (m + k * c) * axis[2] - k)


_PATH_STEP_RAD = math.radians(3.0)
"""The held jug's path is judged at rotations this far apart, at most."""

def _turn(rotation_from: Matrix3, rotation_to: Matrix3) -> tuple[Vec3, float]:
    """The shortest turn from one rotation to the other, in the world frame: the unit axis
    and angle [rad] of ``rotation_to . rotation_from^T``."""
    return _axis_angle(_times_transposed(rotation_to, rotation_from))


def _times_transposed(a: Matrix3, b: Matrix3) -> Matrix3:
    """``a . b^T``, written out: it runs at every move and turn of a held jug, on the
    abstract skills' hot path, where the generator form took a sixth of an episode."""
    (a0, a1, a2), (b0, b1, b2) = a, b
    return ((a0[0] * b0[0] + a0[1] * b0[1] + a0[2] * b0[2],
             a0[0] * b1[0] + a0[1] * b1[1] + a0[2] * b1[2],
             a0[0] * b2[0] + a0[1] * b2[1] + a0[2] * b2[2]),
            (a1[0] * b0[0] + a1[1] * b0[1] + a1[2] * b0[2],
             a1[0] * b1[0] + a1[1] * b1[1] + a1[2] * b1[2],
             a1[0] * b2[0] + a1[1] * b2[1] + a1[2] * b2[2]),
            (a2[0] * b0[0] + a2[1] * b0[1] + a2[2] * b0[2],
             a2[0] * b1[0] + a2[1] * b1[1] + a2[2] * b1[2],
             a2[0] * b2[0] + a2[1] * b2[1] + a2[2] * b2[2]))


def _axis_angle(r: Matrix3) -> tuple[Vec3, float]:
    """The unit axis and angle [rad] of rotation matrix ``r``, by way of its quaternion
    (Shepperd's method: exact also near half a turn)."""
    t = r[0][0] + r[1][1] + r[2][2]
    if t > max(r[0][0], r[1][1], r[2][2]):
        w = math.sqrt(1.0 + t) / 2
        v = ((r[2][1] - r[1][2]) / (4 * w), (r[0][2] - r[2][0]) / (4 * w),
             (r[1][0] - r[0][1]) / (4 * w))
    elif r[0][0] >= r[1][1] and r[0][0] >= r[2][2]:
        x = math.sqrt(max(0.0, 1.0 + r[0][0] - r[1][1] - r[2][2])) / 2
        w = (r[2][1] - r[1][2]) / (4 * x)
        v = (x, (r[0][1] + r[1][0]) / (4 * x), (r[0][2] + r[2][0]) / (4 * x))
    elif r[1][1] >= r[2][2]:
        y = math.sqrt(max(0.0, 1.0 + r[1][1] - r[0][0] - r[2][2])) / 2
        w = (r[0][2] - r[2][0]) / (4 * y)
        v = ((r[0][1] + r[1][0]) / (4 * y), y, (r[1][2] + r[2][1]) / (4 * y))
    else:
        z = math.sqrt(max(0.0, 1.0 + r[2][2] - r[0][0] - r[1][1])) / 2
        w = (r[1][0] - r[0][1]) / (4 * z)
        v = ((r[0][2] + r[2][0]) / (4 * z), (r[1][2] + r[2][1]) / (4 * z), z)
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if n < 1e-12:
        return (0.0, 0.0, 1.0), 0.0
    if w < 0.0:  # the shorter way round
        v, w = (-v[0], -v[1], -v[2]), -w
    return (v[0] / n, v[1] / n, v[2] / n), 2.0 * math.atan2(n, w)


def water_after_motion(grasp_from: Sequence[float], rotation_from: Matrix3,
                       grasp_to: Sequence[float], rotation_to: Matrix3,
                       glass_world: Sequence[float] | None) -> str | None:
    """:func:`water_leaves`' answer without the place: ``"glass"``, ``"spilled"`` or
    ``None``."""
    left = water_leaves(grasp_from, rotation_from, grasp_to, rotation_to, glass_world)
    return None if left is None else left[0]


def water_leaves(grasp_from: Sequence[float], rotation_from: Matrix3,
                 grasp_to: Sequence[float], rotation_to: Matrix3,
                 glass_world: Sequence[float] | None) -> tuple[str, Vec3] | None:
    """Where a held jug's water goes as the jug moves from one pose to another: its grasp
    point along the straight line, its rotation (world-frame matrices, the jug's axes along
    the tool's) along the shortest turn between the two, as the robot turns it. ``None``
    when no pose of the path tilts the jug to :data:`POUR_TILT_MIN_RAD`: the water stays in.
    Otherwise the water leaves at every pose tilted that far, over the lip (:func:`pour_lip`),
    and ends ``"glass"`` when every such pose is tilted at most :data:`POUR_TILT_MAX_RAD` with
    its lip over the glass (:func:`pours_into_glass`), with the lip of the first such pose,
    where the water began to leave; else ``"spilled"``, with the lip of the first pose whose
    water missed the glass. Where the water missed, not where it began: a turn that begins
    to pour over the glass and swings away spills as surely as one that never came near it,
    and an evolution told that such water began at the glass keeps those turns.

    The water leaves as soon as the tilt passes level, wherever the lip is then: a rotation
    that tips the jug past level away from the glass spills, even if it ends over it (as in
    MuJoCo, where the arm turns the jug through intermediate rotations)."""
    cos_min = math.cos(POUR_TILT_MIN_RAD) + 1e-12
    z0 = (rotation_from[0][2], rotation_from[1][2], rotation_from[2][2])
    z1 = (rotation_to[0][2], rotation_to[1][2], rotation_to[2][2])
    u, angle = _turn(rotation_from, rotation_to)
    # the jug's axis on the way: z(s) = z0 cos(sa) + (u x z0) sin(sa) + u (u.z0)(1 - cos(sa)),
    # its height a + b cos(sa) + c sin(sa); a quick answer when it never comes down to level
    uz = u[0] * z0[0] + u[1] * z0[1] + u[2] * z0[2]
    cross = (u[1] * z0[2] - u[2] * z0[1], u[2] * z0[0] - u[0] * z0[2],
             u[0] * z0[1] - u[1] * z0[0])
    a, b, c = u[2] * uz, z0[2] - u[2] * uz, cross[2]
    lowest = min(z0[2], z1[2])
    phase = math.atan2(c, b)  # a + r cos(sa - phase): lowest at sa = phase + pi
    for turn in (phase + math.pi, phase - math.pi):
        if 0.0 < turn < angle:
            lowest = min(lowest, a - math.hypot(b, c))
    if lowest > cos_min:
        return None
    steps = max(1, math.ceil(angle / _PATH_STEP_RAD),
                math.ceil(math.dist(grasp_from, grasp_to) / (POUR_RADIUS_M / 4)))
    first: Vec3 | None = None
    for i in range(steps + 1):
        s = i / steps
        ca, sa = math.cos(s * angle), math.sin(s * angle)
        w = 1.0 - ca
        axis = (z0[0] * ca + cross[0] * sa + u[0] * uz * w,
                z0[1] * ca + cross[1] * sa + u[1] * uz * w,
                z0[2] * ca + cross[2] * sa + u[2] * uz * w)
        if axis[2] > cos_min:
            continue
        grasp = (grasp_from[0] + s * (grasp_to[0] - grasp_from[0]),
                 grasp_from[1] + s * (grasp_to[1] - grasp_from[1]),
                 grasp_from[2] + s * (grasp_to[2] - grasp_from[2]))
        lip = pour_lip(grasp, axis)
        first = first or lip
        if glass_world is None or axis[2] < math.cos(POUR_TILT_MAX_RAD) or \
                not pours_into_glass(lip, glass_world):
            return "spilled", lip
    return None if first is None else ("glass", first)


def move_held_water(bb: Blackboard, before: tuple[Any, Any] | None) -> None:
    """Pour or spill the water of the jug a gripper holds after the gripper moved from the
    pose ``before`` (``gripper_position_world``, ``gripper_rotation``; ``None``: it holds
    the jug only from now on) to the one ``bb`` now says, by :func:`water_after_motion`:
    the commanded rotation, so that the kinematic twins pour exactly where the abstract
    skills do, not by the rotation IK reached within its tolerance."""
    position, rotation = bb.get("gripper_position_world"), bb.get("gripper_rotation")
    if bb.get("water") != "jug" or position is None or rotation is None:
        return
    start, turned = position, rotation
    if before is not None and before[0] is not None and before[1] is not None:
        start, turned = before
    left = water_leaves(start, rpy_matrix(turned), position, rpy_matrix(rotation),
                        bb.get("glass_position_world"))
    if left is not None:
        bb["water"], bb["water_left_at_world"] = left


def rpy_matrix(rotation: Sequence[float]) -> Matrix3:
    """The rotation matrix of roll, pitch, yaw ``rotation`` [rad] about the fixed x, y, z
    axes: ``Rz(yaw) Ry(pitch) Rx(roll)``."""
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
    return glass_world is not None and _hits(grasp_world, rpy_matrix(rotation), glass_world)


def held_jug_turns_into_glass(grasp_world: Sequence[float], rotation_from: Matrix3,
                              rotation_to: Matrix3, glass_world: Sequence[float] | None
                              ) -> bool:
    """Whether the held jug, turned about its grasp point ``grasp_world`` from one rotation
    to another (world-frame matrices) along the shortest turn, as the robot turns it, would
    reach into the glass at some pose on the way or at its end (:func:`held_jug_hits_glass`
    at every :data:`_PATH_STEP_RAD`)."""
    if glass_world is None:
        return False
    g = GLASS_HALF_EXTENTS_M
    gap = (max(abs(grasp_world[0] - glass_world[0]) - g[0], 0.0),
           max(abs(grasp_world[1] - glass_world[1]) - g[1], 0.0),
           max(abs(grasp_world[2] - (glass_world[2] - g[2])) - g[2], 0.0))
    if gap[0] ** 2 + gap[1] ** 2 + gap[2] ** 2 > _JUG_REACH_M**2:
        return False  # farther from the glass than any point of the jug from its grasp
    u, angle = _turn(rotation_from, rotation_to)
    steps = max(1, math.ceil(angle / _PATH_STEP_RAD))
    (f0, f1, f2) = rotation_from
    from_t = ((f0[0], f1[0], f2[0]), (f0[1], f1[1], f2[1]), (f0[2], f1[2], f2[2]))
    for i in range(1, steps + 1):
        # turn . rotation_from, as turn . (rotation_from^T)^T
        r = _times_transposed(_axis_angle_matrix(u, angle * i / steps), from_t)
        if _hits(grasp_world, r, glass_world):
            return True
    return False


def _axis_angle_matrix(u: Vec3, angle: float) -> Matrix3:
    """The rotation by ``angle`` [rad] about unit axis ``u`` (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    t = 1.0 - c
    x, y, z = u
    return ((c + x * x * t, x * y * t - z * s, x * z * t + y * s),
            (y * x * t + z * s, c + y * y * t, y * z * t - x * s),
            (z * x * t - y * s, z * y * t + x * s, c + z * z * t))


_JUG_REACH_M = math.sqrt(JUG_HALF_EXTENTS_M[0] ** 2 + JUG_HALF_EXTENTS_M[1] ** 2
                         + (JUG_GRASP_ABOVE_CENTRE_M + JUG_HALF_EXTENTS_M[2]) ** 2)
"""How far from its grasp point the held jug reaches: its farthest corner [m]."""


def _hits(grasp_world: Sequence[float], r: Matrix3, glass_world: Sequence[float]) -> bool:
    """:func:`held_jug_hits_glass` for the rotation matrix ``r``."""
    # the turned box's bounds in closed form (this runs at every move of the held jug, on
    # the abstract skills' hot path): centre = grasp + R (0, 0, -G), half extent along
    # world axis i = sum over j of |R_ij| h_j; the same bounds as its eight corners give
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
    """Where the water should leave the jug: :data:`POUR_POINT_ABOVE_RIM_M` above the rim's
    centre ``glass_world`` [m]."""
    return (float(glass_world[0]), float(glass_world[1]),
            float(glass_world[2]) + POUR_POINT_ABOVE_RIM_M)


def lip_at(grasp_world: Sequence[float], rotation: Sequence[float]) -> Vec3:
    """:func:`pour_lip` of a jug held at ``grasp_world`` with the gripper at roll-pitch-yaw
    ``rotation`` [rad]: where its water would leave (upright: its mouth's centre) [m]."""
    r = rpy_matrix(rotation)
    return pour_lip(grasp_world, (r[0][2], r[1][2], r[2][2]))


def distance_to_pour(grasp_world: Sequence[float], rotation: Sequence[float],
                     glass_world: Sequence[float]) -> float:
    """How far a held jug that still holds its water is from pouring it at
    :func:`pour_point` [m]: the distance from its lip (:func:`lip_at`) to that point, plus
    the arc its lip still has to turn through before the water leaves (the mouth's radius
    times the tilt short of :data:`POUR_TILT_MIN_RAD`), so that a jug tipped part way with
    its lip at the point is not taken for one that pours."""
    short = max(0.0, POUR_TILT_MIN_RAD - tilt(rotation))
    return distance(lip_at(grasp_world, rotation), pour_point(glass_world)) + \
        JUG_MOUTH_RADIUS_M * short
