"""Tick-wise execution: agreement with run-to-completion, preemption, wall-clock limits."""

from __future__ import annotations

import threading
from collections.abc import Generator
from typing import Literal

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skillcompose import (
    FSA,
    RUNNING,
    Blackboard,
    ParamError,
    Registry,
    SkillDefinitionError,
    State,
    compile_fsa,
    run_ticking,
    skill,
)
from skillcompose.errors import SkillProtocolError
from skillcompose.skill import GeneratorSkill, TickingSkill

from .mixed_skills import Calls, as_skill, make_registry, mixed_fsa


@pytest.fixture
def calls() -> Calls:
    return Calls()


@pytest.fixture
def registry(calls: Calls) -> Registry:
    """The mixed skills (in place of the package conftest's demo registry)."""
    return make_registry(calls)


def test_decorator_reads_long_running_declarations(registry: Registry) -> None:
    move, wait = registry.resolve("Move"), registry.resolve("Wait")
    assert isinstance(move, TickingSkill) and isinstance(wait, GeneratorSkill)
    assert move.spec.outcomes == ("success", "failure")  # "running" is not an outcome
    assert move.spec.param_names == ("n",) and wait.spec.param_names == ("n",)
    assert move.spec.reads == {"count"} and move.spec.writes == {"pos"}
    assert move.long_running and not registry.resolve("Bump").long_running


def test_long_running_skill_called_directly_runs_to_completion(registry: Registry) -> None:
    bb = Blackboard()
    out = registry.resolve("Move")(bb, 0, n=4)
    assert out in ("success", "failure")
    assert bb["pos"] == pytest.approx(4.0, abs=1.0)  # four ticks of ~1.0 each


def test_bad_long_running_declarations_are_rejected() -> None:
    with pytest.raises(SkillDefinitionError, match="tick must be"):
        @skill
        class BadTick:
            def start(self, bb: Blackboard, rng: np.random.Generator) -> None: ...
            def tick(self, bb: Blackboard) -> Literal["running", "success"]:
                return "success"
    with pytest.raises(SkillDefinitionError, match="defines both"):
        @skill
        class NoStart:
            def tick(self, bb: Blackboard, rng: np.random.Generator
                     ) -> Literal["running", "success"]:
                return "success"
    with pytest.raises(SkillDefinitionError, match="'running' cannot be an outcome"):
        skill(outcomes=("success", "running"), name="Lazy")(lambda bb, rng: "success")


def test_generator_yielding_an_outcome_is_a_protocol_error() -> None:
    @skill(outcomes=("success",))
    def sloppy(bb: Blackboard, rng: np.random.Generator) -> Generator[str, None, str]:
        yield "success"  # should be `return "success"`
        return "success"

    fsa = FSA({"S": State("Sloppy", {}, {"success": "success"})}, "S")
    res = run_ticking(compile_fsa(fsa, Registry([sloppy])), Blackboard(), 0)
    assert res.outcome == "error" and isinstance(res.error, SkillProtocolError)
    assert "yielded 'success'" in str(res.error)


@pytest.mark.parametrize("nested", [False, True])
def test_tickwise_and_run_to_completion_agree(registry: Registry, nested: bool) -> None:
    fsa = mixed_fsa()
    if nested:
        registry.add_fsa(mixed_fsa("Inner"))
        fsa = FSA(
            {
                "First": State("Bump", {}, {"success": "In", "failure": "failure"}),
                "In": State("Inner", {}, {"success": "success", "failure": "First"}),
            },
            "First", step_limit=6,
        )
    compiled = compile_fsa(fsa, registry)
    outcomes = set()
    longer = 0
    for seed in range(40):
        bb1, bb2 = Blackboard(), Blackboard()
        whole = compiled.run(bb1, seed, trace=True)
        run = compiled.start(bb2, seed, trace=True)
        ticked = run.run()
        assert ticked == whole  # outcome, steps, last state and the whole trace
        assert bb1.to_dict() == bb2.to_dict()
        assert compiled.run(Blackboard(), seed) == run_ticking(compiled, Blackboard(), seed)
        assert run.ticks >= run.steps
        longer += run.ticks > run.steps  # a long-running skill took several ticks
        outcomes.add(whole.outcome)
    assert outcomes >= {"success"} and len(outcomes) >= 2  # the seeds exercise several ends
    assert longer >= 20


def test_instant_skills_take_one_tick_per_step(registry: Registry) -> None:
    fsa = FSA({"A": State("Bump", {}, {"success": "A", "failure": "success"})}, "A",
              step_limit=30)
    compiled = compile_fsa(fsa, registry)
    for seed in range(10):
        run = compiled.start(Blackboard(), seed, trace=True)
        while run.tick() == RUNNING:
            pass
        assert run.ticks == run.steps == run.result.steps
        assert run.result == compiled.run(Blackboard(), seed, trace=True)


