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
  only when the unfolded arms then clear the simulated table), so that the IK starts
  there; the kinematic twin plans the grasp (side, else top); the arm passes a pre-grasp
  pose :data:`PRE_GRASP_M` back along the approach (and one above that), so the open
  fingers come straight onto the object (a straight tool line solved backwards from the
  plan, :func:`~skillcompose.skills.dynamic_world.cartesian_path`, each step clear of the
  simulated table and the other object; when the plan's configuration has no such line,
  another configuration of the same grasp pose that has one replaces it,
  :func:`_regrasp`), then the fingers close and hold it by friction. A motion on the way
  whose line would touch the table or the other object goes over it with the shoulder
  lifted, else with the torso raised (:func:`clear_transits`; also for
  MoveGripperToStack). ``failure``: the kinematic reasons, ``missed`` (the fingers closed
  on nothing or on the other object), ``blocked`` (a motion did not reach its goal),
  ``hit_table``.
- ``MoveGripperToStack(which, dx, dy, dz)``: the kinematic plan, reached by lifting the
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
from collections.abc import Mapping, Sequence
from itertools import pairwise
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
    in_dynamic_world,
    sync,
    tool_world,
)
from skillcompose.skills.kinematic_world import (
    TABLE_KEY,
    TOOL_KEYS,
    TORSO_RANGE_M,
    RobotState,
    commit,
    object_box,
    reach,
    read_state,
    scene_world,
)
from skillcompose.skills.move_to_push_dynamic import (
    UNFOLD_TORSO_M,
    base_route,
    make_move_base,
    object_keys,
    unfolded,
)
from skillcompose.skills.network import Topology
from skillcompose.skills.stacking_world import DEFAULT_HALF_EXTENTS_M, held, stacked

