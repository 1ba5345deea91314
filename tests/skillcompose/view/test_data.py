"""The viewer's data layer, its live publisher, the live example and the ``view`` command's
usage errors: no browser, no server."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path

import pytest

from examples import live_patrol
from skillcompose import FSA, load_fsa
from skillcompose.cli import main
from skillcompose.evolve.rundir import RunDir
from skillcompose.view.data import find_runs, mermaid, read_fsa, read_history, read_run
from skillcompose.view.episode import run_episode
from skillcompose.view.live import LivePublisher, read_live

from .conftest import REPO, child_env, free_port

POUR = REPO / "examples" / "pour_water_reference.fsa.yaml"


def write_run(path: Path, info: Mapping[str, object], generations: int) -> None:
    path.mkdir(parents=True)
    (path / "run.json").write_text(json.dumps(info))
    with (path / "history.jsonl").open("w") as f:
        for g in range(generations):
            f.write(json.dumps({"generation": g, "best": 1.0 / (g + 1)}) + "\n")


def test_history_skips_a_line_being_written(tmp_path: Path) -> None:
    h = tmp_path / "history.jsonl"
    h.write_text('{"generation": 0, "best": 2}\n{"generation": 1, "best": 1}\n{"genera')
    history = read_history(h)
    assert (history.generations, history.best, history.points) == (2, 1.0, ((0, 2.0), (1, 1.0)))
    missing = read_history(tmp_path / "missing.jsonl")
    assert (missing.generations, missing.points, missing.problem) == (0, (), "")


def test_runs_and_their_status(tmp_path: Path) -> None:
    done = {"task": "t", "result": {"best_fitness": 0.25, "fresh": {"success_rate": 0.9}}}
    write_run(tmp_path / "a" / "finished", done, 4)
    write_run(tmp_path / "running", {"task": "t"}, 2)
    held = RunDir(tmp_path / "running")
    held.lock()  # as evolve holds it while it runs
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    write_run(tmp_path / "stopped", {"task": "t"}, 3)
    (tmp_path / "stopped" / ".lock").write_text(f"{dead.pid}\n")
    (tmp_path / "torn").mkdir()
    (tmp_path / "torn" / "run.json").write_text('{"task": ')
    try:
        runs = {r.name: r for r in find_runs(tmp_path)}
    finally:
        held.unlock()
    assert {n: r.status for n, r in runs.items()} == {
        "a/finished": "finished", "running": "running", "stopped": "interrupted",
        "torn": "unreadable"}
    assert (runs["a/finished"].best, runs["a/finished"].success) == (0.25, 0.9)
    assert runs["a/finished"].generations == 4
    assert runs["running"].best == 0.5  # the last generation's, while it runs
    assert "not a JSON object" in runs["torn"].problem


def test_read_fsa_gives_problems_with_lines(tmp_path: Path) -> None:
    text = POUR.read_text().replace("success: Grasp", "success: Grsap", 1)
    bad = tmp_path / "bad.fsa.yaml"
    bad.write_text(text)
    view = read_fsa(bad)
    line = text.splitlines().index("      success: Grsap") + 1
    assert view.fsa is None and view.error_lines == (line,)
    missing = read_fsa(tmp_path / "gone.yaml")
    assert missing.problems[0].message == "file not found"


def test_mermaid_marks_start_terminals_traps_and_active() -> None:
    fsa = load_fsa(POUR)
    text = mermaid(fsa, active="Grasp", traps=["Pour"], unreachable=["Check"])
    ids = {s: f"s{k}" for k, s in enumerate(fsa.states)}
    assert f"class {ids['Recognise']} start" in text
    assert f"class {ids['Grasp']} active" in text
    assert f"class {ids['Pour']} trap" in text and f"class {ids['Check']} unreachable" in text
    assert text.count("-->") == sum(len(set(st.transitions.values()))
                                    for st in fsa.states.values())


def test_episode_is_the_traced_run() -> None:
    from skillcompose import load_task

    task = load_task("examples.pour_water")
    trial = next(iter(task.each_trial(task.compile(load_fsa(POUR)), 5, 1, trace_first=True)))
    episode = run_episode(POUR, "examples.pour_water", 5)
    assert trial.result.trace is not None
    assert [f.state for f in episode.frames[1:]] == [ev.state for ev in trial.result.trace]
    assert episode.outcome == trial.result.outcome and not episode.kinematic


def test_episode_on_another_backend_is_checked() -> None:
    from skillcompose.errors import SkillcomposeError

    with pytest.raises(SkillcomposeError, match="--backend 'nonsense': no loaded skill"):
        run_episode(POUR, "examples.pour_water", 0, backend="nonsense")


def test_live_patrol_publishes_each_state(tmp_path: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    states = []
    original = LivePublisher.publish

    def spy(self: LivePublisher, run: object, bb: object = None) -> bool:
        wrote = original(self, run, bb)  # type: ignore[arg-type]
        if wrote:
            record = read_live(self.path)
            assert record is not None
            states.append(record["state"] or record["outcome"])
        return wrote

    monkeypatch.setattr(LivePublisher, "publish", spy)
    assert live_patrol.run(tmp_path, time_scale=0.02) == "success"
    record = read_live(tmp_path / "live_patrol.live.json")
    assert record is not None and record["done"] and record["steps"] == 7
    shown = [s for k, s in enumerate(states) if k == 0 or states[k - 1] != s]
    assert shown == ["Drive", "Scan"] * 3 + ["Dock", "success"]
    assert load_fsa_text(record["fsa"]).states.keys() == {"Drive", "Scan", "Dock"}


def load_fsa_text(text: str) -> FSA:
    from skillcompose.fsafile import loads_fsa

    return loads_fsa(text)


def test_live_file_name_is_checked(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"must end in \.live\.json"):
        LivePublisher(tmp_path / "x.json", live_patrol.patrol_fsa())


def test_view_usage_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                        ) -> None:
    assert main(["view", str(tmp_path / "nothing")]) == 2
    assert "no such file or folder" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["view", "--host", "example", str(tmp_path)])
    assert exc.value.code == 2
    assert "is not an IP address" in capsys.readouterr().err
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        assert main(["view", str(tmp_path), "--port", str(port)]) == 2
    err = capsys.readouterr().err
    assert f"--port {port}" in err and "in use" in err and "Traceback" not in err
    for bad in ("0", "-1", "nan", "soon"):
        with pytest.raises(SystemExit) as exc:
            main(["view", str(tmp_path), "--refresh", bad])
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert "--refresh" in err and "from 0.1 to 3600" in err and "Traceback" not in err
        assert len(err.strip().splitlines()) <= 2  # usage line and the error


def test_refresh_reaches_the_pages(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--refresh`` is how often the pages list the folder: it reaches the viewer's
    configuration, and a viewer given none lists it once a second."""
    from nicegui import ui

    import skillcompose.view.app as app
    from skillcompose.view.trust import ViewerConfig

    built: list[ViewerConfig] = []
    monkeypatch.setattr(app, "build", built.append)
    monkeypatch.setattr(ui, "run", lambda **_: None)
    for extra, expected in (([], 1.0), (["--refresh", "0.5"], 0.5), (["--refresh", "30"], 30.0)):
        assert main(["view", str(tmp_path), "--port", str(free_port()), *extra]) == 0
        assert built[-1].refresh == expected


