"""Stacking (section 4.3) on the ``dynamic`` backend: the PR2 in MuJoCo.

The twins of the kinematic GraspParam, MoveGripperToStack and OpenGripper
(:mod:`skillcompose.skills.kinematic`), of CheckSuccess and of MoveToReach, with their
names, parameters, outcomes and blackboard keys; RecogniseObject is the shared one of
:mod:`skillcompose.skills.stacking`. They run in a
:class:`~skillcompose.skills.dynamic_world.DynamicWorld` whose episode the task's setup
starts (:func:`start_episode`: the table of ``table_world`` and both objects, boxes of
``object_half_extents_m``, :data:`OBJECT_MASS_KG` each with friction
:data:`OBJECT_FRICTION`, standing upright at ``object_positions_world``). Each plan is the
kinematic twin's; the motion is physics' (:func:`~skillcompose.skills.dynamic_world.dynamic_twin`),
and the blackboard's object positions are written from the simulation after every skill.

- ``GraspParam(which)``: tucked arms first unfold (the torso raised, and lowered again
  only when the unfolded arms then clear the simulated table; an arm whose unfolding
  would sweep the table or an object unfolds wrist first, or panned out,
  :func:`~skillcompose.skills.stacking_transits.unfold_route`), so that the IK starts
  there; the kinematic twin plans the grasp (side, else top; a top plan is retried from
  the side, :func:`_grasp_plan`); the arm
  passes a pre-grasp pose :data:`PRE_GRASP_M` back along the approach (and one above
  that), reached clear of both objects, so the open fingers come straight onto the object
  (a straight tool line solved backwards from the plan,
  :func:`~skillcompose.skills.dynamic_world.cartesian_path`, each step clear of the
  simulated table and the other object; when the plan's configuration has no such line,
  another configuration of the same grasp pose that has one replaces it,
  :func:`_regrasp`, else the grasp turned about the object's axis, :func:`_turned`), then
  the fingers close and hold it by friction. A motion on the way whose line would touch
  the table or the other object goes over it with the shoulder lifted, else with the
  torso raised (:mod:`~skillcompose.skills.stacking_transits`; also for
  MoveGripperToStack). ``failure``: the kinematic reasons, ``missed`` (the fingers
  closed on nothing or on the other object), ``blocked`` (a motion did not reach its
  goal), ``hit_table``; a failed grasp opens the fingers and backs out along its approach
  (:func:`_back_out`) before the retry plans.
- ``MoveGripperToStack(which, dx, dy, dz)``: the kinematic plan (when it finds no arm
  configuration, the goal with the gripper turned about the vertical,
  :func:`_stack_plan`), reached by lifting the
  gripper straight up by :data:`LIFT_M` or until the held object clears the other's top
  (:func:`_lift_m`), then to :data:`LIFT_M` above the goal, then down; the held object is
  checked against the other object on the way. ``failure``: the kinematic reasons,
  ``dropped`` (the held object left the fingers), ``blocked``, ``hit_table``.
- ``OpenGripper``: the fingers open; the released object falls and settles for
  :data:`REST_S` (2 s) before the blackboard is written. Always ``success``.
- ``CheckSuccess``: **stacked** (``success``) when neither object is held and one rests on
  the other as simulated, 2 s after the release: both upright (z axes within 20° of
  vertical), the top one's bottom within 1 cm of the other's top and its centre over the
  other's top face (:func:`skillcompose.skills.stacking.stacked` on the simulated poses);
  else ``failure``.
- ``MoveToReach``: the nested move-to-push FSA of :mod:`skillcompose.skills.stacking` on the
  dynamic MoveBase (:mod:`skillcompose.skills.move_to_push_dynamic`: the base drives, a held
  object rides in the gripper) and its Push check by IK (moving nothing).

What physics produces (a slip, a topple, a collision with the table) ends as an outcome with
``last_failure_reason``, never as an error; the same seed gives the same episode.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pinocchio as pin

from skillcompose import Blackboard, Registry
from skillcompose.robots.collision import Scene
from skillcompose.robots.model import ARMS, Arm
from skillcompose.robots.physics import PhysicsWorld
from skillcompose.robots.physics_model import ObjectSpec, SceneSpec
from skillcompose.skills import kinematic as skills_kinematic
from skillcompose.skills import stacking as skills_stacking
from skillcompose.skills import stacking_kinematic
from skillcompose.skills.dynamic_world import (
    DynamicSkill,
    DynamicWorld,
    arm_touches_table,
    cartesian_path,
    dynamic_twin,
    follow_path,
    in_dynamic_world,
    sync,
    tool_world,
)
from skillcompose.skills.kinematic_world import (
    GRASP_KEY,
    TABLE_KEY,
    TOOL_KEYS,
    KinematicSkill,
    KinematicWorld,
    RobotState,
    arms_for,
    commit,
    grasp_pose_world,
    object_box,
    object_position,
    reach,
    read_state,
    scene_world,
    stack_object_name,
)
from skillcompose.skills.move_to_push_dynamic import (
    UNFOLD_TORSO_M,
    base_route,
    make_move_base,
    object_keys,
    unfolded,
)
from skillcompose.skills.network import Topology
from skillcompose.skills.stacking_transits import (
    CONTINUOUS,
    clear_transits,
    hop,
    line_touches_table,
    over,
    touches,
    unfold_route,
    with_arm,
    wrap,
)
from skillcompose.skills.stacking_world import DEFAULT_HALF_EXTENTS_M, held, stacked

__all__ = [
    "BACK_OUT_M",
    "LIFT_M",
    "OBJECT_FRICTION",
    "OBJECT_MASS_KG",
    "PRE_GRASP_M",
    "REST_S",
    "check_success",
    "clear_transits",
    "grasp_param",
    "line_touches_table",
    "move_gripper_to_stack",
    "open_gripper",
    "register",
    "scene_of",
    "start_episode",
]

OBJECT_MASS_KG = 0.2
"""Each stacking object's mass [kg]."""
OBJECT_FRICTION = 0.5
"""Each stacking object's sliding friction (on the table and on each other; the finger pads
have their own, 1.5)."""
PRE_GRASP_M = 0.09
"""A grasp passes a pose this far back along the approach (the tool's x axis) [m]."""
LIFT_M = 0.10
"""MoveGripperToStack lifts the gripper this far before it moves, and comes down this far
onto its goal [m]."""
CLEAR_M = 0.03
"""A held object is lifted until its bottom is this far above the other objects' tops [m]
before it is carried across (:func:`_lift_m`)."""
LIFT_STEP_M = 0.05
"""The lift's straight line is passed through a waypoint about this often [m]."""
NEAR_RAD = 0.8
"""A waypoint is this close to the next in every joint [rad], at most."""
REST_S = 2.0
"""Simulated time a released object is given to come to rest [s]."""
REGRASP_TRIES = 8
"""GraspParam: when no straight approach line ends in the kinematic plan's configuration,
this many other IK solutions of the pre-grasp pose are tried as its start (:func:`_regrasp`)."""
BACK_OUT_M = PRE_GRASP_M
"""A failed grasp opens the fingers and backs the gripper out this far along its approach
[m] (:func:`_back_out`) ..."""
BACK_OUT_MIN_M = 0.02
"""... or as far as its straight line goes, when that is at least this far [m] ..."""
BACK_OUT_SPEED_M_S = 0.1
"""... at this tool speed [m/s]."""
TURN_RAD = tuple(sign * k * 0.25 for k in (1, 2, 3, 4) for sign in (1, -1))
"""GraspParam: when neither the plan's nor another configuration of its grasp pose has a
clear straight approach, the grasp is turned about the object's vertical axis by these
angles [rad], the first with one replacing the plan (:func:`_turned`)."""
SIDE_RETRIES = 2
"""GraspParam: when the kinematic plan grasps from above, its preferred side grasp is tried
this many times more (:func:`_grasp_plan`)."""


