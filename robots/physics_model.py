"""The PR2 and its room as a MuJoCo model: what :mod:`skillcompose.robots.physics` runs.

Units: metres [m], radians [rad], kilograms [kg], seconds [s], newtons [N]. The world frame
is the floor frame of :mod:`skillcompose.robots.model`: z up, the floor at z = 0, and the
PR2's ``base_footprint`` on the floor, facing +x at yaw 0.

How the model is made (see docs/robots.md, "The physics model (MuJoCo)"):

- **Robot.** MuJoCo compiles ``example-robot-data``'s PR2 URDF itself (the one Pinocchio
  reads), ``package://`` paths resolved, with ``balanceinertia`` (some URDF inertias break
  the triangle inequality) and ``fusestatic="false"`` (every link stays a body, so the tool
  frames ``l_gripper_tool_frame`` / ``r_gripper_tool_frame`` are bodies).
- **Collision geometry.** The URDF's collision meshes, through the **convex hulls** MuJoCo
  computes of them, except: the proximal finger links do not collide (the hull of the
  C-shaped link fills the C and strikes what the tips close on), and each finger tip gets
  a thin box *pad* on its inner face (fitted to the hull), because a box on a box gives
  several contact points where a hull gives one, and a held object must not pivot about
  the line between the two fingers.
- **Root.** The base moves on three joints of ``base_footprint``: ``base_x``, ``base_y``
  (slides along world x, y) and ``base_yaw`` (hinge about z), each driven by a position
  servo.
- **Actuators.** Position servos (PD) on the base, the torso and the 14 arm joints, gains
  in :data:`ARM_GAINS`, :data:`TORSO_GAINS`, :data:`BASE_GAINS`; every robot body is
  gravity-compensated (``gravcomp = 1``), as the PR2's counterbalanced arms are, so the
  servos only fight inertia and what the hand carries. Joint armature (the gears'
  reflected inertia) keeps the light wrist stable at the 2 ms step.
- **Grippers.** The URDF's mimic joints become MuJoCo joint equalities (the finger, tip and
  parallel-link joints follow ``*_gripper_l_finger_joint``), stiffened here; one position
  servo per gripper drives that joint with a torque limit, so closed fingers squeeze what
  they hold with a bounded torque and hold it by friction (elliptic cones; stiff finger
  contacts of friction :data:`FINGER_FRICTION` with a torsional part).
- **Contacts.** No self-collision: robot geoms are ``contype`` :data:`ROBOT_BIT`,
  ``conaffinity`` :data:`WORLD_BIT`; the table, objects and particles collide with the
  robot and each other; the floor with objects and particles but not the robot (whose
  base is driven, not rolled).
- **Room.** A floor plane, the table as a static box (:class:`skillcompose.robots.collision.Box`),
  objects (:class:`ObjectSpec`: boxes, cylinders, spheres and open-top cups made of five
  boxes, each on a free joint) and water as ``n_particles`` small frictionless spheres on
  three slide joints each, with viscous drag.

Compiling takes about 40 ms; :func:`compile_scene` caches one model per :class:`SceneSpec`
per process, and every :class:`~skillcompose.robots.physics.PhysicsWorld` of that scene
shares it read-only (each has its own ``MjData``).
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import mujoco  # type: ignore[import-untyped]  # no stubs or py.typed
import numpy as np

from skillcompose.robots.collision import Box
from skillcompose.robots.errors import InvalidConfiguration, RobotDataNotFound
from skillcompose.robots.model import (
    ARM_JOINTS,
    ARMS,
    ROBOT_FRAME,
    ROBOT_PACKAGE,
    TOOL_FRAMES,
    TORSO_JOINT,
    Arm,
    find_pr2_urdf,
)

__all__ = [
    "ARM_GAINS",
    "BASE_JOINTS",
    "DEFAULT_TABLE",
    "GRIPPER_JOINTS",
    "ObjectShape",
    "ObjectSpec",
    "PhysicsModel",
    "SceneSpec",
    "compile_scene",
    "pr2_urdf_for_mujoco",
]

ObjectShape = Literal["box", "cylinder", "sphere", "cup"]
OBJECT_SHAPES: tuple[ObjectShape, ...] = ("box", "cylinder", "sphere", "cup")

ROBOT_BIT = 2
"""``contype`` of robot geoms; their ``conaffinity`` is :data:`WORLD_BIT`, so two robot
geoms never collide."""
WORLD_BIT = 4
"""Set in the ``contype`` of the table, objects and particles (what the robot touches)."""
FLOOR_BIT = 1
"""Floor, table, objects and particles touch each other through this bit; the robot lacks it."""

BASE_JOINTS = ("base_x", "base_y", "base_yaw")
"""The root's joints: slides along world x and y [m], hinge about world z [rad]."""
GRIPPER_JOINTS: dict[Arm, str] = {arm: f"{arm[0]}_gripper_l_finger_joint" for arm in ARMS}
"""The joint each gripper servo drives; the other finger joints follow it (equalities)."""
GRIPPER_OPEN_RAD = 0.548
"""``*_gripper_l_finger_joint`` fully open (the URDF's upper limit) [rad]; 0 is closed."""

