"""The web app of ``skillcompose view``, built with NiceGUI (FastAPI, uvicorn, Vue/Quasar).

Pages: ``/`` runs (table and fitness chart, updated live), ``/fsa`` an FSA file (graph,
states, YAML with its problems at their lines), ``/replay`` one episode stepped forward and
back (graph, blackboard, changes, the PR2 in 3D on a kinematic task), ``/live`` the FSAs a
program publishes as they run (:mod:`skillcompose.view.live`). Every script, style and mesh
is served by this process: NiceGUI ships Vue, Quasar, ECharts, Mermaid and three.js, and the
PR2's meshes come from ``example-robot-data``.

A page shows what it cannot read (a vanished run, a broken file, a task that does not load)
as a one-line message and goes on; nothing a page or its timer raises reaches the browser
or the terminal as a traceback.
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any
from urllib.parse import urlencode

from nicegui import app, ui
from nicegui import run as background
from starlette.requests import Request

from skillcompose.errors import FSAValidationError, SkillcomposeError, clip, one_line, printable
from skillcompose.registry import Registry
from skillcompose.task import load_task, parse_settings

from .data import (
    FSAView,
    RunSummary,
    find_runs,
    mermaid,
    pid_alive,
    read_fsa,
    read_fsa_file,
    read_run_info,
)
from .episode import Episode, run_episode
from .folder import walk_below
from .fsa_parts import STYLE, graph_legend, states_table, yaml_html
from .guard import Guard, cookie_name
from .live import LIVE_SUFFIX, live_problem, read_live
from .trust import (
    ViewerConfig,
    address_problem,
    checked_settings,
    file_below,
    request_refusal,
    seed_of,
    task_refusal,
)

__all__ = ["ViewerConfig", "build", "fsa_files", "live_files", "request_refusal",
           "task_refusal"]

log = logging.getLogger("skillcompose.view")

REFRESH_S = 1.0  # how often the runs page re-reads the run directories
LIVE_REFRESH_S = 0.25
LIVE_LIST_S = 1.0  # how often the live page looks for new live files
REPLAY_TIMEOUT_S = 300.0  # the longest a replay's episode may take before its page fails
MAX_FILES = 500
MAX_LIST_DEPTH = 8  # how deep below the folder FSA and live files are looked for
MAX_ERROR_CHARS = 2000  # the most of an error message a page shows
MAX_TASK_ERROR_CHARS = 300  # ... of an error loading a task (it may quote other files)
MERMAID = {"securityLevel": "strict"}  # no HTML but Mermaid's own, sanitised; no clicks
COLOURS = ("#2563eb", "#dc2626", "#059669", "#d97706", "#7c3aed", "#0891b2", "#db2777",
           "#65a30d", "#475569", "#ea580c")


def fsa_files(config: ViewerConfig) -> list[Path]:
    """The FSA files the pages offer: the given file, then ``*.fsa.yaml``, ``best.yaml`` and
    ``best_evolved.yaml`` below the root (hidden folders skipped, linked folders not
    entered, links leading outside the root left out)."""
    out: list[Path] = [config.file] if config.file is not None else []
    names = ("best.yaml", "best_evolved.yaml")
    out += [p for p in walk_below(config.root, lambda n: n.endswith(".fsa.yaml") or n in names,
                                  max_depth=MAX_LIST_DEPTH, max_files=MAX_FILES)
            if p not in out]
    return out[:MAX_FILES]


def live_files(root: Path) -> list[Path]:
    return list(walk_below(root, lambda n: n.endswith(LIVE_SUFFIX),
                           max_depth=MAX_LIST_DEPTH, max_files=MAX_FILES))


def _error_text(exc: BaseException, limit: int = MAX_ERROR_CHARS) -> str:
    """An error as a page shows it: printable (one line, or one line per problem listed),
    at most ``limit`` characters."""
    return clip(printable(exc), limit)


def _error(text: str) -> None:
    ui.label(text).classes("text-red-700 whitespace-pre-wrap").props("data-testid=error")


def _safe(where: str, build: Callable[[], None]) -> None:
    """Run a page part; show what went wrong as one line instead of a traceback."""
    try:
        build()
    except SkillcomposeError as exc:
        _error(f"{where}: {_error_text(exc)}")
    except Exception as exc:
        log.warning("%s: %s: %s", where, type(exc).__name__, clip(one_line(str(exc)), 300))
        _error(f"{where}: unexpected {type(exc).__name__}: {_error_text(exc, 300)}")


def _raise(exc: BaseException) -> None:
    raise exc


def _header(active: str) -> None:
    with ui.header().classes("items-center bg-slate-800 py-2 px-4 gap-6"):
        ui.label("skillcompose view").classes("text-lg font-semibold text-white")
        for name, url in (("Runs", "/"), ("FSA", "/fsa"), ("Replay", "/replay"),
                          ("Live", "/live")):
            link = ui.link(name, url).classes("text-white no-underline text-base")
            if name == active:
                link.classes("border-b-2 border-amber-400 font-semibold")


def _fmt(value: float | None, digits: int = 4) -> str:
    return "–" if value is None else f"{value:.{digits}g}"


def _task_registry(target: str | None, settings: Mapping[str, Any]) -> tuple[Registry | None,
                                                                            str]:
    if not target:
        return None, ""
    task = load_task(target, **dict(settings))
    return task.registry, f"task {task.name}"


def _address(**values: str) -> str | None:
    """Why a page's address cannot be used (its first bad value), or None."""
    for name, value in values.items():
        problem = address_problem(name, value)
        if problem is not None:
            return problem
    return None


