"""Restarts of the whole population, which grows at each (``restart_patience``,
``restart_growth``, ``population_max``): when they happen, what they keep, and every
invariant of a run across them (backends, resume, budgets), and Koza's effort of a run whose
population grows."""

from __future__ import annotations

import sys
from itertools import accumulate
from pathlib import Path
from typing import Any

import pytest

from skillcompose.evolve import (
    PRESETS,
    CheckpointError,
    EvolutionConfig,
    EvolutionConfigError,
    EvolutionResult,
    RunDir,
    evolve,
    preset_settings,
)
from skillcompose.evolve.cli import _config, build_parser
from skillcompose.task import Task, load_task

GROWING = EvolutionConfig(population=8, initial_nodes=6, generations=12, elitism=1,
                          cache=True, unique_children=True, restart_patience=2,
                          restart_growth=2, population_max=24, checkpoint_every=1)
"""A toy run that stalls and restarts: 8 individuals, then 16, then 24 (the cap)."""
QUICK: dict[str, Any] = {"simplify_result": False, "check_trials": 0}


@pytest.fixture(scope="module")
def task() -> Task:
    return load_task("examples.toy_task", p_fail=0.3, tolerance=0.002)


@pytest.fixture(scope="module")
def straight(task: Task) -> EvolutionResult:
    return evolve(task, GROWING, seed=3, **QUICK)


def _sizes(r: EvolutionResult) -> list[int]:
    return [h.population for h in r.history]


def _run(r: EvolutionResult) -> tuple[object, ...]:
    return ([(h.generation, h.best, h.mean, h.median, h.best_size, h.total_evaluations,
              h.population, h.faults["jobs"]) for h in r.history],
            r.best_fitness, r.evaluations, r.genome_evaluations, r.stopped_by, r.evolved_fsa)


def _jobs(r: EvolutionResult) -> list[int]:
    return list(accumulate(h.faults["jobs"] for h in r.history))


def test_the_population_after_restarts_grows_by_its_factor_up_to_its_cap() -> None:
    cfg = EvolutionConfig(population=30, restart_patience=5, restart_growth=4,
                          population_max=1920)
    assert [cfg.population_after(k) for k in range(6)] == [30, 120, 480, 1920, 1920, 1920]
    assert [cfg.replace(population_max=1000).population_after(k) for k in range(5)] == [
        30, 120, 480, 1000, 1000]
    assert cfg.replace(restart_growth=1).population_after(10**12) == 30  # never loops
    assert cfg.replace(population_max=None).population_after(100) == 10**6


def test_a_stalled_run_restarts_with_its_best_and_a_larger_population() -> None:
    from skillcompose.evolve.breeding import breed, grows, next_size
    from skillcompose.evolve.genome import SkillSet
    from skillcompose.evolve.operators import initialize
    from skillcompose.evolve.state import RunState

    task = load_task("examples.toy_task", p_fail=0.3, tolerance=0.002)
    skills = SkillSet.from_task(task)
    run = RunState(task, GROWING, 0, skills, None, 1, {})
    for _ in range(GROWING.population):
        g = initialize(skills, run.rng, GROWING.initial_nodes)
        g.origin = {"uid": run.uid()}
        run.population.append(g)
    fitness = [3.0, 1.0, 2.0, 4.0, 5.0, 6.0, 7.0, 8.0]  # minimised: individual 1 is the best
    run.island_best = [(1.0, 0)]  # the best since generation 0
    run.generation = 1
    assert not grows(run) and next_size(run) == 8  # one generation without improvement
    run.generation = 2
    assert grows(run) and next_size(run) == 16  # two: the patience is spent
    best_code = run.population[1].encode()
    children = list(breed(run, fitness))
    assert len(children) == len(run.population) == 16 and run.restarts == 1
    assert children[0].origin["elite"] and children[0].encode() == best_code  # kept
    assert all(c.origin["ops"] == ["restart"] for c in children[1:])  # the rest afresh
    assert run.island_best == [(1.0, 3)] and not grows(run)  # patience counts again
    # restart_keep 0: each restart is an independent run (the run's best is kept apart)
    run.cfg = GROWING.replace(restart_keep=0)
    run.generation = 5
    children = list(breed(run, [1.0] * 16))
    assert len(children) == 24 and all(c.origin["ops"] == ["restart"] for c in children)


