"""Moving to push (section 4.2) on the ``dynamic`` backend: the PR2 in MuJoCo.

The twins of the kinematic MoveBase and Push (:mod:`skillcompose.skills.kinematic`), with
their names, parameters, outcomes and blackboard keys; RecogniseObject is the shared one of
:mod:`skillcompose.skills.move_to_push` (perception is not physics). They run in a
:class:`~skillcompose.skills.dynamic_world.DynamicWorld` whose episode the task's setup starts
(:func:`start_episode`: the table of ``table_world`` and the object, a box of
``object_half_extents_m``, :data:`OBJECT_MASS_KG` and friction :data:`OBJECT_FRICTION`,
standing at ``object_position_world``).

- ``MoveBase(weights)``: the kinematic twin plans (the same network, the same safety
  distance, the same collision checks at the goal), then the base drives there under
  control, around the table when the straight path would cross it (:func:`base_route`), and
  the torso lifts. ``failure`` as the kinematic twin, or when the motion does not reach its
  goal (``blocked``) or ends with the robot touching the table (``hit_table``).
- ``Push``: the gripper closes, the arm MoveBase chose (the torso and base fixed) goes to a
  pre-push pose :data:`PUSH_CLEARANCE_M` before the object's face, horizontal and pointing
  along the bearing from the base, as low above the object's bottom as the IK allows
  (:data:`PUSH_HEIGHTS_M`: low, so that a tall object slides rather than tips); the closed
  finger tips are then driven
  through the object's place along that bearing, :data:`PUSH_STROKE_M` past first contact,
  at :data:`PUSH_SPEED_M_S`, and back to the pre-push pose. The plan (:func:`_plan`): IK
  puts the tips on the object's face (from the unfolded arm, the arm as it is, then with
  the torso free); the stroke and the retreat are straight lines of the tool
  (:func:`~skillcompose.skills.dynamic_world.cartesian_path`), shortened to
  :data:`MIN_STROKE_M` / :data:`MIN_CLEARANCE_M` when the line ends early, every step kept
  off the simulated table (:func:`~skillcompose.skills.dynamic_world.arm_touches_table`);
  the other, empty arm when the one in use has none. ``failure`` with the IK's reason when
  no push can be planned, and nothing moves. **Pushed** (``success``, ``pushed`` = True):
  after the push, the object's centre moved at least :data:`PUSHED_M` (5 cm) along the push
  direction and it stands upright (its z axis within 20° of vertical). Otherwise ``failure`` with
  ``last_failure_reason``: ``blocked`` / ``hit_table`` (the arm's motion), ``toppled`` (the
  object fell over) or ``not_moved`` (it moved less than 5 cm along the push).

What physics produces ends as an outcome, never as an error; the same seed gives the same
episode.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Mapping, Sequence
from typing import Any, Literal

import numpy as np
import pinocchio as pin

from skillcompose import Blackboard, Registry
from skillcompose.robots.collision import BASE_HALF_EXTENTS_M, Box, Scene
from skillcompose.robots.model import TUCKED_ARM_RAD, Arm
from skillcompose.robots.physics import Motion, PhysicsWorld
from skillcompose.robots.physics_model import ObjectSpec, SceneSpec
from skillcompose.skills import kinematic as skills_kinematic
from skillcompose.skills.dynamic_world import (
    DynamicSkill,
    DynamicWorld,
    Execution,
    arm_touches_table,
    cartesian_path,
    dynamic_twin,
    execute,
    follow_path,
    in_dynamic_world,
    judge_motion,
    sync,
    tool_world,
)
from skillcompose.skills.kinematic_world import (
    TABLE_KEY,
    Reach,
    RobotState,
    arms_for,
    fail,
    object_position,
    reach,
    read_state,
    scene_world,
)
from skillcompose.skills.move_to_push import base_hits_table
from skillcompose.skills.network import Topology

__all__ = [
    "MIN_CLEARANCE_M",
    "MIN_STROKE_M",
    "OBJECT_FRICTION",
    "OBJECT_MASS_KG",
    "PUSHED_M",
    "PUSH_CLEARANCE_M",
    "PUSH_HEIGHTS_M",
    "PUSH_SPEED_M_S",
    "PUSH_STROKE_M",
    "READY_ARM_RAD",
    "approach",
    "base_route",
    "make_move_base",
    "object_keys",
    "push",
    "register",
    "scene_of",
    "start_episode",
    "unfold",
    "unfolded",
]

Pose3 = tuple[float, float, float]

OBJECT_MASS_KG = 0.3
"""The pushed object's mass [kg] (a filled 6 x 6 x 20 cm bottle)."""
OBJECT_FRICTION = 0.3
"""The pushed object's sliding friction (plastic on wood), the table's too."""
PUSHED_M = 0.05
"""A push succeeds when the object's centre moved at least this far along it [m]."""
PUSH_HEIGHTS_M = (0.05, 0.075, 0.10)
"""Heights above the object's bottom the finger tips push at [m], tried in order until the
IK finds both waypoints (never above the object's centre): a 6 cm wide object pushed at
5 cm tips only with friction above 0.6, at 10 cm (its centre, the kinematic twin's aim)
above 0.3. Low pushes put the forearm near the table for deep objects."""
PUSH_CLEARANCE_M = 0.06
"""The pre-push pose keeps the finger tips this far before the object's face [m]."""
PUSH_STROKE_M = 0.07
"""How far the finger tips travel past first contact with the object [m]..."""
MIN_STROKE_M = 0.055
"""... at least, when the arm's straight line ends before (near the end of its reach) [m]."""
STROKE_STEP_M = 0.01
"""The stroke's straight line is solved at this step [m], so that it may end anywhere past
:data:`MIN_STROKE_M` to the centimetre."""
MIN_CLEARANCE_M = 0.02
"""The pre-push pose's clearance when :data:`PUSH_CLEARANCE_M` has no straight line [m]."""
PUSH_SPEED_M_S = 0.1
"""Tool speed of the stroke [m/s]."""
FINGER_REACH_M = 0.019
"""How far the closed finger tips reach beyond the tool frame's origin along its x [m]
(measured on the model's convex hulls)."""
READY_ARM_RAD: dict[Arm, tuple[float, ...]] = {
    "left": (0.0, 0.0, 0.0, -1.7, 0.0, -0.4, 0.0),
    "right": (0.0, 0.0, 0.0, -1.7, 0.0, -0.4, 0.0),
}
"""An arm unfolded, upper arm level and forearm up (the tool 1.26 m above the floor with the
torso down): a tucked arm goes here first, above the table, and the IK of its motions
starts from here (the tucked arm's IK solutions twist the upper arm and sweep the table)."""
UNFOLD_TORSO_M = 0.3
"""The torso's height while a tucked arm unfolds [m]."""
APPROACH_RISE_M = 0.2
"""An arm's approach (:func:`approach`) starts this far above its target [m]..."""
APPROACH_BACK_M = 0.15
"""... and this far back from it, along the tool's x axis on the floor [m]."""
ROUTE_CLEARANCE_M = 0.05
"""The base's path around the table keeps its disc this far from the table [m]."""
_ROUTE_STEP_M = 0.025
_BASE_RADIUS_M = math.hypot(*BASE_HALF_EXTENTS_M)
_OBJECT = "object"
_ObjectHalf = tuple[float, float, float]