def _file_of(config: ViewerConfig, text: str) -> Path:
    """The file a page's address names: relative to the root unless absolute."""
    path = Path(text)
    return path if path.is_absolute() else config.root / path


def _task_of_run(root: Path, path: Path) -> tuple[str | None, dict[str, Any]]:
    """The task module and settings of the run directory holding ``path`` (inside
    ``root``), if any."""
    try:
        info, problem = read_run_info(path.parent, root)
    except (FileNotFoundError, ValueError):
        return None, {}
    module = str(info.get("task_module", ""))
    if problem or not module:
        return None, {}
    settings = info.get("task_settings") or {}
    return module, dict(settings) if isinstance(settings, dict) else {}


# ---------------------------------------------------------------------------------------
# runs
# ---------------------------------------------------------------------------------------
def _run_row(run: RunSummary) -> dict[str, Any]:
    return {
        "name": run.name, "task": run.task, "status": run.status,
        "generations": f"{run.generations}+ (reading)" if run.reading else run.generations,
        "best": _fmt(run.best), "success": run.success_text,
        "settings": run.settings + (f" ({run.problem})" if run.problem else ""),
        "seed": "–" if run.seed is None else run.seed,
        "fsa_url": "/fsa?" + urlencode({"path": f"{run.name}/best.yaml"}),
        "replay_url": "/replay?" + urlencode({
            "path": str(run.path / "best.yaml"), "task": run.task_module,
            "settings": run.task_settings, "seed": 0}),
    }


def _chart_options(runs: list[RunSummary], chosen: set[str]) -> dict[str, Any]:
    series = [{
        "name": run.name, "type": "line", "showSymbol": True, "symbolSize": 5,
        "color": COLOURS[k % len(COLOURS)], "data": [list(p) for p in run.points],
    } for k, run in enumerate(r for r in runs if r.name in chosen)]
    return {
        "animation": False,
        "title": {"text": "best fitness per generation", "left": "center",
                  "textStyle": {"fontSize": 14}},
        "tooltip": {"trigger": "axis"},
        "legend": {"top": 24, "type": "scroll"},
        "grid": {"left": 60, "right": 30, "top": 60, "bottom": 50},
        "xAxis": {"type": "value", "name": "generation", "nameLocation": "middle",
                  "nameGap": 28, "minInterval": 1},
        "yAxis": {"type": "value", "name": "best fitness", "scale": True},
        "series": series,
    }


