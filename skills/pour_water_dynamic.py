"""Pour-water skills on the ``"dynamic"`` backend: the PR2 pours real (simulated) water.

The twins of :mod:`skillcompose.skills.kinematic`'s pour-water skills, made by
:func:`~skillcompose.skills.dynamic_world.dynamic_twin`: each plans with its kinematic twin
(IK, joint limits, the table), then the arm follows the planned joints as a trajectory under
control in MuJoCo (:mod:`skillcompose.robots.physics`), and the blackboard is written again
from the simulation. Same names, parameters and outcomes as the ``"sim"`` and
``"kinematic"`` skills, so the pour-water FSAs run unchanged::

    skillcompose run examples/pour_water_reference.fsa.yaml --task examples.pour_water \\
        --set backend=dynamic

The world (:data:`SCENE`). The jug and the glass are open-top cups on the table
(``DEFAULT_TABLE_WORLD``, top at 0.75 m; the jug on a stand), placed from the abstract
world's keys:

- the **jug** (:data:`JUG`: 7 x 7 x 7.6 cm, 0.15 kg, walls flared 0.1 rad so that a jug
  tipped 90° empties, as a real jug does) is held with the tool frame at its grasp point,
  1.2 cm under its rim (a side grasp, fingers horizontal): the point the abstract skills
  call the spout, ``jug_position_world``. It stands on a block (:data:`STAND`, 13.6 cm) so
  that this point is 20 cm above the table, as the abstract world has it, while a jug
  carried 8 cm above the glass's rim (as the reference FSA carries it) clears the glass;
- the **glass** (:data:`GLASS`: 9 x 9 x 12 cm, 0.2 kg) stands with its rim's centre at
  ``glass_position_world``;
- the **water** is :data:`N_PARTICLES` particles that start in the jug (drag 0.05 N s/m:
  with the model's default 0.01 the stream left the tipped jug fast enough to fly over the
  glass).

The arm moves through waypoints where a straight joint path would fail (:func:`_approach`,
:func:`_carry`, :func:`_turn`): a tucked arm unfolds shoulder first, a held jug travels up,
across and down clear of the glass, a rotation turns the jug about its grasp point.

Outcomes and how physics judges them (``last_failure_reason`` says why a twin failed; what
physics produces, a jug knocked over, a slip, spilled water, is an outcome, never an error):

- every moving twin: ``failure`` when its kinematic plan fails (the kinematic reasons, and
  nothing moves), or when the executed motion went wrong
  (:func:`~skillcompose.skills.dynamic_world.judge_motion`: ``blocked``, ``missed``,
  ``dropped``, ``hit_table``); RotateGripperToParam has only ``success``, and records the
  reason;
- after each twin the blackboard is written from the simulation: the robot, whether a
  gripper holds the jug by contact (``holding_jug``), the jug's grasp point
  (``jug_position_world``, from the jug's simulated pose), the glass's rim
  (``glass_position_world``) and ``water`` from where the particles are
  (:func:`water_state`): ``"glass"`` when at least :data:`POURED_FRACTION` (80 %) of them are
  in the glass, ``"jug"`` while most are in the jug, else ``"spilled"``;
- **CheckSuccess** looks into the simulated glass: ``success`` when at least 80 % of the
  particles are in it (*poured*), else ``failure``.

A twin waits, after its motion, until the water has come to rest (at most
:data:`WATER_SETTLE_S`), so that ``water`` is not read while particles fly.

Determinism: the plans draw from the run's generator; the simulation reads no clock and no
global random state, so the same seed gives the same episode.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np
import pinocchio as pin

from skillcompose import Blackboard, Registry, Skill
from skillcompose.robots.model import ARMS, Arm
from skillcompose.robots.physics import PhysicsWorld
from skillcompose.robots.physics_model import ObjectSpec, SceneSpec
from skillcompose.skills import kinematic
from skillcompose.skills.dynamic_world import (
    BACKEND,
    DynamicSkill,
    DynamicWorld,
    Via,
    dynamic_twin,
    in_dynamic_world,
)
from skillcompose.skills.kinematic_world import (
    DEFAULT_TABLE_WORLD,
    HELD_KEYS,
    RobotState,
    kinematic_skill,
    reach,
    scene_world,
    transform_robot_to_world,
)
from skillcompose.skills.pour_geometry import (
    GLASS_HALF_EXTENTS_M,
    JUG_GRASP_ABOVE_CENTRE_M,
    JUG_HALF_EXTENTS_M,
)

__all__ = [
    "BACKEND",
    "GLASS",
    "JUG",
    "JUG_GRASP_ABOVE_CENTRE_M",
    "N_PARTICLES",
    "POURED_FRACTION",
    "SCENE",
    "SKILLS",
    "STAND",
    "WATER_SETTLE_S",
    "check_success",
    "grasp_object",
    "move_gripper_to_param",
    "move_to_object",
    "object_poses",
    "recognise_object",
    "register",
    "rotate_gripper_to_param",
    "settle_water",
    "start_episode",
    "water_state",
]

JUG = ObjectSpec("jug", "cup", JUG_HALF_EXTENTS_M, 0.15, friction=1.0, flare_rad=0.1,
                 rgba=(0.85, 0.45, 0.2, 1.0))
"""The jug: an open-top cup of 7 x 7 x 7.6 cm outside [m], 0.15 kg."""
GLASS = ObjectSpec("glass", "cup", GLASS_HALF_EXTENTS_M, 0.2, friction=1.0,
                   rgba=(0.7, 0.9, 1.0, 0.5))
"""The glass: an open-top cup of 9 x 9 x 12 cm outside [m], 0.2 kg; its mouth (7.8 cm
inside) is about the abstract skills' pouring radius (4 cm) across."""
STAND = ObjectSpec("stand", "box", (0.05, 0.05, 0.068), 1.5, friction=1.0,
                   rgba=(0.45, 0.45, 0.5, 1.0))
