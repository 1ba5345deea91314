"""The serial evaluator: every job in this process, one after the other."""

from __future__ import annotations

from collections.abc import Iterable

from skillcompose.task import Task

from .evaluation import EvalLimits, Faults, Guard, Job, evaluate_job
from .genome import GenomeCompiler, SkillSet

__all__ = ["SerialEvaluator"]


class SerialEvaluator:
    """Evaluates in this process (the wall-clock limit needs its main thread)."""

    def __init__(
        self, task: Task, skills: SkillSet, limits: EvalLimits | None = None
    ) -> None:
        self.task = task
        self.compiler = GenomeCompiler(task, skills)
        self.workers = 1
        self.limits = limits or EvalLimits()
        self.faults = Faults()

    def evaluate(self, jobs: Iterable[Job], expected: int | None = None) -> list[float]:
        # all jobs first, then all evaluations: interleaving them in one process measured
        # slower (about 10 %) (the two loops evict each other's code and data from the caches)
        jobs = list(jobs)
        faults = Faults()
        out: list[float] = []
        task, compiler = self.task, self.compiler
        with Guard(self.limits.time_limit) as guard:
            for j in jobs:
                f, code, error = evaluate_job(task, compiler, j, guard,
                                              faults.first_error is None)
                out.append(f)
                faults.count(code, j.trials)
                if error is not None and faults.first_error is None:
                    faults.first_error = error
        self.faults = faults
        return out

    def close(self) -> None:
        pass
