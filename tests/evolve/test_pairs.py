"""Pairs (``--pairs``): each action followed by each decision as one more choice of
evolution, exported as the two plain states. Which skills pair, what a pair's node runs and
exports, that every operator keeps pair genomes sound, and that a run with pairs is the same
on every backend."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from benchmarks.tasks import ant
from skillcompose import FSA, CompiledFSA, load_fsa, save_fsa
from skillcompose.cli import main
from skillcompose.evolve import EvolutionConfig, evolve
from skillcompose.evolve.errors import EvolutionConfigError
from skillcompose.evolve.genome import (
    Genome,
    GenomeCompiler,
    Node,
    SkillSet,
    is_action,
    is_decision,
)
from skillcompose.evolve.operators import crossover, initialize, mutate
from skillcompose.fsafile import MAX_STATES
from skillcompose.task import Task, load_task


@pytest.fixture(scope="module")
def sensing() -> Task:
    return load_task("benchmarks.tasks.ant", trail="john_muir", form="sensing")


def labels(skills: SkillSet) -> list[str]:
    """Each choice's skill, or ``Act+Decide`` for a pair."""
    return [c.name if c.then is None else f"{c.name}+{c.then.name}" for c in skills.choices]


def test_actions_that_only_report_done_pair_with_each_sensor(sensing: Task) -> None:
    plain = SkillSet.from_task(sensing)
    paired = SkillSet.from_task(sensing, pairs=True)
    assert labels(plain) == ["FoodAhead", "Move", "TurnLeft", "TurnRight"]
    assert labels(paired) == [*labels(plain), "Move+FoodAhead", "TurnLeft+FoodAhead",
                              "TurnRight+FoodAhead"]
    food = paired.choices[0]
    assert is_decision(food) and not is_action(food)
    for c in paired.choices[4:]:
        assert c.then is food and c.act is not None and is_action(c.act)
        assert c.outcomes == food.outcomes and c.fixed == food.fixed  # the sensor's edges
    # a name still means the plain skill (seed files, tests); the pairs have none
    assert paired.index == plain.index
    # a pair's node is two states in a file: half as many nodes fit
    assert paired.max_nodes <= MAX_STATES // 2 < plain.max_nodes


@pytest.mark.parametrize("module, settings", [
    ("benchmarks.tasks.ant", {"form": "reporting"}),  # every action reports: no actions
    ("benchmarks.tasks.lawnmower", {}),  # no sensor: no decisions
    ("benchmarks.tasks.maze", {"form": "reporting"}),
])
def test_tasks_without_actions_or_decisions_get_no_pairs(module: str,
                                                         settings: dict[str, str]) -> None:
    task = load_task(module, **settings)
    assert labels(SkillSet.from_task(task, pairs=True)) == labels(SkillSet.from_task(task))


def reporting_as_pairs(fsa: FSA, skills: SkillSet) -> Genome:
    """The reporting-form ``fsa`` as a genome of pairs: each state its action then
    FoodAhead, whose yes / no go where the state's food / empty went."""
    ids = {name: k for k, name in enumerate(fsa.states)}
    pair = {c.name: k for k, c in enumerate(skills.choices) if c.then is not None}
    yes, no = (skills.choices[pair["Move"]].outcomes.index(o) for o in ("yes", "no"))
    nodes = {}
    for name, st in fsa.states.items():
        edges = [skills.terminal_code("time_up")] * 3
        edges[yes], edges[no] = ids[st.transitions["food"]], ids[st.transitions["empty"]]
        nodes[ids[name]] = Node(pair[st.skill], [], edges)
    return Genome(nodes, ids[fsa.start])


@pytest.mark.parametrize("fsa", [ant.REFERENCE, ant.SOLUTION], ids=["reference", "solution"])
def test_a_genome_of_pairs_runs_and_exports_what_the_sensing_form_runs(
        sensing: Task, fsa: FSA, tmp_path: Path) -> None:
    skills = SkillSet.from_task(sensing, pairs=True)
    g = reporting_as_pairs(fsa, skills)
    assert g.problems(skills) == []
    compiler = GenomeCompiler(sensing, skills)
    exported = compiler.fsa(g)
    # two plain states per node, named by the node: the action's, then the sensor's
    assert len(exported.states) == 2 * len(fsa.states)
    assert {st.skill for st in exported.states.values()} <= set(sensing.skill_names())
    first = exported.states[exported.start]
    assert first.transitions == {"done": f"FoodAhead_{g.start}", "time_up": "time_up"}
    # the compiled genome, the exported FSA and the sensing form of the reporting FSA all
    # eat the same pellets (81 of the John Muir trail, or all 89)
    eaten = {fsa_fitness(sensing, compiled)
             for compiled in (compiler.compile(g), sensing.compile(exported),
                              sensing.compile(ant.sensing(fsa, ant.STEPS["john_muir"])))}
    assert eaten == {81.0 if fsa is ant.REFERENCE else 89.0}
    # the exported file reads back and seeds evolution as plain skills
    path = tmp_path / "pairs.fsa.yaml"
    save_fsa(exported, path)
    again = Genome.from_fsa(load_fsa(path), SkillSet.from_task(sensing))
    assert len(again.nodes) == 2 * len(fsa.states)
    assert fsa_fitness(sensing, GenomeCompiler(sensing, SkillSet.from_task(sensing)).compile(
        again)) in eaten


