"""Moving to push (§4.2): each skill's outcomes on hand-built worlds, on both backends, and
the task's worlds and fitness."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from skillcompose import FSA, Blackboard, Registry, State, compile_fsa, load_task
from skillcompose.robots.collision import Box
from skillcompose.skills.move_to_push import (
    BASE_STEP_M,
    TORSO_RANGE_M,
    base_hits_table,
    base_in_room,
    classifier_label,
    object_in_robot_frame,
)

ROOT = Path(__file__).resolve().parents[2]
TABLE = Box.table((1.3, 0.0), (0.6, 1.0), 0.75)  # near edge at x = 1.0
OBJECT = (1.1, 0.1, 0.85)


def constant_weights(dx: float, dy: float, turn: float, torso: float, arm: str) -> tuple:
    """Layered weights whose outputs do not depend on the inputs: a fixed base move [m, m,
    rad], torso height [m] and arm, through the output biases only."""
    def logit(p: float) -> float:
        return math.log(p / (1 - p))

    outputs = (
        (dx / BASE_STEP_M + 1) / 2, (dy / BASE_STEP_M + 1) / 2, (turn / math.pi + 1) / 2,
        torso / TORSO_RANGE_M[1], 0.8 if arm == "left" else 0.2,
    )
    second = []
    for o in outputs:
        second += [0.0, 0.0, 0.0, logit(o)]
    return tuple([0.0] * 18 + second)


def world(base: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Blackboard:
    return Blackboard({
        "table_world": TABLE, "object_position_world": OBJECT, "base_pose_world": base,
        "room_half_m": 2.5, "torso_height_m": 0.0, "arm_in_use": None,
        "object_half_extents_m": (0.03, 0.03, 0.10),
    })


def fsa_with(weights: tuple) -> FSA:
    return FSA({
        "Recognise": State("RecogniseObject", {}, {"success": "Move"}),
        "Move": State("MoveBase", {"weights": weights}, {"success": "Push",
                                                        "failure": "failure"}),
        "Push": State("Push", {}, {"success": "success", "failure": "failure"}),
    }, "Recognise")


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_task("examples.move_to_push").registry


GOOD = constant_weights(0.4, 0.0, 0.0, 0.15, "left")  # the object ends 0.7 m ahead, 0.1 left


def test_geometry_helpers() -> None:
    assert object_in_robot_frame((1.0, 1.0, math.pi / 2), (1.0, 2.0, 0.8)) == pytest.approx(
        (1.0, 0.0, 0.8))
    assert base_hits_table((0.8, 0.0, 0.0), TABLE)  # 0.334 m half size reaches x = 1.0
    assert not base_hits_table((0.6, 0.0, 0.0), TABLE)
    assert base_hits_table((0.6, 0.0, 0.0), TABLE, margin_m=0.1)  # a safety distance
    assert base_hits_table((0.7, 0.0, math.pi / 4), TABLE)  # a corner reaches further
    assert base_in_room((2.0, 0.0, 0.0), 2.5) and not base_in_room((2.2, 0.0, 0.0), 2.5)
    assert base_in_room((2.1, 0.0, 0.0), 2.5) and not base_in_room((2.1, 0.0, math.pi / 4), 2.5)


def test_recognise_then_move_writes_the_pose(registry: Registry) -> None:
    bb = world()
    result = compile_fsa(fsa_with(GOOD), registry, "sim").run(bb, 0, trace=True)
    assert result.outcome == "success"
    assert [s.state for s in result.trace or ()] == ["Recognise", "Move", "Push"]
    assert bb["object_location_world"] == OBJECT
    assert bb["base_pose_world"] == pytest.approx((0.4, 0.0, 0.0), abs=1e-9)
    assert bb["torso_height_m"] == pytest.approx(0.15) and bb["arm_in_use"] == "left"
    assert bb["pushed"] is True


@pytest.mark.parametrize(
    ("weights", "base", "why"),
    [
        (constant_weights(1.2, 0.0, 0.0, 0.1, "left"), (0.0, 0.0, 0.0), "into the table"),
        (constant_weights(0.64, 0.0, 0.0, 0.1, "left"), (0.0, 0.0, 0.0), "within 5 cm of it"),
        (constant_weights(-2.0, 0.0, 0.0, 0.1, "left"), (-1.0, 0.0, 0.0), "out of the room"),
    ],
)
def test_move_base_fails_on_the_table_and_out_of_the_room(
    registry: Registry, weights: tuple, base: tuple, why: str
) -> None:
    bb = world(base)
    result = compile_fsa(fsa_with(weights), registry, "sim").run(bb, 0, trace=True)
    assert result.outcome == "failure", why
    assert [s.state for s in result.trace or ()] == ["Recognise", "Move"]
    assert bb["base_pose_world"] == base  # nothing moved


def test_move_base_fails_without_a_recognised_object(registry: Registry) -> None:
    fsa = FSA({"Move": State("MoveBase", {"weights": GOOD}, {"success": "success",
                                                             "failure": "failure"})}, "Move")
    assert compile_fsa(fsa, registry, "sim").run(world(), 0).outcome == "failure"


@pytest.mark.parametrize(
    ("weights", "outcome"),
    [
        (GOOD, "success"),
        (constant_weights(0.4, 0.0, 0.0, 0.15, "right"), "failure"),  # the classifier: left
        (constant_weights(0.0, 0.0, 0.0, 0.15, "left"), "failure"),  # 1.1 m: out of reach
        (constant_weights(0.4, 0.0, math.pi / 2, 0.15, "left"), "failure"),  # turned away
    ],
)
def test_push_follows_the_classifier(registry: Registry, weights: tuple, outcome: str) -> None:
    bb = world()
    assert compile_fsa(fsa_with(weights), registry, "sim").run(bb, 0).outcome == outcome
    label = classifier_label(bb["base_pose_world"], bb["torso_height_m"], OBJECT)
    assert (label == {"left": 1, "right": 2}[bb["arm_in_use"]]) == (outcome == "success")


@pytest.mark.kinematics
def test_the_kinematic_twins_move_the_same_robot_and_judge_by_ik(registry: Registry) -> None:
    sim_bb, kin_bb = world(), world()
    compile_fsa(fsa_with(GOOD), registry, "sim").run(sim_bb, 3)
    result = compile_fsa(fsa_with(GOOD), registry, "kinematic").run(kin_bb, 3)
    assert result.outcome == "success", kin_bb.get("last_failure_detail")
    assert kin_bb["base_pose_world"] == pytest.approx(sim_bb["base_pose_world"])
    assert kin_bb["torso_height_m"] == pytest.approx(sim_bb["torso_height_m"])
    assert kin_bb["pushed"] is True
    assert kin_bb["object_position_world"][0] > OBJECT[0]  # pushed away from the robot


@pytest.mark.kinematics
@pytest.mark.parametrize(
    ("weights", "reason"),
    [
        (constant_weights(0.0, 0.0, 0.0, 0.15, "left"), "unreachable"),
        (constant_weights(1.2, 0.0, 0.0, 0.1, "left"), "collision"),
    ],
)
def test_kinematic_failures_say_why(registry: Registry, weights: tuple, reason: str) -> None:
    bb = world()
    result = compile_fsa(fsa_with(weights), registry, "kinematic").run(bb, 3)
    assert result.outcome == "failure"
    assert bb["last_failure_reason"] == reason


def test_worlds_follow_the_documented_distribution() -> None:
    from examples.move_to_push import OBJECT_BAND_M, ROOM_HALF_M, random_world

    rng = np.random.default_rng(0)
    for judge in (False, True):
        for _ in range(300):
            w = random_world(rng, judge=judge)
            table, obj, base = w["table_world"], w["object_position_world"], w["base_pose_world"]
            assert base_in_room(base, ROOM_HALF_M) and not base_hits_table(base, table)
            (tx, ty, _), (hx, hy, hz) = table.center_m, table.half_extents_m
            assert 0.15 - 1e-9 <= hx <= 0.6 + 1e-9 and 0.70 <= 2 * hz <= 0.80
            inside = min(hx - abs(obj[0] - tx), hy - abs(obj[1] - ty))
            assert OBJECT_BAND_M[0] - 1e-9 <= inside <= OBJECT_BAND_M[1] + 1e-9
            x, y, _ = object_in_robot_frame(base, obj)
            if judge:
                assert x >= 0 and math.hypot(x, y) <= 1.5
    a = [random_world(np.random.default_rng(7)) for _ in range(2)]
    assert a[0]["base_pose_world"] == a[1]["base_pose_world"]  # only the generator decides


def test_fitness_is_success_of_the_push() -> None:
    from examples.move_to_push import fitness

    assert fitness("success", Blackboard({"pushed": True}), 3) == 1.0
    assert fitness("success", Blackboard({}), 3) == 0.0  # a hand-routed success: no push
    assert fitness("failure", Blackboard({"pushed": False}), 3) == 0.0
    assert fitness("timeout", Blackboard({}), 20) == 0.0


def test_ending_names_where_a_run_stopped_and_agrees_with_the_fitness() -> None:
    from examples.move_to_push import ENDINGS, ending, fitness

    cases = {("success", True): "pushed", ("success", False): "ended otherwise",
             ("failure", False): "Push out of reach", ("timeout", False): "out of steps",
             ("error", False): "ended otherwise"}
    for (outcome, pushed), name in cases.items():
        bb = Blackboard({"pushed": pushed})
        assert ending(outcome, bb) == name and name in ENDINGS
        assert (name == "pushed") == (fitness(outcome, bb, 3) == 1.0)


def test_task_settings_are_checked() -> None:
    from skillcompose import TaskError

    with pytest.raises(TaskError, match="network='cnn' must be one of"):
        load_task("examples.move_to_push", network="cnn")
    with pytest.raises(TaskError, match="backend='kinmatic' must be one of"):
        load_task("examples.move_to_push", backend="kinmatic")
    assert load_task("examples.move_to_push", network="recurrent").registry.spec(
        "MoveBase").param("weights").size == 112
    assert load_task("examples.move_to_push", network="layered-12").registry.spec(
        "MoveBase").param("weights").size == 137


@pytest.mark.kinematics
def test_the_evolved_file_runs_on_both_backends_from_the_command_line() -> None:
    """The shipped MoveToReach, unchanged: pushed in most judged worlds on either backend."""
    path = ROOT / "examples" / "move_to_reach.fsa.yaml"
    for backend in ("sim", "kinematic"):
        out = subprocess.run(
            [sys.executable, "-m", "skillcompose", "run", str(path), "--task",
             "examples.move_to_push", "--set", f"backend={backend}", "--set", "judge=true",
             "--trials", "20", "--seed", "1"],
            capture_output=True, text=True, cwd=ROOT, timeout=300,
        )
        assert out.returncode == 0, out.stderr
        assert f"20 run(s), seed 1, backend {backend}" in out.stdout
        counts = dict(line.split()[:2] for line in out.stdout.splitlines()[1:3])
        assert int(counts.get("success", 0)) >= 16, out.stdout


@pytest.mark.slow
def test_a_short_evolution_improves_the_push() -> None:
    from skillcompose.evolve import PRESETS, EvolutionConfig, evolve

    task = load_task("examples.move_to_push", trials=5)
    cfg = EvolutionConfig(**{**PRESETS["push"], "population": 60, "generations": 30,
                             "trials": 5, "confirm_trials": 20})
    result = evolve(task, cfg, seed=1, workers=1, backend="serial")
    first = result.history[0].best
    best = max(h.best for h in result.history)
    assert best > first and best >= 0.4, [h.best for h in result.history]
