"""Run management: resume and extend, finished runs left alone, one process per run
directory, workers that die with their parent, file modes, the exported file's command,
seed names, progress and help."""

from __future__ import annotations

import io
import json
import os
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from skillcompose import FSA, load_fsa, save_fsa
from skillcompose.cli import main as skillcompose_main
from skillcompose.evolve import CheckpointError, EvolutionConfig, EvolutionResult, RunDir, evolve
from skillcompose.evolve.rundir import MAX_DRAWN_STATES
from skillcompose.task import Task, load_task

ROOT = Path(__file__).resolve().parents[2]
TOY = ["examples.toy_task", "--set", "p_fail=0.3", "--set", "tolerance=0.002"]
SMALL = ["--preset", "paper", "--population", "30", "--initial-nodes", "8", "--seed", "4",
         "--quiet", "--simplify-trials", "20", "--backend", "serial"]
CFG = EvolutionConfig(population=30, initial_nodes=8, generations=4, checkpoint_every=3)


def _task() -> Task:
    return load_task("examples.toy_task", p_fail=0.3, tolerance=0.002)


def _history(d: Path) -> list[tuple[object, ...]]:
    keys = ("generation", "best", "mean", "median", "best_size", "total_evaluations")
    return [tuple(json.loads(x)[k] for k in keys)
            for x in (d / "history.jsonl").read_text().splitlines()]


def _same(a: EvolutionResult, b: EvolutionResult) -> None:
    assert [(r.generation, r.best, r.mean, r.median, r.total_evaluations) for r in a.history] \
        == [(r.generation, r.best, r.mean, r.median, r.total_evaluations) for r in b.history]
    assert (a.best_fitness, a.evaluations, a.best_fsa, a.evolved_fsa) == (
        b.best_fitness, b.evaluations, b.best_fsa, b.evolved_fsa)


def _files(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir()) if p.is_file()}


