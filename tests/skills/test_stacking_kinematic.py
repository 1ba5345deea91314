"""The stacking skills on the kinematic backend (the PR2 model), the replay command."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from examples import stacking as task_module
from skillcompose import compile_fsa, load_fsa
from skillcompose.skills import kinematic as kin
from skillcompose.skills import stacking as st
from skillcompose.skills import stacking_kinematic as stk
from skillcompose.task import load_task
from tests.skills.test_stacking import FIRST, SECOND, recognised, world

pytestmark = pytest.mark.kinematics
EXAMPLES = Path(task_module.__file__).parent


def test_twins_share_the_sim_signatures() -> None:
    for sim, twin in ((st.grasp_param, kin.grasp_param),
                      (st.move_gripper_to_stack, kin.move_gripper_to_stack),
                      (st.open_gripper, kin.open_gripper), (st.reach_check, stk.reach_check)):
        assert sim.spec.same_signature(twin.spec), sim.name


def test_grasp_stack_open_on_the_pr2() -> None:
    unseen = world()
    assert kin.grasp_param(unseen, np.random.default_rng(0), which=1.0) == "failure"
    assert unseen["last_failure_reason"] == "not_recognised"
    bb = recognised()
    rng = np.random.default_rng(0)
    assert kin.grasp_param(bb, rng, which=1.0) == "success"
    arm = bb["arm_in_use"]
    assert bb[f"held_object_{arm}"] == "box" and bb["objects_grasped"] == ("box",)
    # into the other object: collision, nothing moves
    assert kin.move_gripper_to_stack(bb, rng, which=0.0, dx=0.0, dy=0.0, dz=0.05) == "failure"
    assert bb["last_failure_reason"] == "collision"
    assert kin.move_gripper_to_stack(bb, rng, which=0.0, dx=0.0, dy=0.0, dz=0.14) == "success"
    assert kin.open_gripper(bb, rng) == "success"
    assert bb["object_positions_world"]["box"][2] == pytest.approx(SECOND[2] + 0.12, abs=1e-3)
    assert st.check_success(bb, rng) == "success"


def test_a_side_grasp_holds_the_object_upright_to_the_end() -> None:
    from skillcompose.skills.kinematic_world import GRASP_KEY, SIDE_GRASP_RISE_M

    far_first, far_second = (0.85, -0.2, 0.81), (0.85, -0.05, 0.81)  # beyond a grasp from above
    bb = recognised(object_positions_world={"box": far_first, "bottle": far_second})
    rng = np.random.default_rng(0)
    assert kin.grasp_param(bb, rng, which=1.0) == "success"
    assert bb[GRASP_KEY] == "side"
    arm = bb["arm_in_use"]
    tool = bb[f"tool_pose_{arm}_world"]
    assert tool[:3] == pytest.approx((*far_first[:2], far_first[2] + SIDE_GRASP_RISE_M),
                                     abs=1e-3)
    assert tool[3:5] == pytest.approx((0.0, 0.0), abs=1e-3)  # horizontal: the box upright
    assert bb["object_positions_world"]["box"] == pytest.approx(far_first, abs=1e-3)
    assert kin.move_gripper_to_stack(bb, rng, which=0.0, dx=0.0, dy=0.0, dz=0.125) == "success"
    tool = bb[f"tool_pose_{arm}_world"]
    assert tool[3:5] == pytest.approx((0.0, 0.0), abs=1e-3)  # still held from the side
    assert bb["object_positions_world"]["box"] == pytest.approx(
        (far_second[0], far_second[1], far_second[2] + 0.125), abs=1e-3)
    assert kin.open_gripper(bb, rng) == "success"
    assert bb[GRASP_KEY] is None
    assert st.check_success(bb, rng) == "success"


def test_grasp_fails_out_of_reach_on_the_pr2() -> None:
    bb = recognised(base_pose_world=(-1.5, 0.0, 0.0))
    assert kin.grasp_param(bb, np.random.default_rng(0), which=1.0) == "failure"
    assert bb["last_failure_reason"] in ("unreachable", "joint_limits")
    assert bb["object_positions_world"]["box"] == FIRST


def test_move_to_reach_check_moves_nothing() -> None:
    bb = world(arm_in_use="right")
    before = dict(bb["object_positions_world"])
    assert stk.reach_check(bb, np.random.default_rng(0)) == "success"
    assert bb["object_positions_world"] == before
    far = world(base_pose_world=(-1.5, 0.0, 0.0), arm_in_use="right")
    assert stk.reach_check(far, np.random.default_rng(0)) == "failure"


def test_reference_fsa_stacks_on_the_pr2() -> None:
    task = load_task("examples.stacking", backend="kinematic")
    compiled = compile_fsa(load_fsa(EXAMPLES / "stacking_reference.fsa.yaml"),
                           task.registry, "kinematic")
    results = task.run_trials(compiled, 4, 1)  # the first world of seed 4: a far start
    assert [f for _, f in results] == [0.0]


@pytest.mark.slow  # draws 8 frames of the PR2, a strip and a GIF: about 6 s
def test_replay_writes_a_frame_per_step(tmp_path: Path) -> None:
    from skillcompose.skills.replay import main

    assert main([str(EXAMPLES / "stacking_reference.fsa.yaml"), "--task",
                 "examples.stacking", "--set", "backend=kinematic", "--seed", "4",
                 "--out", str(tmp_path)]) == 0
    frames = sorted(tmp_path.glob("step_*.png"))
    assert len(frames) == 8  # the start and 7 steps
    assert all(f.stat().st_size > 10_000 for f in frames)
    assert (tmp_path / "strip.png").is_file() and (tmp_path / "replay.gif").is_file()
