"""The robot behind the kinematic skills: its state on the blackboard, the scene, and motions.

The kinematic skills (:mod:`skillcompose.skills.kinematic`) move a PR2 (:mod:`robots`) instead of
flipping
coins. This module holds what they share: the blackboard keys of the robot, the conventions
that tie the abstract world of the ``"sim"`` skills to the robot, the :class:`KinematicWorld`
the skills move in (the model, loaded once per process and shared read-only, and the world's
own IK solvers), the :class:`KinematicSkill` kind bound to one, and one function per kind of
motion check.

Frames. The abstract skills describe the world "in the robot's base frame", named ``world``
in their keys. Here ``world`` is the floor frame of :mod:`robots` (z up) and the PR2 starts
with its ``base_footprint`` on the world origin, facing +x (``base_pose_world`` = (0, 0, 0)):
so the abstract world and the robot frame coincide until a base skill moves the robot, after
which world keys stay in the floor frame and IK targets are brought into the robot frame
with ``base_pose_world``. A gripper rotation ``(roll, pitch, yaw)`` is the tool frame's
rotation ``Rz(yaw) Ry(pitch) Rx(roll)`` in world axes; (0, 0, 0) is the tool's x axis (along
the fingers) pointing along world +x with the fingers horizontal, which is the abstract
skills' "upright" gripper. Its tilt ``arccos(cos roll cos pitch)`` is the same number in both
backends.

Robot keys (written by the kinematic skills; absent keys take the defaults below, so the
abstract task's ``setup`` works unchanged):

============================= ===============================================================
key                           meaning
============================= ===============================================================
``base_pose_world``           base (x [m], y [m], yaw [rad]) in world; default (0, 0, 0)
``torso_height_m``            torso lift [m] in [0, 0.31]; default 0
``q_left_arm_rad``            7 left arm joint angles [rad]; default tucked (PR2 tuck_arms)
``q_right_arm_rad``           7 right arm joint angles [rad]; default tucked
``tool_pose_left_world``      left tool frame (x, y, z [m], roll, pitch, yaw [rad]) in world
``tool_pose_right_world``     right tool frame, same layout
``held_object_left``          name of the object in the left gripper, or None
``held_object_right``         name of the object in the right gripper, or None
``arm_in_use``                the arm that is "the gripper" of the abstract skills, or None
``held_grasp``                how the held stacking object is held (``top`` at its centre or
                              ``side`` 3 cm above it, :data:`GRASP_KINDS`), or None
``table_world``               the table, a :class:`skillcompose.robots.collision.Box`; default
                              :data:`DEFAULT_TABLE_WORLD`; None for no table
``obstacles_world``           more boxes to avoid (a tuple of ``Box``); default none
``glass_position_world``      in the pour world, the glass's rim centre: the glass is a box
                              the arm avoids too (:func:`scene_world`)
``last_failure_reason``       why the last kinematic skill failed: one of
                              :data:`FAILURE_REASONS`
``last_failure_detail``       the same in words: skill, arm, target and solver status
============================= ===============================================================

Determinism. IK restarts draw from a generator seeded by one draw from the run's per IK
request, and stop after a fixed number of restarts rather than a wall-clock budget, so the
same seed gives the same outcome on any machine; no state of one run is left in the world
for the next.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import inspect
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pinocchio as pin

from skillcompose import Blackboard, Skill, SkillSpec, skill
from skillcompose.robots.collision import (
    BASE_HALF_EXTENTS_M,
    BODY_HEIGHT_M,
    Box,
    Scene,
    arm_spheres,
    check_collisions,
)
from skillcompose.robots.ik import IKSolver, IKStatus, IKTarget
from skillcompose.robots.model import (
    ARMS,
    TORSO_JOINT,
    TUCKED_ARM_RAD,
    Arm,
    FloatArray,
    KinematicChain,
    RobotModel,
    load_pr2,
)
from skillcompose.skill import SkillFn
from skillcompose.skills.pour_geometry import GLASS_HALF_EXTENTS_M, glass_at, move_held_water

__all__ = [
    "ARM_IN_USE_KEY",
    "BASE_POSE_KEY",
    "COLLISION_MARGIN_M",
    "DEFAULT_OBJECT_HALF_EXTENTS_M",
    "DEFAULT_TABLE_WORLD",
    "DETAIL_KEY",
    "FAILURE_REASONS",
    "GRASP_KEY",
    "GRASP_KINDS",
    "HELD_KEYS",
    "IK_RESTARTS",
    "MOBILE_BASE_ROBOT",
    "OBJECT_CHOICES",
    "OBSTACLES_KEY",
    "Q_KEYS",
    "REASON_KEY",
    "ROBOT_READS",
    "ROBOT_WRITES",
    "SIDE_GRASP_RISE_M",
    "TABLE_KEY",
    "TOOL_KEYS",
    "TORSO_KEY",
    "TORSO_RANGE_M",
    "WORLD_READS",
    "WORLD_WRITES",
    "GraspKind",
    "KinematicSkill",
    "KinematicWorld",
    "Reach",
    "RobotState",
    "base_collides",
    "commit",
    "fail",
    "grasp_offset_world",
    "grasp_pose_world",
    "horizontal_grasp_world",
    "in_world",
    "kinematic_skill",
    "object_box",
    "object_position",
    "reach",
    "reach_grasp",
    "read_state",
    "scene_world",
    "top_down_grasp_world",
    "transform_robot_to_world",
]

Vec3 = tuple[float, float, float]

BASE_POSE_KEY = "base_pose_world"
TORSO_KEY = "torso_height_m"
Q_KEYS: dict[Arm, str] = {"left": "q_left_arm_rad", "right": "q_right_arm_rad"}
TOOL_KEYS: dict[Arm, str] = {"left": "tool_pose_left_world", "right": "tool_pose_right_world"}
HELD_KEYS: dict[Arm, str] = {"left": "held_object_left", "right": "held_object_right"}
ARM_IN_USE_KEY = "arm_in_use"
GRASP_KEY = "held_grasp"
"""How the held stacking object is held (:data:`GRASP_KINDS`), None when none is."""
TABLE_KEY = "table_world"
OBSTACLES_KEY = "obstacles_world"
REASON_KEY = "last_failure_reason"
DETAIL_KEY = "last_failure_detail"

FAILURE_REASONS = (
    "unreachable",  # no arm configuration puts the tool there, even ignoring joint limits
    "joint_limits",  # reachable only outside the joint limits
    "collision",  # every solution found (or the base, or a held object) hits the scene
    "not_recognised",  # the object has not been recognised yet
    "too_far",  # the gripper is not close enough to grasp
    "not_holding",  # nothing in the gripper to move or release
    "already_holding",  # the gripper is full
    "no_object",  # the world has no such object
)
"""Values of ``last_failure_reason``."""

DEFAULT_TABLE_WORLD = Box.table((0.80, 0.0), (0.70, 1.40), 0.75)
"""The pour-water table: top at z = 0.75 m, front edge at x = 0.45 m, y in [-0.7, 0.7] m.
It holds the jug (0.60, -0.20) and the glass (0.60, 0.20) of :mod:`examples.pour_water`."""
DEFAULT_OBJECT_HALF_EXTENTS_M: Vec3 = (0.03, 0.03, 0.06)
"""Half sizes of a stacking object when ``object_half_extents_m`` does not say [m]: 6 x 6 x
12 cm, tall enough for a grasp from above at its centre to clear the table."""
TORSO_RANGE_M = (0.0, 0.31)
"""Torso lift limits of the PR2 [m]."""
COLLISION_MARGIN_M = 0.01
"""Clearance kept between the robot's collision spheres / base box and the scene [m]."""
IK_RESTARTS = 6
"""Random restarts per IK request (after the attempt from the current configuration)."""
IK_DIAGNOSE_RESTARTS = 3
"""Restarts of the limit-free IK that tells ``joint_limits`` from ``unreachable``."""
MOBILE_BASE_ROBOT = Box((0.0, 0.0, 0.18), (*BASE_HALF_EXTENTS_M, 0.18), 0.0, "robot_base")
"""The PR2's mobile base in the robot frame (top at 0.36 m): the arms must stay out of it.
:mod:`skillcompose.robots.collision` checks no self-collision; this is the one the skills add."""
_IK_TIME_CAP_S = 10.0  # a safety cap only: the restart count bounds the work
_TOUCH_TOLERANCE_M = 0.002  # boxes may touch (stacked) within this much overlap