#: Position-servo stiffness kp [N m/rad or N/m], damping kv and armature per joint group.
ARM_GAINS: dict[str, tuple[float, float, float]] = {
    "shoulder_pan_joint": (2000.0, 120.0, 0.5),
    "shoulder_lift_joint": (2000.0, 120.0, 0.5),
    "upper_arm_roll_joint": (800.0, 40.0, 0.2),
    "elbow_flex_joint": (800.0, 40.0, 0.2),
    "forearm_roll_joint": (200.0, 8.0, 0.05),
    "wrist_flex_joint": (200.0, 8.0, 0.05),
    "wrist_roll_joint": (100.0, 4.0, 0.05),
}
TORSO_GAINS = (1.0e5, 5.0e3, 5.0)
"""kp [N/m], kv [N s/m] and armature [kg] of the torso servo (the URDF's damping of
20 000 N s/m, which makes the torso crawl at its 1.3 cm/s, is replaced by kv)."""
BASE_GAINS = (2.0e5, 2.0e4, 50.0)
"""kp, kv and armature of the base servos (x, y [m]; yaw [rad] takes a tenth)."""
GRIPPER_GAINS = (40.0, 1.0, 0.01)
"""kp [N m/rad], kv and armature of the gripper servo; its torque is capped at
:data:`GRIPPER_TORQUE_NM`."""
GRIPPER_TORQUE_NM = 6.0
"""Largest torque of a gripper servo [N m]: about 40 N between the pads."""
TABLE_FRICTION = 0.3
"""The table's sliding friction: low, because a contact takes the larger coefficient of its
two geoms, so that an object's own ``friction`` decides how it slides on the table."""
FINGER_FRICTION = 1.5
"""Sliding friction of the finger pads (rubber on a dry object)."""
PAD_HALF_EXTENTS_M = (0.015, 0.001, 0.0095)
"""Half sizes of a finger pad [m]: the flat inner face of the finger tip's hull."""
TIMESTEP_S = 0.002

"""Physics time step [s]."""


