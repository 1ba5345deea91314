from __future__ import annotations

import dataclasses

import pytest

from skillcompose.evolve import SkillSet
from skillcompose.task import Task, load_task


@pytest.fixture(scope="session")
def toy() -> Task:
    return load_task("examples.toy_task", p_fail=0.2)


@pytest.fixture(scope="session")
def toy_hard() -> Task:
    """The toy task with skills that fail 3 times in 10 and a tight tolerance: short runs
    stall, so restarts and drift stages happen in them."""
    return load_task("examples.toy_task", p_fail=0.3, tolerance=0.002)


@pytest.fixture(scope="session", params=["free terminals", "terminating skill"])
def toy_skills(request: pytest.FixtureRequest, toy: Task) -> SkillSet:
    """Both ways a run can end: any outcome to a terminal, or (as in the paper) only the
    outcomes of a terminating skill, here PutDown."""
    if request.param == "terminating skill":
        return SkillSet.from_task(dataclasses.replace(toy, terminal_skills=("PutDown",)))
    return SkillSet.from_task(toy)
