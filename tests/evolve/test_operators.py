"""Property tests: from random genomes, every operator keeps the genome's invariants."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skillcompose import Blackboard, compile_fsa
from skillcompose.evolve import (
    EvolutionConfig,
    Genome,
    GenomeCompiler,
    SkillSet,
    add_node,
    change_start,
    crossover,
    delete_node,
    initialize,
    mutate,
    mutate_node,
)
from skillcompose.evolve.rundir import MAX_DRAWN_STATES
from skillcompose.task import Task

seeds = st.integers(min_value=0, max_value=2**32 - 1)
sizes = st.integers(min_value=1, max_value=30)
weights = st.sampled_from([0.0, 0.5, 1.0, 3.0])


def _random(
    skills: SkillSet, seed: int, size: int, weight: float
) -> tuple[Genome, np.random.Generator]:
    rng = np.random.default_rng(seed)
    g = initialize(skills, rng, size, weight)
    assert g.problems(skills) == []
    return g, rng


def _sound(g: Genome, skills: SkillSet, toy: Task) -> None:
    assert g.problems(skills) == []
    fsa = g.to_fsa(skills, step_limit=toy.step_limit)
    assert fsa.check(toy.registry) == []
    assert fsa.unreachable() == []
    back = Genome.from_fsa(fsa, skills).key()
    assert [(a[0], a[2]) for a in back] == [(b[0], b[2]) for b in g.key()]
    for a, b in zip(back, g.key(), strict=True):  # parameters survive units and back, to rounding
        assert np.allclose(a[1], b[1], atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(seed=seeds, size=sizes, weight=weights)
def test_initialize_prunes_and_is_sound(
    toy: Task, toy_skills: SkillSet, seed: int, size: int, weight: float
) -> None:
    g, _ = _random(toy_skills, seed, size, weight)
    assert 1 <= len(g) <= size
    _sound(g, toy_skills, toy)


@settings(max_examples=80, deadline=None)
@given(seed=seeds, size=sizes, weight=weights, op=st.sampled_from(["add", "delete", "start"]))
def test_graph_mutations_keep_invariants(
    toy: Task, toy_skills: SkillSet, seed: int, size: int, weight: float, op: str
) -> None:
    g, rng = _random(toy_skills, seed, size, weight)
    for _ in range(5):
        n = len(g)
        if op == "add":
            added = add_node(g, toy_skills, rng, weight)
            if added:
                assert g.next_id - 1 in g.nodes or len(g) <= n  # new node, unless pruned
        elif op == "delete":
            deleted = delete_node(g, toy_skills, rng, weight)
            assert deleted == (n > 1)
            if deleted:
                assert len(g) < n
        else:
            old = g.start
            if change_start(g, rng):
                assert g.start != old
                node = g.nodes[g.start]
                assert any(t != g.start for t in node.edges)
        _sound(g, toy_skills, toy)


@settings(max_examples=80, deadline=None)
@given(seed=seeds, size=sizes, weight=weights, p=st.sampled_from([0.0, 0.1, 0.5, 1.0]))
def test_node_mutations_keep_invariants(
    toy: Task, toy_skills: SkillSet, seed: int, size: int, weight: float, p: float
) -> None:
    g, rng = _random(toy_skills, seed, size, weight)
    for k in list(g.nodes):
        if k in g.nodes:
            before = g.nodes[k].copy()
            kind = mutate_node(g, k, toy_skills, rng, p, 0.3, weight)
            after = g.nodes[k]
            if kind == "node":  # one edge re-routed elsewhere (when another target exists)
                pairs = zip(before.edges, after.edges, strict=True)
                assert sum(a != b for a, b in pairs) <= 1
                assert after.skill == before.skill
            assert all(0.0 <= x <= 1.0 for x in after.params)
    g.prune()
    _sound(g, toy_skills, toy)
    cfg = EvolutionConfig(p_mut=p, p_add=0.5, p_del=0.5)
    for _ in range(3):
        mutate(g, toy_skills, rng, cfg)
        _sound(g, toy_skills, toy)


@settings(max_examples=80, deadline=None)
@given(s1=seeds, s2=seeds, n1=sizes, n2=sizes, weight=weights)
def test_crossover_keeps_invariants(
    toy: Task, toy_skills: SkillSet, s1: int, s2: int, n1: int, n2: int, weight: float
) -> None:
    g1, rng = _random(toy_skills, s1, n1, weight)
    g2, _ = _random(toy_skills, s2, n2, weight)
    skills_before = sorted(n.skill for n in g1.nodes.values()) + sorted(
        n.skill for n in g2.nodes.values())
    swapped = crossover(g1, g2, toy_skills, rng, weight)
    assert swapped >= 1
    _sound(g1, toy_skills, toy)
    _sound(g2, toy_skills, toy)
    assert len(skills_before) >= len(g1) + len(g2)  # crossover adds no node; pruning removes


def test_crossover_swaps_subgraphs_and_rewires(toy: Task, toy_skills: SkillSet) -> None:
    """Two chains of distinct skills: a 1-node swap exchanges skills at the chosen places."""
    s = toy_skills.index
    from skillcompose.evolve import Node

    g1 = Genome({0: Node(s["FindBlock"], [], [1]), 1: Node(s["PickBlock"], [], [-1, -2])}, 0)
    g2 = Genome({0: Node(s["Wait"], [0.5], [1]), 1: Node(s["PutDown"], [], [-1, -2])}, 0)
    rng = np.random.default_rng(3)
    crossover(g1, g2, toy_skills, rng)
    all_skills = sorted(n.skill for n in (*g1.nodes.values(), *g2.nodes.values()))
    assert g1.problems(toy_skills) == [] and g2.problems(toy_skills) == []
    # a swap exchanges nodes between the genomes: the multiset of skills is kept when
    # nothing was pruned, and each child holds at least one node of the other parent
    assert {s["Wait"], s["PutDown"]} & {n.skill for n in g1.nodes.values()}
    assert len(all_skills) <= 4


def test_genome_compiles_to_the_same_runs_as_compile_fsa(toy: Task, toy_skills: SkillSet) -> None:
    compiler = GenomeCompiler(toy, toy_skills)
    for seed in range(20):
        g, _ = _random(toy_skills, seed, 15, 1.0)
        fast = compiler.compile(g)
        slow = compile_fsa(g.to_fsa(toy_skills, step_limit=toy.step_limit), toy.registry)
        for trial in range(5):
            rng_a, rng_b = np.random.default_rng(trial), np.random.default_rng(trial)
            bb_a, bb_b = toy.setup(rng_a), toy.setup(rng_b)
            ra, rb = fast.run(bb_a, rng_a), slow.run(bb_b, rng_b)
            assert (ra.outcome, ra.steps, ra.last_state) == (rb.outcome, rb.steps, rb.last_state)
            assert {k: bb_a[k] for k in bb_a} == {k: bb_b[k] for k in bb_b}


def test_random_genomes_run(toy: Task, toy_skills: SkillSet) -> None:
    compiler = GenomeCompiler(toy, toy_skills)
    g, _ = _random(toy_skills, 1, 50, 1.0)
    res = compiler.compile(g).run(Blackboard({"p_fail": 0.0, "block_m": 0.0,
                                              "holding": False, "placed": False}), 0)
    assert res.outcome in ("success", "failure", "timeout")
    assert res.error is None


BAD_SEED = (  # an unknown skill in A, PickBlock's failure unrouted in B
    "format: 1\nstart: A\nstates:\n  A:\n    skill: Fly\n    transitions: {success: B}\n"
    "  B:\n    skill: PickBlock\n    transitions: {success: success}\n"
)


def test_seed_fsa_errors_name_the_state(toy_skills: SkillSet) -> None:
    from skillcompose import loads_fsa
    from skillcompose.evolve import SeedFSAError

    with pytest.raises(SeedFSAError) as err:
        Genome.from_fsa(loads_fsa(BAD_SEED, "bad.yaml"), toy_skills)
    msg = str(err.value)
    assert "bad.yaml:4" in msg and "state A" in msg and "'Fly'" in msg
    assert "failure" in msg and "state B" in msg  # the unrouted outcome of PickBlock


def test_a_seed_fsas_transition_on_an_outcome_its_skill_lacks_is_refused(
    toy_skills: SkillSet,
) -> None:
    """A typo'd outcome (``faliure``) would otherwise vanish from the evolved file."""
    from skillcompose import loads_fsa
    from skillcompose.evolve import SeedFSAError

    text = ("format: 1\nname: t\nstart: A\nterminals: [success, failure]\nstates:\n"
            "  A:\n    skill: PickBlock\n    transitions:\n      success: success\n"
            "      faliure: A\n      failure: failure\n")
    with pytest.raises(SeedFSAError) as err:
        Genome.from_fsa(loads_fsa(text, "typo.yaml"), toy_skills)
    assert str(err.value) == (
        "cannot seed evolution from this FSA:\n  typo.yaml:10:16: state A: 'faliure' is not an "
        "outcome of skill PickBlock (its outcomes are ['success', 'failure']); remove it or "
        "rename it to one of ['success', 'failure']")