@dataclass(frozen=True)
class ObjectSpec:
    """A loose object of the room, on a free joint.

    Attributes:
        name: body name, unique in the scene (``table``, ``floor`` and robot links are taken).
        shape: ``box`` (``size_m`` = 3 half extents), ``cylinder`` (radius, half height),
            ``sphere`` (radius) or ``cup`` (3 outer half extents of an open-top box whose
            walls and bottom are ``wall_m`` thick: a jug or a glass).
        size_m: sizes [m] as ``shape`` says.
        mass_kg: total mass [kg], spread over the geoms by volume.
        friction: sliding friction coefficient (MuJoCo takes the larger of two geoms').
        wall_m: a cup's wall and bottom thickness [m].
        rgba: colour for viewers.
        flare_rad: how far a cup's four walls lean out from vertical [rad] (0: a box;
            ``size_m`` is then the outside at the bottom, and the mouth is wider by
            ``2 * size_m[2] * tan(flare_rad)`` on each side). A flared cup tipped 90 degrees
            empties, as a jug or glass does, where a box keeps a layer of particles on
            its lowest wall.
    """

    name: str
    shape: ObjectShape
    size_m: tuple[float, ...]
    mass_kg: float
    friction: float = 1.0
    wall_m: float = 0.006
    rgba: tuple[float, float, float, float] = (0.8, 0.4, 0.2, 1.0)
    flare_rad: float = 0.0

    def __post_init__(self) -> None:
        wanted = {"box": 3, "cylinder": 2, "sphere": 1, "cup": 3}.get(self.shape)
        if wanted is None:
            raise InvalidConfiguration(
                f"object {self.name!r}: shape {self.shape!r} is not one of {OBJECT_SHAPES}")
        sizes = np.asarray(self.size_m, dtype=float)
        if sizes.shape != (wanted,) or not np.all(np.isfinite(sizes)) or np.any(sizes <= 0):
            raise InvalidConfiguration(
                f"object {self.name!r}: a {self.shape} needs {wanted} sizes > 0 [m], "
                f"got {self.size_m}")
        if not (math.isfinite(self.mass_kg) and self.mass_kg > 0):
            raise InvalidConfiguration(f"object {self.name!r}: mass_kg must be > 0, "
                                       f"got {self.mass_kg}")
        if not (math.isfinite(self.friction) and self.friction > 0):
            raise InvalidConfiguration(f"object {self.name!r}: friction must be > 0, "
                                       f"got {self.friction}")
        if self.shape == "cup" and not 0 < 2 * self.wall_m < min(self.size_m[:2]):
            raise InvalidConfiguration(
                f"object {self.name!r}: wall_m {self.wall_m} must be > 0 and leave room "
                f"inside half extents {self.size_m[:2]}")
        if not (math.isfinite(self.flare_rad) and 0.0 <= self.flare_rad <= 0.5) or (
                self.flare_rad and self.shape != "cup"):
            raise InvalidConfiguration(
                f"object {self.name!r}: flare_rad must be in [0, 0.5] rad and only a cup "
                f"flares, got {self.flare_rad} for a {self.shape}")

    @property
    def inner_half_extents_m(self) -> tuple[float, float, float]:
        """A cup's inside as half extents [m], centred ``wall_m / 2`` above its centre (a
        flared cup's at its bottom; it widens by ``tan(flare_rad)`` per metre up)."""
        hx, hy, hz = self.size_m
        return (hx - self.wall_m, hy - self.wall_m, hz - self.wall_m / 2)


DEFAULT_TABLE = Box.table((0.80, 0.0), (0.70, 1.40), 0.75)
"""The kinematic skills' table (``DEFAULT_TABLE_WORLD``): top at z = 0.75 m, front edge at
x = 0.45 m, y in [-0.7, 0.7] m."""


