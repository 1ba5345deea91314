"""The ``world`` setting of moving to push (§4.2) and stacking (§4.3): the ``paper`` worlds
follow the text (placements on the table top, the robot anywhere within 2 m of the table at
any heading, no near or far half, MoveToReach without its in-reach shortcut), and the
default ``facing`` worlds are the ones drawn before the setting existed, draw for draw."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from examples import move_to_push as push
from examples import stacking as stack
from skillcompose import Blackboard, compile_fsa, loads_fsa
from skillcompose.robots.collision import BASE_HALF_EXTENTS_M, Box
from skillcompose.skills import stacking as skills_stacking
from skillcompose.skills.move_to_push import (
    base_hits_table,
    base_in_room,
    base_table_distance,
    classifier_label,
    object_in_robot_frame,
)
from skillcompose.task import TaskError, load_task

SEEDS = st.integers(min_value=0, max_value=2**32 - 1)
FAST = settings(max_examples=60, deadline=None)
EPS = 1e-9
SIDE_SAMPLES = 200
DEFAULT_AND_FACING: list[dict[str, Any]] = [{}, {"world": "facing"}]


# -- independent geometry -------------------------------------------------------------------
def _rect_distance(px: float, py: float, table: Box) -> float:
    """Distance from a floor point to the (axis-aligned) table's footprint."""
    dx = max(abs(px - table.center_m[0]) - table.half_extents_m[0], 0.0)
    dy = max(abs(py - table.center_m[1]) - table.half_extents_m[1], 0.0)
    return math.hypot(dx, dy)


def _footprint_boundary(pose: tuple[float, float, float]) -> list[tuple[float, float]]:
    """Points along the edges of the base footprint at ``pose``, SIDE_SAMPLES per edge."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    hx, hy = BASE_HALF_EXTENTS_M
    corners = [(hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy)]
    points = []
    for (ax, ay), (bx, by) in zip(corners, corners[1:] + corners[:1], strict=True):
        for k in range(SIDE_SAMPLES):
            t = k / SIDE_SAMPLES
            lx, ly = ax + t * (bx - ax), ay + t * (by - ay)
            points.append((x + c * lx - s * ly, y + s * lx + c * ly))
    return points


def _sampled_gap(pose: tuple[float, float, float], table: Box) -> float:
    """The footprints' distance, from above by at most half a sample spacing: the base's
    boundary is sampled, the table's footprint is exact."""
    return min(_rect_distance(px, py, table) for px, py in _footprint_boundary(pose))


SPACING_SLACK = 2 * BASE_HALF_EXTENTS_M[0] / SIDE_SAMPLES / 2


def _check_robot(pose: tuple[float, float, float], table: Box, room_half: float) -> None:
    """The paper's start: wholly in the room, not touching the table, footprint at most
    2 m from the table's, heading in [-pi, pi)."""
    assert base_in_room(pose, room_half)
    assert not base_hits_table(pose, table)
    assert _sampled_gap(pose, table) <= 2.0 + SPACING_SLACK + EPS
    assert -math.pi <= pose[2] < math.pi


def _check_on_top(position: tuple[float, float, float], table: Box, half_height: float
                  ) -> None:
    """A 6 x 6 cm footprint wholly on the top: its centre at least 3 cm in from every edge,
    standing on the top."""
    (tx, ty, _), (hx, hy, _) = table.center_m, table.half_extents_m
    assert abs(position[0] - tx) <= hx - 0.03 + EPS
    assert abs(position[1] - ty) <= hy - 0.03 + EPS
    assert position[2] == pytest.approx(table.top_z_m + half_height)


@FAST
@given(seed=SEEDS, yaw=st.floats(-math.pi, math.pi))
def test_footprint_distance_is_the_footprints_distance(seed: int, yaw: float) -> None:
    rng = np.random.default_rng(seed)
    table = Box.table((float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1))),
                      (float(rng.uniform(0.3, 1.2)), float(rng.uniform(0.3, 1.2))), 0.75)
    pose = (float(rng.uniform(-2.5, 2.5)), float(rng.uniform(-2.5, 2.5)), yaw)
    if base_hits_table(pose, table):
        return
    exact = base_table_distance(pose, table)
    assert exact <= _sampled_gap(pose, table) + EPS
    assert exact >= _sampled_gap(pose, table) - SPACING_SLACK - EPS