def test_a_run_restarts_when_it_stalls_and_grows_to_its_cap(
        straight: EvolutionResult) -> None:
    sizes = _sizes(straight)
    assert sizes[0] == 8 and max(sizes) == 24
    assert sizes == sorted(sizes) and set(sizes) == {8, 16, 24}
    best = [h.best for h in straight.history]
    for g in range(1, len(sizes)):
        if sizes[g] > sizes[g - 1]:  # a restart: no improvement for the last 2 generations
            assert min(best[:g - 1]) <= min(best[g - 2:g])
    # the best is carried over: the run's best never worsens across a restart
    assert all(best[g] <= min(best[:g]) for g in range(1, len(best))
               if sizes[g] > sizes[g - 1])


def test_restarts_are_the_same_run_on_a_pool(task: Task, straight: EvolutionResult) -> None:
    pool = evolve(task, GROWING, seed=3, backend="process", workers=2, **QUICK)
    assert _run(pool) == _run(straight)


def test_a_run_resumed_after_a_restart_is_the_straight_run(
        task: Task, straight: EvolutionResult, tmp_path: Path) -> None:
    sizes = _sizes(straight)
    after = next(g for g in range(1, len(sizes)) if sizes[g] == 24)  # after two restarts
    short = evolve(task, GROWING.replace(generations=after), seed=3, out_dir=tmp_path,
                   **QUICK)
    assert short.generations == after
    state = RunDir(tmp_path).load_checkpoint()
    assert state["restarts"] == 2 and len(state["population"]) == 24
    resumed = evolve(task, GROWING, resume=tmp_path)
    assert _run(resumed) == _run(straight)


def test_a_checkpoint_without_restarts_loads_as_none_so_far(
        task: Task, tmp_path: Path) -> None:
    from skillcompose.evolve.genome import SkillSet
    from skillcompose.evolve.state import RunState

    cfg = EvolutionConfig(population=4, initial_nodes=4, generations=1)
    evolve(task, cfg, seed=0, out_dir=tmp_path, **QUICK)
    older = RunDir(tmp_path).load_checkpoint()
    del older["restarts"]  # as written before restarts grew populations
    skills = SkillSet.from_task(task)
    again = RunState(task, cfg, 0, skills, None, 1, {})
    again.restore(older, "older")
    assert again.restarts == 0 and len(again.population) == 4
    grown = {**older, "restarts": 1}  # 4 individuals cannot follow a restart that grew them
    with pytest.raises(CheckpointError, match="population size 4 after 1 restarts"):
        RunState(task, cfg.replace(restart_patience=1, restart_growth=2), 0, skills, None,
                 1, {}).restore(grown, "grown")


def test_an_evaluation_budget_holds_across_a_restart(
        task: Task, straight: EvolutionResult, tmp_path: Path) -> None:
    sizes, jobs = _sizes(straight), _jobs(straight)
    g = next(g for g in range(1, len(sizes)) if sizes[g] > sizes[g - 1])  # a restart
    limit = jobs[g] - 1  # the restarted generation does not fit, its predecessors do
    stopped = evolve(task, GROWING.replace(max_evaluations=limit), seed=3, out_dir=tmp_path,
                     **QUICK)
    assert stopped.stopped_by == "evaluations" and stopped.generations == g - 1
    assert stopped.genome_evaluations == jobs[g - 1] <= limit
    extended = evolve(task, GROWING, resume=tmp_path)
    assert _run(extended) == _run(straight)