@dataclass(frozen=True)
class SceneSpec:
    """What a physics model holds besides the PR2: compiled once per process per value.

    Attributes:
        table: the table (a static box), or None.
        objects: loose objects.
        n_particles: water particles (spheres), placed by ``PhysicsWorld.reset``.
        particle_radius_m / particle_mass_kg: each particle's size and mass.
        particle_drag_ns_per_m: viscous drag on each particle [N s/m], water's viscosity
            lumped: frictionless particles otherwise leave a tilted jug as off a chute and
            skate across the table (0.01 with 2 g: terminal speed 2 m/s, 0.2 s to slow down).
        timestep_s: physics step [s].
        noslip_iterations: iterations of MuJoCo's no-slip pass after the main solver. With
            0 (the default) a held 0.3 kg box creeps about 0.15 mm/s down the stiff pads;
            with 3 it creeps < 0.01 mm/s, but a step costs up to twice as much.
    """

    table: Box | None = DEFAULT_TABLE
    objects: tuple[ObjectSpec, ...] = ()
    n_particles: int = 0
    particle_radius_m: float = 0.007
    particle_mass_kg: float = 0.002
    particle_drag_ns_per_m: float = 0.01
    timestep_s: float = TIMESTEP_S
    noslip_iterations: int = 0

    def __post_init__(self) -> None:
        names = [o.name for o in self.objects]
        taken = {"table", "floor", "world"}
        clash = sorted({n for n in names if names.count(n) > 1 or n in taken
                        or n.startswith("particle_")})
        if clash:
            raise InvalidConfiguration(
                f"scene objects need unique names other than {sorted(taken)} and "
                f"'particle_*'; clashing: {clash}")
        if not 0 <= self.n_particles <= 500:
            raise InvalidConfiguration(f"n_particles must be in [0, 500], got {self.n_particles}")
        if not (0 < self.particle_radius_m < 0.05 and 0 < self.particle_mass_kg < 1
                and 0 <= self.particle_drag_ns_per_m < 10):
            raise InvalidConfiguration("particle_radius_m must be in (0, 0.05) m, "
                                       "particle_mass_kg in (0, 1) kg and "
                                       "particle_drag_ns_per_m in [0, 10) N s/m")
        if not 0 <= self.noslip_iterations <= 20:
            raise InvalidConfiguration(f"noslip_iterations must be in [0, 20], got "
                                       f"{self.noslip_iterations}")
        if not 0.0002 <= self.timestep_s <= 0.005:
            raise InvalidConfiguration(f"timestep_s must be in [0.0002, 0.005] s, "
                                       f"got {self.timestep_s}")

    def object(self, name: str) -> ObjectSpec:
        """The object called ``name``; raises with the valid names."""
        for spec in self.objects:
            if spec.name == name:
                return spec
        raise InvalidConfiguration(f"no object {name!r} in the scene; objects: "
                                   f"{', '.join(o.name for o in self.objects) or 'none'}")


@dataclass(frozen=True)
class PhysicsModel:
    """A compiled scene and the indices a world needs (shared read-only).

    Attributes:
        scene: the scene it was compiled from.
        model: the MuJoCo model.
        qpos / dof: per joint name, its address in ``qpos`` and ``qvel``.
        actuator: per driven joint name (base, torso, arm and gripper joints), its actuator.
        tool_body: per arm, the body of its tool frame.
        finger_geoms: per arm, the collision geom ids of the (left, right) finger.
        robot_geoms / robot_bodies: every collision geom, and every body, of the robot.
        object_body: per object name, its body id; ``particle_body`` the particles'.
        table_body: the table's body (None without a table); ``base_body`` the robot's
            ``base_footprint``.
    """

    scene: SceneSpec
    model: mujoco.MjModel
    qpos: Mapping[str, int]
    dof: Mapping[str, int]
    actuator: Mapping[str, int]
    tool_body: Mapping[Arm, int]
    finger_geoms: Mapping[Arm, tuple[frozenset[int], frozenset[int]]]
    robot_geoms: frozenset[int]
    robot_bodies: frozenset[int]
    object_body: Mapping[str, int]
    particle_body: tuple[int, ...]
    table_body: int | None
    base_body: int


def pr2_urdf_for_mujoco() -> str:
    """The PR2 URDF's text as MuJoCo reads it: ``package://`` resolved to the installed
    ``example-robot-data``, and a ``<mujoco><compiler .../></mujoco>`` element added."""
    path = find_pr2_urdf()
    package_root = path.parents[3].parent
    text = path.read_text(encoding="utf-8").replace("package://", f"{package_root}/")
    compiler = ('<mujoco><compiler balanceinertia="true" discardvisual="false" '
                'fusestatic="false" strippath="false"/></mujoco>')
    text, count = re.subn(r"(<robot\b[^>]*>)", lambda m: m.group(1) + compiler, text, count=1)
    if count != 1:
        raise RobotDataNotFound(ROBOT_PACKAGE, f"{path} has no <robot> element")
    return text


