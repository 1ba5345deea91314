from __future__ import annotations

import itertools
import os
import re
from pathlib import Path
from types import ModuleType

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


def _chain(tmp_path: Path) -> tuple[str, str]:
    """reach.yaml (MoveToReach, demo skills) and fetch.yaml (Fetch, using MoveToReach)."""
    reach = save_fsa(REACH, tmp_path / "reach.yaml").path
    fetch = save_fsa(_using("MoveToReach", "Fetch"), tmp_path / "fetch.yaml").path
    assert reach is not None and fetch is not None
    return str(reach), str(fetch)


def _using(skill: str, name: str) -> FSA:
    """An FSA called ``name`` of one state running ``skill``."""
    return FSA({"S_1": State(skill, {}, {"success": "success", "failure": "failure"})},
               start="S_1", name=name)


def test_nested_fsa_files_load_in_the_order_their_nesting_needs(tmp_path: Path) -> None:
    reach, fetch = _chain(tmp_path)
    orders: list[list[str | ModuleType]] = [[demo_skills, reach, fetch],
                                            [fetch, reach, demo_skills]]
    for order in orders:
        reg = Registry.from_modules(order)
        assert {"MoveToReach", "Fetch"} <= set(reg)
    again = os.path.relpath(reach)  # one file named two ways is loaded once
    assert {"MoveToReach", "Fetch"} <= set(Registry.from_modules([demo_skills, reach, again,
                                                                  fetch]))


def test_nested_fsa_files_in_a_circle_or_using_themselves_are_one_line(tmp_path: Path) -> None:
    _, fetch = _chain(tmp_path)
    loop = save_fsa(_using("Fetch", "Loop"), tmp_path / "loop.yaml").path
    circle = save_fsa(_using("Loop", "MoveToReach"), tmp_path / "reach.yaml").path
    assert loop is not None and circle is not None
    with pytest.raises(RegistryError) as err:
        Registry.from_modules([demo_skills, fetch, str(loop), str(circle)])
    assert "use each other in a circle: an FSA cannot contain itself" in str(err.value)
    names = re.findall(r"\((\w+)\)", str(err.value))  # each uses the next
    uses = {"Fetch": "MoveToReach", "MoveToReach": "Loop", "Loop": "Fetch"}
    assert len(names) == 4 and all(uses[a] == b for a, b in itertools.pairwise(names))
    itself = save_fsa(_using("MoveToReach", "MoveToReach"), tmp_path / "self.yaml")
    with pytest.raises(RegistryError, match=r"self.yaml: the FSA MoveToReach uses itself"):
        Registry.from_modules([demo_skills, str(itself.path)])


def test_an_fsa_file_named_like_a_skill_is_refused(tmp_path: Path) -> None:
    """Else it became another backend of that skill, which its own states could run: a
    recursion."""
    clash = save_fsa(REACH.replace(name="MoveToObject"), tmp_path / "clash.yaml").path
    with pytest.raises(RegistryError) as err:
        Registry.from_modules([demo_skills, str(clash)])
    assert str(err.value) == (f"{clash}: the FSA's name MoveToObject is a skill already; an "
                              "FSA used as a skill needs a name of its own: rename it (its "
                              "`name:`)")


def test_an_fsa_file_without_a_usable_name_says_which_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    text = save_fsa(REACH, bad).path
    assert text is not None
    bad.write_text(bad.read_text().replace("name: MoveToReach", "name: move to reach"))
    with pytest.raises(RegistryError) as err:
        Registry.from_modules([demo_skills, str(bad)])
    assert str(err.value).startswith(f"{bad}:5:1: an FSA file used as a skill needs a `name:`")


def test_fsas_nested_past_the_limit_are_refused_and_the_limit_runs() -> None:
    """Past the limit the run ran out of Python's stack ("unexpected RecursionError")."""
    from skillcompose.nested import MAX_NESTING

    reg = Registry.from_modules([demo_skills])
    reg.add_fsa(FSA({"S_1": State("Recognise", {}, {"success": "success"})}, start="S_1",
                    name="L1"))
    inner = "L1"
    for level in range(2, MAX_NESTING + 1):
        reg.add_fsa(_using(inner, f"L{level}"))
        inner = f"L{level}"
    top = _using(inner, "Top")
    assert compile_fsa(top, reg).run(Blackboard(), 0).outcome == "success"
    with pytest.raises(RegistryError, match=rf"the FSA Top nests FSAs {MAX_NESTING + 1} deep, "
                       rf"more than the {MAX_NESTING} a run can hold"):
        reg.add_fsa(top)


def test_a_circle_closed_by_replacing_a_skill_is_one_line_not_a_recursion() -> None:
    from skillcompose import fsa_skill

    reg = Registry.from_modules([demo_skills])
    reg.add_fsa(_using("Recognise", "Sub").replace(states={"S_1": State(
        "Recognise", {}, {"success": "success"})}))
    reg.add_fsa(_using("Sub", "Top"))
    reg.add(fsa_skill(_using("Top", "Sub"), reg), replace=True)  # Sub now runs Top
    with pytest.raises(RegistryError, match=r"FSA skill \w+: its nested FSAs run one another "
                       r"in a circle: an FSA cannot contain itself"):
        compile_fsa(_using("Top", "Outer"), reg).run(Blackboard(), 0)