def fsa_fitness(task: Task, compiled: CompiledFSA) -> float:
    (_, fitness), = task.run_trials(compiled, 0, 1)
    return fitness


def test_every_operator_keeps_a_genome_with_pairs_sound(sensing: Task) -> None:
    skills = SkillSet.from_task(sensing, pairs=True)
    cfg = EvolutionConfig(p_mut=0.5, p_add=0.3, p_param=0.5, p_split=0.3)
    rng = np.random.default_rng(5)
    pool = [initialize(skills, rng, 8) for _ in range(6)]
    seen_pairs = 0
    for _ in range(300):
        a, b = (pool[int(i)].copy() for i in rng.integers(len(pool), size=2))
        if rng.random() < 0.5:
            crossover(a, b, skills, rng)
        child = a
        mutate(child, skills, rng, cfg)
        assert child.problems(skills) == []
        seen_pairs += sum(skills.choices[n.skill].then is not None
                          for n in child.nodes.values())
        assert len(GenomeCompiler(sensing, skills).fsa(child).states) == len(child) + sum(
            skills.choices[n.skill].then is not None for n in child.nodes.values())
        pool[int(rng.integers(len(pool)))] = child
    assert seen_pairs > 0


@pytest.mark.parametrize("backend, workers", [("process", 2)])
def test_a_run_with_pairs_is_the_same_on_every_backend(sensing: Task, backend: str,
                                                       workers: int) -> None:
    cfg = EvolutionConfig(population=12, generations=4, elitism=1, initial_nodes=6,
                          cache=True, pairs=True)
    serial = evolve(sensing, cfg, seed=3, backend="serial", simplify_result=False,
                    check_trials=0)
    other = evolve(sensing, cfg, seed=3, backend=backend, workers=workers,
                   simplify_result=False, check_trials=0)
    assert [h.best for h in other.history] == [h.best for h in serial.history]
    assert other.best_fsa.states == serial.best_fsa.states
    assert any("FoodAhead" in name for name in serial.best_fsa.states)


# -- pairs only (``--pairs-only``) -------------------------------------------------------------
def test_pairs_only_draws_the_pairs_in_place_of_the_actions_they_cover(sensing: Task) -> None:
    skills = SkillSet.from_task(sensing, pairs=True, pairs_only=True)
    assert labels(skills) == labels(SkillSet.from_task(sensing, pairs=True))  # names and files
    drawn = [labels(skills)[k] for k in skills.drawable]
    assert drawn == ["FoodAhead", "Move+FoodAhead", "TurnLeft+FoodAhead", "TurnRight+FoodAhead"]
    rng = np.random.default_rng(0)
    assert {skills.draw(rng) for _ in range(400)} == set(skills.drawable)
    for _ in range(20):  # nor does any operator place a covered action alone
        g = initialize(skills, rng, 12)
        mutate(g, skills, rng, EvolutionConfig(p_mut=1.0, p_add=1.0))
        assert all(skills.choices[n.skill].name == "FoodAhead"
                   or skills.choices[n.skill].then is not None for n in g.nodes.values())


@pytest.mark.parametrize("module, settings", [
    ("benchmarks.tasks.ant", {"form": "reporting"}),
    ("benchmarks.tasks.lawnmower", {}),
])
def test_pairs_only_changes_nothing_where_there_are_no_pairs(module: str,
                                                             settings: dict[str, str]) -> None:
    """A task with no pairs draws every skill, from the random stream it drew before."""
    task = load_task(module, **settings)
    skills = SkillSet.from_task(task, pairs=True, pairs_only=True)
    assert skills.drawable == tuple(range(len(skills)))
    a, b = np.random.default_rng(7), np.random.default_rng(7)
    assert [skills.draw(a) for _ in range(50)] == [int(b.integers(len(skills)))
                                                  for _ in range(50)]


def test_pairs_only_needs_pairs_and_has_a_flag(tmp_path: Path) -> None:
    with pytest.raises(EvolutionConfigError, match=r"pairs_only = True .* give pairs = True"):
        EvolutionConfig(pairs_only=True)
    out = tmp_path / "run"
    assert main(["evolve", "benchmarks.tasks.ant", "--set", "trail=santa_fe", "--set",
                 "form=sensing", "--pairs-only", "--generations", "2", "--seed", "1",
                 "--workers", "1", "--quiet", "--out", str(out)]) == 0
    config = json.loads((out / "run.json").read_text())["config"]
    assert config["pairs"] is True and config["pairs_only"] is True