# -- 1, 19: a finished run is left alone ---------------------------------------------------
def test_resume_of_a_finished_run_changes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = tmp_path / "run"
    assert skillcompose_main(["evolve", *TOY, *SMALL, "--generations", "3", "--out", str(d)]) == 0
    best = load_fsa(d / "best.yaml")
    assert not best.meta["evolved"]["solved"]  # unsolved: the budget ran out
    save_fsa(best.rename_state(best.start, "Begin"), d / "best.yaml")  # a hand edit
    before = _files(d)
    assert [h[0] for h in _history(d)] == [0, 1, 2, 3]
    capsys.readouterr()
    assert skillcompose_main(["evolve", "--resume", str(d), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "finished in generation 3" in out and "nothing was changed" in out
    assert "--generations 6" in out  # how to extend it
    assert _files(d) == before  # the hand edit survives; no generation evaluated again
    # a budget below what the run has done is refused, finished or not
    assert skillcompose_main(["evolve", "--resume", str(d), "--quiet",
                              "--generations", "1"]) == 2
    assert "has reached generation 3 already; give --generations 3 or more" in \
        capsys.readouterr().err
    assert _files(d) == before


def test_resume_of_a_finished_run_writes_again_the_exports_that_were_deleted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = tmp_path / "run"
    assert skillcompose_main(["evolve", *TOY, *SMALL, "--generations", "3", "--out", str(d)]) == 0
    before = _files(d)
    del before[".written.json"]  # what it wrote: a record, rewritten with the files
    exported = {name: (d / name).read_bytes() for name in ("best.yaml", "best_evolved.yaml")}
    for name in exported:
        (d / name).unlink()
    capsys.readouterr()
    assert skillcompose_main(["evolve", "--resume", str(d), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "wrote again best.yaml, best_evolved.yaml, which had been deleted" in out
    assert {name: (d / name).read_bytes() for name in exported} == exported  # as written
    assert {k: v for k, v in _files(d).items() if k != ".written.json"} == before
    (d / "best_evolved.yaml").unlink()
    assert skillcompose_main(["evolve", "--resume", str(d), "--quiet"]) == 0
    assert "wrote again best_evolved.yaml, which" in capsys.readouterr().out
    assert {k: v for k, v in _files(d).items() if k != ".written.json"} == before


# -- 2: extending a run ----------------------------------------------------------------------
def test_extending_a_run_equals_an_uninterrupted_run(tmp_path: Path) -> None:
    task = _task()
    full = evolve(task, CFG.replace(generations=8), seed=4, out_dir=tmp_path / "full",
                  simplify_trials=20)
    short = evolve(task, CFG, seed=4, out_dir=tmp_path / "short", simplify_trials=20)
    assert short.generations == 4 and not short.solved
    extended = evolve(task, CFG.replace(generations=8), resume=tmp_path / "short")
    _same(full, extended)
    assert _history(tmp_path / "short") == _history(tmp_path / "full")  # no duplicates
    a, b = load_fsa(tmp_path / "full" / "best.yaml"), load_fsa(tmp_path / "short" / "best.yaml")
    assert (a.states, a.meta["evolved"]["fitness"]) == (b.states, b.meta["evolved"]["fitness"])
    # from the command line, on a process pool: extended again, to 10, as a run to 10
    assert skillcompose_main(["evolve", "--resume", str(tmp_path / "short"), "--quiet",
                              "--generations", "10", "--backend", "process",
                              "--workers", "2"]) == 0
    ten = evolve(task, CFG.replace(generations=10), seed=4, simplify_trials=20)
    assert _history(tmp_path / "short") == [
        (r.generation, r.best, r.mean, r.median, r.best_size, r.total_evaluations)
        for r in ten.history]
    assert json.loads((tmp_path / "short" / "run.json").read_text())["config"][
        "generations"] == 10


def test_a_best_yaml_edited_by_a_person_is_kept_when_the_run_writes_again(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Extending a run whose best.yaml a person edited (as the README suggests) keeps the
    edit, renamed beside it, says so in one line, and writes the run's own; files the run
    wrote itself are simply replaced, a killed run's included."""
    d = tmp_path / "run"
    assert skillcompose_main(["evolve", *TOY, *SMALL, "--generations", "2", "--out", str(d)]) == 0
    edited = (d / "best.yaml").read_text() + "# my notes: route failure back to retry\n"
    (d / "best.yaml").write_text(edited)
    capsys.readouterr()
    assert skillcompose_main(["evolve", "--resume", str(d), "--quiet", "--generations", "4"]) == 0
    err = capsys.readouterr().err
    kept = [line for line in err.splitlines() if "edited" in line]
    assert kept == [f"{d / 'best.yaml'} was edited since this run wrote it: kept as "
                    "best.edited.yaml, and the run writes its own best.yaml"]
    assert (d / "best.edited.yaml").read_text() == edited
    assert "my notes" not in (d / "best.yaml").read_text()
    load_fsa(d / "best.yaml")
    # edited again, and extended again: a second name, the first kept as it was
    (d / "best.yaml").write_text(edited)
    assert skillcompose_main(["evolve", "--resume", str(d), "--quiet", "--generations", "5"]) == 0
    assert (d / "best.edited-2.yaml").read_text() == edited
    assert (d / "best.edited.yaml").read_text() == edited
    # not edited: replaced, nothing kept
    capsys.readouterr()
    assert skillcompose_main(["evolve", "--resume", str(d), "--quiet", "--generations", "6"]) == 0
    assert "was edited" not in capsys.readouterr().err
    assert sorted(p.name for p in d.glob("*.edited*")) == ["best.edited-2.yaml",
                                                           "best.edited.yaml"]
    # the run's record of what it wrote lost: kept, to be safe, without claiming an edit
    (d / ".written.json").unlink()
    assert skillcompose_main(["evolve", "--resume", str(d), "--quiet", "--generations", "7"]) == 0
    kept = [line for line in capsys.readouterr().err.splitlines() if "edited" in line]
    assert kept[1] == (f"{d / 'best.yaml'} may have been edited: the run's record of what it "
                       "wrote there (.written.json) is missing or unreadable: kept as "
                       "best.edited-3.yaml, and the run writes its own best.yaml")
    assert len(kept) == 2 and sorted(p.name for p in d.glob("*.edited*")) == [
        "best.edited-2.yaml", "best.edited-3.yaml", "best.edited.yaml",
        "best_evolved.edited.yaml"]


def test_a_new_run_refuses_a_folder_holding_run_files_without_a_checkpoint(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--out`` into a folder holding a person's best.yaml (their seed FSA, say) or the
    files of a run without its checkpoint: refused before anything is written."""
    mine = tmp_path / "mine"
    mine.mkdir()
    seed = ROOT / "tests" / "evolve" / "data" / "toy_solution.yaml"
    text = seed.read_text() + "# hand-written\n"
    (mine / "best.yaml").write_text(text)
    capsys.readouterr()
    code = skillcompose_main(["evolve", *TOY, *SMALL, "--generations", "1", "--seed-fsa",
                              str(mine / "best.yaml"), "--out", str(mine)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "holds best.yaml but no checkpoint" in err and "another --out" in err
    assert (mine / "best.yaml").read_text() == text
    assert [p.name for p in mine.iterdir()] == ["best.yaml"]  # nothing written there
    with pytest.raises(CheckpointError, match=r"holds run\.json, history\.jsonl but no"):
        (tmp_path / "torn").mkdir()
        (tmp_path / "torn" / "run.json").write_text("{}")
        (tmp_path / "torn" / "history.jsonl").write_text("")
        evolve(_task(), CFG, seed=4, out_dir=tmp_path / "torn")
    assert (tmp_path / "torn" / "run.json").read_text() == "{}"
    (tmp_path / "pictures").mkdir()
    (tmp_path / "pictures" / "fitness.png").write_bytes(b"a person's picture")
    with pytest.raises(CheckpointError, match=r"holds fitness\.png but no checkpoint"):
        evolve(_task(), CFG, seed=4, out_dir=tmp_path / "pictures")
    # what a run killed as it started leaves (run.json, an empty history): nothing anyone
    # would lose, so the same command may start it again there
    done = evolve(_task(), CFG, seed=4, out_dir=tmp_path / "done")
    info = json.loads((tmp_path / "done" / "run.json").read_text())
    (tmp_path / "killed").mkdir()
    (tmp_path / "killed" / "run.json").write_text(json.dumps(
        {k: v for k, v in info.items() if k != "result"}))
    (tmp_path / "killed" / "history.jsonl").write_text("")
    again = evolve(_task(), CFG, seed=4, out_dir=tmp_path / "killed")
    assert [(r.best, r.mean) for r in again.history] == [(r.best, r.mean) for r in done.history]


def test_resume_refuses_settings_that_change_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = tmp_path / "run"
    assert skillcompose_main(["evolve", *TOY, *SMALL, "--generations", "2", "--out", str(d)]) == 0
    before = _files(d)
    capsys.readouterr()
    code = skillcompose_main(["evolve", "--resume", str(d), "--population", "50", "--seed", "3",
                              "--set", "p_fail=0.5", "--no-simplify", "--crn"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    for named in ("--population 50 (the run has 30)", "--seed 3 (the run has 4)",
                  "--set p_fail=0.5 (the run has 0.3)", "--no-simplify", "--crn"):
        assert named in err, named
    # the same values as the run's are not a change
    assert skillcompose_main(["evolve", "--resume", str(d), "--population", "30", "--seed", "4",
                              "--quiet"]) == 0
    assert _files(d) == before
    with pytest.raises(CheckpointError, match=r"population 31 \(the run has 30\)"):
        evolve(_task(), CFG.replace(population=31), resume=d)
    with pytest.raises(CheckpointError, match=r"simplify_trials 7 \(the run has 20\)"):
        evolve(_task(), resume=d, simplify_trials=7)


# -- 19: killed during the final writes, simplification settings, lock, temporary files ----
def test_a_run_killed_in_its_final_writes_resumes_without_repeating_a_generation(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    task = _task()
    full = evolve(task, CFG, seed=4, out_dir=tmp_path / "full", simplify_trials=20)
    import skillcompose.evolve.export as export

    def killed(*args: object, **kwargs: object) -> object:
        raise KeyboardInterrupt

    monkeypatch.setattr(export, "simplify", killed)
    with pytest.raises(KeyboardInterrupt):
        evolve(task, CFG, seed=4, out_dir=tmp_path / "b", simplify_trials=20)
    monkeypatch.undo()
    (tmp_path / "b" / ".best.yaml.tmp-x1y2z3").write_text("half a file")  # left by a kill
    resumed = evolve(task, resume=tmp_path / "b")
    _same(full, resumed)
    assert _history(tmp_path / "b") == _history(tmp_path / "full")
    assert not list((tmp_path / "b").glob(".*.tmp-*"))


def test_ctrl_c_says_how_to_continue_the_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import skillcompose.evolve.export as export

    def interrupted(*args: object, **kwargs: object) -> object:
        raise KeyboardInterrupt

    monkeypatch.setattr(export, "simplify", interrupted)
    d = tmp_path / "my run"
    assert skillcompose_main(["evolve", *TOY, *SMALL, "--generations", "1", "--out", str(d)]) \
        == 130
    assert capsys.readouterr().err.splitlines()[-1:] == [
        f"interrupted; continue the run with: skillcompose evolve --resume '{d}'"]
    assert skillcompose_main(["evolve", *TOY, *SMALL, "--generations", "1"]) == 130  # no run
    assert capsys.readouterr().err.splitlines()[-1:] == ["interrupted"]


def test_no_simplify_is_part_of_the_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    args = [*TOY, *SMALL, "--generations", "4", "--checkpoint-every", "2", "--no-simplify"]
    assert skillcompose_main(["evolve", *args, "--out", str(a)]) == 0
    rd = RunDir(b)
    # b stops after its checkpoint of generation 2, as a kill there would leave it
    task = _task()
    with pytest.raises(KeyboardInterrupt):
        def stop(rec: object) -> None:
            if getattr(rec, "generation", 0) == 3:
                raise KeyboardInterrupt
        evolve(task, CFG.replace(checkpoint_every=2), seed=4, out_dir=b,
               simplify_result=False, simplify_trials=20, on_generation=stop)
    assert json.loads(rd.run_json.read_text())["simplify"] is False
    assert skillcompose_main(["evolve", "--resume", str(b), "--quiet"]) == 0
    assert (a / "best.yaml").read_text() == (b / "best.yaml").read_text()
    evolved = load_fsa(b / "best_evolved.yaml")
    assert load_fsa(b / "best.yaml").states == evolved.states  # not simplified
    capsys.readouterr()


def test_two_processes_cannot_evolve_in_one_directory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = tmp_path / "run"
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from skillcompose.evolve import RunDir; "
         "r = RunDir(sys.argv[1]); r.lock(); print('locked', flush=True); time.sleep(60)", str(d)],
        cwd=ROOT, stdout=subprocess.PIPE, text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "locked"
        code = skillcompose_main(["evolve", *TOY, *SMALL, "--generations", "1", "--out", str(d)])
        err = capsys.readouterr().err
        assert code == 2 and f"in use by another evolve (process {holder.pid})" in err
        assert not (d / "history.jsonl").exists()
    finally:
        holder.kill()
        holder.wait(timeout=10)
    assert skillcompose_main(["evolve", *TOY, *SMALL, "--generations", "1", "--out", str(d)]) == 0


# -- 3: workers die with their parent -------------------------------------------------------
def _children(pid: int) -> set[int]:
    out: set[int] = set()
    for task in Path(f"/proc/{pid}/task").iterdir():
        text = (task / "children").read_text().split()
        out |= {int(x) for x in text}
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc")
def test_no_worker_survives_a_kill_9_of_the_evolving_process(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(
        # p_fail 1: no FSA can solve it, so the run is still going when it is killed
        [sys.executable, "-m", "skillcompose.evolve.cli", "evolve", "examples.toy_task",
         "--set", "p_fail=1.0", "--population", "200",
         "--generations", "100000", "--backend", "process", "--workers", "2", "--quiet",
         "--out", str(tmp_path / "run")],
        cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    workers: set[int] = set()
    try:
        deadline = time.time() + 60
        while time.time() < deadline and len(workers) < 2:
            time.sleep(0.05)
            workers = _children(proc.pid) if proc.poll() is None else set()
            if (tmp_path / "run" / "history.jsonl").exists() and len(workers) >= 2 and \
                    (tmp_path / "run" / "history.jsonl").read_text().count("\n") >= 2:
                break
        assert len(workers) >= 2, "the pool did not start"
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    deadline = time.time() + 10
    while time.time() < deadline and any(map(_alive, workers)):
        time.sleep(0.05)
    survivors = [w for w in workers if _alive(w)]
    for w in survivors:  # never leave them running, even when the test fails
        os.kill(w, signal.SIGKILL)
    assert not survivors


# -- 4: file modes ----------------------------------------------------------------------------
def test_outputs_honour_the_umask_and_keep_an_existing_mode(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        evolve(_task(), CFG.replace(generations=1), seed=4, out_dir=tmp_path / "run",
               simplify_trials=20)
        for p in (tmp_path / "run").iterdir():
            if p.name != ".lock":
                assert p.stat().st_mode & 0o777 == 0o644, p.name
        f = tmp_path / "mine.yaml"
        save_fsa(load_fsa(tmp_path / "run" / "best.yaml"), f)
        assert f.stat().st_mode & 0o777 == 0o644
        f.chmod(0o640)
        save_fsa(load_fsa(f), f)
        assert f.stat().st_mode & 0o777 == 0o640
        os.umask(0o077)
        save_fsa(load_fsa(f), tmp_path / "private.yaml")
        assert (tmp_path / "private.yaml").stat().st_mode & 0o777 == 0o600
    finally:
        os.umask(old)


# -- 5: the exported file knows its task ----------------------------------------------------
def test_the_printed_command_runs_the_exported_fsa(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = tmp_path / "run"
    assert skillcompose_main(["evolve", *TOY, *SMALL, "--generations", "2", "--out", str(d)]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("run it: "))
    words = shlex.split(line.removeprefix("run it: "))
    assert words[:3] == ["skillcompose", "run", str(d / "best.yaml")]
    assert skillcompose_main(words[1:]) == 0
    assert "1 run(s)" in capsys.readouterr().out
    fsa = load_fsa(d / "best.yaml")
    evolved = fsa.meta["evolved"]
    assert evolved["task_module"] == "examples.toy_task"
    assert evolved["task_settings"] == {"p_fail": 0.3, "tolerance": 0.002}
    assert evolved["config"]["population"] == 30
    head = (d / "best.yaml").read_text().split("format:")[0]
    assert "--task examples.toy_task --set p_fail=0.3 --set tolerance=0.002" in head


# -- 6: seed names and comments ---------------------------------------------------------------
SEED = """\
# my own fetch
format: 1
start: Find
step_limit: 20
terminals: [success, failure]
states:
  Find:
    skill: FindBlock
    transitions: {success: Dawdle}
  Dawdle:              # useless: simplification takes it out
    skill: Wait
    params: {seconds: 1.0}
    transitions: {success: Pick}
  Pick:
    skill: PickBlock
    transitions: {success: Haul, failure: Pick}   # retry
  Haul:
    skill: Carry
    params:
      distance: 0.7    # the goal
    transitions: {success: Drop, failure: Haul}
  Drop:
    skill: PutDown
    transitions: {success: success, failure: failure}
"""


def test_seed_fsa_keeps_its_state_names_and_comments(tmp_path: Path) -> None:
    seed = tmp_path / "seed.yaml"
    seed.write_text(SEED)
    task = load_task("examples.toy_task", p_fail=0.0, trials=2)
    result = evolve(task, CFG.replace(generations=3), seed=0, seed_fsa=seed,
                    out_dir=tmp_path / "run", simplify_trials=20)
    assert result.solved and result.generations == 0
    assert set(result.evolved_fsa.states) == {"Find", "Dawdle", "Pick", "Haul", "Drop"}
    assert set(result.best_fsa.states) == {"Find", "Pick", "Haul", "Drop"}
    evolved_text = (tmp_path / "run" / "best_evolved.yaml").read_text()
    for comment in ("# useless: simplification takes it out", "# retry", "# the goal"):
        assert comment in evolved_text
    text = (tmp_path / "run" / "best.yaml").read_text()
    assert "# retry" in text and "# the goal" in text  # Pick and Haul are unchanged
    assert "Dawdle" not in text
    assert text.startswith("# Evolved by skillcompose") and "my own fetch" not in text
    assert load_fsa(tmp_path / "run" / "best.yaml").states["Find"].transitions == {
        "success": "Pick"}  # changed by simplification, so written afresh


def test_a_seed_fsas_time_limit_is_said_to_be_dropped(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A state's time_limit (a guard for a hardware skill) is not part of the genome: the
    run says so in one line as it starts, instead of dropping it silently."""
    seed = tmp_path / "seed.yaml"
    seed.write_text(SEED.replace("    skill: PickBlock\n",
                                 "    skill: PickBlock\n    time_limit: 0.5   # guard\n"))
    task = load_task("examples.toy_task", p_fail=0.0, trials=2)
    evolve(task, CFG.replace(generations=1), seed=0, seed_fsa=seed,
           out_dir=tmp_path / "run", simplify_trials=20)
    warned = [x for x in capsys.readouterr().err.splitlines() if "time_limit" in x]
    assert warned == [f"warning: {seed}: the time_limit of Pick (0.5 s) is not part of what "
                      "evolves: evolution runs the states without it and the evolved FSA has "
                      "none; put it back in the exported file (or bound whole evaluations "
                      "with --eval-time-limit)"]
    evolve(task, resume=tmp_path / "run")
    assert "time_limit" not in capsys.readouterr().err  # said once


# -- 7: progress -----------------------------------------------------------------------------
class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_says_what_is_known_and_no_eta() -> None:
    for stream in (io.StringIO(), _Terminal()):
        evolve(_task(), CFG.replace(generations=3), seed=4, progress=stream,
               simplify_result=False)
        text = stream.getvalue()
        assert "gen 3/3" in text and "gen/s" in text and "best 0." in text, text
        assert "ETA" not in text and "remaining" not in text


def test_robustness_and_long_runs_show_progress_on_a_terminal(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import skillcompose.progress as progress
    from skillcompose.robustness import robustness_sweep

    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)
    monkeypatch.setattr(progress, "REDRAW_S", 0.0)
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    robustness_sweep(ROOT / "tests" / "evolve" / "data" / "toy_solution.yaml",
                     "examples.toy_task", [0.0, 0.5], reps=50)
    assert "100/100" in term.getvalue() and "run/s" in term.getvalue()
    term.seek(0)
    term.truncate()
    assert skillcompose_main(["run", str(ROOT / "tests" / "evolve" / "data" / "toy_solution.yaml"),
                              "--task", "examples.toy_task", "--trials", "40"]) == 0
    assert "40/40" in term.getvalue()
    capsys.readouterr()


# -- 8: help ---------------------------------------------------------------------------------
def test_evolve_help_is_for_people(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        skillcompose_main(["evolve", "--help"])
    text = capsys.readouterr().out
    assert "--resume" in text and "--generations 400" in text
    for internal in ("``", ":func:", "Wired into", "register_cli", "main(argv)"):
        assert internal not in text


@pytest.mark.slow  # evolves, then extends: about 2.5 s
def test_extending_a_solved_run_says_how_to_search_on(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = tmp_path / "run"
    assert skillcompose_main(["evolve", "examples.toy_task", "--seed", "1", "--quiet",
                              "--workers", "1", "--out", str(d)]) == 0
    capsys.readouterr()
    assert skillcompose_main(["evolve", "--resume", str(d), "--generations", "2000",
                              "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "(solved); nothing was changed. A solved run is not extended" in out
    assert "skillcompose evolve examples.toy_task --set p_fail=0.1" in out
    assert f"--seed-fsa {d / 'best.yaml'} --out NEW_FOLDER" in out


def test_the_progress_line_shows_the_best_evaluation_so_far() -> None:
    """A candidate demoted by its holds test or confirmation (the run's best then takes its
    measured mean, 0.9 here) must not make 'best' go back up on the progress line."""
    import io
    from types import SimpleNamespace

    from skillcompose.evolve.progress import Progress
    from skillcompose.evolve.result import GenerationRecord

    records = [GenerationRecord(g, best, 1.0, 1.0, 3, 10, 10 * (g + 1), 100.0, 6.0 * g)
               for g, best in enumerate([1.0, 0.5, 0.8])]
    run = SimpleNamespace(history=records, best=(None, 0.9, 1),
                          task=SimpleNamespace(minimize=True),
                          cfg=SimpleNamespace(generations=10, max_evaluations=None,
                                            max_episodes=None),
                          fault_totals=SimpleNamespace(describe=lambda: ""))
    log = io.StringIO()
    Progress(log).show(run, records[-1])  # type: ignore[arg-type]
    line = log.getvalue().splitlines()[-1]
    assert "best 0.5 (this generation 0.8," in line


@pytest.mark.slow  # evolves (p_fail 1: never solved) for a few seconds before the Ctrl-C
def test_ctrl_c_on_the_process_group_gives_one_line(tmp_path: Path) -> None:
    """Ctrl-C reaches every process of the group: the pool's workers used to print
    'Process ForkProcess-1:' and a traceback each before the command's one line."""
    import signal

    proc = subprocess.Popen(
        [sys.executable, "-m", "skillcompose", "evolve", "examples.toy_task", "--preset",
         "paper", "--set", "p_fail=1.0", "--population", "4000", "--generations", "1000",
         "--workers", "2", "--out", str(tmp_path / "run")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        # as a terminal starts it: a pytest started in the background of a script ignores
        # SIGINT, and a child that starts so never gets Python's KeyboardInterrupt
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.time() + 60
        while time.time() < deadline and not (tmp_path / "run" / "checkpoint.json").exists():
            time.sleep(0.2)
        time.sleep(1.0)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130
    assert "ForkProcess" not in err and "Traceback" not in err, err
    assert err.strip().splitlines()[-1].startswith("interrupted; continue the run with: ")


def test_an_out_dir_that_cannot_be_made_is_one_error_before_any_work(tmp_path: Path) -> None:
    a_file = tmp_path / "a_file"
    a_file.write_text("x", encoding="utf-8")
    generations: list[object] = []
    with pytest.raises(CheckpointError, match=r"the run's folder cannot be made \(Not a "
                                              r"directory\); give a folder you can write in"):
        evolve(_task(), CFG, seed=1, out_dir=a_file / "run", on_generation=generations.append)
    assert generations == []  # refused before a generation was evaluated


def test_the_command_line_says_why_a_large_best_has_no_picture(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The files the command lists leave best.png out, and a line says why and how to draw
    the FSA."""
    out = tmp_path / "run"
    assert skillcompose_main([
        "evolve", "examples.toy_task", "--preset", "paper", "--initial-nodes", "1500",
        "--population", "2", "--generations", "1", "--seed", "1", "--no-simplify",
        "--check-trials", "0", "--quiet", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "best.png" not in text.split("files written:")[1].split("(no best.png")[0]
    assert f"states are more than {MAX_DRAWN_STATES} to draw legibly; best.dot holds the " \
        f"graph, or: skillcompose show {out / 'best.yaml'} -o best.svg)" in text
    assert not (out / "best.png").exists()


def test_a_picture_of_an_earlier_best_goes_when_the_best_is_too_large_to_draw(
        tmp_path: Path) -> None:
    """``best.png`` never shows another FSA than ``best.yaml``: drawn for a small best,
    removed when a later best has more than MAX_DRAWN_STATES states."""
    rundir = RunDir(tmp_path)
    rundir.plots([], FSA.chain(["Wait"] * 3))
    assert rundir.best_png.stat().st_size > 0
    rundir.plots([], FSA.chain(["Wait"] * (MAX_DRAWN_STATES + 1)))
    assert not rundir.best_png.exists()
    rundir.plots([], FSA.chain(["Wait"] * (MAX_DRAWN_STATES + 1)))  # nothing to remove
    rundir.plots([], FSA.chain(["Wait"] * 4))
    assert rundir.best_png.exists()