def test_a_seed_fsas_timeout_transition_is_refused_as_validate_refuses_it(
    toy_skills: SkillSet,
) -> None:
    """validate accepts ``timeout:`` only for a skill that declares it; the seed check
    took it for any state with a time limit, and the edge vanished from the evolved file."""
    from skillcompose import loads_fsa
    from skillcompose.evolve import SeedFSAError

    text = ("format: 1\nname: t\nstart: A\nterminals: [success, failure]\nstates:\n"
            "  A:\n    skill: PickBlock\n    time_limit: 5\n    transitions:\n"
            "      success: success\n      failure: failure\n      timeout: failure\n")
    with pytest.raises(SeedFSAError, match=r"state A: 'timeout' is not an outcome of skill "
                       r"PickBlock"):
        Genome.from_fsa(loads_fsa(text, "t.yaml"), toy_skills)


def test_seed_fsa_errors_keep_one_problem_per_line(toy_skills: SkillSet) -> None:
    from skillcompose import loads_fsa
    from skillcompose.errors import printable
    from skillcompose.evolve import SeedFSAError

    with pytest.raises(SeedFSAError) as err:
        Genome.from_fsa(loads_fsa(BAD_SEED, "bad\n  seed\x1b.yaml"), toy_skills)
    lines = printable(err.value).split("\n")
    assert lines[0] == "cannot seed evolution from this FSA:" and len(lines) == 3
    assert all(line.startswith("  bad\\n  seed\\x1b.yaml:") for line in lines[1:])
    assert all(line.isprintable() for line in lines)