def _preempt_at(registry: Registry, fsa: FSA, seed: int, k: int) -> tuple:
    compiled = compile_fsa(fsa, registry)
    bb = Blackboard()
    run = compiled.start(bb, seed)
    for _ in range(k):
        if run.tick() != RUNNING:
            break
    was_running = not run.done
    act = run._act  # a nested FSA is active while one of its states is: look inside
    while act is not None and hasattr(act, "run"):
        act = act.run._act
    was_active = act is not None  # a user skill's activation is between ticks
    state = run.state
    result = run.preempt()
    return run, bb, was_running, was_active, state, result


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**16), k=st.integers(0, 40), nested=st.booleans())
def test_preemption_cancels_the_running_skill_exactly_once(
    seed: int, k: int, nested: bool
) -> None:
    calls = Calls()
    registry = make_registry(calls)
    fsa = mixed_fsa()
    if nested:
        registry.add_fsa(mixed_fsa("Inner"))
        fsa = FSA({"In": State("Inner", {}, {"success": "success", "failure": "In"})},
                  "In", step_limit=4)
    run, bb, was_running, was_active, state, result = _preempt_at(registry, fsa, seed, k)
    total = sum(calls.cancels.values())
    if not was_running:  # ended before the preemption: nothing to cancel
        assert total == 0 and result.outcome != "preempted"
        return
    assert result.outcome == "preempted" and result.last_state == state
    assert total == (1 if was_active else 0)
    for name, key in (("Move", "pos"), ("Wait", "waited")):
        if calls.cancels.get(name):
            assert bb[key] == -1  # the cancel hook ran and its write stayed
    assert bb._client is None
    run.preempt()
    assert run.tick() == "preempted" and sum(calls.cancels.values()) == total


def test_nested_preemption_reaches_the_inner_skill(registry: Registry, calls: Calls) -> None:
    registry.add_fsa(mixed_fsa("Inner"))
    outer = FSA({"In": State("Inner", {}, {"success": "success", "failure": "failure"})},
                "In")
    run = compile_fsa(outer, registry).start(Blackboard(), 3)
    ticks = 0
    while "pos" not in run.bb or run.bb["pos"] == 0.0:  # until Move inside Inner runs
        assert run.tick() == RUNNING
        ticks += 1
    inner_act = run._act
    assert inner_act is not None and inner_act.run.state == "B"  # type: ignore[attr-defined]
    result = run.preempt()
    assert result.outcome == "preempted" and result.last_state == "In"
    assert inner_act.run.result.outcome == "preempted"  # type: ignore[attr-defined]
    assert calls.cancels == {"Move": 1} and run.bb["pos"] == -1.0


def test_preempt_records_a_trace_step(registry: Registry) -> None:
    run = compile_fsa(mixed_fsa(), registry).start(Blackboard(), 0, trace=True)
    while not run.active:
        run.tick()
    result = run.preempt()
    assert result.trace is not None
    last = result.trace[-1]
    assert (last.outcome, last.target, last.state) == ("preempted", "preempted", run.state)


