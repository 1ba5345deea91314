"""The push ceiling: a world has a pose exactly when some grid pose puts the object within
the classifier's reach with the base clear of the table and in the room."""

from __future__ import annotations

import json
import sys
from pathlib import Path

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
                              "--out", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "push_ceiling.json").read_text())["rows"]
    assert len(rows) == 6 and all(0 <= r["with_pose"] <= 3 for r in rows)
    assert {r["step_m"] for r in rows} == {0.1, 0.05}
    text = (tmp_path / "push_ceiling.md").read_text()
    assert "Written by `benchmarks/push_ceiling.py`" in text and "## Against the targets" in text
