"""Budgets in evaluations and episodes: never overrun, used as far as a whole generation
goes, reported, combined with the others, resumable and extendable like --generations."""

from __future__ import annotations

import contextlib
import io
import json
from itertools import accumulate
from pathlib import Path
from typing import Any

import pytest

from skillcompose.cli import main as skillcompose_main
from skillcompose.evolve import (
    PRESETS,
    CheckpointError,
    EvolutionConfig,
    EvolutionConfigError,
    EvolutionError,
    EvolutionResult,
    RunDir,
    evolve,
)
from skillcompose.evolve.config import MOST
from skillcompose.task import Task, load_task

TOY = ["examples.toy_task", "--set", "p_fail=0.3", "--set", "tolerance=0.002"]
SMALL = ["--preset", "paper", "--population", "30", "--initial-nodes", "8", "--seed", "4",
         "--quiet", "--simplify-trials", "10", "--check-trials", "10", "--backend", "serial"]
# costs that vary from generation to generation: elites and genomes met before are free,
# two trials per evaluation
VARIED = EvolutionConfig(population=30, initial_nodes=8, generations=40, cache=True,
                         elitism=2, trials=2, checkpoint_every=3)
QUICK: dict[str, Any] = {"simplify_trials": 10, "check_trials": 10}


@pytest.fixture(scope="module")
def task() -> Task:
    return load_task("examples.toy_task", p_fail=0.3, tolerance=0.002)


@pytest.fixture(scope="module")
def unlimited(task: Task) -> EvolutionResult:
    """The run without evaluation or episode budgets, whose history says what each
    generation cost."""
    return evolve(task, VARIED, seed=4, **QUICK)


def _jobs(r: EvolutionResult) -> list[int]:
    """Genome evaluations of the run after each generation."""
    return list(accumulate(h.faults["jobs"] for h in r.history))


def _same(a: EvolutionResult, b: EvolutionResult) -> None:
    def strip(r: EvolutionResult) -> list[tuple[Any, ...]]:
        return [(h.generation, h.best, h.mean, h.median, h.best_size, h.evaluations,
                 h.total_evaluations, h.faults["jobs"]) for h in r.history]

    assert strip(a) == strip(b)
    assert (a.best_fitness, a.solved, a.generations, a.genome_evaluations, a.episodes,
            a.stopped_by, a.budgets, a.best_fsa, a.evolved_fsa, a.fresh) == (
        b.best_fitness, b.solved, b.generations, b.genome_evaluations, b.episodes,
        b.stopped_by, b.budgets, b.best_fsa, b.evolved_fsa, b.fresh)


# -- the settings ------------------------------------------------------------------------
def test_budgets_round_trip_and_old_settings_have_none() -> None:
    cfg = EvolutionConfig(max_evaluations=500, max_episodes=2000)
    assert EvolutionConfig.from_dict(cfg.to_dict()) == cfg
    old = EvolutionConfig().to_dict()
    del old["max_evaluations"], old["max_episodes"]  # a run directory of an older version
    back = EvolutionConfig.from_dict(old)
    assert (back.max_evaluations, back.max_episodes) == (None, None)


@pytest.mark.parametrize("value", [0, -1, 1.5, True, "10", MOST + 1])
@pytest.mark.parametrize("name", ["max_evaluations", "max_episodes"])
def test_bad_budgets_are_refused_naming_them(name: str, value: object) -> None:
    with pytest.raises(EvolutionConfigError, match=rf"{name} = .*expected a whole number "
                       rf"from 1 to {MOST:,}, or None"):
        EvolutionConfig(**{name: value})  # type: ignore[arg-type]
    EvolutionConfig.from_dict({name: MOST})


def test_a_budget_must_hold_the_first_generation(task: Task) -> None:
    with pytest.raises(EvolutionError, match=r"max_evaluations = 29 cannot hold the first "
                       r"generation .*give --max-evaluations 30 or more"):
        evolve(task, VARIED.replace(max_evaluations=29))
    with pytest.raises(EvolutionError, match=r"max_episodes = 59 cannot hold the first "
                       r"generation .*of 2 trials.*give --max-episodes 60 or more"):
        evolve(task, VARIED.replace(max_episodes=59))


# -- respected exactly ------------------------------------------------------------------
@pytest.mark.parametrize("budget", [30, 49, 57, 66, 151])
def test_an_evaluation_budget_is_never_overrun_and_used_to_the_last_whole_generation(
    task: Task, unlimited: EvolutionResult, budget: int
) -> None:
    r = evolve(task, VARIED.replace(max_evaluations=budget), seed=4, **QUICK)
    jobs = _jobs(unlimited)
    last = max(g for g, used in enumerate(jobs) if used <= budget)
    assert jobs[last + 1] > budget  # the next generation would have overrun it
    assert (r.stopped_by, r.generations, r.genome_evaluations) == (
        "evaluations", last, jobs[last])
    assert r.genome_evaluations <= budget
    assert r.budgets["evaluations"] == {"limit": budget, "used": jobs[last]}
    assert r.budgets["generations"] == {"limit": 40, "used": last}
    assert r.budgets["episodes"] == {"limit": None, "used": r.episodes}
    assert not r.solved
    # up to there, the run of the unlimited one
    assert [h.best for h in r.history] == [h.best for h in unlimited.history[:last + 1]]