"""The block the jug stands on (10 x 10 x 13.6 cm, 1.5 kg), so that its grasp point is
20 cm above the table as ``jug_position_world`` says."""
N_PARTICLES = 30
"""Water particles (7 mm radius, 2 g each: 80 g of water)."""
SCENE = SceneSpec(objects=(JUG, GLASS, STAND), n_particles=N_PARTICLES, particle_drag_ns_per_m=0.05)
"""The pour-water scene: the default table, the jug on its stand, the glass and the water."""
POURED_FRACTION = 0.8
"""The water counts as poured when at least this share of the particles is in the glass."""
WATER_SETTLE_S = 3.0
"""A twin waits at most this long [s] after its motion for the particles to come to rest."""
_TABLE_TOP_M = DEFAULT_TABLE_WORLD.center_m[2] + DEFAULT_TABLE_WORLD.half_extents_m[2]
_CLEARANCE_M = 0.05  # a tool this close above the table top comes from below it [m]
_FRONT_M = 0.35  # the rise before an approach: this far ahead of the base [m]
_JUG_HANG_M = JUG_GRASP_ABOVE_CENTRE_M + JUG.size_m[2]  # grasp point to the jug's bottom [m]
_CARRY_CLEARANCE_M = 0.03  # a carried jug's bottom passes this far above the glass [m]
_TURN_STEP_RAD = math.radians(30.0)
_RESTING_M_S = 0.03  # particles slower than this are at rest [m/s]
_SETTLE_STEP_S = 0.1

_WORLD_WRITES = ("jug_position_world", "glass_position_world", "holding_jug", "water")
"""The world keys the twins write from the simulation (beyond their kinematic twins')."""


# -- the world ---------------------------------------------------------------------------------
def object_poses(jug_position_world: Sequence[float], glass_position_world: Sequence[float]
                 ) -> dict[str, tuple[float, float, float]]:
    """The centres [m] of the jug and the glass (upright) whose grasp point and rim centre
    are the abstract world's ``jug_position_world`` and ``glass_position_world``."""
    jx, jy, jz = (float(v) for v in jug_position_world[:3])
    gx, gy, gz = (float(v) for v in glass_position_world[:3])
    jug_z = jz - JUG_GRASP_ABOVE_CENTRE_M
    stand_z = jug_z - JUG.size_m[2] - STAND.size_m[2]
    return {"jug": (jx, jy, jug_z), "glass": (gx, gy, gz - GLASS.size_m[2]),
            "stand": (jx, jy, stand_z)}


def start_episode(world: DynamicWorld, bb: Blackboard) -> PhysicsWorld:
    """Start ``bb``'s physics episode (:meth:`DynamicWorld.start`): the robot as ``bb`` says,
    the jug and the glass where its keys put them, the water in the jug."""
    return world.start(bb, SCENE, object_poses=object_poses(bb["jug_position_world"],
                                                            bb["glass_position_world"]),
                       particles_in="jug")


