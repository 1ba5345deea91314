"""Drift stages between the growing ones (``drift_patience``): which stage drifts, its size
and patience, that it ranks the newer genome first at equal fitness, and that a run with
them is the same run on a pool and across resume."""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path
from typing import Any

import pytest

from skillcompose.evolve import EvolutionConfig, EvolutionConfigError, EvolutionResult, evolve
from skillcompose.evolve.cli import _config, build_parser
from skillcompose.task import Task

DRIFTING = EvolutionConfig(population=8, initial_nodes=6, generations=30, elitism=1,
                           cache=True, unique_children=True, restart_patience=2,
                           restart_growth=2, population_max=24, drift_patience=3,
                           checkpoint_every=1)
"""A toy run whose stages alternate: 8 growing, 8 drifting, 16, 8, 24 (the cap), 8, ..."""
QUICK: dict[str, Any] = {"simplify_result": False, "check_trials": 0}


@pytest.fixture(scope="module")
def straight(toy_hard: Task) -> EvolutionResult:
    return evolve(toy_hard, DRIFTING, seed=5, **QUICK)


def _run(r: EvolutionResult) -> tuple[object, ...]:
    return ([(h.generation, h.best, h.mean, h.best_size, h.total_evaluations, h.population)
             for h in r.history], r.best_fitness, r.evaluations, r.evolved_fsa)


def test_every_second_stage_drifts_with_the_first_size_and_its_own_patience() -> None:
    cfg = EvolutionConfig(population=30, restart_patience=100, restart_growth=4,
                          population_max=1920, drift_patience=400)
    assert [cfg.population_after(k) for k in range(10)] == [
        30, 30, 120, 30, 480, 30, 1920, 30, 1920, 30]
    assert [cfg.drifting(k) for k in range(4)] == [False, True, False, True]
    assert [cfg.patience_after(k) for k in range(4)] == [100, 400, 100, 400]
    plain = cfg.replace(drift_patience=0)  # without: every stage grows, none drifts
    assert [plain.population_after(k) for k in range(4)] == [30, 120, 480, 1920]
    assert not any(plain.drifting(k) for k in range(10))
    assert {plain.patience_after(k) for k in range(10)} == {100}


def test_a_drift_stage_ranks_the_newer_of_two_equals_first(toy_hard: Task) -> None:
    from skillcompose.evolve.breeding import breed
    from skillcompose.evolve.genome import SkillSet
    from skillcompose.evolve.operators import initialize
    from skillcompose.evolve.state import RunState

    skills = SkillSet.from_task(toy_hard)

    def elite(restarts: int) -> int:
        run = RunState(toy_hard, DRIFTING, 0, skills, None, 1, {})
        for _ in range(DRIFTING.population):
            g = initialize(skills, run.rng, DRIFTING.initial_nodes)
            g.origin = {"uid": run.uid()}
            run.population.append(g)
        run.restarts = restarts
        run.island_best = [(1.0, 0)]
        fitness = [1.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]  # 0 and 1 tie for the best
        kept = next(iter(breed(run, fitness)))  # the first child is the one elite
        return int(kept.origin["uid"])

    assert elite(0) == 0  # a growing stage keeps the first of equals
    assert elite(1) == 1  # a drift stage keeps the newer one
    assert elite(2) == 0


def test_a_drifting_run_alternates_its_stages(straight: EvolutionResult) -> None:
    sizes = [h.population for h in straight.history]
    stages = [sizes[0]] + [b for a, b in pairwise(sizes) if a != b]
    # growing 8, a drift stage of 8 (no change of size), 16, drift 8, 24, drift 8, ...
    assert stages[:5] == [8, 16, 8, 24, 8]
    assert straight.generations == DRIFTING.generations


def test_a_drifting_run_is_the_same_on_a_pool_and_across_resume(
        toy_hard: Task, straight: EvolutionResult, tmp_path: Path) -> None:
    pool = evolve(toy_hard, DRIFTING, seed=5, backend="process", workers=2, **QUICK)
    assert _run(pool) == _run(straight)
    sizes = [h.population for h in straight.history]
    after = next(g for g in range(1, len(sizes)) if sizes[g] == 24) + 1  # the fourth stage
    evolve(toy_hard, DRIFTING.replace(generations=after), seed=5, out_dir=tmp_path, **QUICK)
    assert _run(evolve(toy_hard, DRIFTING, resume=tmp_path)) == _run(straight)


@pytest.mark.parametrize(("changes", "message"), [
    ({"drift_patience": 50}, "drift_patience = 50 needs restart_patience"),
    ({"drift_patience": 50, "restart_patience": 10},
     "restart_growth = 1 grows nothing; give restart_growth of 2 or more"),
    ({"drift_patience": -1}, "drift_patience = -1: expected a whole number from 0"),
])
def test_bad_drift_settings_are_refused_with_the_fix(
        changes: dict[str, Any], message: str) -> None:
    with pytest.raises(EvolutionConfigError, match=message):
        EvolutionConfig(**changes)


def test_the_command_line_sets_the_drift_patience() -> None:
    args = build_parser().parse_args(
        ["evolve", "examples.toy_task", "--preset", "adaptive", "--drift-patience", "300"])
    assert _config(args).drift_patience == 300
