"""The PR2 in a MuJoCo world: the running world the dynamic skills move in.

Units: metres [m], radians [rad], seconds [s] of *simulated* time. Frames: the world is the
floor frame of :mod:`skillcompose.robots.model` (z up, the base on the floor facing +x at
yaw 0); a pose ``(x, y, z, roll, pitch, yaw)`` is a position [m] and the rotation
``Rz(yaw) Ry(pitch) Rx(roll)`` [rad], as the kinematic skills' blackboard keys.

A :class:`PhysicsWorld` holds one ``MjData`` on a model shared per scene
(:func:`~skillcompose.robots.physics_model.compile_scene`). Poses are written only by
:meth:`PhysicsWorld.reset`; after it only the simulation moves things: the arms, torso and
base follow their position servos through a trajectory (:meth:`~PhysicsWorld.track_arm`,
:meth:`~PhysicsWorld.move_torso`, :meth:`~PhysicsWorld.drive_base`), the fingers close on
what is between them (:meth:`~PhysicsWorld.close_gripper`), and objects fall, slide, topple
and spill. Each motion returns what happened, measured (:class:`Motion`); the queries
(:meth:`~PhysicsWorld.held_object`, :meth:`~PhysicsWorld.object_pose`,
:meth:`~PhysicsWorld.upright`, :meth:`~PhysicsWorld.particles_in`,
:meth:`~PhysicsWorld.robot_contacts`) turn the physics into a skill's outcome.

Control: the servo targets are updated every :data:`CONTROL_PERIOD_S` (10 ms, five physics
steps) along a minimum-jerk profile from where the joints are to the goal, then held while
the motion settles. Determinism: nothing reads a clock or a global random state; the same
scene and calls give bit-identical results on one machine and MuJoCo build.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import mujoco  # type: ignore[import-untyped]  # no stubs or py.typed
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from skillcompose.robots.errors import InvalidConfiguration
from skillcompose.robots.model import (
    ARM_JOINTS,
    ARMS,
    TORSO_JOINT,
    TUCKED_ARM_RAD,
    Arm,
    FloatArray,
    RobotPose,
)
from skillcompose.robots.physics_model import (
    BASE_JOINTS,
    GRIPPER_JOINTS,
    GRIPPER_OPEN_RAD,
    PhysicsModel,
    SceneSpec,
    compile_scene,
)

__all__ = [
    "CONTROL_PERIOD_S",
    "Motion",
    "PhysicsWorld",
    "PoseRecorder",
    "robot_pose_at",
]

Pose6 = tuple[float, float, float, float, float, float]

CONTROL_PERIOD_S = 0.01
"""How often the servo targets move along a trajectory [s]."""
ARM_TOLERANCE_RAD = 0.02
"""A motion reached its goal when every joint ends this close to it [rad] (torso: 5 mm)."""
SETTLE_S = 0.4
"""Simulated time a motion keeps the goal after its trajectory, to settle [s]."""
_GRIPPER_CLOSED_RAD = -0.05  # below the closed stop: the servo keeps squeezing what it holds
_UPRIGHT_RAD = 0.35  # an object is upright while its z axis is within 20 deg of world z


@dataclass(frozen=True)
class Motion:
    """What a servo motion did.

    Attributes:
        reached: every joint ended within tolerance of its goal.
        error: largest final joint error [rad, or m for the torso and base position].
        duration_s: simulated time it took, trajectory and settling [s].
        contacts: ``(robot body, other body)`` pairs touching at the end (see
            :meth:`PhysicsWorld.robot_contacts`).
    """

    reached: bool
    error: float
    duration_s: float
    contacts: tuple[tuple[str, str], ...] = ()


@dataclass
class PoseRecorder:
    """Body poses collected every ``every_s`` of simulated time, for a replay.

    Attributes:
        every_s: sampling period [s], a multiple of :data:`CONTROL_PERIOD_S`.
        bodies: names of the bodies to record; empty: the objects, the particles, the base
            and both tool frames.
        times_s: time of each sample [s].
        positions / quaternions: per sample, one row per body (x, y, z [m]; w, x, y, z).
        robot: per sample, the robot's configuration (:class:`RobotPose`: base, torso, arms),
            from which a replay draws the PR2 itself.
        objects: the scene's objects in the order of the first rows of ``positions``.
    """

    every_s: float = 0.05
    bodies: tuple[str, ...] = ()
    times_s: list[float] = field(default_factory=list)
    positions: list[FloatArray] = field(default_factory=list)
    quaternions: list[FloatArray] = field(default_factory=list)
    robot: list[RobotPose] = field(default_factory=list)
    objects: tuple[str, ...] = ()
    _ids: NDArray[np.intp] | None = field(default=None, repr=False)
    _physics: PhysicsModel | None = field(default=None, repr=False)
    _next_s: float = field(default=0.0, repr=False)

    def _bind(self, physics: PhysicsModel) -> None:
        names = self.bodies or (
            *physics.object_body, *(f"particle_{i}" for i in range(len(physics.particle_body))),
            "base_footprint", "l_gripper_tool_frame", "r_gripper_tool_frame")
        self.bodies = tuple(names)
        ids = [mujoco.mj_name2id(physics.model, mujoco.mjtObj.mjOBJ_BODY, n) for n in names]
        missing = [n for n, i in zip(names, ids, strict=True) if i < 0]
        if missing:
            raise InvalidConfiguration(f"recorder: no bodies {missing} in the model")
        self._ids = np.array(ids, dtype=np.intp)
        self._physics = physics
        self.objects = tuple(physics.object_body)
        self.times_s.clear()
        self.positions.clear()
        self.quaternions.clear()
        self.robot.clear()
        self._next_s = 0.0

    def _sample(self, data: mujoco.MjData) -> None:
        if self._ids is None or data.time + 1e-9 < self._next_s:
            return
        self.times_s.append(float(data.time))
        self.positions.append(np.array(data.xpos[self._ids]))
        self.quaternions.append(np.array(data.xquat[self._ids]))
        if self._physics is not None:
            self.robot.append(robot_pose_at(self._physics, data.qpos))
        self._next_s = data.time + self.every_s


def robot_pose_at(physics: PhysicsModel, qpos: FloatArray) -> RobotPose:
    """The PR2's configuration in ``qpos`` of a model of ``physics`` (base yaw wrapped)."""
    index = physics.qpos
    x, y, yaw = (float(qpos[index[n]]) for n in BASE_JOINTS)
    arms = {arm: tuple(float(qpos[index[n]]) for n in ARM_JOINTS[arm]) for arm in ARMS}
    return RobotPose((x, y, _wrap(yaw)), float(qpos[index[TORSO_JOINT]]), arms)