def test_an_episode_budget_holds_across_a_restart(
        task: Task, straight: EvolutionResult) -> None:
    sizes = _sizes(straight)
    g = next(g for g in range(1, len(sizes)) if sizes[g] > sizes[g - 1])
    limit = straight.history[g].total_evaluations - 1
    stopped = evolve(task, GROWING.replace(max_episodes=limit), seed=3, **QUICK)
    assert stopped.stopped_by == "episodes" and stopped.generations == g - 1
    assert stopped.episodes == straight.history[g - 1].total_evaluations <= limit


@pytest.mark.parametrize(("changes", "message"), [
    ({"restart_patience": 5, "islands": 2, "population": 20},
     "restarts the whole population, which islands = 2 split"),
    ({"restart_patience": 5, "restart_after": 5}, "two kinds of restart; give one"),
    ({"restart_patience": 5, "population_max": 100}, "population_max = 100 must be at least "
                                                     "population = 300"),
    ({"restart_growth": 0}, "restart_growth = 0: expected a whole number from 1"),
    ({"population_max": 1}, "population_max = 1: expected a whole number from 2"),
    ({"restart_patience": 5, "population": 10, "restart_keep": 10},
     "restart_keep = 10 must be smaller than population = 10"),
])
def test_bad_restart_settings_are_refused_with_the_fix(
        changes: dict[str, Any], message: str) -> None:
    with pytest.raises(EvolutionConfigError, match=message):
        EvolutionConfig(**changes)


def test_the_command_line_sets_restarts_and_the_default_uses_them() -> None:
    args = build_parser().parse_args(
        ["evolve", "examples.toy_task", "--preset", "paper", "--restart-patience", "40",
         "--restart-growth", "3", "--population-max", "900", "--restart-keep", "0"])
    cfg = _config(args)
    assert (cfg.restart_patience, cfg.restart_growth, cfg.population_max,
            cfg.restart_keep) == (40, 3, 900, 0)
    assert preset_settings("default", True) == PRESETS["adaptive"]
    assert PRESETS["adaptive"]["restart_patience"] > 0
    assert "restart_patience" not in PRESETS["paper"] and PRESETS["paper"] == {}
    assert EvolutionConfig().restart_patience == 0  # the paper's table 1: no restarts


def test_koza_effort_counts_the_individuals_a_growing_population_processed() -> None:
    root = Path(__file__).resolve().parents[2]
    sys.path.insert(0, str(root / "benchmarks"))
    try:
        import bench_search
    finally:
        sys.path.remove(str(root / "benchmarks"))
    bench = next(b for b in bench_search.BENCHES if b.name == "maze, sensing")

    def result(seed: int, solved_at: int | None, sizes: list[int]) -> Any:
        return bench_search.RunResult(bench.name, "adaptive", seed, solved_at is not None,
                                      solved_at, len(sizes) - 1, 100, 1.0, 30,
                                      [(g, 0.0, 10 * (g + 1)) for g in range(len(sizes))],
                                      sizes=sizes)

    # solved after 2 generations of 30 and 2 of 120: 300 individuals, not M (i + 1) = 120
    runs = [result(0, 3, [30, 30, 120, 120]), result(1, 1, [30, 30])]
    assert [bench_search.solved_individuals(r) for r in runs] == [300, 60]
    row = bench_search.summarise(bench, "adaptive", runs, 4000)
    assert row.effort == 300  # both solved within 300 individuals: P = 1
    assert bench_search.population_text(runs) == "30 to 120"
    # half solved within 60: 60 ceil(ln 0.01 / ln 0.5) = 60 * 7 = 420 > 300
    assert bench_search.effort_in_individuals([300, 60]) == 300
    assert bench_search.effort_in_individuals([None, 60]) == 420
    # a fixed population is Koza's M (i + 1) as before
    fixed = [bench_search.RunResult(bench.name, "d", s, True, g, 10, 100, 1.0, 30)
             for s, g in enumerate([3, 5])]
    assert bench_search.summarise(bench, "d", fixed, 10).effort == \
        bench_search.koza_effort([3, 5], 30, 10)[0] == 180
