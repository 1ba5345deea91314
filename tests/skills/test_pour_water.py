"""The six pour-water skills: outcomes, probabilities (with fixed seeds) and effects."""

from __future__ import annotations

import math

import numpy as np
import pytest

from examples.pour_water import GLASS_RIM_WORLD, GRIPPER_HOME_WORLD, JUG_SPOUT_WORLD, setup
from skillcompose import Blackboard, BlackboardAccessError, BlackboardKeyError, Registry, Skill
from skillcompose.skills import pour_water as pw

N = 20_000  # calls per probability estimate: 4 standard errors at p = 0.2 are ±0.011


def world(p_fail: float = 0.2) -> Blackboard:
    return setup(np.random.default_rng(0), p_fail=p_fail)


def recognised(p_fail: float = 0.2) -> Blackboard:
    bb = world(p_fail)
    pw.recognise_object(bb, 0)
    return bb


def approached(p_fail: float = 0.0) -> Blackboard:
    bb = recognised(p_fail)
    assert pw.move_to_object(bb, 0) == "success"
    return bb


def holding(p_fail: float = 0.0) -> Blackboard:
    bb = approached(p_fail)
    assert pw.grasp_object(bb, 0) == "success"
    bb["p_fail"] = p_fail
    return bb


def rate(skill: Skill, bb: Blackboard, seed: int, **params: float) -> float:
    """Fraction of ``failure`` over N calls on ``bb`` (whose preconditions a success keeps)."""
    rng = np.random.default_rng(seed)
    fails = sum(skill(bb, rng, **params) == "failure" for _ in range(N))
    return fails / N


def close(got: float, p_fail: float) -> bool:
    """Within 4 standard errors of ``p_fail`` (exact when p_fail is 0 or 1)."""
    return abs(got - p_fail) <= 4 * math.sqrt(p_fail * (1 - p_fail) / N)


def test_registry_has_the_six_skills_with_their_outcomes() -> None:
    reg = Registry()
    pw.register(reg)
    assert reg.names() == [
        "RecogniseObject", "MoveToObject", "GraspObject", "MoveGripperToParam",
        "RotateGripperToParam", "CheckSuccess",
    ]
    assert reg.spec("RecogniseObject").outcomes == ("success",)
    assert reg.spec("RotateGripperToParam").outcomes == ("success",)
    for name in ("MoveToObject", "GraspObject", "MoveGripperToParam", "CheckSuccess"):
        assert reg.spec(name).outcomes == ("success", "failure")
    assert reg.spec("MoveGripperToParam").param_names == ("x", "y", "z")
    assert {p.unit for p in reg.spec("MoveGripperToParam").params} == {"m"}
    assert reg.spec("RotateGripperToParam").param_names == ("rho", "phi", "theta")
    assert {p.unit for p in reg.spec("RotateGripperToParam").params} == {"rad"}
    for s in pw.SKILLS:
        assert s.backend == "sim"


def test_recognise_object_stores_both_locations_and_always_succeeds() -> None:
    rng = np.random.default_rng(1)
    for _ in range(100):
        bb = world(p_fail=1.0)
        assert pw.recognise_object(bb, rng) == "success"
        assert bb["jug_location_world"] == JUG_SPOUT_WORLD
        assert bb["glass_location_world"] == GLASS_RIM_WORLD


def test_recognise_object_without_a_world_names_the_missing_key_and_the_fix() -> None:
    with pytest.raises(BlackboardKeyError, match=r"jug_position_world.*--task examples\."):
        pw.recognise_object(Blackboard(), 0)


@pytest.mark.parametrize(("p_fail", "seed"), [(0.2, 11), (0.5, 12)])
def test_move_to_object_fails_with_p_fail(p_fail: float, seed: int) -> None:
    assert close(rate(pw.move_to_object, recognised(p_fail), seed), p_fail)


def test_move_to_object_brings_the_gripper_within_10_cm_of_the_jug() -> None:
    bb = approached()
    d = pw.distance(bb["gripper_position_world"], bb["jug_position_world"])
    assert 0.0 < d <= pw.APPROACH_TOLERANCE_M == 0.10
    assert bb["gripper_rotation"] == (0.0, 0.0, 0.0)


def test_move_to_object_fails_without_recognition_and_draws_nothing() -> None:
    rng = np.random.default_rng(3)
    before = rng.bit_generator.state
    bb = world(p_fail=0.0)
    assert pw.move_to_object(bb, rng) == "failure"
    assert rng.bit_generator.state == before
    assert bb["gripper_position_world"] == GRIPPER_HOME_WORLD


