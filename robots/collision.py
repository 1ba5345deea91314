"""Collision checks of the PR2 against a table and boxes, with exact box geometry.

The robot is approximated conservatively: the mobile base and body by an upright
box of the base footprint (0.668 m square, floor to 1.4 m), each arm by spheres
swept along the segments shoulder -> elbow -> wrist -> tool frame. Obstacles are
boxes (a table is a box from the floor to its top). Self-collisions are not
checked. Distances are exact for sphere-box and box-box (separating axes).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from skillcompose.robots.errors import InvalidConfiguration
from skillcompose.robots.model import (
    ARM_JOINTS,
    ROBOT_FRAME,
    TOOL_FRAMES,
    FloatArray,
    KinematicChain,
)

#: Base/body footprint half extents (x, y) [m] and height [m].
BASE_HALF_EXTENTS_M = (0.334, 0.334)
BODY_HEIGHT_M = 1.4
#: Radius [m] of the circle around the base footprint (used by the optimiser).
BASE_RADIUS_M = float(np.hypot(*BASE_HALF_EXTENTS_M))
#: Arm segments as (from joint, to joint or tool frame, sphere radius [m]).
_ARM_SEGMENTS = (
    ("shoulder_lift_joint", "elbow_flex_joint", 0.08),
    ("elbow_flex_joint", "wrist_flex_joint", 0.065),
    ("wrist_flex_joint", "tool", 0.045),
)


@dataclass(frozen=True)
class Box:
    """An upright box obstacle.

    Attributes:
        center_m: centre in world (x, y, z) [m].
        half_extents_m: half sizes along the box axes [m].
        yaw_rad: rotation about world z [rad].
        name: a label for reports.
    """

    center_m: tuple[float, float, float]
    half_extents_m: tuple[float, float, float]
    yaw_rad: float = 0.0
    name: str = "box"

    def __post_init__(self) -> None:
        values = np.array([*self.center_m, *self.half_extents_m, self.yaw_rad], dtype=float)
        if values.shape != (7,) or not np.all(np.isfinite(values)) or min(self.half_extents_m) <= 0:
            raise InvalidConfiguration(
                f"box {self.name!r}: centre and half extents need 3 finite values each, "
                f"half extents > 0; got centre {self.center_m}, half extents {self.half_extents_m}"
            )

    @classmethod
    def table(
        cls,
        center_xy_m: tuple[float, float],
        size_xy_m: tuple[float, float],
        height_m: float,
        yaw_rad: float = 0.0,
        name: str = "table",
    ) -> Box:
        """A table as a solid box from the floor to its top at ``height_m``."""
        return cls(
            (center_xy_m[0], center_xy_m[1], height_m / 2),
            (size_xy_m[0] / 2, size_xy_m[1] / 2, height_m / 2),
            yaw_rad,
            name,
        )

    @property
    def top_z_m(self) -> float:
        """Height of the top face [m]."""
        return self.center_m[2] + self.half_extents_m[2]

    def points_to_box_frame(self, points_world_m: FloatArray) -> FloatArray:
        """Express world points (k x 3) in the box frame [m]."""
        c, s = np.cos(self.yaw_rad), np.sin(self.yaw_rad)
        rel = np.atleast_2d(points_world_m) - np.asarray(self.center_m)
        return np.column_stack(
            [c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1], rel[:, 2]]
        )

    def signed_distance_m(self, points_world_m: FloatArray) -> FloatArray:
        """Exact signed distance [m] from each point to the box (negative inside)."""
        d = np.abs(self.points_to_box_frame(points_world_m)) - np.asarray(self.half_extents_m)
        outside = np.linalg.norm(np.maximum(d, 0.0), axis=1)
        inside = np.minimum(d.max(axis=1), 0.0)
        return np.asarray(outside + inside)

    def corners_xy_m(self) -> FloatArray:
        """The 4 footprint corners in world (x, y) [m]."""
        c, s = np.cos(self.yaw_rad), np.sin(self.yaw_rad)
        hx, hy = self.half_extents_m[0], self.half_extents_m[1]
        local = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
        rot = np.array([[c, -s], [s, c]])
        return np.asarray(local @ rot.T + np.asarray(self.center_m[:2]))

    def overlaps(self, other: Box, margin_m: float = 0.0) -> bool:
        """Whether two upright boxes, each grown by ``margin_m / 2``, intersect (exact SAT)."""
        z_gap = abs(self.center_m[2] - other.center_m[2]) - (
            self.half_extents_m[2] + other.half_extents_m[2]
        )
        if z_gap > margin_m:
            return False
        a, b = self.corners_xy_m(), other.corners_xy_m()
        for yaw in (self.yaw_rad, other.yaw_rad):
            for axis in (
                np.array([np.cos(yaw), np.sin(yaw)]),
                np.array([-np.sin(yaw), np.cos(yaw)]),
            ):
                pa, pb = a @ axis, b @ axis
                if pa.max() + margin_m < pb.min() or pb.max() + margin_m < pa.min():
                    return False
        return True


@dataclass(frozen=True)
class Scene:
    """Obstacles around the robot (a table and boxes on it), in world."""

    boxes: tuple[Box, ...] = ()

    def with_box(self, box: Box) -> Scene:
        """A new scene with ``box`` added."""
        return Scene((*self.boxes, box))


@dataclass(frozen=True)
class CollisionReport:
    """Result of a collision query.

    Attributes:
        collides: whether any robot part is closer than the margin to a box.
        clearance_m: smallest signed distance (robot part to box) minus margin [m].
        pairs: ``(robot part, box name)`` pairs in collision.
    """

    collides: bool
    clearance_m: float
    pairs: tuple[tuple[str, str], ...]


def base_box(chain: KinematicChain, coordinates: FloatArray) -> Box:
    """The base/body box of the robot in world at ``coordinates``."""
    placement = chain.transform_frame_to_world(ROBOT_FRAME, coordinates)
    yaw = float(np.arctan2(placement.rotation[1, 0], placement.rotation[0, 0]))
    x, y, _ = placement.translation
    return Box(
        (float(x), float(y), BODY_HEIGHT_M / 2),
        (*BASE_HALF_EXTENTS_M, BODY_HEIGHT_M / 2),
        yaw,
        "robot_base",
    )


def arm_spheres(
    chain: KinematicChain, coordinates: FloatArray
) -> tuple[FloatArray, FloatArray, list[str]]:
    """Sphere centres (k x 3) [m], radii (k,) [m] and part names of the chain's arms."""
    names: list[str] = []
    for arm in chain.arms:
        prefix = ARM_JOINTS[arm][0][:2]
        names += [
            prefix + s for s in ("shoulder_lift_joint", "elbow_flex_joint", "wrist_flex_joint")
        ]
        names.append(TOOL_FRAMES[arm])
    # joints are frames too in Pinocchio models built from URDF
    origins = chain.frame_origins_world(names, coordinates)
    centres: list[FloatArray] = []
    radii: list[float] = []
    parts: list[str] = []
    for a_index, arm in enumerate(chain.arms):
        points = {
            "shoulder_lift_joint": origins[4 * a_index],
            "elbow_flex_joint": origins[4 * a_index + 1],
            "wrist_flex_joint": origins[4 * a_index + 2],
            "tool": origins[4 * a_index + 3],
        }
        for start, end, radius in _ARM_SEGMENTS:
            p0, p1 = points[start], points[end]
            count = max(2, int(np.ceil(np.linalg.norm(p1 - p0) / radius)) + 1)
            for t in np.linspace(0.0, 1.0, count):
                centres.append(p0 + t * (p1 - p0))
                radii.append(radius)
                parts.append(f"{arm}:{start}->{end}")
    return np.array(centres), np.array(radii), parts