# -- the episode -------------------------------------------------------------------------------
def _half_extents(bb: Blackboard) -> _ObjectHalf:
    half = bb.get("object_half_extents_m") or (0.03, 0.03, 0.10)
    return (float(half[0]), float(half[1]), float(half[2]))


def scene_of(bb: Blackboard) -> SceneSpec:
    """The physics scene of a move-to-push blackboard: its ``table_world`` and the object."""
    return SceneSpec(table=bb.get(TABLE_KEY), objects=(
        ObjectSpec(_OBJECT, "box", _half_extents(bb), OBJECT_MASS_KG, OBJECT_FRICTION),))


def start_episode(world: DynamicWorld, bb: Blackboard) -> PhysicsWorld:
    """Start ``bb``'s physics episode in ``world``: the robot as ``bb`` says, the object
    upright at ``object_position_world``."""
    x, y, z = (float(v) for v in bb["object_position_world"])
    return world.start(bb, scene_of(bb), object_poses={_OBJECT: (x, y, z)})


def object_keys(physics: PhysicsWorld, bb: Blackboard) -> Mapping[str, Any]:
    """The world keys as simulated: the pushed object's centre (``object_position_world``),
    or the stacking objects' (``object_positions_world``, in the blackboard's order), as the
    scene has them."""
    objects = physics.physics.object_body
    out: dict[str, Any] = {}
    if _OBJECT in objects:
        x, y, z = physics.object_pose(_OBJECT)[:3]
        out["object_position_world"] = (x, y, z)
    stack = bb.get("object_positions_world")
    if isinstance(stack, Mapping) and all(name in objects for name in stack):
        out["object_positions_world"] = {
            str(name): tuple(physics.object_pose(str(name))[:3]) for name in stack}
    return out