def test_seed_fsa_parameters_are_checked_as_the_model_checks_them(
    toy: Task, toy_skills: SkillSet
) -> None:
    from skillcompose import FSAValidationError, loads_fsa
    from skillcompose.evolve import SeedFSAError

    text = (
        "format: 1\nstart: A\nstates:\n  A:\n    skill: Carry\n"
        "    params: {distance: 7.0, speed: 1}\n"
        "    transitions: {success: success, failure: failure}\n"
    )
    fsa = loads_fsa(text, "seed.yaml")
    with pytest.raises(FSAValidationError) as model:
        fsa.validate(toy.registry)
    with pytest.raises(SeedFSAError) as genome:
        Genome.from_fsa(fsa, toy_skills)
    said = str(genome.value)
    for problem in model.value.problems:  # the same words, each at its line
        assert f"seed.yaml:{problem.line}:{problem.column}: {problem.render()}" in said


@settings(max_examples=40, deadline=None)
@given(seed=seeds, size=sizes)
def test_terminating_skills_alone_end_runs(toy: Task, seed: int, size: int) -> None:
    """With terminal_skills set (the paper's model), only those skills' outcomes reach a
    terminal, through initialisation, mutation and crossover alike."""
    import dataclasses

    skills = SkillSet.from_task(dataclasses.replace(toy, terminal_skills=("PutDown",)))
    cfg = EvolutionConfig(population=2, p_mut=0.5, p_add=0.5, p_del=0.5)
    rng = np.random.default_rng(seed)
    g1 = initialize(skills, rng, size)
    g2 = initialize(skills, rng, size)
    for _ in range(5):
        mutate(g1, skills, rng, cfg)
        crossover(g1, g2, skills, rng)
    for g in (g1, g2):
        assert g.problems(skills) == []
        for n in g.nodes.values():
            c = skills.choices[n.skill]
            for o, t in enumerate(n.edges):
                assert (t < 0) == (c.name == "PutDown"), (c.name, c.outcomes[o], t)


