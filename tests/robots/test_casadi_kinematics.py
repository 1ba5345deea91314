from __future__ import annotations

import numpy as np
import pytest

from skillcompose.robots.casadi_kinematics import CasadiKinematics
from skillcompose.robots.model import TOOL_FRAMES, RobotModel

pytestmark = pytest.mark.kinematics

CHAINS = ["left_arm", "right_arm_torso", "left_arm_torso_base", "both_arms_torso_base"]


@pytest.mark.parametrize("name", CHAINS)
def test_casadi_forward_kinematics_matches_pinocchio(pr2: RobotModel, name: str) -> None:
    chain = pr2.chain(name)
    sym = CasadiKinematics(chain)
    rng = np.random.default_rng(11)
    for arm in chain.arms:
        fk = sym.forward_function(TOOL_FRAMES[arm])
        jac = sym.jacobian_function(TOOL_FRAMES[arm])
        for _ in range(20):
            theta = chain.sample_coordinates(rng)
            expected = chain.transform_tool_to_world(arm, theta)
            position, rotation = fk(theta)
            np.testing.assert_allclose(np.array(position).ravel(), expected.translation, atol=1e-9)
            np.testing.assert_allclose(np.array(rotation), expected.rotation, atol=1e-9)
            np.testing.assert_allclose(
                np.array(jac(theta)), chain.jacobian_tool_world(arm, theta), atol=1e-9
            )


@pytest.mark.parametrize("name", ["right_arm_torso", "both_arms_torso_base"])
def test_jacobian_matches_finite_differences(pr2: RobotModel, name: str) -> None:
    chain = pr2.chain(name)
    rng = np.random.default_rng(5)
    eps = 1e-6
    for arm in chain.arms:
        for _ in range(10):
            theta = chain.sample_coordinates(rng)
            jac = chain.jacobian_tool_world(arm, theta)
            base = chain.transform_tool_to_world(arm, theta)
            numeric = np.zeros_like(jac)
            for i in range(chain.n_coordinates):
                plus, minus = theta.copy(), theta.copy()
                plus[i] += eps
                minus[i] -= eps
                mp = chain.transform_tool_to_world(arm, plus)
                mm = chain.transform_tool_to_world(arm, minus)
                numeric[:3, i] = (mp.translation - mm.translation) / (2 * eps)
                # angular velocity in world axes: vee(dR R^T)
                skew = (mp.rotation - mm.rotation) / (2 * eps) @ base.rotation.T
                numeric[3:, i] = [skew[2, 1], skew[0, 2], skew[1, 0]]
            np.testing.assert_allclose(jac, numeric, atol=1e-7)


def test_joint_origins_match_pinocchio(pr2: RobotModel) -> None:
    chain = pr2.chain("both_arms_torso_base")
    sym = CasadiKinematics(chain)
    import casadi as ca

    origins = ca.Function(
        "origins",
        [sym.coordinates],
        [ca.horzcat(*[p.translation_m for p in sym.joint_placements_world[1:]])],
    )
    theta = chain.sample_coordinates(np.random.default_rng(2))
    expected = np.array(list(chain.joint_origins_world(theta).values())).T
    np.testing.assert_allclose(np.array(origins(theta)), expected, atol=1e-9)
