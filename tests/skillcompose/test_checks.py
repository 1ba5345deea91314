"""The number rules every entry point shares (skillcompose.checks)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from skillcompose.checks import is_real, is_whole, real_in, whole_in


@pytest.mark.parametrize("value", [True, False, np.bool_(True), "3", None, 3.0, [3]])
def test_what_is_not_a_whole_number(value: object) -> None:
    assert not is_whole(value) and not is_whole(value, numpy=True)


def test_numpy_numbers_only_when_asked() -> None:
    assert is_whole(3) and not is_whole(np.int64(3)) and is_whole(np.int64(3), numpy=True)
    assert is_real(0.5) and not is_real(np.float32(0.5))
    assert is_real(np.float32(0.5), numpy=True) and not is_real(True, numpy=True)


def test_bounds_and_nan() -> None:
    assert whole_in(1, 1, 3) and whole_in(3, 1, 3) and not whole_in(4, 1, 3)
    assert whole_in(10**12, 0) and not whole_in(-1, 0)
    assert real_in(0.0, 0.0, 1.0) and not real_in(0.0, 0.0, 1.0, low_open=True)
    assert not real_in(1.0, 0.0, 1.0, high_open=True) and not real_in(math.nan, 0.0, 1.0)
    assert real_in(math.inf, -math.inf, math.inf)
    assert not real_in(math.inf, -math.inf, math.inf, high_open=True)