@functools.lru_cache(maxsize=8)
def compile_scene(scene: SceneSpec = SceneSpec()) -> PhysicsModel:
    """The MuJoCo model of the PR2 in ``scene`` (compiled once per scene per process)."""
    spec = mujoco.MjSpec.from_string(pr2_urdf_for_mujoco())
    _set_options(spec, scene.timestep_s, scene.noslip_iterations)
    robot_names = {b.name for b in spec.bodies if b.name and b.name != "world"}
    _add_root(spec)
    _set_robot_contacts(spec)
    _add_pads(spec)
    _add_servos(spec)
    _add_room(spec, scene)
    try:
        model = spec.compile()
    except ValueError as exc:  # MuJoCo's compiler errors
        raise RobotDataNotFound(ROBOT_PACKAGE, f"MuJoCo cannot compile the PR2: {exc}") from exc
    return _index(scene, model, robot_names)


def _set_options(spec: mujoco.MjSpec, timestep_s: float, noslip_iterations: int) -> None:
    spec.modelname = "pr2_room"
    option = spec.option
    option.timestep = timestep_s
    option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    option.solver = mujoco.mjtSolver.mjSOL_NEWTON
    option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    option.impratio = 1.0  # 10 makes boxes landing on an edge spin off (elliptic cones)
    option.noslip_iterations = noslip_iterations
    option.iterations = 30
    option.ls_iterations = 10
    option.tolerance = 1e-8
    spec.compiler.degree = False


def _add_root(spec: mujoco.MjSpec) -> None:
    base = spec.body(ROBOT_FRAME)
    armature = BASE_GAINS[2]
    for name, axis in zip(BASE_JOINTS, ((1, 0, 0), (0, 1, 0), (0, 0, 1)), strict=True):
        joint = base.add_joint()
        joint.name = name
        joint.type = (mujoco.mjtJoint.mjJNT_HINGE if name == "base_yaw"
                      else mujoco.mjtJoint.mjJNT_SLIDE)
        joint.axis = axis
        joint.armature = armature if name != "base_yaw" else armature / 10
    for body in spec.bodies:
        if body.name and body.name != "world":
            body.gravcomp = 1.0


def _set_robot_contacts(spec: mujoco.MjSpec) -> None:
    for geom in spec.geoms:
        if geom.contype or geom.conaffinity:
            geom.contype = ROBOT_BIT
            geom.conaffinity = WORLD_BIT
            geom.condim = 3
            geom.friction = (1.0, 0.005, 0.0001)
            if "finger_tip" in geom.parent.name:
                _finger_contact(geom, spec.option.timestep)
            elif "finger" in geom.parent.name:
                # the hull of the C-shaped proximal finger fills the C and would strike what
                # the tips close on: only the tips (and their pads) touch the world
                geom.contype = 0
                geom.conaffinity = 0
    for joint in spec.joints:
        if joint.name == TORSO_JOINT:
            _set_damping(joint, 0.0)
            joint.armature = TORSO_GAINS[2]
        for suffix, (_kp, _kv, armature) in ARM_GAINS.items():
            if joint.name.endswith(suffix):
                joint.armature = armature
        if "gripper" in joint.name:
            joint.armature = GRIPPER_GAINS[2]
        if joint.name.endswith("r_parallel_root_joint"):
            # the URDF couples it with multiplier -1 but limits it to [0, 0.548]: the limit
            # would hold the whole gripper shut, so this linkage joint (no geometry) is free
            joint.limited = mujoco.mjtLimited.mjLIMITED_FALSE
    for equality in spec.equalities:
        equality.solref = (2 * spec.option.timestep, 1.0)
        equality.solimp = (0.95, 0.99, 0.001, 0.5, 2.0)


