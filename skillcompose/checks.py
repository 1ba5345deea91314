"""The rules for numbers that every entry point checks the same way: a value from a file, a
command line or a Python call is a number only when it is one, never a ``bool`` (which
Python counts as an int: ``True`` is not one trial), and it lies within its bounds, NaN never.

``numpy=True`` also takes numpy's numbers (``np.int64(3)``, ``np.float32(0.5)``), for values
a program computes; without it only Python's, for settings that are written to JSON as they
are (a run's config, a checkpoint)."""

from __future__ import annotations

import numbers
from typing import Any

__all__ = ["is_real", "is_whole", "real_in", "whole_in"]


def is_whole(value: Any, *, numpy: bool = False) -> bool:
    """A whole number: an ``int`` (or, with ``numpy``, any integral number), not a bool."""
    if isinstance(value, bool) or type(value).__name__ == "bool_":
        return False
    return isinstance(value, numbers.Integral if numpy else int)


def is_real(value: Any, *, numpy: bool = False) -> bool:
    """A real number: an ``int`` or ``float`` (or, with ``numpy``, any real number), not a
    bool. NaN and infinities are numbers here; bounds exclude them where they must."""
    if isinstance(value, bool) or type(value).__name__ == "bool_":
        return False
    return isinstance(value, numbers.Real if numpy else (int, float))


def whole_in(value: Any, low: int, high: int | None = None, *, numpy: bool = False) -> bool:
    """A whole number from ``low`` to ``high`` (no upper bound when None)."""
    return is_whole(value, numpy=numpy) and low <= value and (high is None or value <= high)


def real_in(value: Any, low: float, high: float, *, low_open: bool = False,
            high_open: bool = False, numpy: bool = False) -> bool:
    """A real number within ``[low, high]``, each end open when asked (NaN never is)."""
    if not is_real(value, numpy=numpy):
        return False
    above = value > low if low_open else value >= low
    below = value < high if high_open else value <= high
    return bool(above and below)
