"""The PR2 robot model: URDF loading, a planar base, reduced kinematic chains.

Units: lengths in metres [m], angles in radians [rad]. The world frame is the
floor frame in which the planar base moves; the robot frame is ``base_footprint``
(the planar joint's child frame, on the floor, x forward, z up).

A *chain* is a reduced Pinocchio model in which every joint not listed is
locked at a reference configuration. A chain's configuration is a vector of
*joint coordinates*, one value per degree of freedom: the planar base gives
``(x [m], y [m], yaw [rad])``, the torso a height [m], revolute joints an
angle [rad] (continuous joints unwrapped, reported in [-pi, pi]).
"""

from __future__ import annotations

import functools
import importlib.metadata
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from skillcompose.robots.errors import (
    ChainNotFound,
    FrameNotFound,
    InvalidConfiguration,
    RobotDataNotFound,
)

FloatArray = NDArray[np.float64]
Arm = Literal["left", "right"]
ARMS: tuple[Arm, Arm] = ("left", "right")

ROBOT_PACKAGE = "example-robot-data"
URDF_SUFFIX = "robots/pr2_description/urdf/pr2.urdf"
BASE_JOINT = "base_planar_joint"
TORSO_JOINT = "torso_lift_joint"
_ARM_JOINT_SUFFIXES = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "upper_arm_roll_joint",
    "elbow_flex_joint",
    "forearm_roll_joint",
    "wrist_flex_joint",
    "wrist_roll_joint",
)
ARM_JOINTS: dict[Arm, tuple[str, ...]] = {
    arm: tuple(f"{arm[0]}_{s}" for s in _ARM_JOINT_SUFFIXES) for arm in ARMS
}
TOOL_FRAMES: dict[Arm, str] = {"left": "l_gripper_tool_frame", "right": "r_gripper_tool_frame"}
ROBOT_FRAME = "base_footprint"

#: Tucked arms (the PR2 ``tuck_arms`` pose), 7 joint angles per arm [rad].
TUCKED_ARM_RAD: dict[Arm, tuple[float, ...]] = {
    "left": (0.06024, 1.248526, 1.789070, -1.683386, -1.7343417, -0.0962141, -0.0864407),
    "right": (-0.023593, 1.1072800, -1.5566882, -2.124408, -1.4175, -1.8417, 0.21436),
}

#: Chain name -> (uses base, uses torso, arms).
CHAIN_LAYOUT: dict[str, tuple[bool, bool, tuple[Arm, ...]]] = {
    "left_arm": (False, False, ("left",)),
    "right_arm": (False, False, ("right",)),
    "left_arm_torso": (False, True, ("left",)),
    "right_arm_torso": (False, True, ("right",)),
    "left_arm_torso_base": (True, True, ("left",)),
    "right_arm_torso_base": (True, True, ("right",)),
    "both_arms_torso_base": (True, True, ("left", "right")),
}


def find_pr2_urdf() -> Path:
    """Return the path of the PR2 URDF shipped by the ``example-robot-data`` wheel.

    Raises:
        RobotDataNotFound: the distribution is not installed or has no PR2 URDF.
    """
    try:
        dist = importlib.metadata.distribution(ROBOT_PACKAGE)
    except importlib.metadata.PackageNotFoundError as exc:
        raise RobotDataNotFound(ROBOT_PACKAGE, "the distribution is not installed") from exc
    for entry in dist.files or ():
        if str(entry).replace("\\", "/").endswith(URDF_SUFFIX):
            path = Path(str(dist.locate_file(entry)))
            if path.is_file():
                return path
            raise RobotDataNotFound(ROBOT_PACKAGE, f"{URDF_SUFFIX} is listed but missing on disk")
    raise RobotDataNotFound(ROBOT_PACKAGE, f"no file ending in {URDF_SUFFIX}")


def _wrap_rad(angle_rad: FloatArray) -> FloatArray:
    return np.asarray((angle_rad + np.pi) % (2.0 * np.pi) - np.pi, dtype=np.float64)