# -- moving to push -------------------------------------------------------------------------
@FAST
@given(seed=SEEDS, judge=st.booleans())
def test_push_paper_world_follows_section_4_2(seed: int, judge: bool) -> None:
    w = push.random_world(np.random.default_rng(seed), judge=judge, world="paper")
    table, obj, pose = w["table_world"], w["object_position_world"], w["base_pose_world"]
    assert set(w) == {"table_world", "object_position_world", "base_pose_world"}
    (tx, ty, _), (hx, hy, hz) = table.center_m, table.half_extents_m
    assert min(hx, hy) >= 0.15 - EPS and max(hx, hy) <= 0.6 + EPS  # the table as today
    assert 0.70 - EPS <= 2 * hz <= 0.80 + EPS and max(abs(tx), abs(ty)) <= 1.5
    _check_robot(pose, table, push.ROOM_HALF_M)
    _check_on_top(obj, table, push.OBJECT_HALF_EXTENTS_M[2])
    if judge:
        x, y, _ = object_in_robot_frame(pose, obj)
        assert x >= 0.0 and math.hypot(x, y) <= push.JUDGE_MAX_DISTANCE_M
    again = push.random_world(np.random.default_rng(seed), judge=judge, world="paper")
    assert again == w  # only the generator decides


@FAST
@given(seed=SEEDS, judge=st.booleans())
def test_push_setup_carries_the_paper_world(seed: int, judge: bool) -> None:
    bb = push.setup(np.random.default_rng(seed), judge=judge, world="paper")
    w = push.random_world(np.random.default_rng(seed), judge=judge, world="paper")
    assert {k: bb[k] for k in w} == w
    assert bb["torso_height_m"] == 0.0 and bb["arm_in_use"] is None


def _quarters(yaws: list[float]) -> list[float]:
    counts = [0, 0, 0, 0]
    for yaw in yaws:
        counts[min(int((yaw + math.pi) / (math.pi / 2)), 3)] += 1
    return [c / len(yaws) for c in counts]


def _deeper_than(obj: tuple[float, float, float], table: Box, depth: float) -> bool:
    (tx, ty, _), (hx, hy, _) = table.center_m, table.half_extents_m
    return min(hx - abs(obj[0] - tx), hy - abs(obj[1] - ty)) > depth


def test_push_paper_world_spreads_over_the_circle_and_the_top() -> None:
    worlds = [push.random_world(np.random.default_rng(seed), world="paper")
              for seed in range(2000)]
    assert min(_quarters([w["base_pose_world"][2] for w in worlds])) >= 0.15
    big = [w for w in worlds if min(w["table_world"].half_extents_m[:2]) > 0.40]
    deep = [w for w in big if _deeper_than(w["object_position_world"], w["table_world"], 0.30)]
    assert len(big) > 100 and len(deep) >= 0.05 * len(big)
    # the robot may start with the table behind it, which the facing world never does
    behind = [w for w in worlds
              if object_in_robot_frame(w["base_pose_world"], w["table_world"].center_m)[0] < 0]
    assert len(behind) >= 0.15 * len(worlds)
    facing = [push.random_world(np.random.default_rng(seed)) for seed in range(300)]
    assert not any(_deeper_than(w["object_position_world"], w["table_world"], 0.30 + EPS)
                   for w in facing)