def test_a_random_failure_moves_nothing() -> None:
    bb = recognised(p_fail=1.0)
    assert pw.move_to_object(bb, 0) == "failure"
    assert bb["gripper_position_world"] == GRIPPER_HOME_WORLD
    assert pw.move_gripper_to_param(bb, 0, x=0.5, y=0.0, z=1.0) == "failure"
    assert bb["gripper_position_world"] == GRIPPER_HOME_WORLD


@pytest.mark.parametrize(("p_fail", "seed"), [(0.2, 21), (0.7, 22)])
def test_grasp_object_fails_with_p_fail_when_approached(p_fail: float, seed: int) -> None:
    bb = approached(0.0)
    bb["p_fail"] = p_fail
    assert close(rate(pw.grasp_object, bb, seed), p_fail)


def test_grasp_object_fails_unless_detected_and_approached() -> None:
    rng = np.random.default_rng(4)
    for _ in range(200):
        assert pw.grasp_object(world(p_fail=0.0), rng) == "failure"  # neither
        assert pw.grasp_object(recognised(p_fail=0.0), rng) == "failure"  # not approached
    bb = approached(p_fail=0.0)
    del bb["jug_location_world"]  # approached but, somehow, not detected
    assert pw.grasp_object(bb, rng) == "failure"


def test_grasp_object_puts_the_jug_in_the_gripper() -> None:
    bb = holding()
    assert bb["holding_jug"] is True
    assert bb["jug_position_world"] == bb["gripper_position_world"]
    assert bb["water"] == "jug"


@pytest.mark.parametrize(("p_fail", "seed"), [(0.2, 31), (0.0, 32), (1.0, 33)])
def test_move_gripper_to_param_fails_with_p_fail(p_fail: float, seed: int) -> None:
    got = rate(pw.move_gripper_to_param, world(p_fail), seed, x=0.5, y=0.1, z=1.0)
    assert close(got, p_fail)


def test_move_gripper_to_param_moves_the_jug_only_when_held() -> None:
    bb = recognised(p_fail=0.0)
    pw.move_gripper_to_param(bb, 0, x=0.4, y=0.3, z=1.2)
    assert bb["gripper_position_world"] == (0.4, 0.3, 1.2)
    assert bb["jug_position_world"] == JUG_SPOUT_WORLD
    bb = holding()
    pw.move_gripper_to_param(bb, 0, x=0.4, y=0.3, z=1.2)
    assert bb["jug_position_world"] == (0.4, 0.3, 1.2)


def test_move_gripper_to_param_declares_the_workspace() -> None:
    spec = pw.move_gripper_to_param.spec
    assert [(p.low, p.high) for p in spec.params] == list(pw.WORKSPACE_WORLD)
    with pytest.raises(Exception, match=r"between 0\.75 and 1\.5"):
        pw.move_gripper_to_param(world(), 0, z=0.5)


def over_glass(height: float = 0.08, dx: float = 0.0, dy: float = 0.0
               ) -> tuple[float, float, float]:
    return (GLASS_RIM_WORLD[0] + dx, GLASS_RIM_WORLD[1] + dy, GLASS_RIM_WORLD[2] + height)


# tipped level towards +x, the jug's lip lies 2.8 cm beyond its spout (3.5 cm below it):
# a spout 2 cm short of the glass's centre puts the lip 0.8 cm past it
SHORT = -0.02


def test_rotating_the_held_jug_over_the_glass_pours_it() -> None:
    bb = holding()
    g = over_glass(dx=SHORT)
    pw.move_gripper_to_param(bb, 0, x=g[0], y=g[1], z=g[2])
    assert bb["water"] == "jug"
    rng = np.random.default_rng(5)
    assert pw.rotate_gripper_to_param(bb, rng, rho=0.0, phi=math.pi / 2, theta=0.0) == "success"
    assert bb["water"] == "glass"
    assert pw.check_success(bb, rng) == "success"


