from __future__ import annotations

import numpy as np
import pytest

from skillcompose import (
    ERROR,
    FSA,
    TIMEOUT,
    Blackboard,
    FSAValidationError,
    Registry,
    State,
    UndeclaredOutcomeError,
    compile_fsa,
    run_fsa,
)
from skillcompose.executor import trial_rngs
from skillcompose.task import trials

POUR = FSA(
    {
        "Recognise_1": State("Recognise", {}, {"success": "Move_2"}),
        "Move_2": State("MoveToObject", {"approach": 0.2, "p_fail": 0.3},
                        {"success": "Grasp_3", "failure": "Move_2"}),
        "Grasp_3": State("GraspObject", {"force": 3, "arm": "right"},
                         {"success": "success", "failure": "Move_2"}),
    },
    start="Recognise_1",
    step_limit=20,
)


def test_runs_to_a_terminal_outcome(registry: Registry) -> None:
    bb = Blackboard()
    result = run_fsa(POUR, registry, bb, 1)
    assert result.outcome == "success"
    assert bb["held"] == "right"
    assert bb["gripper"] == pytest.approx((0.3, 0.0, 0.8))
    assert result.steps >= 3


def test_same_seed_same_outcome_sequence(registry: Registry) -> None:
    c = compile_fsa(POUR.with_params("Move_2", p_fail=0.6).replace(step_limit=5), registry)

    def sequence(seed: int) -> list[tuple[str, int]]:
        return [(r.outcome, r.steps) for r in (c.run(None, rng) for rng in trial_rngs(seed, 200))]

    a, b, other = sequence(7), sequence(7), sequence(8)
    assert a == b
    assert a != other
    assert {o for o, _ in a} == {"success", TIMEOUT}


def test_one_trial_loop_in_parts_or_whole(registry: Registry) -> None:
    """The trial loop gives trial k the same numbers whether it runs the whole range or a
    part (as a robustness worker does), and the same as drawing them by hand."""
    c = compile_fsa(POUR.with_params("Move_2", p_fail=0.6).replace(step_limit=5), registry)
    whole = [(t.number, t.result.outcome, t.result.steps) for t in trials(c, 7, 30)]
    parts = [(t.number, t.result.outcome, t.result.steps)
             for start, stop in ((0, 11), (11, 12), (12, 30))
             for t in trials(c, 7, stop - start, start=start)]
    assert whole == parts
    by_hand = [(k, *c.run(None, rng)[:2]) for k, rng in enumerate(trial_rngs(7, 30))]
    assert whole == by_hand


def test_trial_loop_catches_what_it_is_told_to(registry: Registry) -> None:
    c = compile_fsa(POUR, registry)

    def setup(rng: np.random.Generator) -> Blackboard:
        if rng.random() < 0.5:
            raise SystemExit("no world")
        return Blackboard()

    caught = list(trials(c, 0, 20, setup=setup, catch=lambda e: isinstance(e, SystemExit),
                         worst=99.0, score=lambda r, bb: 1.0))
    assert {(t.result.outcome, t.fitness) for t in caught} == {(ERROR, 99.0), ("success", 1.0)}
    assert all(isinstance(t.result.error, SystemExit) for t in caught if t.fitness == 99.0)
    with pytest.raises(SystemExit):
        list(trials(c, 0, 20, setup=setup))


def test_timeout_after_step_limit(registry: Registry) -> None:
    loop = FSA({"A": State("Noop", {}, {"success": "A"})}, "A", step_limit=7)
    result = run_fsa(loop, registry, None, 0)
    assert (result.outcome, result.steps) == (TIMEOUT, 7)


def test_error_outcome_and_propagation(registry: Registry) -> None:
    fsa = FSA({"N": State("Noop", {}, {"success": "X"}),
               "X": State("Explode", {}, {"success": "success"})}, "N")
    result = run_fsa(fsa, registry, None, 0)
    assert result.outcome == ERROR
    assert result.last_state == "X"
    assert isinstance(result.error, RuntimeError)
    assert "motor fault" in result.format_error()
    with pytest.raises(RuntimeError, match="motor fault"):
        run_fsa(fsa, registry, None, 0, propagate=True)
    traced = run_fsa(fsa, registry, None, 0, trace=True)
    assert traced.outcome == ERROR and traced.trace is not None
    assert [e.state for e in traced.trace] == ["N", "X"]


