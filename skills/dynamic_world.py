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

import functools
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from skillcompose import Blackboard, Skill, SkillSpec
from skillcompose.errors import BlackboardKeyError
from skillcompose.robots.model import ARMS, Arm
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
    read_state,
)

__all__ = [
    "BACKEND",
    "DYNAMIC_FAILURE_REASONS",
    "DynamicSkill",
    "DynamicWorld",
    "Execution",
    "dynamic_twin",
    "execute",
    "in_dynamic_world",
    "judge_motion",
    "sync",
]

BACKEND = "dynamic"

DYNAMIC_FAILURE_REASONS = (
    "blocked",  # a motion did not reach its goal within tolerance (something was in the way)
    "missed",  # a grasp closed the fingers on nothing
    "dropped",  # an object left the gripper that held it
    "hit_table",  # the robot ends a motion touching the table
    "toppled",  # an object that must stand upright does not
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


def execute(world: DynamicWorld, physics: PhysicsWorld, before: RobotState,
            after: RobotState) -> Execution:
    """Move the simulated robot from where it is to the plan ``after`` (read from the
    blackboard a kinematic skill wrote), ``before`` being the robot it planned from: the base
    first, then the torso, then each arm whose joints the plan changed; then close the
    fingers of an arm that the plan says now holds an object, or open those of an arm it
    says let go. Holding arms are moved before the others' grasps close."""
    motions: list[tuple[str, Motion]] = []
    bx, by, byaw = physics.base_pose()
    tx, ty, tyaw = after.base_pose_world
    if math.hypot(tx - bx, ty - by) > 1e-4 or abs(_wrap(tyaw - byaw)) > 1e-4:
        duration = max(MIN_MOTION_S, math.hypot(tx - bx, ty - by) / BASE_SPEED_M_S,
                       abs(_wrap(tyaw - byaw)) / BASE_TURN_RAD_S)
        motions.append(("base", physics.drive_base(tx, ty, tyaw, duration)))
    torso = physics.torso_m()
    if abs(after.torso_height_m - torso) > 1e-4:
        duration = max(MIN_MOTION_S, abs(after.torso_height_m - torso) / TORSO_SPEED_M_S)
        motions.append(("torso", physics.move_torso(after.torso_height_m, duration)))
    for arm in ARMS:
        now = physics.arm_q(arm)
        goal = after.q_arm_rad[arm]
        if any(abs(_wrap(g - n)) > 1e-4 for g, n in zip(goal, now, strict=True)):
            motions.append((arm, physics.track_arm(arm, goal, _arm_duration(now, goal))))
    grasped: dict[Arm, str | None] = {}
    released: dict[Arm, str | None] = {}
    for arm in ARMS:
        if after.held[arm] is not None and before.held[arm] is None:
            grasped[arm] = physics.close_gripper(arm)
        elif after.held[arm] is None and before.held[arm] is not None:
            physics.open_gripper(arm)
            released[arm] = before.held[arm]
    return Execution(tuple(motions), grasped, released)


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
        bb[Q_KEYS[arm]] = tuple(_wrap(v) for v in q[arm])
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


def dynamic_twin(
    kinematic: KinematicSkill, *, world_keys: ObjectKeys | None = None,
    judge: Judge | None = None, prepare: Judge | None = None,
) -> DynamicSkill:
    """The dynamic twin of ``kinematic`` (see the module docstring): plan with it, execute,
    write the blackboard from the simulation (with ``world_keys``), judge the motion
    (:func:`judge_motion`), then ``judge`` (a task's own rule, e.g. "the object moved 5 cm
    and stands"). ``prepare`` runs before the plan and may return an outcome that ends the
    skill there (e.g. a pre-grasp approach that failed)."""
    spec = kinematic.spec
    name = spec.name
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
        done = execute(world, physics, before, planned)
        now = sync(physics, bb, planned=planned, world_keys=world_keys)
        why = judge_motion(physics, bb, name, planned, done, now)
        if why is None and judge is not None:
            verdict = judge(physics, bb, rng, params)
            if verdict is not None:
                return verdict
        if why is not None:
            return failure or str(outcome)
        return str(outcome)

    run.__name__ = run.__qualname__ = f"{name}_dynamic"
    run.__doc__ = (f"The dynamic twin of {name}: its kinematic plan executed and judged by "
                   f"physics.\n\n{kinematic.spec.doc or ''}")
    return DynamicSkill(spec, run)  # the declaration is the kinematic twin's, exactly
