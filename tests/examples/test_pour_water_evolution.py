"""A short evolution of the pour-water task solves it (small population, fixed seed)."""

from __future__ import annotations

import pytest

from skillcompose.evolve import EvolutionConfig, evolve
from skillcompose.robustness import robustness_sweep
from skillcompose.task import load_task

TASK = "examples.pour_water"


@pytest.mark.slow  # a few seconds
def test_short_evolution_solves_pouring_water() -> None:
    task = load_task(TASK, p_fail=0.2)
    cfg = EvolutionConfig(
        population=150, initial_nodes=12, elitism=2, common_random_numbers=True,
        param_sigma=0.1, generations=200,
    )
    result = evolve(task, cfg, seed=0, simplify_result=False)
    assert result.solved and result.best_fitness == 0.0
    assert result.generations < 200
    fsa = result.evolved_fsa
    assert {"GraspObject", "MoveGripperToParam", "RotateGripperToParam"} <= set(
        fsa.skills_used()
    )
    # what evolution found pours the water in fresh worlds too, not only in the one it met
    (row,) = robustness_sweep(fsa, TASK, [0.2], reps=300, seed=123)
    assert row.solved_rate > 0.0