def test_core_does_not_import_the_viewer() -> None:
    code = ("import sys, skillcompose, skillcompose.cli; skillcompose.cli.build_parser(); "
            "print(sorted(m for m in sys.modules if m.startswith(('nicegui', "
            "'skillcompose.view.app'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env=child_env()).stdout
    assert out.strip() == "[]"


@pytest.mark.skipif(not Path("/proc/locks").exists(), reason="the system lists no locks")
def test_a_run_whose_process_id_was_reused_is_not_running(tmp_path: Path) -> None:
    """A run killed by force leaves its process id in ``.lock``; once another process has
    that id, the run is still interrupted: what counts is who holds the lock."""
    write_run(tmp_path / "killed", {"task": "t"}, 2)
    (tmp_path / "killed" / ".lock").write_text(f"{os.getpid()}\n")  # a live process's id
    assert [r.status for r in find_runs(tmp_path)] == ["interrupted"]
    held = RunDir(tmp_path / "killed")
    held.lock()
    try:
        assert [r.status for r in find_runs(tmp_path)] == ["running"]
    finally:
        held.unlock()
    assert [r.status for r in find_runs(tmp_path)] == ["interrupted"]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_pipes_in_the_folder_viewed_never_hang_the_viewer(tmp_path: Path) -> None:
    """A run.json, history.jsonl, FSA file or live file that is a named pipe (reading it
    would wait for a writer for ever) is reported as unreadable at once."""
    import signal

    from skillcompose.view.live import read_live

    run = tmp_path / "odd"
    run.mkdir()
    for name in ("run.json", "history.jsonl", "best.yaml", "patrol.live.json"):
        os.mkfifo(run / name)
    signal.alarm(30)  # a regression would hang here: fail instead
    try:
        assert find_runs(tmp_path) == []  # a run.json that is no file makes no run
        summary = read_run(run, tmp_path)
        assert summary is not None and summary.status == "unreadable"
        assert summary.problem == "run.json cannot be read: it is a pipe, not a regular file"
        history = read_history(run / "history.jsonl")
        assert history.generations == 0 and "a pipe" in history.problem
        view = read_fsa(run / "best.yaml")
        assert view.fsa is None
        assert [p.message for p in view.problems] == [
            "cannot read the file: it is a pipe, not a regular file"]
        assert read_live(run / "patrol.live.json") is None
    finally:
        signal.alarm(0)


def test_an_episode_whose_skill_exits_ends_in_error(tmp_path: Path) -> None:
    """A replayed skill calling sys.exit() ends the episode in error; the viewer goes on."""
    fsa = tmp_path / "quit.fsa.yaml"
    fsa.write_text("format: 1\nstart: F\nstates:\n  F:\n    skill: Fault\n"
                   "    transitions: {success: success, failure: failure}\n")
    episode = run_episode(fsa, "tests.evolve.faulty_task", 0, {"fault": "exit"})
    assert episode.outcome == "error"
    assert [(f.state, f.outcome) for f in episode.frames[1:]] == [("F", "error")]


def test_the_runs_table_gives_the_fresh_rate_with_its_bounds_and_verdict() -> None:
    from skillcompose.view.data import fresh_text

    assert fresh_text({"success_rate": 0.998, "lower": 0.995, "upper": 1.0,
                       "holds": True}) == "99.8% (99.5–100.0) holds"
    assert fresh_text({"success_rate": 0.075, "lower": 0.047, "upper": 0.113,
                       "holds": False}) == "7.5% (4.7–11.3) does not hold"
    assert fresh_text({"success_rate": 0.5}) == "50.0%"  # a run from before the bounds
    assert fresh_text({"success_rate": "x"}) == "–"
    # a deterministic task's one episode is every episode: a verdict, no bounds
    assert fresh_text({"success_rate": 1.0, "lower": 0.05, "upper": 1.0, "holds": True,
                       "deterministic": True}) == "reaches the target"
    assert fresh_text({"success_rate": 0.0, "lower": 0.0, "upper": 0.95, "holds": False,
                       "deterministic": True}) == "does not reach the target"


def test_the_live_patrol_runs_by_its_path_from_any_folder(tmp_path: Path) -> None:
    """`python -m examples.live_patrol` worked only from the repository root; the docs give
    the path form, which must work from anywhere."""
    import subprocess
    import sys

    script = Path(__file__).resolve().parents[3] / "examples" / "live_patrol.py"
    done = subprocess.run([sys.executable, str(script), "--help"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "usage: python examples/live_patrol.py" in done.stdout
