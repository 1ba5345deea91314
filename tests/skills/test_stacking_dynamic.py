"""Stacking on the dynamic backend (the PR2 in MuJoCo): a grasped box stays in the fingers
while it is carried and rests on the other after the release, physics' failures are
outcomes, the shipped FSA stacks, and runs repeat exactly."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

pytest.importorskip("mujoco")

from skillcompose import Blackboard, compile_fsa, load_fsa
from skillcompose.executor import trial_rngs
from skillcompose.robots.model import ARMS
from skillcompose.skills import stacking_dynamic as sd
from skillcompose.skills.dynamic_world import (
    DYNAMIC_FAILURE_REASONS,
    arm_touches_table,
    world_of,
)
from skillcompose.skills.kinematic_world import FAILURE_REASONS, read_state
from skillcompose.skills.move_to_push_dynamic import unfolded
from skillcompose.skills.stacking_world import stacked
from skillcompose.task import Task, load_task

pytestmark = [pytest.mark.physics, pytest.mark.kinematics]

SHIPPED = "docs/results/stacking_best.fsa.yaml"
SEED = 30_000  # the reproduction's scenes
# the shipped file's states' parameters
WHICH_GRASP = 0.7818458873531227
STACK = {"which": 0.07814379907208957, "dx": -0.013029712019154538,
         "dy": -0.005102085712462706, "dz": 0.13963042514898763}


def _scene(k: int) -> tuple[Task, Blackboard, np.random.Generator]:
    task = load_task("examples.stacking", backend="dynamic", trials=1)
    rng = list(trial_rngs(SEED, k + 1))[k]
    return task, task.setup(rng), rng


def _call(task: Task, bb: Blackboard, rng: np.random.Generator, name: str,
          **params: Any) -> str:
    return str(task.registry.resolve(name, "dynamic").bind(task.registry, "dynamic")(
        bb, rng, **params))


def test_a_grasped_box_is_carried_and_rests_on_the_other() -> None:
    task, bb, rng = _scene(1)
    assert _call(task, bb, rng, "RecogniseObject") == "success"
    assert _call(task, bb, rng, "MoveToReach") == "success"
    assert _call(task, bb, rng, "GraspParam", which=WHICH_GRASP) == "success", \
        bb.get("last_failure_detail")
    arm = bb["arm_in_use"]
    carried = bb[f"held_object_{arm}"]
    assert carried is not None
    world = world_of(task.registry)
    assert world is not None and world.physics is not None
    assert world.physics.held_object(arm) == carried
    assert _call(task, bb, rng, "MoveGripperToStack", **STACK) == "success", \
        bb.get("last_failure_detail")
    assert world.physics.held_object(arm) == carried  # held by friction all the way
    assert _call(task, bb, rng, "OpenGripper") == "success"
    assert bb[f"held_object_{arm}"] is None and stacked(bb)
    assert all(world.physics.upright(n) for n in bb["object_positions_world"])
    assert _call(task, bb, rng, "CheckSuccess") == "success"


def test_a_transit_through_the_table_goes_over_it() -> None:
    # scene 9: the joint-space line to the grasp's first waypoint passes the upper arm
    # through the table's edge; the arm goes with its shoulder lifted first
    task, bb, rng = _scene(9)
    world = world_of(task.registry)
    assert world is not None and world.physics is not None
    assert _call(task, bb, rng, "RecogniseObject") == "success"
    assert _call(task, bb, rng, "MoveToReach") == "success"
    before = unfolded(read_state(bb), ARMS)
    assert _call(task, bb, rng, "GraspParam", which=WHICH_GRASP) == "success", \
        bb.get("last_failure_detail")
    arm = bb["arm_in_use"]
    assert world.physics.held_object(arm) == bb["grasp_target"]
    planned = read_state(bb)
    route = sd.clear_transits(world.physics, arm, before, [planned])
    assert route[-1] is planned and len(route) <= 3
    assert not any(arm_touches_table(world.physics, s, arm) for s in route[:-1])
    if len(route) > 1:  # inserted only where the direct motion touches the table
        assert sd.line_touches_table(world.physics, before, planned, arm)


def test_a_box_too_wide_for_the_fingers_is_an_outcome() -> None:
    task, bb, rng = _scene(1)
    world = world_of(task.registry)
    assert world is not None
    wide = {name: (0.06, 0.06, 0.06) for name in bb["object_positions_world"]}
    bb["object_half_extents_m"] = wide  # 12 cm across: the open fingers span 9 cm
    bb["object_positions_world"] = {n: (p[0], p[1], p[2]) for n, p in
                                    bb["object_positions_world"].items()}
    sd.start_episode(world, bb)
    _call(task, bb, rng, "RecogniseObject")
    outcomes = [_call(task, bb, rng, "GraspParam", which=WHICH_GRASP) for _ in range(2)]
    assert "failure" in outcomes
    assert bb["last_failure_reason"] in (*DYNAMIC_FAILURE_REASONS, *FAILURE_REASONS)


def _runs(n: int, first: int = 0, trace: bool = False) -> list[tuple[object, ...]]:
    task = load_task("examples.stacking", backend="dynamic", trials=1)
    compiled = compile_fsa(load_fsa(SHIPPED), task.registry, "dynamic")
    out: list[tuple[object, ...]] = []
    for rng in list(trial_rngs(SEED, first + n))[first:]:
        bb = task.setup(rng)
        result = compiled.run(bb, rng, trace=trace)
        out.append((task.score(result, bb), result.outcome, bb.get("last_failure_reason"),
                    bb["object_positions_world"],
                    [(s.state, s.outcome) for s in result.trace or ()]))
    return out


@pytest.mark.slow
def test_the_shipped_fsa_stacks_on_most_scenes() -> None:
    scores = [o[0] for o in _runs(4, first=1)]
    assert sum(s == 0.0 for s in scores) >= 2, scores  # measured: 3 of these 4


@pytest.mark.slow
def test_same_seed_same_episode() -> None:
    assert _runs(1, first=1, trace=True) == _runs(1, first=1, trace=True)
