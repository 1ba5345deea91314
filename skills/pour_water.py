"""The pour-water skills of the paper's section 4.1, on the abstract "sim" backend.

These are *minimal simulator* skills (section 3.8): each one reads the world from the
blackboard, decides whether it can run, and writes its effect back. No physics: a grasp is
"the jug is in the gripper", a pour is "the water is in the glass".

The world (all positions in the robot's base frame ``world``, metres; angles in radians):

============================ ==============================================================
key                          meaning (written by the task's ``setup`` unless said otherwise)
============================ ==============================================================
``p_fail``                   probability of a random ``failure`` of MoveToObject,
                             GraspObject and MoveGripperToParam (one knob for all three)
``jug_position_world``       the jug's spout, the point that pours [m]
``glass_position_world``     the centre of the glass's rim [m]
``gripper_position_world``   the gripper; the held jug's spout sits at this point [m]
``gripper_rotation``         the gripper's roll, pitch, yaw (ρ, φ, θ) [rad]
``holding_jug``              the jug is in the gripper
``water``                    where the water is: ``"jug"``, ``"glass"`` or ``"spilled"``
``water_left_at_world``      where the water left the jug, its lip then: where it began to
                             pour into the glass, or where it first missed the glass
                             (absent while it is in the jug) [m]
``jug_location_world``       where RecogniseObject saw the jug (absent until then) [m]
``glass_location_world``     where RecogniseObject saw the glass (absent until then) [m]
``robot_check``              which robot the abstract skills ask before they pour
                             (``"pr2"``: the kinematic model, ``"physics"``: the PR2 in
                             MuJoCo) and the episode's starting world (the jug's spout, the
                             glass's rim, the gripper's home), as ``(kind, (jug, glass,
                             home))``; see "The robot" below. Absent or ``None``: the
                             abstract rule alone
============================ ==============================================================

Positions and rotations are plain ``(x, y, z)`` float tuples: these skills run millions of
times during evolution.

Pouring. The water leaves the held jug as soon as the jug tips past level
(:data:`POUR_TILT_MIN_RAD`, 90°: with less tilt it stays in), over the lowest point of the
jug's mouth, its *lip* (:func:`~skillcompose.skills.pour_geometry.pour_lip`: the mouth is a
circle of 3.5 cm around a centre 2.8 cm along the jug's axis from the grasp point, 1.2 cm
under the rim plus 1.6 cm that a tipped jug slides in the fingers). It lands in the glass
when the lip is over the glass's mouth: at most :data:`POUR_RADIUS_M` (2 cm) from the rim's
centre horizontally, and between :data:`POUR_HEIGHT_MIN_M` (level with the rim) and
:data:`POUR_HEIGHT_MAX_M` (12 cm, higher splashes) above it; tilted more than
:data:`POUR_TILT_MAX_RAD` (120°) the water leaves through the whole mouth and spills.
The jug turns about its grasp point along the shortest turn from its rotation to the new
one, as the robot turns it, and the water goes as every pose on the way says
(:func:`~skillcompose.skills.pour_geometry.water_after_motion`): a rotation that tips the
jug past level with its lip away from the glass spills, wherever it ends. So the yaw θ
matters: it decides where the lip points. A tilted gripper that grasps the jug tips it at
once, where it stands. These numbers were measured in MuJoCo, where the rule is checked
against the physics by ``benchmarks/pour_rule.py`` (``docs/results/pour_rule.md``). The
tilt of rotation (ρ, φ, θ), roll about x, pitch about y, yaw about z, applied in that order
about the fixed axes, is ``arccos(cos ρ · cos φ)``.

The jug is a body. The held jug hangs below its spout (the grasp point: 7.6 cm tall, held
1.2 cm under its rim; :data:`~skillcompose.skills.pour_geometry.JUG_HALF_EXTENTS_M`), and the
glass is a 9 x 9 x 12 cm cup under its rim: a move or a rotation that would put the jug into
the glass (:func:`~skillcompose.skills.pour_geometry.held_jug_hits_glass`) does not happen
(MoveGripperToParam fails, RotateGripperToParam leaves the gripper as it was), on every
backend. So an upright jug's spout comes no lower than 6.4 cm above the rim's centre, and
a jug tipped over the glass from lower than about 8 cm swings a corner into it on the way.

The robot. With ``robot_check`` set (the task's default, ``reach=pr2``), a pose that would
pour into the glass is taken only if the PR2's arm can take it:
:func:`skillcompose.skills.pour_robot.pr2_can_pour` runs the kinematic twins to that pose
(with ``reach=physics``, :func:`~skillcompose.skills.pour_robot.physics_can_pour` runs the
MuJoCo twins there and asks whether the water ends in the glass).
Where it cannot, RotateGripperToParam leaves the gripper as it was (still ``success``, as
its kinematic twin does) and MoveGripperToParam fails without moving, so the jug does not
pour. Poses that do not pour into the glass are not checked.

Randomness comes only from the run's generator ``rng``: a skill whose preconditions hold
draws one number and fails when it is below ``p_fail``; a skill whose preconditions fail
returns ``failure`` without drawing.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np

from skillcompose import Blackboard, BlackboardKeyError, Registry, skill
from skillcompose.skills.pour_geometry import (
    APPROACH_OFFSET_M,
    APPROACH_TOLERANCE_M,
    POUR_HEIGHT_MAX_M,
    POUR_HEIGHT_MIN_M,
    POUR_RADIUS_M,
    POUR_TILT_MAX_RAD,
    POUR_TILT_MIN_RAD,
    WORKSPACE_WORLD,
    GripperX,
    GripperY,
    GripperZ,
    Pitch,
    Roll,
    Vec3,
    Yaw,
    distance,
    held_jug_hits_glass,
    held_jug_turns_into_glass,
    move_held_water,
    pours_into_glass,
    rpy_matrix,
    tilt,
    water_leaves,
)

if TYPE_CHECKING:
    from collections.abc import Sequence

__all__ = [
    "APPROACH_OFFSET_M",
    "APPROACH_TOLERANCE_M",
    "POUR_HEIGHT_MAX_M",
    "POUR_HEIGHT_MIN_M",
    "POUR_RADIUS_M",
    "POUR_TILT_MAX_RAD",
    "POUR_TILT_MIN_RAD",
    "SKILLS",
    "WORKSPACE_WORLD",
    "GripperX",
    "GripperY",
    "GripperZ",
    "Pitch",
    "Roll",
    "Vec3",
    "Yaw",
    "check_success",
    "distance",
    "grasp_object",
    "move_gripper_to_param",
    "move_to_object",
    "pours_into_glass",
    "recognise_object",
    "register",
    "rotate_gripper_to_param",
    "tilt",
]

_WORLD_KEYS = ("jug_position_world", "glass_position_world", "gripper_position_world")


def _world(bb: Blackboard, key: str, who: str) -> Vec3:
    value = bb.get(key)
    if value is None:
        raise BlackboardKeyError(
            f"skill {who}: the pour-water world is not set up (blackboard key {key!r} is "
            "missing); run the FSA with its task (`--task examples.pour_water`), whose setup "
            f"writes {', '.join(_WORLD_KEYS)}"
        )
    return (float(value[0]), float(value[1]), float(value[2]))


def _random_failure(bb: Blackboard, rng: np.random.Generator) -> bool:
    return rng.random() < bb["p_fail"]


def _water_after(bb: Blackboard, position: Vec3,
                 rotation: Vec3 | None = None) -> tuple[str, Vec3] | None:
    """Where the held jug's water would go if the jug moved from its pose now to
    ``position`` and ``rotation`` (``None``: the rotation it has, as a move keeps it)
    (:func:`~skillcompose.skills.pour_geometry.water_after_motion`): ``None`` when it stays
    in the jug, or when there is no held jug with water in it; else where it ends and where
    it left (:func:`~skillcompose.skills.pour_geometry.water_leaves`)."""
    if not bb["holding_jug"] or bb["water"] != "jug":
        return None
    now = rpy_matrix(bb["gripper_rotation"])  # a move turns nothing: one matrix for both
    return water_leaves(bb["jug_position_world"], now, position,
                        now if rotation is None else rpy_matrix(rotation),
                        bb["glass_position_world"])


def _robot_can_take(bb: Blackboard, left: tuple[str, Vec3] | None, position: Vec3,
                    rotation: Vec3) -> bool:
    """Whether the held jug may move to this pose, where its water goes as ``left`` says
    (:func:`_water_after`): always, unless it would pour into the glass and the robot check
    (``robot_check``) says the PR2's arm cannot take the pose."""
    check = bb.get("robot_check")
    if check is None or left is None or left[0] != "glass":
        return True
    # imported here: the PR2 model loads only when a pose would pour
    from skillcompose.skills.pour_robot import can_pour

    kind, (jug, glass, home) = check
    return can_pour(str(kind), (_vec(jug), _vec(glass), _vec(home)), _vec(position),
                    _vec(rotation))


