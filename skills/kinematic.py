"""Kinematic skills: the PR2 (:mod:`robots`) does what the abstract skills pretend to do.

Registered under the ``"kinematic"`` backend. The *twins* carry the names, parameters and
outcomes of the abstract ``"sim"`` skills, so an FSA found with the abstract skills runs
unchanged on these ones::

    registry = Registry()
    skillcompose.skills.pour_water.register(registry)   # "sim"
    skillcompose.skills.kinematic.register(registry)    # "kinematic"
    compile_fsa(fsa, registry, "kinematic").run(setup(rng), rng)

or, task-free, ``skillcompose run FILE --skills skillcompose.skills.kinematic --backend kinematic``.

Instead of a coin flip with ``p_fail``, a kinematic skill fails for a kinematic reason: IK
finds no configuration (``unreachable``), only outside the joint limits (``joint_limits``),
or every configuration hits the table or, in the pour world, the glass (``collision``); it
writes the reason to ``last_failure_reason`` (and words to ``last_failure_detail``) and
moves nothing. On success it writes the joint angles, the torso height, the tool poses and
what each gripper holds, beside the abstract world keys the twin writes. Keys, frames and defaults:
:mod:`skillcompose.skills.kinematic_world`.

Twins of the pour-water skills (section 4.1, :mod:`skillcompose.skills.pour_water`):

- ``RecogniseObject`` and ``CheckSuccess``: as the abstract ones (perception is not kinematics).
- ``MoveToObject``: the gripper upright 6 cm in front of the recognised jug, by IK (arm on
  the jug's side first, then the other).
- ``GraspObject``: within 10 cm of the jug, the tool moves onto it (its spout) and closes.
- ``MoveGripperToParam`` (x, y, z): the gripper, keeping its rotation, to (x, y, z) in world.
- ``RotateGripperToParam`` (rho, phi, theta): the gripper rotated in place; only ``success``:
  an impossible rotation leaves the gripper, and ``last_failure_reason`` says why.

Twins of the skills of the paper's other experiments:

- ``MoveBase`` (weights), section 4.2, of :mod:`skillcompose.skills.move_to_push`'s network
  skill (built per topology by :func:`make_move_base`): the same network gives the base pose,
  torso height and arm; fails when the base or an arm hits the table or leaves the room.
- ``Push``, section 4.2: the arm chosen by MoveBase pushes ``object_position_world`` 5 cm
  away from the robot, horizontally, torso fixed; fails when IK says it cannot.
- ``GraspParam`` (which), ``MoveGripperToStack`` (which, dx, dy, dz), ``OpenGripper``,
  section 4.3, on the objects ``object_positions_world`` (first, second).

New skills a programmer reaches for: ``MoveBasePose`` (x, y, yaw, torso, arm: MoveBase's five
outputs as explicit parameters), ``MoveGripperToPose`` (arm, pose), ``PlaceBase`` (arm,
object) and the condition ``Reachable`` (arm, object) with outcomes ``yes`` / ``no``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Annotated, Any, Literal

import numpy as np
import pinocchio as pin

from skillcompose import Blackboard, BlackboardKeyError, Param, Registry, Skill, skill
from skillcompose.robots.collision import BASE_HALF_EXTENTS_M, Box, Scene, check_collisions
from skillcompose.robots.model import ARMS, Arm
from skillcompose.skills.kinematic_world import (
    COLLISION_MARGIN_M,
    DETAIL_KEY,
    GRASP_KEY,
    REASON_KEY,
    ROBOT_READS,
    ROBOT_WRITES,
    TORSO_RANGE_M,
    WORLD_READS,
    WORLD_WRITES,
    GraspKind,
    KinematicSkill,
    KinematicWorld,
    RobotState,
    arms_for,
    base_collides,
    boxes_collide,
    commit,
    fail,
    fmt,
    free_arms,
    horizontal_grasp_world,
    in_world,
    kinematic_skill,
    object_box,
    object_position,
    reach,
    reach_either,
    reach_grasp,
    read_state,
    scene_world,
    stack_object_name,
    transform_robot_to_world,
)
from skillcompose.skills.move_to_push import SAFETY_M, base_in_room, network_goal, weights_parameter
from skillcompose.skills.network import Topology
from skillcompose.skills.pour_geometry import (
    APPROACH_OFFSET_M,
    APPROACH_TOLERANCE_M,
    WORKSPACE_WORLD,
    GripperX,
    GripperY,
    GripperZ,
    Pitch,
    Roll,
    Yaw,
    glass_at,
    held_jug_hits_glass,
    held_jug_turns_into_glass,
    rpy_matrix,
)
from skillcompose.skills.stacking_world import StackDX, StackDY, StackDZ, Which, landing_z

__all__ = [
    "BACKEND", "PLACE_BASE_CANDIDATES", "PUSH_DISTANCE_M", "SKILLS", "check_success",
    "grasp_object", "grasp_param", "make_move_base", "move_base_pose", "move_gripper_to_param",
    "move_gripper_to_pose", "move_gripper_to_stack", "move_to_object", "open_gripper",
    "place_base", "push", "reachable", "recognise_object", "register", "register_move_to_push",
    "rotate_gripper_to_param",
]

BACKEND = "kinematic"
PUSH_DISTANCE_M = 0.05
"""How far Push moves the tool, and the object, along the bearing from the base [m]."""
PLACE_BASE_CANDIDATES = 24
"""Base poses PlaceBase tries before it gives up."""
_X_M, _Y_M, _Z_M = WORKSPACE_WORLD
_PI = math.pi
_FLOOR_M = (-3.0, 3.0)  # base and pose targets: the paper's 5 m^2 room around the start

_MOVE_READS = (*ROBOT_READS, *WORLD_READS)
_MOVE_WRITES = (*ROBOT_WRITES, *WORLD_WRITES)
_ObjectName = Literal["jug", "glass", "object", "first", "second"]


def _rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    return np.asarray(pin.rpy.rpyToMatrix(roll, pitch, yaw))


def _holding_arm(state: RobotState, name: str) -> Arm | None:
    return next((a for a in ARMS if state.held[a] == name), None)


def _empty_arms(state: RobotState, arms: tuple[Arm, ...]) -> tuple[Arm, ...]:
    return tuple(a for a in arms if state.held[a] is None)


# -- twins of the pour-water skills ----------------------------------------------------------
@skill(
    name="RecogniseObject",
    reads=("jug_position_world", "glass_position_world"),
    writes=("jug_location_world", "glass_location_world"),
    backend=BACKEND,
)
def recognise_object(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    """Store where the jug and the glass are (both assumed visible): always ``success``."""
    for name in ("jug", "glass"):
        value = bb.get(f"{name}_position_world")
        if value is None:
            raise BlackboardKeyError(
                f"skill RecogniseObject: blackboard key '{name}_position_world' is missing; "
                "run the FSA with its task (`--task examples.kinematic_pour`), whose setup "
                "writes the jug and glass positions"
            )
        bb[f"{name}_location_world"] = (float(value[0]), float(value[1]), float(value[2]))
    return "success"


@kinematic_skill(
    name="MoveToObject",
    reads=(*_MOVE_READS, "jug_location_world"),
    writes=_MOVE_WRITES,
)
def move_to_object(
    world: KinematicWorld, bb: Blackboard, rng: np.random.Generator
) -> Literal["success", "failure"]:
    """The gripper, upright, 6 cm in front of (−x of) the recognised jug, by IK.

    ``failure`` (``not_recognised``) before RecogniseObject; ``unreachable`` /
    ``joint_limits`` / ``collision`` when neither free arm can get there. With the jug
    already held nothing moves (as the abstract twin).
    """
    seen = bb.get("jug_location_world")
    if seen is None:
        return fail(bb, "not_recognised", "MoveToObject: the jug has not been recognised; "
                    "run RecogniseObject first")
    state = read_state(bb)
    if _holding_arm(state, "jug") is not None:
        return "success"
    target = pin.SE3(_rpy(0.0, 0.0, 0.0),
                     np.array([seen[0] - APPROACH_OFFSET_M, seen[1], seen[2]]))
    arms = _empty_arms(state, arms_for(state, target.translation))
    if not arms:
        return fail(bb, "already_holding", "MoveToObject: both grippers are full")
    answer = reach_either(world, state, arms, target, scene_world(bb), rng)
    if answer.state is None:
        return fail(bb, answer.reason, f"MoveToObject: {answer.detail}")
    new = RobotState(answer.state.base_pose_world, answer.state.torso_height_m,
                     answer.state.q_arm_rad, answer.state.held, answer.arm)
    commit(world, bb, new, gripper_rotation=(0.0, 0.0, 0.0))
    return "success"


@kinematic_skill(
    name="GraspObject",
    reads=(*_MOVE_READS, "jug_location_world"),
    writes=(*_MOVE_WRITES, "holding_jug"),
)
def grasp_object(
    world: KinematicWorld, bb: Blackboard, rng: np.random.Generator
) -> Literal["success", "failure"]:
    """Move the tool onto the jug (keeping its rotation) and close: the jug is held.

    ``failure``: ``not_recognised``; ``too_far`` when the gripper in use is more than 10 cm
    from the jug; ``already_holding``; or the IK reasons. A tilted grasp may spill the water.
    """
    if bb.get("jug_location_world") is None:
        return fail(bb, "not_recognised", "GraspObject: the jug has not been recognised")
    state = read_state(bb)
    if _holding_arm(state, "jug") is not None:
        return "success"
    jug = np.asarray(bb["jug_position_world"], dtype=float)
    robot_to_world = transform_robot_to_world(state.base_pose_world)
    tools = {a: robot_to_world * world.transform_tool_to_robot(a, state.torso_height_m,
                                                             state.q_arm_rad[a])
             for a in ARMS}
    gaps = {a: float(np.linalg.norm(tools[a].translation - jug)) for a in ARMS}
    arm: Arm = state.arm_in_use or ("left" if gaps["left"] <= gaps["right"] else "right")
    gap = gaps[arm]
    if gap > APPROACH_TOLERANCE_M:
        return fail(bb, "too_far", f"GraspObject: the {arm} gripper is {gap:.3f} m from the "
                    f"jug, more than {APPROACH_TOLERANCE_M} m; run MoveToObject first")
    if state.held[arm] is not None:
        return fail(bb, "already_holding",
                    f"GraspObject: the {arm} gripper holds {state.held[arm]!r}")
    answer = reach(world, state, arm, pin.SE3(tools[arm].rotation, jug), scene_world(bb), rng)
    if answer.state is None:
        return fail(bb, answer.reason, f"GraspObject: {answer.detail}")
    held = dict(answer.state.held)
    held[arm] = "jug"
    new = RobotState(answer.state.base_pose_world, answer.state.torso_height_m,
                     answer.state.q_arm_rad, held, arm)
    bb["holding_jug"] = True
    rotation = bb.get("gripper_rotation") if state.arm_in_use == arm else None
    commit(world, bb, new, gripper_rotation=None if rotation is None else tuple(rotation))
    return "success"


def _gripper_arms(state: RobotState, position: Sequence[float]) -> tuple[Arm, ...]:
    jug_arm = _holding_arm(state, "jug")
    if jug_arm is not None:
        return (jug_arm,)
    return _empty_arms(state, free_arms(state, position))


@kinematic_skill(
    name="MoveGripperToParam",
    reads=_MOVE_READS,
    writes=_MOVE_WRITES,
)
def move_gripper_to_param(
    world: KinematicWorld,
    bb: Blackboard,
    rng: np.random.Generator,
    *,
    x: GripperX = 0.6,
    y: GripperY = 0.0,
    z: GripperZ = 1.1,
) -> Literal["success", "failure"]:
    """Move the gripper, keeping its rotation, to ``(x, y, z)`` in world [m] by IK.

    The gripper is the arm holding the jug, else the arm in use (then the other), else the
    arm on the target's side. A held jug moves with it. ``failure`` with the IK reason, or
    ``collision`` when the held jug would reach into the glass there.
    """
    state = read_state(bb)
    position = np.array([x, y, z])
    rotation = bb.get("gripper_rotation") or (0.0, 0.0, 0.0)
    arms = _gripper_arms(state, (x, y, z))
    if not arms:
        return fail(bb, "already_holding", "MoveGripperToParam: both grippers are full")
    if _holding_arm(state, "jug") and held_jug_hits_glass((x, y, z), rotation, glass_at(bb)):
        return fail(bb, "collision", f"MoveGripperToParam: the held jug would reach into "
                    f"the glass at {fmt((x, y, z))} m")
    answer = reach_either(world, state, arms, pin.SE3(_rpy(*rotation), position),
                          scene_world(bb), rng)
    if answer.state is None:
        return fail(bb, answer.reason, f"MoveGripperToParam: {answer.detail}")
    new = RobotState(answer.state.base_pose_world, answer.state.torso_height_m,
                     answer.state.q_arm_rad, answer.state.held, answer.arm)
    commit(world, bb, new, gripper_rotation=(float(rotation[0]), float(rotation[1]),
                                      float(rotation[2])))
    return "success"


@kinematic_skill(
    name="RotateGripperToParam",
    reads=_MOVE_READS,
    writes=_MOVE_WRITES,
)
def rotate_gripper_to_param(
    world: KinematicWorld,
    bb: Blackboard,
    rng: np.random.Generator,
    *,
    rho: Roll = 0.0,
    phi: Pitch = 0.0,
    theta: Yaw = 0.0,
) -> Literal["success"]:
    """Rotate the gripper in place to roll, pitch, yaw ``(rho, phi, theta)`` [rad] by IK.

    A held jug pours by the abstract twin's rule. The abstract twin has only ``success``:
    when the rotation is impossible, or would turn the held jug into the glass, the gripper
    stays, ``last_failure_reason`` says why, and the outcome is still ``success``.
    """
    state = read_state(bb)
    robot_to_world = transform_robot_to_world(state.base_pose_world)
    arm = _holding_arm(state, "jug") or state.arm_in_use
    if arm is None:
        gripper = bb.get("gripper_position_world") or (0.6, 0.0, 1.1)
        arm = arms_for(state, gripper)[0]
    tool = robot_to_world * world.transform_tool_to_robot(
        arm, state.torso_height_m, state.q_arm_rad[arm])
    if _holding_arm(state, "jug") and held_jug_turns_into_glass(
            tool.translation, rpy_matrix(bb.get("gripper_rotation") or (0.0, 0.0, 0.0)),
            rpy_matrix((rho, phi, theta)), glass_at(bb)):
        fail(bb, "collision", "RotateGripperToParam (gripper left as it was): the held jug "
             "would turn into the glass")
        return "success"
    target = pin.SE3(_rpy(rho, phi, theta), tool.translation.copy())
    answer = reach(world, state, arm, target, scene_world(bb), rng)
    if answer.state is None:
        fail(bb, answer.reason, f"RotateGripperToParam (gripper left as it was): "
             f"{answer.detail}")
        return "success"
    new = RobotState(answer.state.base_pose_world, answer.state.torso_height_m,
                     answer.state.q_arm_rad, answer.state.held, arm)
    commit(world, bb, new, gripper_rotation=(rho, phi, theta))
    return "success"


@skill(name="CheckSuccess", reads=("water",), backend=BACKEND)
def check_success(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    """Look into the glass: ``success`` when the water is in it, ``failure`` otherwise."""
    return "success" if bb["water"] == "glass" else "failure"


# -- new skills ------------------------------------------------------------------------------
@kinematic_skill(name="MoveGripperToPose", reads=_MOVE_READS, writes=_MOVE_WRITES)
def move_gripper_to_pose(
    world: KinematicWorld,
    bb: Blackboard,
    rng: np.random.Generator,
    *,
    arm: Literal["left", "right"] = "right",
    x: Annotated[float, Param(*_FLOOR_M, unit="m", doc="tool x, world frame")] = 0.6,
    y: Annotated[float, Param(*_FLOOR_M, unit="m", doc="tool y, world frame")] = 0.0,
    z: Annotated[float, Param(0.0, 2.0, unit="m", doc="tool z, world frame")] = 1.0,
    roll: Annotated[float, Param(-_PI, _PI, unit="rad", doc="tool roll, world x")] = 0.0,
    pitch: Annotated[float, Param(-_PI, _PI, unit="rad", doc="tool pitch, world y")] = 0.0,
    yaw: Annotated[float, Param(-_PI, _PI, unit="rad", doc="tool yaw, world z")] = 0.0,
) -> Literal["success", "failure"]:
    """Put ``arm``'s tool frame on the pose (x, y, z, roll, pitch, yaw) in world, torso
    free, base fixed; ``arm`` becomes the arm in use. ``failure`` with the IK reason."""
    state = read_state(bb)
    target = pin.SE3(_rpy(roll, pitch, yaw), np.array([x, y, z]))
    answer = reach(world, state, arm, target, scene_world(bb), rng)
    if answer.state is None:
        return fail(bb, answer.reason, f"MoveGripperToPose: {answer.detail}")
    new = RobotState(answer.state.base_pose_world, answer.state.torso_height_m,
                     answer.state.q_arm_rad, answer.state.held, arm)
    commit(world, bb, new, gripper_rotation=(roll, pitch, yaw))
    return "success"


@kinematic_skill(
    name="Reachable",
    reads=(*ROBOT_READS, *WORLD_READS),
    writes=(REASON_KEY, DETAIL_KEY),
)
def reachable(
    world: KinematicWorld,
    bb: Blackboard,
    rng: np.random.Generator,
    *,
    arm: Literal["left", "right"] = "right",
    object: _ObjectName = "object",
) -> Literal["yes", "no"]:
    """Can ``arm`` grasp ``object`` from where the robot stands? A condition: moves nothing.

    The grasp is horizontal, pointing along the bearing from the base (the grasp of
    :mod:`skillcompose.robots.reachability`), the torso stays at its height, collisions with the
    table (and the pour world's glass, unless it is the object) count. ``yes`` when IK
    finds a collision-free configuration; ``no`` writes the reason.
    """
    position = object_position(bb, object)
    if position is None:
        fail(bb, "no_object", f"Reachable: the world has no object {object!r}")
        return "no"
    state = read_state(bb)
    target = horizontal_grasp_world(state.base_pose_world, position)
    answer = reach(world, state, arm, target, scene_world(bb, glass=object != "glass"), rng,
                   move_torso=False)  # the glass, when it is the goal, is not in the way
    if answer.state is None:
        fail(bb, answer.reason, f"Reachable: {answer.detail}")
        return "no"
    return "yes"


@kinematic_skill(name="PlaceBase", reads=_MOVE_READS, writes=_MOVE_WRITES)
def place_base(
    world: KinematicWorld,
    bb: Blackboard,
    rng: np.random.Generator,
    *,
    arm: Literal["left", "right"] = "right",
    object: _ObjectName = "object",
) -> Literal["success", "failure"]:
    """Move the base (and torso and arm) so that ``arm`` grasps ``object`` horizontally.

    Tries up to :data:`PLACE_BASE_CANDIDATES` base poses drawn from the run's generator
    around the object (the object 0.35–0.75 m ahead, on the arm's side, heading within
    ±0.7 rad of it); a candidate whose base box hits the scene is skipped, else arm and
    torso IK (collision-free) decides. ``failure``: ``no_object``, ``collision`` (every
    base pose collides) or ``unreachable``.
    """
    position = object_position(bb, object)
    if position is None:
        return fail(bb, "no_object", f"PlaceBase: the world has no object {object!r}")
    state = read_state(bb)
    scene = scene_world(bb)
    sign = 1.0 if arm == "left" else -1.0
    heading = math.atan2(position[1] - state.base_pose_world[1],
                         position[0] - state.base_pose_world[0])
    tried_arm = False
    reasons: list[str] = []
    for k in range(PLACE_BASE_CANDIDATES):
        if k == 0:
            yaw, ahead, side = heading, 0.55, 0.2
        else:
            yaw = heading + rng.uniform(-0.7, 0.7)
            ahead, side = rng.uniform(0.35, 0.75), rng.uniform(-0.05, 0.45)
        c, s = math.cos(yaw), math.sin(yaw)
        base = (position[0] - (c * ahead - s * sign * side),
                position[1] - (s * ahead + c * sign * side), yaw)
        if base_collides(base, scene) is not None:
            continue
        moved = RobotState(base, state.torso_height_m, state.q_arm_rad, state.held, arm)
        if _arms_collide(world, moved, scene):
            continue
        tried_arm = True
        answer = reach(world, moved, arm, horizontal_grasp_world(base, position), scene, rng,
                       restarts=2, diagnose=False)
        if answer.state is not None:
            commit(world, bb, RobotState(base, answer.state.torso_height_m, answer.state.q_arm_rad,
                                  answer.state.held, arm))
            return "success"
        reasons.append(answer.reason)
    if not tried_arm:
        return fail(bb, "collision", f"PlaceBase: every base pose tried near {fmt(position)} "
                    "collides with the scene")
    reason = "collision" if reasons and all(r == "collision" for r in reasons) else "unreachable"
    return fail(bb, reason, f"PlaceBase: from no base pose tried can the {arm} arm grasp "
                f"{object!r} at {fmt(position)} m")


def _arms_collide(world: KinematicWorld, state: RobotState, scene: Scene) -> bool:
    """Whether either arm, at its joint angles, hits the scene (robot-frame check)."""
    robot_to_world = transform_robot_to_world(state.base_pose_world)
    local = Scene(tuple(_box_to_robot(b, robot_to_world) for b in scene.boxes))
    return any(
        check_collisions(world.chains[a], state.coordinates(a), local,
                         margin_m=COLLISION_MARGIN_M).collides
        for a in ARMS
    )


def _box_to_robot(box: Box, robot_to_world: pin.SE3) -> Box:
    centre = robot_to_world.actInv(np.asarray(box.center_m, dtype=float))
    yaw = math.atan2(robot_to_world.rotation[1, 0], robot_to_world.rotation[0, 0])
    return Box((float(centre[0]), float(centre[1]), float(centre[2])), box.half_extents_m,
               box.yaw_rad - yaw, box.name)


def _drive_base(
    world: KinematicWorld, bb: Blackboard, who: str, pose: tuple[float, float, float], torso: float,
    arm: Literal["left", "right"],
) -> Literal["success", "failure"]:
    """Drive the base to ``pose`` (x, y, yaw in world), set the torso, choose the arm:
    ``failure`` (``collision``) when the base box or an arm at the new pose hits the scene,
    or the base leaves the room (``room_half_m``, when the world has one); held objects
    move with the robot."""
    x, y, yaw = pose
    room = bb.get("room_half_m")
    if room is not None and not base_in_room(pose, float(room)):
        return fail(bb, "collision", f"{who}: the base at {fmt(pose)} (m, m, rad) leaves the "
                    f"room |x|, |y| <= {float(room):g} m")
    state = read_state(bb)
    scene = scene_world(bb)
    hit = base_collides(pose, scene)
    if hit is not None:
        return fail(bb, "collision", f"{who}: the base at {fmt(pose)} (m, m, rad) "
                    f"hits {hit!r} (base half size {BASE_HALF_EXTENTS_M[0]} m)")
    moved = RobotState((x, y, yaw), torso, state.q_arm_rad, state.held, arm)
    if _arms_collide(world, moved, scene):
        return fail(bb, "collision", f"{who}: at {fmt(pose)} with the torso at "
                    f"{torso:.3f} m an arm hits the scene")
    commit(world, bb, moved)
    return "success"


@kinematic_skill(name="MoveBasePose", reads=(*_MOVE_READS, "room_half_m"), writes=_MOVE_WRITES)
def move_base_pose(
    world: KinematicWorld,
    bb: Blackboard,
    rng: np.random.Generator,
    *,
    x: Annotated[float, Param(*_FLOOR_M, unit="m", doc="base x, world frame")] = 0.0,
    y: Annotated[float, Param(*_FLOOR_M, unit="m", doc="base y, world frame")] = 0.0,
    yaw: Annotated[float, Param(-_PI, _PI, unit="rad", doc="base heading, world z")] = 0.0,
    torso: Annotated[float, Param(*TORSO_RANGE_M, unit="m", doc="torso lift")] = 0.0,
    arm: Literal["left", "right"] = "right",
) -> Literal["success", "failure"]:
    """Drive the base to (x, y, yaw) in world, set the torso, choose the arm: section 4.2's
    five MoveBase outputs as explicit parameters. ``failure`` (``collision``) when the base
    box or an arm at the new pose hits the table; held objects move with the robot."""
    return _drive_base(world, bb, "MoveBasePose", (x, y, yaw), torso, arm)


def make_move_base(topology: Topology) -> KinematicSkill:
    """The kinematic twin of the network ``MoveBase`` of
    :mod:`skillcompose.skills.move_to_push`: the same network and the same mapping of its
    outputs to a base pose, torso height and arm, then the motion of :func:`move_base_pose`
    on the PR2 model."""
    weights_type: Any  # a run-time Annotated[...]: its length depends on the topology
    weights_type, zeros = weights_parameter(topology)

    def move_base(
        world: KinematicWorld, bb: Blackboard, rng: np.random.Generator, *,
        weights: weights_type = zeros,
    ) -> Literal["success", "failure"]:
        goal = network_goal(bb, rng, topology, weights)
        if goal == "no_object":
            return fail(bb, "no_object", "MoveBase: no object_location_world; run "
                        "RecogniseObject first")
        if goal == "too_close":
            return fail(bb, "collision", "MoveBase: the network's base pose comes closer "
                        f"than {SAFETY_M} m to the table")
        pose, torso, arm = goal
        return _drive_base(world, bb, "MoveBase", pose, torso, arm)

    move_base.__doc__ = make_move_base.__doc__
    # this module postpones annotations; the vector's length is only known here
    move_base.__annotations__["weights"] = weights_type
    return kinematic_skill(name="MoveBase",
                           reads=(*_MOVE_READS, "object_location_world", "room_half_m"),
                           writes=_MOVE_WRITES)(move_base)


@kinematic_skill(name="Push", reads=_MOVE_READS, writes=(*_MOVE_WRITES, "pushed"))
def push(
    world: KinematicWorld, bb: Blackboard, rng: np.random.Generator
) -> Literal["success", "failure"]:
    """Push ``object_position_world`` 5 cm away from the robot with the arm in use.

    The tool, horizontal and pointing along the bearing from the base, goes from 5 cm before
    the object's centre to its centre (torso and base fixed: MoveBase chose them); the object
    then sits 5 cm further. ``failure`` with the IK reason of either waypoint, or
    ``no_object``.
    """
    position = object_position(bb, "object")
    if position is None:
        return fail(bb, "no_object", "Push: the world has no object_position_world")
    state = read_state(bb)
    arm = state.arm_in_use or arms_for(state, position)[0]
    if state.held[arm] is not None:
        return fail(bb, "already_holding", f"Push: the {arm} gripper holds {state.held[arm]!r}")
    end = horizontal_grasp_world(state.base_pose_world, position)
    direction = end.rotation[:, 0]
    start = pin.SE3(end.rotation, end.translation - PUSH_DISTANCE_M * direction)
    scene = scene_world(bb)
    first = reach(world, state, arm, start, scene, rng, move_torso=False)
    if first.state is None:
        return fail(bb, first.reason, f"Push (contact): {first.detail}")
    second = reach(world, first.state, arm, end, scene, rng, move_torso=False)
    if second.state is None:
        return fail(bb, second.reason, f"Push (stroke): {second.detail}")
    pushed = end.translation + PUSH_DISTANCE_M * direction
    commit(world, bb, RobotState(second.state.base_pose_world, second.state.torso_height_m,
                          second.state.q_arm_rad, second.state.held, arm),
           moved_objects={"object": (float(pushed[0]), float(pushed[1]), float(pushed[2]))})
    bb["pushed"] = True
    return "success"


_WHICH = Which


@kinematic_skill(name="GraspParam",
                 reads=(*_MOVE_READS, "objects_grasped", "object_locations_world"),
                 writes=(*_MOVE_WRITES, "objects_grasped", "grasp_target"))
def grasp_param(
    world: KinematicWorld,
    bb: Blackboard, rng: np.random.Generator, *, which: _WHICH = 1.0
) -> Literal["success", "failure"]:
    """Grasp the first (``which`` > 0.5) or second stacking object, from the side else from
    above (:data:`skillcompose.skills.kinematic_world.GRASP_KINDS`), by IK with the arm on its side
    (then
    the other). ``failure``: ``no_object``, ``not_recognised``, ``already_holding`` or the IK
    reason. Writes the object it tries to ``grasp_target`` and,
    grasped, appends it to ``objects_grasped``."""
    name = stack_object_name(bb, which)
    if name is None:
        return fail(bb, "no_object", "GraspParam: object_positions_world needs two objects")
    if bb.get("object_locations_world") is None:
        return fail(bb, "not_recognised", "GraspParam: the objects were not recognised; run "
                    "RecogniseObject first")
    state = read_state(bb)
    if any(state.held[a] is not None for a in ARMS):
        return fail(bb, "already_holding", "GraspParam: a gripper already holds an object")
    bb["grasp_target"] = name
    position = object_position(bb, name)
    assert position is not None  # the name came from the same mapping
    kind, answer = reach_grasp(world, state, arms_for(state, position), position, scene_world(bb),
                               rng)
    if answer.state is None:
        return fail(bb, answer.reason, f"GraspParam: {answer.detail}")
    bb[GRASP_KEY] = kind
    held = dict(answer.state.held)
    held[answer.arm] = name
    commit(world, bb, RobotState(answer.state.base_pose_world, answer.state.torso_height_m,
                          answer.state.q_arm_rad, held, answer.arm))
    bb["objects_grasped"] = (*(bb.get("objects_grasped") or ()), name)
    return "success"


@kinematic_skill(name="MoveGripperToStack", reads=_MOVE_READS, writes=_MOVE_WRITES)
def move_gripper_to_stack(
    world: KinematicWorld,
    bb: Blackboard,
    rng: np.random.Generator,
    *,
    which: _WHICH = 1.0,
    dx: StackDX = 0.0,
    dy: StackDY = 0.0,
    dz: StackDZ = 0.1,
) -> Literal["success", "failure"]:
    """Move the gripper, from above, to the chosen object's centre + (dx, dy, dz) in world.

    The paper's failures without the coin flip: ``collision`` when the tool point ends inside
    the table or an object, or a held object would sink into one (touching is stacking);
    the IK reasons when the arm cannot get there. A held object moves with the gripper.
    """
    name = stack_object_name(bb, which)
    if name is None:
        return fail(bb, "no_object",
                    "MoveGripperToStack: object_positions_world needs two objects")
    state = read_state(bb)
    anchor = object_position(bb, name)
    assert anchor is not None
    position = np.array(anchor) + np.array([dx, dy, dz])
    holding = next((a for a in ARMS if state.held[a] is not None), None)
    arms = (holding,) if holding is not None else free_arms(state, position)
    stack = bb.get("object_positions_world") or {}
    others = [object_box(bb, n, p) for n, p in stack.items()
              if n not in state.held.values()]
    table = scene_world(bb).boxes
    solid = [*table, *others]
    if any(float(b.signed_distance_m(position)[0]) < 0.0 for b in solid):
        return fail(bb, "collision", f"MoveGripperToStack: the gripper at {fmt(position)} m "
                    "would be inside the table or an object")
    if holding is not None:
        carried = state.held[holding]
        assert carried is not None
        hit = boxes_collide(object_box(bb, carried, position), solid)
        if hit is not None:
            return fail(bb, "collision", f"MoveGripperToStack: the held {carried!r} at "
                        f"{fmt(position)} m would sink into {hit!r}")
    kinds: tuple[GraspKind, ...] = ("top",) if holding is None else \
        (bb.get(GRASP_KEY) or "top",)
    _, answer = reach_grasp(world, state, arms, position, Scene(tuple(table)), rng, kinds)
    if answer.state is None:
        return fail(bb, answer.reason, f"MoveGripperToStack: {answer.detail}")
    commit(world, bb, RobotState(answer.state.base_pose_world, answer.state.torso_height_m,
                          answer.state.q_arm_rad, answer.state.held, answer.arm))
    return "success"


@kinematic_skill(name="OpenGripper", reads=_MOVE_READS, writes=(*_MOVE_WRITES, "holding_jug"))
def open_gripper(
    world: KinematicWorld, bb: Blackboard, rng: np.random.Generator
) -> Literal["success"]:
    """Open the gripper in use; a held stacking object falls straight down onto the highest
    surface under it (the table, another object or the floor). Always ``success``."""
    state = read_state(bb)
    arm = state.arm_in_use or next((a for a in ARMS if state.held[a] is not None), None)
    if arm is None or state.held[arm] is None:
        return "success"
    name = state.held[arm]
    assert name is not None
    held = dict(state.held)
    held[arm] = None
    released = RobotState(state.base_pose_world, state.torso_height_m, state.q_arm_rad, held,
                          state.arm_in_use)
    centre = object_position(bb, name) or (0.0, 0.0, 0.0)
    commit(world, bb, released)
    bb[GRASP_KEY] = None
    if name == "jug":
        bb["holding_jug"] = False  # the jug stays where it was let go (not modelled)
        return "success"
    box = object_box(bb, name, centre)
    stack = bb.get("object_positions_world") or {}
    z = landing_z(box, [*scene_world(bb).boxes,
                        *(object_box(bb, n, p) for n, p in stack.items() if n != name)])
    commit(world, bb, released, moved_objects={name: (box.center_m[0], box.center_m[1], z)})
    return "success"


SKILLS: tuple[Skill, ...] = (
    recognise_object,
    move_to_object,
    grasp_object,
    move_gripper_to_param,
    rotate_gripper_to_param,
    check_success,
    move_gripper_to_pose,
    reachable,
    place_base,
    move_base_pose,
    push,
    grasp_param,
    move_gripper_to_stack,
    open_gripper,
)
"""Every kinematic skill: the six pour-water twins first."""

TWINS = tuple(s.name for s in SKILLS[:6])
"""Names of the skills that have an abstract ("sim") twin today."""


def register(registry: Registry, *, world: KinematicWorld | None = None) -> KinematicWorld:
    """Add every kinematic skill (backend ``"kinematic"``) to ``registry``, running in
    ``world`` (default: a new :class:`~skillcompose.skills.kinematic_world.KinematicWorld`); return
    it.

    The registry refuses a twin whose signature differs from the abstract skill of the same
    name already in it. Task-free: ``--skills skillcompose.skills.kinematic``.
    """
    world = world or KinematicWorld()
    for s in in_world(SKILLS, world):
        registry.add(s)
    return world


def register_move_to_push(registry: Registry, *, topology: Topology = "layered") -> None:
    """Add the kinematic twins of the move-to-push skills (:mod:`skillcompose.skills.move_to_push`):
    MoveBase for a ``topology`` network and Push. RecogniseObject has one implementation
    for both backends (perception is not kinematics)."""
    world = KinematicWorld()
    registry.add(make_move_base(topology).in_world(world))
    registry.add(push.in_world(world))