def water_state(physics: PhysicsWorld) -> Literal["glass", "jug", "spilled"]:
    """Where the water is, from the particles: ``"glass"`` when at least
    :data:`POURED_FRACTION` of them are in the glass, ``"jug"`` while more than half are in
    the jug, else ``"spilled"``."""
    total = len(physics.physics.particle_body)
    if physics.particles_in("glass") >= POURED_FRACTION * total:
        return "glass"
    if 2 * physics.particles_in("jug") > total:
        return "jug"
    return "spilled"


def _grasp_point(physics: PhysicsWorld) -> tuple[float, float, float]:
    placement = physics.object_transform("jug")
    point = placement.act(np.array([0.0, 0.0, JUG_GRASP_ABOVE_CENTRE_M]))
    return (float(point[0]), float(point[1]), float(point[2]))


def _rim(physics: PhysicsWorld) -> tuple[float, float, float]:
    placement = physics.object_transform("glass")
    point = placement.act(np.array([0.0, 0.0, GLASS.size_m[2]]))
    return (float(point[0]), float(point[1]), float(point[2]))


def _world_keys(physics: PhysicsWorld, bb: Blackboard) -> Mapping[str, Any]:
    """The abstract world's keys from the simulation (see the module docstring)."""
    holding = any(bb.get(HELD_KEYS[arm]) == "jug" for arm in ARMS)
    return {"jug_position_world": _grasp_point(physics), "glass_position_world": _rim(physics),
            "holding_jug": holding, "water": water_state(physics)}


def _particles_moving(physics: PhysicsWorld) -> bool:
    model, data = physics.model, physics.data
    bodies = physics.physics.particle_body
    if not bodies:
        return False
    speeds = [float(np.linalg.norm(data.qvel[model.jnt_dofadr[model.body_jntadr[b]]:
                                             model.jnt_dofadr[model.body_jntadr[b]] + 3]))
              for b in bodies]
    return max(speeds) > _RESTING_M_S


def settle_water(physics: PhysicsWorld, max_s: float = WATER_SETTLE_S) -> float:
    """Let time pass until the particles rest (or ``max_s`` [s]); the time waited [s]."""
    waited = 0.0
    while waited < max_s - 1e-9 and _particles_moving(physics):
        physics.step(_SETTLE_STEP_S)
        waited += _SETTLE_STEP_S
    return waited


def _settled(physics: PhysicsWorld, bb: Blackboard, rng: np.random.Generator,
             params: Mapping[str, Any]) -> str | None:
    """Every twin's judge: wait for the water, then write the world keys again."""
    waited = settle_water(physics)
    if waited > 0.0:
        for key, value in _world_keys(physics, bb).items():
            if key in bb:
                bb[key] = value
    return None


# -- the paths the arm takes ----------------------------------------------------------------
def _moving_arm(before: RobotState, planned: RobotState) -> Arm | None:
    for arm in ARMS:
        if any(abs(a - b) > 1e-4 for a, b in zip(before.q_arm_rad[arm], planned.q_arm_rad[arm],
                                                 strict=True)):
            return arm
    return None


def _tool(world: DynamicWorld, state: RobotState, arm: Arm) -> pin.SE3:
    robot_to_world = transform_robot_to_world(state.base_pose_world)
    return robot_to_world * world.kinematic.transform_tool_to_robot(
        arm, state.torso_height_m, state.q_arm_rad[arm])


def _waypoints(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator,
               start: RobotState, arm: Arm, poses: Sequence[pin.SE3]) -> list[RobotState]:
    """IK of each tool pose in turn, each from the last; a pose IK cannot reach is left out."""
    states: list[RobotState] = []
    at = start
    for pose in poses:
        answer = reach(world.kinematic, at, arm, pose, scene_world(bb), rng, restarts=2,
                       diagnose=False)
        if answer.state is not None:
            at = RobotState(answer.state.base_pose_world, answer.state.torso_height_m,
                            answer.state.q_arm_rad, start.held, start.arm_in_use)
            states.append(at)
    return states