def check_collisions(
    chain: KinematicChain,
    coordinates: FloatArray,
    scene: Scene,
    *,
    margin_m: float = 0.0,
) -> CollisionReport:
    """Collisions between the robot (base/body and arm spheres) and the scene's boxes."""
    theta = chain.check_coordinates(coordinates)
    centres, radii, parts = arm_spheres(chain, theta)
    body = base_box(chain, theta)
    pairs: list[tuple[str, str]] = []
    clearance = np.inf
    for box in scene.boxes:
        gaps = box.signed_distance_m(centres) - radii - margin_m
        clearance = min(clearance, float(gaps.min()))
        for index in np.flatnonzero(gaps < 0.0):
            pair = (parts[index], box.name)
            if pair not in pairs:
                pairs.append(pair)
        if body.overlaps(box, margin_m):
            pairs.append(("robot_base", box.name))
            clearance = min(clearance, -margin_m)
    return CollisionReport(bool(pairs), clearance, tuple(pairs))


def collision_checker(scene: Scene, margin_m: float = 0.0) -> CollisionCheckFn:
    """A ``collides(chain, coordinates) -> bool`` callable for :meth:`IKSolver.solve`."""
    return CollisionCheckFn(scene, margin_m)


@dataclass(frozen=True)
class CollisionCheckFn:
    """Callable wrapper binding a scene and margin (see :func:`collision_checker`)."""

    scene: Scene
    margin_m: float = 0.0

    def __call__(self, chain: KinematicChain, coordinates: FloatArray) -> bool:
        return check_collisions(chain, coordinates, self.scene, margin_m=self.margin_m).collides


def scene_from_boxes(boxes: Sequence[Box]) -> Scene:
    """A scene from a sequence of boxes."""
    return Scene(tuple(boxes))