OBJECT_CHOICES = ("jug", "glass", "object", "first", "second")
"""Objects a skill parameter may name: the pour-water jug and glass (``jug_position_world``,
``glass_position_world``), the single object of the pushing experiment
(``object_position_world``) and the first / second object of the stacking experiment (the
first two entries of ``object_positions_world``)."""

# -- blackboard key groups -------------------------------------------------------------------
_POUR_KEYS = (
    "jug_position_world", "glass_position_world", "gripper_position_world",
    "gripper_rotation", "holding_jug", "water",
)
_OBJECT_KEYS = ("object_position_world", "object_positions_world", "object_half_extents_m")
ROBOT_READS = (
    BASE_POSE_KEY, TORSO_KEY, *Q_KEYS.values(), *HELD_KEYS.values(), ARM_IN_USE_KEY,
    GRASP_KEY, TABLE_KEY, OBSTACLES_KEY,
)
"""Keys every kinematic skill reads: the robot and the scene."""
ROBOT_WRITES = (
    BASE_POSE_KEY, TORSO_KEY, *Q_KEYS.values(), *TOOL_KEYS.values(), *HELD_KEYS.values(),
    ARM_IN_USE_KEY, GRASP_KEY, REASON_KEY, DETAIL_KEY,
)
"""Keys a moving kinematic skill writes about the robot."""
WORLD_READS = (*_POUR_KEYS, *_OBJECT_KEYS)
"""World keys a moving skill reads: a held object moves with the gripper that holds it."""
WORLD_WRITES = (
    "jug_position_world", "gripper_position_world", "gripper_rotation", "water",
    "water_left_at_world", "object_position_world", "object_positions_world",
)
"""World keys a moving skill may write."""