# the facing world as drawn before the `world` setting existed (commit 6ff144b), seed by seed:
# (seed, judge) -> (table centre, table half extents, object, base pose)
PUSH_FACING = {
    (0, False): ((-1.4504170934144127, 0.9398107176008175, 0.35204867619680974),
                 (0.4366327592946544, 0.27140402119374163, 0.35204867619680974),
                 (-1.2677477226501415, 0.7196193263064969, 0.8040973523936195),
                 (1.147482804919992, 0.21812495732711445, -2.9137892651979334)),
    (7, True): ((-0.8981798280390144, -0.3913910681933799, 0.384601606044092),
                (0.15530731149412763, 0.23658096479338978, 0.384601606044092),
                (-0.8961177403098268, -0.2618478124029662, 0.869203212088184),
                (-1.7276945946928008, -1.1620034771810728, 0.19914145014502554)),
    (42, False): ((0.5921040871780918, -1.2174679563370514, 0.39292989599556916),
                  (0.4982802218501835, 0.3474952978884235, 0.39292989599556916),
                  (0.94768480297013, -0.9635468013653223, 0.8858597919911383),
                  (1.4303215263847688, -1.8594318366222706, 3.1156147914194543)),
}


@pytest.mark.parametrize(("key", "expected"), list(PUSH_FACING.items()))
def test_push_facing_world_is_unchanged(key: tuple[int, bool], expected: tuple) -> None:
    seed, judge = key
    for kwargs in DEFAULT_AND_FACING:
        w = push.random_world(np.random.default_rng(seed), judge=judge, **kwargs)
        got = (w["table_world"].center_m, w["table_world"].half_extents_m,
               w["object_position_world"], w["base_pose_world"])
        for g, e in zip(got, expected, strict=True):
            assert g == pytest.approx(e, rel=1e-12, abs=1e-12)


@FAST
@given(seed=SEEDS, judge=st.booleans())
def test_push_facing_is_the_default(seed: int, judge: bool) -> None:
    a, b = np.random.default_rng(seed), np.random.default_rng(seed)
    assert push.random_world(a, judge=judge) == push.random_world(b, judge=judge,
                                                                  world="facing")
    assert a.random() == b.random()  # the same numbers drawn


def test_push_world_setting_is_checked_and_recorded() -> None:
    with pytest.raises(TaskError, match=r"setting world='round' must be one of "
                                        r"\['facing', 'paper'\]"):
        load_task("examples.move_to_push", world="round")
    with pytest.raises(ValueError, match=r"world='round' must be one of"):
        push.random_world(np.random.default_rng(0), world="round")  # type: ignore[arg-type]
    assert load_task("examples.move_to_push").settings["world"] == "facing"
    task = load_task("examples.move_to_push", world="paper", judge=True)
    assert task.settings["world"] == "paper"
    assert task.setup is not None
    bb = task.setup(np.random.default_rng(5))
    w = push.random_world(np.random.default_rng(5), judge=True, world="paper")
    assert bb["base_pose_world"] == w["base_pose_world"]


# -- stacking -------------------------------------------------------------------------------
@FAST
@given(seed=SEEDS)
def test_stacking_paper_world_follows_sections_4_2_and_4_3(seed: int) -> None:
    w = stack.random_world(np.random.default_rng(seed), world="paper")
    table, pose = w["table_world"], w["base_pose_world"]
    objects = w["object_positions_world"]
    assert w["near"] is None
    assert list(objects) == ["box", "bottle"]
    (tx, ty, _), (hx, hy, hz) = table.center_m, table.half_extents_m
    assert min(hx, hy) >= 0.25 - EPS and max(hx, hy) <= 0.6 + EPS  # the table as today
    assert 0.70 - EPS <= 2 * hz <= 0.80 + EPS and max(abs(tx), abs(ty)) <= 1.5
    _check_robot(pose, table, stack.ROOM_HALF_M)
    for position in objects.values():
        _check_on_top(position, table, stack.OBJECT_HALF_EXTENTS_M[2])
    a, b = objects.values()
    assert math.dist(a[:2], b[:2]) >= 0.12 - EPS
    again = stack.random_world(np.random.default_rng(seed), world="paper")
    assert again == w