def _runs_page(config: ViewerConfig) -> None:
    """The runs table and chart; filled, and kept up to date, by a timer whose reads of the
    run directories run in a worker thread (the histories read incrementally and bounded,
    :mod:`.data`), so that a large history never holds up other pages."""
    _header("Runs")
    ui.label(f"Runs under {_shown(config, config.root)}").classes("text-xl font-semibold")
    count = ui.label("").props("data-testid=run-count").classes("text-slate-600")
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
    ui.label("Tick runs to compare them on the chart; FSA opens a run's best FSA, replay "
             "runs it once.") \
        .classes("text-sm text-slate-500")
    chart = ui.echart(_chart_options([], set())) \
        .classes("w-full h-96").props("data-testid=fitness-chart")
    chart.classes("fitness-chart")
    state: dict[str, Any] = {"key": None, "runs": None, "first": True}

    def show(current: list[RunSummary], force: bool) -> None:
        if state["first"]:  # the first listing ticks the first runs
            state["first"] = False
            table.selected = [_run_row(r) for r in current[: len(COLOURS)]]
        chosen = {r["name"] for r in table.selected}
        key = tuple(current), tuple(sorted(chosen))
        count.text = f"{len(current)} run(s)"
        if key == state["key"] and not force:
            return
        state["key"] = key
        names = {r.name for r in current}
        table.rows = [_run_row(r) for r in current]
        table.selected = [row for row in table.selected if row["name"] in names]
        table.update()
        chart.options.clear()
        chart.options.update(_chart_options(current, {r["name"] for r in table.selected}))
        chart.update()

    async def refresh() -> None:
        try:
            current = await background.io_bound(find_runs, config.root)
        except Exception as exc:  # as _safe: one line in the page, never a traceback
            count.text = f"runs: unexpected {type(exc).__name__}: {_error_text(exc, 300)}"
            return
        if current is not None:
            state["runs"] = current
            _safe("runs", lambda: show(current, False))

    def reselect() -> None:
        if state["runs"] is not None:
            _safe("runs", lambda: show(state["runs"], True))

    table.on_select(lambda _: reselect())
    ui.timer(REFRESH_S, refresh)


# ---------------------------------------------------------------------------------------
# FSA files
# ---------------------------------------------------------------------------------------
def _outside(config: ViewerConfig, chosen: Path) -> None:
    _error(f"{chosen}: not below {_shown(config, config.root)} (links followed); the viewer "
           "shows only files there")


def _fsa_page(config: ViewerConfig, path: str, task: str, request: str | None = None) -> None:
    _header("FSA")
    ui.add_head_html(STYLE)
    bad = _address(path=path, task=task)
    if bad is not None:
        _error(bad)
        return
    files = fsa_files(config)
    chosen = _file_of(config, path) if path else (files[0] if files else None)
    options = {str(f): _rel(config, f) for f in files}
    if chosen is not None:
        options.setdefault(str(chosen), _rel(config, chosen))
    # a task this page will not import is not carried to the next one either (another
    # site's link would otherwise need only one click on the viewer's own controls)
    carried = task if task and task_refusal(config, task, request) is None else ""
    with ui.row().classes("items-center gap-4 w-full"):
        ui.select(options, value=str(chosen) if chosen else None, label="FSA file",
                  on_change=lambda e: ui.navigate.to(
                      "/fsa?" + urlencode({"path": e.value, "task": carried}))) \
            .classes("min-w-[28rem]").props("data-testid=fsa-select")
    if chosen is None:
        ui.label(f"No FSA file under {_shown(config, config.root)} (files named *.fsa.yaml "
                 "or best.yaml).")
        return
    root = file_below(config, chosen)
    if root is None:
        _outside(config, chosen)
        return

    def build() -> None:
        assert chosen is not None and root is not None
        target, settings = (task or config.task), dict(config.settings)
        if not target:
            target, settings = _task_of_run(root, chosen)
        refusal = task_refusal(config, target, request) if target else None
        if refusal is None and target:
            settings, refusal = checked_settings(config, settings)
        registry, what = None, ""
        if refusal is not None:
            ui.label(refusal).classes("text-orange-700").props("data-testid=task-refused")
        else:
            try:
                registry, what = _task_registry(target, settings)
            except SkillcomposeError as exc:  # it may quote other files: a short line
                ui.label(f"task {target}: {_error_text(exc, MAX_TASK_ERROR_CHARS)}") \
                    .classes("text-orange-700").props("data-testid=task-error")
        view = read_fsa(chosen, registry, what, root=root)
        _fsa_body(view, _shown(config, view.path))

    _safe(_shown(config, chosen), build)


def _shown(config: ViewerConfig, path: Path) -> str:
    """``path`` as the person named it: below the root as given on the command line."""
    try:
        rel = path.resolve().relative_to(config.root.resolve())
    except (ValueError, OSError):
        return str(path)
    if not config.label:
        return str(path)
    return str(Path(config.label) / rel) if rel.parts else config.label


def _rel(config: ViewerConfig, path: Path) -> str:
    try:
        return str(path.relative_to(config.root))
    except ValueError:
        return str(path)


