"""The py_trees bridge: FSA and skill behaviours, tree skills, one blackboard story."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Literal

import numpy as np
import py_trees
import pytest
from py_trees.common import Status

from skillcompose import FSA, Blackboard, Registry, State, compile_fsa, skill
from skillcompose.bt import BridgeError, FSABehaviour, SkillBehaviour, tree_skill

from .mixed_skills import Calls, make_registry, mixed_fsa


@pytest.fixture
def calls() -> Calls:
    return Calls()


@pytest.fixture
def registry(calls: Calls) -> Registry:
    """The mixed skills (in place of the package conftest's demo registry)."""
    return make_registry(calls)


@pytest.fixture(autouse=True)
def clean_py_trees_blackboard() -> Iterator[None]:
    """py_trees' blackboard is process-global: start and end every test with it empty."""
    py_trees.blackboard.Blackboard.clear()
    yield
    py_trees.blackboard.Blackboard.clear()


def tick_until_done(root: py_trees.behaviour.Behaviour, limit: int = 100) -> int:
    tree = py_trees.trees.BehaviourTree(root)
    tree.setup()
    for n in range(1, limit + 1):
        tree.tick()
        if root.status != Status.RUNNING:
            return n
    raise AssertionError(f"{root.name} still running after {limit} ticks")


def test_fsa_behaviour_runs_the_fsa_tick_by_tick(registry: Registry) -> None:
    compiled = compile_fsa(mixed_fsa(), registry)
    fb = FSABehaviour(compiled, seed=7)
    statuses = []
    tree = py_trees.trees.BehaviourTree(fb)
    tree.setup()
    while fb.status != Status.SUCCESS and fb.status != Status.FAILURE:
        tree.tick()
        statuses.append(fb.status)
    assert statuses[:-1] == [Status.RUNNING] * (len(statuses) - 1)
    res = fb.last_result
    assert res is not None and fb.fsa_run is not None
    assert len(statuses) == fb.fsa_run.ticks  # one FSA tick per tree tick
    # the same run as run-to-completion with the first child seed of the behaviour's seed
    rng = np.random.default_rng(np.random.SeedSequence(7).spawn(1)[0])
    assert compiled.run(Blackboard(), rng) == res
    assert fb.status == (Status.SUCCESS if res.outcome == "success" else Status.FAILURE)


def test_status_map_is_user_set_and_checked(registry: Registry) -> None:
    always_fails = FSA({"A": State("Bump", {}, {"success": "failure", "failure": "failure"})},
                       "A", name="f")
    fb = FSABehaviour(always_fails, registry, status_map={"failure": "SUCCESS"})
    tick_until_done(fb)
    assert fb.status == Status.SUCCESS and fb.last_result.outcome == "failure"  # type: ignore[union-attr]
    with pytest.raises(BridgeError, match="never ends with"):
        FSABehaviour(always_fails, registry, status_map={"spilled": Status.FAILURE})
    with pytest.raises(BridgeError, match=r"use Status\.SUCCESS"):
        FSABehaviour(always_fails, registry, status_map={"failure": Status.RUNNING})


def test_terminate_preempts_the_fsa_and_cancels_its_skill_once(
    registry: Registry, calls: Calls
) -> None:
    fb = FSABehaviour(mixed_fsa("pick"), registry, seed=1)
    # a higher-priority guard that becomes true later interrupts the FSA (selector w/o memory)
    stop = py_trees.behaviours.CheckBlackboardVariableExists(name="Stop?",
                                                             variable_name="/stop")
    root = py_trees.composites.Selector("Root", memory=False, children=[stop, fb])
    tree = py_trees.trees.BehaviourTree(root)
    tree.setup()
    while not (fb.fsa_run is not None and fb.fsa_run.active):
        tree.tick()
    assert fb.status == Status.RUNNING
    py_trees.blackboard.Blackboard.set("/stop", True)
    tree.tick()
    assert fb.status == Status.INVALID and root.status == Status.SUCCESS
    assert fb.last_result is not None and fb.last_result.outcome == "preempted"
    assert sum(calls.cancels.values()) == 1
    assert "preempted in state" in fb.feedback_message
    tree.tick()
    assert sum(calls.cancels.values()) == 1  # never cancelled twice


def test_fsa_keys_are_shared_with_the_tree_in_a_namespace(registry: Registry) -> None:
    """Tree → FSA: the FSA reads `count` set by the tree; FSA → tree: it writes `pos`."""
    seed_count = py_trees.behaviours.SetBlackboardVariable(
        name="Count=10", variable_name="/pick/count", variable_value=10, overwrite=True)
    other = py_trees.behaviours.SetBlackboardVariable(
        name="Other", variable_name="/pick/undeclared", variable_value=1, overwrite=True)
    fb = FSABehaviour(mixed_fsa("pick"), registry, seed=2)
    root = py_trees.composites.Sequence("Root", memory=True, children=[seed_count, other, fb])
    tick_until_done(root)
    bb = fb.fsa_blackboard
    assert bb["count"] >= 11  # started from the tree's 10, Bump added to it
    storage = py_trees.blackboard.Blackboard.storage
    assert storage["/pick/count"] == bb["count"]
    assert "pos" in bb  # Move ran
    for key in ("pos", "waited"):
        if key in bb:
            assert storage[f"/pick/{key}"] == bb[key]
    assert "undeclared" not in bb  # only declared keys cross
    with pytest.raises(AttributeError, match="write access"):
        fb.bridge.client.set("/pick/undeclared", 2)  # py_trees enforces the other side


def test_key_map_and_namespace_checks(registry: Registry) -> None:
    fb = FSABehaviour(mixed_fsa("pick"), registry, key_map={"pos": "/world/arm_pos"})
    assert fb.bridge.names["pos"] == "/world/arm_pos"
    assert fb.bridge.names["count"] == "/pick/count"
    with pytest.raises(BridgeError, match="neither reads nor writes"):
        FSABehaviour(mixed_fsa("pick"), registry, key_map={"nope": "/x"})
    with pytest.raises(BridgeError, match="namespace"):
        FSABehaviour(mixed_fsa("pick"), registry, namespace="/a.b")


def test_skill_behaviour_binds_parameters(registry: Registry, calls: Calls) -> None:
    sb = SkillBehaviour("Move", registry, params={"n": 4}, namespace="/arm",
                        status_map={"success": "SUCCESS", "failure": "SUCCESS"})
    ticks = tick_until_done(sb)
    assert ticks == 4 and sb.status == Status.SUCCESS  # four ticks of Move(n=4)
    assert py_trees.blackboard.Blackboard.get("/arm/pos") == sb.fsa_blackboard["pos"]
    assert calls.cancels == {}


def test_tree_skill_in_an_fsa_shares_data_and_is_preempted() -> None:
    @skill(writes=("count",))
    def count_up(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
        bb["count"] = bb.get("count", 0) + 1
        return "success"

    def look() -> py_trees.behaviour.Behaviour:
        # reads /look/count (pushed from the FSA), writes /look/seen (pulled back)
        check = py_trees.behaviours.CheckBlackboardVariableValue(
            name="Count>=2?",
            check=py_trees.common.ComparisonExpression("/look/count", 2, lambda a, b: a >= b))
        mark = py_trees.behaviours.SetBlackboardVariable(
            name="Seen", variable_name="/look/seen", variable_value="cup", overwrite=True)
        spy = py_trees.behaviours.SetBlackboardVariable(
            name="Spy", variable_name="/look/secret", variable_value=1, overwrite=True)
        wait = py_trees.behaviours.TickCounter(name="Wait2", duration=2,
                                               completion_status=Status.SUCCESS)
        return py_trees.composites.Sequence("Look", memory=True,
                                            children=[check, wait, mark, spy])

    reg = Registry([count_up])
    reg.add(tree_skill(look, name="Look", reads=("count",), writes=("seen",),
                       namespace="/look"))
    fsa = FSA({"C": State("CountUp", {}, {"success": "L"}),
               "L": State("Look", {}, {"success": "success", "failure": "C"})},
              "C", step_limit=10)
    compiled = compile_fsa(fsa, reg)
    bb = Blackboard()
    run = compiled.start(bb, 0, trace=True)
    res = run.run()
    assert res.outcome == "success" and bb["seen"] == "cup" and bb["count"] == 2
    assert "secret" not in bb  # the tree's undeclared key stays in the tree
    assert [s.outcome for s in res.trace or ()] == ["success", "failure", "success", "success"]
    assert res == compiled.run(Blackboard(), 0, trace=True)  # same in both modes

    # preempting the FSA while the tree runs stops the tree
    run = compiled.start(Blackboard({"count": 5}), 0)
    while run.state != "L" or not run.active:
        run.tick()
    run.tick()
    tree = run._act.root  # type: ignore[union-attr]
    assert tree.status == Status.RUNNING
    assert run.preempt().outcome == "preempted" and tree.status == Status.INVALID


def test_fsa_in_tree_with_tree_in_fsa_share_one_namespace() -> None:
    """An FSA (in a tree) whose Look state is a tree: all three see /pick/*."""

    @skill(writes=("target",))
    def choose(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
        bb["target"] = "mug"
        return "success"

    def confirm() -> py_trees.behaviour.Behaviour:
        return py_trees.behaviours.CheckBlackboardVariableValue(
            name="Target is mug?",
            check=py_trees.common.ComparisonExpression("/pick/target", "mug",
                                                       lambda a, b: a == b))

    reg = Registry([choose])
    reg.add(tree_skill(confirm, name="Confirm", reads=("target",), namespace="/pick"))
    fsa = FSA({"Ch": State("Choose", {}, {"success": "Co"}),
               "Co": State("Confirm", {}, {"success": "success", "failure": "failure"})},
              "Ch", name="pick")
    fb = FSABehaviour(fsa, reg)
    after = py_trees.behaviours.CheckBlackboardVariableValue(
        name="Tree sees mug?",
        check=py_trees.common.ComparisonExpression("/pick/target", "mug", lambda a, b: a == b))
    root = py_trees.composites.Sequence("Root", memory=True, children=[fb, after])
    tick_until_done(root)
    assert fb.last_result is not None and fb.last_result.outcome == "success"
    assert root.status == Status.SUCCESS


def test_ascii_rendering_shows_the_fsa_states(registry: Registry) -> None:
    fb = FSABehaviour(mixed_fsa("pick"), registry)
    text = py_trees.display.ascii_tree(py_trees.composites.Sequence(
        "Root", memory=True, children=[fb]))
    for line in ("pick", "A: Bump()", "B: Move(n=3)", "C: Wait(n=2)"):
        assert line in text
