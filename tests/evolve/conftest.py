from __future__ import annotations

import pytest

from evolve import SkillSet
from skillcompose.task import Task, load_task


@pytest.fixture(scope="session")
def toy() -> Task:
    return load_task("examples.toy_task", p_fail=0.2)


@pytest.fixture(scope="session")
def toy_skills(toy: Task) -> SkillSet:
    return SkillSet.from_task(toy)