@FAST
@given(seed=SEEDS)
def test_stacking_paper_world_has_no_near_or_far_half(seed: int) -> None:
    bb = stack.setup(np.random.default_rng(seed), p_fail=0.0, world="paper")
    assert bb["start_near"] is None
    for near in (True, False):
        with pytest.raises(ValueError, match=r"near=(True|False) does not apply to "
                                             r"world='paper'"):
            stack.random_world(np.random.default_rng(seed), near=near, world="paper")
        with pytest.raises(ValueError, match="does not apply to world='paper'"):
            stack.setup(np.random.default_rng(seed), near=near, world="paper")


def test_stacking_paper_world_ignores_the_near_fraction(monkeypatch: pytest.MonkeyPatch
                                                        ) -> None:
    before = [stack.random_world(np.random.default_rng(s), world="paper") for s in range(20)]
    for fraction in (0.0, 1.0):
        monkeypatch.setattr(stack, "NEAR_FRACTION", fraction)
        after = [stack.random_world(np.random.default_rng(s), world="paper")
                 for s in range(20)]
        assert after == before


def test_stacking_paper_world_spreads_over_the_circle_and_the_top() -> None:
    worlds = [stack.random_world(np.random.default_rng(seed), world="paper")
              for seed in range(2000)]
    assert min(_quarters([w["base_pose_world"][2] for w in worlds])) >= 0.15
    big = [w for w in worlds if min(w["table_world"].half_extents_m[:2]) > 0.40]
    deep = [w for w in big for p in w["object_positions_world"].values()
            if _deeper_than(p, w["table_world"], 0.30)]
    assert len(big) > 100 and len(deep) >= 0.05 * len(big)
    # no start is forced near or far: either both objects are reached at the start, or
    # neither, or one, as it falls
    labels = [[classifier_label(w["base_pose_world"], 0.0, p) != 0
               for p in w["object_positions_world"].values()] for w in worlds[:400]]
    assert {tuple(x) for x in labels} >= {(False, False), (True, True)}


STACK_FACING = {
    (0, None): ((0.9398107176008175, 1.238266731833165, 0.35082638177642644),
                {"box": (0.6665405247873069, 1.0750541554604227, 0.7616527635528529),
                 "bottle": (0.8414898635430025, 1.167932148953414, 0.7616527635528529)},
                (1.8158946117494326, 0.20730610124545867, 1.4659257179133731), False),
    (1, True): ((1.3459483414117317, -0.5645056439685436, 0.3572079806359817),
                {"box": (1.185778050731269, -0.9737370107782009, 0.7744159612719634),
                 "bottle": (1.4133793879279264, -1.0624828884312993, 0.7744159612719634)},
                (1.2314714059292344, -1.6887966003264767, 1.7218172427574139), True),
    (7, False): ((-0.8243784300282244, -0.5995011452663237, 0.38878428451225966),
                 {"box": (-0.44306515807002617, -0.8177439583096529, 0.8375685690245194),
                  "bottle": (-0.5397267494430062, -0.9657340890802806, 0.8375685690245194)},
                 (1.4633095960687652, 0.6108961472058132, -2.8855737189471946), False),
}


@pytest.mark.parametrize(("key", "expected"), list(STACK_FACING.items()))
def test_stacking_facing_world_is_unchanged(key: tuple[int, bool | None], expected: tuple
                                            ) -> None:
    seed, near = key
    centre, objects, pose, was_near = expected
    for kwargs in DEFAULT_AND_FACING:
        w = stack.random_world(np.random.default_rng(seed), near=near, **kwargs)
        assert w["table_world"].center_m == pytest.approx(centre, rel=1e-12, abs=1e-12)
        assert w["base_pose_world"] == pytest.approx(pose, rel=1e-12, abs=1e-12)
        assert list(w["object_positions_world"]) == list(objects)
        for name, position in objects.items():
            assert w["object_positions_world"][name] == pytest.approx(position, rel=1e-12,
                                                                      abs=1e-12)
        assert w["near"] is was_near