def _approach(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator,
              before: RobotState, planned: RobotState) -> Sequence[RobotState]:
    """An arm that starts below the table top (tucked) unfolds joint by joint, shoulder pan
    first, then shoulder lift, then the rest: a straight joint path swings the elbow
    forward under the table's edge."""
    arm = _moving_arm(before, planned)
    if arm is None or _tool(world, before, arm).translation[2] > _TABLE_TOP_M + _CLEARANCE_M:
        return ()
    q = list(before.q_arm_rad[arm])
    goal = planned.q_arm_rad[arm]
    states = []
    for joint in (0, 1):
        q[joint] = goal[joint]
        states.append(before.with_arm(arm, planned.torso_height_m, q))
    return states


def _carry(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator,
           before: RobotState, planned: RobotState) -> Sequence[RobotState]:
    """A held jug travels high enough to clear the glass and the stand: up, across, down."""
    arm = _moving_arm(before, planned)
    if arm is None or before.held[arm] != "jug":
        return ()
    start, goal = _tool(world, before, arm), _tool(world, planned, arm)
    rim = bb.get("glass_position_world")
    over = -math.inf if rim is None else float(rim[2]) + _JUG_HANG_M + _CARRY_CLEARANCE_M
    travel = max(float(start.translation[2]), float(goal.translation[2]), over)
    poses = []
    if travel > start.translation[2] + 0.01:
        poses.append(pin.SE3(start.rotation, np.array([*start.translation[:2], travel])))
    if travel > goal.translation[2] + 0.01:
        poses.append(pin.SE3(goal.rotation, np.array([*goal.translation[:2], travel])))
    return _waypoints(world, bb, rng, before, arm, poses)


def _turn(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator,
          before: RobotState, planned: RobotState) -> Sequence[RobotState]:
    """A rotation in place passes through intermediate rotations (every 30°) at the same
    tool point, so that the jug turns about its grasp point rather than swinging."""
    arm = _moving_arm(before, planned)
    if arm is None:
        return ()
    start, goal = _tool(world, before, arm), _tool(world, planned, arm)
    angle = float(np.linalg.norm(pin.log3(start.rotation.T @ goal.rotation)))
    steps = int(angle // _TURN_STEP_RAD)
    if steps < 1:
        return ()
    turn = pin.log3(start.rotation.T @ goal.rotation)
    poses = [pin.SE3(start.rotation @ pin.exp3(turn * (k / (steps + 1))), start.translation)
             for k in range(1, steps + 1)]
    return _waypoints(world, bb, rng, before, arm, poses)


# -- the skills --------------------------------------------------------------------------------
def _twin(skill: Skill, via: Via | None = None) -> DynamicSkill:
    assert isinstance(skill, kinematic.KinematicSkill)
    return dynamic_twin(skill, world_keys=_world_keys, judge=_settled, writes=_WORLD_WRITES,
                        via=via)


recognise_object = kinematic.recognise_object.with_backend(BACKEND)
"""RecogniseObject, shared perception: it reads ``jug_position_world`` and
``glass_position_world``, which the dynamic twins keep as simulated. Always ``success``."""
move_to_object = _twin(kinematic.move_to_object, _approach)
grasp_object = _twin(kinematic.grasp_object)
move_gripper_to_param = _twin(kinematic.move_gripper_to_param, _carry)
rotate_gripper_to_param = _twin(kinematic.rotate_gripper_to_param, _turn)


def _check_success(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator
                   ) -> Literal["success", "failure"]:
    """Look into the simulated glass (after the water has come to rest): ``success`` when at
    least 80 % of the particles are in it, ``failure`` otherwise; writes ``water``."""
    physics = world.current(bb, "CheckSuccess")
    settle_water(physics)
    bb["water"] = water_state(physics)
    return "success" if bb["water"] == "glass" else "failure"


check_success = DynamicSkill(
    kinematic_skill(name="CheckSuccess", reads=("water",), writes=("water",))(
        _check_success).spec,
    _check_success)

SKILLS: tuple[Skill, ...] = (
    recognise_object,
    move_to_object,
    grasp_object,
    move_gripper_to_param,
    rotate_gripper_to_param,
    check_success,
)
"""The six pour-water skills on the dynamic backend, in the paper's order."""


def register(registry: Registry, *, world: DynamicWorld | None = None) -> DynamicWorld:
    """Add the six dynamic pour-water skills to ``registry``, running in ``world`` (default:
    a new :class:`DynamicWorld`); return it. A task's setup starts each episode in it
    (:func:`start_episode`)."""
    world = world or DynamicWorld()
    for s in in_dynamic_world(SKILLS, world):
        registry.add(s)
    return world