# -- the world the skills move in ----------------------------------------------------------
@functools.lru_cache(maxsize=1)
def _pr2() -> tuple[RobotModel, dict[Arm, KinematicChain], dict[Arm, KinematicChain]]:
    """The PR2 and its arm + torso chains, with and without arm joint limits: loaded once
    per process (about 0.3 s) and only read, each thread with its own Pinocchio work data."""
    model = load_pr2()
    chains: dict[Arm, KinematicChain] = {arm: model.chain(f"{arm}_arm_torso") for arm in ARMS}
    free = {}
    for arm in ARMS:
        chain = chains[arm]
        arm_coordinates = np.array([name != TORSO_JOINT for name in chain.coordinate_names])
        free[arm] = dataclasses.replace(
            chain,
            lower_limits=np.where(arm_coordinates, -np.inf, chain.lower_limits),
            upper_limits=np.where(arm_coordinates, np.inf, chain.upper_limits),
        )
    return model, chains, free


class KinematicWorld:
    """The robot the kinematic skills move: the PR2 model and chains (shared read-only by
    every world of the process) and this world's IK solvers, one per arm (arm + torso, in
    the robot frame). A registry's kinematic skills run in the world their ``register``
    made (:class:`KinematicSkill`); nothing of it is global. The solvers draw from the
    generator each request passes, derived from the run's."""

    def __init__(self) -> None:
        self.model, self.chains, free = _pr2()
        self.solvers = {arm: IKSolver(chain=self.chains[arm], arm=arm) for arm in ARMS}
        self.free_solvers = {arm: IKSolver(chain=free[arm], arm=arm) for arm in ARMS}
        """Solvers on the same chains without arm joint limits: they tell
        ``joint_limits`` from ``unreachable``."""

    def transform_tool_to_robot(self, arm: Arm, torso_m: float, q_arm_rad: Sequence[float]
                                ) -> pin.SE3:
        """Tool frame of ``arm`` in the robot frame ``base_footprint``."""
        return self.chains[arm].transform_tool_to_world(arm, np.array([torso_m, *q_arm_rad]))


