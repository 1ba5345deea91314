"""A task whose ``Crash`` skill kills the worker process that runs it (or raises in the
main process): for testing that a dead worker costs one evaluation, not the run."""

from __future__ import annotations

import os
from typing import Literal

import numpy as np

from examples import toy_task
from skillcompose import Blackboard, Registry, skill
from skillcompose.task import Task

MAIN_PID = os.getpid()


@skill
def crash(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    """Exit the worker process at once, as a segfaulting simulator would."""
    if os.getpid() != MAIN_PID:
        os._exit(3)
    raise RuntimeError("Crash ran in the main process")


def make_task(**settings: float) -> Task:
    base = toy_task.make_task(**settings)  # type: ignore[arg-type]
    registry = Registry()
    toy_task.register(registry)
    registry.add(crash)
    from dataclasses import replace

    return replace(base, registry=registry, name="crashy")
