"""The robot behind the dynamic skills: kinematic plans, executed and judged by physics.

The ``"dynamic"`` backend runs the same FSA files as ``"sim"`` and ``"kinematic"`` on the PR2
in MuJoCo (:mod:`skillcompose.robots.physics`). A dynamic skill is the *twin* of a kinematic
one (same name, parameters, outcomes and blackboard keys), made by :func:`dynamic_twin`:

1. **Plan.** The kinematic skill runs on the blackboard as it is (the robot as the last
   physics step left it): it chooses the arm, solves IK, checks the goal for collisions,
   and writes the robot it plans. A plan that fails is the outcome: nothing moves.
2. **Execute.** The plan becomes motions under control (:func:`execute`): the base drives,
   the torso lifts, the arm follows a joint trajectory to the planned configuration; an
   object the plan says is now held is grasped by closing the real fingers, and one it says
   is let go is released by opening them. Nothing is placed by assignment: a held object
   moves because friction holds it, a pushed one because the fingers touch it.
3. **Judge.** The blackboard is written again from the simulation (:func:`sync`: the robot's
   joints, base and tool poses, what each gripper holds by contact, the objects' positions,
   the water by where its particles are), and the motion judged (:func:`judge_motion`): a
   motion that did not reach its goal (``blocked``), a grasp that closed on nothing
   (``missed``), an object that left the gripper that held it (``dropped``), or an arm
   touching the table (``hit_table``) is a ``failure``, with ``last_failure_reason``. A
   twin without a ``failure`` outcome (RotateGripperToParam) records the reason and keeps
   its one outcome, as its kinematic twin does. Whatever physics produces ends as an
   outcome, never as an error.

Episodes. A task's ``setup`` draws the world as for the other backends and then starts the
physics episode (:meth:`DynamicWorld.start`): every pose is written once, there; after it only
the simulation moves things. A dynamic skill refuses a blackboard whose episode was not
started (run the FSA with its task, ``--task ... --set backend=dynamic``).

Determinism. The plan draws from the run's generator, the simulation reads no clock and no
global random state: the same seed gives the same episode.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco  # type: ignore[import-untyped]  # no stubs or py.typed
import numpy as np
import pinocchio as pin

from skillcompose import Blackboard, Skill, SkillSpec
from skillcompose.errors import BlackboardKeyError
from skillcompose.robots.collision import Scene
from skillcompose.robots.model import ARM_JOINTS, ARMS, TORSO_JOINT, Arm
from skillcompose.robots.physics import Motion, PhysicsWorld, PoseRecorder
from skillcompose.robots.physics_model import SceneSpec
from skillcompose.skill import SkillFn
from skillcompose.skills.kinematic_world import (
    ARM_IN_USE_KEY,
    BASE_POSE_KEY,
    HELD_KEYS,
    Q_KEYS,
    TOOL_KEYS,
    TORSO_KEY,
    KinematicSkill,
    KinematicWorld,
    RobotState,
    fail,
    reach,
    read_state,
    transform_robot_to_world,
)

__all__ = [
    "BACKEND",
    "DYNAMIC_FAILURE_REASONS",
    "BaseRoute",
    "DynamicSkill",
    "DynamicWorld",
    "Execution",
    "Recover",
    "Via",
    "arm_touches_table",
    "cartesian_path",
    "dynamic_twin",
    "execute",
    "follow_path",
    "in_dynamic_world",
    "judge_motion",
    "sync",
    "tool_world",
    "world_of",
]

BACKEND = "dynamic"

DYNAMIC_FAILURE_REASONS = (
    "blocked",  # a motion did not reach its goal within tolerance (something was in the way)
    "missed",  # a grasp closed the fingers on nothing
    "dropped",  # an object left the gripper that held it
    "hit_table",  # the robot ends a motion touching the table
    "toppled",  # an object that must stand upright does not
    "not_moved",  # a pushed object moved less than the push asks
)
"""Values of ``last_failure_reason`` that only physics gives, besides the kinematic ones."""

ARM_SPEED_RAD_S = 1.0
"""Fastest joint speed of an arm trajectory [rad/s]: a motion takes the largest joint
change over this, at least :data:`MIN_MOTION_S`."""
BASE_SPEED_M_S = 0.5
"""Base speed [m/s] (its turning speed is :data:`BASE_TURN_RAD_S`)."""
BASE_TURN_RAD_S = 1.0
TORSO_SPEED_M_S = 0.05
"""Torso lift speed [m/s] (the PR2's is about 0.013-0.05 m/s)."""
MIN_MOTION_S = 0.3
CARTESIAN_STEP_M = 0.02
"""A straight-line tool motion (:func:`cartesian_path`) is solved by IK at most this far
apart [m]..."""
CARTESIAN_JUMP_RAD = 0.3
"""... no joint changing more than this between two of its steps [rad] ..."""
LINE_TOLERANCE_M = 0.01
"""... and the tool kept this close to the line between them, where the servo's straight
line in joint space takes it (checked at the steps' joint-space midpoints) [m]."""
TABLE_GAP_M = 0.005
"""A planned arm configuration keeps every link of the arm this far from the simulated
table (:func:`arm_touches_table`) [m]."""
PATH_LAG_RAD = 0.15
"""A step of a path on the way that ends this far from its goal [rad] was held up."""


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class DynamicWorld:
    """The robot the dynamic skills move: a kinematic world to plan in (the model and IK
    solvers, as the kinematic skills use) and the physics episode in progress.

    A registry's dynamic skills run in the world their ``register`` made
    (:class:`DynamicSkill`); nothing of it is global. ``recorder``, when given, samples body
    poses during every episode (for a replay); :attr:`episodes` counts those started."""

    def __init__(self, *, kinematic: KinematicWorld | None = None,
                 recorder: PoseRecorder | None = None) -> None:
        self.kinematic = kinematic or KinematicWorld()
        self.recorder = recorder
        self.physics: PhysicsWorld | None = None
        self._episode: Blackboard | None = None
        self.episodes = 0

    def start(
        self, bb: Blackboard, scene: SceneSpec, *,
        object_poses: Mapping[str, Sequence[float]] | None = None,
        particles_in: str | None = None,
    ) -> PhysicsWorld:
        """Start the episode of ``bb``: compile ``scene`` (cached per process), then write
        the robot as ``bb`` describes it (:func:`~skillcompose.skills.kinematic_world.read_state`)
        and the objects at ``object_poses``, once; return the running world."""
        state = read_state(bb)
        world = PhysicsWorld(scene, recorder=self.recorder)
        holding = {arm for arm in ARMS if state.held[arm] is not None}
        world.reset(base_pose_world=state.base_pose_world, torso_m=state.torso_height_m,
                    q_arm_rad=dict(state.q_arm_rad), object_poses=object_poses,
                    particles_in=particles_in,
                    gripper_open={arm: arm not in holding for arm in ARMS})
        self.physics, self._episode = world, bb
        self.episodes += 1
        return world

    def current(self, bb: Blackboard, skill: str) -> PhysicsWorld:
        """The running world of ``bb``'s episode; raises when none was started for it."""
        if self.physics is None or self._episode is not bb:
            raise BlackboardKeyError(
                f"skill {skill}: no physics episode was started for this blackboard; run the "
                "FSA with its task on the dynamic backend (--task MODULE --set "
                "backend=dynamic), whose setup starts one")
        return self.physics


class DynamicSkill(KinematicSkill):
    """A skill of the ``dynamic`` backend, ``f(world, bb, rng, *, params...)`` with ``world``
    a :class:`DynamicWorld`; :meth:`in_world` binds it to one."""

    __slots__ = ()

    def __init__(self, spec: SkillSpec, impl: Any, *, world: Any = None) -> None:
        super().__init__(spec, impl, backend=BACKEND, world=world)

    def bind(self, registry: Any = None, backend: str | None = None) -> SkillFn:
        return functools.partial(self.impl, self.world or DynamicWorld())


def in_dynamic_world(skills: Iterable[Skill], world: DynamicWorld) -> list[Skill]:
    """``skills``, the dynamic ones bound to ``world`` (the others need none)."""
    return [s.in_world(world) if isinstance(s, DynamicSkill) else s  # type: ignore[arg-type]
            for s in skills]


# -- execute a plan ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Execution:
    """What executing a plan did: each motion in order (``base``, ``torso``, ``left`` /
    ``right`` arm), the objects each grasp closed on and each release let go of."""

    motions: tuple[tuple[str, Motion], ...]
    grasped: Mapping[Arm, str | None]
    released: Mapping[Arm, str | None]

    @property
    def reached(self) -> bool:
        return all(m.reached for _, m in self.motions)

    def worst(self) -> tuple[str, Motion] | None:
        """The motion furthest from its goal among those that did not reach it."""
        missed = [(name, m) for name, m in self.motions if not m.reached]
        return max(missed, key=lambda item: item[1].error) if missed else None


def _arm_duration(before: Sequence[float], after: Sequence[float]) -> float:
    change = max((abs(_wrap(b - a)) for a, b in zip(before, after, strict=True)), default=0.0)
    return max(MIN_MOTION_S, change / ARM_SPEED_RAD_S)


BaseRoute = Callable[[Blackboard, tuple[float, float, float], tuple[float, float, float]],
                    Sequence[tuple[float, float, float]]]
"""A task's rule for the base's path: ``(bb, start, goal)`` -> the base poses (x [m], y [m],
yaw [rad]) in world to drive through, the goal last (e.g. around the table)."""


def _changed(a: float, b: float) -> bool:
    return abs(_wrap(a - b)) > 1e-4


def _lift_torso(physics: PhysicsWorld, before: RobotState, after: RobotState,
                out: list[tuple[str, Motion]]) -> None:
    """Move the torso to ``after``'s height when the plan changed it from ``before``'s."""
    if abs(after.torso_height_m - before.torso_height_m) > 1e-4:
        duration = max(MIN_MOTION_S,
                       abs(after.torso_height_m - physics.torso_m()) / TORSO_SPEED_M_S)
        out.append(("torso", physics.move_torso(after.torso_height_m, duration)))


def execute(world: DynamicWorld, physics: PhysicsWorld, before: RobotState,
            after: RobotState, *, route: BaseRoute | None = None,
            bb: Blackboard | None = None) -> Execution:
    """Move the simulated robot from where it is to the plan ``after`` (read from the
    blackboard a kinematic skill wrote), ``before`` being the robot it planned from: the base
    first (through ``route``'s poses when given, with ``bb``), then each arm whose joints
    the plan changed, at the higher of the two torso heights (a rising torso rises first, a
    lowering one lowers after the arms: lowered first, it drove a held box into the table);
    then close the fingers of an arm that the plan says now
    holds an object, or open those of an arm it says let go. Holding arms are moved before
    the others' grasps close.

    What moves is what the plan changed from ``before``, not what differs from the
    simulation: a servo that holds a load ends a little off its goal (a wrist holding a box
    sags a few mrad), and commanding the sagged angle again would let it sag further."""
    motions: list[tuple[str, Motion]] = []
    tx, ty, tyaw = after.base_pose_world
    sx, sy, syaw = before.base_pose_world
    if math.hypot(tx - sx, ty - sy) > 1e-4 or _changed(tyaw, syaw):
        start = physics.base_pose()
        legs = list(route(bb, start, (tx, ty, tyaw))) if route is not None and bb is not None \
            else [(tx, ty, tyaw)]
        for k, (lx, ly, lyaw) in enumerate(legs):
            bx, by, byaw = physics.base_pose()
            duration = max(MIN_MOTION_S, math.hypot(lx - bx, ly - by) / BASE_SPEED_M_S,
                           abs(_wrap(lyaw - byaw)) / BASE_TURN_RAD_S)
            last = k == len(legs) - 1
            motion = physics.drive_base(lx, ly, lyaw, duration,
                                        **({} if last else {"settle_s": 0.0}))
            if last:  # a leg on the way is not judged: the servo lags it by design
                motions.append(("base", motion))
    torso: list[tuple[str, Motion]] = []
    lowers = after.torso_height_m < before.torso_height_m - 1e-4
    if not lowers:
        _lift_torso(physics, before, after, torso)
    for arm in ARMS:
        now = physics.arm_q(arm)
        goal = after.q_arm_rad[arm]
        if any(_changed(g, b) for g, b in zip(goal, before.q_arm_rad[arm], strict=True)):
            motions.append((arm, physics.track_arm(arm, goal, _arm_duration(now, goal))))
    if lowers:
        _lift_torso(physics, before, after, torso)
    motions[1 if motions and motions[0][0] == "base" else 0:0] = torso  # base, torso, arms
    grasped: dict[Arm, str | None] = {}
    released: dict[Arm, str | None] = {}
    for arm in ARMS:
        if after.held[arm] is not None and before.held[arm] is None:
            grasped[arm] = physics.close_gripper(arm)
        elif after.held[arm] is None and before.held[arm] is not None:
            physics.open_gripper(arm)
            released[arm] = before.held[arm]
    return Execution(tuple(motions), grasped, released)


# -- straight-line tool motions ---------------------------------------------------------------
def tool_world(world: DynamicWorld, state: RobotState, arm: Arm,
               q_arm_rad: Sequence[float] | None = None) -> pin.SE3:
    """``arm``'s tool frame in world for ``state`` (or its joints at ``q_arm_rad``)."""
    q = state.q_arm_rad[arm] if q_arm_rad is None else q_arm_rad
    return transform_robot_to_world(state.base_pose_world) * \
        world.kinematic.transform_tool_to_robot(arm, state.torso_height_m, q)


def arm_touches_table(physics: PhysicsWorld, state: RobotState, arm: Arm, *,
                      gap_m: float = TABLE_GAP_M, objects: Sequence[str] = (),
                      carried: str | None = None) -> tuple[str, ...]:
    """The links of ``arm`` (shoulder to finger tips) that come within ``gap_m`` of the table
    (or of one of ``objects``, as they stand now) in the physics model itself when the robot
    is at ``state`` (base, torso, that arm's joints; the rest as simulated now): the check
    the kinematic world's sphere model cannot make for the links it does not cover (the
    shoulder's housing), nor for the objects, which its scene leaves out. With ``carried``
    (an object the arm holds), that object moves with the tool as it is held now, and is
    named too when it comes within ``gap_m`` of one of ``objects``. Moves nothing: it poses
    a copy of the simulation's state."""
    compiled = physics.physics
    if compiled.table_body is None and not objects:
        return ()
    model = compiled.model
    cache = _TABLE_CHECK.get(id(model))
    if cache is None or cache[0] is not model:
        bodies: dict[int, list[int]] = {}
        for g in range(model.ngeom):
            bodies.setdefault(int(model.geom_bodyid[g]), []).append(g)
        links = {a: [g for g in compiled.robot_geoms if
                     model.body(int(model.geom_bodyid[g])).name.startswith(f"{a[0]}_")]
                 for a in ARMS}
        cache = (model, mujoco.MjData(model), bodies, links)
        _TABLE_CHECK[id(model)] = cache
    _, data, bodies, links = cache
    others = [g for name in objects for g in bodies.get(compiled.object_body[name], [])]
    table = bodies.get(compiled.table_body, []) if compiled.table_body is not None else []
    data.qpos[:] = physics.data.qpos
    x, y, yaw = state.base_pose_world
    for name, value in (("base_x", x), ("base_y", y), ("base_yaw", yaw),
                        (TORSO_JOINT, state.torso_height_m),
                        *zip(ARM_JOINTS[arm], state.q_arm_rad[arm], strict=True)):
        data.qpos[compiled.qpos[name]] = value
    mujoco.mj_kinematics(model, data)
    near: set[str] = set()
    if carried is not None:
        body, tool = compiled.object_body[carried], compiled.tool_body[arm]
        held_in_tool = _frame(physics.data, tool).actInv(_frame(physics.data, body))
        moved = _frame(data, tool) * held_in_tool
        address = int(model.jnt_qposadr[model.body_jntadr[body]])
        data.qpos[address:address + 3] = moved.translation
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, np.asarray(moved.rotation).reshape(-1))
        data.qpos[address + 3:address + 7] = quat
        mujoco.mj_kinematics(model, data)
        if any(mujoco.mj_geomDistance(model, data, g, t, gap_m, None) < gap_m
               for g in bodies.get(body, []) for t in others):
            near.add(carried)
    for g in links[arm]:
        for t in (*table, *others):
            if mujoco.mj_geomDistance(model, data, g, t, gap_m, None) < gap_m:
                near.add(model.body(int(model.geom_bodyid[g])).name)
                break
    return tuple(sorted(near))


