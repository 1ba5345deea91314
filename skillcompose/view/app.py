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

import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any
from urllib.parse import urlencode

from nicegui import app, ui
from nicegui import run as background
from starlette.requests import Request

from skillcompose.errors import FSAValidationError, SkillcomposeError, clip
from skillcompose.fsa import FSA
from skillcompose.registry import Registry
from skillcompose.task import load_task, parse_settings

from .common import (
    MAX_TASK_ERROR_CHARS,
    error_text,
    header,
    rel_path,
    reraise,
    safe,
    show_error,
    shown_path,
)
from .data import mermaid, pid_alive, read_fsa, read_run_info
from .episode import Episode, run_episode
from .folder import walk_below
from .fsa_parts import MERMAID, STYLE, fsa_body, problems_card, quiet_table, task_field
from .guard import Guard, cookie_name
from .live import LIVE_SUFFIX, live_problem, read_live
from .runs_page import show_runs
from .trust import (
    ViewerConfig,
    address_problem,
    checked_settings,
    file_below,
    request_refusal,
    seed_of,
    task_refusal,
)

__all__ = ["ViewerConfig", "build", "first_loading", "fsa_files", "live_files",
           "request_refusal", "task_refusal"]

LIVE_REFRESH_S = 0.25
REPLAY_TIMEOUT_S = 300.0  # the longest a replay's episode may take before its page fails
MAX_FILES = 500
MAX_LIST_DEPTH = 8  # how deep below the folder FSA and live files are looked for


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
# FSA files
# ---------------------------------------------------------------------------------------
def _outside(config: ViewerConfig, chosen: Path) -> None:
    show_error(f"{chosen}: not below {shown_path(config, config.root)} (links followed); the "
               "viewer shows only files there")


def _fsa_page(config: ViewerConfig, path: str, task: str, request: str | None = None) -> None:
    header("FSA")
    ui.add_head_html(STYLE)
    bad = _address(path=path, task=task)
    if bad is not None:
        show_error(bad)
        return
    files = fsa_files(config)
    chosen = _file_of(config, path) if path else (files[0] if files else None)
    options = {str(f): rel_path(config, f) for f in files}
    if chosen is not None:
        options.setdefault(str(chosen), rel_path(config, chosen))
    # a task this page will not import is not carried to the next one either (another
    # site's link would otherwise need only one click on the viewer's own controls)
    carried = task if task and task_refusal(config, task, request) is None else ""
    root = file_below(config, chosen) if chosen is not None else None
    target, settings = (task or config.task), dict(config.settings)
    if not target and chosen is not None and root is not None:
        target, settings = _task_of_run(root, chosen)
    refusal = task_refusal(config, target, request) if target else None
    with ui.row().classes("items-end gap-4 w-full"):
        ui.select(options, value=str(chosen) if chosen else None, label="FSA file",
                  on_change=lambda e: ui.navigate.to(
                      "/fsa?" + urlencode({"path": e.value, "task": carried}))) \
            .classes("min-w-[28rem]").props("data-testid=fsa-select")
        if chosen is not None:  # a refused task is not offered to Check
            task_field("" if refusal else target or "", lambda t: ui.navigate.to(
                "/fsa?" + urlencode({"path": str(chosen), "task": t})))
    if chosen is None:
        ui.label(f"No FSA file under {shown_path(config, config.root)} (files named "
                 "*.fsa.yaml or best.yaml).")
        return
    if root is None:
        _outside(config, chosen)
        return

    def build() -> None:
        assert chosen is not None and root is not None
        checked, refused = settings, refusal
        if refused is None and target:
            checked, refused = checked_settings(config, settings)
        registry, what = None, ""
        if refused is not None:
            ui.label(refused).classes("text-orange-700").props("data-testid=task-refused")
        else:
            try:
                registry, what = _task_registry(target, checked)
            except SkillcomposeError as exc:  # it may quote other files: a short line
                ui.label(f"task {target}: {error_text(exc, MAX_TASK_ERROR_CHARS)}") \
                    .classes("text-orange-700").props("data-testid=task-error")
        view = read_fsa(chosen, registry, what, root=root)
        fsa_body(view, shown_path(config, view.path))

    safe(shown_path(config, chosen), build)


