"""Golden traces: a run's steps kept in a file, so that a change of behaviour shows as a diff.

The file is text, one line per step and per blackboard change, as ``skillcompose run
--trace`` prints them (values in full, floats to 12 significant digits, memory addresses
left out, so the file changes only when the behaviour does), then how the run ended and,
for an episode, its fitness. :func:`assert_golden_trace` compares a run with the file and
fails with a unified diff; with ``update=True`` it writes the file instead, and the review
of that file's change is the review of the behaviour's.
"""

from __future__ import annotations

import difflib
import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from ..blackboard import DELETED
from ..display import trace_lines
from ..errors import exception_text, one_line
from ..executor import RunResult
from .assertions import CheckFailed
from .episodes import Episode

__all__ = ["GoldenTraceError", "assert_golden_trace", "golden_text", "golden_value"]

_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


class GoldenTraceError(CheckFailed):
    """A run differs from its golden trace, or the golden trace is missing."""


def golden_value(value: Any, digits: int = 12) -> str:
    """A blackboard value in a golden trace: its ``repr`` in one line, floats (numpy's too,
    in containers and arrays) to ``digits`` significant digits, no memory addresses."""
    if value is DELETED:
        return "∅"
    return _ADDRESS.sub("", one_line(repr(_plain(value, digits))))


class _Array(list[Any]):
    def __repr__(self) -> str:
        return f"array({super().__repr__()})"


def _plain(value: Any, digits: int) -> Any:
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (float, np.floating)):
        f = float(value)
        return float(f"{f:.{digits}g}") if math.isfinite(f) else f
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.ndarray):
        return _Array(_plain(value.tolist(), digits))
    if isinstance(value, list):
        return [_plain(v, digits) for v in value]
    if isinstance(value, tuple):
        items = [_plain(v, digits) for v in value]
        return type(value)(*items) if hasattr(value, "_fields") else tuple(items)  # a NamedTuple
    if isinstance(value, dict):
        return {k: _plain(v, digits) for k, v in value.items()}
    return value


def golden_text(run: Episode | RunResult, *, digits: int = 12) -> str:
    """The golden trace of a traced run (an :class:`Episode` or a ``RunResult``)."""
    result = run.result if isinstance(run, Episode) else run
    if not isinstance(result, RunResult) or result.trace is None:
        raise TypeError("a golden trace needs a traced run: run_episode(fsa, task, seed) or "
                        "compiled.run(bb, rng, trace=True)")
    if isinstance(run, Episode):
        head = (f"# FSA {run.fsa}, task {run.task}, seed {run.seed}, backend {run.backend}")
    else:
        head = "# a run of an FSA"
    lines = [head, *trace_lines(result, lambda v: golden_value(v, digits))]
    if result.error is not None:
        lines.append(f"error: {_ADDRESS.sub('', one_line(exception_text(result.error)))}")
    if isinstance(run, Episode):
        lines.append(f"fitness: {golden_value(run.fitness, digits)}")
    return "\n".join(lines) + "\n"


def assert_golden_trace(
    run: Episode | RunResult, path: str | os.PathLike[str], *, update: bool = False,
    digits: int = 12, hint: str = "pass update=True to rewrite it",
) -> bool:
    """Compare ``run``'s golden trace with the file at ``path``; raise
    :class:`GoldenTraceError` with a unified diff (``-`` the file, ``+`` this run) when they
    differ or the file is missing. ``update=True`` writes the file instead (its folders
    too) and returns True when it changed. ``hint`` says how to update (in the message)."""
    __tracebackhide__ = True
    text = golden_text(run, digits=digits)
    file = Path(path)
    stored = file.read_text(encoding="utf-8").replace("\r\n", "\n") if file.exists() else None
    if update:
        if stored == text:
            return False
        file.parent.mkdir(parents=True, exist_ok=True)
        file.write_text(text, encoding="utf-8")
        return True
    if stored is None:
        raise GoldenTraceError(f"golden trace {_shown(file)} does not exist; {hint}. "
                               f"This run:\n{text}")
    if stored != text:
        diff = difflib.unified_diff(stored.splitlines(), text.splitlines(),
                                    f"{_shown(file)} (stored)", "this run", lineterm="")
        raise GoldenTraceError(f"the run differs from its golden trace {_shown(file)}; if the "
                               f"change is intended, {hint} and review the file's diff\n"
                               + "\n".join(diff))
    return False


def _shown(file: Path) -> str:
    """``file`` relative to the current folder when it is inside it."""
    try:
        return str(file.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(file)
