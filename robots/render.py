"""Pictures of a robot configuration with a table and boxes (matplotlib 3-D, PNG).

The PR2 is drawn with its real meshes: Pinocchio reads the visual geometry of the URDF in
``example-robot-data`` (a :class:`pinocchio.GeometryModel`) and places every link for the
configuration; trimesh loads each mesh file and reduces it to at most
:data:`MAX_FACES_PER_MESH` triangles (quadric decimation); matplotlib draws all triangles,
shaded by one light, in one ``Poly3DCollection`` together with the scene's boxes, so that
they are depth-sorted together. The meshes are loaded once per process and robot file.
Uses matplotlib's object API with the Agg canvas: no pyplot, no global backend switch, no
display or GPU needed. Why this and not an OpenGL renderer: see docs/robots.md.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from skillcompose.robots.collision import Box, Scene
from skillcompose.robots.errors import RobotDataNotFound
from skillcompose.robots.model import (
    ARMS,
    BASE_JOINT,
    TOOL_FRAMES,
    FloatArray,
    RobotModel,
    RobotPose,
)

__all__ = ["MAX_FACES_PER_MESH", "Camera", "LinkMesh", "RobotTriangles", "fit_camera",
           "link_meshes", "render_configuration", "robot_triangles", "scene_camera"]

MAX_FACES_PER_MESH = 400
"""Each link's mesh is decimated to at most this many triangles (the PR2: 13 777 in all,
from 27 561)."""

_LIGHT_DIRECTION = np.array([0.35, -0.45, 0.82]) / np.linalg.norm([0.35, -0.45, 0.82])
_GREY = np.array([0.72, 0.73, 0.76])


@dataclass(frozen=True)
class LinkMesh:
    """One visual mesh of the robot, in the frame of its geometry object."""

    name: str  # the geometry object's name, e.g. "l_upper_arm_link_0"
    geometry_id: int  # index in the visual GeometryModel
    vertices_m: FloatArray  # (n, 3), scaled as the URDF says
    faces: np.ndarray  # (m, 3) vertex indices
    colour: FloatArray  # RGB in [0, 1]


@dataclass(frozen=True)
class RobotTriangles:
    """The robot's triangles in the world frame for one configuration."""

    triangles_m: FloatArray  # (n, 3, 3): n triangles, 3 corners, xyz [m]
    colours: FloatArray  # (n, 3) RGB of each triangle before shading
    link_of_triangle: tuple[str, ...]  # the geometry object each triangle belongs to


@functools.lru_cache(maxsize=4)
def _visual_geometry(urdf_path: Path) -> tuple[pin.Model, pin.GeometryModel, tuple[LinkMesh, ...]]:
    import trimesh

    model = pin.buildModelFromUrdf(str(urdf_path), pin.JointModelPlanar(), BASE_JOINT)
    share = urdf_path.parents[4]  # .../share: package://example-robot-data/... resolves here
    try:
        geometry = pin.buildGeomFromUrdf(model, str(urdf_path), pin.GeometryType.VISUAL,
                                         package_dirs=[str(share)])
    except (RuntimeError, ValueError) as exc:
        raise RobotDataNotFound("example-robot-data",
                                f"cannot read the visual meshes of {urdf_path}: {exc}") from exc
    meshes = []
    for gid, obj in enumerate(geometry.geometryObjects):
        path = Path(obj.meshPath)
        if path.suffix.lower() not in (".stl", ".dae", ".obj", ".ply") or not path.is_file():
            continue  # the PR2's sensor frames are small boxes: not drawn
        try:
            mesh = trimesh.load_mesh(path, force="mesh")
        except (ValueError, OSError) as exc:
            raise RobotDataNotFound("example-robot-data",
                                    f"cannot read the mesh {path}: {exc}") from exc
        if len(mesh.faces) > MAX_FACES_PER_MESH:
            mesh = mesh.simplify_quadric_decimation(face_count=MAX_FACES_PER_MESH)
        rgb = np.asarray(obj.meshColor[:3], dtype=float)
        colour = 0.35 * rgb + 0.65 * _GREY  # the URDF's colours, toned down towards grey
        meshes.append(LinkMesh(obj.name, gid, np.asarray(mesh.vertices) * obj.meshScale,
                               np.asarray(mesh.faces), colour))
    return model, geometry, tuple(meshes)