# -- the base's path ---------------------------------------------------------------------------
def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _leg_clear(table: Box, a: Pose3, b: Pose3, *, first: bool, last: bool) -> bool:
    """Whether the base's footprint stays clear of ``table`` as it drives from ``a`` to ``b``
    (x, y, yaw each blended alike, as the servo's trajectory does), sampled every 2.5 cm; the
    leg's own start and end are not checked when they are the route's (the task judged
    them)."""
    length = math.hypot(b[0] - a[0], b[1] - a[1])
    turn = _wrap(b[2] - a[2])
    n = max(2, math.ceil(max(length, abs(turn) * _BASE_RADIUS_M) / _ROUTE_STEP_M))
    for k in range(n + 1):
        if (k == 0 and first) or (k == n and last):
            continue
        s = k / n
        pose = (a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), a[2] + s * turn)
        if base_hits_table(pose, table, 0.01):
            return False
    return True


def _corners(table: Box) -> list[tuple[float, float]]:
    """The table's footprint grown by the base's disc and :data:`ROUTE_CLEARANCE_M`: its
    corners in world, in order round it."""
    grow = _BASE_RADIUS_M + ROUTE_CLEARANCE_M
    hx, hy = table.half_extents_m[0] + grow, table.half_extents_m[1] + grow
    c, s = math.cos(table.yaw_rad), math.sin(table.yaw_rad)
    cx, cy = table.center_m[0], table.center_m[1]
    return [(cx + c * u - s * v, cy + s * u + c * v)
            for u, v in ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy))]


def base_route(bb: Blackboard, start: Pose3, goal: Pose3) -> list[Pose3]:
    """The base's path from ``start`` to ``goal`` (x [m], y [m], yaw [rad] in world): straight
    when its footprint stays clear of ``table_world`` on the way, else the shortest path
    round the table through corners of its footprint grown by the base's disc (up to three),
    the heading turning in proportion to the distance driven. With no clear path the
    straight one (physics then judges it). The room's walls are not simulated."""
    table = bb.get(TABLE_KEY)
    if table is None or _leg_clear(table, start, goal, first=True, last=True):
        return [goal]
    corners = _corners(table)
    best: tuple[float, list[Pose3]] | None = None
    for first in range(4):
        for step in (1, -1):
            for count in (1, 2, 3):
                points = [corners[(first + step * k) % 4] for k in range(count)]
                path = [(start[0], start[1]), *points, (goal[0], goal[1])]
                lengths = [math.dist(p, q) for p, q in itertools.pairwise(path)]
                total = sum(lengths)
                if best is not None and total >= best[0]:
                    continue
                turn = _wrap(goal[2] - start[2])
                poses: list[Pose3] = [start]
                driven = 0.0
                for (px, py), length in zip(path[1:], lengths, strict=True):
                    driven += length
                    poses.append((px, py, start[2] + turn * driven / max(total, 1e-9)))
                poses[-1] = goal
                if all(_leg_clear(table, a, b, first=k == 0, last=k == len(poses) - 2)
                       for k, (a, b) in enumerate(itertools.pairwise(poses))):
                    best = (total, poses[1:])
    return best[1] if best is not None else [goal]