@pytest.mark.parametrize("budget", [60, 98, 115, 132, 301])
def test_an_episode_budget_is_never_overrun_and_used_to_the_last_whole_generation(
    task: Task, unlimited: EvolutionResult, budget: int
) -> None:
    r = evolve(task, VARIED.replace(max_episodes=budget), seed=4, **QUICK)
    episodes = [h.total_evaluations for h in unlimited.history]
    last = max(g for g, used in enumerate(episodes) if used <= budget)
    assert episodes[last + 1] > budget
    assert (r.stopped_by, r.generations, r.episodes) == ("episodes", last, episodes[last])
    assert r.episodes <= budget and r.budgets["episodes"]["used"] == r.episodes


def test_budgets_combine_whichever_comes_first(task: Task, unlimited: EvolutionResult) -> None:
    jobs = _jobs(unlimited)
    r = evolve(task, VARIED.replace(generations=3, max_evaluations=10**6, max_episodes=10**6),
               seed=4, **QUICK)
    assert (r.stopped_by, r.generations) == ("generations", 3)
    r = evolve(task, VARIED.replace(max_evaluations=jobs[4], max_episodes=10**6), seed=4,
               **QUICK)
    assert (r.stopped_by, r.generations) == ("evaluations", 4)
    episodes = unlimited.history[2].total_evaluations
    r = evolve(task, VARIED.replace(max_evaluations=jobs[4], max_episodes=episodes), seed=4,
               **QUICK)
    assert (r.stopped_by, r.generations) == ("episodes", 2)


# -- resume and extend --------------------------------------------------------------------
@pytest.mark.parametrize("name", ["max_evaluations", "max_episodes"])
def test_a_run_stopped_by_its_budget_and_extended_is_the_run_to_the_larger_budget(
    task: Task, tmp_path: Path, name: str
) -> None:
    full = VARIED.replace(**{name: 200})
    straight = evolve(task, full, seed=4, out_dir=tmp_path / "straight", **QUICK)
    half = evolve(task, VARIED.replace(**{name: 100}), seed=4, out_dir=tmp_path / "ext",
                  **QUICK)
    assert half.stopped_by == name[4:] and half.generations < straight.generations
    again = evolve(task, VARIED.replace(**{name: 100}), resume=tmp_path / "ext")
    assert again.unchanged and again.stopped_by == name[4:]  # nothing to do within it
    extended = evolve(task, full, resume=tmp_path / "ext")
    _same(extended, straight)
    info = json.loads((tmp_path / "ext" / "run.json").read_text())
    assert info["config"][name] == 200 and info["result"]["stopped_by"] == name[4:]
    assert info["result"]["budgets"] == straight.budgets


def test_the_extension_is_the_same_on_a_process_pool(task: Task, tmp_path: Path) -> None:
    straight = evolve(task, VARIED.replace(max_evaluations=150), seed=4, **QUICK)
    evolve(task, VARIED.replace(max_evaluations=70), seed=4, out_dir=tmp_path / "r", **QUICK)
    pooled = evolve(task, VARIED.replace(max_evaluations=150), resume=tmp_path / "r",
                    backend="process", workers=2)
    _same(pooled, straight)


def test_a_budget_below_what_the_run_used_is_refused(task: Task, tmp_path: Path) -> None:
    d = tmp_path / "r"
    r = evolve(task, VARIED.replace(max_evaluations=100), seed=4, out_dir=d, **QUICK)
    used = r.genome_evaluations
    with pytest.raises(CheckpointError, match=f"has used {used} evaluations already; give "
                       f"--max-evaluations {used} or more"):
        evolve(task, VARIED.replace(max_evaluations=used - 1), resume=d)
    with pytest.raises(CheckpointError, match=f"has used {r.episodes} episodes already; give "
                       f"--max-episodes {r.episodes} or more"):
        evolve(task, VARIED.replace(max_evaluations=100, max_episodes=r.episodes - 1),
               resume=d)
    # no budget at all extends it too: to the generation budget
    r = evolve(task, VARIED.replace(generations=r.generations + 2), resume=d)
    assert (r.stopped_by, r.budgets["evaluations"]["limit"]) == ("generations", None)


def test_a_bred_generation_that_a_smaller_budget_cannot_hold_is_refused(
    task: Task, tmp_path: Path
) -> None:
    """A checkpoint of a generation bred and not evaluated (the run killed as it evaluates):
    its jobs were counted against the budget when it was bred."""
    d = tmp_path / "r"

    def stop(rec: Any) -> None:
        if rec.generation == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        evolve(task, VARIED.replace(checkpoint_every=1), seed=4, out_dir=d,
               on_generation=stop, **QUICK)
    state = RunDir(d).load_checkpoint()
    assert state["generation"] == 3 and state["fitness"] is None
    used = sum(h["faults"]["jobs"] for h in state["history"])
    with pytest.raises(CheckpointError, match=r"has bred generation 3, which takes .* give "
                       r"--max-evaluations .* or more"):
        evolve(task, VARIED.replace(max_evaluations=used + 1), resume=d)