def _fsa_body(view: FSAView, shown: str) -> None:
    fsa = view.fsa
    with ui.row().classes("w-full no-wrap gap-6 items-start"):
        with ui.column().classes("w-3/5 min-w-0 gap-2"):
            if view.problems:
                with ui.card().classes("w-full bg-red-50").props("data-testid=problems"):
                    ui.label(f"{len(view.problems)} problem(s) in {view.path.name}") \
                        .classes("font-semibold text-red-800")
                    for p in view.problems:
                        ui.label(p.render(shown)).classes("text-sm text-red-800") \
                            .props("data-testid=problem")
            if fsa is not None:
                ui.label(f"{fsa.name}: {len(fsa.states)} states, start {fsa.start}, "
                         f"terminals {', '.join(fsa.terminals)}, step limit {fsa.step_limit}") \
                    .classes("font-semibold").props("data-testid=fsa-summary")
                if view.checked_against:
                    ui.label(f"valid; {view.checked_against}").classes("text-sm text-green-700")
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
            ui.html(yaml_html(view)).classes("w-full") \
                .props("data-testid=yaml")  # escaped here, and sanitised (DOMPurify) there


# ---------------------------------------------------------------------------------------
# replay
# ---------------------------------------------------------------------------------------
async def _replay_page(config: ViewerConfig, path: str, task: str, seed: str, settings: str,
                       backend: str, request: str | None = None) -> None:
    _header("Replay")
    bad = _address(path=path, task=task, seed=seed, settings=settings, backend=backend)
    if bad is not None:
        _error(bad)
        return
    files = fsa_files(config)
    chosen = str(_file_of(config, path)) if path else (str(files[0]) if files else "")
    root = file_below(config, Path(chosen)) if chosen else None
    target = task or config.task or ""
    if not target and root is not None:
        target = _task_of_run(root, Path(chosen))[0] or ""
    setting_text = settings or ", ".join(f"{k}={v}" for k, v in config.settings.items())
    number = seed_of(seed)
    with ui.row().classes("items-end gap-4 w-full"):
        file_in = ui.select({str(f): _rel(config, f) for f in files} | (
            {chosen: chosen} if chosen and chosen not in {str(f) for f in files} else {}),
            value=chosen or None, label="FSA file").classes("min-w-[24rem]")
        refusal = task_refusal(config, target, request) if target else None
        task_in = ui.input("task module", value="" if refusal else target).classes("w-56") \
            .props("data-testid=task-input")  # a refused task is not offered to Run
        set_in = ui.input("settings (name=value, ...)", value=setting_text).classes("w-56")
        backend_in = ui.input("backend", value=backend, placeholder="the task's").classes("w-36")
        seed_in = ui.number("seed", value=number if isinstance(number, int) else 0, min=0,
                            precision=0).classes("w-24")

        def go() -> None:
            ui.navigate.to("/replay?" + urlencode({
                "path": file_in.value or "", "task": task_in.value or "",
                "seed": int(seed_in.value or 0), "settings": set_in.value or "",
                "backend": backend_in.value or ""}))

        ui.button("Run", on_click=go).props("data-testid=run-button")
    if not (chosen and target):
        ui.label("Choose an FSA file and a task module (e.g. examples.pour_water), then Run.")
        return
    if root is None:
        _outside(config, Path(chosen))
        return
    if isinstance(number, str):
        _error(number)
        return
    if refusal is not None:
        ui.label(refusal).classes("text-orange-700").props("data-testid=task-refused")
        return
    try:
        chosen_settings, refusal = checked_settings(config, parse_settings(
            [s.strip() for s in setting_text.split(",") if s.strip()]))
    except SkillcomposeError as exc:
        _error(f"replay: {_error_text(exc, MAX_TASK_ERROR_CHARS)}")
        return
    if refusal is not None:
        ui.label(refusal).classes("text-orange-700").props("data-testid=task-refused")
        return
    await _replay_episode(Path(chosen), root, target, number, chosen_settings, backend)


