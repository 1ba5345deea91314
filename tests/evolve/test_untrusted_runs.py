"""A run directory received from someone else: resuming it never runs code that came with
it, a damaged checkpoint is detected, an edited run.json is refused, and every problem is
one line."""

from __future__ import annotations

import contextlib
import io
import json
import os
import pickle
import shutil
import signal
from pathlib import Path
from typing import Any

import pytest

from skillcompose.cli import main as skillcompose_main
from skillcompose.evolve import CheckpointError, RunDir

ARGS = ["examples.toy_task", "--set", "p_fail=0.3", "--population", "20", "--initial-nodes",
        "6", "--generations", "4", "--checkpoint-every", "2", "--seed", "1", "--quiet",
        "--simplify-trials", "10", "--backend", "serial"]
EVIL = "import pathlib\npathlib.Path({marker!r}).write_text('ran')\n"


@pytest.fixture(scope="module")
def stopped_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run stopped after its checkpoint of generation 2 (generations 3, 4 to go), made
    once for the module (each test takes a copy: :func:`run_dir`)."""
    d = tmp_path_factory.mktemp("stopped") / "received"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = skillcompose_main(["evolve", *ARGS, "--generations", "2", "--out", str(d)])
    assert code == 0
    rd = RunDir(d)
    state = rd.load_checkpoint()
    state["run"]["config"]["generations"] = 4  # as if it had been started for 4 and killed
    rd.save_checkpoint(state)
    info = rd.load_run_info()
    info["config"]["generations"] = 4
    rd.write_run_info(info)
    return d


@pytest.fixture
def run_dir(stopped_run: Path, tmp_path: Path) -> Path:
    """A copy of :func:`stopped_run` of this test's own."""
    d = tmp_path / "received"
    shutil.copytree(stopped_run, d)
    return d


def _resume(d: Path, capsys: pytest.CaptureFixture[str], *more: str) -> tuple[int, str]:
    code = skillcompose_main(["evolve", "--resume", str(d), "--quiet", *more])
    err = capsys.readouterr().err
    return code, err


def _one_line_error(code: int, err: str) -> str:
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    return err


def _craft(d: Path, change: Any) -> None:
    """Change the checkpoint's state and write it with a correct checksum, as someone who
    crafts a run directory would."""
    rd = RunDir(d)
    state = rd.load_checkpoint()
    change(state)
    rd.save_checkpoint(state)


def _deep(depth: int) -> list[Any]:
    out: list[Any] = []
    for _ in range(depth):
        out = [out]
    return out


class _Payload:
    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[Any, ...]:
        return (Path.write_text, (self.marker, "ran"))