def _frame(data: Any, body: int) -> pin.SE3:
    return pin.SE3(np.array(data.xmat[body]).reshape(3, 3), np.array(data.xpos[body]))


_TABLE_CHECK: dict[int, tuple[Any, Any, dict[int, list[int]], dict[Arm, list[int]]]] = {}


def _off_line(point: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    length2 = float(ab @ ab)
    s = 0.0 if length2 < 1e-12 else float(np.clip((point - a) @ ab / length2, 0.0, 1.0))
    return float(np.linalg.norm(point - (a + s * ab)))


def cartesian_path(world: DynamicWorld, state: RobotState, arm: Arm, goal_world: pin.SE3,
                   scene: Scene, rng: np.random.Generator, *,
                   step_m: float = CARTESIAN_STEP_M,
                   clear: Callable[[RobotState], bool] | None = None,
                   ) -> list[tuple[RobotState, float]]:
    """``arm``'s tool on a straight line from where it is in ``state`` to ``goal_world``
    (torso and base fixed; the position interpolated, the rotation along the geodesic): the
    robots at most ``step_m`` apart along it, each by IK warm-started from the one before
    (no restarts, so that each is the continuation of the last), clear of ``scene``, within
    :data:`CARTESIAN_JUMP_RAD` of the one before in every joint and with the tool within
    :data:`LINE_TOLERANCE_M` of the line half way between them in joint space. Returns
    ``(robot, distance from the start [m])`` in order, the goal last when the whole line
    has such solutions; it stops at the first step without one (empty: not even the first),
    or whose robot ``clear`` (when given) refuses."""
    start = tool_world(world, state, arm)
    a = np.asarray(start.translation, dtype=float)
    b = np.asarray(goal_world.translation, dtype=float)
    length = float(np.linalg.norm(b - a))
    turn = pin.log3(start.rotation.T @ goal_world.rotation)
    n = max(1, math.ceil(max(length / step_m, float(np.linalg.norm(turn)) / 0.15)))
    out: list[tuple[RobotState, float]] = []
    at = state
    for k in range(1, n + 1):
        s = k / n
        target = pin.SE3(start.rotation @ pin.exp3(s * turn), a + s * (b - a))
        answer = reach(world.kinematic, at, arm, target, scene, rng, move_torso=False,
                       diagnose=False, restarts=0)
        if answer.state is None:
            break
        q0, q1 = at.q_arm_rad[arm], answer.state.q_arm_rad[arm]
        if max(abs(_wrap(x - y)) for x, y in zip(q1, q0, strict=True)) > CARTESIAN_JUMP_RAD:
            break
        mid = [y + 0.5 * _wrap(x - y) for x, y in zip(q1, q0, strict=True)]
        if _off_line(np.asarray(tool_world(world, at, arm, mid).translation), a, b) \
                > LINE_TOLERANCE_M:
            break
        at = RobotState(answer.state.base_pose_world, answer.state.torso_height_m,
                        answer.state.q_arm_rad, state.held, state.arm_in_use)
        if clear is not None and not clear(at):
            break
        out.append((at, s * length))
    return out


def follow_path(physics: PhysicsWorld, arm: Arm, path: Sequence[RobotState],
                speed_m_s: float, step_m: float = CARTESIAN_STEP_M) -> list[Motion]:
    """Drive ``arm`` through ``path``'s joints in order (a :func:`cartesian_path`), each step
    at ``speed_m_s`` of the tool without stopping to settle, the last one settled; returns
    the motions to judge: the last, and any step on the way that ended more than
    :data:`PATH_LAG_RAD` off its goal (held up, not merely lagging the moving goal)."""
    motions: list[Motion] = []
    for k, state in enumerate(path):
        last = k == len(path) - 1
        now = physics.arm_q(arm)
        duration = max(step_m / speed_m_s, 0.5 * _arm_duration(now, state.q_arm_rad[arm]))
        motion = physics.track_arm(arm, state.q_arm_rad[arm], duration,
                                   **({} if last else {"settle_s": 0.0}))
        if last or motion.error > PATH_LAG_RAD:
            motions.append(motion)
    return motions


# -- the blackboard from the simulation ------------------------------------------------------
ObjectKeys = Callable[[PhysicsWorld, Blackboard], Mapping[str, Any]]
"""A task's rule for its world keys from the simulation (e.g. ``object_position_world``,
``water``): key -> value, written when the key is on the blackboard already."""


def sync(physics: PhysicsWorld, bb: Blackboard, *, planned: RobotState,
         world_keys: ObjectKeys | None = None) -> RobotState:
    """Write the robot as simulated (base, torso, joints, tool poses; what each gripper
    holds by contact, among the objects the plan says it holds or grasps) and ``world_keys``'
    values; return the robot written."""
    base = physics.base_pose()
    q = {arm: physics.arm_q(arm) for arm in ARMS}
    held: dict[Arm, str | None] = {}
    for arm in ARMS:
        touching = physics.held_object(arm)
        held[arm] = touching if touching is not None and touching == planned.held[arm] else None
    bb[BASE_POSE_KEY] = base
    bb[TORSO_KEY] = physics.torso_m()
    for arm in ARMS:
        bb[Q_KEYS[arm]] = _wrapped(physics, arm, q[arm])
        bb[TOOL_KEYS[arm]] = physics.tool_pose(arm)
        bb[HELD_KEYS[arm]] = held[arm]
    bb[ARM_IN_USE_KEY] = planned.arm_in_use
    if planned.arm_in_use is not None and "gripper_position_world" in bb:
        tool = physics.tool_pose(planned.arm_in_use)
        bb["gripper_position_world"] = (tool[0], tool[1], tool[2])
    if world_keys is not None:
        for key, value in world_keys(physics, bb).items():
            if key in bb:
                bb[key] = value
    return RobotState(base, bb[TORSO_KEY], {arm: bb[Q_KEYS[arm]] for arm in ARMS}, held,
                      planned.arm_in_use)


def _wrapped(physics: PhysicsWorld, arm: Arm, q: Sequence[float]) -> tuple[float, ...]:
    """``arm``'s joints as simulated, the continuous ones (no limits) wrapped to [-pi, pi]:
    a limited joint whose range is wider than that (the upper arm roll's, -0.8 to 3.9 rad)
    keeps its angle, which wrapped would lie outside its limits, where every IK
    warm-started from it failed or jumped to another branch."""
    model = physics.model
    return tuple(_wrap(v) if not model.jnt_limited[model.joint(name).id] else float(v)
                 for name, v in zip(ARM_JOINTS[arm], q, strict=True))


# -- judge -------------------------------------------------------------------------------------
def judge_motion(physics: PhysicsWorld, bb: Blackboard, skill: str, planned: RobotState,
                 done: Execution, now: RobotState) -> str | None:
    """Why the executed plan failed, written as ``last_failure_reason`` / ``_detail``; None
    when it did what was planned. In order: a grasp that closed on nothing or on another
    object (``missed``), a held object lost (``dropped``), a motion that did not reach its
    goal (``blocked``), the robot touching the table at the end (``hit_table``)."""
    for arm, got in done.grasped.items():
        if got != planned.held[arm]:
            fail(bb, "missed", f"{skill}: the {arm} fingers closed on "
                 f"{'nothing' if got is None else repr(got)}, not {planned.held[arm]!r}")
            return "missed"
    for arm in ARMS:
        if planned.held[arm] is not None and now.held[arm] is None:
            fail(bb, "dropped", f"{skill}: {planned.held[arm]!r} left the {arm} gripper")
            return "dropped"
    worst = done.worst()
    if worst is not None:
        name, motion = worst
        fail(bb, "blocked", f"{skill}: the {name} motion stopped {motion.error:.3f} from its "
             f"goal (touching: {', '.join(f'{a}-{b}' for a, b in motion.contacts) or 'nothing'})")
        return "blocked"
    table = physics.robot_contacts("table")
    if table:
        fail(bb, "hit_table", f"{skill}: {', '.join(link for link, _ in table)} touch the "
             "table")
        return "hit_table"
    return None


Judge = Callable[[PhysicsWorld, Blackboard, np.random.Generator, Mapping[str, Any]], str | None]
"""A twin's own verdict after the motion's: an outcome to return instead, or None."""


def _let_go(physics: PhysicsWorld, bb: Blackboard, done: Execution, planned: RobotState,
            before: RobotState, world_keys: ObjectKeys | None) -> None:
    """After a failure: open the fingers that this skill closed on something, and write the
    blackboard again (the robot holding what it held before)."""
    closed = [arm for arm, got in done.grasped.items() if got is not None]
    if not closed:
        return
    for arm in closed:
        physics.open_gripper(arm)
    held = dict(planned.held)
    for arm in closed:
        held[arm] = before.held[arm]
    sync(physics, bb, planned=dataclasses.replace(planned, held=held), world_keys=world_keys)


Via = Callable[[DynamicWorld, Blackboard, np.random.Generator, RobotState, RobotState],
              Sequence[RobotState]]
"""A twin's waypoints: ``(world, bb, rng, before, planned)`` -> the robots to pass through,
in order, on the way from ``before`` to the plan (e.g. a pre-grasp pose 9 cm back along the
approach); each holds what ``before`` holds."""


Recover = Callable[[DynamicWorld, Blackboard, np.random.Generator, RobotState, RobotState],
                   None]
"""A twin's way out after its motion failed: ``(world, bb, rng, before, planned)``, called
once the failure is written (and fingers closed on something opened again); it may move the
simulated robot (e.g. back the gripper out along its approach), after which the blackboard
is written again from the simulation (the robot holding, at most, what it held before)."""


def dynamic_twin(
    kinematic: KinematicSkill, *, world_keys: ObjectKeys | None = None,
    judge: Judge | None = None, prepare: Judge | None = None, via: Via | None = None,
    route: BaseRoute | None = None, settle_s: float = 0.0, writes: Iterable[str] = (),
    recover: Recover | None = None,
) -> DynamicSkill:
    """The dynamic twin of ``kinematic`` (see the module docstring): plan with it, execute,
    write the blackboard from the simulation (with ``world_keys``), judge the motion
    (:func:`judge_motion`), then ``judge`` (a task's own rule, e.g. "the object moved 5 cm
    and stands"). ``prepare`` runs before the plan and may return an outcome that ends the
    skill there (e.g. a pre-grasp approach that failed). ``via`` gives waypoints executed
    before the plan (aids on the way: only the plan's own motions are judged; a skill that
    fails after its fingers closed on something opens them again, so that a failed grasp
    leaves nothing held, as its kinematic twin does), ``route`` the base's path
    (:func:`execute`), and ``settle_s`` the simulated time [s] that passes after the motion
    before the blackboard is written (e.g. 2 s for a released object to come to rest).
    ``writes`` names world keys the twin writes beyond its kinematic twin's declaration
    (e.g. ``holding_jug`` after a drop); ``world_keys``' values for keys the twin does not
    declare are left alone, never written against the blackboard's access check.
    ``recover``, when given, runs after a failed motion (e.g. a missed grasp backs out), the
    failure's reason kept."""
    spec = kinematic.spec
    if writes:
        spec = dataclasses.replace(spec, writes=spec.writes | frozenset(writes))
    name = spec.name
    if world_keys is not None:
        world_keys = _declared(world_keys, spec.writes)
    failure = "failure" if "failure" in spec.outcomes else None

    def run(world: DynamicWorld, bb: Blackboard, rng: np.random.Generator,
            **params: Any) -> str:
        physics = world.current(bb, name)
        if prepare is not None and (early := prepare(physics, bb, rng, params)) is not None:
            return early
        before = read_state(bb)
        outcome = kinematic.impl(world.kinematic, bb, rng, **params)
        if outcome != "success":
            return str(outcome)
        planned = read_state(bb)
        waypoints = via(world, bb, rng, before, planned) if via is not None else ()
        planned = read_state(bb)  # a via may refine the plan (the same goal, another way)
        at = before
        for waypoint in waypoints:
            execute(world, physics, at, waypoint, route=route, bb=bb)  # aids, not judged
            at = waypoint
        done = execute(world, physics, at, planned, route=route, bb=bb)
        if settle_s > 0.0:
            physics.step(settle_s)
        now = sync(physics, bb, planned=planned, world_keys=world_keys)
        why = judge_motion(physics, bb, name, planned, done, now)
        if why is None and judge is not None:
            verdict = judge(physics, bb, rng, params)
            if verdict is not None:
                return verdict
        if why is not None:
            _let_go(physics, bb, done, planned, before, world_keys)
            if recover is not None:
                recover(world, bb, rng, before, planned)
                sync(physics, bb, planned=dataclasses.replace(planned, held=dict(before.held)),
                     world_keys=world_keys)
            return failure or str(outcome)
        return str(outcome)

    run.__name__ = run.__qualname__ = f"{name}_dynamic"
    run.__doc__ = (f"The dynamic twin of {name}: its kinematic plan executed and judged by "
                   f"physics.\n\n{kinematic.spec.doc or ''}")
    return DynamicSkill(spec, run)  # the kinematic twin's declaration (and ``writes``)


def _declared(world_keys: ObjectKeys, writes: frozenset[str]) -> ObjectKeys:
    """``world_keys`` restricted to the keys a twin declares it writes."""

    def keys(physics: PhysicsWorld, bb: Blackboard) -> Mapping[str, Any]:
        return {k: v for k, v in world_keys(physics, bb).items() if k in writes}

    return keys


def world_of(registry: Any) -> DynamicWorld | None:
    """The :class:`DynamicWorld` a registry's dynamic skills run in (the one a task's
    ``register`` made), or None when it has no bound dynamic skill."""
    for name in registry.names():
        if BACKEND in registry.backends(name):
            impl = registry.resolve(name, BACKEND)
            if isinstance(impl, DynamicSkill) and isinstance(impl.world, DynamicWorld):
                return impl.world
    return None
