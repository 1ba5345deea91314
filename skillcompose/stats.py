"""How often an FSA reaches its task's target, as a statement a user can rely on.

One implementation serves evolution's "solved" and the tests a user writes: a success rate
is measured on episodes never used to choose the FSA, and an FSA *holds* at a required rate
``r`` when the one-sided lower confidence bound of its success rate is at least ``r``.

The bounds are Clopper–Pearson's (exact: their coverage is at least the confidence for every
true rate and sample size, where Wilson's dips below it near 0 and 1, which is where robot
FSAs live). They come from the binomial tail, summed in log space with numpy; scipy's beta
quantile would do the same, but the project does not carry scipy for one function.

:class:`SequentialRateTest` looks at the episodes in growing batches and stops as soon as
the answer is clear: it passes at a look whose lower bound reaches ``r``, and fails as soon
as the upper bound falls below ``r`` or even a perfect remainder could not pass. Each of its
``looks`` checks at ``(1 - confidence) / looks`` (Bonferroni), so looking several times
never raises the chance that an FSA below ``r`` passes above ``1 - confidence``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["RateEstimate", "SequentialRateTest", "binomial_tail", "estimate", "rate_bounds"]


def _log_pmf(n: int, p: float) -> np.ndarray:
    """log P(X = i) for i = 0..n, X ~ Binomial(n, p), 0 < p < 1."""
    i = np.arange(n + 1, dtype=float)
    log_fact = np.concatenate(([0.0], np.cumsum(np.log(np.arange(1, n + 1, dtype=float)))))
    return (log_fact[n] - log_fact - log_fact[::-1]) + i * math.log(p) + \
        (n - i) * math.log1p(-p)


def binomial_tail(k: int, n: int, p: float) -> float:
    """P(X >= k) for X ~ Binomial(n, p)."""
    if k <= 0:
        return 1.0
    if k > n:
        return 0.0
    if p <= 0.0:
        return 0.0
    if p >= 1.0:
        return 1.0
    logs = _log_pmf(n, p)[k:]
    top = float(logs.max())
    return min(1.0, math.exp(top) * float(np.exp(logs - top).sum()))


def _bisect(f: Callable[[float], float], lo: float, hi: float) -> float:
    """The root of the increasing function ``f`` on [lo, hi], to 1e-12."""
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if f(mid) < 0.0:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-12:
            break
    return 0.5 * (lo + hi)


def rate_bounds(successes: int, n: int, alpha: float) -> tuple[float, float]:
    """One-sided Clopper–Pearson bounds at level ``alpha`` each: the lowest rate whose
    chance of ``successes`` or more is ``alpha``, and the highest whose chance of
    ``successes`` or fewer is ``alpha``. With no episodes: (0, 1)."""
    if n <= 0:
        return 0.0, 1.0
    if not 0 <= successes <= n:
        raise ValueError(f"successes = {successes} outside 0..{n}")
    lower = 0.0 if successes == 0 else _bisect(
        lambda p: binomial_tail(successes, n, p) - alpha, 0.0, 1.0)
    upper = 1.0 if successes == n else _bisect(  # P(X <= successes | p) = alpha
        lambda p: alpha - (1.0 - binomial_tail(successes + 1, n, p)), 0.0, 1.0)
    return lower, upper


@dataclass(frozen=True)
class RateEstimate:
    """A success rate measured on ``episodes`` episodes, with its bounds at ``confidence``
    (one-sided each: ``lower`` is the bound a "holds at ``required``" rests on), and the
    verdict when a rate was required."""

    successes: int
    episodes: int
    lower: float
    upper: float
    confidence: float
    required: float | None = None
    holds: bool | None = None

    @property
    def rate(self) -> float:
        return self.successes / self.episodes if self.episodes else 0.0

    def to_dict(self) -> dict[str, object]:
        return {"successes": self.successes, "episodes": self.episodes,
                "success_rate": self.rate, "lower": self.lower, "upper": self.upper,
                "confidence": self.confidence, "required_rate": self.required,
                "holds": self.holds}

    def describe(self) -> str:
        """``97.5 % of 400 episodes (95 % bounds 95.6-98.8 %)``, and the verdict."""
        text = (f"{100 * self.rate:.1f} % of {self.episodes:,} fresh episodes "
                f"({100 * self.confidence:g} % bounds {100 * self.lower:.1f}–"
                f"{100 * self.upper:.1f} %)")
        if self.required is not None and self.holds is not None:
            text += (f": holds at {100 * self.required:g} %" if self.holds
                     else f": below the required {100 * self.required:g} %")
        return text


def estimate(successes: int, episodes: int, confidence: float = 0.95,
             required: float | None = None) -> RateEstimate:
    """The rate of ``successes`` in ``episodes``, its bounds, and whether it holds at
    ``required`` (the lower bound reaches it)."""
    lower, upper = rate_bounds(successes, episodes, 1.0 - confidence)
    holds = None if required is None else (episodes > 0 and lower >= required)
    return RateEstimate(successes, episodes, lower, upper, confidence, required, holds)


class SequentialRateTest:
    """Whether a success rate is at least ``required``, from episodes fed one by one.

    ``looks`` batches double in size from the first look, which is the fewest episodes with
    which a perfect record can pass; the last look is the most episodes the test runs
    (capped by ``max_episodes``). :meth:`add` takes an episode's result and returns True
    (passed), False (failed) or None (go on). A deterministic task needs one episode:
    ``deterministic=True`` decides on it alone.
    """

    def __init__(self, required: float, *, confidence: float = 0.95, looks: int = 5,
                 max_episodes: int = 100_000, deterministic: bool = False) -> None:
        if not 0.0 < required < 1.0 and not deterministic:
            raise ValueError(f"required rate {required!r}: expected a number in (0, 1)")
        if not 0.5 <= confidence < 1.0:
            raise ValueError(f"confidence {confidence!r}: expected a number in [0.5, 1)")
        self.required = required
        self.confidence = confidence
        self.deterministic = deterministic
        self.alpha = (1.0 - confidence) / looks
        first = 1 if deterministic else \
            max(1, math.ceil(math.log(self.alpha) / math.log(required)))
        schedule = [first * 2**j for j in range(looks)]
        self.schedule = [min(n, max_episodes) for n in schedule if n <= max_episodes] \
            or [max_episodes]
        self.max_episodes = self.schedule[-1]
        # the fewest successes that pass at the last look: more failures cannot pass
        self._need_last = self._fewest_passing(self.max_episodes)
        self.successes = 0
        self.episodes = 0
        self.decision: bool | None = None

    def _fewest_passing(self, n: int) -> int:
        if self.deterministic:
            return n
        lo, hi = 0, n + 1  # the smallest k with P(X >= k | required) <= alpha
        while lo < hi:
            mid = (lo + hi) // 2
            if binomial_tail(mid, n, self.required) <= self.alpha:
                hi = mid
            else:
                lo = mid + 1
        return lo

    def add(self, success: bool) -> bool | None:
        if self.decision is not None:
            return self.decision
        self.episodes += 1
        self.successes += bool(success)
        if self.deterministic:
            self.decision = bool(success)
            return self.decision
        failures = self.episodes - self.successes
        if self.max_episodes - failures < self._need_last:
            self.decision = False  # even a perfect remainder cannot pass
        elif self.episodes in self.schedule:
            k, n = self.successes, self.episodes
            if binomial_tail(k, n, self.required) <= self.alpha:
                self.decision = True
            elif 1.0 - binomial_tail(k + 1, n, self.required) <= self.alpha:
                self.decision = False  # the upper bound is below the required rate
            elif n >= self.max_episodes:
                self.decision = False
        return self.decision

    def result(self) -> RateEstimate:
        """What was measured and the verdict (False while undecided). The bounds are each
        at ``(1 - confidence) / looks``: by Bonferroni, the bounds of every look hold
        together with ``confidence``, so those of the look it stopped at do too."""
        lower, upper = rate_bounds(self.successes, self.episodes, self.alpha)
        return RateEstimate(self.successes, self.episodes, lower, upper,
                            self.confidence, self.required, bool(self.decision))