@pytest.mark.parametrize(
    ("where", "angles", "water"),
    [
        (over_glass(dx=SHORT), (0.0, 0.9, 0.0), "jug"),  # 52° is not enough to pour
        (over_glass(dx=SHORT), (0.0, 1.5, 0.0), "jug"),  # nor 86°: not yet level
        (over_glass(dx=SHORT), (0.0, 0.0, 2.5), "jug"),  # yaw alone never pours
        (over_glass(dx=SHORT), (0.0, 1.6, 0.0), "glass"),  # 92° of pitch, the lip over it
        (over_glass(dy=-SHORT), (1.6, 0.0, 0.0), "glass"),  # 92° of roll tips towards -y
        (over_glass(dy=SHORT), (0.0, 1.6, math.pi / 2), "glass"),  # the yaw turns it to +y
        (over_glass(dx=SHORT), (0.0, 1.6, math.pi), "spilled"),  # ... or away from the glass
        (over_glass(), (0.0, 1.6, 0.0), "spilled"),  # the spout at the centre: lip 2.8 cm off
        (over_glass(dx=-0.018), (0.0, 2.0, 0.0), "glass"),  # 115°: the lip swept 1 to -0.7 cm
        (over_glass(dx=SHORT), (0.0, 2.3, 0.0), "spilled"),  # 132°: out through the mouth
        (over_glass(0.2, dx=SHORT), (0.0, 1.6, 0.0), "spilled"),  # too high: splashes
        (over_glass(0.0), (0.0, 1.6, 0.0), "spilled"),  # the jug would be in the glass:
        # it stays where it was, and tipped there it spills
        (over_glass(0.08, 0.05), (0.0, 1.6, 0.0), "spilled"),  # 5 cm off the centre
        ((0.5, -0.3, 1.1), (0.0, 1.6, 0.0), "spilled"),  # nowhere near the glass
    ],
)
def test_pouring_tolerances(
    where: tuple[float, float, float], angles: tuple[float, float, float], water: str
) -> None:
    bb = holding()
    pw.move_gripper_to_param(bb, 0, x=where[0], y=where[1], z=where[2])
    pw.rotate_gripper_to_param(bb, 0, rho=angles[0], phi=angles[1], theta=angles[2])
    assert bb["water"] == water
    assert pw.check_success(bb, 0) == ("success" if water == "glass" else "failure")


def test_the_water_leaves_as_soon_as_the_jug_tips_past_level() -> None:
    """Tipped past level with its lip off the glass, the jug spills; tipped part way, it
    keeps the water, and pours when tipped on past level over the glass."""
    bb = holding()
    g = over_glass(dx=SHORT)
    pw.move_gripper_to_param(bb, 0, x=g[0], y=g[1], z=g[2])
    assert pw.rotate_gripper_to_param(bb, 0, rho=1.6, phi=0.0, theta=0.0) == "success"
    assert bb["water"] == "spilled"  # tipped towards -y: the lip 2.8 cm off to the side
    bb = holding()
    pw.move_gripper_to_param(bb, 0, x=g[0], y=g[1], z=g[2])
    pw.rotate_gripper_to_param(bb, 0, rho=0.0, phi=1.2, theta=0.0)
    assert bb["water"] == "jug"  # 69°: still in
    pw.rotate_gripper_to_param(bb, 0, rho=0.0, phi=1.6, theta=0.0)
    assert bb["water"] == "glass"  # on to 92°, over the glass


def test_spilled_water_is_placed_where_it_missed_the_glass() -> None:
    """Tipped on past 120° over the glass, the water begins to pour into it and then
    spills: the place it left is the lip where it first missed (tipped past 120°), not the
    lip where it began, which lies over the glass."""
    from skillcompose.skills.pour_geometry import POUR_TILT_MAX_RAD, pour_lip, pours_into_glass

    g = over_glass(dx=SHORT)
    began = holding()
    pw.move_gripper_to_param(began, 0, x=g[0], y=g[1], z=g[2])
    pw.rotate_gripper_to_param(began, 0, rho=0.0, phi=1.6, theta=0.0)
    assert began["water"] == "glass"
    assert pours_into_glass(began["water_left_at_world"], GLASS_RIM_WORLD)
    bb = holding()
    pw.move_gripper_to_param(bb, 0, x=g[0], y=g[1], z=g[2])
    pw.rotate_gripper_to_param(bb, 0, rho=0.0, phi=2.6, theta=0.0)
    assert bb["water"] == "spilled"
    # the turn about y is judged every 2.6 / 50 rad: the first pose past 120° is the 41st
    tilt = 2.6 * 41 / 50
    assert 2.6 * 40 / 50 <= POUR_TILT_MAX_RAD < tilt
    missed = pour_lip(g, (math.sin(tilt), 0.0, math.cos(tilt)))
    assert bb["water_left_at_world"] == pytest.approx(missed, abs=1e-9)
    assert math.dist(bb["water_left_at_world"], began["water_left_at_world"]) > 0.02


def test_the_rule_follows_the_shortest_turn() -> None:
    """The path is the shortest turn between the two rotations, whatever angles name them:
    roll pi, pitch pi - 1.6, yaw pi is the rotation of pitch 1.6 alone, and pours alike."""
    bb = holding()
    g = over_glass(dx=SHORT)
    pw.move_gripper_to_param(bb, 0, x=g[0], y=g[1], z=g[2])
    pw.rotate_gripper_to_param(bb, 0, rho=math.pi, phi=math.pi - 1.6, theta=math.pi)
    assert bb["water"] == "glass"


