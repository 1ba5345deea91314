"""The push ceiling: a world has a pose exactly when some grid pose puts the object within
the classifier's reach with the base clear of the table and in the room."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from skillcompose.robots.collision import Box

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import push_ceiling  # noqa: E402

OBJECT_Z = 0.85  # a 75 cm table, the object's centre 10 cm above its top


def _world(size: float, obj: tuple[float, float]) -> dict[str, object]:
    return {"table_world": Box.table((0.0, 0.0), (size, size), 0.75),
            "object_position_world": (obj[0], obj[1], OBJECT_Z)}


def test_an_object_at_the_edge_has_a_pose_and_one_in_a_huge_tables_middle_has_none() -> None:
    cells = push_ceiling.reachable_cells(OBJECT_Z, 0.05)
    assert len(cells) > 0 and cells[:, 0].max() < 1.2  # the arm reaches, and not forever
    assert push_ceiling.pose_exists(_world(1.0, (0.45, 0.0)), cells, 36)
    # 2.4 m square: its middle is 1.2 m from every edge, beyond every arm
    assert not push_ceiling.pose_exists(_world(2.4, (0.0, 0.0)), cells, 36)
    # the same table against the room's wall (2.5 m from the centre): the only side near
    # enough to the object is gone, and the base cannot stand in the wall
    wall = {"table_world": Box.table((1.3, 0.0), (2.4, 2.4), 0.75),
            "object_position_world": (2.45, 0.0, OBJECT_Z)}
    assert not push_ceiling.pose_exists(wall, cells, 36)
    wall["object_position_world"] = (0.15, 0.0, OBJECT_Z)  # its other edge is free
    assert push_ceiling.pose_exists(wall, cells, 36)


@pytest.mark.slow  # six tiny searches, each with its classifier grid: ~4 s
def test_the_quick_run_writes_its_page(tmp_path: Path) -> None:
    assert push_ceiling.main(["--worlds", "3", "--step", "0.1", "--headings", "8",
                              "--judged", "2", "--out", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "push_ceiling.json").read_text())["rows"]
    assert len(rows) == 6 and all(0 <= r["with_pose"] <= 3 for r in rows)
    assert {r["step_m"] for r in rows} == {0.1, 0.05}
    blind = json.loads((tmp_path / "push_ceiling.json").read_text())["blind"]
    assert 1 <= len(blind["rows"]) <= push_ceiling.BLIND_STEPS
    assert all(0 <= r["fresh"] <= 3 and 0 <= r["network_pushed"] <= 3 for r in blind["rows"])
    assert all(0 <= r["wide_pushed"] <= 3 and r["wide_error_m"] >= 0 for r in blind["rows"])
    assert blind["margin_m"] == push_ceiling.MARGIN_M
    assert len(blind["margin_rows"]) <= push_ceiling.BLIND_STEPS
    text = (tmp_path / "push_ceiling.md").read_text()
    assert "Written by `benchmarks/push_ceiling.py`" in text and "## Against the targets" in text
    assert "## Without seeing the table" in text and "12 hidden units" in text
    staged = blind["staged"]
    assert [s["turn_deg"] for s in staged["stages"]] == list(push_ceiling.STAGE_TURNS_DEG)
    assert sum(s["reached"] for s in staged["stages"]) <= 3
    assert len(staged["placements"]) <= push_ceiling.STAGED_STEPS
    assert 0 <= staged["pushed"] <= 3 and 0 <= staged["pr2_pushed"] <= staged["pr2_judged"] == 2
    assert "## The paper's network in two stages" in text
    from skillcompose import load_fsa

    fsa = load_fsa(tmp_path / push_ceiling.STAGED_FILE)  # the file beside the page runs
    assert len(fsa.states) == 2 + len(staged["stages"]) + len(staged["placements"])


def test_placements_are_tried_in_order_and_the_first_one_taken_decides() -> None:
    """free[i, w]: MoveBase can take placement i in world w; pushed: Push then succeeds.
    Placement 0 pushes in worlds 0-1 and fails in world 2; placement 1 is free only in
    worlds 2-3 and pushes in both; placement 2 pushes in world 3 alone."""
    free = np.array([[1, 1, 1, 0], [0, 0, 1, 1], [0, 0, 0, 1]], dtype=bool)
    pushed = np.array([[1, 1, 0, 0], [0, 0, 1, 1], [0, 0, 0, 1]], dtype=bool)
    assert push_ceiling.chain_pushes(free, pushed, [0, 1]).tolist() == [1, 1, 0, 1]
    assert push_ceiling.chain_pushes(free, pushed, [1, 0]).tolist() == [1, 1, 1, 1]
    # greedy: placement 0 gains 2 and loses 1, placement 1 gains 2 and loses none
    assert push_ceiling.blind_order(free, pushed, 3) == [1, 0]  # then nothing gains


def test_a_placement_puts_the_object_where_it_says() -> None:
    from skillcompose.skills.move_to_push import object_in_robot_frame

    world = {"base_pose_world": (1.0, -0.5, 2.0), "object_position_world": (0.2, 0.3, 0.8)}
    place = (0.7, -0.2, math.radians(30), 0.1, "right")
    pose = push_ceiling.placement_pose(world, place)
    x, y, _ = object_in_robot_frame(pose, world["object_position_world"])
    assert (x, y) == pytest.approx((0.7, -0.2))
    # turned 30 degrees from the line the robot saw the object on
    rx, ry, _ = object_in_robot_frame(world["base_pose_world"], world["object_position_world"])
    assert math.remainder(pose[2] - 2.0 - math.atan2(ry, rx) - math.radians(30),
                          2 * math.pi) == pytest.approx(0.0)


def test_a_margin_refuses_placements_that_push_only_when_exact() -> None:
    """With a margin, a placement at the edge of the arm's reach, or whose base is just
    clear of the table, no longer counts as pushing; one well inside still does."""
    from skillcompose.robots.collision import BASE_HALF_EXTENTS_M
    from skillcompose.skills.move_to_push import ARM_CODES, SAFETY_M, _classifier

    side = -0.35  # to the robot's right, where the right arm reaches

    def reached(x: float, y: float = side) -> bool:
        return bool(_classifier().predict_one(np.array(
            [x, y, OBJECT_Z, math.atan2(y, x), 0.0])) == ARM_CODES["right"])

    xs = [round(0.3 + 0.01 * i, 2) for i in range(100)]
    edge = max(x for x in xs if reached(x))  # the farthest point still reached
    assert not reached(edge + 0.1)
    inner = next(x for x in xs if all(reached(x + dx, side + dy) for dx, dy in (
        (0, 0), (0.1, 0), (-0.1, 0), (0, 0.1), (0, -0.1))))
    # a small table far behind the robot, which faces +x from the origin: every base clear
    world = {"table_world": Box.table((-2.5, 0.0), (0.5, 0.5), 0.75),
             "base_pose_world": (0.0, 0.0, 0.0), "object_position_world": (0.5, 0.0, OBJECT_Z)}
    places = [(edge, side, 0.0, 0.0, "right"), (inner, side, 0.0, 0.0, "right")]
    free, pushed = push_ceiling.blind_outcomes([world], places)
    assert free[:, 0].tolist() == [True, True] and pushed[:, 0].tolist() == [True, True]
    free, pushed = push_ceiling.blind_outcomes([world], places, margin=0.1)
    assert free[:, 0].tolist() == [True, True] and pushed[:, 0].tolist() == [False, True]
    # a table beside the base that ``inner`` puts, clear of its footprint by the safety
    # distance and 2 cm, not by the margin as well
    from skillcompose.skills.move_to_push import base_table_distance

    bx, by, yaw = push_ceiling.placement_pose(world, places[1])
    reach_y = BASE_HALF_EXTENTS_M[0] * (abs(math.sin(yaw)) + abs(math.cos(yaw)))
    table = Box.table((bx, by - reach_y - SAFETY_M - 0.02 - 0.25), (0.5, 0.5), 0.75)
    assert base_table_distance((bx, by, yaw), table) == pytest.approx(SAFETY_M + 0.02)
    near = {**world, "table_world": table}
    assert push_ceiling.blind_outcomes([near], [places[1]])[1].tolist() == [[True]]
    assert push_ceiling.blind_outcomes([near], [places[1]], margin=0.1)[1].tolist() == [[False]]


def test_the_staged_fsa_tries_its_staging_moves_then_its_placements_in_order() -> None:
    from skillcompose import loads_fsa

    w = [0.0] * 38
    text = push_ceiling.fsa_text([("S0", w, "F0", "S1"), ("S1", w, "F0", "P"),
                                  ("F0", w, "P", "F1"), ("F1", w, "P", "P")], "S0")
    fsa = loads_fsa(text)
    assert fsa.start == "R"
    edges = {name: dict(state.transitions) for name, state in fsa.states.items()}
    assert edges["R"] == {"success": "S0"}
    assert edges["S0"] == {"success": "F0", "failure": "S1"}
    assert edges["S1"] == {"success": "F0", "failure": "P"}
    assert edges["F0"] == {"success": "P", "failure": "F1"}
    assert edges["F1"] == {"success": "P", "failure": "P"}
    assert edges["P"] == {"success": "success", "failure": "failure"}


def test_a_network_fitted_from_a_staging_pose_is_precise_where_one_from_anywhere_is_not(
) -> None:
    """The staged section's premise: from anywhere within 2 m of the table one move of the
    paper's network lands tens of centimetres from a placement; from the poses a staging
    move reached, a network fitted the same way lands within a few, and the move keeps the
    torso where it put it."""
    from examples.move_to_push import random_world

    rng = np.random.default_rng(5)
    worlds = [random_world(rng, world="paper") for _ in range(60)]
    place = (0.8, -0.4, math.radians(30), 0.0, "right")
    _, anywhere = push_ceiling.fit_network(worlds, place)
    stage, _ = push_ceiling.fit_network(
        worlds, (push_ceiling.STAGE_AHEAD_M, 0.0, 0.0, 0.0, "left"))
    staged = push_ceiling.moved_worlds(worlds, stage)
    assert len(staged) >= 45  # most staging moves land off the table
    assert all(0.0 <= w["torso_m"] <= 0.31 for _, w in staged)
    _, from_staging = push_ceiling.fit_network([w for _, w in staged], place)
    assert anywhere > 0.15 and from_staging < 0.08, (anywhere, from_staging)