class KinematicSkill(Skill):
    """A skill of the ``kinematic`` backend, ``f(world, bb, rng, *, params...)``: it runs in
    a :class:`KinematicWorld`. :meth:`in_world` gives it bound to one (``register`` functions
    bind their skills to the world they make); an unbound one, called alone or compiled,
    makes a world of its own each time it is bound."""

    __slots__ = ("world",)

    def __init__(self, spec: SkillSpec, impl: Any, *, backend: str = "kinematic",
                 world: KinematicWorld | None = None) -> None:
        super().__init__(spec, impl, backend=backend)
        self.world = world

    def in_world(self, world: KinematicWorld) -> KinematicSkill:
        bound = copy.copy(self)
        bound.world = world
        return bound

    def bind(self, registry: Any = None, backend: str | None = None) -> SkillFn:
        return functools.partial(self.impl, self.world or KinematicWorld())


def kinematic_skill(**declaration: Any) -> Callable[[Callable[..., str]], KinematicSkill]:
    """``@skill(**declaration, backend="kinematic")`` for ``f(world, bb, rng, *, ...)``: the
    declaration is read from the signature after ``world``."""

    def wrap(fn: Callable[..., str]) -> KinematicSkill:
        @functools.wraps(fn)
        def declared(bb: Blackboard, rng: np.random.Generator, **params: Any) -> str:
            raise AssertionError("never called: KinematicSkill.bind passes the world")

        sig = inspect.signature(fn)
        declared.__signature__ = sig.replace(  # type: ignore[attr-defined]
            parameters=list(sig.parameters.values())[1:])
        spec = skill(declared, backend="kinematic", **declaration).spec
        return KinematicSkill(spec, fn)

    return wrap


def in_world(skills: Iterable[Skill], world: KinematicWorld) -> list[Skill]:
    """``skills``, the kinematic ones bound to ``world`` (the others need none)."""
    return [s.in_world(world) if isinstance(s, KinematicSkill) else s for s in skills]


# -- the robot's state on the blackboard -----------------------------------------------------
@dataclass(frozen=True)
class RobotState:
    """The robot as the blackboard describes it (see the module's table of keys)."""

    base_pose_world: Vec3
    torso_height_m: float
    q_arm_rad: Mapping[Arm, tuple[float, ...]]
    held: Mapping[Arm, str | None]
    arm_in_use: Arm | None

    def with_arm(
        self, arm: Arm, torso_m: float, q_arm_rad: Sequence[float] | FloatArray
    ) -> RobotState:
        q = dict(self.q_arm_rad)
        q[arm] = tuple(float(v) for v in q_arm_rad)
        return dataclasses.replace(self, torso_height_m=float(torso_m), q_arm_rad=q)

    def coordinates(self, arm: Arm) -> FloatArray:
        """Coordinates of the ``{arm}_arm_torso`` chain: torso [m], 7 joints [rad]."""
        return np.array([self.torso_height_m, *self.q_arm_rad[arm]])


def read_state(bb: Blackboard) -> RobotState:
    """The robot's state, defaults for absent keys (base on the origin, torso down, tucked)."""
    base = bb.get(BASE_POSE_KEY) or (0.0, 0.0, 0.0)
    q = {arm: tuple(float(v) for v in bb.get(Q_KEYS[arm]) or TUCKED_ARM_RAD[arm])
         for arm in ARMS}
    held = {arm: bb.get(HELD_KEYS[arm]) for arm in ARMS}
    if bb.get("holding_jug") and "jug" not in held.values():
        # an abstract run handed over mid-way: the jug is in "the gripper"
        held[bb.get(ARM_IN_USE_KEY) or "right"] = "jug"
    return RobotState(
        (float(base[0]), float(base[1]), float(base[2])),
        float(bb.get(TORSO_KEY, 0.0)),
        q,
        held,
        bb.get(ARM_IN_USE_KEY),
    )


