"""The transfer report's failure causes: the reason the last failing step wrote, not one a
step the FSA recovered from left behind."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Literal

import numpy as np

from skillcompose import Blackboard, Registry, compile_fsa, loads_fsa, skill
from skillcompose.skills.kinematic_world import REASON_KEY

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

import transfer  # noqa: E402


@skill(name="Reach", reads=("tried",), writes=("tried", REASON_KEY))
def _reach(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    """Fails the first time (its reason: collision), then succeeds."""
    if not bb.get("tried"):
        bb["tried"] = True
        bb[REASON_KEY] = "collision"
        return "failure"
    return "success"


@skill(name="Check", reads=("ok",))
def _check(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    """The task's judge: fails unless ``ok``; writes no reason."""
    return "success" if bb.get("ok") else "failure"


_FSA = """
format: 1
start: A
states:
  A: {skill: Reach, transitions: {success: C, failure: %s}}
  C: {skill: Check, transitions: {success: success, failure: failure}}
"""


def _cause(on_failure: str, bb: Blackboard) -> str:
    registry = Registry()
    registry.add(_reach)
    registry.add(_check)
    compiled = compile_fsa(loads_fsa(_FSA % on_failure), registry)
    result = compiled.run(bb, 0, trace=True)
    return transfer.cause(result, bb, registry, "default")


def test_a_reason_the_fsa_recovered_from_is_not_the_cause() -> None:
    bb = Blackboard({"tried": False})
    assert _cause("A", bb) == "failure"  # Reach retried, then the judge failed
    assert bb[REASON_KEY] == "collision"  # left behind by the recovered step
    assert _cause("failure", Blackboard({"tried": False})) == "collision"  # Reach ended it
    assert _cause("A", Blackboard({"tried": True})) == "failure"  # only the judge failed
