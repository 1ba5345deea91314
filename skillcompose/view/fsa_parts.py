"""Parts of the pages that show an FSA file: what was checked, its lines with their
problems, the graph and its legend, the table of states, the task field that checks it
against a task's skills. Every value from the file reaches the page as text: the lines are
HTML-escaped here (and the HTML is sanitised again in the browser, by NiceGUI's DOMPurify),
the table's cells are text."""

from __future__ import annotations

import html
from collections.abc import Callable
from typing import Any

from nicegui import ui

from .data import FSAView, mermaid

__all__ = ["MERMAID", "STYLE", "check_status", "fsa_body", "graph_legend", "problems_card",
           "quiet_table", "states_table", "task_field", "yaml_html"]

MERMAID = {"securityLevel": "strict"}  # no HTML but Mermaid's own, sanitised; no clicks


def yaml_html(view: FSAView) -> str:
    """The file's lines, numbered; a problem's line is marked and its messages follow it."""
    by_line: dict[int, list[str]] = {}
    for p in view.problems:
        if p.line is not None:
            by_line.setdefault(p.line, []).append(p.render())
    out = ['<pre class="yaml-view">']
    for k, line in enumerate(view.text.splitlines() or [""], start=1):
        bad = k in by_line
        cls = "yaml-line bad" if bad else "yaml-line"
        out.append(f'<span class="{cls}" data-line="{k}"><span class="ln">{k:>4}</span> '
                   f"{html.escape(line)}</span>")
        for msg in by_line.get(k, ()):
            out.append(f'<span class="yaml-problem" data-line="{k}">     ▲ '
                       f"{html.escape(msg)}</span>")
    out.append("</pre>")
    return "".join(out)


STYLE = """
<style>
.yaml-view { max-width: 100%; font-size: 12.5px; line-height: 1.45; background: #f8fafc;
  border: 1px solid #e2e8f0; border-radius: 6px; padding: 8px 0; overflow-x: auto; margin: 0; }
.yaml-line, .yaml-problem { display: block; padding: 0 10px 0 calc(10px + 5ch);
  text-indent: -5ch; white-space: pre-wrap; overflow-wrap: anywhere; }
.yaml-line .ln { color: #94a3b8; user-select: none; }
.yaml-line.bad { background: #fee2e2; }
.yaml-problem { color: #b91c1c; background: #fef2f2; font-weight: 600; }
.fsa-graph svg { max-width: 100% !important; height: auto; }
</style>
"""


def graph_legend() -> None:
    with ui.row().classes("gap-3 text-xs text-slate-600 items-center"):
        for text, style in (("start", "border:3px solid #2563eb"),
                            ("terminal outcome", "background:#ecfdf5;border:1px solid #059669"),
                            ("unreachable", "background:#e5e7eb;border:1px dashed #9ca3af"),
                            ("trap (no end reachable)",
                             "background:#fee2e2;border:2px solid #dc2626"),
                            ("active", "background:#fde047;border:3px solid #ca8a04")):
            with ui.row().classes("items-center gap-1"):
                ui.element("span").style("display:inline-block;width:14px;height:14px;"
                                         f"border-radius:3px;{style}")
                ui.label(text)


def states_table(view: FSAView) -> None:
    rows = [{"state": r.name, "skill": r.skill, "params": "; ".join(r.params) or "–",
             "transitions": "; ".join(r.transitions), "flags": ", ".join(r.flags)}
            for r in view.rows]
    ui.table(columns=[
        {"name": c, "label": c, "field": c, "align": "left"}
        for c in ("state", "skill", "params", "transitions", "flags")
    ], rows=rows, row_key="state").classes("w-full").props("dense flat bordered wrap-cells "
                                                           "data-testid=states-table")


def quiet_table(table: Any, text: str) -> None:
    """Show ``text`` in ``table`` while it has no rows (its ``no-data-label``), plainly:
    Quasar's own empty table carries a warning icon, which says something is wrong."""
    table.props["no-data-label"] = text
    table.add_slot("no-data", r"""
        <div class="w-full text-slate-500 italic" data-testid="no-rows">{{ props.message }}</div>
    """)


def task_field(value: str, check: Callable[[str], None]) -> None:
    """The task module the file is checked against, and the button that checks it (Enter
    too): ``check`` gets the text typed."""
    field = ui.input("task module (checks skills and parameters)", value=value,
                     placeholder="e.g. examples.pour_water").classes("w-80") \
        .props("data-testid=fsa-task-input")
    field.on("keydown.enter", lambda: check((field.value or "").strip()))
    ui.button("Check", on_click=lambda: check((field.value or "").strip())) \
        .props("data-testid=check-button")


def check_status(view: FSAView) -> tuple[str, str]:
    """What was checked of a file that has no problem, and its colour: valid (green) only
    when checked against a task's skills and a run from its start can end."""
    fsa = view.fsa
    assert fsa is not None
    if not view.checked_against:
        return ("structure only: its states, transitions, start and terminals are well formed; "
                "its skills and parameters are not checked (no task's skills to check them "
                "against): enter a task module above and press Check", "text-amber-800")
    if fsa.start in view.traps:
        return (f"valid against {view.checked_against}, but no run can end: no terminal "
                f"outcome is reachable from the start state {fsa.start}", "text-orange-700")
    return f"valid; checked against {view.checked_against}", "text-green-700"


def problems_card(view: FSAView, shown: str) -> None:
    """The problems of a file, each with its line, as ``skillcompose validate`` says them."""
    with ui.card().classes("w-full bg-red-50").props("data-testid=problems"):
        ui.label(f"not valid: {len(view.problems)} problem(s) in {view.path.name}") \
            .classes("font-semibold text-red-800")
        for p in view.problems:
            ui.label(p.render(shown)).classes("text-sm text-red-800") \
                .props("data-testid=problem")


def fsa_body(view: FSAView, shown: str) -> None:
    """An FSA file: its problems or what was checked, the graph and the states beside its
    lines."""
    fsa = view.fsa
    with ui.row().classes("w-full no-wrap gap-6 items-start"):
        with ui.column().classes("w-3/5 min-w-0 gap-2"):
            if view.problems:
                problems_card(view, shown)
            if fsa is not None:
                ui.label(f"{fsa.name or view.path.name}: {len(fsa.states)} states, start "
                         f"{fsa.start}, terminals {', '.join(fsa.terminals)}, step limit "
                         f"{fsa.step_limit}").classes("font-semibold") \
                    .props("data-testid=fsa-summary")
                if not view.problems:
                    text, colour = check_status(view)
                    ui.label(text).classes(f"text-sm {colour}").props("data-testid=check-status")
                for names, what in ((view.unreachable, "unreachable from the start (never "
                                     "run)"), (view.traps, "trap: no terminal outcome "
                                               "reachable (a run ends in timeout)")):
                    if names:
                        ui.label(f"{', '.join(names)}: {what}").classes(
                            "text-sm text-orange-700").props("data-testid=flag")
                graph_legend()
                ui.mermaid(mermaid(fsa, params={r.name: r.params for r in view.rows},
                                   unreachable=view.unreachable, traps=view.traps),
                           config=MERMAID) \
                    .classes("fsa-graph w-full").props("data-testid=fsa-graph")
                states_table(view)
        with ui.column().classes("w-2/5 min-w-0"):
            ui.label(shown).classes("text-sm text-slate-600")
            ui.html(yaml_html(view)).classes("w-full min-w-0") \
                .props("data-testid=yaml")  # escaped here, and sanitised (DOMPurify) there
