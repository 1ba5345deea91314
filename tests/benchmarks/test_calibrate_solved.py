"""The calibration script of "solved" in its quick mode: it evolves, re-checks each exported
FSA on new episodes, and writes its report and its rows."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import calibrate_solved  # noqa: E402


@pytest.mark.slow  # evolves the toy task twice: about 3 s
def test_the_quick_calibration_writes_its_report(tmp_path: Path) -> None:
    assert calibrate_solved.main(["--quick", "--workers", "1", "--out", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "solved_runs.json").read_text())
    assert [r["seed"] for r in rows] == [0, 1] and {r["task"] for r in rows} == {"toy"}
    for r in rows:
        assert r["recheck_episodes"] == 200
        if r["solved"]:  # a solved run claims a lower bound at the required rate
            assert r["claimed_lower"] >= r["required"]
    text = (tmp_path / "solved.md").read_text()
    assert "Written by `benchmarks/calibrate_solved.py" in text
    solved = sum(r["solved"] for r in rows)
    held = sum(r["solved"] and r["recheck_rate"] >= r["required"] for r in rows)
    assert f"All tasks: {held} of {solved} solved runs held their rate" in text


def test_a_row_holds_when_the_new_episodes_reach_the_rate() -> None:
    row = calibrate_solved.Row("toy", 0, True, "holds", 0.95, 3, 100, 1.0, 0.96, 2000,
                               0.949, 0.96)
    assert not row.held and row.consistent
    assert calibrate_solved.Row(*[*row.__dict__.values()][:10], 0.97, 0.98).held