# -- the episode -------------------------------------------------------------------------------
def scene_of(bb: Blackboard) -> SceneSpec:
    """The physics scene of a stacking blackboard: its ``table_world`` and both objects."""
    sizes: Mapping[str, Sequence[float]] = bb.get("object_half_extents_m") or {}
    objects = tuple(
        ObjectSpec(str(name), "box",
                   tuple(float(v) for v in sizes.get(name, DEFAULT_HALF_EXTENTS_M)),
                   OBJECT_MASS_KG, OBJECT_FRICTION,
                   rgba=(0.8, 0.4, 0.2, 1.0) if k == 0 else (0.2, 0.5, 0.8, 1.0))
        for k, name in enumerate(bb["object_positions_world"]))
    return SceneSpec(table=bb.get(TABLE_KEY), objects=objects)


def start_episode(world: DynamicWorld, bb: Blackboard) -> PhysicsWorld:
    """Start ``bb``'s physics episode in ``world``: the robot as ``bb`` says, both objects
    upright at ``object_positions_world``."""
    poses = {str(n): tuple(float(v) for v in p) for n, p in bb["object_positions_world"].items()}
    return world.start(bb, scene_of(bb), object_poses=poses)


# -- waypoints ---------------------------------------------------------------------------------
def _tool(bb: Blackboard, arm: str) -> pin.SE3:
    x, y, z, roll, pitch, yaw = bb[TOOL_KEYS[arm]]  # type: ignore[index]
    return pin.SE3(np.asarray(pin.rpy.rpyToMatrix(roll, pitch, yaw)), np.array([x, y, z]))