def _set_damping(joint: mujoco.MjsJoint, value: float) -> None:
    """Linear joint damping: a number in MuJoCo 3, a polynomial (d1, d2, d3) in MuJoCo 4."""
    if np.ndim(joint.damping) == 0:
        joint.damping = value
    else:
        joint.damping = (value, *(0.0,) * (len(joint.damping) - 1))


def _finger_contact(geom: mujoco.MjsGeom, timestep_s: float) -> None:
    """Finger contacts: high friction with a torsional part (condim 4), and stiff (time
    constant two steps), which is what keeps a held object from creeping down the pads;
    the priority makes a contact take these values rather than the object's."""
    geom.friction = (FINGER_FRICTION, 0.02, 0.001)
    geom.condim = 4
    geom.solref = (2 * timestep_s, 1.0)
    geom.solimp = (0.95, 0.99, 0.001, 0.5, 2.0)
    geom.priority = 2


def _add_pads(spec: mujoco.MjSpec) -> None:
    """A thin box on the inner face of each finger tip (see the module docstring)."""
    for arm in ARMS:
        for side, sign in (("l", -1.0), ("r", 1.0)):
            tip = spec.body(f"{arm[0]}_gripper_{side}_finger_tip_link")
            pad = tip.add_geom()
            pad.name = f"{arm[0]}_gripper_{side}_pad"
            pad.type = mujoco.mjtGeom.mjGEOM_BOX
            pad.size = PAD_HALF_EXTENTS_M
            pad.pos = (0.013, sign * 0.0158, 0.0)  # the hull's inner face, 1 mm proud
            pad.contype = ROBOT_BIT
            pad.conaffinity = WORLD_BIT
            _finger_contact(pad, spec.option.timestep)
            pad.mass = 0.0
            pad.density = 0.0
            pad.rgba = (0.1, 0.1, 0.1, 1.0)


def _position_servo(spec: mujoco.MjSpec, joint: str, kp: float, kv: float,
                    ctrlrange: tuple[float, float] | None, force: float | None = None) -> None:
    act = spec.add_actuator()
    act.name = joint
    act.target = joint
    act.trntype = mujoco.mjtTrn.mjTRN_JOINT
    act.set_to_position(kp=kp, kv=kv)
    if ctrlrange is not None:
        act.ctrllimited = True
        act.ctrlrange = ctrlrange
    if force is not None:
        act.forcelimited = True
        act.forcerange = (-force, force)


def _add_servos(spec: mujoco.MjSpec) -> None:
    kp, kv, _ = BASE_GAINS
    for name in BASE_JOINTS:
        scale = 0.1 if name == "base_yaw" else 1.0
        _position_servo(spec, name, kp * scale, kv * scale, None)
    _position_servo(spec, TORSO_JOINT, TORSO_GAINS[0], TORSO_GAINS[1], (0.0, 0.31))
    for arm in ARMS:
        for joint in ARM_JOINTS[arm]:
            suffix = joint[2:]
            jkp, jkv, _ = ARM_GAINS[suffix]
            _position_servo(spec, joint, jkp, jkv, None)
        gkp, gkv, _ = GRIPPER_GAINS
        _position_servo(spec, GRIPPER_JOINTS[arm], gkp, gkv, (-0.1, GRIPPER_OPEN_RAD),
                        GRIPPER_TORQUE_NM)


def _box_geom(body: mujoco.MjsBody, name: str, half: tuple[float, float, float],
              pos: tuple[float, float, float], friction: float,
              rgba: tuple[float, float, float, float]) -> mujoco.MjsGeom:
    geom = body.add_geom()
    geom.name = name
    geom.type = mujoco.mjtGeom.mjGEOM_BOX
    geom.size = half
    geom.pos = pos
    geom.friction = (friction, 0.005, 0.0001)
    geom.rgba = rgba
    geom.contype = WORLD_BIT | FLOOR_BIT
    geom.conaffinity = ROBOT_BIT | FLOOR_BIT
    geom.condim = 4
    return geom


