"""The stacking experiment (paper 4.3) on the sim backend: skills on hand-built worlds,
equation (2), the reference FSA, MoveToReach as a nested FSA, a short evolution."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from examples import stacking as task_module
from skillcompose import Blackboard, compile_fsa, load_fsa, loads_fsa
from skillcompose.executor import trial_rngs
from skillcompose.robots.collision import Box
from skillcompose.skills import stacking as st
from skillcompose.skills.move_to_push import classifier_label
from skillcompose.task import load_task

EXAMPLES = Path(task_module.__file__).parent
FIRST, SECOND = (0.6, -0.2, 0.81), (0.6, -0.1, 0.81)  # the classifier: right arm for both


def world(**extra: Any) -> Blackboard:
    """Robot at the origin facing +x, a table whose front edge is at x = 0.5 m (top 0.75 m),
    two 6 x 6 x 12 cm objects on it within reach of the right arm."""
    return Blackboard({
        "p_fail": 0.0,
        "table_world": Box.table((0.95, 0.0), (0.9, 1.4), 0.75),
        "room_half_m": 2.5,
        "object_positions_world": {"box": FIRST, "bottle": SECOND},
        "object_half_extents_m": {"box": (0.03, 0.03, 0.06), "bottle": (0.03, 0.03, 0.06)},
        "base_pose_world": (0.0, 0.0, 0.0),
        "torso_height_m": 0.0,
        "arm_in_use": None,
        "held_object_left": None,
        "held_object_right": None,
        "objects_grasped": (),
        **extra,
    })


def recognised(**extra: Any) -> Blackboard:
    bb = world(**extra)
    assert st.recognise_objects(bb, 0) == "success"
    return bb


def holding_box(**extra: Any) -> Blackboard:
    bb = recognised(**extra)
    assert st.grasp_param(bb, 0, which=1.0) == "success"
    return bb


def test_recognise_writes_both_objects() -> None:
    bb = world()
    assert st.recognise_objects(bb, 0) == "success"
    assert bb["object_locations_world"] == {"box": FIRST, "bottle": SECOND}


def test_grasp_param_picks_an_object_by_its_parameter() -> None:
    bb = recognised()
    assert st.grasp_param(bb, 0, which=0.2) == "success"
    assert bb["held_object_right"] == "bottle" and bb["arm_in_use"] == "right"
    assert bb["gripper_position_world"] == SECOND
    assert bb["objects_grasped"] == ("bottle",)
    bb = recognised()
    assert st.grasp_param(bb, 0, which=0.9) == "success"
    assert bb["held_object_right"] == "box"


@pytest.mark.parametrize("case", ["not recognised", "already holding", "unreachable",
                                  "random", "under the other"])
def test_grasp_param_failures(case: str) -> None:
    if case == "not recognised":
        bb = world()
    elif case == "already holding":
        bb = holding_box()
    elif case == "unreachable":
        bb = recognised(base_pose_world=(-1.5, 0.0, 0.0))
    elif case == "random":
        bb = recognised(p_fail=1.0)
    else:
        bb = recognised(object_positions_world={"box": FIRST,
                                                "bottle": (0.6, -0.2, 0.93)})
    before = dict(bb.items()) if hasattr(bb, "items") else None
    assert st.grasp_param(bb, 0, which=1.0) == "failure"
    assert bb.get("held_object_left") is None
    if case != "already holding":
        assert bb.get("held_object_right") is None
    del before


def test_move_gripper_to_stack_carries_the_held_object() -> None:
    bb = holding_box()
    assert st.move_gripper_to_stack(bb, 0, which=0.0, dx=0.0, dy=0.0, dz=0.12) == "success"
    goal = (SECOND[0], SECOND[1], SECOND[2] + 0.12)
    assert bb["gripper_position_world"] == pytest.approx(goal)
    assert bb["object_positions_world"]["box"] == pytest.approx(goal)
    assert bb["object_positions_world"]["bottle"] == SECOND


@pytest.mark.parametrize(
    ("which", "dz", "p_fail", "why"),
    [(1.0, 0.15, 0.0, "over the held object itself"),
     (0.0, 0.05, 0.0, "the held object would sink into the other"),
     (0.0, 0.12, 1.0, "random failure")],
)
def test_move_gripper_to_stack_failures(which: float, dz: float, p_fail: float, why: str
                                        ) -> None:
    bb = holding_box(p_fail=0.0)
    bb["p_fail"] = p_fail
    assert st.move_gripper_to_stack(bb, 0, which=which, dx=0.0, dy=0.0, dz=dz) == \
        "failure", why
    assert bb["object_positions_world"]["box"] == FIRST


def test_move_gripper_to_stack_empty_handed() -> None:
    bb = recognised()
    assert st.move_gripper_to_stack(bb, 0, which=0.0, dx=0.0, dy=0.0, dz=0.0) == "failure"
    assert st.move_gripper_to_stack(bb, 0, which=0.0, dx=0.0, dy=0.0, dz=0.2) == "success"
    assert bb["gripper_position_world"] == pytest.approx((0.6, -0.1, 1.01))
    assert bb["object_positions_world"] == {"box": FIRST, "bottle": SECOND}
    far = recognised(base_pose_world=(-1.5, 0.0, 0.0))
    assert st.move_gripper_to_stack(far, 0, which=0.0, dx=0.0, dy=0.0, dz=0.2) == "failure"


def test_open_gripper_drops_onto_the_highest_surface() -> None:
    bb = holding_box()
    assert st.move_gripper_to_stack(bb, 0, which=0.0, dx=0.01, dy=0.0, dz=0.25) == "success"
    assert st.check_success(bb, 0) == "failure"  # still held
    assert st.open_gripper(bb, 0) == "success"
    assert bb["held_object_right"] is None
    assert bb["object_positions_world"]["box"] == pytest.approx((0.61, -0.1, 0.93))
    assert st.check_success(bb, 0) == "success"
    bb = holding_box()  # not over the other object: onto the table
    assert st.move_gripper_to_stack(bb, 0, which=0.0, dx=0.0, dy=-0.15, dz=0.2) == "success"
    assert st.open_gripper(bb, 0) == "success"
    assert bb["object_positions_world"]["box"][2] == pytest.approx(0.81)
    assert st.check_success(bb, 0) == "failure"
    assert st.open_gripper(bb, 0) == "success"  # nothing held: nothing happens


def test_check_success_needs_the_centre_over_the_top() -> None:
    bb = world(object_positions_world={"box": (0.64, -0.1, 0.93), "bottle": SECOND})
    assert st.check_success(bb, 0) == "failure"  # 4 cm off: beyond the 3 cm half width
    bb = world(object_positions_world={"box": (0.62, -0.1, 0.93), "bottle": SECOND})
    assert st.check_success(bb, 0) == "success"
    assert st.check_success(world(), 0) == "failure"


# -- equation (2) ---------------------------------------------------------------------------
def test_fitness_cases() -> None:
    stacked = world(object_positions_world={"box": (0.6, -0.1, 0.93), "bottle": SECOND},
                    objects_grasped=("box",))
    assert task_module.fitness("success", stacked, 7) == 0.0
    never = world()
    assert task_module.fitness("failure", never, 15) == task_module.NO_GRASP_FITNESS
    assert task_module.fitness("timeout", never, 15) == task_module.NO_GRASP_FITNESS
    grasped = world(objects_grasped=("box",))
    d = math.hypot(0.1, 0.12)  # side by side: a bottom face centre to the other's top one
    assert task_module.fitness("timeout", grasped, 15) == pytest.approx(2 * d)
    assert task_module.fitness("failure", grasped, 9) == pytest.approx(d)
    # a success outcome that did not stack (a hand-routed file) scores as "otherwise"
    assert task_module.fitness("success", grasped, 9) == pytest.approx(d)
    # holding nothing at the end after a grasp is not the 50 case
    dropped = world(object_positions_world={"box": (0.6, -0.3, 0.81), "bottle": SECOND},
                    objects_grasped=("box",))
    assert task_module.fitness("failure", dropped, 9) == pytest.approx(math.hypot(0.2, 0.12))
    # d is 0 when one stands on the other: held right on top scores near 0, not 0.12, but
    # no better than the 1 cm tolerance of stacked, so 0 is a stacked success's alone
    held_on_top = world(object_positions_world={"box": (0.6, -0.1, 0.935), "bottle": SECOND},
                        objects_grasped=("box",), held_object_right="box")
    assert task_module.fitness("failure", held_on_top, 9) == pytest.approx(0.01)
    held_at_zero = world(object_positions_world={"box": (0.6, -0.1, 0.93), "bottle": SECOND},
                         objects_grasped=("box",), held_object_right="box")
    assert task_module.distance(held_at_zero) == pytest.approx(0.0)
    assert task_module.fitness("timeout", held_at_zero, 15) == pytest.approx(0.02)
    assert not task_module.make_task().solved(task_module.fitness("timeout", held_at_zero, 15))
    touching = world(object_positions_world={"box": (0.6, -0.16, 0.81), "bottle": SECOND},
                     objects_grasped=("box",))
    assert task_module.fitness("failure", touching, 9) > \
        task_module.fitness("failure", held_on_top, 9)


def test_ending_names_where_a_run_stopped_and_only_stacked_scores_0() -> None:
    on_top = {"box": (0.6, -0.1, 0.93), "bottle": SECOND}
    cases = [
        ("success", world(object_positions_world=on_top, objects_grasped=("box",)),
         "stacked"),
        ("timeout", world(object_positions_world=on_top, objects_grasped=("box",),
                          held_object_right="box"), "holding an object"),
        ("timeout", world(object_positions_world=on_top, objects_grasped=("box",)),
         "let go, no stacked success"),  # stood on it, the steps ran out before CheckSuccess
        ("failure", world(objects_grasped=("box",)), "let go, no stacked success"),
        ("timeout", world(), "never grasped"),
    ]
    for outcome, bb, name in cases:
        assert task_module.ending(outcome, bb) == name and name in task_module.ENDINGS
        assert (name == "stacked") == (task_module.fitness(outcome, bb, 15) == 0.0)


def test_task_settings_are_checked() -> None:
    from skillcompose.task import TaskError

    for bad in ({"backend": "real"}, {"p_fail": 1.5}, {"trials": 0}, {"network": "x"},
                {"move_to_reach": "no/such/file.yaml"}):
        with pytest.raises(TaskError):
            task_module.make_task(**bad)
    task = task_module.make_task()
    assert task.step_limit == 15 and task.settings["p_fail"] == 0.3


@pytest.mark.parametrize(("terminals", "end"), [("[done, failure]", "done"),
                                               ("[success, failure, stuck]", "success")])
def test_a_move_to_reach_file_with_other_ends_is_refused(
    tmp_path: Path, terminals: str, end: str,
) -> None:
    """Stacking reads success or failure of MoveToReach: a renamed or added end would have
    counted as failure without a word."""
    from skillcompose.errors import RegistryError

    text = (EXAMPLES / "move_to_reach.fsa.yaml").read_text()
    assert "terminals: [success, failure]" in text
    path = tmp_path / "mtr.yaml"
    path.write_text(text.replace("terminals: [success, failure]", f"terminals: {terminals}")
                    .replace("success: success", f"success: {end}"))
    with pytest.raises(RegistryError, match=r"mtr.yaml:\d+:1: MoveToReach ends in success or "
                       r"failure .* this FSA's terminals are \["):
        st.make_move_to_reach(path, kinematic=False)


def test_worlds_need_move_to_reach_in_some_and_not_others() -> None:
    near = far = 0
    for rng in trial_rngs(5, 60):
        bb = task_module.setup(rng)
        base = bb["base_pose_world"]
        labels = [classifier_label(base, 0.0, p)
                  for p in bb["object_positions_world"].values()]
        if bb["start_near"]:
            near += 1
            assert labels[0] != 0 and labels[0] == labels[1]
        else:
            far += 1
            assert labels == [0, 0]
    assert near > 10 and far > 10


# -- the reference FSA ----------------------------------------------------------------------
def test_reference_fsa_solves_at_p_fail_0() -> None:
    task = load_task("examples.stacking", p_fail=0.0)
    compiled = compile_fsa(load_fsa(EXAMPLES / "stacking_reference.fsa.yaml"),
                           task.registry, "sim")
    results = task.run_trials(compiled, 0, 300)
    solved = sum(f == 0.0 for _, f in results)
    # the misses are worlds where the evolved MoveToReach cannot reach the object
    assert solved >= 0.97 * len(results)
    for res, f in results:
        if f != 0.0:
            assert res.outcome == "timeout"


# -- MoveToReach, the nested FSA ------------------------------------------------------------
REACH_ONLY = """
format: 1
name: reach_only
start: Reach
step_limit: 15
terminals: [success, failure]
states:
  Reach:
    skill: MoveToReach
    transitions: {success: Check, failure: Check}
  Check:
    skill: CheckSuccess
    transitions: {success: success, failure: failure}
