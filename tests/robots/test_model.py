from __future__ import annotations

import importlib.metadata
from pathlib import Path

import numpy as np
import pytest

from skillcompose.robots.errors import (
    ChainNotFound,
    FrameNotFound,
    InvalidConfiguration,
    RobotDataNotFound,
)
from skillcompose.robots.model import (
    ARM_JOINTS,
    CHAIN_LAYOUT,
    TOOL_FRAMES,
    TUCKED_ARM_RAD,
    RobotModel,
    find_pr2_urdf,
)

pytestmark = pytest.mark.kinematics


def test_urdf_is_found_inside_the_installed_distribution() -> None:
    path = find_pr2_urdf()
    dist = importlib.metadata.distribution("example-robot-data")
    assert path.name == "pr2.urdf"
    assert Path(str(dist.locate_file(""))).resolve() in path.resolve().parents


def test_missing_package_raises_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    def missing(name: str) -> None:
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "distribution", missing)
    with pytest.raises(RobotDataNotFound, match="pip install example-robot-data"):
        find_pr2_urdf()


def test_missing_file_raises(tmp_path: Path) -> None:
    with pytest.raises(RobotDataNotFound):
        RobotModel(tmp_path / "nope.urdf")


def test_chains_have_the_expected_coordinates(pr2: RobotModel) -> None:
    sizes = {
        "left_arm": 7,
        "right_arm": 7,
        "left_arm_torso": 8,
        "right_arm_torso": 8,
        "left_arm_torso_base": 11,
        "right_arm_torso_base": 11,
        "both_arms_torso_base": 18,
    }
    assert set(sizes) == set(CHAIN_LAYOUT)
    for name, n in sizes.items():
        chain = pr2.chain(name)
        assert chain.n_coordinates == n
        for arm in chain.arms:
            assert chain.model.existFrame(TOOL_FRAMES[arm])
            assert set(ARM_JOINTS[arm]) <= set(chain.joint_names)
    both = pr2.chain("both_arms_torso_base")
    assert both.coordinate_names[:4] == (
        "base_planar_joint_x",
        "base_planar_joint_y",
        "base_planar_joint_yaw",
        "torso_lift_joint",
    )


def test_limits_come_from_the_urdf(pr2: RobotModel) -> None:
    chain = pr2.chain("left_arm_torso")
    i = chain.coordinate_index("torso_lift_joint")
    assert (chain.lower_limits[i], chain.upper_limits[i]) == (0.0, 0.31)
    j = chain.coordinate_index("l_elbow_flex_joint")
    assert chain.lower_limits[j] == pytest.approx(-2.3213)
    assert chain.upper_limits[j] == 0.0
    k = chain.coordinate_index("l_forearm_roll_joint")
    assert chain.continuous[k] and np.isinf(chain.upper_limits[k])


def test_unknown_frame_and_chain_list_the_valid_names(pr2: RobotModel) -> None:
    chain = pr2.chain("left_arm")
    with pytest.raises(FrameNotFound) as info:
        chain.frame_id("l_gripper_tool_frme")
    assert "l_gripper_tool_frame" in info.value.valid
    with pytest.raises(ChainNotFound, match="left_arm_torso"):
        pr2.chain("left_leg")
    with pytest.raises(InvalidConfiguration, match="expects 7"):
        chain.transform_tool_to_world("left", np.zeros(6))
    with pytest.raises(InvalidConfiguration, match="right"):
        chain.tool_frame_id("right")


def test_neutral_and_tucked_poses(pr2: RobotModel) -> None:
    chain = pr2.chain("both_arms_torso_base")
    neutral = pr2.coordinates_for(chain, pr2.neutral_pose())
    tucked = pr2.coordinates_for(chain, pr2.tucked_pose())
    assert chain.within_limits(neutral) and chain.within_limits(tucked)
    left = chain.coordinate_index("l_shoulder_lift_joint")
    assert tucked[left] == TUCKED_ARM_RAD["left"][1]
    # arms straight forward at neutral; tucked grippers stay close to the body
    reach_neutral = chain.transform_tool_to_world("left", neutral).translation[0]
    reach_tucked = chain.transform_tool_to_world("left", tucked).translation[0]
    assert reach_neutral > 0.9
    assert reach_tucked < 0.35


def test_locked_joints_follow_the_reference(pr2: RobotModel) -> None:
    low = pr2.chain("left_arm", reference=pr2.tucked_pose(torso_height_m=0.0))
    high = pr2.chain("left_arm", reference=pr2.tucked_pose(torso_height_m=0.2))
    theta = np.zeros(7)
    dz = (
        high.transform_tool_to_world("left", theta).translation
        - low.transform_tool_to_world("left", theta).translation
    )
    np.testing.assert_allclose(dz, [0.0, 0.0, 0.2], atol=1e-12)


def test_coordinate_round_trip(pr2: RobotModel) -> None:
    chain = pr2.chain("both_arms_torso_base")
    rng = np.random.default_rng(3)
    theta = chain.normalise(rng.uniform(-3, 3, chain.n_coordinates))
    back = chain.coordinates_from_q(chain.q_from_coordinates(theta))
    np.testing.assert_allclose(back, theta, atol=1e-12)