# -- the skills --------------------------------------------------------------------------------
def make_move_base(topology: Topology) -> DynamicSkill:
    """The dynamic twin of the kinematic MoveBase for a ``topology`` network (module
    docstring)."""
    return dynamic_twin(skills_kinematic.make_move_base(topology), world_keys=object_keys,
                        route=base_route)


def _touch_pose(physics: PhysicsWorld, state: RobotState, position: Sequence[float],
                half: _ObjectHalf, rise_m: float) -> tuple[pin.SE3, float]:
    """The tool pose in world where the closed finger tips meet the object's face, ``rise_m``
    above its bottom (never above its centre), and the push bearing [rad]."""
    bearing = math.atan2(position[1] - state.base_pose_world[1],
                         position[0] - state.base_pose_world[0])
    yaw = physics.object_pose(_OBJECT)[5]
    depth = abs(math.cos(bearing - yaw)) * half[0] + abs(math.sin(bearing - yaw)) * half[1]
    direction = np.array([math.cos(bearing), math.sin(bearing), 0.0])
    height = min(float(position[2]), float(position[2]) - half[2] + rise_m)
    centre = np.array([float(position[0]), float(position[1]), height])
    rotation = np.asarray(pin.rpy.rpyToMatrix(0.0, 0.0, bearing))
    return pin.SE3(rotation, centre - (depth + FINGER_REACH_M) * direction), bearing


def unfolded(state: RobotState, arms: Sequence[Arm]) -> RobotState:
    """``state`` with ``arms`` at :data:`READY_ARM_RAD` (an arm that is not tucked stays)."""
    q = dict(state.q_arm_rad)
    for arm in arms:
        if max(abs(_wrap(a - b)) for a, b in zip(q[arm], TUCKED_ARM_RAD[arm], strict=True)) \
                < 0.05:
            q[arm] = READY_ARM_RAD[arm]
    return RobotState(state.base_pose_world, state.torso_height_m, q, state.held,
                      state.arm_in_use)


def unfold(physics: PhysicsWorld, state: RobotState, arms: Sequence[Arm]) -> RobotState:
    """Unfold the tucked ``arms`` in the simulation (:func:`unfolded`): the torso rises to
    the top first (a tucked arm unfolding at the torso's bottom near a table strikes it),
    the arms unfold, and the torso returns; returns the robot unfolded."""
    ready = unfolded(state, arms)
    moving = [arm for arm in arms if ready.q_arm_rad[arm] != state.q_arm_rad[arm]]
    if not moving:
        return ready
    torso = physics.torso_m()
    if torso < UNFOLD_TORSO_M:
        physics.move_torso(UNFOLD_TORSO_M, max(0.5, (UNFOLD_TORSO_M - torso) / 0.1),
                           settle_s=0.0)
    for arm in moving:
        physics.track_arm(arm, ready.q_arm_rad[arm], 1.5, settle_s=0.1)
    if torso < UNFOLD_TORSO_M:
        physics.move_torso(state.torso_height_m,
                           max(0.5, (UNFOLD_TORSO_M - state.torso_height_m) / 0.1))
    return ready