class PhysicsWorld:
    """The PR2 and its room, simulated (see the module docstring).

    Args:
        scene: what to compile (cached per scene per process); the default is the table
            alone.
        recorder: optional :class:`PoseRecorder` sampled as the world steps.
    """

    def __init__(self, scene: SceneSpec | None = None, *,
                 recorder: PoseRecorder | None = None) -> None:
        self.physics = compile_scene(scene if scene is not None else SceneSpec())
        self.model = self.physics.model
        self.data = mujoco.MjData(self.model)
        self.recorder = recorder
        self._substeps = max(1, round(CONTROL_PERIOD_S / self.model.opt.timestep))
        self._goal: dict[str, float] = {}
        self.reset()

    # -- episode start ---------------------------------------------------------------------
    def reset(
        self,
        *,
        base_pose_world: Sequence[float] = (0.0, 0.0, 0.0),
        torso_m: float = 0.0,
        q_arm_rad: Mapping[Arm, Sequence[float] | FloatArray] | None = None,
        object_poses: Mapping[str, Sequence[float] | FloatArray] | None = None,
        particles_in: str | None = None,
        gripper_open: bool | Mapping[Arm, bool] = True,
    ) -> None:
        """Start an episode: every pose written once, velocities zero, time 0.

        Args:
            base_pose_world: base (x [m], y [m], yaw [rad]) in world.
            torso_m: torso lift [m], in [0, 0.31].
            q_arm_rad: 7 joint angles per arm [rad]; arms not given are tucked.
            object_poses: per object, ``(x, y, z)`` [m] (upright) or ``(x, y, z, roll,
                pitch, yaw)``; the object's centre. Objects not given are parked under
                the floor (out of the way, asleep).
            particles_in: a cup object to fill with the particles (stacked on a grid in
                its inside), else the particles are parked.
            gripper_open: open (True) or closed, for both grippers or per arm.
        """
        physics, model, data = self.physics, self.model, self.data
        mujoco.mj_resetData(model, data)
        qpos = data.qpos
        base = _finite(base_pose_world, 3, "base_pose_world")
        for name, value in zip(BASE_JOINTS, base, strict=True):
            qpos[physics.qpos[name]] = value
        if not 0.0 <= torso_m <= 0.31:
            raise InvalidConfiguration(f"torso_m must be in [0, 0.31] m, got {torso_m}")
        qpos[physics.qpos[TORSO_JOINT]] = torso_m
        arms: dict[Arm, Sequence[float] | FloatArray] = dict(TUCKED_ARM_RAD)
        arms.update(q_arm_rad or {})
        for arm in ARMS:
            q = _finite(arms[arm], 7, f"q_arm_rad[{arm!r}]")
            for name, value in zip(ARM_JOINTS[arm], q, strict=True):
                qpos[physics.qpos[name]] = value
        opened = {arm: gripper_open if isinstance(gripper_open, bool) else
                  bool(gripper_open.get(arm, True)) for arm in ARMS}
        for arm in ARMS:
            self._set_fingers(arm, GRIPPER_OPEN_RAD if opened[arm] else 0.0)
        poses = dict(object_poses or {})
        unknown = sorted(set(poses) - set(physics.object_body))
        if unknown:
            raise InvalidConfiguration(f"object_poses: no objects {unknown} in the scene; "
                                       f"objects: {sorted(physics.object_body)}")
        for index, name in enumerate(physics.object_body):
            pose = poses.get(name)
            if pose is None:
                self._place_free(physics.object_body[name], (10.0 + index, 10.0, -1.0))
            else:
                self._place_free(physics.object_body[name], _finite(pose, len(pose), name))
        self._place_particles(particles_in)
        self._goal = {name: float(qpos[physics.qpos[name]]) for name in physics.actuator}
        for arm in ARMS:
            self._goal[GRIPPER_JOINTS[arm]] = GRIPPER_OPEN_RAD if opened[arm] else \
                _GRIPPER_CLOSED_RAD
        self._apply_goal()
        mujoco.mj_forward(model, data)
        if self.recorder is not None:
            self.recorder._bind(physics)
            self.recorder._sample(data)

    def _set_fingers(self, arm: Arm, angle_rad: float) -> None:
        prefix = f"{arm[0]}_gripper_"
        for joint in ("l_finger_joint", "r_finger_joint", "l_finger_tip_joint",
                      "r_finger_tip_joint", "l_parallel_root_joint"):
            self.data.qpos[self.physics.qpos[prefix + joint]] = angle_rad
        self.data.qpos[self.physics.qpos[prefix + "r_parallel_root_joint"]] = -angle_rad

    def _place_free(self, body: int, pose: Sequence[float] | FloatArray) -> None:
        if len(pose) not in (3, 6):
            raise InvalidConfiguration(f"a pose is (x, y, z) or (x, y, z, roll, pitch, yaw), "
                                       f"got {len(pose)} values")
        joint = int(self.model.body_jntadr[body])
        address = int(self.model.jnt_qposadr[joint])
        self.data.qpos[address : address + 3] = pose[:3]
        roll, pitch, yaw = (pose[3], pose[4], pose[5]) if len(pose) == 6 else (0.0, 0.0, 0.0)
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, _rpy_matrix(roll, pitch, yaw).reshape(-1))
        self.data.qpos[address + 3 : address + 7] = quat

    def _place_particles(self, container: str | None) -> None:
        bodies = self.physics.particle_body
        if not bodies:
            return
        radius = self.physics.scene.particle_radius_m
        if container is None:
            for index, body in enumerate(bodies):
                self._place_particle(body, (-10.0 - 0.1 * index, 10.0, -1.0))
            return
        obj = self.physics.scene.object(container)
        if obj.shape != "cup":
            raise InvalidConfiguration(f"particles_in: {container!r} is a {obj.shape}, "
                                       "not a cup")
        hx, hy, hz = obj.inner_half_extents_m
        spacing = 2.05 * radius
        nx, ny = max(1, int(2 * (hx - radius) / spacing) + 1), max(
            1, int(2 * (hy - radius) / spacing) + 1)
        address = int(self.model.jnt_qposadr[self.model.body_jntadr[
            self.physics.object_body[container]]])
        centre = np.array(self.data.qpos[address : address + 3])
        flat = np.empty(9)
        mujoco.mju_quat2Mat(flat, self.data.qpos[address + 3 : address + 7])
        rotation = flat.reshape(3, 3)
        floor_z = -hz + obj.wall_m / 2 + radius
        for index, body in enumerate(bodies):
            layer, cell = divmod(index, nx * ny)
            row, col = divmod(cell, nx)
            local = np.array([
                -(nx - 1) * spacing / 2 + col * spacing + (0.3 * radius if layer % 2 else 0.0),
                -(ny - 1) * spacing / 2 + row * spacing,
                floor_z + layer * spacing,
            ])
            self._place_particle(body, centre + rotation @ local)

    def _place_particle(self, body: int, position: Sequence[float] | FloatArray) -> None:
        address = int(self.model.jnt_qposadr[self.model.body_jntadr[body]])
        self.data.qpos[address : address + 3] = position

    # -- stepping ----------------------------------------------------------------------------
    def _apply_goal(self) -> None:
        ctrl = self.data.ctrl
        for name, value in self._goal.items():
            ctrl[self.physics.actuator[name]] = value

    def _advance(self, periods: int) -> None:
        for _ in range(periods):
            mujoco.mj_step(self.model, self.data, nstep=self._substeps)
            if self.recorder is not None:
                self.recorder._sample(self.data)

    def step(self, seconds: float) -> None:
        """Let ``seconds`` of simulated time pass with the servo goals held."""
        if not (math.isfinite(seconds) and seconds >= 0):
            raise InvalidConfiguration(f"step: seconds must be >= 0, got {seconds}")
        self._advance(round(seconds / CONTROL_PERIOD_S))

    @property
    def time_s(self) -> float:
        """Simulated time since :meth:`reset` [s]."""
        return float(self.data.time)

    def _follow(self, goals: Mapping[str, float], duration_s: float, settle_s: float,
                tolerance: Mapping[str, float]) -> Motion:
        """Move the servo goals of ``goals``' joints along a minimum-jerk profile from the
        current goals to ``goals`` in ``duration_s``, hold them ``settle_s``, and measure."""
        if not (math.isfinite(duration_s) and duration_s >= 0 and math.isfinite(settle_s)
                and settle_s >= 0):
            raise InvalidConfiguration(f"duration_s and settle_s must be >= 0, got "
                                       f"{duration_s}, {settle_s}")
        start = {name: self._goal[name] for name in goals}
        periods = max(1, round(duration_s / CONTROL_PERIOD_S))
        began = self.time_s
        for k in range(1, periods + 1):
            s = k / periods
            blend = s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
            for name, goal in goals.items():
                self._goal[name] = start[name] + blend * (goal - start[name])
            self._apply_goal()
            self._advance(1)
        self._advance(round(settle_s / CONTROL_PERIOD_S))
        qpos = self.data.qpos
        errors = {name: abs(float(qpos[self.physics.qpos[name]]) - goal)
                  for name, goal in goals.items()}
        for name in errors:
            if name in ("base_yaw", *ARM_JOINTS["left"], *ARM_JOINTS["right"]):
                errors[name] = abs(_wrap(float(qpos[self.physics.qpos[name]]) - goals[name]))
        worst = max(errors.values(), default=0.0)
        reached = all(errors[n] <= tolerance.get(n, ARM_TOLERANCE_RAD) for n in errors)
        return Motion(reached, worst, self.time_s - began, self.robot_contacts())

    # -- motions -----------------------------------------------------------------------------
    def track_arm(self, arm: Arm, q_target_rad: Sequence[float] | FloatArray, duration_s: float, *,
                  settle_s: float = SETTLE_S, tolerance_rad: float = ARM_TOLERANCE_RAD
                  ) -> Motion:
        """Move ``arm``'s 7 joints to ``q_target_rad`` [rad] in ``duration_s`` under control.

        Continuous joints (forearm and wrist roll) turn the short way round.
        """
        q = _finite(q_target_rad, 7, "q_target_rad")
        goals = {}
        for name, value in zip(ARM_JOINTS[_arm(arm)], q, strict=True):
            low, high = self.model.jnt_range[self.model.joint(name).id]
            if self.model.jnt_limited[self.model.joint(name).id]:
                value = float(np.clip(value, low, high))
            else:  # continuous: the short way from the current goal
                value = self._goal[name] + _wrap(value - self._goal[name])
            goals[name] = float(value)
        return self._follow(goals, duration_s, settle_s, dict.fromkeys(goals, tolerance_rad))

    def move_torso(self, height_m: float, duration_s: float, *,
                   settle_s: float = SETTLE_S) -> Motion:
        """Lift or lower the torso to ``height_m`` [m] (within [0, 0.31])."""
        if not (math.isfinite(height_m) and 0.0 <= height_m <= 0.31):
            raise InvalidConfiguration(f"torso height must be in [0, 0.31] m, got {height_m}")
        return self._follow({TORSO_JOINT: height_m}, duration_s, settle_s,
                            {TORSO_JOINT: 0.005})

    def drive_base(self, x_m: float, y_m: float, yaw_rad: float, duration_s: float, *,
                   settle_s: float = SETTLE_S) -> Motion:
        """Drive the base to ``(x, y, yaw)`` in world (yaw turns the short way)."""
        goal = _finite((x_m, y_m, yaw_rad), 3, "base goal")
        yaw = self._goal["base_yaw"] + _wrap(goal[2] - self._goal["base_yaw"])
        return self._follow({"base_x": goal[0], "base_y": goal[1], "base_yaw": yaw},
                            duration_s, settle_s,
                            {"base_x": 0.01, "base_y": 0.01, "base_yaw": 0.02})

    def close_gripper(self, arm: Arm, duration_s: float = 1.0, *,
                      settle_s: float = 0.3) -> str | None:
        """Close ``arm``'s fingers in ``duration_s`` (the servo's goal swept to past closed,
        so that they squeeze what they meet with its bounded torque) and return the object
        they hold, or None."""
        name = GRIPPER_JOINTS[_arm(arm)]
        self._follow({name: _GRIPPER_CLOSED_RAD}, duration_s, settle_s, {})
        return self.held_object(arm)

    def open_gripper(self, arm: Arm, duration_s: float = 0.6, *,
                     settle_s: float = 0.3) -> str | None:
        """Open ``arm``'s fingers fully; what they still hold afterwards (None, normally)."""
        name = GRIPPER_JOINTS[_arm(arm)]
        self._goal[name] = max(self._goal[name], self.gripper_opening_rad(arm) - 0.05)
        self._follow({name: GRIPPER_OPEN_RAD}, duration_s, settle_s, {})
        return self.held_object(arm)

    # -- queries -----------------------------------------------------------------------------
    def held_object(self, arm: Arm) -> str | None:
        """The object both fingers of ``arm`` touch (the one held), or None."""
        left, right = self.physics.finger_geoms[_arm(arm)]
        touched: list[set[int]] = [set(), set()]
        data, model = self.data, self.model
        for i in range(data.ncon):
            contact = data.contact[i]
            for mine, other in ((contact.geom1, contact.geom2), (contact.geom2, contact.geom1)):
                body = int(model.geom_bodyid[other])
                if mine in left:
                    touched[0].add(body)
                elif mine in right:
                    touched[1].add(body)
        both = touched[0] & touched[1]
        for name, body in self.physics.object_body.items():
            if body in both:
                return name
        return None

    def gripper_opening_rad(self, arm: Arm) -> float:
        """Angle of ``arm``'s ``*_gripper_l_finger_joint`` [rad]: 0 closed, 0.548 open."""
        return float(self.data.qpos[self.physics.qpos[GRIPPER_JOINTS[_arm(arm)]]])

    def object_transform(self, name: str) -> pin.SE3:
        """Placement of object ``name`` (its centre) in world."""
        body = self._object(name)
        return pin.SE3(np.array(self.data.xmat[body]).reshape(3, 3),
                       np.array(self.data.xpos[body]))

    def object_pose(self, name: str) -> Pose6:
        """Object ``name`` as (x, y, z [m], roll, pitch, yaw [rad]) in world."""
        return _pose6(self.object_transform(name))

    def upright(self, name: str, tolerance_rad: float = _UPRIGHT_RAD) -> bool:
        """Whether object ``name``'s z axis is within ``tolerance_rad`` of world z."""
        z_axis_z = float(self.data.xmat[self._object(name)][8])
        return math.acos(max(-1.0, min(1.0, z_axis_z))) <= tolerance_rad

    def tool_transform(self, arm: Arm) -> pin.SE3:
        """Placement of ``arm``'s tool frame (``*_gripper_tool_frame``) in world."""
        body = self.physics.tool_body[_arm(arm)]
        return pin.SE3(np.array(self.data.xmat[body]).reshape(3, 3),
                       np.array(self.data.xpos[body]))

    def tool_pose(self, arm: Arm) -> Pose6:
        """``arm``'s tool frame as (x, y, z [m], roll, pitch, yaw [rad]) in world."""
        return _pose6(self.tool_transform(arm))

    def arm_q(self, arm: Arm) -> tuple[float, ...]:
        """``arm``'s 7 joint angles [rad] (continuous joints as simulated, unwrapped)."""
        return tuple(float(self.data.qpos[self.physics.qpos[n]]) for n in ARM_JOINTS[_arm(arm)])

    def torso_m(self) -> float:
        """Torso lift [m]."""
        return float(self.data.qpos[self.physics.qpos[TORSO_JOINT]])

    def base_pose(self) -> tuple[float, float, float]:
        """Base (x [m], y [m], yaw [rad]) in world, yaw in [-pi, pi]."""
        x, y, yaw = (float(self.data.qpos[self.physics.qpos[n]]) for n in BASE_JOINTS)
        return (x, y, _wrap(yaw))

    def particle_positions(self) -> FloatArray:
        """Positions of the water particles (n x 3) [m] in world."""
        return np.array(self.data.xpos[list(self.physics.particle_body)]).reshape(-1, 3)

    def particles_in(self, container: str) -> int:
        """How many particles are inside cup ``container`` (in its inside, up to its rim;
        a flared cup's widens with height)."""
        obj = self.physics.scene.object(container)
        if obj.shape != "cup":
            raise InvalidConfiguration(f"particles_in: {container!r} is a {obj.shape}, "
                                       "not a cup")
        placement = self.object_transform(container)
        local = (self.particle_positions() - placement.translation) @ placement.rotation
        hx, hy, hz = obj.inner_half_extents_m
        centre_z = obj.wall_m / 2
        widen = math.tan(obj.flare_rad) * (local[:, 2] - (centre_z - hz))  # a flared cup's
        inside = ((np.abs(local[:, 0]) <= hx + widen) & (np.abs(local[:, 1]) <= hy + widen)
                  & (np.abs(local[:, 2] - centre_z) <= hz))
        return int(np.count_nonzero(inside))

    def robot_contacts(self, other: str | None = None) -> tuple[tuple[str, str], ...]:
        """``(robot body, other body)`` pairs in contact now, sorted; only those whose other
        body is ``other`` (an object, ``table`` or ``particle_<i>``) when given."""
        model, data = self.model, self.data
        robot = self.physics.robot_bodies
        pairs: set[tuple[str, str]] = set()
        for i in range(data.ncon):
            contact = data.contact[i]
            b1, b2 = int(model.geom_bodyid[contact.geom1]), int(model.geom_bodyid[contact.geom2])
            if (b1 in robot) == (b2 in robot):
                continue
            mine, theirs = (b1, b2) if b1 in robot else (b2, b1)
            name = model.body(theirs).name
            if other is None or name == other:
                pairs.add((model.body(mine).name, name))
        return tuple(sorted(pairs))

    def touching(self, a: str, b: str) -> bool:
        """Whether bodies ``a`` and ``b`` (objects, ``table``, links) are in contact."""
        ids = {mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, n): n for n in (a, b)}
        if len(ids) != 2 or -1 in ids:
            raise InvalidConfiguration(f"touching: need two bodies of the model, got {a!r}, "
                                       f"{b!r}")
        for i in range(self.data.ncon):
            contact = self.data.contact[i]
            pair = {int(self.model.geom_bodyid[contact.geom1]),
                    int(self.model.geom_bodyid[contact.geom2])}
            if pair == set(ids):
                return True
        return False

    def _object(self, name: str) -> int:
        try:
            return self.physics.object_body[name]
        except KeyError:
            raise InvalidConfiguration(
                f"no object {name!r} in the scene; objects: "
                f"{', '.join(self.physics.object_body) or 'none'}") from None


def _arm(arm: str) -> Arm:
    if arm not in ARMS:
        raise InvalidConfiguration(f"arm must be one of {ARMS}, got {arm!r}")
    return arm


def _finite(values: Sequence[float] | FloatArray, size: int, what: str) -> tuple[float, ...]:
    array = np.asarray(values, dtype=float)
    if array.shape != (size,) or not np.all(np.isfinite(array)):
        raise InvalidConfiguration(f"{what} needs {size} finite values, got {values!r}")
    return tuple(float(v) for v in array)


def _wrap(angle_rad: float) -> float:
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


def _rpy_matrix(roll: float, pitch: float, yaw: float) -> FloatArray:
    return np.asarray(pin.rpy.rpyToMatrix(roll, pitch, yaw))


def _pose6(placement: pin.SE3) -> Pose6:
    x, y, z = (float(v) for v in placement.translation)
    roll, pitch, yaw = (float(v) for v in pin.rpy.matrixToRpy(placement.rotation))
    return (x, y, z, roll, pitch, yaw)
