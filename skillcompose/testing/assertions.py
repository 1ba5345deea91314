"""Assertions about FSAs on a task: how often they reach its target, how one episode ends.

:func:`assert_success_rate` states what evolution's "solved" states, with the same test
(:class:`skillcompose.stats.SequentialRateTest`): the one-sided lower confidence bound
(Clopper–Pearson) of the FSA's success rate is at least the required rate. It runs the
episodes of seeds ``seed``, ``seed + 1``, ... (see :mod:`.episodes`) and stops as soon as
the answer is clear, so an FSA far above or far below the bar costs one look. The same seeds
give the same verdict; a failure names the first failing seed and shows its trace.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from ..stats import RateEstimate, SequentialRateTest
from ..task import Task
from .episodes import Episode, FSALike, check_seed, run_episode, run_episodes

__all__ = [
    "CheckFailed",
    "OutcomeError",
    "RateCheck",
    "SuccessRateError",
    "assert_outcome",
    "assert_success_rate",
    "check_success_rate",
]


class CheckFailed(AssertionError):
    """A check of :mod:`skillcompose.testing` failed; the message says what was found."""


class SuccessRateError(CheckFailed):
    """The success rate of an FSA was not shown to reach the required rate."""

    def __init__(self, message: str, check: RateCheck) -> None:
        super().__init__(message)
        self.check = check


class OutcomeError(CheckFailed):
    """An episode ended otherwise than expected."""

    def __init__(self, message: str, episode: Episode) -> None:
        super().__init__(message)
        self.episode = episode


@dataclass(frozen=True)
class RateCheck:
    """The sequential test of an FSA on a task: what it measured (with the verdict), the
    seeds it ran, the most it would have run, and the first episode that missed the target
    (traced), if any."""

    estimate: RateEstimate
    first_seed: int
    max_episodes: int
    first_failure: Episode | None
    fewest: int = 1
    """The fewest episodes with which the test can pass (all of them successes)."""

    @property
    def passed(self) -> bool:
        return bool(self.estimate.holds)

    @property
    def seeds(self) -> range:
        return range(self.first_seed, self.first_seed + self.estimate.episodes)

    def describe(self) -> str:
        """The verdict, the rate with its bounds, the episodes, and the first failure."""
        est = self.estimate
        required = est.required if est.required is not None else 0.0
        verdict = "holds at" if self.passed else "is not shown to reach"
        lines = [
            f"the success rate {verdict} {100 * required:g} % "
            f"(one-sided lower bound at {100 * est.confidence:g} % confidence)",
            f"observed: {est.describe()}",
            f"episodes: {est.episodes:,} (seeds {self.seeds.start}–{self.seeds.stop - 1}), "
            + _stopping(est, self.max_episodes, self.fewest),
        ]
        if self.first_failure is None:
            lines.append("first failing seed: none")
        else:
            lines.append(f"first failing seed: {self.first_failure.seed}")
            lines.append(self.first_failure.describe())
        return "\n".join(lines)


def _stopping(est: RateEstimate, most: int, fewest: int) -> str:
    """Why the test ran as many episodes as it did."""
    if not est.holds and est.successes == est.episodes and most < fewest:
        return (f"no episode failed, but {most:,} episodes cannot show a rate of "
                f"{100 * (est.required or 0.0):g} %; allow at least {fewest:,} "
                "(max_episodes)")
    if est.episodes < most:
        return f"stopped early (at most {most:,}): the answer was clear"
    return f"the most the test runs ({most:,})"


def check_success_rate(
    fsa: FSALike, task: Task, at_least: float | None = None, confidence: float = 0.95, *,
    seed: int = 0, max_episodes: int = 100_000, looks: int = 5, backend: str | None = None,
) -> RateCheck:
    """:func:`assert_success_rate`'s test, its result returned instead of asserted."""
    for name, value in (("max_episodes", max_episodes), ("looks", looks)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{name} = {value!r}: expected a whole number of at least 1")
    required = task.success_rate if at_least is None else at_least
    test = SequentialRateTest(required, confidence=confidence, looks=looks,
                              max_episodes=max_episodes, deterministic=task.deterministic)
    first = check_seed(seed)
    failing: int | None = None
    seeds = itertools.islice(itertools.count(first), test.max_episodes)
    for episode in run_episodes(fsa, task, seeds, backend=backend):
        if not episode.success and failing is None:
            failing = episode.seed
        if test.add(episode.success) is not None:
            break
    traced = None if failing is None else run_episode(fsa, task, failing, backend=backend)
    uncapped = SequentialRateTest(required, confidence=confidence, looks=looks,
                                  deterministic=task.deterministic)
    return RateCheck(test.result(), first, test.max_episodes, traced, uncapped.schedule[0])


def assert_success_rate(
    fsa: FSALike, task: Task, at_least: float | None = None, confidence: float = 0.95, *,
    seed: int = 0, max_episodes: int = 100_000, looks: int = 5, backend: str | None = None,
) -> RateCheck:
    """Pass when the one-sided lower confidence bound of ``fsa``'s success rate on
    ``task`` is at least ``at_least`` (default: the task's ``success_rate``), as evolution
    decides "solved".

    An episode succeeds when its fitness reaches the task's target. Episodes run for seeds
    ``seed``, ``seed + 1``, ... in looks of doubling size, at most ``max_episodes``, each
    look at ``(1 - confidence) / looks``; a deterministic task needs one episode. Fails with
    :class:`SuccessRateError`: the observed rate, its bounds, the episodes run and the
    first failing seed with its trace. Returns the test's :class:`RateCheck`.
    """
    __tracebackhide__ = True  # pytest: the failure points at the caller's line
    check = check_success_rate(fsa, task, at_least, confidence, seed=seed,
                               max_episodes=max_episodes, looks=looks, backend=backend)
    if not check.passed:
        name = check.first_failure.fsa if check.first_failure is not None else _name(fsa)
        raise SuccessRateError(f"FSA {name} on task {task.name}: {check.describe()}", check)
    return check


def assert_outcome(
    fsa: FSALike, task: Task, seed: int, outcome: str, *, backend: str | None = None,
) -> Episode:
    """Pass when the episode of ``seed`` ends in ``outcome`` (``success``, ``failure``,
    ``timeout``, ``error``, ...); fails with :class:`OutcomeError` showing its trace.
    Returns the episode (traced, with its final blackboard)."""
    __tracebackhide__ = True
    episode = run_episode(fsa, task, seed, backend=backend)
    if episode.outcome != outcome:
        raise OutcomeError(
            f"FSA {episode.fsa} on task {task.name}: expected {outcome!r}, got "
            f"{episode.outcome!r}\n{episode.describe()}", episode)
    return episode


def _name(fsa: FSALike) -> str:
    return str(getattr(fsa, "name", None) or fsa)