def _add_room(spec: mujoco.MjSpec, scene: SceneSpec) -> None:
    world = spec.worldbody
    floor = world.add_geom()
    floor.name = "floor"
    floor.type = mujoco.mjtGeom.mjGEOM_PLANE
    floor.size = (5.0, 5.0, 0.1)
    floor.contype = FLOOR_BIT
    floor.conaffinity = FLOOR_BIT
    floor.friction = (0.8, 0.005, 0.0001)
    if scene.table is not None:
        table = world.add_body()
        table.name = "table"
        table.pos = scene.table.center_m
        half_yaw = scene.table.yaw_rad / 2
        table.quat = (math.cos(half_yaw), 0.0, 0.0, math.sin(half_yaw))
        _box_geom(table, "table", scene.table.half_extents_m, (0.0, 0.0, 0.0),
                  TABLE_FRICTION, (0.6, 0.45, 0.3, 1.0))
    for spec_object in scene.objects:
        _add_object(world, spec_object)
    for index in range(scene.n_particles):
        body = world.add_body()
        body.name = f"particle_{index}"
        # three slides, no rotation: a frictionless sphere's spin changes nothing, and the
        # constraint solver's cost grows with the cube of an island's degrees of freedom
        for axis, letter in zip(((1, 0, 0), (0, 1, 0), (0, 0, 1)), "xyz", strict=True):
            joint = body.add_joint()
            joint.name = f"{body.name}_{letter}"
            joint.type = mujoco.mjtJoint.mjJNT_SLIDE
            joint.axis = axis
            _set_damping(joint, scene.particle_drag_ns_per_m)
        geom = body.add_geom()
        geom.name = body.name
        geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
        geom.size = (scene.particle_radius_m, 0.0, 0.0)
        geom.mass = scene.particle_mass_kg
        geom.friction = (0.0, 0.0, 0.0)
        geom.condim = 1  # water slides: one frictionless constraint row per contact
        geom.priority = 3  # its contacts take the particle's condim, not the other geom's
        geom.rgba = (0.2, 0.45, 0.95, 1.0)
        geom.contype = WORLD_BIT | FLOOR_BIT
        geom.conaffinity = ROBOT_BIT | FLOOR_BIT


def _add_object(world: mujoco.MjsBody, obj: ObjectSpec) -> None:
    body = world.add_body()
    body.name = obj.name
    body.add_freejoint()
    if obj.shape == "box":
        geoms = [_box_geom(body, obj.name, obj.size_m, (0.0, 0.0, 0.0),  # type: ignore[arg-type]
                           obj.friction, obj.rgba)]
    elif obj.shape in ("cylinder", "sphere"):
        geom = _box_geom(body, obj.name, (0.01, 0.01, 0.01), (0.0, 0.0, 0.0), obj.friction,
                         obj.rgba)
        geom.type = (mujoco.mjtGeom.mjGEOM_CYLINDER if obj.shape == "cylinder"
                     else mujoco.mjtGeom.mjGEOM_SPHERE)
        geom.size = (*obj.size_m, *(0.0,) * (3 - len(obj.size_m)))
        geoms = [geom]
    elif obj.flare_rad > 0.0:
        geoms = _flared_cup(body, obj)
    else:
        hx, hy, hz = obj.size_m
        w = obj.wall_m / 2
        parts = (
            ("bottom", (hx, hy, w), (0.0, 0.0, -hz + w)),
            ("wall_px", (w, hy, hz), (hx - w, 0.0, 0.0)),
            ("wall_nx", (w, hy, hz), (-hx + w, 0.0, 0.0)),
            ("wall_py", (hx - 2 * w, w, hz), (0.0, hy - w, 0.0)),
            ("wall_ny", (hx - 2 * w, w, hz), (0.0, -hy + w, 0.0)),
        )
        geoms = [_box_geom(body, f"{obj.name}_{part}", half, pos, obj.friction, obj.rgba)
                 for part, half, pos in parts]
    volumes = [_volume(g) for g in geoms]
    for geom, volume in zip(geoms, volumes, strict=True):
        geom.mass = obj.mass_kg * volume / sum(volumes)


