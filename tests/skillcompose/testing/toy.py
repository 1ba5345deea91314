"""FSAs of the toy task (examples.toy_task) whose success rates are known, for the tests of
skillcompose.testing."""

from __future__ import annotations

from skillcompose import FSA, loads_fsa
from skillcompose.task import Task, load_task

ONCE = """\
format: 1
name: toy_once
start: Find
states:
  Find: {skill: FindBlock, transitions: {success: Pick}}
  Pick: {skill: PickBlock, transitions: {success: Carry, failure: failure}}
  Carry: {skill: Carry, params: {distance: 0.7}, transitions: {success: Put, failure: failure}}
  Put: {skill: PutDown, transitions: {success: success, failure: failure}}
"""
"""Find, pick, carry, put down, without a retry: it reaches the target on
``(1 - p_fail)**2`` of the episodes (picking and carrying each fail at ``p_fail``)."""

P_FAIL_0999 = 0.0005
"""``p_fail`` at which ONCE succeeds on 99.9 % of episodes."""
P_FAIL_090 = 0.05
"""``p_fail`` at which ONCE succeeds on 90.25 % of episodes."""


def once() -> FSA:
    return loads_fsa(ONCE)


def task(p_fail: float) -> Task:
    return load_task("examples.toy_task", p_fail=p_fail)