def _moved_arm(before: RobotState, planned: RobotState) -> Arm | None:
    for arm in ARMS:
        if planned.q_arm_rad[arm] != before.q_arm_rad[arm]:
            return arm
    return None


def _near(world: DynamicWorld, state: RobotState, arm: str, target: pin.SE3, bb: Blackboard,
          rng: np.random.Generator) -> RobotState | None:
    """IK of ``arm`` to ``target`` warm-started from ``state`` without restarts, torso
    fixed, and within :data:`NEAR_RAD` of it in every joint (so that the servo's straight
    line in joint space stays near the tool's); None when there is none."""
    answer = reach(world.kinematic, state, arm, target, scene_world(bb), rng,  # type: ignore[arg-type]
                   move_torso=False, diagnose=False, restarts=0)
    if answer.state is None or max(
            abs(a - b) for a, b in zip(answer.state.q_arm_rad[arm], state.q_arm_rad[arm],  # type: ignore[index]
                                       strict=True)) > NEAR_RAD:
        return None
    return RobotState(answer.state.base_pose_world, answer.state.torso_height_m,
                      answer.state.q_arm_rad, state.held, state.arm_in_use)


def _others(bb: Blackboard, target: str | None) -> tuple[str, ...]:
    """The stacking objects other than ``target`` and those held: what an arm must not
    touch on the way."""
    state = read_state(bb)
    held_now = {state.held[a] for a in ARMS}
    return tuple(str(n) for n in bb.get("object_positions_world") or {}
                 if n != target and n not in held_now)


def _avoid_scene(bb: Blackboard, objects: Sequence[str]) -> Scene:
    positions = bb.get("object_positions_world") or {}
    return scene_world(bb, [object_box(bb, n, positions[n]) for n in objects])


def _grasp_via(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator,
               before: RobotState, planned: RobotState) -> Sequence[RobotState]:
    """GraspParam's waypoints: :data:`PRE_GRASP_M` back along the approach, and
    :data:`LIFT_M` above that, each near the next in joint space, reached clear of the
    table and of both objects (a joint-space sweep to the pre-grasp knocked the target
    over); the approach's straight line clear of the table and of the other object. When
    no such line ends in the plan's configuration, or its start cannot be reached from the
    arm as it is without touching the table or an object (not even round them,
    :mod:`~skillcompose.skills.stacking_transits`), another configuration of the same
    grasp pose that has one (:func:`_regrasp`), else the grasp turned about the object's
    axis (:func:`_turned`), replaces the plan on the blackboard."""
    arm = _moved_arm(before, planned)
    if arm is None:
        return ()
    grasp = _tool(bb, arm)
    avoid = _others(bb, bb.get("grasp_target"))
    back = grasp.translation - PRE_GRASP_M * grasp.rotation[:, 0]
    pre_pose = pin.SE3(grasp.rotation, back)
    keep = RobotState(planned.base_pose_world, planned.torso_height_m, planned.q_arm_rad,
                      before.held, planned.arm_in_use)
    target = bb.get("grasp_target")
    near = (*avoid, *([str(target)] if target else []))
    physics = world.physics

    def reachable(first: RobotState) -> bool:  # from the arm as it is, clear or around
        return physics is None or not line_touches_table(
            physics, before, first, arm, objects=near) or bool(
            over(physics, arm, before, first, near) or hop(physics, arm, before, first, near))

    line = _straight_back(world, bb, rng, keep, arm, pre_pose, avoid)
    if not line or not reachable(line[0]):
        found = _regrasp(world, bb, rng, keep, arm, grasp, pre_pose, avoid, reachable) or \
            _turned(world, bb, rng, keep, arm, grasp, avoid, reachable)
        if found is not None:
            keep, line = found
            commit(world.kinematic, bb, dataclasses.replace(keep, held=planned.held))
            grasp = tool_world(world, keep, arm)
            back = grasp.translation - PRE_GRASP_M * grasp.rotation[:, 0]
            pre_pose = pin.SE3(grasp.rotation, back)
    pre = line[0] if line else _near(world, keep, arm, pre_pose, bb, rng)
    if pre is None:
        return _transit(world, arm, before, (), keep, avoid)
    up = np.array([0.0, 0.0, LIFT_M])
    high = _near(world, pre, arm, pin.SE3(grasp.rotation, back + up), bb, rng)
    first = [*([high] if high is not None else []), pre]
    if physics is None:
        return [*first, *line[1:]]
    reached = clear_transits(physics, arm, before, first, objects=near)
    return [*reached, *_transit(world, arm, pre, line[1:], keep, avoid)]


