"""examples/bt_recovery.py runs (examples are tests)."""

from __future__ import annotations

from collections.abc import Iterator

import py_trees
import pytest
from py_trees.common import Status

from examples import bt_recovery


@pytest.fixture(autouse=True)
def clean_py_trees_blackboard() -> Iterator[None]:
    """py_trees' blackboard is process-global: start and end every test with it empty."""
    py_trees.blackboard.Blackboard.clear()
    yield
    py_trees.blackboard.Blackboard.clear()


def test_main_prints_the_tree_with_the_fsa_inside(capsys: pytest.CaptureFixture[str]) -> None:
    assert bt_recovery.main(["--seed", "0"]) == 0
    out = capsys.readouterr().out
    for text in ("PickOrRecover", "Pick (FSA)", "Reach: MoveArm(speed=0.25)",
                 "CheckHold: CheckHold()", "Recovery"):
        assert text in out


def test_sure_grasp_succeeds_first_time() -> None:
    status, _, pick = bt_recovery.run(seed=1, p_fail=0.0, show=False)
    assert status == Status.SUCCESS and pick.activations == 1
    assert pick.last_result is not None and pick.last_result.outcome == "success"


def test_failing_grasp_is_retried_then_recovered() -> None:
    status, _, pick = bt_recovery.run(seed=1, p_fail=1.0, show=False)
    assert status == Status.SUCCESS  # the recovery branch succeeded
    assert pick.activations == 2  # Retry ran the FSA twice
    assert pick.last_result is not None and pick.last_result.outcome == "failure"
    storage = py_trees.blackboard.Blackboard.storage
    assert storage["/recovery/help"] is True and storage["/pick/attempts"] == 2
    assert storage["/pick/holding"] is False and not storage["/pick/hand"].any()  # reset
