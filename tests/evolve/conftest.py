from __future__ import annotations

import dataclasses
import sys
from collections.abc import Iterator
from typing import Any

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


# -- one local Ray for the tests that only use one -----------------------------------------------
# Starting Ray costs seconds of both cores (its servers and first workers); the tests that
# only evaluate on a running Ray share one (an evaluator given a running Ray leaves it running:
# RayEvaluator._owns_ray). It ships what their tasks need, as ray_runtime_env ships one
# task's. A test that starts Ray itself (test_ray_backend_equals_serial: evolve's own start and
# shutdown) stops the shared one first; the next test that asks for it starts it again.
# These tests are marked private_network, so this runs in the namespace's child pytest only.
_RAY_TASKS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("examples.toy_task", {"p_fail": 0.2}), ("tests.evolve.faulty_task", {}))


@pytest.fixture(scope="session")
def _ray_stopped_at_the_end() -> Iterator[None]:
    yield
    ray = sys.modules.get("ray")
    if ray is not None and ray.is_initialized():
        ray.shutdown()


@pytest.fixture
def local_ray(_ray_stopped_at_the_end: None) -> Any:
    """A running local Ray (started if none is), left running after the test."""
    ray = pytest.importorskip("ray")
    if not ray.is_initialized():
        from skillcompose.evolve.ray_env import ray_runtime_env

        modules: list[str] = []
        for module, settings in _RAY_TASKS:
            env, _ = ray_runtime_env(load_task(module, **settings))
            modules += [m for m in env["py_modules"] if m not in modules]
        ray.init(log_to_driver=False, include_dashboard=False,
                 runtime_env={"py_modules": modules})
    return ray
