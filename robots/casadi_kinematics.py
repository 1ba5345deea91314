"""Symbolic forward kinematics in CasADi, built from a chain's Pinocchio model.

The ``pin`` wheel has no ``pinocchio.casadi``; this module walks the reduced
model's joint placements and joint types (revolute about x/y/z or an unaligned
axis, unbounded revolute, prismatic, planar) and composes the placements as
CasADi ``SX`` expressions of the chain's joint coordinates [m, rad].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from skillcompose.robots.errors import InvalidConfiguration
from skillcompose.robots.model import TOOL_FRAMES, Arm, KinematicChain

_AXES = {
    "X": np.array([1.0, 0.0, 0.0]),
    "Y": np.array([0.0, 1.0, 0.0]),
    "Z": np.array([0.0, 0.0, 1.0]),
}


@dataclass(frozen=True)
class SymbolicPlacement:
    """A placement as CasADi expressions: ``rotation`` (3x3) and ``translation_m`` (3x1)."""

    rotation: ca.SX
    translation_m: ca.SX

    def compose(self, other: SymbolicPlacement) -> SymbolicPlacement:
        """``self * other`` (apply ``other`` first, expressed in ``self``)."""
        return SymbolicPlacement(
            self.rotation @ other.rotation, self.rotation @ other.translation_m + self.translation_m
        )


def _constant(rotation: np.ndarray, translation: np.ndarray) -> SymbolicPlacement:
    return SymbolicPlacement(ca.SX(ca.DM(rotation)), ca.SX(ca.DM(translation.reshape(3, 1))))


def _axis_rotation(axis: np.ndarray, angle: ca.SX) -> ca.SX:
    """Rodrigues' rotation about a unit ``axis`` by ``angle`` [rad]."""
    x, y, z = (float(a) for a in axis)
    c, s = ca.cos(angle), ca.sin(angle)
    t = 1 - c
    return ca.vertcat(
        ca.horzcat(t * x * x + c, t * x * y - s * z, t * x * z + s * y),
        ca.horzcat(t * x * y + s * z, t * y * y + c, t * y * z - s * x),
        ca.horzcat(t * x * z - s * y, t * y * z + s * x, t * z * z + c),
    )


def _joint_motion(shortname: str, joint: object, coords: ca.SX, iv: int) -> SymbolicPlacement:
    """Placement of a joint's child relative to its parent placement, symbolic."""
    zero = ca.SX.zeros(3, 1)
    if shortname == "JointModelPlanar":
        x, y, yaw = coords[iv], coords[iv + 1], coords[iv + 2]
        return SymbolicPlacement(_axis_rotation(_AXES["Z"], yaw), ca.vertcat(x, y, 0))
    if shortname.startswith(("JointModelRUB", "JointModelR")) and "Unaligned" not in shortname:
        axis = _AXES[shortname[-1]]
        return SymbolicPlacement(_axis_rotation(axis, coords[iv]), zero)
    if shortname == "JointModelRevoluteUnaligned":
        axis = np.asarray(joint.extract().axis).ravel()  # type: ignore[attr-defined]
        return SymbolicPlacement(_axis_rotation(axis, coords[iv]), zero)
    if shortname.startswith("JointModelP") and "Unaligned" not in shortname:
        axis = _AXES[shortname[-1]]
        return SymbolicPlacement(ca.SX.eye(3), ca.SX(ca.DM(axis.reshape(3, 1))) * coords[iv])
    if shortname == "JointModelPrismaticUnaligned":
        axis = np.asarray(joint.extract().axis).ravel()  # type: ignore[attr-defined]
        return SymbolicPlacement(ca.SX.eye(3), ca.SX(ca.DM(axis.reshape(3, 1))) * coords[iv])
    raise InvalidConfiguration(
        f"joint type {shortname} is not supported by the CasADi kinematics; supported: "
        "revolute (x/y/z/unaligned), unbounded revolute, prismatic (x/y/z/unaligned), planar"
    )


def angular_jacobian(rotation: ca.SX, coords: ca.SX) -> ca.SX:
    """3 x n angular Jacobian in world axes: column i is ``vee(dR/dq_i R^T)`` [rad/s]."""
    n = coords.shape[0]
    columns = []
    for i in range(n):
        d_rot = ca.jacobian(ca.vec(rotation), coords[i])
        d_rot = ca.reshape(d_rot, 3, 3)
        skew = d_rot @ rotation.T
        columns.append(ca.vertcat(skew[2, 1], skew[0, 2], skew[1, 0]))
    return ca.horzcat(*columns)


@dataclass
class CasadiKinematics:
    """Symbolic kinematics of one chain.

    Attributes:
        chain: the numeric chain the expressions are built from.
        coordinates: the ``SX`` symbol (n x 1) of joint coordinates [m, rad].
        joint_placements_world: symbolic world placement of every joint of the model.
    """

    chain: KinematicChain
    coordinates: ca.SX = field(init=False)
    joint_placements_world: list[SymbolicPlacement] = field(init=False)

    def __post_init__(self) -> None:
        model = self.chain.model
        self.coordinates = ca.SX.sym("q", model.nv)
        identity = SymbolicPlacement(ca.SX.eye(3), ca.SX.zeros(3, 1))
        placements = [identity]
        for jid in range(1, model.njoints):
            joint = model.joints[jid]
            fixed = model.jointPlacements[jid]
            parent = placements[model.parents[jid]]
            local = _constant(fixed.rotation, fixed.translation)
            motion = _joint_motion(joint.shortname(), joint, self.coordinates, joint.idx_v)
            placements.append(parent.compose(local).compose(motion))
        self.joint_placements_world = placements

    def transform_frame_to_world(self, frame_name: str) -> SymbolicPlacement:
        """Symbolic world placement of a frame of the chain."""
        fid = self.chain.frame_id(frame_name)
        frame = self.chain.model.frames[fid]
        parent = self.joint_placements_world[frame.parentJoint]
        return parent.compose(_constant(frame.placement.rotation, frame.placement.translation))

    def transform_tool_to_world(self, arm: Arm) -> SymbolicPlacement:
        """Symbolic world placement of the tool frame of ``arm``."""
        self.chain.tool_frame_id(arm)
        return self.transform_frame_to_world(TOOL_FRAMES[arm])

    def forward_function(self, frame_name: str) -> ca.Function:
        """``f(q) -> (position_m 3x1, rotation 3x3)`` of ``frame_name`` in world."""
        placement = self.transform_frame_to_world(frame_name)
        return ca.Function(
            f"fk_{frame_name}",
            [self.coordinates],
            [placement.translation_m, placement.rotation],
            ["q"],
            ["position_m", "rotation"],
        )

    def jacobian_function(self, frame_name: str) -> ca.Function:
        """``J(q) -> 6 x n`` (linear [m/s] over angular [rad/s], world axes) of ``frame_name``."""
        placement = self.transform_frame_to_world(frame_name)
        linear = ca.jacobian(placement.translation_m, self.coordinates)
        angular = angular_jacobian(placement.rotation, self.coordinates)
        return ca.Function(
            f"jac_{frame_name}",
            [self.coordinates],
            [ca.vertcat(linear, angular)],
            ["q"],
            ["jacobian"],
        )