def approach(world: DynamicWorld, goal: RobotState, arm: Arm, target: pin.SE3,
             scene: Scene, rng: np.random.Generator, *, rise_m: float = APPROACH_RISE_M,
             back_m: float = APPROACH_BACK_M) -> list[RobotState]:
    """Waypoints for ``arm`` (torso and base fixed) on the way to ``goal``, whose tool is at
    ``target`` (a pose in world): the tool ``rise_m`` above the target and ``back_m`` back
    along its x axis (projected on the floor), then 40 % of that, each by IK warm-started
    from the one after it (the goal's joint angles first, no restarts, so that each is near
    the next in joint space) and clear of ``scene``: the arm comes down onto the target
    instead of sweeping through the table on a straight line in joint space. A waypoint the
    IK cannot find so is left out."""
    axis = np.array(target.rotation[:, 0], dtype=float)
    axis[2] = 0.0
    norm = float(np.linalg.norm(axis))
    back = axis / norm if norm > 1e-6 else np.zeros(3)
    states: list[RobotState] = []
    at = goal
    for share in (0.4, 1.0):
        point = target.translation + share * (rise_m * np.array([0.0, 0.0, 1.0]) - back_m * back)
        answer = reach(world.kinematic, at, arm, pin.SE3(target.rotation, point), scene, rng,
                       move_torso=False, diagnose=False, restarts=0)
        if answer.state is not None:
            at = answer.state
            states.insert(0, at)
    return states


def _stroke(world: DynamicWorld, physics: PhysicsWorld, arm: Arm, contact: RobotState,
            touch: pin.SE3, direction: np.ndarray, scene: Scene, rng: np.random.Generator
            ) -> tuple[list[RobotState], list[RobotState]] | None:
    """The straight lines of a push from ``contact`` (the finger tips on the object's face,
    the tool at ``touch``): back to the pre-push pose (:data:`PUSH_CLEARANCE_M`, at least
    :data:`MIN_CLEARANCE_M`) and on through the object (:data:`PUSH_STROKE_M`, at least
    :data:`MIN_STROKE_M`), each a :func:`~skillcompose.skills.dynamic_world.cartesian_path`
    whose every step keeps the arm off the simulated table
    (:func:`~skillcompose.skills.dynamic_world.arm_touches_table`). Returns (pre-push to
    contact, contact to the stroke's end), or None."""

    def clear(state: RobotState) -> bool:
        return not arm_touches_table(physics, state, arm)

    if not clear(contact):
        return None
    back = cartesian_path(world, contact, arm, pin.SE3(
        touch.rotation, touch.translation - PUSH_CLEARANCE_M * direction), scene, rng,
        clear=clear)
    if not back or back[-1][1] < MIN_CLEARANCE_M - 1e-9:
        return None
    forward = cartesian_path(world, contact, arm, pin.SE3(
        touch.rotation, touch.translation + PUSH_STROKE_M * direction), scene, rng,
        step_m=STROKE_STEP_M, clear=clear)
    if not forward or forward[-1][1] < MIN_STROKE_M - 1e-9:
        return None
    into = [state for state, _ in reversed(back[:-1])] + [contact]
    return [back[-1][0], *into], [state for state, _ in forward]


def _contacts(world: DynamicWorld, state: RobotState, ready_arm: RobotState, arm: Arm,
              touch: pin.SE3, scene: Scene, rng: np.random.Generator, *, diagnose: bool
              ) -> Iterator[Reach]:
    """IK answers for the tool at ``touch``, in the order a push tries them: from the arm
    unfolded, from the arm as it is (the kinematic twin's start), then with the torso free
    to move too (raised or lowered, as the kinematic MoveBase's reach may). The last is
    diagnosed when ``diagnose``."""
    for seed, torso in ((ready_arm, False), (state, False), (ready_arm, True)):
        yield reach(world.kinematic, seed, arm, touch, scene, rng, move_torso=torso,
                    diagnose=diagnose and torso)


_Plan = tuple[Arm, RobotState, list[RobotState], list[RobotState], float]