def test_checks_that_do_not_fit_wait_for_the_extension(tmp_path: Path) -> None:
    """A generation at the target whose confirmation and holds test could overrun the
    episode budget stops the run before them, unsolved; an extended run runs them first and
    is the run to the larger budget."""
    task = load_task("examples.toy_task", p_fail=0.2)
    cfg = EvolutionConfig(**{**PRESETS["robust"], "population": 30, "initial_nodes": 8,
                             "generations": 40})
    straight = evolve(task, cfg, seed=3, **QUICK)
    assert straight.solved and straight.stopped_by == "solved"
    budget = straight.history[-1].total_evaluations + 10  # the checks' worst case cannot fit
    short = evolve(task, cfg.replace(max_episodes=budget), seed=3, out_dir=tmp_path / "r",
                   **QUICK)
    assert (short.stopped_by, short.solved) == ("episodes", False)
    assert short.episodes <= budget
    assert short.fresh["kind"] == "measured"  # its FSA measured, never called solved
    state = RunDir(tmp_path / "r").load_checkpoint()
    assert state["checks_pending"] is True
    extended = evolve(task, cfg, resume=tmp_path / "r")
    _same(extended, straight)


# -- the command line ---------------------------------------------------------------------
def _cli(*args: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = skillcompose_main(list(args))
        except SystemExit as exc:  # argparse's usage errors
            code = exc.code if isinstance(exc.code, int) else -1
    return code, out.getvalue(), err.getvalue()


def _one_line(code: int, err: str, naming: str) -> str:
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert naming in lines[0], lines[0]
    return lines[0]


@pytest.mark.parametrize("value", ["0", "-3", "1.5", "ten", str(MOST + 1)])
@pytest.mark.parametrize("option", ["--max-evaluations", "--max-episodes"])
def test_bad_budgets_on_the_command_line_are_one_line(option: str, value: str) -> None:
    line = _one_line(*_cli("evolve", *TOY, option, value)[::2], naming=option)
    assert f"from 1 to {MOST}" in line


def test_the_command_line_reports_budgets_and_extends_them(tmp_path: Path) -> None:
    d = tmp_path / "run"
    code, out, err = _cli("evolve", *TOY, *SMALL, "--max-evaluations", "100", "--out", str(d),
                          "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["stopped_by"] == "evaluations" and doc["genome_evaluations"] <= 100
    assert doc["budgets"]["evaluations"] == {"limit": 100, "used": doc["genome_evaluations"]}
    assert doc["episodes"] == doc["evaluations"] == doc["budgets"]["episodes"]["used"]
    result = json.loads((d / "run.json").read_text())["result"]
    assert (result["stopped_by"], result["budgets"]) == ("evaluations", doc["budgets"])
    # finished: left alone, and told how to extend it
    code, out, err = _cli("evolve", "--resume", str(d), "--quiet")
    assert code == 0, err
    assert "not solved in its budget of 100 evaluations" in out
    assert "--max-evaluations 200" in out
    # a smaller budget is refused in one line naming the option and the fix
    code, out, err = _cli("evolve", "--resume", str(d), "--quiet", "--max-evaluations", "50")
    line = _one_line(code, err, naming="--max-evaluations")
    assert f"give --max-evaluations {doc['genome_evaluations']} or more" in line
    # a larger one extends the run
    code, out, err = _cli("evolve", "--resume", str(d), "--quiet", "--max-evaluations", "200")
    assert code == 0, err
    assert "ended by its evaluations budget: used" in out and "evaluations of 200" in out
    assert json.loads((d / "run.json").read_text())["config"]["max_evaluations"] == 200


def test_an_older_run_directory_without_budgets_resumes_and_takes_one(tmp_path: Path) -> None:
    d = tmp_path / "run"
    assert _cli("evolve", *TOY, *SMALL, "--generations", "3", "--out", str(d))[0] == 0
    rd = RunDir(d)
    state = rd.load_checkpoint()
    for cfg in (state["run"]["config"], state["config"]):
        del cfg["max_evaluations"], cfg["max_episodes"]
    rd.save_checkpoint(state)
    info = rd.load_run_info()
    del info["config"]["max_evaluations"], info["config"]["max_episodes"]
    rd.write_run_info(info)
    code, out, err = _cli("evolve", "--resume", str(d), "--quiet")
    assert code == 0 and "nothing was changed" in out, err
    code, out, err = _cli("evolve", "--resume", str(d), "--quiet", "--generations", "50",
                          "--max-evaluations", "200")
    assert code == 0, err
    result = json.loads((d / "run.json").read_text())["result"]
    assert result["stopped_by"] == "evaluations"
    assert result["budgets"]["evaluations"]["used"] <= 200