def _transit(world: DynamicWorld, arm: Arm, before: RobotState, via: Sequence[RobotState],
             planned: RobotState, objects: Sequence[str] = ()) -> Sequence[RobotState]:
    """``via`` with the clear transits
    (:func:`~skillcompose.skills.stacking_transits.clear_transits`) on the way from
    ``before`` to ``planned``, the plan itself left out."""
    if world.physics is None:
        return via
    keep = RobotState(planned.base_pose_world, planned.torso_height_m, planned.q_arm_rad,
                      before.held, planned.arm_in_use)
    return clear_transits(world.physics, arm, before, [*via, keep], objects=objects,
                          carried=before.held[arm])[:-1]


def _straight_back(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator,
                   planned: RobotState, arm: Arm, pre: pin.SE3,
                   objects: Sequence[str] = ()) -> list[RobotState]:
    """The robots on the straight line from the pre-grasp pose ``pre`` to the planned grasp,
    the plan's own configuration excluded (solved backwards from it, so that the line ends
    in it), each clear of the simulated table and ``objects``
    (:func:`~skillcompose.skills.dynamic_world.arm_touches_table`); empty when the whole
    line has no such solutions."""
    physics = world.physics
    if physics is None:
        return []
    path = cartesian_path(world, planned, arm, pre, _avoid_scene(bb, objects), rng,
                          clear=lambda s: not touches(physics, s, arm, objects))
    if not path or path[-1][1] < PRE_GRASP_M - 1e-6:
        return []
    return [s for s, _ in reversed(path)]


def _regrasp(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator,
             planned: RobotState, arm: Arm, grasp: pin.SE3, pre: pin.SE3,
             objects: Sequence[str] = (), reachable: Callable[[RobotState], bool] | None = None,
             ) -> tuple[RobotState, list[RobotState]] | None:
    """Another configuration of ``planned``'s arm for the grasp pose ``grasp`` (torso and
    base kept), reached on a straight line from the pre-grasp pose ``pre``: IK of ``pre``
    warm-started from :data:`REGRASP_TRIES` random arms (the run's generator), each followed
    by the straight line onto ``grasp``, every step clear of the simulated table and
    ``objects``, and its start ``reachable`` (when given) from the arm as it is;
    ``(grasp configuration, the line's robots before it)``, or None."""
    physics = world.physics
    if physics is None:
        return None
    scene = _avoid_scene(bb, objects)
    chain = world.kinematic.chains[arm]

    def clear(s: RobotState) -> bool:
        return not touches(physics, s, arm, objects)

    for _ in range(REGRASP_TRIES):
        start = with_arm(planned, arm, [float(v) for v in chain.sample_coordinates(rng)[1:]])
        answer = reach(world.kinematic, start, arm, pre, scene, rng, move_torso=False,
                       diagnose=False, restarts=0)
        if answer.state is None:
            continue
        first = RobotState(planned.base_pose_world, planned.torso_height_m,
                           answer.state.q_arm_rad, planned.held, planned.arm_in_use)
        if not clear(first) or (reachable is not None and not reachable(first)):
            continue
        path = cartesian_path(world, first, arm, grasp, scene, rng, clear=clear)
        if not path or path[-1][1] < PRE_GRASP_M - 1e-6:
            continue
        return path[-1][0], [first, *(s for s, _ in path[:-1])]
    return None


