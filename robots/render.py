"""Pictures of a robot configuration with a table and boxes (matplotlib 3-D, PNG).

Draws the base footprint, the kinematic tree as segments between joint origins,
small axes at each tool frame and the scene's boxes. Uses matplotlib's
object API with the Agg canvas: no pyplot, no global backend switch.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from robots.collision import BASE_HALF_EXTENTS_M, Box, Scene
from robots.model import ARMS, TOOL_FRAMES, FloatArray, RobotModel, RobotPose


def _box_faces(box: Box) -> list[FloatArray]:
    corners = box.corners_xy_m()
    z0 = box.center_m[2] - box.half_extents_m[2]
    z1 = box.center_m[2] + box.half_extents_m[2]
    bottom = np.column_stack([corners, np.full(4, z0)])
    top = np.column_stack([corners, np.full(4, z1)])
    faces = [bottom, top]
    for i in range(4):
        j = (i + 1) % 4
        faces.append(np.array([bottom[i], bottom[j], top[j], top[i]]))
    return faces


def render_configuration(
    model: RobotModel,
    pose: RobotPose,
    path: Path,
    *,
    scene: Scene | None = None,
    targets_m: list[FloatArray] | None = None,
    title: str = "",
) -> Path:
    """Render ``pose`` (and the scene) to a PNG at ``path``; returns ``path``."""
    full = model.full_model
    data = full.createData()
    q = model.full_q(pose)
    pin.framesForwardKinematics(full, data, q)
    fig = Figure(figsize=(8, 7))
    ax = fig.add_subplot(projection="3d")
    # kinematic tree: segment from each joint to its parent
    for jid in range(2, full.njoints):
        name = full.names[jid]
        if "gripper" in name or "head" in name or "laser" in name:
            continue
        parent = full.parents[jid]
        a, b = data.oMi[parent].translation, data.oMi[jid].translation
        ax.plot(*np.column_stack([a, b]), color="0.2", linewidth=2.5)
        ax.scatter(*b, color="tab:orange", s=12)
    for arm in ARMS:
        fid = full.getFrameId(TOOL_FRAMES[arm])
        wrist = data.oMi[full.frames[fid].parentJoint].translation
        tool = data.oMf[fid]
        ax.plot(*np.column_stack([wrist, tool.translation]), color="0.2", linewidth=2.5)
        for axis, colour in zip(range(3), ("r", "g", "b"), strict=True):
            tip = tool.translation + 0.08 * tool.rotation[:, axis]
            ax.plot(*np.column_stack([tool.translation, tip]), color=colour, linewidth=1.5)
        ax.text(*tool.translation, f" {arm}", fontsize=8)
    x, y, yaw = pose.base_xy_yaw
    base = Box((x, y, 0.15), (*BASE_HALF_EXTENTS_M, 0.15), yaw, "base")
    ax.add_collection3d(
        Poly3DCollection(_box_faces(base), facecolor="tab:blue", alpha=0.25, edgecolor="tab:blue")
    )
    for box in (scene or Scene()).boxes:
        colour = "tab:brown" if "table" in box.name else "tab:green"
        ax.add_collection3d(
            Poly3DCollection(_box_faces(box), facecolor=colour, alpha=0.35, edgecolor="0.3")
        )
    for point in targets_m or []:
        ax.scatter(*point, color="tab:red", marker="x", s=60)
    centre = np.array([x, y, 0.0])
    ax.set_xlim(centre[0] - 1.2, centre[0] + 1.2)
    ax.set_ylim(centre[1] - 1.2, centre[1] + 1.2)
    ax.set_zlim(0.0, 1.8)
    ax.set_box_aspect((2.4, 2.4, 1.8))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_title(
        title
        or f"PR2  base ({x:.2f} m, {y:.2f} m, {yaw:.2f} rad)  torso {pose.torso_height_m:.2f} m"
    )
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path