def transform_robot_to_world(base_pose_world: Sequence[float]) -> pin.SE3:
    """Placement of the robot frame in world for a base pose (x [m], y [m], yaw [rad])."""
    x, y, yaw = base_pose_world
    return pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, float(yaw)), np.array([x, y, 0.0]))


def _pose6(transform: pin.SE3) -> tuple[float, ...]:
    rpy = pin.rpy.matrixToRpy(transform.rotation)
    return tuple(float(v) for v in (*transform.translation, *rpy))


def commit(
    world: KinematicWorld,
    bb: Blackboard,
    state: RobotState,
    *,
    gripper_rotation: Vec3 | None = None,
    moved_objects: Mapping[str, Vec3] | None = None,
) -> dict[Arm, pin.SE3]:
    """Write ``state`` and everything that follows from it; return the tool poses in world.

    Writes the robot keys and both tool poses; when an arm is in use, the abstract
    ``gripper_position_world`` / ``gripper_rotation`` (``gripper_rotation`` as given, else
    from the tool's rotation); every held object moves with its gripper (the jug's spout and
    a stacking object's centre sit at the tool frame's origin, or :data:`SIDE_GRASP_RISE_M` under it
    when ``held_grasp`` is ``side``), and a held jug's water pours
    or spills as in :mod:`skillcompose.skills.pour_water`. ``moved_objects`` sets other objects'
    positions.
    """
    robot_to_world = transform_robot_to_world(state.base_pose_world)
    # where the jug was, as the abstract skills give it (None: not held until now)
    jug_before = (bb.get("gripper_position_world"), bb.get("gripper_rotation")) \
        if any(bb.get(HELD_KEYS[arm]) == "jug" for arm in ARMS) else None
    bb[BASE_POSE_KEY] = state.base_pose_world
    bb[TORSO_KEY] = state.torso_height_m
    tools: dict[Arm, pin.SE3] = {}
    for arm in ARMS:
        bb[Q_KEYS[arm]] = tuple(state.q_arm_rad[arm])
        tools[arm] = robot_to_world * world.transform_tool_to_robot(
            arm, state.torso_height_m, state.q_arm_rad[arm]
        )
        bb[TOOL_KEYS[arm]] = _pose6(tools[arm])
        bb[HELD_KEYS[arm]] = state.held[arm]
    bb[ARM_IN_USE_KEY] = state.arm_in_use
    if state.arm_in_use is not None:
        tool = tools[state.arm_in_use]
        bb["gripper_position_world"] = _vec3(tool.translation)
        if gripper_rotation is None:
            rpy = pin.rpy.matrixToRpy(tool.rotation)
            gripper_rotation = (float(rpy[0]), float(rpy[1]), float(rpy[2]))
        bb["gripper_rotation"] = gripper_rotation
    positions = dict(moved_objects or {})
    offset = np.asarray(grasp_offset_world(bb.get(GRASP_KEY)))
    for arm in ARMS:
        name = state.held[arm]
        if name is not None:
            at = tools[arm].translation + (0.0 if name in ("jug", "object") else offset)
            positions[name] = _vec3(at)
    stack = bb.get("object_positions_world")
    new_stack = dict(stack) if isinstance(stack, Mapping) else None
    for name, position in positions.items():
        if name == "jug":
            bb["jug_position_world"] = position
        elif name == "object":
            bb["object_position_world"] = position
        elif new_stack is not None and name in new_stack:
            new_stack[name] = position
    if new_stack is not None and new_stack != stack:
        bb["object_positions_world"] = new_stack
    if "jug" in state.held.values():
        move_held_water(bb, jug_before)
    return tools


def fail(bb: Blackboard, reason: str, detail: str) -> Literal["failure"]:
    """Record why a skill failed (``last_failure_reason`` / ``_detail``); return "failure"."""
    bb[REASON_KEY] = reason
    bb[DETAIL_KEY] = detail
    return "failure"


def _vec3(values: Sequence[float] | FloatArray) -> Vec3:
    return (float(values[0]), float(values[1]), float(values[2]))