@dataclass
class KinematicChain:
    """A reduced model: the joints a skill moves, the rest locked.

    Attributes:
        name: chain name, one of :data:`CHAIN_LAYOUT`.
        model: the reduced Pinocchio model (world = floor frame).
        joint_names: names of the moving joints, in coordinate order.
        coordinate_names: one name per coordinate (the base gives ``_x``, ``_y``, ``_yaw``).
        lower_limits / upper_limits: coordinate limits [m or rad]; ``-inf`` / ``inf``
            for the base position and continuous joints.
        continuous: mask of the coordinates that wrap (continuous joints, base yaw).
        arms: the arms of this chain.
    """

    name: str
    model: pin.Model
    joint_names: tuple[str, ...]
    coordinate_names: tuple[str, ...]
    lower_limits: FloatArray
    upper_limits: FloatArray
    continuous: NDArray[np.bool_]
    arms: tuple[Arm, ...]
    _local: threading.local = field(init=False, repr=False, compare=False)
    _joint_kinds: list[tuple[str, int, int]] = field(init=False, repr=False)
    _scalar_q: NDArray[np.intp] = field(init=False, repr=False)
    _scalar_v: NDArray[np.intp] = field(init=False, repr=False)
    _unbounded_q: NDArray[np.intp] = field(init=False, repr=False)
    _unbounded_v: NDArray[np.intp] = field(init=False, repr=False)
    _planar: list[tuple[int, int]] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._local = threading.local()
        kinds: list[tuple[str, int, int]] = []
        for jid in range(1, self.model.njoints):
            joint = self.model.joints[jid]
            short = joint.shortname()
            if short == "JointModelPlanar":
                kind = "planar"
            elif short.startswith("JointModelRUB"):
                kind = "unbounded"
            else:
                kind = "scalar"
            kinds.append((kind, joint.idx_q, joint.idx_v))
        self._joint_kinds = kinds
        self._scalar_q = np.array([iq for k, iq, _ in kinds if k == "scalar"], dtype=np.intp)
        self._scalar_v = np.array([iv for k, _, iv in kinds if k == "scalar"], dtype=np.intp)
        self._unbounded_q = np.array([iq for k, iq, _ in kinds if k == "unbounded"], dtype=np.intp)
        self._unbounded_v = np.array([iv for k, _, iv in kinds if k == "unbounded"], dtype=np.intp)
        self._planar = [(iq, iv) for k, iq, iv in kinds if k == "planar"]

    @property
    def n_coordinates(self) -> int:
        """Number of degrees of freedom (length of a coordinate vector)."""
        return int(self.model.nv)

    @property
    def has_base(self) -> bool:
        """Whether the planar base (x, y, yaw) is part of the chain."""
        return BASE_JOINT in self.joint_names

    def coordinate_index(self, coordinate_name: str) -> int:
        """Index of a coordinate (e.g. ``torso_lift_joint`` or ``base_planar_joint_yaw``)."""
        try:
            return self.coordinate_names.index(coordinate_name)
        except ValueError:
            raise InvalidConfiguration(
                f"chain {self.name!r} has no coordinate {coordinate_name!r}; "
                f"valid: {', '.join(self.coordinate_names)}"
            ) from None

    def frame_id(self, frame_name: str) -> int:
        """Pinocchio frame id of ``frame_name`` in this chain; raises :class:`FrameNotFound`."""
        if not self.model.existFrame(frame_name):
            raise FrameNotFound(frame_name, [f.name for f in self.model.frames])
        return int(self.model.getFrameId(frame_name))

    def tool_frame_id(self, arm: Arm) -> int:
        """Frame id of the tool frame of ``arm``; raises if the arm is not in the chain."""
        if arm not in self.arms:
            raise InvalidConfiguration(
                f"chain {self.name!r} moves arms {self.arms}, not {arm!r}; "
                f"use chain '{arm}_arm', '{arm}_arm_torso' or 'both_arms_torso_base'"
            )
        return self.frame_id(TOOL_FRAMES[arm])

    def check_coordinates(self, coordinates: Sequence[float] | FloatArray) -> FloatArray:
        """Return ``coordinates`` as a float array, validated for shape and finiteness."""
        theta = np.asarray(coordinates, dtype=np.float64)
        if theta.shape != (self.n_coordinates,) or not np.all(np.isfinite(theta)):
            raise InvalidConfiguration(
                f"chain {self.name!r} expects {self.n_coordinates} finite coordinates "
                f"({', '.join(self.coordinate_names)}), got shape {theta.shape}: {theta}"
            )
        return theta

    @property
    def data(self) -> pin.Data:
        """This thread's Pinocchio work data for ``model``: threads sharing a chain (a skill
        thread left running past its state's time limit, say) never share it."""
        try:
            data: pin.Data = self._local.data
        except AttributeError:
            data = self._local.data = self.model.createData()
        return data

    def q_from_coordinates(self, coordinates: FloatArray) -> FloatArray:
        """Pinocchio configuration vector ``q`` from joint coordinates [m, rad]."""
        q = np.empty(self.model.nq)
        q[self._scalar_q] = coordinates[self._scalar_v]
        angles = coordinates[self._unbounded_v]
        q[self._unbounded_q] = np.cos(angles)
        q[self._unbounded_q + 1] = np.sin(angles)
        for iq, iv in self._planar:
            q[iq : iq + 2] = coordinates[iv : iv + 2]
            q[iq + 2] = np.cos(coordinates[iv + 2])
            q[iq + 3] = np.sin(coordinates[iv + 2])
        return q

    def coordinates_from_q(self, q: FloatArray) -> FloatArray:
        """Joint coordinates [m, rad] from a Pinocchio configuration ``q``."""
        theta = np.empty(self.model.nv)
        for kind, iq, iv in self._joint_kinds:
            if kind == "scalar":
                theta[iv] = q[iq]
            elif kind == "unbounded":
                theta[iv] = np.arctan2(q[iq + 1], q[iq])
            else:
                theta[iv : iv + 2] = q[iq : iq + 2]
                theta[iv + 2] = np.arctan2(q[iq + 3], q[iq + 2])
        return theta

    def velocity_from_coordinate_rates(self, coordinates: FloatArray) -> FloatArray:
        """Matrix ``T`` with ``v = T @ d(coordinates)/dt`` (Pinocchio tangent velocity).

        Identity except for the planar base, whose Pinocchio velocity is expressed in
        the robot frame: ``(vx, vy) = R(yaw)^T (dx/dt, dy/dt)``.
        """
        tangent = np.eye(self.model.nv)
        for kind, _iq, iv in self._joint_kinds:
            if kind == "planar":
                c, s = np.cos(coordinates[iv + 2]), np.sin(coordinates[iv + 2])
                tangent[iv : iv + 2, iv : iv + 2] = np.array([[c, s], [-s, c]])
        return tangent

    def normalise(self, coordinates: FloatArray) -> FloatArray:
        """Wrap continuous coordinates to [-pi, pi] [rad]; others unchanged."""
        out = np.array(coordinates, dtype=np.float64)
        out[self.continuous] = _wrap_rad(out[self.continuous])
        return out

    def sample_coordinates(self, rng: np.random.Generator) -> FloatArray:
        """Uniform coordinates inside the limits; [-pi, pi] [rad] for continuous joints.

        The base position (unlimited) is sampled in [-1, 1] [m].
        """
        low = np.where(np.isfinite(self.lower_limits), self.lower_limits, -np.pi)
        high = np.where(np.isfinite(self.upper_limits), self.upper_limits, np.pi)
        low[~self.continuous & ~np.isfinite(self.lower_limits)] = -1.0
        high[~self.continuous & ~np.isfinite(self.upper_limits)] = 1.0
        return rng.uniform(low, high)

    def within_limits(self, coordinates: FloatArray, tolerance: float = 1e-9) -> bool:
        """Whether every coordinate lies inside its limits (within ``tolerance``)."""
        theta = np.asarray(coordinates)
        return bool(
            np.all(theta >= self.lower_limits - tolerance)
            and np.all(theta <= self.upper_limits + tolerance)
        )

    def transform_frame_to_world(self, frame_name: str, coordinates: FloatArray) -> pin.SE3:
        """Placement of ``frame_name`` in the world frame at ``coordinates``."""
        fid = self.frame_id(frame_name)
        q = self.q_from_coordinates(self.check_coordinates(coordinates))
        pin.forwardKinematics(self.model, self.data, q)
        return pin.updateFramePlacement(self.model, self.data, fid).copy()

    def transform_tool_to_world(self, arm: Arm, coordinates: FloatArray) -> pin.SE3:
        """Placement of the gripper tool frame of ``arm`` in the world frame."""
        return self.transform_frame_to_world(TOOL_FRAMES[arm], coordinates)

    def jacobian_tool_world(self, arm: Arm, coordinates: FloatArray) -> FloatArray:
        """6 x n Jacobian of the tool frame w.r.t. the coordinates.

        Rows: linear velocity of the tool origin [m/s] then angular velocity
        [rad/s], both in world axes, per unit coordinate rate.
        """
        fid = self.tool_frame_id(arm)
        theta = self.check_coordinates(coordinates)
        q = self.q_from_coordinates(theta)
        jac = pin.computeFrameJacobian(self.model, self.data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        return np.asarray(jac @ self.velocity_from_coordinate_rates(theta))

    def joint_origins_world(self, coordinates: FloatArray) -> dict[str, FloatArray]:
        """Origin [m] in world of every joint of the reduced model (incl. locked parents)."""
        q = self.q_from_coordinates(self.check_coordinates(coordinates))
        pin.forwardKinematics(self.model, self.data, q)
        return {
            self.model.names[j]: np.array(self.data.oMi[j].translation)
            for j in range(1, self.model.njoints)
        }

    def frame_origins_world(
        self, frame_names: Sequence[str], coordinates: FloatArray
    ) -> FloatArray:
        """k x 3 array of the origins [m] in world of ``frame_names``."""
        ids = [self.frame_id(n) for n in frame_names]
        q = self.q_from_coordinates(self.check_coordinates(coordinates))
        pin.framesForwardKinematics(self.model, self.data, q)
        return np.array([self.data.oMf[i].translation for i in ids])


@dataclass(frozen=True)
class RobotPose:
    """A whole-robot configuration in readable units.

    Attributes:
        base_xy_yaw: base pose in world ``(x [m], y [m], yaw [rad])``.
        torso_height_m: torso lift [m], in [0, 0.31].
        arm_rad: 7 joint angles [rad] per arm, ordered as :data:`ARM_JOINTS`.
    """

    base_xy_yaw: tuple[float, float, float] = (0.0, 0.0, 0.0)
    torso_height_m: float = 0.0
    arm_rad: Mapping[Arm, tuple[float, ...]] = field(
        default_factory=lambda: {"left": (0.0,) * 7, "right": (0.0,) * 7}
    )

    def values_by_coordinate(self) -> dict[str, float]:
        """Value of every coordinate name of the full robot."""
        values = {
            f"{BASE_JOINT}_x": self.base_xy_yaw[0],
            f"{BASE_JOINT}_y": self.base_xy_yaw[1],
            f"{BASE_JOINT}_yaw": self.base_xy_yaw[2],
            TORSO_JOINT: self.torso_height_m,
        }
        for arm in ARMS:
            angles = self.arm_rad[arm]
            if len(angles) != 7:
                raise InvalidConfiguration(f"arm {arm!r} needs 7 joint angles, got {len(angles)}")
            values.update(zip(ARM_JOINTS[arm], angles, strict=True))
        return values


class RobotModel:
    """The PR2 with a planar base and its reduced chains.

    Build with :func:`load_pr2` (cached) or ``RobotModel(urdf_path)``.
    """

    def __init__(self, urdf_path: Path | None = None) -> None:
        self.urdf_path = urdf_path if urdf_path is not None else find_pr2_urdf()
        if not self.urdf_path.is_file():
            raise RobotDataNotFound(ROBOT_PACKAGE, f"{self.urdf_path} is not a file")
        try:
            self.full_model: pin.Model = pin.buildModelFromUrdf(
                str(self.urdf_path), pin.JointModelPlanar(), BASE_JOINT
            )
        except (RuntimeError, ValueError) as exc:
            raise RobotDataNotFound(ROBOT_PACKAGE, f"cannot parse {self.urdf_path}: {exc}") from exc
        for name in (*TOOL_FRAMES.values(), ROBOT_FRAME):
            if not self.full_model.existFrame(name):
                raise FrameNotFound(name, [f.name for f in self.full_model.frames])
        self._chains: dict[str, KinematicChain] = {}

    def neutral_pose(self) -> RobotPose:
        """All joints at zero, base at the world origin (arms straight forward)."""
        return RobotPose()

    def tucked_pose(self, torso_height_m: float = 0.0) -> RobotPose:
        """Arms tucked (PR2 ``tuck_arms``), base at the world origin."""
        return RobotPose(torso_height_m=torso_height_m, arm_rad=dict(TUCKED_ARM_RAD))

    def full_q(self, pose: RobotPose) -> FloatArray:
        """Pinocchio configuration of the full model (grippers and head at zero)."""
        model = self.full_model
        q = pin.neutral(model)
        values = pose.values_by_coordinate()
        x, y, yaw = pose.base_xy_yaw
        base = model.joints[model.getJointId(BASE_JOINT)]
        q[base.idx_q : base.idx_q + 4] = (x, y, np.cos(yaw), np.sin(yaw))
        for name, value in values.items():
            if name.startswith(BASE_JOINT):
                continue
            joint = model.joints[model.getJointId(name)]
            if joint.nq == 2:
                q[joint.idx_q : joint.idx_q + 2] = (np.cos(value), np.sin(value))
            else:
                q[joint.idx_q] = value
        return q

    def chain(self, name: str, reference: RobotPose | None = None) -> KinematicChain:
        """The reduced chain ``name``; locked joints are taken from ``reference``.

        With ``reference=None`` the locked joints are at the neutral pose and the
        chain is cached on this instance.
        """
        if name not in CHAIN_LAYOUT:
            raise ChainNotFound(name, CHAIN_LAYOUT)
        if reference is None and name in self._chains:
            return self._chains[name]
        chain = self._build_chain(name, reference or self.neutral_pose())
        if reference is None:
            self._chains[name] = chain
        return chain

    def coordinates_for(self, chain: KinematicChain, pose: RobotPose) -> FloatArray:
        """The coordinate vector of ``chain`` that matches ``pose``."""
        values = pose.values_by_coordinate()
        return chain.normalise(np.array([values[n] for n in chain.coordinate_names]))

    def _build_chain(self, name: str, reference: RobotPose) -> KinematicChain:
        use_base, use_torso, arms = CHAIN_LAYOUT[name]
        moving = [BASE_JOINT] if use_base else []
        if use_torso:
            moving.append(TORSO_JOINT)
        for arm in arms:
            moving.extend(ARM_JOINTS[arm])
        full = self.full_model
        lock = [j for j in range(1, full.njoints) if full.names[j] not in moving]
        reduced = pin.buildReducedModel(full, lock, self.full_q(reference))
        names = tuple(reduced.names[j] for j in range(1, reduced.njoints))
        coord_names: list[str] = []
        lower: list[float] = []
        upper: list[float] = []
        continuous: list[bool] = []
        for j, jname in enumerate(names, start=1):
            joint = reduced.joints[j]
            short = joint.shortname()
            if short == "JointModelPlanar":
                coord_names += [f"{jname}_x", f"{jname}_y", f"{jname}_yaw"]
                lower += [-np.inf] * 3
                upper += [np.inf] * 3
                continuous += [False, False, True]
            elif short.startswith("JointModelRUB"):
                coord_names.append(jname)
                lower.append(-np.inf)
                upper.append(np.inf)
                continuous.append(True)
            else:
                coord_names.append(jname)
                lower.append(float(reduced.lowerPositionLimit[joint.idx_q]))
                upper.append(float(reduced.upperPositionLimit[joint.idx_q]))
                continuous.append(False)
        return KinematicChain(
            name=name,
            model=reduced,
            joint_names=names,
            coordinate_names=tuple(coord_names),
            lower_limits=np.array(lower),
            upper_limits=np.array(upper),
            continuous=np.array(continuous, dtype=bool),
            arms=arms,
        )


@functools.lru_cache(maxsize=2)
def load_pr2(urdf_path: Path | None = None) -> RobotModel:
    """Load (once per path) the PR2 model from the installed ``example-robot-data``."""
    return RobotModel(urdf_path)
