"""The robot pictures draw the PR2's meshes where forward kinematics puts its links."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from matplotlib.image import imread

from skillcompose.robots.collision import Box, Scene
from skillcompose.robots.model import RobotModel, RobotPose
from skillcompose.robots.render import (
    MAX_FACES_PER_MESH,
    link_meshes,
    render_configuration,
    robot_triangles,
    scene_camera,
)

pytestmark = pytest.mark.kinematics


def _urdf_meshes(pr2: RobotModel) -> int:
    """Visual meshes the URDF names (its <visual> elements with a mesh file)."""
    root = ET.parse(pr2.urdf_path).getroot()
    return sum(visual.find("geometry/mesh") is not None for visual in root.iter("visual"))


def _frame(pr2: RobotModel, pose: RobotPose, frame: str) -> pin.SE3:
    data = pr2.full_model.createData()
    pin.framesForwardKinematics(pr2.full_model, data, pr2.full_q(pose))
    return data.oMf[pr2.full_model.getFrameId(frame)].copy()


def _frame_m(pr2: RobotModel, pose: RobotPose, frame: str) -> np.ndarray:
    return np.asarray(_frame(pr2, pose, frame).translation)


def _in_frame(points_m: np.ndarray, frame: pin.SE3) -> np.ndarray:
    """World points (n, 3) in ``frame``'s coordinates."""
    return (points_m - frame.translation) @ frame.rotation


def test_every_mesh_of_the_urdf_is_loaded_and_decimated(pr2: RobotModel) -> None:
    meshes = link_meshes(pr2)
    assert len(meshes) == _urdf_meshes(pr2) > 40
    assert all(0 < len(m.faces) <= MAX_FACES_PER_MESH for m in meshes)
    names = {m.name for m in meshes}
    for link in ("base_link_0", "torso_lift_link_0", "head_tilt_link_0",
                 "l_upper_arm_link_0", "r_forearm_link_0", "l_gripper_palm_link_0"):
        assert link in names
    assert link_meshes(pr2) is meshes  # loaded once per process


def test_triangles_sit_where_forward_kinematics_puts_the_links(pr2: RobotModel) -> None:
    pose = pr2.tucked_pose()
    robot = robot_triangles(pr2, pose)
    assert robot.triangles_m.shape == (len(robot.link_of_triangle), 3, 3)
    assert len(robot.triangles_m) == sum(len(m.faces) for m in link_meshes(pr2))
    corners = robot.triangles_m.reshape(-1, 3)
    low, high = corners.min(axis=0), corners.max(axis=0)
    assert abs(low[2]) < 0.02  # the wheels stand on the floor
    head = _frame_m(pr2, pose, "head_tilt_link")
    assert head[2] < high[2] < head[2] + 0.25  # the head is the top
    assert high[0] - low[0] < 0.8 and high[1] - low[1] < 0.8  # tucked: within the base
    owners = np.array(robot.link_of_triangle)
    for arm, prefix in (("left", "l"), ("right", "r")):
        palm = robot.triangles_m[owners == f"{prefix}_gripper_palm_link_0"].reshape(-1, 3)
        link = _frame_m(pr2, pose, f"{prefix}_gripper_palm_link")
        assert np.linalg.norm(palm.mean(axis=0) - link) < 0.12, arm  # the palm's mesh


def test_moving_the_base_and_an_arm_moves_their_triangles(pr2: RobotModel) -> None:
    tucked = pr2.tucked_pose()
    arms = dict(tucked.arm_rad)
    arms["left"] = (0.3, 0.2, 0.0, -1.2, 0.0, -0.8, 0.0)
    moved = RobotPose((1.0, -0.5, 0.7), 0.2, arms)
    a, b = robot_triangles(pr2, tucked), robot_triangles(pr2, moved)
    owners = np.array(a.link_of_triangle)
    base = owners == "base_link_0"
    expected = pin.SE3(pin.utils.rotate("z", 0.7), np.array([1.0, -0.5, 0.0]))
    np.testing.assert_allclose(
        b.triangles_m[base].reshape(-1, 3),
        a.triangles_m[base].reshape(-1, 3) @ expected.rotation.T + expected.translation,
        atol=1e-9,
    )
    # every moved link's mesh is where forward kinematics puts its link: the same points in
    # the link's frame in both poses
    for link in ("l_gripper_palm_link", "l_upper_arm_link", "torso_lift_link"):
        mine = owners == f"{link}_0"
        before = _in_frame(a.triangles_m[mine].reshape(-1, 3), _frame(pr2, tucked, link))
        after = _in_frame(b.triangles_m[mine].reshape(-1, 3), _frame(pr2, moved, link))
        np.testing.assert_allclose(after, before, atol=1e-9)
    palm = owners == "l_gripper_palm_link_0"
    assert np.linalg.norm(b.triangles_m[palm].mean(axis=(0, 1))
                          - a.triangles_m[palm].mean(axis=(0, 1))) > 0.3


def test_a_picture_shows_the_robot_the_table_and_an_object(
    pr2: RobotModel, tmp_path: Path
) -> None:
    table = Box((0.95, 0.0, 0.36), (0.3, 0.6, 0.36), 0.0, "table")
    cube = Box((0.8, 0.1, 0.77), (0.03, 0.03, 0.05), 0.0, "cube")
    pose = pr2.tucked_pose()
    out = render_configuration(pr2, pose, tmp_path / "pr2.png", scene=Scene((table, cube)))
    image = imread(out)[..., :3]
    assert image.shape[0] > 500 and image.shape[1] > 500
    # the table's wood and the cube's green are both in the picture
    wood = (image[..., 0] > image[..., 2] + 0.15) & (image[..., 0] > 0.3)
    green = (image[..., 1] > image[..., 0] + 0.15) & (image[..., 1] > image[..., 2] + 0.1)
    assert wood.sum() > 2000 and green.sum() > 20
    camera = scene_camera(pr2, [pose], Scene((table, cube)))
    assert camera.half_width_m >= 0.6  # table and robot in view at one scale


def test_axis_labels_read_upright_and_ticks_do_not_crowd(
        pr2: RobotModel, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The z label was drawn upside down and the x and y ticks overlapped (every 0.25 m)."""
    from matplotlib.figure import Figure

    saved: list[Figure] = []
    original = Figure.savefig

    def keep(self: Figure, *args: object, **kwargs: object) -> None:
        saved.append(self)
        original(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Figure, "savefig", keep)
    render_configuration(pr2, pr2.tucked_pose(), tmp_path / "pose.png")
    ax: Any = saved[-1].axes[0]  # an Axes3D
    assert ax.zaxis.label.get_text() == "z [m]" and ax.zaxis.label.get_rotation() == 90
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        assert len(axis.get_major_locator()()) <= 7