def link_meshes(model: RobotModel) -> tuple[LinkMesh, ...]:
    """The robot's visual meshes, decimated; loaded once per process and robot file."""
    return _visual_geometry(model.urdf_path)[2]


def robot_triangles(model: RobotModel, pose: RobotPose) -> RobotTriangles:
    """Every triangle of the robot's visual meshes, placed for ``pose`` in the world frame."""
    visual_model, geometry, meshes = _visual_geometry(model.urdf_path)
    data = visual_model.createData()
    geometry_data = pin.GeometryData(geometry)
    pin.updateGeometryPlacements(visual_model, data, geometry, geometry_data,
                                 model.full_q(pose))
    triangles, colours, owners = [], [], []
    for mesh in meshes:
        placement = geometry_data.oMg[mesh.geometry_id]
        world = mesh.vertices_m @ placement.rotation.T + placement.translation
        triangles.append(world[mesh.faces])
        colours.append(np.repeat(mesh.colour[None, :], len(mesh.faces), axis=0))
        owners.extend([mesh.name] * len(mesh.faces))
    return RobotTriangles(np.concatenate(triangles), np.concatenate(colours), tuple(owners))


def _box_faces(box: Box, tile_m: float = 0.0) -> list[FloatArray]:
    """The six faces of ``box``; with ``tile_m``, each cut into tiles at most that wide, so
    that the picture's depth sort (one depth per polygon) orders them right among the
    robot's small triangles."""
    corners = box.corners_xy_m()
    z0 = box.center_m[2] - box.half_extents_m[2]
    z1 = box.center_m[2] + box.half_extents_m[2]
    bottom = np.column_stack([corners, np.full(4, z0)])
    top = np.column_stack([corners, np.full(4, z1)])
    faces = [bottom, top]
    for i in range(4):
        j = (i + 1) % 4
        faces.append(np.array([bottom[i], bottom[j], top[j], top[i]]))
    if tile_m <= 0.0:
        return faces
    tiles = []
    for f in faces:  # a parallelogram f[0] + s (f[1] - f[0]) + t (f[3] - f[0])
        u, v = f[1] - f[0], f[3] - f[0]
        nu = max(1, int(np.ceil(np.linalg.norm(u) / tile_m)))
        nv = max(1, int(np.ceil(np.linalg.norm(v) / tile_m)))
        for a in range(nu):
            for b in range(nv):
                p = f[0] + u * a / nu + v * b / nv
                tiles.append(np.array([p, p + u / nu, p + u / nu + v / nv, p + v / nv]))
    return tiles


def _shade(polygons: list[FloatArray], colours: FloatArray) -> FloatArray:
    """Lambert shading of each polygon by one light from above, both sides lit."""
    shades = np.empty(len(polygons))
    for k, poly in enumerate(polygons):
        n = np.cross(poly[1] - poly[0], poly[2] - poly[0])
        norm = np.linalg.norm(n)
        shades[k] = abs(n @ _LIGHT_DIRECTION) / norm if norm > 0 else 0.5
    return np.clip(colours * (0.45 + 0.55 * shades[:, None]), 0.0, 1.0)


def _box_colour(box: Box) -> FloatArray:
    if "table" in box.name or "shelf" in box.name:
        return np.array([0.66, 0.50, 0.34])
    if any(word in box.name for word in ("obstacle", "wall")):
        return np.array([0.55, 0.55, 0.58])
    return np.array([0.15, 0.60, 0.30])


@dataclass(frozen=True)
class Camera:
    """Where a picture looks from: angles [deg] and the cube of space it shows [m]."""

    azim_deg: float
    elev_deg: float
    centre_m: tuple[float, float, float]
    half_width_m: float


def fit_camera(points_m: FloatArray, facing_rad: float) -> Camera:
    """A camera that shows every point (n, 3) [m] at one scale, looking from behind the
    right of a robot that faces ``facing_rad`` (world yaw): its arm, the table and the
    objects side by side."""
    low, high = points_m.min(axis=0), points_m.max(axis=0)
    low[2] = 0.0
    centre = (low + high) / 2
    half = max(float(np.max(high - low)) / 2 + 0.05, 0.6)
    return Camera(float(np.degrees(facing_rad)) - 105.0, 28.0,
                  (float(centre[0]), float(centre[1]), half), half)


