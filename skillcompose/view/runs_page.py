"""The runs page (``/``): every run directory below the folder in a table, and the best
fitness per generation of the ticked runs on one chart, kept up to date by a timer whose
reads of the run directories run in a worker thread (the histories read incrementally and
bounded, :mod:`.history`), so that a large history never holds up other pages.

The table says what ``skillcompose evolve`` and ``run.json`` say: *generations* is the index
of the last generation evaluated (0: the initial population; a history of N + 1 lines),
*best fitness* the run's result (``result.best_fitness``: the best FSA's fitness once a
confirmation or fresh-episode check may have demoted a lucky evaluation). The chart plots
each generation's best evaluation, and marks the result on it, so both numbers are seen
together, each named.
"""

from __future__ import annotations

from typing import Any
from urllib.parse import urlencode

from nicegui import run as background
from nicegui import ui

from .common import error_text, header, safe, shown_path
from .data import RunSummary, find_runs
from .trust import ViewerConfig

__all__ = ["COLOURS", "best_note", "chart_options", "fmt", "run_row",
           "show_runs"]

COLOURS = ("#2563eb", "#dc2626", "#059669", "#d97706", "#7c3aed", "#0891b2", "#db2777",
           "#65a30d", "#475569", "#ea580c")
EXPLAINED = (
    "generations: the index of the last generation evaluated (0: the initial population), "
    "the N of skillcompose evolve's \"after N generations\" and of run.json's "
    "result.generations. best fitness: the run's result, as evolve prints it (run.json's "
    "result.best_fitness: a lucky evaluation may have been demoted by a confirmation or "
    "fresh-episode check); the chart plots each generation's best evaluation and marks "
    "the result with a diamond. A run without a result yet shows its last generation's "
    "best evaluation.")


def fmt(value: float | None, digits: int = 4) -> str:
    return "–" if value is None else f"{value:.{digits}g}"


def best_note(run: RunSummary) -> str:
    """What the best fitness shown is, when the chart shows another number or the run has
    no result yet ("" when the result and the chart's last point agree)."""
    if run.best is None:
        return ""
    if not run.best_is_result:
        return "so far: the last generation's best evaluation (no result yet)"
    if run.generation_best is not None and fmt(run.generation_best) != fmt(run.best):
        return (f"the run's result; the chart's last point: {fmt(run.generation_best)}, "
                "that generation's best evaluation")
    return ""


def _generations(run: RunSummary) -> str:
    last = "–" if run.last_generation is None else str(run.last_generation)
    if run.reading and run.status != "finished":  # the history's last line is not read yet
        return f"{last}+ (reading)" if run.last_generation is not None else "(reading)"
    return last


def run_row(run: RunSummary) -> dict[str, Any]:
    return {
        "name": run.name, "task": run.task, "status": run.status,
        "generations": _generations(run),
        "best": fmt(run.best), "best_note": best_note(run), "success": run.success_text,
        "settings": run.settings + (f" ({run.problem})" if run.problem else ""),
        "seed": "–" if run.seed is None else run.seed,
        "fsa_url": "/fsa?" + urlencode({"path": f"{run.name}/best.yaml"}),
        "replay_url": "/replay?" + urlencode({
            "path": str(run.path / "best.yaml"), "task": run.task_module,
            "settings": run.task_settings, "seed": 0}),
    }


def _series(run: RunSummary, colour: str) -> dict[str, Any]:
    series: dict[str, Any] = {
        "name": run.name, "type": "line", "showSymbol": True, "symbolSize": 5,
        "color": colour, "data": [list(p) for p in run.points],
    }
    if run.best_is_result and run.best is not None and run.points:
        at = run.last_generation if run.last_generation is not None else run.points[-1][0]
        series["markPoint"] = {
            "symbol": "diamond", "symbolSize": 16,
            "data": [{"name": "the run's result", "coord": [at, run.best],
                      "value": fmt(run.best)}],
            "label": {"show": True, "position": "top", "formatter": "result {c}",
                      "color": colour},
        }
    return series


