from __future__ import annotations

import numpy as np
import pytest

from robots.ik import IKSolver, IKStatus, IKTarget, solve_ik
from robots.model import RobotModel

pytestmark = pytest.mark.kinematics


@pytest.mark.parametrize(
    ("name", "arm"), [("left_arm", "left"), ("right_arm", "right"), ("left_arm_torso", "left")]
)
def test_pose_targets_of_in_limit_configurations_are_solved(
    pr2: RobotModel, name: str, arm: str
) -> None:
    chain = pr2.chain(name)
    solver = IKSolver(chain=chain, arm=arm, seed=0, time_budget_s=0.05)  # type: ignore[arg-type]
    rng = np.random.default_rng(42)
    for _ in range(60):
        goal = chain.transform_tool_to_world(arm, chain.sample_coordinates(rng))  # type: ignore[arg-type]
        result = solver.solve(IKTarget.from_transform(goal))
        assert result.success, result
        assert result.coordinates is not None
        assert chain.within_limits(result.coordinates)
        reached = chain.transform_tool_to_world(arm, result.coordinates)  # type: ignore[arg-type]
        assert np.linalg.norm(reached.translation - goal.translation) < 1e-5
        assert np.linalg.norm(reached.rotation - goal.rotation) < 1e-5


def test_position_only_target(pr2: RobotModel) -> None:
    chain = pr2.chain("right_arm")
    result = solve_ik(chain, "right", IKTarget(np.array([0.6, -0.3, 0.7])), time_budget_s=0.05)
    assert result.success
    assert result.coordinates is not None
    reached = chain.transform_tool_to_world("right", result.coordinates).translation
    np.testing.assert_allclose(reached, [0.6, -0.3, 0.7], atol=1e-5)
    assert result.orientation_error_rad == 0.0


def test_far_target_is_reported_unreachable_without_raising(pr2: RobotModel) -> None:
    chain = pr2.chain("left_arm_torso")
    result = solve_ik(chain, "left", IKTarget(np.array([2.5, 0.3, 0.8]), np.eye(3)))
    assert result.status is IKStatus.UNREACHABLE
    assert not result.success
    assert "arm's length" in result.message
    assert result.time_s < 1e-3


def test_target_beyond_reach_of_a_fixed_torso(pr2: RobotModel) -> None:
    chain = pr2.chain("left_arm_torso")
    goal = IKTarget(np.array([0.5, 0.2, 1.75]))
    assert solve_ik(chain, "left", goal, time_budget_s=0.05).success  # torso can rise
    low = solve_ik(chain, "left", goal, time_budget_s=0.05, fixed={"torso_lift_joint": 0.0})
    assert low.status is IKStatus.UNREACHABLE


def test_fixed_coordinates_are_held(pr2: RobotModel) -> None:
    chain = pr2.chain("right_arm_torso")
    goal = IKTarget(np.array([0.55, -0.25, 0.9]), np.eye(3))
    result = solve_ik(chain, "right", goal, fixed={"torso_lift_joint": 0.12}, time_budget_s=0.05)
    assert result.success
    assert result.coordinates is not None
    assert result.coordinates[chain.coordinate_index("torso_lift_joint")] == 0.12


def test_in_reach_but_infeasible_orientation_is_not_a_success(pr2: RobotModel) -> None:
    # gripper pointing back at the shoulder from just in front of it: impossible for PR2
    chain = pr2.chain("left_arm")
    shoulder = chain.joint_origins_world(np.zeros(7))["l_shoulder_pan_joint"]
    backwards = np.diag([-1.0, -1.0, 1.0])
    target = IKTarget(shoulder + np.array([0.12, 0.0, 0.0]), backwards)
    result = solve_ik(chain, "left", target, time_budget_s=0.01)
    assert result.status in {IKStatus.UNREACHABLE, IKStatus.JOINT_LIMITS}
    assert result.coordinates is not None and chain.within_limits(result.coordinates)
