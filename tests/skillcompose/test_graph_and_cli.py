from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from skillcompose import FSA, State, save_fsa
from skillcompose.cli import main
from skillcompose.draw import DrawingError, render, to_dot, to_mermaid
from skillcompose.graph import to_networkx, trap_states

LOOPY = FSA(
    {
        "Count_1": State("Count", {}, {"again": "Count_1", "done": "Coin_2"}),
        "Coin_2": State("Coin", {"p": 0.9}, {"heads": "success", "tails": "Spin_3"}),
        "Spin_3": State("Noop", {}, {"success": "Spin_4"}),
        "Spin_4": State("Noop", {}, {"success": "Spin_3"}),
    },
    start="Count_1",
    step_limit=12,
    name="loopy",
)


def test_graph_and_trap_states() -> None:
    g = to_networkx(LOOPY)
    assert g.number_of_edges() == 6
    assert g.nodes["Count_1"]["start"]
    assert trap_states(LOOPY) == ["Spin_3", "Spin_4"] == LOOPY.trap_states()


@pytest.mark.parametrize("name", ["pour_water_reference", "stacking_reference",
                                  "move_to_reach"])
def test_trap_states_without_networkx_agree(name: str) -> None:
    import dataclasses

    from skillcompose import load_fsa

    fsa = load_fsa(Path(__file__).resolve().parents[2] / "examples" / f"{name}.fsa.yaml")
    cut = fsa.replace(states={  # the start's outcomes all loop back: nothing ends
        s: st if s != fsa.start else dataclasses.replace(
            st, transitions=dict.fromkeys(st.transitions, fsa.start))
        for s, st in fsa.states.items()})
    assert fsa.trap_states() == trap_states(fsa) == []
    assert cut.trap_states() == trap_states(cut) == [fsa.start]


def test_dot_and_mermaid() -> None:
    dot = to_dot(LOOPY)
    assert 's0 [label="Count_1", color=red' in dot  # the start is marked
    assert 's1 -> t0 [label="heads"]' in dot  # generated ids: t0 is the terminal success
    assert 't0 [label="success", shape=box' in dot
    assert 's1 [label="Coin_2\\np=0.9"' in dot
    mmd = to_mermaid(LOOPY)
    assert "[*] --> s0" in mmd and "s1 --> [*] : heads → success" in mmd


def test_render_formats(tmp_path: Path) -> None:
    assert render(LOOPY, tmp_path / "a.dot").read_text().startswith("digraph")
    assert render(LOOPY, tmp_path / "a.mmd").read_text().startswith("stateDiagram-v2")
    with pytest.raises(DrawingError, match=r"use a \.dot, \.mmd"):
        render(LOOPY, tmp_path / "a.jpeg")
    # without Graphviz, pictures come from matplotlib; with it, from dot
    assert render(LOOPY, tmp_path / "a.svg").read_text().lstrip().startswith("<")
    assert render(LOOPY, tmp_path / "a.png").read_bytes().startswith(b"\x89PNG")
    assert render(LOOPY, tmp_path / "m.png", engine="matplotlib").stat().st_size > 1000
    if shutil.which("dot") is None:
        with pytest.raises(DrawingError, match="apt-get install graphviz"):
            render(LOOPY, tmp_path / "b.svg", engine="dot")


def test_layers_go_left_to_right() -> None:
    from skillcompose.draw import layers

    grid = layers(LOOPY)
    assert grid["Count_1"] == (0, 0)
    assert grid["Coin_2"][0] == 1 and grid["Spin_3"][0] == 2 and grid["Spin_4"][0] == 3
    assert grid["success"][0] == grid["failure"][0] == 4


def test_cli_run_validate_show_skills(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = save_fsa(LOOPY, tmp_path / "loopy.fsa.yaml").path
    assert path is not None
    skills = ["--skills", "tests.skillcompose.demo_skills"]
    assert main(["run", path, *skills, "--trials", "500", "--seed", "3"]) == 0
    out = capsys.readouterr().out
    assert "500 run(s), seed 3" in out and "success" in out and "timeout" in out
    assert main(["run", path, *skills, "--trials", "500", "--seed", "3"]) == 0
    assert capsys.readouterr().out == out  # same seed, same report
    assert main(["run", path, *skills, "--trace", "--seed", "1"]) == 0
    out = capsys.readouterr().out
    assert "Count_1 (Count) -> again -> Count_1" in out and "count: ∅ => 1" in out
    assert main(["validate", path, *skills]) == 0
    out = capsys.readouterr().out
    assert "valid, 4 states" in out and "no terminal outcome can be reached from Spin_3" in out
    assert main(["show", path]) == 0
    assert capsys.readouterr().out.startswith('digraph "loopy"')
    assert main(["skills", *skills]) == 0
    out = capsys.readouterr().out
    assert "param approach: float in [0.05, 0.3] m (default 0.1)" in out


def test_cli_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("format: 1\nstart: A\nstates:\n  A: {skill: Nope, transitions: {x: success}}\n")
    assert main(["run", str(bad), "--skills", "tests.skillcompose.demo_skills"]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:4:14: state A: unknown skill 'Nope'; did you mean Noop?" in err
    assert "Traceback" not in err
    assert main(["run", str(bad)]) == 2
    assert "no skills loaded; give --skills MODULE or --task TASK" in capsys.readouterr().err


def test_cli_reports_skill_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = save_fsa(FSA({"X": State("Explode", {}, {"success": "success"})}, "X"),
                 tmp_path / "x.yaml").path
    assert f is not None
    # every run ended in error: counted, the first shown with where it was raised, exit 1
    assert main(["run", f, "--skills", "tests.skillcompose.demo_skills", "--trials", "3"]) == 1
    captured = capsys.readouterr()
    assert "error" in captured.out
    assert ("3 run(s) ended in error; the first (run 0) in state X: RuntimeError: motor "
            "fault\n") in captured.err
    assert 'demo_skills.py", line 72, in explode' in captured.err
    assert "every run of" in captured.err
    assert main(["run", f, "--skills", "tests.skillcompose.demo_skills", "--trace"]) == 1
    assert "Traceback" in capsys.readouterr().err


def test_python_dash_m(tmp_path: Path) -> None:
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "skillcompose", "--help"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "evolve" in proc.stdout and "run" in proc.stdout
