"""The success-rate statement: Clopper–Pearson bounds and the sequential test that evolution's
"solved" and the testing helpers share."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skillcompose.stats import SequentialRateTest, binomial_tail, estimate, rate_bounds


def _exact_tail(k: int, n: int, p: Fraction) -> float:
    return float(sum(math.comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(k, n + 1)))


@given(st.integers(1, 60), st.data())
@settings(max_examples=60, deadline=None)
def test_the_binomial_tail_is_the_exact_sum(n: int, data: st.DataObject) -> None:
    k = data.draw(st.integers(0, n + 1))
    p = Fraction(data.draw(st.integers(1, 99)), 100)
    assert binomial_tail(k, n, float(p)) == pytest.approx(_exact_tail(k, n, p), abs=1e-12)


def test_clopper_pearson_bounds_match_known_values() -> None:
    lower, upper = rate_bounds(95, 100, 0.025)  # the two-sided 95 % interval of 95/100
    assert lower == pytest.approx(0.8872, abs=1e-4)
    assert upper == pytest.approx(0.9836, abs=1e-4)
    assert rate_bounds(100, 100, 0.05)[0] == pytest.approx(0.05 ** (1 / 100))
    assert rate_bounds(0, 10, 0.05) == (0.0, pytest.approx(1 - 0.05 ** (1 / 10)))
    assert rate_bounds(0, 0, 0.05) == (0.0, 1.0)


@given(st.integers(1, 300), st.data())
@settings(max_examples=60, deadline=None)
def test_the_lower_bound_is_where_the_tail_is_alpha(n: int, data: st.DataObject) -> None:
    k = data.draw(st.integers(1, n))
    lower, upper = rate_bounds(k, n, 0.05)
    assert lower <= k / n <= upper
    assert binomial_tail(k, n, lower) == pytest.approx(0.05, abs=1e-6)


def test_a_092_fsa_does_not_hold_at_095_and_a_0999_one_does() -> None:
    rng = np.random.default_rng(1)
    passed = {0.92: 0, 0.999: 0}
    for rate in passed:
        for _ in range(40):
            test = SequentialRateTest(0.95)
            while test.add(bool(rng.random() < rate)) is None:
                pass
            passed[rate] += bool(test.decision)
    assert passed[0.92] == 0
    assert passed[0.999] == 40


def test_an_fsa_just_below_the_bar_passes_at_most_as_often_as_the_confidence_allows() -> None:
    rng = np.random.default_rng(2)
    runs, passes = 400, 0
    for _ in range(runs):
        test = SequentialRateTest(0.9, max_episodes=2000)
        while test.add(bool(rng.random() < 0.9)) is None:
            pass
        passes += bool(test.decision)
    assert passes / runs <= 0.05


def test_a_bad_fsa_fails_in_few_episodes_and_a_perfect_one_passes_at_the_first_look() -> None:
    test = SequentialRateTest(0.99)
    episodes = 0
    while test.add(False) is None:
        episodes += 1
    assert test.decision is False and test.episodes < 100
    perfect = SequentialRateTest(0.99)
    while perfect.add(True) is None:
        pass
    assert perfect.decision is True and perfect.episodes == perfect.schedule[0]
    # the first look is the fewest perfect episodes whose bound reaches the bar
    assert 0.99 ** perfect.schedule[0] <= perfect.alpha < 0.99 ** (perfect.schedule[0] - 1)
    result = perfect.result()
    assert result.holds and result.lower >= 0.99 and result.upper == 1.0


def test_a_deterministic_task_decides_on_one_episode() -> None:
    test = SequentialRateTest(0.95, deterministic=True)
    assert test.add(True) is True and test.episodes == 1
    test = SequentialRateTest(0.95, deterministic=True)
    assert test.add(False) is False


def test_an_estimate_says_its_rate_bounds_and_verdict() -> None:
    e = estimate(195, 200, 0.95, required=0.9)
    assert e.holds is True and e.rate == 0.975
    text = e.describe()
    assert "97.5 % of 200 fresh episodes" in text and "holds at 90 %" in text
    assert estimate(150, 200, required=0.9).holds is False
    assert estimate(150, 200).holds is None
    assert set(e.to_dict()) >= {"success_rate", "lower", "upper", "episodes", "holds"}


@pytest.mark.parametrize("bad", [0.0, 1.0, -0.1, 1.5])
def test_a_required_rate_outside_zero_one_is_refused(bad: float) -> None:
    with pytest.raises(ValueError, match="required rate"):
        SequentialRateTest(bad)
