"""Faults during evolution are counted, bounded and reported, the same on every backend;
results are reported honestly (fresh episodes, exit status). Uses tests/evolve/faulty_task.py,
whose ``Fault`` skill misbehaves in the way its ``fault`` setting says."""

from __future__ import annotations

import dataclasses
import io
import json
import math
import os
import time
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pytest

from skillcompose import FSA, Blackboard, Registry, State, load_fsa, save_fsa, skill
from skillcompose.cli import main as skillcompose_main
from skillcompose.evolve import EvolutionConfig, Genome, Job, Node, SkillSet, evolve
from skillcompose.evolve.errors import EvolutionError
from skillcompose.evolve.evaluation import EvalLimits, Faults
from skillcompose.evolve.holds import describe_fresh
from skillcompose.evolve.pool import ProcessEvaluator
from skillcompose.evolve.serial import SerialEvaluator
from skillcompose.task import Task, load_task

FAULTY = "tests.evolve.faulty_task"
TOY_SOLUTION = Path(__file__).parent / "data" / "toy_solution.yaml"
SMALL = EvolutionConfig(population=16, generations=2, initial_nodes=4)


def _history(result: Any) -> list[tuple[Any, ...]]:
    """What must be equal between backends: fitness statistics and deterministic faults."""
    return [(r.best, r.mean, r.median, r.best_size,
             {k: v for k, v in r.faults.items() if k not in ("worker_deaths", "recycled")})
            for r in result.history]


def _jobs(task: Task, skill_names: list[str], trials: int = 1) -> list[Job]:
    """One job per name: a one-state FSA running that skill, every outcome ending the run."""
    skills = SkillSet.from_task(task)
    jobs = []
    for i, name in enumerate(skill_names):
        k = skills.index[name]
        edges = [-1] * len(skills.choices[k].outcomes)
        jobs.append(Job.of(Genome({0: Node(k, [0.5] * skills.choices[k].genes, edges)}, 0),
                           0, (1, 0, i), trials))
    return jobs


# -- item 9: errors counted, the first shown, exit status --------------------------------------
def test_evolve_fails_when_every_evaluation_raises(capsys: pytest.CaptureFixture[str]) -> None:
    code = skillcompose_main([
        "evolve", FAULTY, "--preset", "paper", "--set", "fault=setup", "--population", "10",
        "--generations", "1",
        "--initial-nodes", "3", "--workers", "1", "--quiet", "--check-trials", "5",
    ])
    err = capsys.readouterr().err
    assert code == 1
    assert "faults: 20 raised in 20 evaluations (20 failed entirely)" in err
    assert "RuntimeError: the world could not be set up" in err
    assert 'faulty_task.py", line' in err  # the traceback summary names the place
    assert "every one of the 20 evaluations failed" in err


