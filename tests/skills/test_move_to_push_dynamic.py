"""Moving to push on the dynamic backend (the PR2 in MuJoCo): a push moves the object through
contact, physics' failures are outcomes, the shipped FSA pushes, and runs repeat exactly."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mujoco")

from skillcompose import Blackboard, Registry, compile_fsa, load_fsa
from skillcompose.executor import trial_rngs
from skillcompose.robots.physics_model import ObjectSpec, SceneSpec
from skillcompose.skills import move_to_push_dynamic as mtp
from skillcompose.skills.dynamic_world import (
    DYNAMIC_FAILURE_REASONS,
    DynamicWorld,
    in_dynamic_world,
    world_of,
)
from skillcompose.skills.kinematic_world import DEFAULT_TABLE_WORLD, FAILURE_REASONS
from skillcompose.task import load_task

pytestmark = [pytest.mark.physics, pytest.mark.kinematics]

SHIPPED = "examples/move_to_reach.fsa.yaml"
HALF = (0.03, 0.03, 0.10)


def _facing_bb() -> Blackboard:
    """The robot at the origin facing the default table, the object on it."""
    return Blackboard({
        "table_world": DEFAULT_TABLE_WORLD, "object_position_world": (0.60, -0.20, 0.85),
        "object_half_extents_m": HALF, "base_pose_world": (0.0, 0.0, 0.0),
        "torso_height_m": 0.2, "arm_in_use": "right", "room_half_m": 2.5,
    })


def _push(world: DynamicWorld, bb: Blackboard) -> str:
    (bound,) = in_dynamic_world((mtp.push,), world)
    return str(bound.bind()(bb, np.random.default_rng(3)))


def _first_world(scene: SceneSpec | None = None) -> tuple[Blackboard, object, object]:
    """The shipped FSA on the first judged placement of the reproduction (seed 20 000),
    optionally with another scene: (blackboard after the run, outcome, object at start)."""
    task = load_task("examples.move_to_push", backend="dynamic", judge=True)
    world = world_of(task.registry)
    assert world is not None
    compiled = compile_fsa(load_fsa(SHIPPED), task.registry, "dynamic")
    rng = next(iter(trial_rngs(20_000, 1)))
    bb = task.setup(rng)
    if scene is not None:
        world.start(bb, scene, object_poses={"object": tuple(bb["object_position_world"])})
    assert world.physics is not None
    start = np.array(world.physics.object_pose("object")[:3])
    result = compiled.run(bb, rng)
    return bb, result.outcome, start


def test_a_push_moves_the_object_5_cm_and_it_stands() -> None:
    bb, outcome, start = _first_world()
    assert outcome == "success" and bb["pushed"] is True, bb.get("last_failure_detail")
    moved = np.array(bb["object_position_world"]) - np.asarray(start)
    assert float(np.linalg.norm(moved[:2])) >= mtp.PUSHED_M
    assert abs(float(moved[2])) < 0.01  # it slid on the table, upright


def test_a_grippy_object_topples_and_that_is_an_outcome() -> None:
    bb = load_task("examples.move_to_push", judge=True).setup(next(iter(trial_rngs(20_000, 1))))
    grippy = SceneSpec(table=bb["table_world"], objects=(
        ObjectSpec("object", "box", HALF, 0.3, 3.0),))  # friction 3: it tips, not slides
    after, outcome, _ = _first_world(grippy)
    assert outcome == "failure"
    assert after["last_failure_reason"] in (*DYNAMIC_FAILURE_REASONS, *FAILURE_REASONS)
    assert "pushed" not in after


def test_a_skill_without_an_episode_refuses_with_the_fix() -> None:
    from skillcompose.errors import BlackboardKeyError

    with pytest.raises(BlackboardKeyError, match="backend=dynamic"):
        _push(DynamicWorld(), _facing_bb())


def test_the_base_drives_round_the_table() -> None:
    bb = Blackboard({"table_world": DEFAULT_TABLE_WORLD})
    straight = mtp.base_route(bb, (0.0, 0.0, 0.0), (0.0, 1.5, 0.0))
    assert straight == [(0.0, 1.5, 0.0)]
    around = mtp.base_route(bb, (0.0, 0.0, 0.0), (1.6, 0.0, np.pi))
    assert len(around) >= 2 and around[-1] == (1.6, 0.0, np.pi)


def _outcomes(n: int, seed: int = 20_000, trace: bool = False) -> list[tuple[object, ...]]:
    task = load_task("examples.move_to_push", backend="dynamic", judge=True)
    compiled = compile_fsa(load_fsa(SHIPPED), task.registry, "dynamic")
    out: list[tuple[object, ...]] = []
    for rng in trial_rngs(seed, n):
        bb = task.setup(rng)
        result = compiled.run(bb, rng, trace=trace)
        out.append((task.score(result, bb), result.outcome, bb.get("last_failure_reason"),
                    bb["object_position_world"], bb["base_pose_world"],
                    [(s.state, s.outcome) for s in result.trace or ()]))
    return out


@pytest.mark.slow
def test_the_shipped_fsa_pushes_on_most_judged_placements() -> None:
    scores = [o[0] == 1.0 for o in _outcomes(6)]
    assert sum(scores) >= 4, scores  # measured: 5 of these 6 (17 of the first 20)


def test_same_seed_same_episode() -> None:
    assert _outcomes(1, seed=20_003, trace=True) == _outcomes(1, seed=20_003, trace=True)


def test_the_task_takes_backend_dynamic() -> None:
    task = load_task("examples.move_to_push", backend="dynamic", world="paper")
    assert task.backend == "dynamic"
    assert isinstance(task.registry, Registry)