# -- wall-clock limits -----------------------------------------------------------------------
class FakeClock:
    """Each call advances one second: limits are deterministic in tests."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        self.t += 1.0
        return self.t


def _hanging_registry(calls: Calls, with_timeout_outcome: bool) -> Registry:
    outs = ("success", "timeout") if with_timeout_outcome else ("success",)

    @skill(outcomes=outs, writes=("stuck",))
    class Stuck:
        def start(self, bb: Blackboard, rng: np.random.Generator) -> None:
            bb["stuck"] = 0

        def tick(self, bb: Blackboard, rng: np.random.Generator) -> str:
            bb["stuck"] += 1
            return "running"  # never finishes

        def cancel(self, bb: Blackboard) -> None:
            calls.cancel("Stuck")

    @skill(writes=("done",))
    def finish(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
        bb["done"] = True
        return "success"

    return Registry([as_skill(Stuck), finish])


@pytest.mark.parametrize("routed", [False, True])
def test_hanging_long_running_skill_is_stopped_by_its_time_limit(
    calls: Calls, routed: bool
) -> None:
    reg = _hanging_registry(calls, routed)
    tr = {"success": "success", "timeout": "Finish"} if routed else {"success": "success"}
    fsa = FSA({"Hang": State("Stuck", {}, tr),
               "Finish": State("Finish", {}, {"success": "failure"})}, "Hang")
    run = compile_fsa(fsa, reg).start(Blackboard(), 0, time_limits={"Hang": 2.5},
                                      clock=FakeClock(), trace=True)
    res = run.run(max_ticks=100)
    assert calls.cancels == {"Stuck": 1}
    # started at t=1 s, ticked at t=2 and t=3, stopped at t=4 (3 s > 2.5 s) before ticking
    assert run.bb["stuck"] == 3
    if routed:  # the skill declares `timeout`: the state's transition is taken
        assert (res.outcome, res.steps, run.bb["done"]) == ("failure", 2, True)
        assert res.trace is not None and res.trace[0].outcome == "timeout"
    else:
        assert (res.outcome, res.steps, res.last_state) == ("timeout", 1, "Hang")


def test_hanging_blocking_skill_runs_in_a_thread_and_is_abandoned() -> None:
    release = threading.Event()
    cancels: list[str] = []

    @skill(writes=("late",), outcomes=("success",))
    class Blocking:
        def __call__(self, bb: Blackboard, rng: np.random.Generator) -> str:
            release.wait(10.0)  # a driver call that hangs
            bb["late"] = True
            rng.random()
            return "success"

        def cancel(self, bb: Blackboard) -> None:
            cancels.append("Blocking")
            release.set()  # tell the hung call to give up

    fsa = FSA({"B": State("Blocking", {}, {"success": "success"})}, "B")
    bb = Blackboard({"before": 1})
    rng = np.random.default_rng(5)
    state = rng.bit_generator.state
    run = compile_fsa(fsa, Registry([as_skill(Blocking)])).start(bb, rng, time_limits={"B": 0.1})
    res = run.run(period=0.005)
    assert (res.outcome, res.last_state) == ("timeout", "B")
    assert cancels == ["Blocking"]
    for t in threading.enumerate():  # let the abandoned thread finish its late write
        if t.name == "skillcompose-Blocking":
            t.join(5.0)
    assert bb.to_dict() == {"before": 1}  # its late write went to its private copy
    assert rng.bit_generator.state == state  # and it drew from a copy of the generator


def test_threaded_skill_that_finishes_in_time_matches_the_inline_run(
    registry: Registry,
) -> None:
    fsa = mixed_fsa()
    compiled = compile_fsa(fsa, registry)
    for seed in range(5):
        whole = compiled.run(Blackboard(), seed, trace=True)
        run = compiled.start(Blackboard(), seed, trace=True, time_limits={"A": 30.0})
        assert run.run(period=0.001) == whole


def test_time_limit_errors_name_the_state(registry: Registry) -> None:
    compiled = compile_fsa(mixed_fsa(), registry)
    with pytest.raises(ParamError, match="no state 'Q'"):
        compiled.start(time_limits={"Q": 1.0})
    with pytest.raises(ParamError, match="state A: the limit must be a positive"):
        compiled.start(time_limits={"A": -1})


def test_result_while_running_is_an_error(registry: Registry) -> None:
    run = compile_fsa(mixed_fsa(), registry).start(Blackboard(), 0)
    with pytest.raises(SkillProtocolError, match="still running"):
        _ = run.result



def test_preemption_at_every_tick_covers_active_idle_and_finished_runs() -> None:
    seen = {"active": 0, "idle": 0, "finished": 0}
    for seed in range(6):
        for k in range(0, 14):
            calls = Calls()
            reg = make_registry(calls)
            _, _, running, _, _, result = _preempt_at(reg, mixed_fsa(), seed, k)
            total = sum(calls.cancels.values())
            if not running:
                seen["finished"] += 1
                assert total == 0
            elif total == 1:
                seen["active"] += 1
                assert result.outcome == "preempted"
            else:
                seen["idle"] += 1
                assert total == 0 and result.outcome == "preempted"
    assert min(seen.values()) >= 5, seen


@pytest.mark.parametrize("traced", [False, True])
def test_a_long_running_skill_that_exits_between_ticks_ends_the_run_in_error(
    traced: bool,
) -> None:
    """sys.exit() in a later tick of a long-running skill (the tick-wise engine's fast path)
    ends the run in error, saying where, before the exit goes on to the caller."""
    import sys

    @skill
    def Quit(bb: Blackboard, rng: np.random.Generator) -> Generator[
            str, None, Literal["success"]]:
        yield RUNNING
        sys.exit(3)

    reg = Registry()
    reg.add(Quit)
    fsa = FSA(states={"Q": State("Quit", transitions={"success": "success"})}, start="Q")
    run = compile_fsa(fsa, reg).start(Blackboard(), np.random.default_rng(0), trace=traced)
    assert run.tick() == RUNNING
    with pytest.raises(SystemExit):
        run.tick()
    assert run.done and run.result.outcome == "error"
    assert isinstance(run.result.error, SystemExit) and run.result.error.code == 3
