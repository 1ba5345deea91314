"""How the runtime's objects show themselves in a notebook (Jupyter's ``_repr_*_`` methods).

An :class:`~skillcompose.FSA` shows its drawing (``FSA._repr_svg_``, from
:func:`skillcompose.draw.to_svg`); a :class:`~skillcompose.RunResult` shows how the run
ended and, when it was traced, a table of its steps with what each changed on the
blackboard (:func:`run_result_html`). Plain HTML, no scripts and nothing fetched.
"""

from __future__ import annotations

import html
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING, Any

from .blackboard import DELETED
from .errors import clip

if TYPE_CHECKING:
    from .executor import RunResult

__all__ = ["html_table", "run_result_html", "short_value", "trace_lines"]


def short_value(v: Any, width: int = 60) -> str:
    """``repr(v)`` cut to ``width`` characters; a deleted key as ∅."""
    return "∅" if v is DELETED else clip(repr(v), width)


def trace_lines(result: RunResult, value: Callable[[Any], str] = short_value) -> list[str]:
    """A traced run as ``skillcompose run --trace`` prints it: a line per step (state, skill,
    outcome, where it went), a line per blackboard key it changed (``value`` shows the old
    and the new value), and how the run ended."""
    lines = []
    for ev in result.trace or ():
        lines.append(f"{ev.step:>4}  {ev.state} ({ev.skill}) -> {ev.outcome} -> {ev.target}")
        lines += [f"        {key}: {value(old)} => {value(new)}"
                  for key, (old, new) in ev.changes.items()]
    lines.append(f"ended: {result.outcome} after {result.steps} step(s)")
    return lines


def html_table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    """A plain HTML table; every cell escaped."""
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>"
        for row in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def run_result_html(result: RunResult) -> str:
    """How a run ended, and its trace (when it was traced) as a table of steps."""
    ended = f"<p><b>{html.escape(result.outcome)}</b> after {result.steps} step(s)"
    if result.last_state is not None:
        ended += f", last state {html.escape(result.last_state)}"
    ended += "</p>"
    if result.error is not None:
        ended += (f"<p>error: {html.escape(type(result.error).__name__)}: "
                  f"{html.escape(str(result.error))}</p>")
    if not result.trace:
        return ended
    rows = [
        (ev.step, ev.state, ev.skill, ev.outcome, ev.target,
         "; ".join(f"{k}: {short_value(old)} → {short_value(new)}"
                   for k, (old, new) in ev.changes.items()))
        for ev in result.trace
    ]
    return ended + html_table(
        ("step", "state", "skill", "outcome", "next", "blackboard changes"), rows)