@settings(max_examples=30, deadline=None)
@given(seed=SEEDS, near=st.sampled_from([None, True, False]))
def test_stacking_facing_is_the_default(seed: int, near: bool | None) -> None:
    a, b = np.random.default_rng(seed), np.random.default_rng(seed)
    assert stack.random_world(a, near=near) == stack.random_world(b, near=near,
                                                                  world="facing")
    assert a.random() == b.random()


def test_stacking_world_setting_is_checked_and_recorded() -> None:
    with pytest.raises(TaskError, match=r"setting world='paper2' must be one of "
                                        r"\['facing', 'paper'\]"):
        load_task("examples.stacking", world="paper2")
    with pytest.raises(ValueError, match=r"world='x' must be one of"):
        stack.random_world(np.random.default_rng(0), world="x")  # type: ignore[arg-type]
    facing, paper = load_task("examples.stacking"), load_task("examples.stacking",
                                                              world="paper")
    assert facing.settings["world"] == "facing" and paper.settings["world"] == "paper"
    reach = {t.settings["world"]: t.registry.resolve("MoveToReach", "sim")
             for t in (facing, paper)}
    assert isinstance(reach["paper"], skills_stacking.MoveToReach)
    assert isinstance(reach["facing"], skills_stacking.MoveToReach)
    assert reach["facing"].shortcut and not reach["paper"].shortcut
    assert paper.setup is not None
    assert paper.setup(np.random.default_rng(3))["start_near"] is None


# -- MoveToReach with and without its shortcut ----------------------------------------------
def _in_reach() -> Blackboard:
    """The robot at the origin facing +x; both objects within the right arm's reach, already
    recognised."""
    bb = Blackboard({
        "p_fail": 0.0,
        "table_world": Box.table((0.95, 0.0), (0.9, 1.4), 0.75),
        "room_half_m": 2.5,
        "object_positions_world": {"box": (0.6, -0.2, 0.81), "bottle": (0.6, -0.1, 0.81)},
        "object_half_extents_m": {"box": (0.03, 0.03, 0.06), "bottle": (0.03, 0.03, 0.06)},
        "base_pose_world": (0.0, 0.0, 0.0),
        "torso_height_m": 0.0,
        "arm_in_use": None,
        "held_object_left": None,
        "held_object_right": None,
        "objects_grasped": (),
    })
    assert skills_stacking.recognise_objects(bb, 0) == "success"
    assert skills_stacking.reach_check(bb, 0) == "success"
    return bb


def test_move_to_reach_without_shortcut_runs_the_nested_fsa_when_in_reach() -> None:
    moved = []
    for shortcut in (True, False):
        reach = skills_stacking.make_move_to_reach(stack.MOVE_TO_REACH_FILE, kinematic=False,
                                                   shortcut=shortcut)
        assert reach.shortcut is shortcut
        bb = _in_reach()
        rng = np.random.default_rng(3)
        assert reach.bind(None, "sim")(bb, rng) == "success"
        ran = "object_location_world" in bb  # MoveToReach's own RecogniseObject wrote it
        assert ran is not shortcut
        moved.append((bb["base_pose_world"], bb["torso_height_m"]) != ((0.0, 0.0, 0.0), 0.0))
        if shortcut:
            check = np.random.default_rng(3)
            check.random()  # only the random failure's number was drawn
            assert rng.random() == check.random()
    assert moved == [False, True]


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


@pytest.mark.parametrize("world", ["facing", "paper"])
def test_move_to_reach_is_one_step_of_the_caller_in_both_worlds(world: str) -> None:
    task = load_task("examples.stacking", p_fail=0.0, world=world)
    compiled = compile_fsa(loads_fsa(REACH_ONLY, "reach_only"), task.registry, "sim")
    bb = _in_reach()
    result = compiled.run(bb, np.random.default_rng(3), trace=True)
    assert result.steps == 2
    assert result.trace is not None and result.trace[0].skill == "MoveToReach"
    assert ("object_location_world" in bb) is (world == "paper")
