from __future__ import annotations

from pathlib import Path

import pytest

from skillcompose import (
    FSA,
    TIMEOUT,
    Blackboard,
    Registry,
    RegistryError,
    State,
    compile_fsa,
    save_fsa,
)
from tests.skillcompose import demo_skills

REACH = FSA(
    {
        "Recognise_1": State("Recognise", {}, {"success": "Move_2"}),
        "Move_2": State("MoveToObject", {"p_fail": 0.5},
                        {"success": "success", "failure": "Move_2"}),
    },
    start="Recognise_1",
    step_limit=6,
    name="MoveToReach",
)


def test_an_fsa_becomes_a_skill_sharing_the_blackboard(tmp_path: Path) -> None:
    reg = Registry.from_modules([demo_skills])
    path = save_fsa(REACH, tmp_path / "reach.fsa.yaml").path
    assert path is not None
    nested = reg.add_fsa(path)  # from a file, as the paper's stacking reuses MoveToReach
    assert nested.spec.outcomes == ("success", "failure")
    assert nested.spec.writes >= {"jug", "gripper"}
    stack = FSA(
        {
            "MoveToReach_1": State("MoveToReach", {}, {"success": "Grasp_2",
                                                        "failure": "MoveToReach_1"}),
            "Grasp_2": State("GraspObject", {}, {"success": "success", "failure": "failure"}),
        },
        start="MoveToReach_1",
        step_limit=10,
    )
    compiled = compile_fsa(stack, reg)
    outcomes = set()
    for seed in range(40):
        bb = Blackboard()
        result = compiled.run(bb, seed, trace=True)
        outcomes.add(result.outcome)
        if result.outcome == "success":
            assert bb["held"] == "left"  # the nested FSA's writes are seen by the parent
            assert result.trace is not None
            reached = [e for e in result.trace if e.state == "MoveToReach_1"][-1]
            assert reached.outcome == "success" and "gripper" in reached.changes
    # the nested step limit (6) is hit sometimes: mapped to the child's failure outcome
    assert "success" in outcomes


def test_nested_timeout_maps_to_failure_by_default() -> None:
    reg = Registry.from_modules([demo_skills])
    loop = FSA({"N": State("Noop", {}, {"success": "N"})}, "N", step_limit=3, name="Spin")
    reg.add_fsa(loop)
    parent = FSA({"S": State("Spin", {}, {"success": "success", "failure": "failure"})}, "S")
    result = compile_fsa(parent, reg).run(None, 0)
    assert (result.outcome, result.steps) == ("failure", 1)
    reg2 = Registry.from_modules([demo_skills])
    skill = reg2.add_fsa(loop.replace(terminals=("done",)).replace(
        states={"N": State("Noop", {}, {"success": "N"})}), on_timeout=TIMEOUT)
    assert skill.spec.outcomes == ("done", TIMEOUT)


def test_nested_errors_surface_in_the_parent() -> None:
    reg = Registry.from_modules([demo_skills])
    reg.add_fsa(FSA({"X": State("Explode", {}, {"success": "success"})}, "X", name="Boom"))
    parent = FSA({"B": State("Boom", {}, {"success": "success", "failure": "failure"})}, "B")
    result = compile_fsa(parent, reg).run(None, 0)
    assert result.outcome == "error" and result.last_state == "B"
    assert "motor fault" in str(result.error)


def test_a_nested_fsa_needs_a_name() -> None:
    reg = Registry.from_modules([demo_skills])
    with pytest.raises(RegistryError, match="needs an identifier name"):
        reg.add_fsa(REACH.replace(name=""))