def _turned(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator,
            planned: RobotState, arm: Arm, grasp: pin.SE3, objects: Sequence[str] = (),
            reachable: Callable[[RobotState], bool] | None = None,
            ) -> tuple[RobotState, list[RobotState]] | None:
    """The grasp turned about the vertical through its tool point (the object's axis) by
    each of :data:`TURN_RAD` in turn (a side grasp then comes from another bearing, a top
    grasp closes across other faces): IK of the turned pose warm-started from ``planned``
    (torso and base kept), clear of the simulated table and ``objects``, whose straight
    line back to its own pre-grasp pose (:func:`_straight_back`) is clear too, from which
    the gripper can be lifted (:func:`_liftable`), and whose line's start is ``reachable``
    (when given); the first such ``(grasp configuration, the line's robots before it)``, or
    None. Where the
    planned bearing has no clear approach (the other object beside the line, a joint
    limit), the open fingers came down on the other object or struck the table."""
    physics = world.physics
    if physics is None:
        return None
    scene = _avoid_scene(bb, objects)
    for turn in TURN_RAD:
        rotation = pin.rpy.rpyToMatrix(0.0, 0.0, turn) @ grasp.rotation
        target = pin.SE3(rotation, grasp.translation)
        answer = reach(world.kinematic, planned, arm, target, scene, rng, move_torso=False,
                       diagnose=False)
        if answer.state is None:
            continue
        at = RobotState(planned.base_pose_world, planned.torso_height_m,
                        answer.state.q_arm_rad, planned.held, planned.arm_in_use)
        if touches(physics, at, arm, objects):
            continue
        pre = pin.SE3(rotation, grasp.translation - PRE_GRASP_M * rotation[:, 0])
        line = _straight_back(world, bb, rng, at, arm, pre, objects)
        if line and _liftable(world, rng, at, arm, target) and (
                reachable is None or reachable(line[0])):
            return at, line
    return None


def _liftable(world: DynamicWorld, rng: np.random.Generator, state: RobotState, arm: Arm,
              grasp: pin.SE3) -> bool:
    """Whether ``arm``'s tool at ``grasp`` in ``state`` goes straight up by :data:`LIFT_M`
    (:func:`~skillcompose.skills.dynamic_world.cartesian_path`; torso and base kept), as
    MoveGripperToStack first lifts it: a turned grasp near a joint limit could not, and the
    carry tore the object from the fingers."""
    up = pin.SE3(grasp.rotation, grasp.translation + np.array([0.0, 0.0, LIFT_M]))
    path = cartesian_path(world, state, arm, up, Scene(()), rng)
    return bool(path) and path[-1][1] >= LIFT_M - 1e-6


def _stack_via(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator,
               before: RobotState, planned: RobotState) -> Sequence[RobotState]:
    """MoveGripperToStack's waypoints: the gripper straight up from where it is, by
    :data:`LIFT_M` or more (:func:`_lift_m`: a held object's bottom then clears the other
    objects' tops), then :data:`LIFT_M` above the goal; the arm's motions clear of the
    table and the other objects."""
    arm = _moved_arm(before, planned)
    if arm is None:
        return ()
    goal = _tool(bb, arm)
    now = world.kinematic.transform_tool_to_robot(arm, before.torso_height_m,
                                                  before.q_arm_rad[arm])
    x, y, yaw = before.base_pose_world
    start = pin.SE3(np.asarray(pin.rpy.rpyToMatrix(0.0, 0.0, yaw)), np.array([x, y, 0.0])) * now
    keep = RobotState(planned.base_pose_world, planned.torso_height_m, planned.q_arm_rad,
                      before.held, planned.arm_in_use)
    up = np.array([0.0, 0.0, 1.0])
    above = _near(world, keep, arm, pin.SE3(goal.rotation, goal.translation + LIFT_M * up),
                  bb, rng)
    avoid = _others(bb, None)
    carried = before.held[arm]
    lift = _lift_m(world.physics, bb, carried)
    lifted = _lift_line(world, bb, rng, before, arm, lift, avoid)
    if not lifted:
        lift_from = RobotState(before.base_pose_world, planned.torso_height_m,
                               before.q_arm_rad, before.held, before.arm_in_use)
        for height in dict.fromkeys((lift, LIFT_M)):
            near = _near(world, lift_from, arm,
                         pin.SE3(start.rotation, start.translation + height * up), bb, rng)
            if near is not None:
                lifted = [near]
                break
    return _transit(world, arm, before, [*lifted, *([above] if above is not None else [])],
                    keep, avoid)


