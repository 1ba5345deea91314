from __future__ import annotations

import numpy as np
import pytest

from skillcompose.robots.base_placement import BasePlacer, random_table_scene
from skillcompose.robots.collision import Box, Scene, check_collisions
from skillcompose.robots.ik import IKStatus, IKTarget
from skillcompose.robots.model import RobotModel
from skillcompose.robots.optimisation import OptimisedBasePlacer, solve_both_arms

pytestmark = pytest.mark.kinematics


def test_box_signed_distance_is_exact() -> None:
    box = Box((1.0, 0.0, 0.5), (0.5, 0.25, 0.5), yaw_rad=np.pi / 2)
    points = np.array([[1.0, 0.0, 0.5], [1.0, 1.0, 0.5], [1.5, 0.0, 1.5]])
    np.testing.assert_allclose(box.signed_distance_m(points), [-0.25, 0.5, np.hypot(0.25, 0.5)])


def test_box_overlap_uses_separating_axes() -> None:
    a = Box((0.0, 0.0, 0.5), (0.5, 0.5, 0.5))
    rotated = Box((1.15, 0.0, 0.5), (0.5, 0.5, 0.5), yaw_rad=np.pi / 4)  # corner at x=0.443
    assert a.overlaps(rotated)
    assert not a.overlaps(Box((1.25, 0.0, 0.5), (0.5, 0.5, 0.5), yaw_rad=np.pi / 4))
    assert not a.overlaps(Box((0.0, 0.0, 2.0), (0.5, 0.5, 0.2)))


def test_arm_through_table_collides(pr2: RobotModel) -> None:
    chain = pr2.chain("left_arm_torso_base")
    theta = pr2.coordinates_for(chain, pr2.neutral_pose())  # arm straight forward, z ~ 0.79 m
    low_table = Scene((Box.table((0.8, 0.2), (0.4, 0.4), 0.70),))
    high_table = Scene((Box.table((0.8, 0.2), (0.4, 0.4), 0.85),))
    assert not check_collisions(chain, theta, low_table).collides
    report = check_collisions(chain, theta, high_table)
    assert report.collides and report.clearance_m < 0
    assert any(box == "table" for _, box in report.pairs)
    against_base = Scene((Box.table((0.3, 0.0), (0.2, 0.2), 0.5),))
    assert ("robot_base", "table") in check_collisions(chain, theta, against_base).pairs


@pytest.mark.parametrize("arm", ["left", "right"])
def test_base_placement_reaches_without_collision(pr2: RobotModel, arm: str) -> None:
    placer = BasePlacer(model=pr2, arm=arm, seed=3, time_budget_s=0.5)  # type: ignore[arg-type]
    chain = pr2.chain(f"{arm}_arm_torso_base")
    rng = np.random.default_rng(7)
    for _ in range(15):
        scene, target = random_table_scene(rng)
        result = placer.place(target, scene)
        assert result.success, result
        pose = result.pose(pr2)
        assert pose is not None
        theta = pr2.coordinates_for(chain, pose)
        assert chain.within_limits(theta)
        assert not check_collisions(chain, theta, scene, margin_m=0.0).collides
        reached = chain.transform_tool_to_world(arm, theta)  # type: ignore[arg-type]
        assert np.linalg.norm(reached.translation - target.position_m) < 1e-5
        assert np.linalg.norm(reached.rotation - target.rotation) < 1e-5


def test_base_placement_reports_unreachable_target(pr2: RobotModel) -> None:
    placer = BasePlacer(model=pr2, arm="left", seed=0, time_budget_s=0.05)
    result = placer.place(IKTarget(np.array([1.0, 0.0, 2.6]), np.eye(3)), Scene())
    assert result.status is IKStatus.UNREACHABLE
    assert result.base_xy_yaw is None and result.pose(pr2) is None


def test_optimised_base_placement_with_collision_margin(pr2: RobotModel) -> None:
    placer = OptimisedBasePlacer(model=pr2, arm="left", seed=0, n_boxes=1, margin_m=0.03)
    rng = np.random.default_rng(1)
    successes = 0
    for _ in range(5):
        scene, target = random_table_scene(rng)
        result = placer.place(target, scene)
        if result.success:
            successes += 1
            assert result.coordinates is not None
            report = check_collisions(placer.chain, result.coordinates, scene, margin_m=0.02)
            assert not report.collides
            assert result.position_error_m < 1e-5
        else:
            assert result.status in {IKStatus.UNREACHABLE, IKStatus.COLLISION}
    assert successes >= 4


def test_both_arms_at_once(pr2: RobotModel) -> None:
    chain = pr2.chain("both_arms_torso_base")
    theta = pr2.coordinates_for(chain, pr2.tucked_pose(0.1))
    theta[4:11] = [0.3, 0.2, 0.0, -1.2, 0.0, -0.8, 0.0]
    theta[11:] = [-0.3, 0.2, 0.0, -1.2, 0.0, -0.8, 0.0]
    left = chain.transform_tool_to_world("left", theta)
    right = chain.transform_tool_to_world("right", theta)
    targets = {
        "left": IKTarget(left.translation + np.array([0.1, 0.0, 0.05]), left.rotation),
        "right": IKTarget(right.translation + np.array([0.05, -0.05, 0.0]), right.rotation),
    }
    result = solve_both_arms(pr2, targets, base_xy_yaw=(0.0, 0.0, 0.0))  # type: ignore[arg-type]
    assert result.success, result
    assert result.coordinates is not None
    np.testing.assert_allclose(result.coordinates[:3], 0.0, atol=1e-12)
    for arm, target in targets.items():
        reached = chain.transform_tool_to_world(arm, result.coordinates)  # type: ignore[arg-type]
        assert np.linalg.norm(reached.translation - target.position_m) < 1e-5