def scene_camera(model: RobotModel, poses: list[RobotPose], scene: Scene | None) -> Camera:
    """One camera for pictures of ``poses`` in ``scene`` (a replay's frames): it shows the
    robot in each pose and every box, facing from the first pose to the table, if any."""
    points = [robot_triangles(model, p).triangles_m.reshape(-1, 3) for p in poses]
    boxes = list((scene or Scene()).boxes)
    points += [np.asarray(f) for b in boxes for f in _box_faces(b)]
    x, y, yaw = poses[0].base_xy_yaw
    table = next((b for b in boxes if "table" in b.name), None)
    if table is not None and np.hypot(table.center_m[0] - x, table.center_m[1] - y) > 0.05:
        yaw = float(np.arctan2(table.center_m[1] - y, table.center_m[0] - x))
    return fit_camera(np.concatenate(points), yaw)


def render_configuration(
    model: RobotModel,
    pose: RobotPose,
    path: Path,
    *,
    scene: Scene | None = None,
    targets_m: list[FloatArray] | None = None,
    title: str = "",
    camera: Camera | None = None,
) -> Path:
    """Render ``pose`` (and the scene) to a PNG at ``path``; returns ``path``. ``camera``
    defaults to :func:`scene_camera` of this pose; give one to keep it across pictures."""
    robot = robot_triangles(model, pose)
    fig = Figure(figsize=(7, 6.5))
    ax = fig.add_subplot(projection="3d", computed_zorder=False)
    # one collection, so that the robot's triangles and the boxes' tiles are depth-sorted
    # together
    polygons = list(robot.triangles_m)
    colours = [robot.colours]
    for box in (scene or Scene()).boxes:
        # each tile as two triangles: polygons of one size (matplotlib pads mixed sizes with
        # values that can overflow its automatic limits)
        tiles = [tri for t in _box_faces(box, tile_m=0.06) for tri in (t[:3], t[[0, 2, 3]])]
        polygons += tiles
        colours.append(np.repeat(_box_colour(box)[None, :], len(tiles), axis=0))
    shaded = _shade(polygons, np.concatenate(colours))
    ax.add_collection3d(Poly3DCollection(  # edges in the face's colour: no seams
        polygons, facecolors=shaded, edgecolors=shaded, linewidths=0.3, zorder=1))
    full = model.full_model
    data = full.createData()
    pin.framesForwardKinematics(full, data, model.full_q(pose))
    for arm in ARMS:  # the tool frames, which the skills' targets refer to
        tool = data.oMf[full.getFrameId(TOOL_FRAMES[arm])]
        for axis, colour in zip(range(3), ("r", "g", "b"), strict=True):
            tip = tool.translation + 0.08 * tool.rotation[:, axis]
            ax.plot(*np.column_stack([tool.translation, tip]), color=colour, linewidth=1.5,
                    zorder=4)
    for point in targets_m or []:
        ax.scatter(*point, color="tab:red", marker="x", s=60, zorder=5)
    view = camera or scene_camera(model, [pose], scene)
    c = view.centre_m
    ax.set_xlim(c[0] - view.half_width_m, c[0] + view.half_width_m)
    ax.set_ylim(c[1] - view.half_width_m, c[1] + view.half_width_m)
    ax.set_zlim(0.0, 2 * view.half_width_m)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.view_init(elev=view.elev_deg, azim=view.azim_deg)
    x, y, yaw = pose.base_xy_yaw
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_pane_color((0.96, 0.96, 0.97, 1.0))
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):  # at most 5 ticks: labels never overlap
        axis.set_major_locator(MaxNLocator(nbins=5))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.zaxis.set_rotate_label(False)  # matplotlib turns it upside down on this view
    ax.set_zlabel("z [m]", rotation=90)
    ax.set_title(
        title
        or f"PR2  base ({x:.2f} m, {y:.2f} m, {yaw:.2f} rad)  torso {pose.torso_height_m:.2f} m",
        fontsize=10,
    )
    fig.subplots_adjust(left=0.0, right=1.0, bottom=0.02, top=0.95)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path