def _start_leads_on(g: Genome) -> bool:
    return any(t >= 0 and t != g.start for t in g.nodes[g.start].edges)


def _has_candidate(g: Genome) -> bool:
    return any(any(t >= 0 and t != k for t in n.edges) for k, n in g.nodes.items())


def test_no_initial_genome_starts_at_a_lone_terminating_skill() -> None:
    """Pour water, as the paper: CheckSuccess ends every run it runs in. A genome that starts
    there is one state long whatever its other nodes; before the fix about 17 % of initial
    genomes did."""
    from skillcompose import load_task

    skills = SkillSet.from_task(load_task("examples.pour_water"))
    rng = np.random.default_rng(0)
    genomes = [initialize(skills, rng, 12) for _ in range(300)]
    assert all(_start_leads_on(g) for g in genomes if _has_candidate(g))
    assert sum(_has_candidate(g) for g in genomes) > 290  # the property is not vacuous


@settings(max_examples=60, deadline=None)
@given(s1=seeds, s2=seeds, n1=sizes, n2=sizes)
def test_mutation_and_crossover_rechoose_a_start_left_without_a_way_on(
    toy: Task, toy_skills: SkillSet, s1: int, s2: int, n1: int, n2: int
) -> None:
    cfg = EvolutionConfig(p_mut=0.6, p_add=0.5, p_del=0.5)
    g1, rng = _random(toy_skills, s1, n1, 1.0)
    g2, _ = _random(toy_skills, s2, n2, 1.0)
    for _ in range(4):
        crossover(g1, g2, toy_skills, rng)
        for g in (g1, g2):
            assert _start_leads_on(g) or not _has_candidate(g)
            mutate(g, toy_skills, rng, cfg)
            assert _start_leads_on(g) or not _has_candidate(g)
            _sound(g, toy_skills, toy)


def test_a_start_rewired_to_loop_on_itself_is_rechosen(toy_skills: SkillSet) -> None:
    from skillcompose.evolve import Node, fix_start

    s = toy_skills.index
    g = Genome({0: Node(s["FindBlock"], [], [0]), 1: Node(s["PickBlock"], [], [2, 1]),
                2: Node(s["PutDown"], [], [-1, -2])}, 0)
    assert fix_start(g, np.random.default_rng(0))
    assert g.start == 1
    g.prune()
    assert sorted(g.nodes) == [1, 2]  # the old start, unreachable now, is pruned
    assert not fix_start(g, np.random.default_rng(0))


def test_a_node_mutation_that_strands_the_start_moves_it(toy_skills: SkillSet) -> None:
    """FindBlock -> PickBlock -> PutDown: re-routing the start's only edge onto itself used
    to leave a one-state genome after pruning; now the start moves to PickBlock."""
    from skillcompose.evolve import Node

    s = toy_skills.index
    cfg = EvolutionConfig(p_mut=0.3, p_add=0.0, p_del=0.0)
    stranded = 0
    for seed in range(300):
        g = Genome({0: Node(s["FindBlock"], [], [1]), 1: Node(s["PickBlock"], [], [2, 2]),
                    2: Node(s["PutDown"], [], [-1, -2])}, 0)
        rng = np.random.default_rng(seed)
        ops = mutate(g, toy_skills, rng, cfg)
        stranded += "fix-start" in ops
        assert _start_leads_on(g) or not _has_candidate(g), (seed, ops, g.nodes)
        assert len(g) >= 2 or not _has_candidate(g)
    assert stranded > 5  # the case happened


def test_genome_compiled_programs_also_run_tick_by_tick(toy: Task, toy_skills: SkillSet) -> None:
    """A compiled genome is a whole CompiledFSA: its tick-wise run (used for long-running
    skills and time limits) gives the run-to-completion result. It used to raise in zip()."""
    compiler = GenomeCompiler(toy, toy_skills)
    for seed in range(10):
        g, _ = _random(toy_skills, seed, 15, 1.0)
        compiled = compiler.compile(g)
        for trial in range(3):
            rng_a, rng_b = np.random.default_rng(trial), np.random.default_rng(trial)
            a = compiled.run(toy.setup(rng_a), rng_a)
            b = compiled.start(toy.setup(rng_b), rng_b).run()
            assert (a.outcome, a.steps, a.last_state) == (b.outcome, b.steps, b.last_state)