def test_the_held_jug_cannot_enter_the_glass() -> None:
    """The jug hangs 6.4 cm below its spout: a move that would put it into the glass fails
    and moves nothing; a rotation that would turn it into the glass, at its end or on the
    way, leaves the gripper."""
    bb = holding()
    before = bb["gripper_position_world"]
    g = over_glass(0.03, dx=SHORT)
    assert pw.move_gripper_to_param(bb, 0, x=g[0], y=g[1], z=g[2]) == "failure"
    assert bb["gripper_position_world"] == before and bb["water"] == "jug"
    g = over_glass(0.065, dx=SHORT)
    assert pw.move_gripper_to_param(bb, 0, x=g[0], y=g[1], z=g[2]) == "success"
    # a small roll dips a corner of the jug's bottom, only just above the rim, into it
    assert pw.rotate_gripper_to_param(bb, 0, rho=0.2, phi=0.0, theta=0.0) == "success"
    assert bb["gripper_rotation"] == (0.0, 0.0, 0.0) and bb["water"] == "jug"
    # tipping it about the grasp point swings a corner of its bottom down into the glass on
    # the way, though the jug ends clear of it: the gripper stays
    assert pw.rotate_gripper_to_param(bb, 0, rho=0.0, phi=math.pi / 2, theta=0.0) == "success"
    assert bb["gripper_rotation"] == (0.0, 0.0, 0.0) and bb["water"] == "jug"
    assert not pw.held_jug_hits_glass(g, (0.0, math.pi / 2, 0.0), GLASS_RIM_WORLD)
    g = over_glass(0.08, dx=SHORT)  # 1.5 cm higher the corner passes over the rim
    assert pw.move_gripper_to_param(bb, 0, x=g[0], y=g[1], z=g[2]) == "success"
    assert pw.rotate_gripper_to_param(bb, 0, rho=0.0, phi=math.pi / 2, theta=0.0) == "success"
    assert bb["water"] == "glass"


def test_tilting_before_moving_over_the_glass_spills_for_good() -> None:
    bb = holding()
    pw.rotate_gripper_to_param(bb, 0, rho=0.0, phi=1.6, theta=0.0)
    assert bb["water"] == "spilled"
    g = over_glass(dx=SHORT)
    pw.move_gripper_to_param(bb, 0, x=g[0], y=g[1], z=g[2])
    pw.rotate_gripper_to_param(bb, 0, rho=0.0, phi=1.6, theta=0.0)
    assert bb["water"] == "spilled"
    assert pw.check_success(bb, 0) == "failure"


def test_a_jug_carried_tilted_but_not_level_pours_when_tipped_over_the_glass() -> None:
    bb = holding()
    pw.rotate_gripper_to_param(bb, 0, rho=0.0, phi=-1.2, theta=0.0)  # 69°: stays in
    g = over_glass(dx=-SHORT)
    pw.move_gripper_to_param(bb, 0, x=g[0], y=g[1], z=g[2])
    assert bb["water"] == "jug"
    pw.rotate_gripper_to_param(bb, 0, rho=0.0, phi=-1.6, theta=0.0)  # tipped towards -x
    assert bb["water"] == "glass"


def test_rotating_an_empty_gripper_moves_no_water() -> None:
    bb = recognised()
    for rho in np.linspace(-math.pi, math.pi, 13):
        assert pw.rotate_gripper_to_param(bb, 0, rho=float(rho), phi=1.0, theta=0.0) == "success"
        assert bb["water"] == "jug"


def test_check_success_reads_only_the_water() -> None:
    assert pw.check_success.spec.reads == frozenset({"water"})
    for water, out in (("jug", "failure"), ("spilled", "failure"), ("glass", "success")):
        assert pw.check_success(Blackboard({"water": water}), 0) == out


def test_skills_touch_only_the_keys_they_declare() -> None:
    bb = holding()
    bb._client = pw.check_success.spec.access()
    with pytest.raises(BlackboardAccessError, match="CheckSuccess"):
        bb["holding_jug"]


def test_tilt_is_the_angle_from_upright() -> None:
    assert pw.tilt((0.0, 0.0, 1.0)) == 0.0
    assert pw.tilt((0.0, math.pi / 2, 0.0)) == pytest.approx(math.pi / 2)
    assert pw.tilt((math.pi, 0.0, 0.0)) == pytest.approx(math.pi)
    assert pw.tilt((math.pi / 3, math.pi / 3, 0.0)) == pytest.approx(math.acos(0.25))
