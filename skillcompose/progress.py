"""Progress of long commands (many runs of an FSA, robustness sweeps) on a terminal.

A bar from tqdm on standard error: only on a terminal (never in a log or a pipe), only once
the work has taken :data:`SHOW_AFTER_S` seconds (short commands print nothing), with the
count, the rate and, as the total is known, the time left at the rate so far.
"""

from __future__ import annotations

import sys
from typing import Any, TextIO

from tqdm import tqdm

__all__ = ["REDRAW_S", "SHOW_AFTER_S", "progress_bar"]

SHOW_AFTER_S = 2.0
REDRAW_S = 0.1  # at most this often


def progress_bar(total: int, unit: str, desc: str = "", file: TextIO | None = None, *,
                 disable: bool = False) -> Any:
    """A tqdm bar of ``total`` ``unit`` s on ``file`` (default standard error); it draws
    itself only on a terminal and after :data:`SHOW_AFTER_S` seconds, never when
    ``disable`` (``-q``). Use it as a context manager and call ``update(n)``."""
    stream = file if file is not None else sys.stderr
    return tqdm(
        total=total, unit=unit, desc=desc or None, file=stream, delay=SHOW_AFTER_S,
        mininterval=REDRAW_S, disable=disable or not getattr(stream, "isatty", lambda: False)(),
        leave=False, dynamic_ncols=True,
    )