# -- objects and the scene -------------------------------------------------------------------
def object_position(bb: Blackboard, name: str) -> Vec3 | None:
    """Position of a named object (see :data:`OBJECT_CHOICES`) in world [m], or None."""
    if name in ("jug", "glass", "object"):
        value = bb.get(f"{name}_position_world")
        return None if value is None else _vec3(value)
    stack = bb.get("object_positions_world")
    if not isinstance(stack, Mapping):
        return None
    names = list(stack)
    index = 0 if name == "first" else 1 if name == "second" else None
    if index is None:
        key: str | None = name if name in stack else None
    else:
        key = names[index] if index < len(names) else None
    return None if key is None else _vec3(stack[key])


def stack_object_name(bb: Blackboard, which: float) -> str | None:
    """The stacking object a ``which`` parameter picks: > 0.5 the first, else the second."""
    stack = bb.get("object_positions_world")
    if not isinstance(stack, Mapping) or len(stack) < 2:
        return None
    names = list(stack)
    return str(names[0] if which > 0.5 else names[1])


def object_box(bb: Blackboard, name: str, centre_world: Sequence[float]) -> Box:
    """A stacking object as a box centred at ``centre_world``."""
    sizes = bb.get("object_half_extents_m") or {}
    half = sizes.get(name, DEFAULT_OBJECT_HALF_EXTENTS_M)
    return Box(_vec3(centre_world), _vec3(half), 0.0, name)


def scene_world(bb: Blackboard, extra: Sequence[Box] = (), *, glass: bool = True) -> Scene:
    """The table, the pour world's glass (when ``glass_position_world`` is set and
    ``glass``: the arm must not knock it over; a 9 x 9 x 12 cm box under its rim),
    ``obstacles_world`` and ``extra`` boxes, in world."""
    table, rim, g = bb.get(TABLE_KEY, DEFAULT_TABLE_WORLD), glass_at(bb), GLASS_HALF_EXTENTS_M
    boxes = ([table] if table is not None else []) + (
        [Box((rim[0], rim[1], rim[2] - g[2]), g, 0.0, "glass")] if glass and rim else []
    ) + list(bb.get(OBSTACLES_KEY) or ()) + list(extra)
    return Scene(tuple(boxes))


def _scene_in_robot_frame(scene: Scene, base_pose_world: Sequence[float]) -> Scene:
    x, y, yaw = base_pose_world
    c, s = math.cos(yaw), math.sin(yaw)
    boxes = []
    for box in scene.boxes:
        dx, dy = box.center_m[0] - x, box.center_m[1] - y
        boxes.append(Box(
            (c * dx + s * dy, -s * dx + c * dy, box.center_m[2]),
            box.half_extents_m, box.yaw_rad - yaw, box.name,
        ))
    return Scene(tuple(boxes))


def base_collides(base_pose_world: Sequence[float], scene: Scene) -> str | None:
    """Name of the scene box the base/body box overlaps (with the margin), or None."""
    x, y, yaw = base_pose_world
    body = Box(
        (float(x), float(y), BODY_HEIGHT_M / 2), (*BASE_HALF_EXTENTS_M, BODY_HEIGHT_M / 2),
        float(yaw), "robot_base",
    )
    for box in scene.boxes:
        if body.overlaps(box, COLLISION_MARGIN_M):
            return box.name
    return None


def boxes_collide(box: Box, others: Sequence[Box]) -> str | None:
    """Name of a box in ``others`` that ``box`` penetrates (touching is allowed), or None."""
    shrunk = Box(box.center_m, tuple(max(h - _TOUCH_TOLERANCE_M, 1e-4)  # type: ignore[arg-type]
                                     for h in box.half_extents_m), box.yaw_rad, box.name)
    for other in others:
        if shrunk.overlaps(other):
            return other.name
    return None


def horizontal_grasp_world(base_pose_world: Sequence[float], position_world: Sequence[float]
                           ) -> pin.SE3:
    """A horizontal grasp of ``position_world``, pointing along the bearing from the base
    (the grasp of :mod:`skillcompose.robots.reachability`, in world)."""
    bearing = math.atan2(position_world[1] - base_pose_world[1],
                         position_world[0] - base_pose_world[0])
    return pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, bearing), np.asarray(position_world, float))