def test_the_resumable_run_resumes(run_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, err = _resume(run_dir, capsys)
    assert code == 0, err
    assert [json.loads(x)["generation"] for x in
            (run_dir / "history.jsonl").read_text().splitlines()] == [0, 1, 2, 3, 4]


def test_a_pickle_is_never_loaded(
    run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    marker = tmp_path / "pwned"
    evil = pickle.dumps(_Payload(marker))
    (run_dir / "checkpoint.json").unlink()
    (run_dir / "checkpoint.pkl").write_bytes(evil)  # the format of older versions
    err = _one_line_error(*_resume(run_dir, capsys))
    assert "pickle" in err and "never loaded" in err
    (run_dir / "checkpoint.json").write_bytes(evil)
    err = _one_line_error(*_resume(run_dir, capsys))
    assert "damaged" in err
    assert not marker.exists()


def test_a_task_module_inside_the_run_directory_is_never_imported(
    run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    marker = tmp_path / "pwned"
    (run_dir / "evil_task.py").write_text(EVIL.format(marker=str(marker)))
    # run.json alone names it: refused, it differs from the checkpoint
    info = json.loads((run_dir / "run.json").read_text())
    info["task_module"] = str(run_dir / "evil_task.py")
    (run_dir / "run.json").write_text(json.dumps(info))
    err = _one_line_error(*_resume(run_dir, capsys))
    assert "differs from the run's checkpoint in task_module" in err
    # run.json and a checkpoint with a recomputed checksum name it: refused, it is inside
    for module in (str(run_dir / "evil_task.py"), "evil_task"):
        info["task_module"] = module
        (run_dir / "run.json").write_text(json.dumps(info))
        _craft(run_dir, lambda st, m=module: st["run"].update(task_module=m))
        monkeypatch.chdir(run_dir)  # where a dotted name would be found
        err = _one_line_error(*_resume(run_dir, capsys))
        assert "inside the run directory" in err and "never run" in err
    assert not marker.exists()


@pytest.mark.parametrize("module", ["received.evil", "received.ruamel.evil", "ruamel.evil"])
def test_a_task_module_reaching_inside_through_a_package_is_never_imported(
    run_dir: Path, module: str, monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Through the package above the run directory, through a namespace package inside
    it, or through one imported already (``ruamel``) whose folders the import computes
    afresh with the current directory on the path: refused, nothing imported."""
    import ruamel.yaml  # noqa: F401 - imported already, as in the command line's process

    from skillcompose.evolve.resume import load_recorded_task

    marker = run_dir / "RAN"
    (run_dir / "ruamel").mkdir()
    for path in (run_dir / "evil.py", run_dir / "ruamel" / "evil.py"):
        path.write_text(EVIL.format(marker=str(marker)))
    monkeypatch.chdir(run_dir if module == "ruamel.evil" else run_dir.parent)
    record = RunDir(run_dir).load_checkpoint()["run"]
    with pytest.raises(CheckpointError, match="inside the run directory"):
        load_recorded_task({**record, "task_module": module}, run_dir)
    assert not marker.exists()


def test_an_edited_run_json_does_not_resume_as_another_task(
    run_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    before = (run_dir / "history.jsonl").read_text()
    info = json.loads((run_dir / "run.json").read_text())
    info["task_settings"]["p_fail"] = 0.9
    (run_dir / "run.json").write_text(json.dumps(info))
    err = _one_line_error(*_resume(run_dir, capsys))
    assert "task_settings" in err and "0.9" in err and "0.3" in err
    assert (run_dir / "history.jsonl").read_text() == before


@pytest.mark.parametrize("edit, expected", [
    (lambda st: st["run"].update(seed="x"), "seed = \"x\" is not valid"),
    (lambda st: st["run"].update(task_settings=[1]), "task_settings = [1] is not valid"),
    (lambda st: st["run"].update(config={"population": -3}), "population = -3"),
    (lambda st: st["run"].pop("task"), "has no 'task'"),
    (lambda st: st.update(population=[[1, 2]]), "malformed"),
    (lambda st: st.update(population="x" * 5), "malformed"),
    (lambda st: st["population"][0][0].__setitem__(0, 999), "malformed"),
    (lambda st: st.update(rng={"bit_generator": "MT19937"}), "malformed"),
    (lambda st: st.update(generation=-1), "malformed"),
    (lambda st: st.update(cache=[[["a"], 1, 1]]), "malformed"),
    (lambda st: st["population"][0].__setitem__(0, _deep(900)), "malformed"),
    (lambda st: st["run"]["task_settings"].update(p_fail=_deep(900)), "task_settings ="),
    # values far past any run's, which would make the resume run for ever or fail inside
    (lambda st: st["run"].update(check_trials=10**30), "check_trials = 10000000000000"),
    (lambda st: st["run"].update(simplify_trials=10**30), "simplify_trials ="),
    (lambda st: st["run"]["config"].update(trials=10**30), "trials = 1000000000000"),
    (lambda st: st["run"]["config"].update(tournament=10**30), "tournament = 10000000"),
    (lambda st: st["run"]["config"].update(terminal_weight=float("inf")),
     "terminal_weight = inf: expected a finite number"),
    (lambda st: st["rng"]["state"].update(state=-1), "malformed (OverflowError"),
    (lambda st: st["rng"].update(has_uint32="x"), "malformed"),
    (lambda st: st["history"][0].update(best={}), "malformed"),
    (lambda st: st["history"][0].update(generation=-5), "malformed"),
    (lambda st: st["history"].append(7), "malformed"),
])
def test_malformed_values_give_one_line(
    run_dir: Path, capsys: pytest.CaptureFixture[str], edit: Any, expected: str
) -> None:
    rd = RunDir(run_dir)
    good_info = rd.load_run_info()
    _craft(run_dir, edit)
    state = rd.load_checkpoint()
    if isinstance(state.get("run"), dict):  # run.json says the same, so only the values speak
        rd.write_run_info({**good_info, **state["run"]})
    err = _one_line_error(*_resume(run_dir, capsys))
    assert expected in err, err


def test_a_malformed_run_json_gives_one_line(
    run_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for text in ("{not json", "[1, 2]", '{"task": 1}'):
        (run_dir / "run.json").write_text(text)
        _one_line_error(*_resume(run_dir, capsys))


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_run_files_that_are_pipes_devices_or_huge_give_one_line(
    run_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A checkpoint or run.json that is a pipe (reading it would wait for ever), a device
    (it would never end) or a file larger than any run writes: refused at once, in one
    line, without reading it whole."""
    signal.alarm(60)  # a regression would hang here: fail instead
    try:
        saved = {n: (run_dir / n).read_bytes() for n in ("checkpoint.json", "run.json")}
        for name in saved:
            (run_dir / name).unlink()
            os.mkfifo(run_dir / name)
            err = _one_line_error(*_resume(run_dir, capsys))  # read first, or locked first
            assert f"{name} cannot be read: it is a pipe, not a regular file" in err or \
                f"{name} is a pipe, where the run keeps a file; remove or rename" in err, err
            (run_dir / name).unlink()
            (run_dir / name).symlink_to("/dev/zero")
            err = _one_line_error(*_resume(run_dir, capsys))
            assert f"{name} cannot be read: it is a device, not a regular file" in err or \
                f"{name} is a device, where the run keeps a file" in err, err
            (run_dir / name).unlink()
            with (run_dir / name).open("wb") as f:  # sparse: no disk spent
                f.truncate((3 << 30) if name == "checkpoint.json" else (32 << 20))
            err = _one_line_error(*_resume(run_dir, capsys))
            assert "more than any run writes there" in err, err
            (run_dir / name).write_bytes(saved[name])
        assert _resume(run_dir, capsys)[0] == 0  # put back: it resumes
    finally:
        signal.alarm(0)


def test_a_folder_where_a_run_file_goes_is_refused_before_any_work(
    run_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for name in ("history.jsonl", "best.yaml", "best.png", "fitness.png"):
        saved = run_dir / name
        kept = run_dir.parent / f"kept-{name}"
        if saved.exists():
            saved.rename(kept)
        saved.mkdir()
        err = _one_line_error(*_resume(run_dir, capsys))
        assert f"{saved} is a folder, where the run keeps a file; remove or rename it" in err
        assert [h["generation"] for h in map(json.loads, (
            kept if name == "history.jsonl" else run_dir / "history.jsonl"
        ).read_text().splitlines())] == [0, 1, 2]  # nothing evaluated
        saved.rmdir()
        if kept.exists():
            kept.rename(saved)
    assert _resume(run_dir, capsys)[0] == 0


@pytest.mark.skipif(not hasattr(os, "O_NOFOLLOW"), reason="no O_NOFOLLOW here")
def test_a_lock_file_that_is_a_link_or_a_pipe_is_refused_and_nothing_written(
    run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A received directory whose .lock points at a file of yours: taking the lock would
    write a process id over it. Refused, on resume and on a new run; a pipe too."""
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes\n")
    signal.alarm(60)  # a pipe opened to wait for a writer would hang: fail instead
    try:
        for make in (lambda p: p.symlink_to(notes), os.mkfifo,
                     lambda p: p.symlink_to("/dev/zero")):
            (run_dir / ".lock").unlink(missing_ok=True)
            make(run_dir / ".lock")
            err = _one_line_error(*_resume(run_dir, capsys))
            assert f"{run_dir / '.lock'} is a" in err and "remove it, then run again" in err
            fresh = tmp_path / f"new{len(list(tmp_path.iterdir()))}"
            fresh.mkdir()
            (fresh / ".lock").symlink_to(notes)
            code = skillcompose_main(["evolve", *ARGS, "--out", str(fresh)])
            assert code == 2 and "is a link, where evolve keeps its lock file" in \
                capsys.readouterr().err
        assert notes.read_text() == "my notes\n"
        (run_dir / ".lock").unlink()
        assert _resume(run_dir, capsys)[0] == 0
    finally:
        signal.alarm(0)


def test_a_run_killed_as_it_was_extended_resumes(
    run_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``run.json`` takes a longer budget before the checkpoint does: a kill between the two
    leaves them differing only in what a resume may change, and the run resumes; a real
    difference is named key by key."""
    rd = RunDir(run_dir)
    info = rd.load_run_info()
    rd.write_run_info({**info, "config": {**info["config"], "generations": 50}})
    assert _resume(run_dir, capsys)[0] == 0
    info = rd.load_run_info()
    rd.write_run_info({**info, "config": {**info["config"], "trials": 7}})
    err = _one_line_error(*_resume(run_dir, capsys))
    assert "run.json differs from the run's checkpoint in config.trials 7 (the run has " in err


def test_every_single_bit_flip_is_detected(run_dir: Path) -> None:
    rd = RunDir(run_dir)
    data = (run_dir / "checkpoint.json").read_bytes()
    assert rd.parse_checkpoint(data) == rd.load_checkpoint()
    flipped = bytearray(data)
    for bit in range(8 * len(data)):  # every bit of the file, header and content
        flipped[bit // 8] ^= 1 << (bit % 8)
        with pytest.raises(CheckpointError) as info:
            rd.parse_checkpoint(bytes(flipped))
        assert "\n" not in str(info.value)
        flipped[bit // 8] ^= 1 << (bit % 8)


def test_resuming_from_inside_a_received_folder_imports_nothing_from_it(
        run_dir: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """`cd received && skillcompose evolve --resume .`: modules a library may try to import
    (matplotlib tries `import winreg`) placed in the folder are never imported, during the
    resume or after it."""
    marker = run_dir.parent / "ran"
    for name in ("winreg", "pyecharts", "_winapi_stray"):
        (run_dir / f"{name}.py").write_text(EVIL.format(marker=str(marker)), encoding="utf-8")
    monkeypatch.chdir(run_dir)
    monkeypatch.setattr("sys.path", [p for p in __import__("sys").path if p not in ("", ".")])
    code, err = _resume(Path("."), capsys)
    assert code == 0, err
    assert not marker.exists()
    import importlib.util
    import sys

    assert str(run_dir) not in sys.path and "" not in sys.path
    assert importlib.util.find_spec("_winapi_stray") is None
    assert not marker.exists()