def test_undeclared_outcome_is_an_error_naming_the_skill(registry: Registry) -> None:
    fsa = FSA({"L": State("Liar", {}, {"success": "success"})}, "L")
    result = run_fsa(fsa, registry, None, 0)
    assert isinstance(result.error, UndeclaredOutcomeError)
    assert "skill Liar returned 'sucess'" in str(result.error)


def test_access_violation_during_a_run(registry: Registry) -> None:
    fsa = FSA({"S": State("Sneaky", {}, {"success": "success"})}, "S")
    result = run_fsa(fsa, registry, Blackboard({"jug": 1}), 0)
    assert result.outcome == ERROR
    assert "skill Sneaky wrote" in str(result.error)


def test_trace_records_diffs(registry: Registry) -> None:
    result = run_fsa(POUR.with_params("Move_2", p_fail=0.0), registry, None, 0, trace=True)
    assert result.trace is not None
    steps = [(e.state, e.outcome, e.target) for e in result.trace]
    assert steps == [("Recognise_1", "success", "Move_2"), ("Move_2", "success", "Grasp_3"),
                     ("Grasp_3", "success", "success")]
    assert set(result.trace[0].changes) == {"jug"}
    assert result.trace[2].changes["held"][1] == "right"


def test_trace_and_fast_modes_agree(registry: Registry) -> None:
    c = compile_fsa(POUR.with_params("Move_2", p_fail=0.5), registry)
    for seed in range(50):
        fast = c.run(Blackboard(), seed)
        traced = c.run(Blackboard(), seed, trace=True)
        assert (fast.outcome, fast.steps, fast.last_state) == \
            (traced.outcome, traced.steps, traced.last_state)


def test_validation_lists_every_problem(registry: Registry) -> None:
    bad = FSA(
        {
            "A": State("Nope", {}, {"success": "B"}),
            "B": State("MoveToObject", {"approach": 9.0, "speed": 1},
                       {"success": "success", "sucess": "B"}),
        },
        "A",
    )
    with pytest.raises(FSAValidationError) as info:
        compile_fsa(bad, registry)
    text = str(info.value)
    assert "5 problems" in text
    assert "unknown skill 'Nope'" in text
    assert "outcome 'failure' of skill MoveToObject has no transition" in text
    assert "add `failure: <state or success/failure>` under B.transitions" in text
    assert "'sucess' is not an outcome of skill MoveToObject" in text
    assert "approach" in text and "between 0.05 and 0.3" in text
    assert "no parameter 'speed'" in text


def test_structure_checked_at_construction() -> None:
    with pytest.raises(FSAValidationError, match="start state 'Z' does not exist"):
        FSA({"A": State("Noop", {}, {"success": "success"})}, "Z")
    with pytest.raises(FSAValidationError, match=r"goes to 'Bb'.*did you mean 'B'"):
        FSA({"A": State("Noop", {}, {"success": "Bb"}),
             "B": State("Noop", {}, {"success": "success"})}, "A")
    with pytest.raises(FSAValidationError, match="cannot be named 'success'"):
        FSA({"success": State("Noop", {}, {"success": "success"})}, "success")
    with pytest.raises(FSAValidationError, match="step_limit"):
        FSA({"A": State("Noop", {}, {"success": "success"})}, "A", step_limit=0)


def test_unreachable_and_pruned(registry: Registry) -> None:
    fsa = POUR.with_state("Orphan_9", State("Noop", {}, {"success": "Move_2"}))
    assert fsa.unreachable() == ["Orphan_9"]
    assert set(fsa.pruned().states) == set(POUR.states)
    compile_fsa(fsa, registry)  # unreachable states are allowed, only reported


def test_class_skill_instance_is_reused(registry: Registry) -> None:
    c = compile_fsa(POUR, registry)
    impl = registry.resolve("GraspObject")
    before = impl.bind().calls  # type: ignore[attr-defined]
    c.run(None, 0)
    c.run(None, 1)
    assert impl.bind().calls > before  # type: ignore[attr-defined]


def test_blackboard_free_of_client_after_run(registry: Registry) -> None:
    bb = Blackboard()
    run_fsa(POUR, registry, bb, 0)
    bb["anything"] = 1  # no skill's access restriction lingers
    assert np.isclose(bb["anything"], 1)
