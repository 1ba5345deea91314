"""Objects show themselves in a notebook: FSAs as SVG, run results as HTML tables."""

from __future__ import annotations

from pathlib import Path

from skillcompose import FSA, RunResult, State, load_fsa, load_task
from skillcompose.display import html_table

ROOT = Path(__file__).resolve().parents[2]


def test_an_fsa_shows_its_drawing_as_svg() -> None:
    fsa = load_fsa(ROOT / "examples" / "pour_water_reference.fsa.yaml")
    svg = fsa._repr_svg_()
    assert "<svg" in svg and svg.rstrip().endswith("</svg>")


def test_a_traced_run_shows_each_step_and_its_changes() -> None:
    task = load_task("examples.pour_water")
    fsa = load_fsa(ROOT / "examples" / "pour_water_reference.fsa.yaml")
    trial = next(iter(task.each_trial(task.compile(fsa), 0, 1, trace_first=True)))
    page = trial.result._repr_html_()
    assert trial.result.trace is not None
    assert page.count("<tr>") == len(trial.result.trace) + 1  # a header and one per step
    assert f"<b>{trial.result.outcome}</b>" in page and "jug_location_world" in page


def test_html_is_escaped() -> None:
    result = RunResult("<oops>", 0, "<b>", None, ValueError("a < b"))
    page = result._repr_html_()
    assert "<oops>" not in page and "&lt;oops&gt;" in page and "a &lt; b" in page
    assert "<td>&lt;x&gt;</td>" in html_table(["h"], [["<x>"]])


def test_an_unreachable_state_is_still_drawn() -> None:
    fsa = FSA({"A": State("Noop", {}, {"success": "success"}),
               "B": State("Noop", {}, {"success": "A"})}, "A")
    assert "<svg" in fsa._repr_svg_()
