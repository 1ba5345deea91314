"""The pour-water task: equation (1), its settings, and the hand-written reference FSA."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from examples import pour_water as ex
from skillcompose import FSA, Blackboard, CompiledFSA, State, compile_fsa, load_fsa
from skillcompose.skills import pour_water as pw
from skillcompose.task import Task, TaskError, load_task

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = ROOT / "examples" / "pour_water_reference.fsa.yaml"


LEVEL = (0.0, math.pi / 2, 0.0)  # tipped level towards +x: the lip 2.8 cm on, 3.5 cm down


def end_state(
    *, holding: bool, spout: tuple[float, float, float], water: str = "jug",
    rotation: tuple[float, float, float] = LEVEL,
) -> Blackboard:
    bb = ex.setup(np.random.default_rng(0))
    bb["holding_jug"] = holding
    bb["jug_position_world"] = spout
    bb["gripper_rotation"] = rotation
    bb["water"] = water
    return bb


SPOUT = (0.572, 0.50, 0.955)  # tipped level, its lip 30 cm beside the pouring point
D = 0.30


def test_fitness_is_zero_on_success() -> None:
    bb = end_state(holding=True, spout=(0.6, 0.2, 0.95), water="glass")
    assert ex.fitness("success", bb, 6) == 0.0


def test_fitness_is_20_when_the_jug_is_not_in_the_gripper() -> None:
    for outcome in ("failure", "timeout"):
        assert ex.fitness(outcome, end_state(holding=False, spout=SPOUT), 20) == 20.0


def test_fitness_is_twice_the_distance_on_timeout() -> None:
    assert ex.fitness("timeout", end_state(holding=True, spout=SPOUT), 20) == pytest.approx(2 * D)


def test_fitness_is_the_distance_otherwise() -> None:
    assert ex.fitness("failure", end_state(holding=True, spout=SPOUT), 7) == pytest.approx(D)


def test_the_distance_is_the_waters_to_the_pouring_point() -> None:
    """Still in the jug: from the lip, plus the arc the lip must turn before the water
    leaves; spilled: from where it began to leave."""
    from skillcompose.skills.pour_geometry import JUG_MOUTH_RADIUS_M

    gx, gy, gz = ex.GLASS_RIM_WORLD
    at_point = (gx - 0.028, gy, gz + 0.05 + 0.035)  # the level jug's lip at the point
    assert ex.fitness("failure", end_state(holding=True, spout=at_point), 7) == \
        pytest.approx(0.0, abs=1e-9)
    # tipped 60 degrees at the same spout, the jug keeps its water: the 30 degrees of arc
    # its lip still has to turn count
    short = end_state(holding=True, spout=at_point, rotation=(0.0, math.pi / 3, 0.0))
    assert ex.fitness("failure", short, 7) > JUG_MOUTH_RADIUS_M * math.pi / 6
    spilled = end_state(holding=True, spout=(0.2, -0.5, 1.4), water="spilled")
    spilled["water_left_at_world"] = (gx, gy + 0.1, gz + 0.05)
    assert ex.fitness("failure", spilled, 7) == pytest.approx(0.1)


def test_a_turn_that_pours_then_swings_away_scores_where_it_missed() -> None:
    """The trap the place of spilled water closes: a turn that began to pour at the
    pouring point and tipped on past 120° scores the distance from where it missed (2 cm
    and more here), not about 0 from where it began."""
    bb = end_state(holding=True, spout=SPOUT, rotation=(0.0, 0.0, 0.0))
    bb["p_fail"] = 0.0
    gx, gy, gz = ex.GLASS_RIM_WORLD
    at = (gx - 0.02, gy, gz + 0.08)
    pw.move_gripper_to_param(bb, 0, x=at[0], y=at[1], z=at[2])
    poured = Blackboard({k: bb[k] for k in bb})
    pw.rotate_gripper_to_param(poured, 0, rho=0.0, phi=1.6, theta=0.0)
    pw.rotate_gripper_to_param(bb, 0, rho=0.0, phi=2.6, theta=0.0)
    assert poured["water"] == "glass" and bb["water"] == "spilled"
    assert ex.fitness("failure", poured, 7) < 0.01
    assert ex.fitness("failure", bb, 7) > 0.02


def test_success_without_water_in_the_glass_is_not_rewarded() -> None:
    assert ex.fitness("success", end_state(holding=True, spout=SPOUT), 3) == pytest.approx(D)
    assert ex.fitness("success", end_state(holding=False, spout=SPOUT), 3) == 20.0


def test_make_task_settings_and_their_errors() -> None:
    task = load_task("examples.pour_water", p_fail=0.35)
    assert task.step_limit == 20 and task.minimize and task.target == 0.0
    assert task.settings["p_fail"] == 0.35
    assert task.setup(np.random.default_rng(0))["p_fail"] == 0.35
    assert task.ref is not None and task.ref.build().settings == task.settings
    assert load_task("examples.pour_water").settings["p_fail"] == 0.2  # the paper's
    with pytest.raises(TaskError, match=r"p_fail=1\.5 must be a probability"):
        ex.make_task(p_fail=1.5)
    with pytest.raises(TaskError, match="trials=0"):
        ex.make_task(trials=0)
    with pytest.raises(TaskError, match="rejected settings"):
        load_task("examples.pour_water", pfail=0.3)


def test_setup_draws_nothing_from_the_generator() -> None:
    rng = np.random.default_rng(9)
    before = rng.bit_generator.state
    ex.setup(rng)
    assert rng.bit_generator.state == before


def reference_task(p_fail: float) -> tuple[Task, CompiledFSA]:
    task = load_task("examples.pour_water", p_fail=p_fail)
    return task, compile_fsa(load_fsa(REFERENCE), task.registry, task.backend)


def test_reference_fsa_solves_the_task_at_p_fail_zero() -> None:
    task, compiled = reference_task(0.0)
    runs = task.run_trials(compiled, seed=0, trials=20)
    assert all(r.outcome == "success" and r.steps == 6 and f == 0.0 for r, f in runs)
    assert task.solved(task.evaluate(compiled, seed=0, trials=20))


def test_reference_fsa_is_robust_at_the_papers_p_fail() -> None:
    task, compiled = reference_task(0.2)
    runs = task.run_trials(compiled, seed=1, trials=2000)
    assert all(r.outcome == "success" for r, _ in runs)  # it retries within 20 steps
    assert max(r.steps for r, _ in runs) > 6  # and it did have to retry


def test_reference_fsa_file_is_six_states_with_the_papers_step_limit() -> None:
    fsa = load_fsa(REFERENCE)
    assert fsa.step_limit == 20
    assert sorted(fsa.skills_used()) == sorted(
        ["RecogniseObject", "MoveToObject", "GraspObject", "MoveGripperToParam",
         "RotateGripperToParam", "CheckSuccess"]
    )
    assert fsa.unreachable() == []


def test_editing_the_reference_parameters_breaks_it() -> None:
    task = load_task("examples.pour_water", p_fail=0.0)
    fsa = load_fsa(REFERENCE)
    too_high = fsa.with_params("MoveOverGlass", z=1.1)  # 23 cm above the rim: splashes
    not_tilted = fsa.with_params("Pour", phi=0.5)
    for edited in (too_high, not_tilted):
        run = task.run_trials(compile_fsa(edited, task.registry, task.backend), 0, 1)[0]
        assert run[0].outcome == "failure" and run[1] > 0.0


def test_a_chain_without_retries_fails_as_often_as_p_fail_predicts() -> None:
    """Three random-failure skills in a row succeed with (1 - p)^3."""
    task = load_task("examples.pour_water", p_fail=0.2)
    reg = task.registry
    fsa = FSA.chain(
        ["RecogniseObject", "MoveToObject", "GraspObject", "MoveGripperToParam",
         "RotateGripperToParam", "CheckSuccess"], registry=reg, step_limit=20,
    )
    fsa = fsa.with_params("MoveGripperToParam_4", x=0.58, y=0.2, z=0.95)
    fsa = fsa.with_params("RotateGripperToParam_5", rho=0.0, phi=1.6, theta=0.0)
    fsa = fsa.replace(states={
        **fsa.states,
        "CheckSuccess_6": State("CheckSuccess", {}, {"success": "success", "failure": "failure"}),
    })
    runs = task.run_trials(compile_fsa(fsa, reg, task.backend), seed=2, trials=4000)
    rate = np.mean([r.outcome == "success" for r, _ in runs])
    assert abs(rate - 0.8**3) < 4 * np.sqrt(0.512 * 0.488 / 4000)


def test_the_closest_place_to_the_glass_is_one_that_pours() -> None:
    """The fitness's distance is from the jug's lip to the pouring point, 5 cm over the rim:
    a jug held upright just beside the glass at rim height, where the distance to the rim
    itself is small, scores worse than every pose that pours, taken as if its water were
    still in (drawn with rotations that pour from there, the jug clear of the glass)."""
    from skillcompose.skills.pour_geometry import (
        held_jug_hits_glass,
        rpy_matrix,
        water_after_motion,
    )

    gx, gy, gz = ex.GLASS_RIM_WORLD
    beside = (gx - 0.081, gy, gz)
    assert not held_jug_hits_glass(beside, (0.0, 0.0, 0.0), ex.GLASS_RIM_WORLD)
    worst_in_window = 0.0
    rng = np.random.default_rng(0)
    upright = rpy_matrix((0.0, 0.0, 0.0))
    pouring = 0
    while pouring < 300:
        r, a = 0.06 * np.sqrt(rng.random()), 2 * np.pi * rng.random()
        spout = (gx + r * np.cos(a), gy + r * np.sin(a), gz + rng.uniform(0.0, 0.2))
        rx, ry, rz = (float(v) for v in rng.uniform(-np.pi, np.pi, 3))
        rotation = (rx, ry, rz)
        if held_jug_hits_glass(spout, rotation, ex.GLASS_RIM_WORLD) or water_after_motion(
                spout, upright, spout, rpy_matrix(rotation), ex.GLASS_RIM_WORLD) != "glass":
            continue
        pouring += 1
        there = ex.fitness("failure", end_state(holding=True, spout=spout, rotation=rotation), 9)
        worst_in_window = max(worst_in_window, there)
    held_upright = end_state(holding=True, spout=beside, rotation=(0.0, 0.0, 0.0))
    assert ex.fitness("failure", held_upright, 9) > worst_in_window