def _lift_line(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator,
               before: RobotState, arm: Arm, lift: float, objects: Sequence[str]
               ) -> list[RobotState]:
    """The gripper lifted straight up from where it is by ``lift`` [m] (torso and base
    kept; :func:`~skillcompose.skills.dynamic_world.cartesian_path`, clear of the table and
    of ``objects``, the held object with it): the robots every :data:`LIFT_STEP_M` or so on
    the way, the top last; empty when the line does not reach :data:`LIFT_M`."""
    physics = world.physics
    if physics is None:
        return []
    start = tool_world(world, before, arm)
    top = pin.SE3(start.rotation, start.translation + np.array([0.0, 0.0, lift]))
    carried = before.held[arm]
    path = cartesian_path(world, before, arm, top, Scene(()), rng,  # the table: by `clear`
                          clear=lambda s: not touches(physics, s, arm, objects, carried))
    if not path or path[-1][1] < LIFT_M - 1e-6:
        return []
    out: list[RobotState] = []
    done = 0.0
    for k, (state, distance) in enumerate(path):
        if distance - done >= LIFT_STEP_M - 1e-6 or k == len(path) - 1:
            out.append(state)
            done = distance
    return out


def _lift_m(physics: PhysicsWorld | None, bb: Blackboard, held_name: str | None) -> float:
    """How far MoveGripperToStack lifts the gripper first [m]: :data:`LIFT_M`, or more when
    the held object's bottom would not then be :data:`CLEAR_M` above every other object's
    top, as simulated (carried across at 10 cm, a 12 cm tall box swept the other off the
    table)."""
    sizes: Mapping[str, Sequence[float]] = bb.get("object_half_extents_m") or {}

    def half(name: str) -> float:
        return float(sizes.get(name, DEFAULT_HALF_EXTENTS_M)[2])

    names = [str(n) for n in bb.get("object_positions_world") or {}]
    if physics is None or held_name is None or held_name not in names:
        return LIFT_M
    bottom = physics.object_pose(held_name)[2] - half(held_name)
    tops = [physics.object_pose(n)[2] + half(n) for n in names if n != held_name]
    return max([LIFT_M, *(top + CLEAR_M - bottom for top in tops)])


def _unfold(physics: PhysicsWorld, bb: Blackboard, rng: np.random.Generator,
            params: Mapping[str, Any]) -> str | None:
    """Before GraspParam plans: the tucked arms unfold above the table, so that its IK
    starts there: the torso rises to :data:`UNFOLD_TORSO_M` first, the arms unfold, and the
    torso goes back down only when the unfolded arms would then stay clear of the simulated
    table (lowered onto it, the arms were pressed on the table by the torso's servo, which
    shoved the whole base away)."""
    state = read_state(bb)
    ready = unfolded(state, ARMS)
    if ready == state:
        return None
    moving = [arm for arm in ARMS if ready.q_arm_rad[arm] != state.q_arm_rad[arm]]
    torso = physics.torso_m()
    high = max(torso, UNFOLD_TORSO_M)
    if high > torso:
        physics.move_torso(high, max(0.5, (high - torso) / 0.1), settle_s=0.0)
    names = tuple(str(n) for n in bb.get("object_positions_world") or {})
    at = dataclasses.replace(state, torso_height_m=high)
    for arm in moving:
        goal = with_arm(at, arm, ready.q_arm_rad[arm])
        route = unfold_route(physics, arm, at, goal, names)
        for k, waypoint in enumerate(route):
            last = k == len(route) - 1
            q = waypoint.q_arm_rad[arm]
            change = max(abs(a - b) for a, b in zip(q, physics.arm_q(arm), strict=True))
            physics.track_arm(arm, q, 1.5 if last else max(0.5, change),
                              settle_s=0.1 if last else 0.0)
        at = goal
    if high > torso and not any(arm_touches_table(physics, ready, arm) for arm in ARMS):
        physics.move_torso(torso, max(0.5, (high - torso) / 0.1))
    sync(physics, bb, planned=state, world_keys=object_keys)
    return None