def top_down_grasp_world(base_pose_world: Sequence[float], position_world: Sequence[float]
                         ) -> pin.SE3:
    """A grasp from above (tool x axis down), fingers across the robot's heading."""
    rotation = pin.rpy.rpyToMatrix(0.0, 0.0, float(base_pose_world[2])) @ \
        pin.rpy.rpyToMatrix(0.0, math.pi / 2, 0.0)
    return pin.SE3(rotation, np.asarray(position_world, float))


GraspKind = Literal["top", "side"]
GRASP_KINDS: tuple[GraspKind, ...] = ("side", "top")
"""How a stacking object is held, in the order GraspParam tries them: from the side,
:data:`SIDE_GRASP_RISE_M` above its centre (the fingers clear the table; it reaches farther
across a table, and the PR2 takes bottles so), else from above at its centre. The object
stays upright either way, and every later pose of the holding gripper keeps the kind it was
grasped with."""
SIDE_GRASP_RISE_M = 0.03
"""A side grasp holds an object this far above its centre [m]."""


def grasp_offset_world(kind: GraspKind | None) -> Vec3:
    """A held object's centre relative to the tool point of a ``kind`` grasp [m]."""
    return (0.0, 0.0, -SIDE_GRASP_RISE_M) if kind == "side" else (0.0, 0.0, 0.0)


def grasp_pose_world(kind: GraspKind, base_pose_world: Sequence[float],
                     centre_world: Sequence[float]) -> pin.SE3:
    """The tool pose that holds an upright object with its centre at ``centre_world``."""
    if kind == "top":
        return top_down_grasp_world(base_pose_world, centre_world)
    tool = np.asarray(centre_world, float) - np.asarray(grasp_offset_world(kind))
    return horizontal_grasp_world(base_pose_world, tool)


def reach_grasp(
    world: KinematicWorld, state: RobotState, arms: Sequence[Arm],
    centre_world: Sequence[float], scene: Scene, rng: np.random.Generator,
    kinds: Sequence[GraspKind] = GRASP_KINDS, **options: Any,
) -> tuple[GraspKind, Reach]:
    """:func:`reach_either` for the pose of each grasp kind in turn: the first success, else
    the first kind's failure."""
    first: tuple[GraspKind, Reach] | None = None
    for kind in kinds:
        answer = reach_either(world, state, arms, grasp_pose_world(
            kind, state.base_pose_world, centre_world), scene, rng, **options)
        if answer.ok:
            return kind, answer
        first = first or (kind, answer)
    assert first is not None
    return first


# -- motions ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Reach:
    """The answer to "can ``arm`` put its tool on this pose": a new state or a reason."""

    arm: Arm
    state: RobotState | None
    reason: str = ""
    detail: str = ""

    @property
    def ok(self) -> bool:
        return self.state is not None


