"""The robustness tool: sweeps, determinism across workers, table, plot and CLI."""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import pytest

from skillcompose import FSA, FSAValidationError, State
from skillcompose.robustness import (
    RobustnessError,
    SweepRow,
    parse_values,
    plot_sweep,
    robustness_sweep,
    write_csv,
)
from skillcompose.robustness_cli import register_cli
from skillcompose.task import TaskError, load_task

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = str(ROOT / "examples" / "pour_water_reference.fsa.yaml")
TASK = "examples.pour_water"


def test_sweep_of_the_reference_fsa_on_a_few_points() -> None:
    rows = robustness_sweep(REFERENCE, TASK, [0.0, 0.5, 0.9, 1.0], reps=400, seed=0)
    assert [r.value for r in rows] == [0.0, 0.5, 0.9, 1.0]
    assert all(isinstance(r, SweepRow) and r.reps == 400 for r in rows)
    zero, half, high, one = rows
    assert zero.mean == 0.0 and zero.std == 0.0 and zero.success_rate == 1.0
    assert zero.mean_steps == 6.0 and zero.solved_rate == 1.0
    assert half.success_rate > 0.98  # the paper: solved almost always below 0.5
    assert 0.0 < high.success_rate < 0.5 and high.timeout_rate > 0.5 and high.mean > 1.0
    assert high.solved_rate == high.success_rate  # the reference succeeds only by pouring
    # p_fail = 1: MoveToObject never succeeds, so the jug is never held: fitness 20
    assert one.mean == 20.0 and one.timeout_rate == 1.0 and one.mean_steps == 20.0
    for r in rows:
        assert sum(r.outcomes.values()) == r.reps


def test_same_rows_for_any_number_of_workers_and_any_grid() -> None:
    one = robustness_sweep(REFERENCE, TASK, [0.6, 0.8], reps=300, seed=5, workers=1)
    two = robustness_sweep(REFERENCE, TASK, [0.6, 0.8], reps=300, seed=5, workers=2)
    assert one == two
    # repetition r uses the same generator at every point: a point ignores its neighbours
    alone = robustness_sweep(REFERENCE, TASK, [0.8], reps=300, seed=5)
    assert alone[0] == one[1]
    other_seed = robustness_sweep(REFERENCE, TASK, [0.8], reps=300, seed=6)
    assert other_seed[0] != alone[0]


def test_sweep_accepts_an_fsa_object_and_a_loaded_task() -> None:
    task = load_task(TASK, p_fail=0.3)
    fsa = FSA(
        {"R": State("RecogniseObject", {}, {"success": "C"}),
         "C": State("CheckSuccess", {}, {"success": "success", "failure": "failure"})},
        "R", step_limit=20,
    )
    rows = robustness_sweep(fsa, task, [0.0, 1.0], reps=50)
    for r in rows:  # never grasps: CheckSuccess fails, the jug is not held
        assert r.mean == 20.0 and r.rate("failure") == 1.0 and r.mean_steps == 2.0


def test_success_that_does_not_solve_the_task_is_told_apart() -> None:
    """An FSA that declares success without pouring: outcome success, never solved."""
    fsa = FSA({"R": State("RecogniseObject", {}, {"success": "success"})}, "R", step_limit=20)
    (row,) = robustness_sweep(fsa, TASK, [0.2], reps=30)
    assert row.success_rate == 1.0 and row.solved_rate == 0.0 and row.mean == 20.0


def test_step_limit_override() -> None:
    rows = robustness_sweep(REFERENCE, TASK, [1.0], reps=20, step_limit=7)
    assert rows[0].mean_steps == 7.0


def test_sweep_errors_name_the_problem() -> None:
    with pytest.raises(RobustnessError, match="reps=0"):
        robustness_sweep(REFERENCE, TASK, [0.1], reps=0)
    with pytest.raises(RobustnessError, match="no values"):
        robustness_sweep(REFERENCE, TASK, [], reps=5)
    with pytest.raises(RobustnessError, match="finite number"):
        robustness_sweep(REFERENCE, TASK, [float("nan")], reps=5)
    with pytest.raises(TaskError, match="must be a probability"):
        robustness_sweep(REFERENCE, TASK, [1.5], reps=5)
    fsa = FSA({"A": State("Dance", {}, {"success": "success"})}, "A")
    with pytest.raises(FSAValidationError, match="unknown skill 'Dance'"):
        robustness_sweep(fsa, TASK, [0.1], reps=5)
    task = load_task(TASK)
    from dataclasses import replace

    with pytest.raises(RobustnessError, match="not made by load_task"):
        robustness_sweep(REFERENCE, replace(task, ref=None), [0.1], reps=5)


