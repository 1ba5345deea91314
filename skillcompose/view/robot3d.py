"""The PR2's visual meshes placed for a blackboard's configuration, and the world's boxes.

Pinocchio reads the visual geometry of ``example-robot-data``'s PR2 URDF (its STL meshes,
boxes and a cylinder); :func:`frame` places every piece for the robot pose a kinematic
blackboard holds (:func:`skillcompose.skills.replay.robot_pose`) and lists the table, obstacles and
objects (:func:`skillcompose.skills.replay.world_scene`). The browser loads the meshes themselves
from
:func:`mesh_root`, served by the viewer. Importing this module loads Pinocchio.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from skillcompose import Blackboard
from skillcompose.robots.collision import Box, Scene
from skillcompose.robots.model import RobotPose, load_pr2
from skillcompose.skills.replay import robot_pose, world_scene

__all__ = ["PARTICLE_SIZE_M", "Piece", "WorldBox", "frame", "frame_at", "mesh_root", "pieces"]

_X90 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # y-axis → z-axis


@dataclass(frozen=True)
class Piece:
    """One visual part of the robot: a mesh (``mesh`` relative to :func:`mesh_root`), a box
    (``size`` in m) or a cylinder (``size`` = radius, length), with its colour."""

    name: str
    kind: str  # mesh, box, cylinder
    mesh: str
    size: tuple[float, ...]
    scale: tuple[float, float, float]
    colour: str


@dataclass(frozen=True)
class WorldBox:
    name: str
    centre: tuple[float, float, float]
    size: tuple[float, float, float]  # full edge lengths [m]
    yaw: float  # [rad]


def _share(urdf: Path) -> Path:
    # .../share/example-robot-data/robots/pr2_description/urdf/pr2.urdf
    return urdf.parents[4]


@functools.cache
def _geometry() -> tuple[Any, Any]:
    model = load_pr2()
    geom = pin.buildGeomFromUrdf(model.full_model, str(model.urdf_path), pin.GeometryType.VISUAL,
                                 package_dirs=[str(_share(model.urdf_path))])
    return model, geom


def mesh_root() -> Path:
    """The folder the mesh paths of :func:`pieces` are relative to: the PR2's package."""
    model, _ = _geometry()
    return Path(model.urdf_path).parents[1]


def _hex(rgba: Any) -> str:
    r, g, b = (int(255 * min(1.0, max(0.0, float(c)))) for c in list(rgba)[:3])
    if (r, g, b) == (255, 255, 255):  # the URDF's "no colour": a light grey
        r, g, b = (200, 204, 210)
    return f"#{r:02x}{g:02x}{b:02x}"


@functools.cache
def pieces() -> tuple[Piece, ...]:
    """The robot's visual parts, in the order :func:`frame` places them."""
    _, geom = _geometry()
    root = mesh_root()
    out = []
    for g in geom.geometryObjects:
        shape = g.geometry
        kind = type(shape).__name__
        scale = tuple(float(v) for v in g.meshScale)
        if kind.startswith("BVH") and str(g.meshPath).lower().endswith(".stl"):
            rel = Path(g.meshPath).resolve().relative_to(root.resolve()).as_posix()
            out.append(Piece(g.name, "mesh", rel, (), scale, _hex(g.meshColor)))  # type: ignore[arg-type]
        elif kind == "Box":
            size = tuple(2.0 * float(v) for v in shape.halfSide)
            out.append(Piece(g.name, "box", "", size, scale, _hex(g.meshColor)))  # type: ignore[arg-type]
        elif kind == "Cylinder":
            size = (float(shape.radius), 2.0 * float(shape.halfLength))
            out.append(Piece(g.name, "cylinder", "", size, scale, _hex(g.meshColor)))  # type: ignore[arg-type]
    return tuple(out)


def frame(bb: Blackboard) -> dict[str, Any]:
    """Where every piece of :func:`pieces` is (``poses``: position [m] and 3×3 rotation) for
    the robot on ``bb``, and the world's boxes (``boxes``)."""
    boxes = [_world_box(b) for b in world_scene(bb).boxes]
    for key, value in sorted(bb.to_dict().items()):  # the jug, the glass: points, no size
        name = key.removesuffix("_position_world")
        if (key.endswith("_position_world") and name not in ("gripper", "object")
                and isinstance(value, (tuple, list)) and len(value) == 3):
            boxes.append(WorldBox(name, (float(value[0]), float(value[1]),
                                         float(value[2]) - 0.06), (0.07, 0.07, 0.12), 0.0))
    return {"poses": _poses(robot_pose(bb)), "boxes": boxes}


PARTICLE_SIZE_M = 0.014
"""Edge of the cube a water particle is drawn as [m]."""


def frame_at(pose: RobotPose, scene: Scene, particles: Sequence[Any] = ()) -> dict[str, Any]:
    """:func:`frame` for a robot ``pose`` and a ``scene`` given directly (a sample of a
    dynamic episode's recording), each water particle a small cube named ``particle_<i>``."""
    boxes = [_world_box(b) for b in scene.boxes]
    boxes += [WorldBox(f"particle_{i}", (float(p[0]), float(p[1]), float(p[2])),
                       (PARTICLE_SIZE_M,) * 3, 0.0) for i, p in enumerate(particles)]
    return {"poses": _poses(pose), "boxes": boxes}


def _world_box(b: Box) -> WorldBox:
    return WorldBox(b.name, (float(b.center_m[0]), float(b.center_m[1]), float(b.center_m[2])),
                    tuple(2.0 * float(h) for h in b.half_extents_m),  # type: ignore[arg-type]
                    float(b.yaw_rad))


def _poses(pose: RobotPose) -> list[tuple[tuple[float, ...], list[list[float]]]]:
    model, geom = _geometry()
    data = model.full_model.createData()
    gdata = pin.GeometryData(geom)
    pin.forwardKinematics(model.full_model, data, model.full_q(pose))
    pin.updateGeometryPlacements(model.full_model, data, geom, gdata)
    by_name = {g.name: k for k, g in enumerate(geom.geometryObjects)}
    poses = []
    for piece in pieces():
        placement = gdata.oMg[by_name[piece.name]]
        rot = np.asarray(placement.rotation)
        if piece.kind == "cylinder":
            rot = rot @ _X90  # three.js cylinders stand along y, coal's along z
        poses.append((tuple(round(float(v), 5) for v in placement.translation),
                      [[round(float(v), 6) for v in row] for row in rot]))
    return poses