def chart_options(runs: list[RunSummary], chosen: set[str]) -> dict[str, Any]:
    series = [_series(run, COLOURS[k % len(COLOURS)])
              for k, run in enumerate(r for r in runs if r.name in chosen)]
    return {
        "animation": False,
        "title": {"text": "best evaluation per generation (◆ the run's result)",
                  "left": "center", "textStyle": {"fontSize": 14}},
        "tooltip": {"trigger": "axis"},
        "legend": {"top": 24, "type": "scroll"},
        "grid": {"left": 60, "right": 80, "top": 60, "bottom": 50},
        "xAxis": {"type": "value", "name": "generation", "nameLocation": "middle",
                  "nameGap": 28, "minInterval": 1},
        "yAxis": {"type": "value", "name": "best fitness", "scale": True},
        "series": series,
    }


def _table() -> Any:
    columns: list[dict[str, Any]] = [
        {"name": "name", "label": "run", "field": "name", "align": "left", "sortable": True},
        {"name": "task", "label": "task", "field": "task", "align": "left"},
        {"name": "status", "label": "status", "field": "status", "align": "left"},
        {"name": "generations", "label": "generations", "field": "generations"},
        {"name": "best", "label": "best fitness", "field": "best"},
        {"name": "success", "label": "fresh success (95 % bounds)", "field": "success"},
        {"name": "seed", "label": "seed", "field": "seed"},
        {"name": "settings", "label": "settings", "field": "settings", "align": "left"},
    ]
    table = ui.table(columns=columns, rows=[], row_key="name", selection="multiple") \
        .classes("w-full").props("data-testid=runs-table flat bordered dense")
    table.add_slot("body-cell-status", r"""
        <q-td :props="props">
          <q-badge :label="props.value" :color="{running: 'blue', finished: 'green',
                   interrupted: 'orange'}[props.value] || 'red'" />
        </q-td>""")
    table.add_slot("body-cell-name", r"""
        <q-td :props="props">
          <span class="font-medium">{{ props.value }}</span>
          <a :href="props.row.fsa_url" class="text-blue-700 ml-3">FSA</a>
          <a :href="props.row.replay_url" class="text-blue-700 ml-2">replay</a>
        </q-td>""")
    table.add_slot("body-cell-best", r"""
        <q-td :props="props">
          <span data-testid="best-value">{{ props.value }}</span>
          <div v-if="props.row.best_note" data-testid="best-note"
               class="text-xs text-slate-500 whitespace-normal max-w-[16rem] ml-auto">
            {{ props.row.best_note }}</div>
        </q-td>""")
    return table


def show_runs(config: ViewerConfig) -> None:
    """The runs table and chart; filled, and kept up to date, by the timer."""
    header("Runs")
    ui.label(f"Runs under {shown_path(config, config.root)}").classes("text-xl font-semibold")
    count = ui.label("").props("data-testid=run-count").classes("text-slate-600")
    table = _table()
    ui.label(EXPLAINED).classes("text-sm text-slate-500").props("data-testid=runs-explained")
    ui.label("Tick runs to compare them on the chart; FSA opens a run's best FSA, replay "
             "runs it once.") \
        .classes("text-sm text-slate-500")
    chart = ui.echart(chart_options([], set())) \
        .classes("w-full h-96").props("data-testid=fitness-chart")
    chart.classes("fitness-chart")
    state: dict[str, Any] = {"key": None, "runs": None, "first": True}

    def show(current: list[RunSummary], force: bool) -> None:
        if state["first"]:  # the first listing ticks the first runs
            state["first"] = False
            table.selected = [run_row(r) for r in current[: len(COLOURS)]]
        chosen = {r["name"] for r in table.selected}
        key = tuple(current), tuple(sorted(chosen))
        count.text = f"{len(current)} run(s)"
        if key == state["key"] and not force:
            return
        state["key"] = key
        names = {r.name for r in current}
        table.rows = [run_row(r) for r in current]
        table.selected = [row for row in table.selected if row["name"] in names]
        table.update()
        chart.options.clear()
        chart.options.update(chart_options(current, {r["name"] for r in table.selected}))
        chart.update()

    async def refresh() -> None:
        try:
            current = await background.io_bound(find_runs, config.root)
        except Exception as exc:  # as safe: one line in the page, never a traceback
            count.text = f"runs: unexpected {type(exc).__name__}: {error_text(exc, 300)}"
            return
        if current is not None:
            state["runs"] = current
            safe("runs", lambda: show(current, False))

    def reselect() -> None:
        if state["runs"] is not None:
            safe("runs", lambda: show(state["runs"], True))

    table.on_select(lambda _: reselect())
    ui.timer(config.refresh, refresh)  # re-read the run directories