async def _replay_episode(path: Path, root: Path, target: str, seed: int,
                          settings: Mapping[str, Any], backend: str) -> None:
    """Read the FSA (inside ``root``), run its episode and show it. The episode runs in a
    worker thread, so a long one does not stop the server answering other pages meanwhile;
    this page is sent when it ends (see REPLAY_TIMEOUT_S)."""
    holder = ui.column().classes("w-full")
    try:
        fsa = read_fsa_file(path, root)  # the file asked for: its problems in full
    except SkillcomposeError as exc:
        with holder:
            _error(f"replay: {_error_text(exc)}")
        return
    try:
        episode = await background.io_bound(run_episode, path, target, seed, settings,
                                            backend=backend.strip() or None, fsa=fsa)
        failure = None
    except Exception as exc:  # shown by _safe below, as every page part's errors are
        episode, failure = None, exc

    def build() -> None:
        if isinstance(failure, SkillcomposeError) and not isinstance(
                failure, FSAValidationError):  # the task's: it may quote other files
            _error(f"replay: {_error_text(failure, MAX_TASK_ERROR_CHARS)}")
            return
        if failure is not None:
            raise failure
        assert episode is not None
        _episode_view(episode)

    with holder:
        _safe("replay", build)


def _episode_view(ep: Episode) -> None:
    n = len(ep.frames) - 1
    ui.label(f"{ep.path.name} on task {ep.task}, backend {ep.backend}, seed {ep.seed}: "
             f"{ep.outcome} after {ep.steps} step(s)").classes("font-semibold") \
        .props("data-testid=episode-summary")
    pos = {"k": 0}
    with ui.row().classes("items-center gap-2 w-full"):
        first = ui.button(icon="first_page", on_click=lambda: show(0)) \
            .props("flat data-testid=first").tooltip("the world before the first step")
        back = ui.button("back", icon="chevron_left", on_click=lambda: show(pos["k"] - 1)) \
            .props("data-testid=back")
        fwd = ui.button("forward", on_click=lambda: show(pos["k"] + 1)) \
            .props("icon-right=chevron_right data-testid=forward")
        last = ui.button(icon="last_page", on_click=lambda: show(n)) \
            .props("flat data-testid=last").tooltip("the last step")
        slider = ui.slider(min=0, max=max(n, 1), value=0,
                           on_change=lambda e: show(int(e.value))).classes("w-64")
        step_label = ui.label("").classes("text-base").props("data-testid=step-label")
    active_label = ui.label("").classes("hidden").props("data-testid=active-state")
    robot: Callable[[Mapping[str, Any] | None], None] | None = None
    with ui.row().classes("w-full no-wrap gap-6 items-start"):
        with ui.column().classes("w-2/5" if ep.kinematic else "w-1/2"):
            graph = ui.mermaid(mermaid(ep.fsa, active=ep.fsa.start), config=MERMAID) \
                .classes("fsa-graph w-full").props("data-testid=replay-graph")
        with ui.column().classes("w-3/5 gap-2" if ep.kinematic else "w-1/2 gap-2"):
            if ep.kinematic:
                robot = _robot_scene(ep)
            else:
                changes, board = _step_tables()
    if ep.kinematic:
        with ui.row().classes("w-full no-wrap gap-6 items-start"):
            changes, board = _step_tables(half=True)

    def show(k: int) -> None:
        k = max(0, min(n, k))
        pos["k"] = k
        f = ep.frames[k]
        if f.state is None:
            text = f"step 0 of {n}: the world before the first step; start {ep.fsa.start}"
            active = ep.fsa.start
        else:
            text = f"step {k} of {n}: {f.state} ({f.skill}) → {f.outcome} → {f.target}"
            active = f.state
        step_label.text = text
        active_label.text = active or ""
        graph.set_content(mermaid(ep.fsa, active=active))
        changes.rows = [{"key": key, "before": a, "after": b}
                        for key, (a, b) in f.changes.items()]
        board.rows = [{"key": key, "value": v} for key, v in f.blackboard.items()]
        if slider.value != k:
            slider.value = k
        for b, on in ((first, k > 0), (back, k > 0), (fwd, k < n), (last, k < n)):
            b.set_enabled(on)
        if robot is not None:
            robot(f.robot)

    show(0)


def _step_tables(half: bool = False) -> tuple[Any, Any]:
    """The tables of what a step changed and of the blackboard after it."""
    tables = []
    for title, cols, testid in (("changed in this step", ("key", "before", "after"), "changes"),
                                ("blackboard after this step", ("key", "value"), "blackboard")):
        with ui.column().classes("w-1/2 gap-1" if half else "w-full gap-1"):
            ui.label(title).classes("font-semibold")
            tables.append(ui.table(columns=[
                {"name": c, "label": c, "field": c, "align": "left"} for c in cols],
                rows=[], row_key="key").classes("w-full")
                .props(f"dense flat bordered wrap-cells data-testid={testid}"))
    return tables[0], tables[1]