def _flared_cup(body: mujoco.MjsBody, obj: ObjectSpec) -> list[mujoco.MjsGeom]:
    """A cup whose walls lean out by ``obj.flare_rad``, each about its bottom outer edge;
    the walls are as wide as the mouth, so they overlap at the corners (one body: its geoms
    do not collide with each other) and leave no gap there."""
    hx, hy, hz = obj.size_m
    w = obj.wall_m / 2
    alpha = obj.flare_rad
    spread = 2 * hz * math.tan(alpha)
    length = hz / math.cos(alpha)  # half the slanted wall's length
    geoms = [_box_geom(body, f"{obj.name}_bottom", (hx, hy, w), (0.0, 0.0, -hz + w),
                       obj.friction, obj.rgba)]
    for part, axis, sign in (("px", 0, 1.0), ("nx", 0, -1.0), ("py", 1, 1.0), ("ny", 1, -1.0)):
        half = (hx, hy)[axis]
        across = (hy, hx)[axis] + spread
        lean = sign * alpha  # the top moves out along the wall's normal
        out = sign * (half - w * math.cos(alpha) + length * math.sin(alpha))
        z = -hz + w * math.sin(alpha) + length * math.cos(alpha)
        if axis == 0:
            size, pos = (w, across, length), (out, 0.0, z)
            quat = (math.cos(lean / 2), 0.0, math.sin(lean / 2), 0.0)
        else:
            size, pos = (across, w, length), (0.0, out, z)
            quat = (math.cos(lean / 2), -math.sin(lean / 2), 0.0, 0.0)
        geom = _box_geom(body, f"{obj.name}_wall_{part}", size, pos, obj.friction, obj.rgba)
        geom.quat = quat
        geoms.append(geom)
    return geoms


def _volume(geom: mujoco.MjsGeom) -> float:
    size = geom.size
    if geom.type == mujoco.mjtGeom.mjGEOM_BOX:
        return float(8 * size[0] * size[1] * size[2])
    if geom.type == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return float(2 * math.pi * size[0] ** 2 * size[1])
    return float(4 / 3 * math.pi * size[0] ** 3)


def _index(scene: SceneSpec, model: mujoco.MjModel, robot_names: set[str]) -> PhysicsModel:
    def body_id(name: str) -> int:
        return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name))

    qpos = {model.joint(j).name: int(model.jnt_qposadr[j]) for j in range(model.njnt)}
    dof = {model.joint(j).name: int(model.jnt_dofadr[j]) for j in range(model.njnt)}
    actuator = {model.actuator(a).name: a for a in range(model.nu)}
    robot_bodies = frozenset(body_id(n) for n in robot_names)
    robot_geoms = frozenset(
        g for g in range(model.ngeom)
        if int(model.geom_bodyid[g]) in robot_bodies and model.geom_contype[g] == ROBOT_BIT)
    fingers: dict[Arm, tuple[frozenset[int], frozenset[int]]] = {}
    for arm in ARMS:
        sides = []
        for side in ("l", "r"):
            bodies = {body_id(f"{arm[0]}_gripper_{side}_finger_link"),
                      body_id(f"{arm[0]}_gripper_{side}_finger_tip_link")}
            sides.append(frozenset(g for g in robot_geoms if int(model.geom_bodyid[g]) in bodies))
        fingers[arm] = (sides[0], sides[1])
    return PhysicsModel(
        scene=scene,
        model=model,
        qpos=qpos,
        dof=dof,
        actuator=actuator,
        tool_body={arm: body_id(TOOL_FRAMES[arm]) for arm in ARMS},
        finger_geoms=fingers,
        robot_geoms=robot_geoms,
        robot_bodies=robot_bodies,
        object_body={o.name: body_id(o.name) for o in scene.objects},
        particle_body=tuple(body_id(f"particle_{i}") for i in range(scene.n_particles)),
        table_body=body_id("table") if scene.table is not None else None,
        base_body=body_id(ROBOT_FRAME),
    )