"""


def _far_world(seed: int) -> Blackboard:
    return task_module.setup(np.random.default_rng(seed), p_fail=0.0, near=False)


def test_move_to_reach_shares_blackboard_and_generator_and_is_one_step() -> None:
    task = load_task("examples.stacking", p_fail=0.0)
    outer = compile_fsa(loads_fsa(REACH_ONLY, "reach_only"), task.registry, "sim")
    inner = compile_fsa(load_fsa(task_module.MOVE_TO_REACH_FILE),
                        st.reach_registry(kinematic=False), "sim")
    for seed in range(5):
        bb_outer, bb_inner = _far_world(seed), _far_world(seed)
        rng_outer, rng_inner = np.random.default_rng(seed), np.random.default_rng(seed)
        result = outer.run(bb_outer, rng_outer, trace=True)
        rng_inner.random()  # MoveToReach draws its random failure first
        inner_result = inner.run(bb_inner, rng_inner)
        assert inner_result.steps >= 3  # RecogniseObject, MoveBase..., Push
        assert result.steps == 2  # MoveToReach is one step of the caller
        assert result.trace is not None and result.trace[0].skill == "MoveToReach"
        # the caller's blackboard holds what the nested skills wrote
        assert bb_outer["base_pose_world"] == bb_inner["base_pose_world"]
        first = next(iter(bb_outer["object_positions_world"].values()))
        assert bb_outer["object_location_world"] == first  # the empty-handed target
        # the same generator: both consumed the same numbers
        assert rng_outer.random() == rng_inner.random()
        moved = result.trace[0].outcome == "success"
        assert moved == (inner_result.outcome == "success")


def test_move_to_reach_fails_at_random_with_p_fail() -> None:
    reach = st.make_move_to_reach(task_module.MOVE_TO_REACH_FILE, kinematic=False)
    fn = reach.bind(None, "sim")
    bb = _far_world(1)
    bb["p_fail"] = 1.0
    start = bb["base_pose_world"]
    assert fn(bb, np.random.default_rng(0)) == "failure"
    assert bb["base_pose_world"] == start


def test_move_to_reach_targets_the_other_object_when_holding_and_carries_it() -> None:
    reach = st.make_move_to_reach(task_module.MOVE_TO_REACH_FILE, kinematic=False)
    fn = reach.bind(None, "sim")
    for seed in range(20):
        bb = _far_world(seed)
        first, second = bb["object_positions_world"]
        assert st.reach_target(bb) == (first, bb["object_positions_world"][first])
        bb["held_object_left"] = first
        bb["gripper_position_world"] = bb["object_positions_world"][first]
        assert st.reach_target(bb) == (second, bb["object_positions_world"][second])
        before = bb["base_pose_world"]
        held_before = bb["object_positions_world"][first]
        if fn(bb, np.random.default_rng(seed)) == "success" and \
                bb["base_pose_world"] != before:
            # the held object moved with the base, the gripper with it, the arm kept
            assert bb["object_positions_world"][first] != held_before
            assert bb["gripper_position_world"] == bb["object_positions_world"][first]
            assert bb["arm_in_use"] == "left"
            assert bb["object_location_world"] == bb["object_positions_world"][second]
            return
    pytest.fail("no world where MoveToReach moved the robot while holding an object")


def test_move_to_reach_does_not_move_when_the_target_is_in_reach() -> None:
    reach = st.make_move_to_reach(task_module.MOVE_TO_REACH_FILE, kinematic=False)
    fn = reach.bind(None, "sim")
    bb = recognised()  # the right arm reaches both objects from the origin
    assert st.reach_check(bb, 0) == "success"  # empty-handed: either arm will do
    rng = np.random.default_rng(3)
    assert fn(bb, rng) == "success"
    assert bb["base_pose_world"] == (0.0, 0.0, 0.0)
    assert "object_location_world" not in bb  # the evolved FSA did not run
    check = np.random.default_rng(3)
    check.random()  # only the random failure's number was drawn
    assert rng.random() == check.random()
    far = _far_world(2)
    assert st.reach_check(far, 0) == "failure"


def test_reach_goal_holding_is_where_the_held_object_would_stand() -> None:
    bb = holding_box()
    name, point = st.reach_goal(bb)  # type: ignore[misc]
    assert name == "bottle"
    assert point == pytest.approx((SECOND[0], SECOND[1], SECOND[2] + 0.12))
    assert st.reach_arms(bb) == ("right",)
    assert st.reach_arms(recognised()) == ("left", "right")
    assert st.reach_goal(world(object_positions_world={"box": FIRST})) is None


def test_move_to_reach_goes_for_the_object_grasp_param_last_tried() -> None:
    bb = recognised(p_fail=1.0)
    assert st.reach_target(bb) == ("box", FIRST)  # before any grasp: the first
    assert st.grasp_param(bb, 0, which=0.0) == "failure"  # a random failure
    assert bb["grasp_target"] == "bottle"
    assert st.reach_target(bb) == ("bottle", SECOND)


# -- evolution ------------------------------------------------------------------------------
@pytest.mark.slow
def test_short_evolution_improves_fitness() -> None:
    from skillcompose.evolve import PRESETS, EvolutionConfig, evolve

    task = load_task("examples.stacking")
    cfg = EvolutionConfig(**{**PRESETS["robust"], "population": 80, "generations": 12,
                             "confirm_trials": 0})
    result = evolve(task, cfg, seed=1, workers=1, backend="serial")
    first, last = result.history[0].best, result.history[-1].best
    assert last < first
    assert min(h.best for h in result.history) < 1.0  # something grasped and moved