def _robot_scene(ep: Episode) -> Callable[[Mapping[str, Any] | None], None]:
    """The PR2, table and objects in 3D; returns the function that poses them for a frame."""
    from .robot3d import pieces

    ui.label("the PR2, the table and the objects (drag to turn, scroll to zoom)") \
        .classes("font-semibold")
    scene = ui.scene(width=820, height=620, grid=(4, 16), background_color="#f1f5f9") \
        .props("data-testid=robot-scene")
    objects: list[Any] = []
    boxes: dict[str, Any] = {}
    with scene:
        for piece in pieces():
            obj: Any
            if piece.kind == "mesh":
                obj = scene.stl(f"/pr2-meshes/{piece.mesh}").scale(*piece.scale)
            elif piece.kind == "box":
                obj = scene.box(piece.size[0], piece.size[1], piece.size[2])
            else:
                obj = scene.cylinder(piece.size[0], piece.size[0], piece.size[1])
            objects.append(obj.material(piece.colour))
    scene.move_camera(x=-0.35, y=-1.45, z=1.45, look_at_x=0.45, look_at_y=0.0,
                      look_at_z=0.7, duration=0.0)

    def pose(frame: Mapping[str, Any] | None) -> None:
        if frame is None:
            return
        for obj, (p, rot) in zip(objects, frame["poses"], strict=True):
            obj.move(*p).rotate_R(rot)
        for b in frame["boxes"]:
            if b.name not in boxes:
                with scene:
                    colour = "#a16207" if "table" in b.name else "#16a34a"
                    boxes[b.name] = scene.box(b.size[0], b.size[1], b.size[2]) \
                        .material(colour, opacity=0.85).with_name(f"box:{b.name}")
            boxes[b.name].move(*b.centre).rotate(0.0, 0.0, b.yaw)

    return pose


# ---------------------------------------------------------------------------------------
# live
# ---------------------------------------------------------------------------------------
def _live_page(config: ViewerConfig) -> None:
    _header("Live")
    ui.label(f"FSAs publishing their state under {_shown(config, config.root)} "
             f"(files *{LIVE_SUFFIX})") \
        .classes("text-xl font-semibold")
    ui.label("A program publishes with skillcompose.view.live.LivePublisher; try "
             "python examples/live_patrol.py --out DIR.").classes("text-sm text-slate-500")
    holder = ui.column().classes("w-full gap-4")
    cards: dict[Path, dict[str, Any]] = {}
    state: dict[str, Any] = {"empty": None, "paths": [], "listed": 0.0}

    def show(records: list[tuple[Path, dict[str, Any] | None]]) -> None:
        paths = [p for p, _ in records]
        if not paths and state["empty"] is None:
            with holder:
                state["empty"] = ui.label("No live file yet; this page updates by itself.") \
                    .props("data-testid=no-live")
        for path, record in records:
            if record is None:
                continue
            if state["empty"] is not None:
                state["empty"].delete()
                state["empty"] = None
            card = cards.get(path)
            if card is None:
                card = cards[path] = _live_card(holder, config, path)
            card["update"](record)  # each card shows its own file's problem
        for gone in [p for p in cards if p not in paths]:
            cards.pop(gone)["card"].delete()

    def read() -> list[tuple[Path, dict[str, Any] | None]]:  # in a worker thread
        if time.monotonic() - state["listed"] >= LIVE_LIST_S:  # a new file: once a second
            state["paths"], state["listed"] = live_files(config.root), time.monotonic()
        return [(p, read_live(p, config.root)) for p in state["paths"]]

    async def refresh() -> None:
        try:
            records = await background.io_bound(read)
        except Exception as exc:  # as _safe: one line in the page, never a traceback
            records, failure = None, exc
            _safe("live", lambda: _raise(failure))
        if records is not None:
            _safe("live", lambda: show(records))

    ui.timer(LIVE_REFRESH_S, refresh)