def _back_out(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator,
              before: RobotState, planned: RobotState) -> None:
    """After a failed grasp: the fingers open (closed on nothing, they stayed shut, and the
    retry pushed the object ahead with their tips), and the gripper backs out
    :data:`BACK_OUT_M` along the approach (the planned grasp's tool x axis) on a straight
    line (:func:`~skillcompose.skills.dynamic_world.cartesian_path`, clear of the simulated
    table and the other object), else as far as that line goes, else straight up by
    :data:`LIFT_M`; so the retry plans from clear of the object instead of nudging it on."""
    physics = world.physics
    arm = next((a for a in ARMS if planned.held[a] is not None and before.held[a] is None),
               None)
    if physics is None or arm is None:
        return
    physics.open_gripper(arm)
    now = read_state(bb)
    avoid = _others(bb, bb.get("grasp_target"))
    scene = _avoid_scene(bb, avoid)
    start = tool_world(world, now, arm)
    away = -np.asarray(tool_world(world, planned, arm).rotation[:, 0])
    for direction, distance in ((away, BACK_OUT_M), (np.array([0.0, 0.0, 1.0]), LIFT_M)):
        goal = pin.SE3(start.rotation, start.translation + distance * direction)
        path = cartesian_path(world, now, arm, goal, scene, rng,
                              clear=lambda s: not touches(physics, s, arm, avoid))
        if path and path[-1][1] >= BACK_OUT_MIN_M:
            follow_path(physics, arm, [s for s, _ in path], BACK_OUT_SPEED_M_S)
            return


# -- the skills --------------------------------------------------------------------------------
def _grasp_plan(world: KinematicWorld, bb: Blackboard, rng: np.random.Generator,
                **params: Any) -> str:
    """GraspParam's plan: the kinematic twin's; when it grasps from above, the side grasp
    it prefers is tried :data:`SIDE_RETRIES` times more (its IK restarts from random arms
    and now and then misses a side grasp that exists), the first found replacing the plan.
    Held from above, an object far from the base could not be carried over the other (the
    arm cannot reach as far from above; the kinematic twin grasped the same object from the
    side)."""
    before = read_state(bb)
    outcome = str(skills_kinematic.grasp_param.impl(world, bb, rng, **params))
    name = bb.get("grasp_target")
    if outcome != "success" or bb.get(GRASP_KEY) != "top" or name is None:
        return outcome
    position = object_position(bb, str(name))
    if position is None:
        return outcome
    pose = grasp_pose_world("side", before.base_pose_world, position)
    for _ in range(SIDE_RETRIES):
        for arm in arms_for(before, position):
            answer = reach(world, before, arm, pose, scene_world(bb), rng)
            if answer.state is not None:
                bb[GRASP_KEY] = "side"
                commit(world, bb, RobotState(answer.state.base_pose_world,
                                             answer.state.torso_height_m,
                                             answer.state.q_arm_rad,
                                             {**answer.state.held, arm: str(name)}, arm))
                return outcome
    return outcome


