"""Whether an FSA holds: its success rate on fresh episodes, the statement "solved" makes.

A run with ``require_holds`` (every preset but ``paper``) calls its task solved only when the
FSA it would export (simplified, as written) reaches the task's target on episodes never used
to select it, with a one-sided lower confidence bound (Clopper–Pearson, at the config's
``holds_confidence``) of at least the required rate (the config's ``success_rate``, else the
task's). The test is :class:`skillcompose.stats.SequentialRateTest`: it stops as soon as the
answer is clear, so an FSA far below the bar costs a few episodes and one far above it the
first look. A deterministic task needs one episode.

The worlds come from ``SeedSequence(seed, spawn_key=(4, generation, k))``: a stream of their
own, which neither breeding, evaluation, confirmation nor simplification draws from.

The exported FSA of a run is also measured on a fixed count of fresh episodes at its end
(:func:`check_fresh`, stream 3), unless the holds test's episodes say it already;
:func:`describe_fresh` puts either in one line.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from skillcompose.fsa import FSA
from skillcompose.stats import RateEstimate, SequentialRateTest, estimate
from skillcompose.task import Task

from .config import EvolutionConfig
from .evaluation import TIMED_OUT, Guard, iter_episodes

__all__ = [
    "FRESH_STREAM",
    "HOLDS_STREAM",
    "FreshCheck",
    "check_fresh",
    "describe_fresh",
    "fresh_differs",
    "holds_test",
    "measure_fresh",
    "required_rate",
]

FRESH_STREAM = 3
"""The spawn key of the worlds of a run's final fresh-episode check (:func:`check_fresh`)."""

HOLDS_STREAM = 4
"""The spawn key of the worlds the holds test draws (after breeding 0, evaluation 1,
confirmation 2 and the final fresh check 3)."""


@dataclass(frozen=True)
class FreshCheck:
    """An FSA on fresh episodes: the success rate with its bounds (and the verdict when a
    rate was required), the mean fitness, and the episodes that raised or ran out of time."""

    estimate: RateEstimate
    mean_fitness: float
    raised: int
    timeouts: int
    seed: int
    kind: str  # "holds": the sequential test that decides "solved"; "measured": a fixed count
    deterministic: bool = False  # the task's episodes are all the same: one was run

    @property
    def episodes(self) -> int:
        return self.estimate.episodes

    @property
    def passed(self) -> bool:
        return bool(self.estimate.holds)

    def to_dict(self) -> dict[str, Any]:
        return {**self.estimate.to_dict(), "mean_fitness": self.mean_fitness,
                "raised": self.raised, "timeouts": self.timeouts, "seed": self.seed,
                "kind": self.kind, "deterministic": self.deterministic}


def required_rate(task: Task, cfg: EvolutionConfig) -> float:
    """The success rate a run asks of its FSA: the config's, else the task's."""
    return task.success_rate if cfg.success_rate is None else cfg.success_rate


def _run(task: Task, fsa: FSA, seq: np.random.SeedSequence, most: int,
         time_limit: float | None, stop: Any) -> tuple[list[float], int, int]:
    compiled = task.compile(fsa)
    scores: list[float] = []
    raised = timeouts = 0
    with Guard(time_limit) as guard:
        for f, code in iter_episodes(task, compiled, seq, most, guard):
            raised += code >> 2
            timeouts += code & TIMED_OUT
            scores.append(f)
            if stop(task.solved(f)):
                break
    return scores, raised, timeouts


def _mean(scores: list[float]) -> float:
    return float(statistics.fmean(scores)) if scores else math.nan