@pytest.mark.parametrize(
    ("text", "values"),
    [("0:1:5", [0.0, 0.25, 0.5, 0.75, 1.0]), ("0.3", [0.3]), ("0,0.2, 0.5", [0.0, 0.2, 0.5]),
     ("0:1:1", [0.0])],
)
def test_parse_values(text: str, values: list[float]) -> None:
    assert parse_values(text) == values


def test_parse_values_21_points_are_clean() -> None:
    v = parse_values("0:1:21")
    assert len(v) == 21 and v[3] == 0.15 and v[-1] == 1.0


@pytest.mark.parametrize("text", ["0:1", "a,b", "0:1:0", "", "0:1:x"])
def test_parse_values_rejects_with_the_accepted_forms(text: str) -> None:
    with pytest.raises(RobustnessError, match="START:STOP:COUNT"):
        parse_values(text)


def test_csv_and_plot(tmp_path: Path) -> None:
    rows = robustness_sweep(REFERENCE, TASK, [0.0, 0.95], reps=100)
    path = write_csv(rows, tmp_path / "sweep.csv")
    with path.open() as f:
        table = list(csv.DictReader(f))
    assert list(table[0])[:8] == [
        "p_fail", "reps", "mean", "std", "min", "max", "mean_steps", "solved_rate"
    ]
    assert {"success_rate", "failure_rate", "timeout_rate", "error_rate"} <= set(table[0])
    assert float(table[1]["mean"]) == pytest.approx(rows[1].mean, rel=1e-5)
    assert float(table[1]["success_rate"]) == rows[1].success_rate
    png = plot_sweep(rows, tmp_path / "fig.png", title="t")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def run_cli(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="skillcompose")
    register_cli(parser.add_subparsers())
    args = parser.parse_args(argv)
    return int(args.func(args))


def test_cli_writes_table_and_plot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fig = tmp_path / "out" / "fig.png"
    code = run_cli([
        "robustness", REFERENCE, "--task", TASK, "--p-fail", "0:1:3", "--reps", "50",
        "-o", str(fig), "--seed", "3", "--workers", "1",
    ])
    assert code == 0
    assert fig.is_file() and fig.with_suffix(".csv").is_file()
    out = capsys.readouterr().out
    assert out.splitlines()[0].split()[:3] == ["p_fail", "reps", "mean"]
    assert len(out.splitlines()) == 4
    rows = list(csv.DictReader(fig.with_suffix(".csv").open()))
    expected = robustness_sweep(REFERENCE, TASK, [0.0, 0.5, 1.0], reps=50, seed=3)
    assert [float(r["mean"]) for r in rows] == pytest.approx([e.mean for e in expected])


def test_cli_rejects_setting_the_swept_setting(tmp_path: Path) -> None:
    with pytest.raises(RobustnessError, match="conflicts"):
        run_cli(["robustness", REFERENCE, "--task", TASK, "--set", "p_fail=0.1",
                 "--reps", "5", "--csv", str(tmp_path / "x.csv")])


def test_a_sweep_takes_nested_fsa_files_and_locates_the_files_problems(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    from skillcompose import save_fsa
    from skillcompose.cli import main

    fetch = save_fsa(FSA({
        "Find": State("RecogniseObject", {}, {"success": "Reach"}),
        "Reach": State("MoveToObject", {}, {"success": "success", "failure": "Reach"}),
    }, start="Find", step_limit=10, name="FetchJug"), tmp_path / "fetch.yaml").path
    outer = save_fsa(FSA({"Fetch": State("FetchJug", {}, {"success": "success",
                                                          "failure": "failure"})},
                         start="Fetch", step_limit=5), tmp_path / "outer.yaml").path
    args = ["robustness", str(outer), "--task", TASK, "--p-fail", "0,1", "--reps", "6",
            "--workers", "2", "--quiet"]
    assert main([*args, "--skills", str(fetch)]) == 0  # loaded in the workers too
    rows = [line.split() for line in capsys.readouterr().out.strip().splitlines()[1:]]
    assert [(r[0], r[6]) for r in rows] == [("0", "1"), ("1", "0")]  # value, success_rate
    assert main(args) == 2
    assert capsys.readouterr().err.startswith(
        f"skillcompose robustness: error: {outer}:10:12: state Fetch: unknown skill 'FetchJug'")
