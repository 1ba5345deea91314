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


@skill(name="Grasp", writes=(REASON_KEY,))
def _grasp(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    """Succeeds, noting a fallback it took (a reason that is no failure)."""
    bb[REASON_KEY] = "joint_limits"
    return "success"


@skill(name="Stuck", writes=(REASON_KEY,))
def _stuck(bb: Blackboard, rng: np.random.Generator) -> Literal["failure"]:
    """Always fails, always for the same reason."""
    bb[REASON_KEY] = "unreachable"
    return "failure"


@skill(name="Bump", writes=(REASON_KEY,))
def _bump(bb: Blackboard, rng: np.random.Generator) -> Literal["failure"]:
    """Always fails by collision: Reach's reason again, a write no trace shows."""
    bb[REASON_KEY] = "collision"
    return "failure"


@skill(name="Check", reads=("ok",))
def _check(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    """The task's judge: fails unless ``ok``; writes no reason."""
    return "success" if bb.get("ok") else "failure"


def _cause(states: str, bb: Blackboard) -> str:
    registry = Registry()
    for s in (_reach, _grasp, _stuck, _bump, _check):
        registry.add(s)
    text = "format: 1\nstart: A\nstep_limit: 6\nstates:\n" + states
    result = compile_fsa(loads_fsa(text), registry).run(bb, 0, trace=True)
    return transfer.cause(result, bb, registry, "default")


_JUDGE = "  C: {skill: Check, transitions: {success: success, failure: failure}}\n"


def test_a_reason_the_fsa_recovered_from_is_not_the_cause() -> None:
    retry = "  A: {skill: Reach, transitions: {success: C, failure: A}}\n" + _JUDGE
    bb = Blackboard({"tried": False})
    assert _cause(retry, bb) == "failure"  # Reach retried, then the judge failed
    assert bb[REASON_KEY] == "collision"  # left behind by the recovered step
    ended = "  A: {skill: Reach, transitions: {success: C, failure: failure}}\n" + _JUDGE
    assert _cause(ended, Blackboard({"tried": False})) == "collision"  # Reach ended it
    assert _cause(retry, Blackboard({"tried": True})) == "failure"  # only the judge failed


def test_a_reason_written_by_a_step_that_went_on_is_not_the_cause() -> None:
    went_on = "  A: {skill: Grasp, transitions: {success: C}}\n" + _JUDGE
    bb = Blackboard()
    assert _cause(went_on, bb) == "failure" and bb[REASON_KEY] == "joint_limits"


def test_a_skill_that_writes_reasons_gives_the_one_it_rewrote() -> None:
    """Reach fails with collision and is recovered from; a later skill then fails writing
    a reason of its own, another or the same: that reason is the cause either way."""
    for last, reason in (("Stuck", "unreachable"), ("Bump", "collision")):
        again = ("  A: {skill: Reach, transitions: {success: B, failure: A}}\n"
                 f"  B: {{skill: {last}, transitions: {{failure: failure}}}}\n")
        assert _cause(again, Blackboard({"tried": False})) == reason


def test_a_state_failing_until_the_step_limit_gives_its_reason() -> None:
    stuck = "  A: {skill: Stuck, transitions: {failure: A}}\n"
    assert _cause(stuck, Blackboard()) == "unreachable"
    judged = ("  A: {skill: Check, transitions: {success: success, failure: B}}\n"
              "  B: {skill: Check, transitions: {success: success, failure: A}}\n")
    assert _cause(judged, Blackboard()) == "timeout"  # no reason at all
