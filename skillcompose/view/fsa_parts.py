"""Parts of the pages that show an FSA file: its lines with their problems, the graph's
legend and the table of states. Every value from the file reaches the page as text: the
lines are HTML-escaped here (and the HTML is sanitised again in the browser, by NiceGUI's
DOMPurify), the table's cells are text."""

from __future__ import annotations

import html

from nicegui import ui

from .data import FSAView

__all__ = ["STYLE", "graph_legend", "states_table", "yaml_html"]


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
.yaml-line, .yaml-problem { display: block; padding: 0 10px; white-space: pre; }
.yaml-line .ln { color: #94a3b8; user-select: none; }
.yaml-line.bad { background: #fee2e2; }
.yaml-problem { color: #b91c1c; background: #fef2f2; font-weight: 600; white-space: pre-wrap; }
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