# ---------------------------------------------------------------------------------------
# replay
# ---------------------------------------------------------------------------------------
async def _replay_page(config: ViewerConfig, path: str, task: str, seed: str, settings: str,
                       backend: str, request: str | None = None) -> None:
    header("Replay")
    bad = _address(path=path, task=task, seed=seed, settings=settings, backend=backend)
    if bad is not None:
        show_error(bad)
        return
    files = fsa_files(config)
    first = None if path else await background.io_bound(first_loading, config, files)
    found, broken = (_file_of(config, path), []) if path else first or (None, [])
    chosen = str(found) if found is not None else ""
    root = file_below(config, Path(chosen)) if chosen else None
    target = task or config.task or ""
    if not target and root is not None:
        target = _task_of_run(root, Path(chosen))[0] or ""
    setting_text = settings or ", ".join(f"{k}={v}" for k, v in config.settings.items())
    number = seed_of(seed)
    with ui.row().classes("items-end gap-4 w-full"):
        file_in = ui.select({str(f): rel_path(config, f) for f in files} | (
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
    if broken:
        _broken_note(config, broken, found is None)
    if not chosen:
        if not broken:
            ui.label(f"No FSA file under {shown_path(config, config.root)} (files named "
                     "*.fsa.yaml or best.yaml).")
        return
    if root is None:
        _outside(config, Path(chosen))
        return
    view = read_fsa(Path(chosen), root=root)
    if view.fsa is None or view.problems:  # its problems, each at its line
        problems_card(view, shown_path(config, view.path))
        ui.link("its lines, with the problems marked, on the FSA page",
                "/fsa?" + urlencode({"path": chosen})).classes("text-blue-700")
        return
    if not target:
        ui.label("Choose a task module (e.g. examples.pour_water), then Run.")
        return
    if isinstance(number, str):
        show_error(number)
        return
    if refusal is not None:
        ui.label(refusal).classes("text-orange-700").props("data-testid=task-refused")
        return
    try:
        chosen_settings, refusal = checked_settings(config, parse_settings(
            [s.strip() for s in setting_text.split(",") if s.strip()]))
    except SkillcomposeError as exc:
        show_error(f"replay: {error_text(exc, MAX_TASK_ERROR_CHARS)}")
        return
    if refusal is not None:
        ui.label(refusal).classes("text-orange-700").props("data-testid=task-refused")
        return
    await _replay_episode(view.fsa, Path(chosen), target, number, chosen_settings, backend)


def first_loading(config: ViewerConfig, files: list[Path]) -> tuple[Path | None, list[Path]]:
    """The first of ``files`` whose FSA loads (read as the FSA page reads it, without a
    task), and the files before it that do not."""
    broken: list[Path] = []
    for f in files:
        root = file_below(config, f)
        if root is not None:
            view = read_fsa(f, root=root)
            if view.fsa is not None and not view.problems:
                return f, broken
        broken.append(f)
    return None, broken


def _broken_note(config: ViewerConfig, broken: list[Path], none_loads: bool) -> None:
    names = ", ".join(rel_path(config, f) for f in broken[:3]) + (
        f" and {len(broken) - 3} more" if len(broken) > 3 else "")
    text = (f"No FSA file under {shown_path(config, config.root)} loads: {names} (each has "
            "problems; the FSA page shows them at their lines)." if none_loads else
            f"Skipped {len(broken)} FSA file(s) that do not load: {names} (the FSA page "
            "shows their problems); opened the first that does.")
    ui.label(text).classes("text-orange-700").props("data-testid=broken-files")


async def _replay_episode(fsa: FSA, path: Path, target: str, seed: int,
                          settings: Mapping[str, Any], backend: str) -> None:
    """Run the episode of ``fsa`` (read from ``path``) and show it. The episode runs in a
    worker thread, so a long one does not stop the server answering other pages meanwhile;
    this page is sent when it ends (see REPLAY_TIMEOUT_S)."""
    holder = ui.column().classes("w-full")
    try:
        episode = await background.io_bound(run_episode, path, target, seed, settings,
                                            backend=backend.strip() or None, fsa=fsa)
        failure = None
    except Exception as exc:  # shown by safe below, as every page part's errors are
        episode, failure = None, exc

    def build() -> None:
        if isinstance(failure, SkillcomposeError) and not isinstance(
                failure, FSAValidationError):  # the task's: it may quote other files
            show_error(f"replay: {error_text(failure, MAX_TASK_ERROR_CHARS)}")
            return
        if failure is not None:
            raise failure
        assert episode is not None
        _episode_view(episode)

    with holder:
        safe("replay", build)


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
    within = _substep_controls(ep)
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
        changes.props["no-data-label"] = "nothing has run yet" if f.state is None else \
            "this step changed nothing on the blackboard"
        changes.rows = [{"key": key, "before": a, "after": b}
                        for key, (a, b) in f.changes.items()]
        board.rows = [{"key": key, "value": v} for key, v in f.blackboard.items()]
        if slider.value != k:
            slider.value = k
        for b, on in ((first, k > 0), (back, k > 0), (fwd, k < n), (last, k < n)):
            b.set_enabled(on)
        if robot is not None:
            robot(f.robot)
        if within is not None and robot is not None:
            within(f.substeps, robot)

    show(0)


def _substep_controls(ep: Episode) -> Callable[[Any, Any], None] | None:
    """On a dynamic episode, a slider through the simulation's samples within the step shown
    (every ``SUBSTEP_S`` of simulated time); returns the function that loads a step's."""
    if not any(f.substeps for f in ep.frames):
        return None
    current: dict[str, Any] = {"substeps": (), "robot": None}
    with ui.row().classes("items-center gap-2 w-full"):
        ui.label("within the step (simulated time)").classes("text-sm")
        slider = ui.slider(min=0, max=1, value=0, on_change=lambda e: pick(int(e.value))) \
            .classes("w-64").props("data-testid=substep")
        label = ui.label("").classes("text-sm").props("data-testid=substep-label")

    def pick(j: int) -> None:
        subs, robot = current["substeps"], current["robot"]
        if not subs or robot is None:
            label.text = "no motion in this step"
            return
        j = max(0, min(len(subs) - 1, j))
        t, frame = subs[j]
        label.text = f"t = {t:.2f} s ({j + 1} of {len(subs)})"
        robot(frame)

    def load(substeps: Any, robot: Any) -> None:
        current["substeps"], current["robot"] = substeps, robot
        last = max(len(substeps) - 1, 0)
        slider.props(f"max={max(last, 1)}")
        slider.set_enabled(bool(substeps))
        if slider.value != last:
            slider.value = last  # its on_change shows the step's end
        else:
            pick(last)

    return load


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
            quiet_table(tables[-1], "the blackboard is empty")
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
                    colour = "#a16207" if "table" in b.name else \
                        "#2563eb" if b.name.startswith("particle_") else "#16a34a"
                    boxes[b.name] = scene.box(b.size[0], b.size[1], b.size[2]) \
                        .material(colour, opacity=0.85).with_name(f"box:{b.name}")
            boxes[b.name].move(*b.centre).rotate(0.0, 0.0, b.yaw)

    return pose


# ---------------------------------------------------------------------------------------
# live
# ---------------------------------------------------------------------------------------
def _live_page(config: ViewerConfig) -> None:
    header("Live")
    ui.label(f"FSAs publishing their state under {shown_path(config, config.root)} "
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
        if time.monotonic() - state["listed"] >= config.refresh:  # new files: each --refresh
            state["paths"], state["listed"] = live_files(config.root), time.monotonic()
        return [(p, read_live(p, config.root)) for p in state["paths"]]

    async def refresh() -> None:
        try:
            records = await background.io_bound(read)
        except Exception as exc:  # as safe: one line in the page, never a traceback
            records, failure = None, exc
            safe("live", lambda: reraise(failure))
        if records is not None:
            safe("live", lambda: show(records))

    ui.timer(LIVE_REFRESH_S, refresh)


def _live_card(holder: Any, config: ViewerConfig, path: Path) -> dict[str, Any]:
    from skillcompose.fsafile import loads_fsa

    with holder, ui.card().classes("w-full") as card:
        card.props["data-testid"] = "live-card"
        card.props["data-file"] = path.name  # a value, never parsed as props
        title = ui.label(rel_path(config, path)).classes("font-semibold")
        status = ui.label("").props("data-testid=live-status")
        active = ui.label("").classes("hidden").props("data-testid=live-active")
        with ui.row().classes("w-full no-wrap gap-6 items-start"):
            graph = ui.mermaid("flowchart TD\n  wait[waiting]", config=MERMAID) \
                .classes("fsa-graph w-1/2").props("data-testid=live-graph")
            board = ui.table(columns=[{"name": c, "label": c, "field": c, "align": "left"}
                                      for c in ("key", "value")], rows=[], row_key="key") \
                .classes("w-1/2").props("dense flat bordered")
            quiet_table(board, "nothing published on the blackboard")
    memo: dict[str, Any] = {"text": None, "fsa": None, "shown": None}

    def update(record: dict[str, Any]) -> None:
        problem = live_problem(record)
        if problem is not None:
            status.text = f"{rel_path(config, path)} cannot be shown: {problem}"
            return
        if record["fsa"] != memo["text"]:
            memo["text"] = record["fsa"]
            try:
                memo["fsa"] = loads_fsa(record["fsa"], str(path))
            except SkillcomposeError as exc:
                memo["fsa"] = None
                status.text = f"its FSA cannot be read: {error_text(exc)}"
        fsa = memo["fsa"]
        if fsa is None:
            return
        state, done, outcome = record.get("state"), record["done"], record.get("outcome")
        steps, pid = record["steps"], record.get("pid")
        title.text = f"{clip(record.get('name') or fsa.name, 200)} ({rel_path(config, path)}), " \
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
            status.text = f"{rel_path(config, path)} cannot be shown: " \
                f"{type(exc).__name__}: {error_text(exc, 300)}"

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
        safe("runs", lambda: show_runs(config))

    @ui.page("/fsa", title="skillcompose view: FSA")
    def fsa_page(request: Request, path: str = "", task: str = "") -> None:
        safe("FSA", lambda: _fsa_page(config, path, task, request_refusal(request.headers)))

    @ui.page("/replay", title="skillcompose view: replay", response_timeout=REPLAY_TIMEOUT_S)
    async def replay_page(request: Request, path: str = "", task: str = "", seed: str = "0",
                          settings: str = "", backend: str = "") -> None:
        try:
            await _replay_page(config, path, task, seed, settings, backend,
                               request_refusal(request.headers))
        except Exception as exc:  # as safe: one line, never a traceback in the page
            failure = exc
            safe("replay", lambda: reraise(failure))

    @ui.page("/live", title="skillcompose view: live")
    def live_page() -> None:
        safe("live", lambda: _live_page(config))

    try:
        from .robot3d import mesh_root
    except ImportError:  # pragma: no cover - Pinocchio is a dependency of skillcompose
        return
    try:
        app.add_static_files("/pr2-meshes", mesh_root())
    except Exception as exc:
        print(f"skillcompose view: the PR2's meshes cannot be served: {exc}", file=sys.stderr)