def _vec(v: Sequence[float]) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))


@skill(
    reads=("jug_position_world", "glass_position_world"),
    writes=("jug_location_world", "glass_location_world"),
    backend="sim",
)
def recognise_object(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    """Find the jug and the glass with the stereo camera and store where they are.

    Both objects are assumed visible, so this always succeeds.
    """
    bb["jug_location_world"] = _world(bb, "jug_position_world", "RecogniseObject")
    bb["glass_location_world"] = _world(bb, "glass_position_world", "RecogniseObject")
    return "success"


@skill(
    reads=("jug_location_world", "jug_position_world", "holding_jug", "p_fail"),
    writes=("gripper_position_world", "gripper_rotation"),
    backend="sim",
)
def move_to_object(
    bb: Blackboard, rng: np.random.Generator
) -> Literal["success", "failure"]:
    """Bring the gripper, upright, to within 10 cm of the jug (a pre-grasp pose).

    ``failure`` when the jug has not been recognised, or at random with ``p_fail``. With the
    jug already in the gripper there is nothing to approach: the gripper does not move.
    """
    seen = bb.get("jug_location_world")
    if seen is None:
        return "failure"
    if _random_failure(bb, rng):
        return "failure"
    if not bb["holding_jug"]:
        bb["gripper_position_world"] = (seen[0] - APPROACH_OFFSET_M, seen[1], seen[2])
        bb["gripper_rotation"] = (0.0, 0.0, 0.0)
    return "success"


@skill(
    reads=(
        "jug_location_world", "gripper_position_world", "gripper_rotation", "p_fail",
        "glass_position_world", "water",
    ),
    writes=("holding_jug", "jug_position_world", "water", "water_left_at_world"),
    backend="sim",
)
def grasp_object(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    """Close the gripper on the jug; the jug is then held with its spout at the gripper.

    ``failure`` unless the jug was recognised and the gripper is within 10 cm of it, or at
    random with ``p_fail``. Grasping with a tilted gripper tilts the jug (and may spill).
    """
    if bb.get("jug_location_world") is None:
        return "failure"
    gripper = bb["gripper_position_world"]
    jug = bb["jug_position_world"]
    if distance(gripper, jug) > APPROACH_TOLERANCE_M:
        return "failure"
    if _random_failure(bb, rng):
        return "failure"
    bb["holding_jug"] = True
    bb["jug_position_world"] = gripper
    move_held_water(bb, None)  # a tilted gripper tilts the jug at once, where it is
    return "success"


@skill(
    reads=("p_fail", "holding_jug", "gripper_rotation", "glass_position_world", "robot_check",
           "jug_position_world", "water"),
    writes=("gripper_position_world", "jug_position_world", "water", "water_left_at_world"),
    backend="sim",
)
def move_gripper_to_param(
    bb: Blackboard,
    rng: np.random.Generator,
    *,
    x: GripperX = 0.6,
    y: GripperY = 0.0,
    z: GripperZ = 1.1,
) -> Literal["success", "failure"]:
    """Move the gripper to ``(x, y, z)`` in the world frame [m]; a held jug moves with it.

    ``failure`` at random with ``p_fail`` (the planner found no path), when the held jug
    would reach into the glass, or when it would pour into the glass from a pose the PR2
    cannot take: nothing moves.
    """
    if _random_failure(bb, rng):
        return "failure"
    target = (x, y, z)
    if bb["holding_jug"] and held_jug_hits_glass(target, bb["gripper_rotation"],
                                                 bb["glass_position_world"]):
        return "failure"
    left = _water_after(bb, target)
    if not _robot_can_take(bb, left, target, bb["gripper_rotation"]):
        return "failure"
    bb["gripper_position_world"] = target
    if bb["holding_jug"]:
        bb["jug_position_world"] = target
    if left is not None:
        bb["water"], bb["water_left_at_world"] = left
    return "success"


@skill(
    reads=("holding_jug", "jug_position_world", "glass_position_world", "robot_check",
           "gripper_rotation", "water"),
    writes=("gripper_rotation", "water", "water_left_at_world"),
    backend="sim",
)
def rotate_gripper_to_param(
    bb: Blackboard,
    rng: np.random.Generator,
    *,
    rho: Roll = 0.0,
    phi: Pitch = 0.0,
    theta: Yaw = 0.0,
) -> Literal["success"]:
    """Rotate the gripper in place to roll, pitch, yaw ``(rho, phi, theta)`` [rad].

    The held jug turns with it, about its grasp point, along the shortest turn: its water
    leaves as soon as it tips past level, into the glass when its lip is over it (see the
    module). Always ``success``; a rotation that would pour but that the PR2's arm cannot
    take leaves the gripper as it was.
    """
    if bb["holding_jug"] and held_jug_turns_into_glass(
            bb["jug_position_world"], rpy_matrix(bb["gripper_rotation"]),
            rpy_matrix((rho, phi, theta)), bb["glass_position_world"]):
        return "success"  # the jug would turn into the glass: the gripper stays
    left = _water_after(bb, bb["jug_position_world"], (rho, phi, theta))
    if not _robot_can_take(bb, left, bb["jug_position_world"], (rho, phi, theta)):
        return "success"
    bb["gripper_rotation"] = (rho, phi, theta)
    if left is not None:
        bb["water"], bb["water_left_at_world"] = left
    return "success"


@skill(reads=("water",), backend="sim")
def check_success(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    """Look into the glass: ``success`` when the water is in it, ``failure`` otherwise."""
    return "success" if bb["water"] == "glass" else "failure"


SKILLS = (
    recognise_object,
    move_to_object,
    grasp_object,
    move_gripper_to_param,
    rotate_gripper_to_param,
    check_success,
)
"""The six skills of section 4.1, in the order the paper lists them."""


def register(registry: Registry) -> None:
    """Add the six pour-water skills (backend ``"sim"``) to ``registry``."""
    for s in SKILLS:
        registry.add(s)