__all__ = [
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
TRANSIT_SAMPLES = 10
"""A joint-space motion between waypoints is checked against the simulated table at this
many points along it."""
RAISE_RAD = (0.0, 0.3, 0.6)
"""A motion whose joint-space line touches the table goes first to its goal with the
shoulder lifted: by these amounts above the higher of its two ends [rad], the first clear."""
SHOULDER_LIFT = 1
"""The shoulder lift's index among an arm's joints (larger: lower)."""
SHOULDER_LIFT_MIN_RAD = -0.5
HOP_TORSO_M = TORSO_RANGE_M[1]
"""A motion that cannot pass over the table with the shoulder lifted passes with the torso
raised this high [m] (:func:`_hop`) ..."""
HOP_MIN_M = 0.05
"""... when that is at least this much above both its ends [m]."""
REGRASP_TRIES = 8
"""GraspParam: when no straight approach line ends in the kinematic plan's configuration,
this many other IK solutions of the pre-grasp pose are tried as its start (:func:`_regrasp`)."""
CONTINUOUS = (4, 6)
"""The continuous joints' indices among an arm's joints (forearm and wrist roll), which
turn the short way round."""


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


def _with_arm(state: RobotState, arm: Arm, q: Sequence[float]) -> RobotState:
    return RobotState(state.base_pose_world, state.torso_height_m,
                      {**state.q_arm_rad, arm: tuple(q)}, state.held, state.arm_in_use)


def line_touches_table(physics: PhysicsWorld, a: RobotState, b: RobotState, arm: Arm, *,
                       samples: int = TRANSIT_SAMPLES, objects: Sequence[str] = (),
                       carried: str | None = None) -> bool:
    """Whether ``arm`` touches the simulated table (or one of ``objects``) somewhere on the
    motion from ``a`` to ``b`` as :func:`~skillcompose.skills.dynamic_world.execute` makes
    it (at ``b``'s base; the ends excluded): the servo's straight line in joint space, at
    ``b``'s torso when the torso rises (it rises first) and at ``a``'s when it lowers (it
    lowers last), and the torso's own vertical motion, each checked at ``samples`` points;
    with ``carried``, the object the arm holds is checked against ``objects`` too."""
    qa, qb = a.q_arm_rad[arm], b.q_arm_rad[arm]
    delta = [_wrap(y - x) if j in CONTINUOUS else y - x
             for j, (x, y) in enumerate(zip(qa, qb, strict=True))]
    za, zb = a.torso_height_m, b.torso_height_m
    lowers = zb < za
    inner = [k / samples for k in range(1, samples)]

    def at(q: Sequence[float], z: float) -> RobotState:
        return dataclasses.replace(_with_arm(b, arm, q), torso_height_m=z)

    arm_line = [at([x + t * d for x, d in zip(qa, delta, strict=True)], za if lowers else zb)
                for t in inner] if any(abs(d) > 1e-9 for d in delta) else []
    torso_line = [at(qb if lowers else qa, za + t * (zb - za)) for t in inner] \
        if abs(zb - za) > 1e-9 else []
    corner = [at(qb, za) if lowers else at(qa, zb)] if arm_line and torso_line else []
    poses = [*arm_line, *corner, *torso_line] if lowers else \
        [*torso_line, *corner, *arm_line]
    return any(_touches(physics, s, arm, objects, carried) for s in poses)


def _wrap(angle: float) -> float:
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def clear_transits(physics: PhysicsWorld, arm: Arm, start: RobotState,
                   waypoints: Sequence[RobotState], *, objects: Sequence[str] = (),
                   carried: str | None = None) -> list[RobotState]:
    """``waypoints`` (from ``start``), with configurations inserted before each whose motion
    touches the simulated table or one of ``objects`` (the arm, or the object it has
    ``carried``): over it with the shoulder lifted
    (:func:`_over`), else over it with the torso raised (:func:`_hop`); the waypoint left as
    it is when there are none."""
    out: list[RobotState] = []
    at = start
    for goal in waypoints:
        if line_touches_table(physics, at, goal, arm, objects=objects, carried=carried):
            out.extend(_over(physics, arm, at, goal, objects, carried)
                       or _hop(physics, arm, at, goal, objects, carried))
        out.append(goal)
        at = goal
    return out


def _touches(physics: PhysicsWorld, state: RobotState, arm: Arm,
             objects: Sequence[str], carried: str | None = None) -> bool:
    return bool(arm_touches_table(physics, state, arm, objects=objects, carried=carried))


def _over(physics: PhysicsWorld, arm: Arm, start: RobotState, goal: RobotState,
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
            raised.append(_with_arm(goal, arm, q))
        for via in ([raised[1]], raised):
            if any(_touches(physics, s, arm, objects, carried) for s in via):
                continue
            legs = list(pairwise([start, *via, goal]))
            if len(via) == 2 and _touches(physics, start, arm, objects, carried):
                legs = legs[1:]  # lifting off the table it touches already
            if not any(line_touches_table(physics, a, b, arm, objects=objects,
                                          carried=carried) for a, b in legs):
                return via
    return []


def _hop(physics: PhysicsWorld, arm: Arm, start: RobotState, goal: RobotState,
         objects: Sequence[str] = (), carried: str | None = None) -> list[RobotState]:
    """The configurations to pass from ``start`` to ``goal`` with the torso raised to the
    top (:data:`HOP_TORSO_M`): the torso rises (the whole arm straight up), the arm moves up
    there, and the torso comes down onto ``goal`` (straight down); none when the torso is
    not :data:`HOP_MIN_M` higher so, or a motion on the way touches the simulated table or
    ``objects`` (lifting off what ``start`` touches aside)."""
    top = HOP_TORSO_M
    if top - max(start.torso_height_m, goal.torso_height_m) < HOP_MIN_M:
        return []
    up = dataclasses.replace(_with_arm(goal, arm, start.q_arm_rad[arm]), torso_height_m=top)
    across = dataclasses.replace(goal, torso_height_m=top)
    if _touches(physics, up, arm, objects, carried) or \
            _touches(physics, across, arm, objects, carried):
        return []
    if line_touches_table(physics, up, across, arm, objects=objects, carried=carried) or \
            line_touches_table(physics, across, goal, arm, objects=objects, carried=carried):
        return []
    return [up, across]


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
    :data:`LIFT_M` above that, each near the next in joint space; the approach's straight
    line clear of the table and of the other object. When no such line ends in the plan's
    configuration, another configuration of the same grasp pose that has one
    (:func:`_regrasp`) replaces the plan on the blackboard."""
    arm = _moved_arm(before, planned)
    if arm is None:
        return ()
    grasp = _tool(bb, arm)
    avoid = _others(bb, bb.get("grasp_target"))
    back = grasp.translation - PRE_GRASP_M * grasp.rotation[:, 0]
    pre_pose = pin.SE3(grasp.rotation, back)
    keep = RobotState(planned.base_pose_world, planned.torso_height_m, planned.q_arm_rad,
                      before.held, planned.arm_in_use)
    line = _straight_back(world, bb, rng, keep, arm, pre_pose, avoid)
    if not line:
        found = _regrasp(world, bb, rng, keep, arm, grasp, pre_pose, avoid)
        if found is not None:
            keep, line = found
            commit(world.kinematic, bb, dataclasses.replace(keep, held=planned.held))
    pre = line[0] if line else _near(world, keep, arm, pre_pose, bb, rng)
    if pre is None:
        return ()
    up = np.array([0.0, 0.0, LIFT_M])
    high = _near(world, pre, arm, pin.SE3(grasp.rotation, back + up), bb, rng)
    via = [*([high] if high is not None else []), *(line or [pre])]
    return _transit(world, arm, before, via, keep, avoid)


def _transit(world: DynamicWorld, arm: Arm, before: RobotState, via: Sequence[RobotState],
             planned: RobotState, objects: Sequence[str] = ()) -> Sequence[RobotState]:
    """``via`` with the clear transits (:func:`clear_transits`) on the way from ``before``
    to ``planned``, the plan itself left out."""
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
                          clear=lambda s: not _touches(physics, s, arm, objects))
    if not path or path[-1][1] < PRE_GRASP_M - 1e-6:
        return []
    return [s for s, _ in reversed(path)]


def _regrasp(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator,
             planned: RobotState, arm: Arm, grasp: pin.SE3, pre: pin.SE3,
             objects: Sequence[str] = ()) -> tuple[RobotState, list[RobotState]] | None:
    """Another configuration of ``planned``'s arm for the grasp pose ``grasp`` (torso and
    base kept), reached on a straight line from the pre-grasp pose ``pre``: IK of ``pre``
    warm-started from :data:`REGRASP_TRIES` random arms (the run's generator), each followed
    by the straight line onto ``grasp``, every step clear of the simulated table and
    ``objects``; ``(grasp configuration, the line's robots before it)``, or None."""
    physics = world.physics
    if physics is None:
        return None
    scene = _avoid_scene(bb, objects)
    chain = world.kinematic.chains[arm]

    def clear(s: RobotState) -> bool:
        return not _touches(physics, s, arm, objects)

    for _ in range(REGRASP_TRIES):
        start = _with_arm(planned, arm, [float(v) for v in chain.sample_coordinates(rng)[1:]])
        answer = reach(world.kinematic, start, arm, pre, scene, rng, move_torso=False,
                       diagnose=False, restarts=0)
        if answer.state is None:
            continue
        first = RobotState(planned.base_pose_world, planned.torso_height_m,
                           answer.state.q_arm_rad, planned.held, planned.arm_in_use)
        if not clear(first):
            continue
        path = cartesian_path(world, first, arm, grasp, scene, rng, clear=clear)
        if not path or path[-1][1] < PRE_GRASP_M - 1e-6:
            continue
        return path[-1][0], [first, *(s for s, _ in path[:-1])]
    return None


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
                          clear=lambda s: not _touches(physics, s, arm, objects, carried))
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
    for arm in moving:
        physics.track_arm(arm, ready.q_arm_rad[arm], 1.5, settle_s=0.1)
    if high > torso and not any(arm_touches_table(physics, ready, arm) for arm in ARMS):
        physics.move_torso(torso, max(0.5, (high - torso) / 0.1))
    sync(physics, bb, planned=state, world_keys=object_keys)
    return None


# -- the skills --------------------------------------------------------------------------------
grasp_param = dynamic_twin(skills_kinematic.grasp_param, world_keys=object_keys,
                           prepare=_unfold, via=_grasp_via, route=base_route)
"""The dynamic GraspParam (module docstring)."""
move_gripper_to_stack = dynamic_twin(skills_kinematic.move_gripper_to_stack,
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