def test_some_errors_are_counted_and_the_run_succeeds(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code = skillcompose_main([
        "evolve", FAULTY, "--set", "fault=raise", "--set", "p_fault=0.5", "--population", "20",
        "--generations", "2", "--initial-nodes", "4", "--workers", "1", "--quiet",
        "--check-trials", "5",
    ])
    err = capsys.readouterr().err
    assert code == 0
    assert " raised in 60 evaluations" in err and "ValueError: the Fault skill broke" in err


# -- item 10: the exported FSA on fresh episodes --------------------------------------------
@pytest.mark.slow  # a whole run from the command line: about 1.5 s
def test_the_summary_and_run_json_report_fresh_episodes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    """Table 1 with one trial solves the noisy toy task on a lucky episode: the summary says
    how the exported FSA does on fresh ones, with its bounds, and that solved was the
    paper's criterion."""
    out = tmp_path / "run"
    code = skillcompose_main([
        "evolve", "examples.toy_task", "--preset", "paper", "--set", "p_fail=0.4",
        "--population", "100",
        "--initial-nodes", "12", "--generations", "60", "--seed", "1", "--workers", "1",
        "--out", str(out), "--quiet", "--simplify-trials", "50", "--check-trials", "100",
    ])
    assert code == 0
    captured = capsys.readouterr()
    info = json.loads((out / "run.json").read_text())["result"]
    fresh = info["fresh"]
    assert info["solved"] and info["solved_by"] == "evaluation"
    assert fresh["episodes"] == 100 and fresh["differs"] and fresh["holds"] is False
    assert 0.0 < fresh["success_rate"] < 1.0
    assert fresh["lower"] < fresh["success_rate"] < fresh["upper"]
    assert fresh["required_rate"] == 0.95
    assert (f"the exported FSA: {100 * fresh['success_rate']:.1f} % of 100 fresh episodes "
            "reach the target (95 % bounds") in captured.out
    assert "does not hold at the required 95 %" in captured.out
    assert "solved by the paper's criterion (one evaluation reached the target)" \
        in captured.out


# -- item 11: deterministic tasks -------------------------------------------------------------
def test_a_deterministic_task_runs_one_trial() -> None:
    toy = load_task("examples.toy_task", p_fail=0.0, trials=5)

    def fixed_world(rng: np.random.Generator) -> Blackboard:
        return Blackboard({"p_fail": 0.0, "block_m": 0.1, "holding": False, "placed": False})

    task = dataclasses.replace(toy, setup=fixed_world, deterministic=True, ref=None)
    result = evolve(task, SMALL.replace(confirm_trials=20), seed=0, simplify_trials=200,
                    check_trials=200)
    assert [r.evaluations for r in result.history] == [16] * len(result.history)
    assert result.best_fsa.meta["simplified"]["trials"] == 1
    assert result.fresh["episodes"] == 1
    # one episode is every episode: the summary gives a verdict, not a rate of a sample of one
    assert result.fresh["deterministic"] is True
    verdict = "reaches" if result.fresh["success_rate"] == 1.0 else "does not reach"
    assert describe_fresh(result.fresh) == (
        f"{verdict} the target on a fresh episode (a deterministic task: every episode is "
        "the same)")
    # a run.json from before the flag (or a noisy task's check of one episode): rate, bounds
    older = {k: v for k, v in result.fresh.items() if k != "deterministic"}
    assert describe_fresh(older).startswith(
        f"{100 * older['success_rate']:.1f} % of 1 fresh episodes reach the target (95 % "
        "bounds ")


# -- item 12: a task's terminal outcomes ----------------------------------------------------
@skill
def check_time(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "time_up"]:
    """End the run: ``time_up`` when the block was not placed."""
    return "success" if bb.get("placed", False) else "time_up"


def test_a_task_declares_its_terminal_outcomes(tmp_path: Path) -> None:
    toy = load_task("examples.toy_task", p_fail=0.0)
    registry = Registry()
    from examples import toy_task

    toy_task.register(registry)
    registry.add(check_time)
    task = dataclasses.replace(
        toy, registry=registry, terminal_skills=("CheckTime",), ref=None,
        terminals=("success", "failure", "time_up"),
    )
    skills = SkillSet.from_task(task)
    choice = skills.choices[skills.index["CheckTime"]]
    assert [choice.fixed_edge(k) for k in range(2)] == [-1, -3]  # both end the run
    result = evolve(task, SMALL.replace(generations=3, initial_nodes=8), seed=2,
                    out_dir=tmp_path / "run", check_trials=5)
    fsa = load_fsa(tmp_path / "run" / "best_evolved.yaml")
    assert fsa.terminals == ("success", "failure", "time_up")
    checks = [st for st in result.evolved_fsa.states.values() if st.skill == "CheckTime"]
    for st in checks:
        assert st.transitions == {"success": "success", "time_up": "time_up"}


# -- item 13: one step limit ------------------------------------------------------------------
def test_run_with_a_task_uses_the_tasks_step_limit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    loop = FSA({"W": State("Wait", {}, {"success": "W"})}, "W", step_limit=100)
    path = save_fsa(loop, tmp_path / "loop.yaml").path
    assert path is not None
    code = skillcompose_main(["run", path, "--task", "examples.toy_task", "--set",
                              "step_limit=7", "--trials", "3"])
    captured = capsys.readouterr()
    assert code == 0
    assert "timeout" in captured.out and "mean steps 7.00" in captured.out
    assert "step limit 7 from task toy_fetch (the file's 100 applies" in captured.err


# -- items 14 and 15: time limits, fault counts, the same on every backend -----------------
@pytest.mark.slow
@pytest.mark.timeout(120)  # a hang guard: the skill hangs for good without the limit
def test_a_hanging_skill_times_out_the_same_on_every_backend(tmp_path: Path) -> None:
    task = load_task(FAULTY, fault="hang", p_fault=0.3)
    cfg = SMALL.replace(eval_time_limit=0.2, generations=1)
    runs = []
    for backend, workers in (("serial", 1), ("process", 1), ("process", 2)):
        result = evolve(task, cfg, seed=4, backend=backend, workers=workers,
                        simplify_result=False, check_trials=0,
                        out_dir=tmp_path / f"{backend}{workers}")
        runs.append(result)
    timeouts = [r.faults["timeouts"] for r in runs[0].history]
    assert sum(timeouts) > 0
    assert _history(runs[0]) == _history(runs[1]) == _history(runs[2])
    lines = (tmp_path / "serial1" / "history.jsonl").read_text().splitlines()
    assert [json.loads(x)["faults"]["timeouts"] for x in lines] == timeouts
    info = json.loads((tmp_path / "process2" / "run.json").read_text())
    assert info["result"]["faults"]["timeouts"] == sum(timeouts)


def _slow_toy(slow_s: float, p_slow: float) -> Task:
    """The toy task (p_fail 0.1) whose score takes ``slow_s`` seconds on a share ``p_slow``
    of its worlds (drawn with the world), else 10 ms."""
    toy = load_task("examples.toy_task", p_fail=0.1)

    def setup(rng: np.random.Generator) -> Blackboard:
        bb = toy.setup(rng)
        bb["slow"] = bool(rng.random() < p_slow)
        return bb

    def fitness(outcome: str, bb: Blackboard, steps: int) -> float:
        time.sleep(slow_s if bb["slow"] else 0.01)
        return toy.fitness(outcome, bb, steps)

    return dataclasses.replace(toy, setup=setup, fitness=fitness, ref=None)


@pytest.mark.timeout(60)  # a hang guard
def test_a_confirmation_is_limited_episode_by_episode_not_as_a_whole() -> None:
    """``eval_time_limit`` bounds an evaluation (one episode here); a confirmation of 60
    episodes, each well within it, takes longer than the limit in all and still counts
    (it used to run as one job and be cut off at the limit, scoring worst)."""
    task = _slow_toy(0.0, 0.0)
    cfg = SMALL.replace(confirm_trials=60, confirm_rate=0.9, eval_time_limit=0.2,
                        generations=3)
    result = evolve(task, cfg, seed=0, seed_fsa=TOY_SOLUTION, simplify_result=False,
                    check_trials=0)
    assert result.solved and result.generations == 0
    assert result.evaluations == 16 + 60  # the generation's episodes and the confirmation's
    assert result.faults.timeouts == 0 and result.faults.raised == 0


@pytest.mark.timeout(60)  # a hang guard
def test_a_confirmation_episode_past_the_limit_is_a_counted_time_out(tmp_path: Path) -> None:
    """An episode of a confirmation that runs past the limit scores worst and is counted
    among the run's time-outs (it used to leave no trace), in the result and, after a
    resume, still."""
    task = _slow_toy(0.5, 0.1)
    cfg = SMALL.replace(confirm_trials=40, confirm_rate=0.5, eval_time_limit=0.2,
                        generations=1)
    result = evolve(task, cfg, seed=1, seed_fsa=TOY_SOLUTION, simplify_result=False,
                    check_trials=0, out_dir=tmp_path / "run")
    in_generations = sum(r.faults["timeouts"] for r in result.history)
    assert result.faults.timeouts > in_generations
    resumed = evolve(task, cfg.replace(generations=2), resume=tmp_path / "run",
                     simplify_result=False, check_trials=0)
    assert resumed.faults.timeouts >= result.faults.timeouts


@pytest.mark.timeout(60)  # a hang guard: the stuck worker never returns unless killed
def test_a_worker_stuck_past_the_limit_is_killed() -> None:
    """A skill the alarm cannot reach (SIGALRM blocked): the parent kills its worker after
    the limit and a grace period; only that job scores worst, as a time-out."""
    task = load_task(FAULTY, fault="stuck")
    jobs = _jobs(task, ["FindBlock", "Fault", "Carry", "FindBlock"])
    expected = SerialEvaluator(task, SkillSet.from_task(task)).evaluate([jobs[0], jobs[2],
                                                                        jobs[3]])
    ev = ProcessEvaluator(task, SkillSet.from_task(task), workers=2,
                          limits=EvalLimits(time_limit=0.2))
    try:
        out = ev.evaluate(jobs)  # returns at all: the stuck worker was killed
        assert out[1] == task.worst and [out[0], out[2], out[3]] == expected
        assert ev.faults.timeouts == 1 and ev.faults.worker_deaths == 0
        assert ev.evaluate(jobs[:1]) == expected[:1]  # a fresh worker took its place
    finally:
        ev.close()


def test_faults_are_recorded_per_generation_and_shown(tmp_path: Path) -> None:
    task = load_task(FAULTY, fault="raise", p_fault=0.5)
    stream = io.StringIO()
    serial = evolve(task, SMALL, seed=1, out_dir=tmp_path / "s", progress=stream,
                    check_trials=5)
    pool = evolve(task, SMALL, seed=1, backend="process", workers=2, check_trials=5)
    assert _history(serial) == _history(pool)
    assert serial.faults.first_error == pool.faults.first_error  # the first in job order
    raised = [r.faults["raised"] for r in serial.history]
    assert raised[0] > 0 and serial.faults.raised == sum(raised)
    assert serial.faults.first_error is not None
    assert "ValueError: the Fault skill broke" in serial.faults.first_error
    assert f"faults: {raised[0]} raised" in stream.getvalue()
    lines = (tmp_path / "s" / "history.jsonl").read_text().splitlines()
    assert [json.loads(x)["faults"]["raised"] for x in lines] == raised
    info = json.loads((tmp_path / "s" / "run.json").read_text())["result"]
    assert info["faults"]["raised"] == sum(raised)
    assert "ValueError" in info["first_error"]


def test_pool_workers_are_pinned_a_core_each_by_default() -> None:
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) < 2:
        pytest.skip("pinning shows with two cores or more")
    task = load_task(FAULTY)
    jobs = _jobs(task, ["FindBlock", "Carry", "FindBlock"])
    expected = SerialEvaluator(task, SkillSet.from_task(task)).evaluate(jobs)
    for pin, placed in ((None, [{cpus[0]}, {cpus[1]}]), (False, [set(cpus)] * 2)):
        skills = SkillSet.from_task(task)
        ev = ProcessEvaluator(task, skills, workers=2) if pin is None else \
            ProcessEvaluator(task, skills, workers=2, pin=pin)  # None: the default
        try:
            assert ev.evaluate(jobs) == expected
            assert [os.sched_getaffinity(w.process.pid) for w in ev._pool] == placed
        finally:
            ev.close()