def reach(
    world: KinematicWorld,
    state: RobotState,
    arm: Arm,
    target_world: pin.SE3,
    scene: Scene,
    rng: np.random.Generator,
    *,
    move_torso: bool = True,
    position_only: bool = False,
    restarts: int = IK_RESTARTS,
    diagnose: bool = True,
) -> Reach:
    """Solve IK for ``arm`` (and the torso unless ``move_torso`` is False) to put its tool
    frame on ``target_world``, collision-free with ``scene`` (world boxes); the base stays.

    The other arm keeps its joint angles; when the torso moves, it is checked against the
    scene too. Failure reasons: ``collision`` (solutions exist but hit the scene),
    ``joint_limits`` (solutions exist only outside the limits), ``unreachable``; without
    ``diagnose`` the last two are both reported as ``unreachable``.
    """
    kin = world
    robot_to_world = transform_robot_to_world(state.base_pose_world)
    target_robot = robot_to_world.actInv(target_world)
    target = IKTarget(
        np.array(target_robot.translation),
        None if position_only else np.array(target_robot.rotation),
    )
    local_scene = _scene_in_robot_frame(scene, state.base_pose_world)
    other: Arm = "right" if arm == "left" else "left"
    other_chain = kin.chains[other]
    other_q = state.q_arm_rad[other]
    torso_now = state.torso_height_m

    def collides(chain: KinematicChain, theta: FloatArray) -> bool:
        if check_collisions(chain, theta, local_scene, margin_m=COLLISION_MARGIN_M).collides:
            return True
        centres, radii, _ = arm_spheres(chain, theta)
        if np.any(MOBILE_BASE_ROBOT.signed_distance_m(centres) < radii):
            return True
        if abs(float(theta[0]) - torso_now) < 1e-9:
            return False
        return check_collisions(other_chain, np.array([theta[0], *other_q]), local_scene,
                                margin_m=COLLISION_MARGIN_M).collides

    fixed = None if move_torso else {TORSO_JOINT: torso_now}
    result = kin.solvers[arm].solve(
        target, initial=state.coordinates(arm), fixed=fixed, collides=collides,
        time_budget_s=_IK_TIME_CAP_S, diagnose=False, max_restarts=restarts,
        rng=np.random.default_rng(int(rng.integers(2**63))),
    )
    where = (f"{arm} arm to {_fmt(target_world.translation)} m "
             f"(rpy {_fmt(pin.rpy.matrixToRpy(target_world.rotation))} rad) in world")
    if result.success and result.coordinates is not None:
        theta = result.coordinates
        return Reach(arm, state.with_arm(arm, float(theta[0]), theta[1:]))
    if result.status is IKStatus.COLLISION:
        return Reach(arm, None, "collision",
                     f"{where}: every arm configuration found hits the scene or the robot's base")
    if result.status is IKStatus.UNREACHABLE:
        return Reach(arm, None, "unreachable",
                     f"{where}: farther from the shoulder than the arm's length")
    if not diagnose:
        return Reach(arm, None, "unreachable",
                     f"{where}: no arm configuration found (IK: {result.status.value})")
    loose = kin.free_solvers[arm].solve(
        target, initial=state.coordinates(arm), fixed=fixed, time_budget_s=_IK_TIME_CAP_S,
        diagnose=False, max_restarts=IK_DIAGNOSE_RESTARTS,
        rng=np.random.default_rng(int(rng.integers(2**63))),
    )
    if loose.success:
        return Reach(arm, None, "joint_limits",
                     f"{where}: reachable only outside the joint limits")
    return Reach(arm, None, "unreachable",
                 f"{where}: no arm configuration found (IK: {result.status.value})")


def reach_either(
    world: KinematicWorld,
    state: RobotState,
    arms: Sequence[Arm],
    target_world: pin.SE3,
    scene: Scene,
    rng: np.random.Generator,
    **options: Any,
) -> Reach:
    """:func:`reach` with each of ``arms`` in turn; the first success, else the first
    arm's failure."""
    first: Reach | None = None
    for arm in arms:
        answer = reach(world, state, arm, target_world, scene, rng, **options)
        if answer.ok:
            return answer
        first = first or answer
    if first is None:
        raise ValueError("reach_either needs at least one arm")
    return first


def arms_for(state: RobotState, position_world: Sequence[float]) -> tuple[Arm, Arm]:
    """Both arms, the one on the target's side of the robot first."""
    x, y, yaw = state.base_pose_world
    lateral = -math.sin(yaw) * (position_world[0] - x) + math.cos(yaw) * (position_world[1] - y)
    return ("left", "right") if lateral >= 0.0 else ("right", "left")


def free_arms(state: RobotState, position_world: Sequence[float]) -> tuple[Arm, ...]:
    """The arms that may move to ``position_world`` when the gripper is empty: the arm in
    use first, else the target's side first."""
    if state.arm_in_use is not None:
        other: Arm = "right" if state.arm_in_use == "left" else "left"
        return (state.arm_in_use, other)
    return arms_for(state, position_world)


def _fmt(values: Sequence[float] | FloatArray) -> str:
    return "(" + ", ".join(f"{float(v):.3f}" for v in values) + ")"


fmt = _fmt
"""``(1.000, 2.000)``: a vector for a failure detail."""
