"""Run management meets faults: a resumed run keeps its fault counts and first error (they
are in the checkpoint), and ``--resume`` knows the settings of faults and limits: it refuses
those that change a run (the time limit, the fresh-episode check) and allows the others
(when workers are replaced)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from skillcompose.cli import main as skillcompose_main
from skillcompose.evolve import CheckpointError, EvolutionConfig, RunDir, evolve
from skillcompose.task import Task, load_task

FAULTY = "tests.evolve.faulty_task"
ARGS = ["evolve", FAULTY, "--set", "fault=raise", "--set", "p_fault=0.5", "--population", "16",
        "--initial-nodes", "4", "--seed", "2", "--backend", "serial", "--quiet",
        "--simplify-trials", "5", "--check-trials", "5"]
CFG = EvolutionConfig(population=16, initial_nodes=4, generations=4, checkpoint_every=2)


def _task() -> Task:
    return load_task(FAULTY, fault="raise", p_fault=0.5)


def _files(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir()) if p.is_file()}


def test_a_resumed_run_keeps_its_faults_and_first_error(tmp_path: Path) -> None:
    task = _task()
    full = evolve(task, CFG, seed=2, out_dir=tmp_path / "full", simplify_trials=5,
                  check_trials=5)
    assert full.faults.raised > 0 and full.faults.first_error is not None

    def stop(rec: object) -> None:  # killed after the checkpoint of generation 2
        if getattr(rec, "generation", 0) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        evolve(task, CFG, seed=2, out_dir=tmp_path / "b", simplify_trials=5, check_trials=5,
               on_generation=stop)
    state = RunDir(tmp_path / "b").load_checkpoint()
    assert isinstance(state["first_error"], str)
    assert [r["faults"]["raised"] for r in state["history"]] == [
        r.faults["raised"] for r in full.history[:len(state["history"])]]
    resumed = evolve(task, resume=tmp_path / "b")
    assert [r.faults for r in resumed.history] == [r.faults for r in full.history]
    assert resumed.faults == full.faults  # counts and the first error, from generation 0 on
    assert resumed.fresh == full.fresh
    result = json.loads((tmp_path / "b" / "run.json").read_text())["result"]
    assert result == json.loads((tmp_path / "full" / "run.json").read_text())["result"]
    again = evolve(task, resume=tmp_path / "b")  # finished: read back, nothing written
    assert again.unchanged and again.faults == full.faults and again.fresh == full.fresh


def test_resume_refuses_a_new_time_limit_or_check_and_allows_worker_recycling(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = tmp_path / "run"
    assert skillcompose_main([*ARGS, "--generations", "2", "--eval-time-limit", "30",
                              "--out", str(d)]) == 0
    info = json.loads((d / "run.json").read_text())
    assert info["config"]["eval_time_limit"] == 30 and info["check_trials"] == 5
    before = _files(d)
    capsys.readouterr()
    code = skillcompose_main(["evolve", "--resume", str(d), "--eval-time-limit", "0",
                              "--check-trials", "50", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "--eval-time-limit 0 (the run has 30 s)" in err
    assert "--check-trials 50 (the run has 5)" in err
    # the run's own values, and when workers are replaced, change nothing
    assert skillcompose_main(["evolve", "--resume", str(d), "--eval-time-limit", "30",
                              "--check-trials", "5", "--worker-max-jobs", "3",
                              "--worker-max-growth-mb", "10", "--quiet"]) == 0
    assert _files(d) == before
    with pytest.raises(CheckpointError, match=r"eval_time_limit 5\.0 \(the run has 30\.0\)"):
        evolve(_task(), EvolutionConfig(population=16, initial_nodes=4, generations=2,
                                        eval_time_limit=5.0), resume=d)
    with pytest.raises(CheckpointError, match=r"check_trials 9 \(the run has 5\)"):
        evolve(_task(), resume=d, check_trials=9)


def test_extending_a_run_may_recycle_its_workers(tmp_path: Path) -> None:
    task = _task()
    full = evolve(task, CFG, seed=2, out_dir=tmp_path / "full", simplify_trials=5,
                  check_trials=5)
    evolve(task, CFG.replace(generations=2), seed=2, out_dir=tmp_path / "b",
           simplify_trials=5, check_trials=5)
    extended = evolve(task, CFG.replace(worker_max_jobs=5), resume=tmp_path / "b",
                      backend="process", workers=2)
    assert [r.best for r in extended.history] == [r.best for r in full.history]
    assert sum(r.faults["recycled"] for r in extended.history) > 0
    assert extended.faults.raised == full.faults.raised
    assert extended.best_fsa.states == full.best_fsa.states
    assert extended.best_fsa.meta["evolved"]["config"]["worker_max_jobs"] == 5
    recorded = json.loads((tmp_path / "b" / "run.json").read_text())["config"]
    assert recorded["worker_max_jobs"] == 5  # recorded, as the new budget is


def test_bad_fault_counts_in_a_checkpoint_are_one_line_errors(tmp_path: Path) -> None:
    d = tmp_path / "run"
    evolve(_task(), CFG.replace(generations=2), seed=2, out_dir=d, simplify_trials=5,
           check_trials=5)
    rd = RunDir(d)
    good = rd.load_checkpoint()
    for bad in ({"faults": {"raised": "many"}}, {"faults": {"raised": [[[1]]]}},
                {"faults": ["raised"]}):
        state = json.loads(json.dumps(good))
        state["history"][0].update(bad)
        state["fitness"] = None  # not finished: resuming reads everything
        rd.save_checkpoint(state)
        with pytest.raises(CheckpointError, match="malformed") as info:
            evolve(_task(), resume=d)
        assert "\n" not in str(info.value)
    state = json.loads(json.dumps(good))
    state["first_error"] = {"not": "text"}
    rd.save_checkpoint(state)
    with pytest.raises(CheckpointError, match="first_error"):
        evolve(_task(), resume=d)
