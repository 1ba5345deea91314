from __future__ import annotations

import numpy as np
import pytest

from skillcompose import (
    DELETED,
    Access,
    Blackboard,
    BlackboardAccessError,
    BlackboardKeyError,
    BlackboardTypeError,
    diff,
)


def test_instances_do_not_share_memory() -> None:
    a, b = Blackboard(), Blackboard()
    a["x"] = 1
    assert "x" not in b


def test_declared_access_is_enforced_and_named() -> None:
    bb = Blackboard({"jug": 1, "glass": 2})
    bb._client = Access("Pour", frozenset({"jug"}), frozenset({"water"}))
    assert bb["jug"] == 1
    bb["water"] = True
    assert bb["water"] is True  # writing implies reading
    with pytest.raises(BlackboardAccessError, match=r"skill Pour read .*'glass'.*reads="):
        bb["glass"]
    with pytest.raises(BlackboardAccessError, match=r"skill Pour wrote .*'jug'"):
        bb["jug"] = 3
    with pytest.raises(BlackboardAccessError):
        _ = "glass" in bb
    with pytest.raises(BlackboardAccessError):
        bb.get("glass")


def test_missing_key_message() -> None:
    with pytest.raises(BlackboardKeyError, match="before anything wrote it"):
        Blackboard()["nothing"]


def test_typed_keys() -> None:
    bb = Blackboard(types={"pose": np.ndarray})
    bb["pose"] = np.zeros(3)
    with pytest.raises(BlackboardTypeError, match="wrote list to blackboard key 'pose'"):
        bb["pose"] = [0, 0, 0]
    bb.declare("n", int)
    with pytest.raises(BlackboardTypeError):
        bb.declare("n", float)


def test_log_and_diff() -> None:
    bb = Blackboard({"a": 1})
    before = bb.to_dict()
    bb.start_log()
    bb["a"] = 2
    bb["a"] = 3
    bb["b"] = np.array([1.0, 2.0])
    bb["c"] = 0
    del bb["c"]
    log = bb.take_log()
    assert log["a"] == (1, 3)
    assert log["b"][0] is DELETED
    assert "c" not in log  # created and deleted within the step: no change
    bb["a"] = 3  # same value: not a change
    assert bb.take_log() == {}
    d = diff(before, bb.to_dict())
    assert set(d) == {"a", "b"}
    assert d["a"] == (1, 3)