@settings(max_examples=60, deadline=None)
@given(seed=seeds, size=sizes, weight=weights)
def test_a_split_sends_every_free_outcome_of_the_new_node_where_the_taken_edge_led(
    toy: Task, toy_skills: SkillSet, seed: int, size: int, weight: float
) -> None:
    g, rng = _random(toy_skills, seed, size, weight)
    before = {k: list(n.edges) for k, n in g.nodes.items()}
    if not add_node(g, toy_skills, rng, weight, split=True):
        return
    new = g.next_id - 1
    (src, o), = [(k, i) for k, edges in before.items() if k in g.nodes
                 for i, t in enumerate(edges) if g.nodes[k].edges[i] != t]
    assert g.nodes[src].edges[o] == new  # the one edge changed: it leads to the new node
    choice = toy_skills.choices[g.nodes[new].skill]
    for i, t in enumerate(g.nodes[new].edges):
        fixed = choice.fixed_edge(i)
        assert t == (before[src][o] if fixed is None else fixed)
    _sound(g, toy_skills, toy)


def test_p_split_zero_never_splits_and_one_always_splits(toy_skills: SkillSet) -> None:
    """``p_split`` 0 (the paper's) adds nodes with random edges only; 1 makes every added
    node a split."""
    from skillcompose.evolve import EvolutionConfig

    paper, split = EvolutionConfig(p_add=1.0), EvolutionConfig(p_add=1.0, p_split=1.0)
    kinds: dict[str, set[str]] = {"paper": set(), "split": set()}
    for seed in range(30):
        for name, cfg in (("paper", paper), ("split", split)):
            g, rng = _random(toy_skills, seed, 8, 1.0)
            kinds[name] |= {op for op in mutate(g, toy_skills, rng, cfg) if op in ("add", "split")}
    assert kinds == {"paper": {"add"}, "split": {"split"}}


def test_genomes_never_outgrow_what_an_fsa_file_holds() -> None:
    """An FSA file holds at most MAX_STATES states and MAX_VALUES values: initialisation and
    the add mutation stop at ``SkillSet.max_nodes``."""
    from skillcompose.fsafile import MAX_STATES
    from skillcompose.task import load_task

    skills = SkillSet.from_task(load_task("examples.toy_task", p_fail=0.1))
    assert skills.max_nodes == MAX_STATES  # small skills: the states bound it
    push = SkillSet.from_task(load_task("examples.move_to_push"))
    assert push.max_nodes < MAX_STATES  # a network's weights: the values bound it
    rng = np.random.default_rng(0)
    small = SkillSet(skills.choices, skills.terminals)
    small.max_nodes = 6
    assert len(initialize(small, rng, 50).nodes) <= 6
    g = initialize(small, rng, 6)
    while add_node(g, small, rng):
        pass
    assert len(g.nodes) <= 6
    small.max_nodes = len(g.nodes)
    before = g.copy()
    assert not add_node(g, small, rng) and g.key() == before.key()


@pytest.mark.slow
def test_a_run_of_huge_genomes_exports_a_file_that_loads(tmp_path: Path) -> None:
    """A run with 1500 initial nodes and p_add 1 exported a best.yaml of 969 states, which
    load_fsa refused."""
    from skillcompose import load_fsa
    from skillcompose.evolve import EvolutionConfig, evolve
    from skillcompose.task import load_task

    task = load_task("examples.toy_task", p_fail=0.1)
    cfg = EvolutionConfig(population=2, generations=1, initial_nodes=1500, p_add=1.0)
    result = evolve(task, cfg, seed=1, out_dir=tmp_path / "run", check_trials=0,
                    simplify_result=False)
    assert len(load_fsa(tmp_path / "run" / "best.yaml").states) == len(result.best_fsa.states)
    # too many states to draw legibly: no best.png (nor in the files the run lists), the DOT
    # text still written
    assert len(result.best_fsa.states) > MAX_DRAWN_STATES
    assert not (tmp_path / "run" / "best.png").exists()
    assert (tmp_path / "run" / "best.dot").exists()
    assert [f.name for f in result.files if f.suffix == ".png"] == ["fitness.png"]