def _stack_plan(world: KinematicWorld, bb: Blackboard, rng: np.random.Generator,
                **params: Any) -> str:
    """MoveGripperToStack's plan: the kinematic twin's; when that finds no arm configuration
    for the goal (``unreachable``, ``joint_limits``), the same goal with the holding gripper
    turned about the vertical by each of :data:`TURN_RAD` (the held object is upright
    either way, only turned), of those the arm reaches the one nearest the arm as it is (the
    smallest largest joint change: a far one swept the upper arm through the table); else
    the kinematic failure. The side grasp's pose points along the bearing from the base,
    and an object far to one side of the robot was reachable only turned."""
    outcome = str(skills_kinematic.move_gripper_to_stack.impl(world, bb, rng, **params))
    if outcome == "success" or bb.get("last_failure_reason") not in ("unreachable",
                                                                      "joint_limits"):
        return outcome
    state = read_state(bb)
    arm = next((a for a in ARMS if state.held[a] is not None), None)
    name = stack_object_name(bb, float(params.get("which", 1.0)))
    anchor = None if name is None else object_position(bb, name)
    if arm is None or anchor is None:
        return outcome
    position = [a + float(params.get(k, d)) for a, k, d in
                zip(anchor, ("dx", "dy", "dz"), (0.0, 0.0, 0.1), strict=True)]
    goal = grasp_pose_world(bb.get(GRASP_KEY) or "top", state.base_pose_world, position)
    table = Scene(scene_world(bb).boxes)
    found: list[tuple[float, RobotState]] = []
    for turn in TURN_RAD:
        turned = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, turn) @ goal.rotation, goal.translation)
        answer = reach(world, state, arm, turned, table, rng)
        if answer.state is not None:
            change = max(abs(wrap(b - a)) if j in CONTINUOUS else abs(b - a) for j, (a, b) in
                         enumerate(zip(state.q_arm_rad[arm], answer.state.q_arm_rad[arm],
                                       strict=True)))
            found.append((change, answer.state))
    if not found:
        return outcome
    best = min(found, key=lambda item: item[0])[1]
    commit(world, bb, RobotState(best.base_pose_world, best.torso_height_m, best.q_arm_rad,
                                 best.held, arm))
    return "success"


grasp_param = dynamic_twin(KinematicSkill(skills_kinematic.grasp_param.spec, _grasp_plan),
                           world_keys=object_keys,
                           prepare=_unfold, via=_grasp_via, route=base_route,
                           recover=_back_out)
"""The dynamic GraspParam (module docstring)."""
move_gripper_to_stack = dynamic_twin(
    KinematicSkill(skills_kinematic.move_gripper_to_stack.spec, _stack_plan),
    world_keys=object_keys, via=_stack_via, route=base_route)
"""The dynamic MoveGripperToStack (module docstring)."""
open_gripper = dynamic_twin(skills_kinematic.open_gripper, world_keys=object_keys,
                            settle_s=REST_S)
"""The dynamic OpenGripper (module docstring)."""


def _check_success(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator
                   ) -> Literal["success", "failure"]:
    physics = world.current(bb, "CheckSuccess")
    names = list(bb["object_positions_world"])
    if held(bb) is not None or not all(physics.upright(str(n)) for n in names):
        return "failure"
    return "success" if stacked(bb) else "failure"


check_success = DynamicSkill(skills_stacking.check_success.spec, _check_success)
"""The dynamic CheckSuccess (module docstring): the blackboard's positions are the
simulation's, and both objects must stand upright."""


def _reach_check(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator) -> str:
    return str(stacking_kinematic.reach_check.impl(world.kinematic, bb, rng))


reach_check = DynamicSkill(stacking_kinematic.reach_check.spec, _reach_check)
"""MoveToReach's Push on the dynamic backend: the kinematic check (IK, moving nothing) on the
simulated robot."""


def register(registry: Registry, *, move_to_reach: str | Path | None = None,
             topology: Topology = "layered", shortcut: bool = True,
             world: DynamicWorld | None = None) -> DynamicWorld:
    """Add the dynamic GraspParam, MoveGripperToStack, OpenGripper and CheckSuccess and, given
    its file, MoveToReach (on the dynamic MoveBase) to ``registry``, running in ``world``
    (default: a new one); return the world, whose episodes the task starts
    (:func:`start_episode`)."""
    world = world or DynamicWorld()
    for s in in_dynamic_world((grasp_param, move_gripper_to_stack, open_gripper,
                               check_success), world):
        registry.add(s)
    if move_to_reach is not None:
        nested = skills_stacking.reach_registry(topology, kinematic=False)
        for s in in_dynamic_world((make_move_base(topology), reach_check), world):
            nested.add(s)
        nested.backend = "dynamic"
        registry.add(skills_stacking.make_move_to_reach(
            move_to_reach, topology=topology, shortcut=shortcut, registry=nested),
            backend="dynamic")
    return world
