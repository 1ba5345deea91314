"""Vector parameters in the genome: every operator keeps them whole, files and seeds keep
them exact, and their mutation follows the paper's library (PyEvolve)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skillcompose import compile_fsa, dumps_fsa, loads_fsa
from skillcompose.evolve import (
    EvolutionConfig,
    Genome,
    GenomeCompiler,
    SkillSet,
    crossover,
    initialize,
    mutate,
    mutate_genes,
)
from skillcompose.task import Task, load_task

seeds = st.integers(min_value=0, max_value=2**32 - 1)


@pytest.fixture(scope="module", params=["layered", "recurrent"])
def push(request: pytest.FixtureRequest) -> Task:
    return load_task("examples.move_to_push", network=request.param, trials=2)


def _sound(g: Genome, skills: SkillSet, task: Task) -> None:
    assert g.problems(skills) == []
    for n in g.nodes.values():
        assert len(n.params) == skills.choices[n.skill].genes
    fsa = g.to_fsa(skills, step_limit=task.step_limit)
    assert fsa.check(task.registry) == []
    back = Genome.from_fsa(loads_fsa(dumps_fsa(fsa, registry=task.registry)), skills)
    for a, b in zip(back.key(), g.key(), strict=True):
        assert a[0] == b[0] and a[2] == b[2]
        assert np.allclose(a[1], b[1], atol=1e-12)  # written and read back exactly


@settings(max_examples=25, deadline=None)
@given(s1=seeds, s2=seeds)
def test_operators_keep_vector_genes_whole(push: Task, s1: int, s2: int) -> None:
    skills = SkillSet.from_task(push)
    n = push.registry.spec("MoveBase").param("weights").size
    assert skills.choices[skills.index["MoveBase"]].genes == n
    rng = np.random.default_rng(s1)
    g1, g2 = initialize(skills, rng, 12), initialize(skills, np.random.default_rng(s2), 12)
    cfg = EvolutionConfig(p_mut=0.5, p_add=0.5, p_del=0.2, param_sigma=0.3)
    for _ in range(3):
        crossover(g1, g2, skills, rng)
        for g in (g1, g2):
            mutate(g, skills, rng, cfg)
            _sound(g, skills, push)


def test_compiled_genomes_run_the_network(push: Task) -> None:
    skills = SkillSet.from_task(push)
    compiler = GenomeCompiler(push, skills)
    for seed in range(10):
        g = initialize(skills, np.random.default_rng(seed), 12)
        fast = compiler.compile(g)
        slow = compile_fsa(g.to_fsa(skills, step_limit=push.step_limit), push.registry)
        for trial in range(3):
            ra, rb = np.random.default_rng([seed, trial]), np.random.default_rng([seed, trial])
            bb_a, bb_b = push.setup(ra), push.setup(rb)
            a, b = fast.run(bb_a, ra), slow.run(bb_b, rb)
            assert (a.outcome, a.steps, a.error) == (b.outcome, b.steps, None)
            assert bb_a.get("base_pose_world") == bb_b.get("base_pose_world")


def test_few_genes_mutate_each_with_p_mut() -> None:
    """n * p_mut < 1: each gene on its own coin, as before vectors existed."""
    changed = []
    for seed in range(2000):
        genes = [0.5] * 3
        mutate_genes(genes, np.random.default_rng(seed), 0.1, 0.05)
        changed.append(sum(x != 0.5 for x in genes))
    assert 0.27 < np.mean(changed) < 0.33  # 3 genes x 0.1
    assert max(changed) >= 2  # independent coins: two genes at once happen


def test_many_genes_mutate_round_n_p_at_random() -> None:
    """n * p_mut >= 1: round(n * p_mut) genes drawn at random, as PyEvolve's real Gaussian
    list mutator did: 38 weights at p_mut 0.1 take 4 draws."""
    for seed in range(200):
        genes = [0.5] * 38
        mutate_genes(genes, np.random.default_rng(seed), 0.1, 0.05)
        assert 1 <= sum(x != 0.5 for x in genes) <= 4
        assert all(0.0 <= x <= 1.0 for x in genes)
    counts = []
    for seed in range(200):
        genes = [0.5] * 112
        mutate_genes(genes, np.random.default_rng(seed), 0.1, 0.05)
        counts.append(sum(x != 0.5 for x in genes))
    assert max(counts) == 11 and min(counts) >= 8  # round(11.2) draws, a few repeat


def test_seed_fsa_keeps_the_weights(tmp_path: Path, push: Task) -> None:
    skills = SkillSet.from_task(push)
    g = initialize(skills, np.random.default_rng(5), 12)
    path = tmp_path / "seed.yaml"
    path.write_text(dumps_fsa(g.to_fsa(skills), registry=push.registry))
    text = path.read_text()
    assert "weights: [" in text and "floats, each in [-3, 3]" in text
    seeded = Genome.from_fsa(loads_fsa(text, str(path)), skills)
    assert sorted(seeded.nodes) == sorted(g.reachable())  # ids come from the state names
    for k, node in seeded.nodes.items():
        assert node.params == pytest.approx(g.nodes[k].params, abs=1e-12)
