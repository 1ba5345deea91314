"""Skill bias (``skill_bias``): a random node's skill drawn partly as often as an island's
best genomes use each skill. What the draw becomes, that 0 is the uniform draw and its random
stream, and that a run with it is the same on a pool and across resume."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from skillcompose.evolve import EvolutionConfig, EvolutionConfigError, EvolutionResult, evolve
from skillcompose.evolve.cli import _config, build_parser
from skillcompose.evolve.genome import Genome, Node, SkillSet
from skillcompose.task import Task, load_task

BIASED = EvolutionConfig(population=12, initial_nodes=6, generations=12, elitism=1,
                         cache=True, unique_children=True, skill_bias=0.5, checkpoint_every=1)
QUICK: dict[str, Any] = {"simplify_result": False, "check_trials": 0}


@pytest.fixture(scope="module")
def sensing() -> Task:
    return load_task("benchmarks.tasks.ant", trail="santa_fe", steps=100, form="sensing")


def _one_skill(skill: int, nodes: int) -> Genome:
    return Genome({k: Node(skill, [], []) for k in range(nodes)}, 0)


def _shares(skills: SkillSet, draws: int = 20_000) -> np.ndarray:
    rng = np.random.default_rng(1)
    counts = np.bincount([skills.draw(rng) for _ in range(draws)], minlength=len(skills))
    return counts / draws


def test_the_draw_leans_toward_what_the_best_use(sensing: Task) -> None:
    skills = SkillSet.from_task(sensing, pairs=True)  # FoodAhead, 3 actions, 3 pairs
    m = len(skills.drawable)
    assert m == 7
    uniform = _shares(skills)
    assert np.allclose(uniform, 1 / m, atol=0.01)
    # the best use Move+FoodAhead (choice 4) three times, TurnLeft (2) once
    skills.learn([_one_skill(4, 3), _one_skill(2, 1)], 0.5)
    expected = np.full(m, 0.5 / m)
    expected[4] += 0.5 * 3 / 4
    expected[2] += 0.5 * 1 / 4
    assert np.allclose(_shares(skills), expected, atol=0.01)
    # no share, or nothing drawable counted: the uniform draw and its very random stream
    for share, genomes in ((0.0, [_one_skill(4, 3)]), (0.5, [])):
        skills.learn(genomes, share)
        a, b = np.random.default_rng(7), np.random.default_rng(7)
        assert [skills.draw(a) for _ in range(50)] == [int(b.integers(m)) for _ in range(50)]


def test_only_drawable_choices_count(sensing: Task) -> None:
    skills = SkillSet.from_task(sensing, pairs=True, pairs_only=True)
    move = skills.index["Move"]  # a plain action a pair covers: not drawn with pairs_only
    assert move not in skills.drawable
    skills.learn([_one_skill(move, 5)], 0.9)  # counts nothing drawable: uniform
    assert np.allclose(_shares(skills)[list(skills.drawable)], 1 / len(skills.drawable),
                       atol=0.015)


@pytest.fixture(scope="module")
def straight(sensing: Task) -> EvolutionResult:
    return evolve(sensing, BIASED, seed=3, **QUICK)


def _run(r: EvolutionResult) -> tuple[object, ...]:
    return ([(h.generation, h.best, h.mean, h.best_size, h.total_evaluations)
             for h in r.history], r.best_fitness, r.evaluations, r.evolved_fsa)


def test_a_biased_run_differs_from_the_uniform_one_and_is_the_same_on_a_pool_and_resumed(
        sensing: Task, straight: EvolutionResult, tmp_path: Path) -> None:
    uniform = evolve(sensing, BIASED.replace(skill_bias=0.0), seed=3, **QUICK)
    assert _run(uniform) != _run(straight)  # the bias changes which skills are placed
    pool = evolve(sensing, BIASED, seed=3, backend="process", workers=2, **QUICK)
    assert _run(pool) == _run(straight)
    evolve(sensing, BIASED.replace(generations=5), seed=3, out_dir=tmp_path, **QUICK)
    assert _run(evolve(sensing, BIASED, resume=tmp_path)) == _run(straight)


@pytest.mark.parametrize("value", [-0.1, 1.0, 1.5])
def test_a_bias_outside_its_range_is_refused(value: float) -> None:
    with pytest.raises(EvolutionConfigError, match=f"skill_bias = {value}: expected a number "
                                                   "from 0 to below 1"):
        EvolutionConfig(skill_bias=value)


def test_the_command_line_sets_the_bias() -> None:
    args = build_parser().parse_args(["evolve", "examples.toy_task", "--skill-bias", "0.25"])
    assert _config(args).skill_bias == 0.25