def _live_card(holder: Any, config: ViewerConfig, path: Path) -> dict[str, Any]:
    from skillcompose.fsafile import loads_fsa

    with holder, ui.card().classes("w-full") as card:
        card.props["data-testid"] = "live-card"
        card.props["data-file"] = path.name  # a value, never parsed as props
        title = ui.label(_rel(config, path)).classes("font-semibold")
        status = ui.label("").props("data-testid=live-status")
        active = ui.label("").classes("hidden").props("data-testid=live-active")
        with ui.row().classes("w-full no-wrap gap-6 items-start"):
            graph = ui.mermaid("flowchart TD\n  wait[waiting]", config=MERMAID) \
                .classes("fsa-graph w-1/2").props("data-testid=live-graph")
            board = ui.table(columns=[{"name": c, "label": c, "field": c, "align": "left"}
                                      for c in ("key", "value")], rows=[], row_key="key") \
                .classes("w-1/2").props("dense flat bordered")
    memo: dict[str, Any] = {"text": None, "fsa": None, "shown": None}

    def update(record: dict[str, Any]) -> None:
        problem = live_problem(record)
        if problem is not None:
            status.text = f"{_rel(config, path)} cannot be shown: {problem}"
            return
        if record["fsa"] != memo["text"]:
            memo["text"] = record["fsa"]
            try:
                memo["fsa"] = loads_fsa(record["fsa"], str(path))
            except SkillcomposeError as exc:
                memo["fsa"] = None
                status.text = f"its FSA cannot be read: {_error_text(exc)}"
        fsa = memo["fsa"]
        if fsa is None:
            return
        state, done, outcome = record.get("state"), record["done"], record.get("outcome")
        steps, pid = record["steps"], record.get("pid")
        title.text = f"{clip(record.get('name') or fsa.name, 200)} ({_rel(config, path)}), " \
            f"process {pid}"
        skill = fsa.states[state].skill if state in fsa.states else "?"
        gone = not done and isinstance(pid, int) and not pid_alive(pid)
        status.text = (f"ended: {outcome} after {steps} step(s)" if done else
                       f"stopped: process {pid} is gone; it was in {state} ({skill}) after "
                       f"{steps} step(s)" if gone else
                       f"running: {state} ({skill}), {steps} step(s) done")
        active.text = str(state if not done else outcome)
        shown = (state, done, outcome)
        if shown != memo["shown"]:
            memo["shown"] = shown
            graph.set_content(mermaid(fsa, active=None if done else state,
                                      ended=outcome if done else None))
        board.rows = [{"key": clip(str(k), 200), "value": clip(str(v), 200)}
                      for k, v in list((record.get("blackboard") or {}).items())[:500]]

    def guarded(record: dict[str, Any]) -> None:
        try:
            update(record)
        except Exception as exc:  # this card's file only; the others go on
            status.text = f"{_rel(config, path)} cannot be shown: " \
                f"{type(exc).__name__}: {_error_text(exc, 300)}"

    return {"card": card, "update": guarded}


# ---------------------------------------------------------------------------------------
def build(config: ViewerConfig) -> None:
    """Register the pages (and the PR2's meshes as static files) for ``config``, behind
    :class:`.guard.Guard` (security headers and the Content-Security-Policy on every
    response; the Host, Origin and fetch-metadata checks and, with a token, the token)."""
    app.add_middleware(Guard, token=config.token, cookie=cookie_name(config.port),
                       remote=config.remote)

    @ui.page("/", title="skillcompose view: runs")
    def runs_page() -> None:
        _safe("runs", lambda: _runs_page(config))

    @ui.page("/fsa", title="skillcompose view: FSA")
    def fsa_page(request: Request, path: str = "", task: str = "") -> None:
        _safe("FSA", lambda: _fsa_page(config, path, task, request_refusal(request.headers)))

    @ui.page("/replay", title="skillcompose view: replay", response_timeout=REPLAY_TIMEOUT_S)
    async def replay_page(request: Request, path: str = "", task: str = "", seed: str = "0",
                          settings: str = "", backend: str = "") -> None:
        try:
            await _replay_page(config, path, task, seed, settings, backend,
                               request_refusal(request.headers))
        except Exception as exc:  # as _safe: one line, never a traceback in the page
            failure = exc
            _safe("replay", lambda: _raise(failure))

    @ui.page("/live", title="skillcompose view: live")
    def live_page() -> None:
        _safe("live", lambda: _live_page(config))

    try:
        from .robot3d import mesh_root
    except ImportError:  # pragma: no cover - Pinocchio is a dependency of skillcompose
        return
    try:
        app.add_static_files("/pr2-meshes", mesh_root())
    except Exception as exc:
        print(f"skillcompose view: the PR2's meshes cannot be served: {exc}", file=sys.stderr)