def test_an_interrupted_batch_leaves_no_lock_held(monkeypatch: pytest.MonkeyPatch) -> None:
    """Workers stopped by an interrupt may be claiming a chunk, under the shared counter's
    lock: the pool that follows must not wait on that lock for ever."""
    import multiprocessing

    import skillcompose.evolve.pool as pool

    task = load_task(FAULTY)
    jobs = _jobs(task, ["FindBlock", "Carry", "FindBlock"])
    expected = SerialEvaluator(task, SkillSet.from_task(task)).evaluate(jobs)
    ev = ProcessEvaluator(task, SkillSet.from_task(task), workers=1)
    ctx = multiprocessing.get_context("fork")

    def hold(lock: Any, held: Any) -> None:
        lock.acquire()
        held.set()
        time.sleep(60)

    def interrupted(*args: object, **kwargs: object) -> object:
        # as a worker killed half-way through claiming a chunk leaves it: the lock held
        held = ctx.Event()
        holder = ctx.Process(target=hold, args=(ev._counter.get_lock(), held), daemon=True)
        holder.start()
        held.wait(10)
        holder.kill()
        holder.join()
        raise KeyboardInterrupt

    try:
        assert ev.evaluate(jobs) == expected
        monkeypatch.setattr(pool, "wait", interrupted)
        with pytest.raises(KeyboardInterrupt):
            ev.evaluate(jobs)
        monkeypatch.undo()
        lock = ev._counter.get_lock()
        assert lock.acquire(timeout=2)
        lock.release()
        assert ev.evaluate(jobs) == expected
    finally:
        ev.close()