def _plan(world: DynamicWorld, physics: PhysicsWorld, bb: Blackboard, state: RobotState,
          position: Sequence[float], arms: Sequence[Arm], rng: np.random.Generator
          ) -> _Plan | Reach:
    """The push's arm, its arm unfolded, its two straight lines (:func:`_stroke`) and the
    push bearing: for each arm (the one in use first), each height of
    :data:`PUSH_HEIGHTS_M` from the lowest, each IK start of :func:`_contacts`; else the
    first informative IK failure."""
    scene = scene_world(bb)
    failure: Reach | None = None
    for arm in arms:
        ready_arm = unfolded(state, (arm,))
        for k, rise in enumerate(PUSH_HEIGHTS_M):
            touch, bearing = _touch_pose(physics, state, position, _half_extents(bb), rise)
            direction = np.asarray(touch.rotation[:, 0], dtype=float)
            for answer in _contacts(world, state, ready_arm, arm, touch, scene, rng,
                                    diagnose=failure is None
                                    and k == len(PUSH_HEIGHTS_M) - 1):
                if answer.state is None:
                    if failure is None or failure.reason == "unreachable":
                        failure = answer
                    continue
                contact = RobotState(answer.state.base_pose_world,
                                     answer.state.torso_height_m, answer.state.q_arm_rad,
                                     state.held, arm)
                lines = _stroke(world, physics, arm, contact, touch, direction, scene, rng)
                if lines is not None:
                    return arm, ready_arm, lines[0], lines[1], bearing
    if failure is None:
        failure = Reach(arms[0], None, "collision", f"{arms[0]} arm: every straight stroke "
                        "through the object brings the arm onto the table")
    return failure


def _push(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator
          ) -> Literal["success", "failure"]:
    physics = world.current(bb, "Push")
    position = object_position(bb, _OBJECT)
    if position is None:
        return fail(bb, "no_object", "Push: the world has no object_position_world")
    state = read_state(bb)
    arm = state.arm_in_use or arms_for(state, position)[0]
    if state.held[arm] is not None:
        return fail(bb, "already_holding", f"Push: the {arm} gripper holds {state.held[arm]!r}")
    other: Arm = "right" if arm == "left" else "left"
    arms = (arm, other) if state.held[other] is None else (arm,)
    plan = _plan(world, physics, bb, state, position, arms, rng)
    if isinstance(plan, Reach):
        return fail(bb, plan.reason, f"Push: {plan.detail}")
    arm, ready_arm, into, through, bearing = plan
    ready = into[0]
    scene = scene_world(bb)
    was = np.array(physics.object_pose(_OBJECT)[:3])
    physics.close_gripper(arm)
    unfold(physics, state, (arm,))
    motions: list[tuple[str, Motion]] = []
    at = ready_arm
    target = tool_world(world, ready, arm)
    waypoints = [w for w in approach(world, ready, arm, target, scene, rng)
                 if not arm_touches_table(physics, w, arm)]
    for waypoint in (*waypoints, ready):
        motions.extend(execute(world, physics, at, waypoint).motions)
        at = waypoint
    for path in (into[1:], through, [*reversed(through[:-1]), *reversed(into)]):
        motions.extend((arm, m) for m in follow_path(physics, arm, path, PUSH_SPEED_M_S))
    now = sync(physics, bb, planned=ready, world_keys=object_keys)
    if judge_motion(physics, bb, "Push", ready, Execution(tuple(motions), {}, {}), now):
        return "failure"
    moved = float((np.array(physics.object_pose(_OBJECT)[:3]) - was)[:2]
                  @ np.array([math.cos(bearing), math.sin(bearing)]))
    if not physics.upright(_OBJECT):
        return fail(bb, "toppled", "Push: the object fell over")
    if moved < PUSHED_M:
        return fail(bb, "not_moved", f"Push: the object moved {moved:.3f} m along the push, "
                    f"less than {PUSHED_M} m")
    bb["pushed"] = True
    return "success"


push = DynamicSkill(skills_kinematic.push.spec, _push)
"""The dynamic Push (module docstring); its declaration is the kinematic twin's."""


def register(registry: Registry, *, topology: Topology = "layered",
             world: DynamicWorld | None = None) -> DynamicWorld:
    """Add the dynamic MoveBase (a ``topology`` network) and Push to ``registry``, running in
    ``world`` (default: a new one); return the world, whose episodes the task starts
    (:func:`start_episode`). RecogniseObject is :mod:`skillcompose.skills.move_to_push`'s."""
    world = world or DynamicWorld()
    for s in in_dynamic_world((make_move_base(topology), push), world):
        registry.add(s)
    return world