def holds_test(task: Task, fsa: FSA, seed: int, key: tuple[int, ...], required: float, *,
               confidence: float = 0.95, max_episodes: int = 100_000,
               time_limit: float | None = None) -> FreshCheck:
    """The sequential test of ``fsa`` at ``required`` on the worlds of stream ``key``."""
    test = SequentialRateTest(required, confidence=confidence, max_episodes=max_episodes,
                              deterministic=task.deterministic)
    seq = np.random.SeedSequence(seed, spawn_key=(HOLDS_STREAM, *key))
    scores, raised, timeouts = _run(task, fsa, seq, test.max_episodes, time_limit,
                                    lambda ok: test.add(ok) is not None)
    return FreshCheck(test.result(), _mean(scores), raised, timeouts, seed, "holds",
                      task.deterministic)


def measure_fresh(task: Task, fsa: FSA, seq: np.random.SeedSequence, episodes: int,
                  seed: int, *, required: float | None = None, confidence: float = 0.95,
                  time_limit: float | None = None) -> FreshCheck:
    """``fsa`` on ``episodes`` worlds of ``seq`` (one for a deterministic task): its rate
    with bounds at ``confidence``, and whether that lower bound reaches ``required``."""
    scores, raised, timeouts = _run(task, fsa, seq, episodes, time_limit, lambda ok: False)
    successes = sum(map(task.solved, scores))
    return FreshCheck(estimate(successes, len(scores), confidence, required),
                      _mean(scores), raised, timeouts, seed, "measured", task.deterministic)


def check_fresh(
    task: Task, fsa: FSA, seed: int, trials: int, time_limit: float | None = None,
    required: float | None = None, confidence: float = 0.95,
) -> dict[str, Any]:
    """How ``fsa`` does on ``trials`` fresh episodes (worlds from ``SeedSequence(seed,
    spawn_key=(3,))``, never seen during evolution or simplification): the share that
    reach the task's target (``success_rate``) with its one-sided bounds at ``confidence``
    (``lower``, ``upper``; Clopper–Pearson), whether the lower one reaches ``required``
    (``holds``, None when no rate is required), the mean fitness, and the episodes that
    raised or ran past ``time_limit`` [s] (each scores worst)."""
    seq = np.random.SeedSequence(seed, spawn_key=(FRESH_STREAM,))
    return measure_fresh(task, fsa, seq, trials, seed, required=required,
                         confidence=confidence, time_limit=time_limit).to_dict()


def describe_fresh(fresh: Mapping[str, Any]) -> str:
    """One line for a fresh check of ``run.json`` or a result: the rate, its bounds and,
    when a rate was required, whether it holds (older runs: the rate alone). A deterministic
    task's one episode is every episode: the line says whether it reached the target, with
    no rate or bounds, which would read as a sample of one."""
    rate, episodes = fresh.get("success_rate"), fresh.get("episodes")
    if not isinstance(rate, (int, float)) or not isinstance(episodes, int):
        return "not measured"
    if fresh.get("deterministic") is True and episodes == 1:
        return ("reaches the target" if rate >= 1.0 else "does not reach the target") + \
            " on a fresh episode (a deterministic task: every episode is the same)"
    text = f"{100 * rate:.1f} % of {episodes:,} fresh episodes reach the target"
    lower, upper = fresh.get("lower"), fresh.get("upper")
    if isinstance(lower, (int, float)) and isinstance(upper, (int, float)):
        conf = fresh.get("confidence", 0.95)
        text += f" ({100 * conf:g} % bounds {100 * lower:.1f}–{100 * upper:.1f} %)"
    required, holds = fresh.get("required_rate"), fresh.get("holds")
    if isinstance(required, (int, float)) and isinstance(holds, bool):
        text += (f"; holds at the required {100 * required:g} %" if holds else
                 f"; does not hold at the required {100 * required:g} %")
    return text


def fresh_differs(task: Task, evolved: float, fresh: float) -> bool:
    """Whether the fitness on fresh episodes tells another story than the evolved one: the
    task counts one as solved and not the other, or they differ by more than 10 %."""
    if task.solved(evolved) != task.solved(fresh):
        return True
    if math.isinf(evolved) or math.isinf(fresh) or math.isnan(fresh):
        return evolved != fresh
    return abs(fresh - evolved) > 0.1 * max(abs(fresh), abs(evolved))