def test_a_worker_killed_claiming_a_chunk_costs_no_result(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """A worker that dies while it holds the shared counter's lock (killed for time as its
    job ended, say) would leave the others waiting on it for ever: the pool is replaced and
    the batch run again, to the serial results, and one death is counted."""
    import signal

    import skillcompose.evolve.pool as pool

    task = load_task(FAULTY)
    jobs = _jobs(task, ["FindBlock", "Carry", "FindBlock"] * 4)
    expected = SerialEvaluator(task, SkillSet.from_task(task)).evaluate(jobs)
    ev = ProcessEvaluator(task, SkillSet.from_task(task), workers=2)
    run_packed = pool._run_packed
    marker = tmp_path / "died"

    def dies_claiming(*args: Any) -> int:
        done = run_packed(*args)
        if not marker.exists():  # once: the first chunk's worker dies taking the lock
            marker.touch()
            ev._counter.get_lock().acquire()
            os._exit(1)
        return done

    def hung(signum: int, frame: object) -> None:
        raise TimeoutError("the pool waited on a dead worker's lock")

    monkeypatch.setattr(pool, "_run_packed", dies_claiming)  # forked workers inherit it
    old = signal.signal(signal.SIGALRM, hung)
    signal.alarm(60)
    try:
        assert ev.evaluate(jobs) == expected
        assert marker.exists() and ev.faults.worker_deaths == 1
        assert ev.evaluate(jobs) == expected  # the next batch, on the fresh pool
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
        ev.close()


def test_dead_workers_are_counted_as_lost_jobs() -> None:
    task = load_task("tests.evolve.crashy_task", p_fail=0.0)
    result = evolve(task, SMALL, seed=0, backend="process", workers=2, simplify_result=False,
                    check_trials=0)
    serial = evolve(task, SMALL, seed=0, simplify_result=False, check_trials=0)
    lost = [r.faults["lost"] for r in result.history]
    assert sum(lost) > 0 and sum(r.faults["worker_deaths"] for r in result.history) >= sum(lost)
    # in this process Crash raises instead: the same evaluations fail, counted as raised
    assert [r.faults["failed"] for r in serial.history] == \
        [r.faults["failed"] for r in result.history]
    assert [(r.best, r.mean) for r in serial.history] == [(r.best, r.mean) for r in result.history]


def test_a_run_whose_every_evaluation_kills_its_worker_stops_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    """Going on would only count deaths. The first two such generations are recorded, each
    evaluation lost (shared episodes can all end their process by chance); the third is
    not."""
    d = tmp_path / "run"
    code = skillcompose_main([
        "evolve", FAULTY, "--set", "fault=crash_setup", "--population", "6", "--generations",
        "3", "--initial-nodes", "3", "--workers", "2", "--quiet", "--out", str(d),
    ])
    err = capsys.readouterr().err
    assert code == 2
    # the default for a noisy task shares each generation's episodes among its
    # evaluations, so it takes three such generations in a row to stop
    assert err.count("\n") == 1 and err.startswith(
        "skillcompose evolve: error: every evaluation of generation 2 (6) killed the worker "
        "process running it, as did every evaluation of the 2 generations before it (they "
        "shared their episodes): os._exit in task faulty_crash_setup or a skill, a crash in "
        "C code")
    assert f"go on with: skillcompose evolve --resume {d}" in err
    history = [json.loads(line) for line in (d / "history.jsonl").read_text().splitlines()]
    assert [(h["faults"]["jobs"], h["faults"]["lost"]) for h in history] == [(6, 6), (6, 6)]
    assert (d / "checkpoint.json").is_file()


def test_shared_episodes_that_kill_every_worker_now_and_then_do_not_stop_the_run() -> None:
    """With common random numbers a generation's evaluations share their worlds, so a
    world that ends its process kills them all: in 30 % of generations here. Such a
    generation is recorded, each evaluation lost; two in a row still go on."""
    from skillcompose.evolve.algorithm import LOST_IN_A_ROW

    task = load_task(FAULTY, fault="crash_world", p_fault=0.3)
    cfg = EvolutionConfig(population=6, generations=8, initial_nodes=3,
                          common_random_numbers=True, trials=1)
    result = evolve(task, cfg, seed=4, backend="process", workers=2, simplify_result=False,
                    check_trials=0)
    lost = [r.faults["lost"] for r in result.history]
    assert result.generations == 8 and LOST_IN_A_ROW == 3
    assert lost == [0, 6, 6, 0, 0, 0, 0, 0, 6]  # every evaluation, in generations 1, 2 and 8
    # their best and mean are the task's worst (+inf here: lower is better), not a score
    assert all((r.best, r.mean, r.median) == (task.worst,) * 3
               for r, n in zip(result.history, lost, strict=True) if n)
    assert any(r.best != task.worst for r in result.history)


def test_a_generation_with_no_fitness_records_the_worst_where_higher_is_better() -> None:
    """Its mean and median are the worst fitness, -inf for a task that maximises, not the
    +inf that would read as the best there is."""
    task = dataclasses.replace(load_task(FAULTY, fault="crash_world", p_fault=0.3),
                               minimize=False, target=1e9)
    cfg = EvolutionConfig(population=6, generations=2, initial_nodes=3,
                          common_random_numbers=True, trials=1)
    result = evolve(task, cfg, seed=4, backend="process", workers=2, simplify_result=False,
                    check_trials=0)
    lost = result.history[1]
    assert lost.faults["lost"] == 6
    assert (lost.best, lost.mean, lost.median) == (-math.inf,) * 3


def test_shared_episodes_that_kill_every_worker_three_generations_running_stop_the_run(
) -> None:
    task = load_task(FAULTY, fault="crash_world", p_fault=1.0)
    cfg = EvolutionConfig(population=6, generations=8, initial_nodes=3,
                          common_random_numbers=True, trials=1)
    with pytest.raises(EvolutionError) as err:
        evolve(task, cfg, seed=4, backend="process", workers=2, simplify_result=False,
               check_trials=0)
    assert str(err.value).startswith(
        "every evaluation of generation 2 (6) killed the worker process running it, as did "
        "every evaluation of the 2 generations before it (they shared their episodes): "
        "os._exit in task faulty_crash_world")


def test_a_best_fitness_of_infinity_says_where_it_came_from(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A best fitness of inf (or -inf) is the default error_fitness of an episode that
    raised, not a score the FSA earned: the summary says so, not a bare ``inf``."""
    code = skillcompose_main([
        "evolve", FAULTY, "--set", "fault=setup", "--population", "6", "--generations", "1",
        "--initial-nodes", "3", "--quiet", "--no-simplify",
    ])
    out = capsys.readouterr().out
    assert code == 1
    assert out.startswith("faulty_setup: not solved, best fitness inf (an episode of it "
                          "raised, ran past the time limit or was lost, scored as the task's "
                          "error_fitness, by default the worst) after 1 generations")


def test_a_robustness_sweep_whose_worker_dies_is_one_line(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code = skillcompose_main([
        "robustness", str(TOY_SOLUTION), "--task", FAULTY, "--set", "fault=crash_setup",
        "--reps", "4", "--workers", "2", "--p-fail", "0:0.5:2", "--quiet",
    ])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("skillcompose robustness: error: a worker process running task "
                          "faulty_crash_setup died in the sweep of p_fail (os._exit")


def test_a_robustness_sweep_whose_every_run_ends_in_error_fails_as_run_does(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    fsa = tmp_path / "fault.yaml"
    fsa.write_text("format: 1\nname: f\nstart: F\nterminals: [success, failure]\nstates:\n"
                   "  F:\n    skill: Fault\n    transitions: {success: success, "
                   "failure: failure}\n")
    args = ["robustness", str(fsa), "--task", FAULTY, "--reps", "3", "--workers", "1",
            "--p-fail", "0:0.5:2", "--quiet"]
    assert skillcompose_main([*args, "--set", "fault=raise"]) == 1
    out, err = capsys.readouterr()
    assert "error_rate" in out  # the table still comes
    assert err == (f"skillcompose robustness: error: every run of {fsa} ended in error (a "
                   "skill raised or exited); see the first with: skillcompose run "
                   f"{fsa} --task {FAULTY} --set fault=raise\n")
    assert skillcompose_main([*args, "--reps", "20", "--set", "fault=raise", "--set",
                              "p_fault=0.5"]) == 0
    assert capsys.readouterr().err == ""  # some runs in error: the table says how many


# -- item 16: SystemExit and KeyboardInterrupt inside a skill ---------------------------------
def test_sys_exit_in_a_skill_is_a_fault_not_the_end(capsys: pytest.CaptureFixture[str]) -> None:
    code = skillcompose_main([
        "evolve", FAULTY, "--set", "fault=exit", "--population", "12", "--generations", "1",
        "--initial-nodes", "4", "--workers", "1", "--quiet", "--check-trials", "5",
    ])
    captured = capsys.readouterr()
    assert code == 0 and "faulty_exit: " in captured.out
    assert "raised in 24 evaluations" in captured.err and "SystemExit: 0" in captured.err


@pytest.mark.parametrize("sigint", ["default", "ignored"])
def test_keyboard_interrupt_raised_by_a_skill_is_a_fault(
        sigint: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """As run from a terminal, and in the background (``nohup``, ``&`` in a script), where
    the process ignores SIGINT: either way the skill's KeyboardInterrupt is its fault."""
    import signal

    monkeypatch.setattr(signal, "getsignal", _sigint_as(sigint, signal.getsignal))
    task = load_task(FAULTY, fault="interrupt")
    result = evolve(task, SMALL, seed=0, simplify_result=False, check_trials=0)
    assert result.faults.raised > 0 and "KeyboardInterrupt" in str(result.faults.first_error)


def _sigint_as(sigint: str, getsignal: Any) -> Any:
    """``signal.getsignal`` reporting SIGINT's handler as Python's default or as ignored,
    whatever pytest was started under."""
    import signal

    def reported(signum: int) -> Any:
        if signum != signal.SIGINT:
            return getsignal(signum)
        return signal.default_int_handler if sigint == "default" else signal.SIG_IGN

    return reported


def test_a_real_ctrl_c_still_stops_the_run() -> None:
    import signal

    old = signal.signal(signal.SIGINT, signal.default_int_handler)  # as from a terminal
    try:
        task = load_task(FAULTY, fault="sigint")
        with pytest.raises(KeyboardInterrupt):
            evolve(task, SMALL, seed=0, simplify_result=False, check_trials=0)
    finally:
        signal.signal(signal.SIGINT, old)


# -- item 17: workers are recycled --------------------------------------------------------------
def _rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/statm", "rb") as f:
        return int(f.read().split()[1]) * 4096 / 2**20


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="needs /proc")
def test_leaking_workers_are_replaced_and_results_do_not_change() -> None:
    leaky = load_task(FAULTY, fault="leak", leak_mb=8.0)
    clean = load_task(FAULTY, fault="leak", leak_mb=0.0)
    jobs = _jobs(leaky, ["Fault", "FindBlock", "Carry", "Fault"] * 15)  # 240 MB leaked
    expected = SerialEvaluator(clean, SkillSet.from_task(clean)).evaluate(jobs)
    biggest = {}
    for name, limits, recycled in (("growth", EvalLimits(max_growth_mb=40.0), True),
                                   ("jobs", EvalLimits(max_jobs=10), True),
                                   ("none", EvalLimits(), False)):
        ev = ProcessEvaluator(leaky, SkillSet.from_task(leaky), workers=2, limits=limits)
        try:
            assert ev.evaluate(jobs) == expected
            assert ev.faults.total == 0
            # how many depends on how the workers shared the chunks (the machine's load)
            assert (ev.faults.recycled >= 1) if recycled else ev.faults.recycled == 0
            biggest[name] = max(_rss_mb(w.process.pid) for w in ev._pool)
        finally:
            ev.close()
    assert biggest["growth"] < biggest["none"] - 50


# -- item 18 (and 14 on Ray): a dead or stuck actor costs only its own job ---------------------
@pytest.mark.slow
@pytest.mark.private_network  # starts Ray, which listens: see tests/conftest.py
def test_ray_reruns_a_dead_actors_chunk_job_by_job(local_ray: Any) -> None:
    from skillcompose.evolve.ray_backend import RayEvaluator

    crashy = load_task(FAULTY, fault="crash")
    hang = load_task(FAULTY, fault="hang")
    # on the shared Ray of tests/evolve/conftest.py: each evaluator leaves it running
    ev = RayEvaluator(crashy, SkillSet.from_task(crashy), workers=1, chunks_per_worker=1)
    try:
        jobs = _jobs(crashy, ["FindBlock", "Carry", "Fault", "FindBlock"])
        good = SerialEvaluator(crashy, SkillSet.from_task(crashy)).evaluate(
            [jobs[0], jobs[1], jobs[0], jobs[3]])
        out = ev.evaluate(jobs)
        assert out[2] == crashy.worst and [out[0], out[1], out[3]] == \
            [good[0], good[1], good[3]]
        assert ev.lost == 1 and ev.faults.lost == 1
    finally:
        ev.close()
    ev = RayEvaluator(hang, SkillSet.from_task(hang), workers=1, chunks_per_worker=1,
                      limits=EvalLimits(time_limit=0.3))
    try:
        jobs = _jobs(hang, ["FindBlock", "Fault", "Carry"])
        out = ev.evaluate(jobs)
        assert out[1] == hang.worst and ev.faults.timeouts == 1 and out[0] != hang.worst
    finally:
        ev.close()


def test_faults_add_up() -> None:
    a = Faults()
    a.count(3 << 2, 3)  # every episode raised: failed entirely
    a.count(1 << 2, 3)
    a.count(1, 3)  # a time-out
    assert (a.jobs, a.failed, a.raised, a.timeouts) == (3, 2, 4, 1)
    assert a.describe() == "4 raised, 1 time-out"


def test_simplification_and_the_fresh_check_survive_sys_exit() -> None:
    from skillcompose.evolve import check_fresh, simplify

    task = load_task(FAULTY, fault="exit", p_fault=0.5)
    fsa = FSA({"F": State("FindBlock", {}, {"success": "X"}),
               "X": State("Fault", {}, {"success": "success", "failure": "failure"})}, "F")
    simplified = simplify(task, fsa, seed=0, trials=20)
    assert simplified.meta["simplified"]["trials"] == 20
    fresh = check_fresh(task, fsa, seed=0, trials=20)
    assert 0 < fresh["raised"] < 20 and fresh["episodes"] == 20


@pytest.mark.slow
@pytest.mark.private_network  # starts Ray, which listens: see tests/conftest.py
def test_faults_on_ray_equal_the_serial_run(local_ray: Any) -> None:
    task = load_task(FAULTY, fault="raise", p_fault=0.5)
    serial = evolve(task, SMALL, seed=3, simplify_result=False, check_trials=0)
    on_ray = evolve(task, SMALL, seed=3, backend="ray", workers=2, simplify_result=False,
                    check_trials=0)
    assert sum(r.faults["raised"] for r in serial.history) > 0
    assert _history(serial) == _history(on_ray)
    assert serial.faults.first_error == on_ray.faults.first_error


def test_the_fresh_check_warning_suggests_leaving_the_paper_preset() -> None:
    from skillcompose.evolve import EvolutionConfig
    from skillcompose.evolve.cli import _hold_hint

    task = load_task("examples.pour_water")
    paper = _hold_hint(EvolutionConfig(), task)
    assert "without --preset paper" in paper and "--trials" in paper
    assert "--trials" not in _hold_hint(EvolutionConfig(trials=5), task)


def test_a_run_whose_task_sometimes_kills_its_process_finishes_and_counts_it(
    tmp_path: Path,
) -> None:
    """Confirmations, holds tests, simplification and the fresh check run the task too; in
    the evolving process such a task ended the run without a word (status 3, and again on
    every resume). On the process backend they run in a child of their own: a check that
    kills it fails and counts as lost, and the run finishes. In a process of its own: a
    regression would end this one."""
    d = tmp_path / "run"
    done = _cli_in_a_process(
        ["evolve", FAULTY, "--set", "fault=crash", "--set", "p_fault=0.5", "--population",
         "12", "--generations", "3", "--initial-nodes", "4", "--workers", "2", "--quiet",
         "--out", str(d)], timeout=300)
    assert done.returncode in (0, 1), done.stderr[-2000:]
    assert "Traceback" not in done.stderr
    assert (d / "best.yaml").is_file() and (d / "best_evolved.yaml").is_file()
    result = json.loads((d / "run.json").read_text())["result"]
    per_generation = sum(json.loads(line)["faults"]["lost"]
                         for line in (d / "history.jsonl").read_text().splitlines())
    assert per_generation > 0 and result["faults"]["lost"] >= per_generation


def _cli_in_a_process(args: list[str], timeout: float) -> Any:
    """``skillcompose ARGS`` in a Python process of its own (a run that a regression would
    end or hang cannot take the test's process with it): the completed process."""
    import subprocess
    import sys

    return subprocess.run(
        [sys.executable, "-c", "import sys; from skillcompose.cli import main; "
         "sys.exit(main(sys.argv[1:]))", *args],
        capture_output=True, text=True, timeout=timeout, check=False)


def test_a_check_that_kills_its_process_returns_none_and_the_next_one_runs() -> None:
    from skillcompose.evolve.isolated import IsolatedChecks

    task = load_task("examples.toy_task")
    checks = IsolatedChecks(task, SkillSet.from_task(task))
    try:
        checks.start()
        name, first = checks.call(_in_child, False) or ("", 0)
        assert name == "toy_fetch" and first != os.getpid()
        assert checks.call(_in_child, True) is None and checks.deaths == 1
        name, second = checks.call(_in_child, False) or ("", 0)  # a new child (spawned)
        assert name == "toy_fetch" and second not in (os.getpid(), first)
    finally:
        checks.close()


def test_a_check_stuck_where_no_signal_reaches_is_killed_after_the_limit() -> None:
    """An episode of a check that blocks SIGALRM and waits would hang the run for ever: the
    child notes when each episode started, and the parent kills it a little after the
    limit; that check returns None as a time-out, and the next one runs in a new child."""
    from skillcompose.evolve.evaluation import EvalLimits
    from skillcompose.evolve.isolated import IsolatedChecks, check_kill_after

    # a run gives its checks more grace than its workers: the limit and max(5 s, 50 %)
    assert (check_kill_after(2.0), check_kill_after(60.0), check_kill_after(None)) == \
        (7.0, 90.0, None)
    task = load_task("examples.toy_task")
    limits = EvalLimits(0.3)  # here the worker's grace, to keep the test short
    checks = IsolatedChecks(task, SkillSet.from_task(task), limits.kill_after)
    try:
        checks.start()
        t = time.monotonic()
        assert checks.call(_stuck_in_child, 0.3) is None
        assert checks.last_overran and checks.overran == 1
        assert time.monotonic() - t < (limits.kill_after or 0) + 5
        assert (checks.call(_in_child, False) or ("", 0))[0] == "toy_fetch"
        assert checks.call(_in_child, True) is None and not checks.last_overran
    finally:
        checks.close()


@pytest.mark.slow  # waits out the checks' time limits: about 7 s
def test_a_run_whose_checks_get_stuck_finishes_and_says_why(tmp_path: Path) -> None:
    """The final fresh check's episodes block SIGALRM and wait: the run used to wait for
    ever. Now the checks' process is killed a little after the limit, the check counts as
    a time-out, and the run ends with one warning line that says so. In a process of its
    own, so that a regression cannot hang this one past the timeout."""
    d = tmp_path / "run"
    done = _cli_in_a_process(
        ["evolve", FAULTY, "--set", "fault=stuck_checks", "--set", "p_fault=1", "--population",
         "6", "--generations", "1", "--initial-nodes", "3", "--workers", "2", "--quiet",
         "--eval-time-limit", "0.5", "--no-simplify", "--out", str(d)], timeout=120)
    assert done.returncode in (0, 1), done.stderr[-2000:]
    assert "Traceback" not in done.stderr
    warned = [line for line in done.stderr.splitlines() if line.startswith("warning:")]
    assert warned == [
        "warning: the end of the run ran task faulty_stuck_checks and an episode ran past the "
        "evaluation time limit where no signal stopped it (SIGALRM blocked, a wait in C code), "
        "and its process was killed: the fresh-episode check is skipped"], done.stderr
    result = json.loads((d / "run.json").read_text())["result"]
    assert result["faults"]["timeouts"] >= 1


def _stuck_in_child(task: Task, compiler: Any, limit: float) -> None:
    """An episode under the check's limit that no signal can stop."""
    import signal

    from skillcompose.evolve.evaluation import Guard

    with Guard(limit) as guard, guard.episode():
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGALRM})
        time.sleep(3600)


def _in_child(task: Task, compiler: Any, die: bool) -> tuple[str, int]:
    """What :class:`IsolatedChecks` runs: the task's name and the process that ran it."""
    if die:
        os._exit(3)
    return task.name, os.getpid()


@pytest.mark.parametrize(("solved", "warned"), [(True, True), (False, False)])
def test_the_fresh_episode_warning_comes_only_for_a_run_called_solved(
        solved: bool, warned: bool, capsys: pytest.CaptureFixture[str]) -> None:
    """An unsolved run's FSA not holding is no news: the warning is for a run whose 'solved'
    the fresh episodes contradict (the paper preset in --json mode)."""
    from types import SimpleNamespace

    from skillcompose.evolve import EvolutionConfig
    from skillcompose.evolve.cli import _warn
    from skillcompose.evolve.evaluation import Faults

    result = SimpleNamespace(unchanged=False, solved=solved, fresh={"holds": False},
                             faults=Faults(), nothing_succeeded=False)
    _warn(result, EvolutionConfig(), load_task("examples.pour_water"))  # type: ignore[arg-type]
    err = capsys.readouterr().err
    assert ("does not hold on fresh ones" in err) is warned
