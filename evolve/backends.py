"""The evaluation backends by name: where a run's evaluations go (``backend=``)."""

from __future__ import annotations

from skillcompose.task import Task

from .config import EVALUATION_BACKENDS
from .errors import EvolutionError
from .evaluation import EvalLimits
from .genome import SkillSet
from .pool import ProcessEvaluator
from .ray_backend import RayEvaluator
from .serial import SerialEvaluator

__all__ = ["BACKENDS", "make_evaluator"]

BACKENDS = EVALUATION_BACKENDS  # where evaluations run (defined with the settings)


def make_evaluator(
    backend: str, task: Task, skills: SkillSet, workers: int | None, chunks_per_worker: int = 2,
    limits: EvalLimits | None = None, islands: int = 1,
) -> SerialEvaluator | ProcessEvaluator | RayEvaluator:
    """The evaluator of ``backend``; on Ray, island k's jobs run on the k-th node first."""
    if backend == "serial":
        return SerialEvaluator(task, skills, limits)
    if backend == "process":
        return ProcessEvaluator(task, skills, workers, limits)
    if backend == "ray":
        ray_evaluator = RayEvaluator(task, skills, workers, chunks_per_worker, limits)
        ray_evaluator.groups = islands
        return ray_evaluator
    raise EvolutionError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
