"""Every way of running an FSA is one engine: run-to-completion (``outcome``, ``run``), traced,
tick-wise, time-limited, and programs compiled from genomes agree on outcome, steps, fitness
and trace, over random FSAs and seeds."""

from __future__ import annotations

import itertools
from collections.abc import Generator
from typing import Annotated, Any, Literal, cast

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from skillcompose import (
    FSA,
    RUNNING,
    Blackboard,
    CompiledFSA,
    Param,
    Registry,
    RunResult,
    Skill,
    State,
    compile_fsa,
    skill,
)
from skillcompose.evolve import GenomeCompiler, SkillSet
from skillcompose.evolve.operators import initialize
from skillcompose.task import Task

KEYS = {"x": float, "n": int}


@skill(reads=("x",), writes=KEYS)
def nudge(
    bb: Blackboard, rng: np.random.Generator, *,
    by: Annotated[float, Param(-1.0, 1.0)] = 0.5,
) -> Literal["up", "down", "same"]:
    bb["x"] = bb.get("x", 0.0) + by * float(rng.random())
    bb["n"] = bb.get("n", 0) + 1
    r = rng.random()
    return "up" if r < 0.4 else "down" if r < 0.8 else "same"


@skill(reads=("x",), writes={"x": float})
def coin(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    return "success" if rng.random() < 0.5 else "failure"


@skill(reads=("x",))
def fragile(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    if rng.random() < 0.1:
        raise RuntimeError("fragile broke")
    return "success" if bb.get("x", 0.0) > 0 else "failure"


@skill(reads=("x",), writes=KEYS)
class Count:
    """A class skill with state across calls."""

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self, bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
        self.calls += 1
        bb["n"] = bb.get("n", 0) + 1
        return "success" if rng.random() < 0.7 else "failure"


@skill(reads=("x",), writes=KEYS)
class Spin:
    """Long-running: start / tick."""

    def start(self, bb: Blackboard, rng: np.random.Generator, *,
              ticks: Annotated[int, Param(1, 4)] = 2) -> None:
        self.left = ticks

    def tick(self, bb: Blackboard, rng: np.random.Generator
             ) -> Literal["running", "success", "failure"]:
        self.left -= 1
        bb["x"] = bb.get("x", 0.0) - float(rng.random())
        if self.left > 0:
            return RUNNING
        return "success" if bb["x"] < 1.0 else "failure"


@skill(reads=("x",), writes=KEYS)
def crawl(
    bb: Blackboard, rng: np.random.Generator, *, ticks: Annotated[int, Param(1, 3)] = 2
) -> Generator[str, None, Literal["success", "failure"]]:
    for _ in range(ticks - 1):
        bb["n"] = bb.get("n", 0) + 1
        yield RUNNING
    return "success" if rng.random() < 0.6 else "failure"


# mypy ignores class decorators: the classes Count and Spin are Skills
SKILLS: list[Skill] = [nudge, coin, fragile, cast(Skill, Count), cast(Skill, Spin), crawl]


def fitness(outcome: str, bb: Blackboard, steps: int) -> float:
    return abs(bb.get("x", 0.0)) + 0.1 * bb.get("n", 0) + steps + (outcome != "success")


def setup(rng: np.random.Generator) -> Blackboard:
    return Blackboard({"x": float(rng.normal())})


def make_task(registry: Registry, step_limit: int) -> Task:
    return Task("modes", registry, setup, fitness, step_limit=step_limit, error_fitness=99.0)


@st.composite
def random_fsas(draw: st.DrawFn) -> FSA:
    registry = Registry(SKILLS)
    n = draw(st.integers(1, 6))
    names = [f"S{k}" for k in range(n)]
    targets = st.sampled_from([*names, "success", "failure"])
    states = {}
    for name in names:
        skill_name = draw(st.sampled_from(registry.names()))
        spec = registry.spec(skill_name)
        params = {p.name: draw(st.sampled_from([p.low, p.high])) for p in spec.params}
        states[name] = State(skill_name, params, {o: draw(targets) for o in spec.outcomes})
    return FSA(states, "S0", step_limit=draw(st.integers(1, 25)))


def _signature(result: RunResult, task: Task, bb: Blackboard) -> tuple[Any, ...]:
    return (result.outcome, result.steps, result.last_state, task.score(result, bb))


def _trace(result: RunResult) -> list[tuple[Any, ...]]:
    assert result.trace is not None
    return [(s.step, s.state, s.skill, s.outcome, s.target, dict(s.changes)) for s in result.trace]


def all_modes(compiled: CompiledFSA, task: Task, seed: int) -> None:
    """Run ``compiled`` every way on the same world and generator; all must agree."""
    results: dict[str, tuple[Any, ...]] = {}
    traces: dict[str, list[tuple[Any, ...]]] = {}

    def fresh() -> tuple[Blackboard, np.random.Generator]:
        rng = np.random.default_rng(seed)
        return setup(rng), rng

    bb, rng = fresh()
    try:
        outcome, steps = compiled.outcome(bb, rng)
        results["outcome"] = (outcome, steps)
    except RuntimeError:
        results["outcome"] = ("error", None)
    for name, trace in (("run", False), ("traced", True)):
        bb, rng = fresh()
        res = compiled.run(bb, rng, trace=trace)
        results[name] = (*_signature(res, task, bb), bb.to_dict())
        if trace:
            traces[name] = _trace(res)
    limited = dict.fromkeys(compiled.names, 60.0)
    for name, limits, trace in (("ticked", None, False), ("ticked, traced", None, True),
                                ("time-limited", limited, True)):
        bb, rng = fresh()
        run = compiled.start(bb, rng, trace=trace, time_limits=limits)
        ticks = 0
        while run.tick() == RUNNING:
            ticks += 1
            assert ticks < 10_000_000
        results[name] = (*_signature(run.result, task, bb), bb.to_dict())
        if trace:
            traces[name] = _trace(run.result)
        if limits is None:  # run() counts the ticks it takes as tick() would
            bb, rng = fresh()
            whole = compiled.start(bb, rng, trace=trace)
            whole.run()
            assert whole.ticks == run.ticks == ticks + 1, name
    first = results["run"]
    assert results["outcome"][0] == first[0]
    if first[0] != "error":
        assert results["outcome"][1] == first[1]
    for name, got in results.items():
        if name != "outcome":
            assert got == first, name
    for name, got_trace in traces.items():
        assert got_trace == traces["traced"], name
    traced = traces["traced"]
    assert [s[0] for s in traced] == list(range(1, first[1] + 1))  # one record per step
    assert traced[0][1] == compiled.fsa.start
    for before, after in itertools.pairwise(traced):
        assert before[4] == after[1]  # each step's target is the next step's state
    if first[0] == "timeout":  # the step limit: the run stops before the next state
        assert first[1] == compiled.step_limit and traced[-1][4] == first[2]
    else:  # a terminal outcome, or the error of the last state
        assert (traced[-1][1], traced[-1][4]) == (first[2], first[0])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(fsa=random_fsas(), seed=st.integers(0, 2**32 - 1))
def test_every_engine_mode_agrees_on_random_fsas(fsa: FSA, seed: int) -> None:
    registry = Registry(SKILLS)
    compiled = compile_fsa(fsa, registry)
    all_modes(compiled, make_task(registry, fsa.step_limit), seed)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(nodes=st.integers(1, 8), gseed=st.integers(0, 2**32 - 1), seed=st.integers(0, 2**32 - 1),
       step_limit=st.integers(1, 25))
def test_genome_compiled_programs_agree_with_compile_fsa(
    nodes: int, gseed: int, seed: int, step_limit: int
) -> None:
    registry = Registry(SKILLS)
    task = make_task(registry, step_limit)
    skills = SkillSet.from_task(task)
    g = initialize(skills, np.random.default_rng(gseed), nodes)
    compiler = GenomeCompiler(task, skills)
    program = compiler.compile(g)
    reference = compile_fsa(compiler.fsa(g), registry)
    assert program.names == reference.names
    all_modes(program, task, seed)
    for compiled in (program, reference):
        rng = np.random.default_rng(seed)
        bb = setup(rng)
        res = compiled.run(bb, rng, trace=True)
        if compiled is program:
            expected = (_signature(res, task, bb), _trace(res))
        else:
            assert (_signature(res, task, bb), _trace(res)) == expected
