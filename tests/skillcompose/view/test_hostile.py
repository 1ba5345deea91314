"""Opening what someone sent you runs no script: hostile text in every field the viewer shows.

A folder made by someone else holds script in every value the pages show: the FSA's name,
state, skill, parameter and outcome names, parameter values and comments, run-folder and
live-file names, every value of ``run.json`` and of a live file, the blackboard of a replay
(keys and values, from a task file given on the command line), and a page's own address.
Each payload tries another way in: HTML (``<img onerror>``, ``<svg onload>``,
``<script>``), a NiceGUI ``:``-prop (evaluated as JavaScript), a Vue ``{{ }}`` expression, a
JavaScript template literal, a Mermaid directive and a ``javascript:`` link. Each sets
``window.__pwned`` and fetches a marker address served by a small handler here; the test
fails on a dialog, on ``window.__pwned``, on a request to the marker, and (as every browser
test) on any console error (a refused inline script is one) or failed request. Each page
must also show the hostile text as text.
"""

from __future__ import annotations

import http.server
import json
import os
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any, ClassVar
from urllib.parse import urlencode

import pytest

from .conftest import REPO, Page, Viewer, append_generation, free_port, start_viewer, wait_for
from .test_browser import runs_table

pytestmark = [pytest.mark.slow, pytest.mark.browser]

MARK_PORT = free_port()
MARK = f"http://127.0.0.1:{MARK_PORT}/pwned"
JS = f"window.__pwned=1;fetch('{MARK}')"
TEXT = (f'<img src=x onerror="{JS}"> <script>{JS}</script> " :x="{JS}" '
        f"{{{{ (window.__pwned=1) }}}} ${{window.__pwned=1}} `);{JS};(` "
        f"%%{{init: {{'securityLevel':'loose'}}}}%% <a href=\"javascript:{JS}\">a</a> "
        f"click s0 call alert(1) <svg onload=\"{JS}\"></svg> </script><b>bold</b>")
"""Free text: names of FSAs, skills, parameters and outcomes, values, comments."""
NAME = f"<img/src=x/onerror={JS}>{{{{window.__pwned=1}}}}:x=1%%{{init:{{}}}}%%"
"""A name without spaces (a state's)."""
FILE = '<img src=x onerror="window.__pwned=1"> :x="window.__pwned=1" {{window.__pwned=1}}'
"""A file or folder name (no slash)."""
SHOWN = TEXT[:30]
"""What of TEXT every place shows (a table cell cuts a long value; a blackboard value is
its repr, cut)."""

BAD_RUNS = {"bad_settings": json.dumps({"task": "t", "task_settings": [1, 2]}),
            "bad_text": '{"task": "\\ud800"}',
            "bad_seed": json.dumps({"task": "t", "seed": 10**30})}
"""run.json files with one bad value each."""

TASK = f'''
from typing import Literal

import numpy as np

from skillcompose import Blackboard, Registry, skill
from skillcompose.task import Task

TEXT = {TEXT!r}


@skill(writes={{"note": str, TEXT: str}})
def Hostile(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    bb["note"] = TEXT
    bb[TEXT] = TEXT
    return "success"


def make_task() -> Task:
    return Task(name="hostile", registry=Registry([Hostile]),
                setup=lambda rng: Blackboard({{TEXT: TEXT}}), fitness=lambda r, bb: 0.0)
'''


def fsa_text(state: str = NAME, skill: str = TEXT, *, broken: bool = False) -> str:
    q = json.dumps
    target = q(state + "2") if not broken else q(state + "-nowhere")
    if skill == "Hostile":  # one the hostile task runs: its outcomes, no parameters
        return f"""format: 1
name: {q(TEXT)}
start: {q(state)}
terminals: [success, failure]
states:
  {q(state)}:
    skill: Hostile
    transitions: {{success: {q(state + "2")}, failure: failure}}
  {q(state + "2")}:
    skill: Hostile
    transitions: {{success: success, failure: failure}}
"""
    return f"""format: 1
name: {q(TEXT)}
# {TEXT}
start: {q(state)}
terminals: [success, failure]
states:
  {q(state)}:  # {TEXT}
    skill: {q(skill)}
    params: {{{q(TEXT)}: {q(TEXT)}}}
    transitions: {{{q(TEXT)}: {target}, success: success}}
  {q(state + "2")}:
    skill: Hostile
    transitions: {{success: success, failure: failure}}
"""


class Marker(http.server.BaseHTTPRequestHandler):
    hits: ClassVar[list[str]] = []

    def do_GET(self) -> None:
        Marker.hits.append(self.path)
        self.send_response(204)
        self.end_headers()

    def log_message(self, *args: Any) -> None:
        pass


@pytest.fixture(scope="module")
def marker() -> Iterator[list[str]]:
    server = http.server.ThreadingHTTPServer(("127.0.0.1", MARK_PORT), Marker)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield Marker.hits
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=10)


@pytest.fixture(scope="module")
def hostile(tmp_path_factory: pytest.TempPathFactory, marker: list[str]
            ) -> Iterator[tuple[Viewer, Path, Path]]:
    """A folder of hostile runs, FSA files and live files, and the viewer over it, given
    the hostile task file on its command line (outside the folder)."""
    base = tmp_path_factory.mktemp("hostile")
    root = base / "runs"
    run = root / FILE
    run.mkdir(parents=True)
    (run / "run.json").write_text(json.dumps({
        "task": TEXT, "task_module": TEXT, "seed": 3, "backend": TEXT, "workers": 2,
        "task_settings": {TEXT: TEXT, "p": 0.5},
        "config": {"population": TEXT, "generations": TEXT},
        "result": {"best_fitness": 0.5, "fresh": {"success_rate": 0.5, "holds": TEXT}},
    }))
    for g in range(3):
        append_generation(run, g)
    (run / "best.yaml").write_text(fsa_text())
    (root / f"{FILE}.fsa.yaml").write_text(fsa_text(broken=True))
    (root / "replay.fsa.yaml").write_text(fsa_text(skill="Hostile"))
    live = root / "live"
    live.mkdir()
    record = {"format": "skillcompose live state", "name": TEXT, "pid": 1, "started": 0.0,
              "time": 0.0, "state": NAME, "steps": 2, "done": False, "outcome": None,
              "last": {"state": TEXT}, "blackboard": {TEXT: TEXT, "x": TEXT},
              "fsa": fsa_text()}
    (live / f"{FILE}.live.json").write_text(json.dumps(record))
    (live / f"{FILE} ended.live.json").write_text(json.dumps(
        record | {"done": True, "outcome": TEXT, "state": None}))
    for name, text in BAD_RUNS.items():  # one bad value costs only its own row
        (root / name).mkdir()
        (root / name / "run.json").write_text(text)
    os.mkdir(bytes(root) + b"/not-utf8-\xff")  # a name no page can show: left out
    (root / "bad_seed" / "history.jsonl").write_text(
        '{"generation": 1000000000000000000000000000000, "best": 1e400}\n'
        '{"generation": 0, "best": 1}\n')
    (live / "a bad.live.json").write_text(json.dumps(record | {"blackboard": [1]}))
    (live / "b text.live.json").write_text(json.dumps(record).replace(
        '"steps"', '"\\udc00": 1, "steps"'))
    task = base / "hostile_task.py"
    task.write_text(TASK)
    viewer = start_viewer([str(root), "--task", str(task)], base / "view.log", REPO)
    try:
        yield viewer, root, task
    finally:
        code, text = viewer.stop()
        assert code in (0, 130), text
        assert "Traceback" not in text, text


def watch(page: Page) -> list[str]:
    dialogs: list[str] = []

    def dismiss(dialog: Any) -> None:
        dialogs.append(f"{dialog.type}: {dialog.message}")
        dialog.dismiss()

    page.page.on("dialog", dismiss)
    return dialogs


def untouched(page: Page, dialogs: list[str], marker: list[str]) -> None:
    page.page.wait_for_timeout(800)  # a late handler (an image failing to load) has run
    assert page.page.evaluate("() => window.__pwned") is None
    assert dialogs == []
    assert marker == []
    assert page.errors == []


def test_runs_page_shows_hostile_run_as_text(hostile: tuple[Viewer, Path, Path], page: Page,
                                             marker: list[str]) -> None:
    viewer, _, _ = hostile
    dialogs = watch(page)
    page.goto(viewer.url + "/")
    table = page.page.get_by_test_id("runs-table")
    wait_for(lambda: FILE in table.inner_text(), what="the hostile run's row")
    assert table.inner_text().count(SHOWN) >= 2  # the task, the settings: as they are
    rows = wait_for(lambda: set(BAD_RUNS) <= set(runs_table(page)) and runs_table(page),
                    what="the bad runs' rows")
    assert {name: rows[name][2] for name in BAD_RUNS} == dict.fromkeys(BAD_RUNS, "unreadable")
    assert "task_settings is a list" in rows["bad_settings"][7]
    assert "not Unicode" in rows["bad_text"][7] and "seed is outside" in rows["bad_seed"][7]
    assert len(rows) == 1 + len(BAD_RUNS)  # and not the folder whose name is not UTF-8
    box = page.page.locator(".fitness-chart canvas").first.bounding_box()
    assert box is not None
    page.page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.page.wait_for_timeout(500)  # the chart's tooltip names the run (HTML of ECharts)
    untouched(page, dialogs, marker)


def test_fsa_pages_show_hostile_names_as_text(hostile: tuple[Viewer, Path, Path],
                                              page: Page, marker: list[str]) -> None:
    viewer, _, _ = hostile
    dialogs = watch(page)
    for path in (f"{FILE}/best.yaml", f"{FILE}.fsa.yaml"):
        page.goto(viewer.url + "/fsa?" + urlencode({"path": path}))
        wait_for(lambda: page.page.locator("[data-testid=yaml]").count()
                 and (page.page.locator("[data-testid=fsa-graph] svg").count()
                      or page.page.get_by_test_id("problem").count()), what="the FSA")
        assert f"# {TEXT}" in page.page.get_by_test_id("yaml").inner_text()  # a comment
        if path.endswith("best.yaml"):
            wait_for(lambda: NAME in page.page.get_by_test_id("fsa-graph").inner_text(),
                     what="the state's name in the graph")
            assert SHOWN in page.page.get_by_test_id("states-table").inner_text()
        else:
            assert NAME in page.page.get_by_test_id("problem").first.inner_text()
        page.page.locator("[data-testid=fsa-select]").click()  # the files' names, listed
        page.page.wait_for_timeout(300)
        page.page.keyboard.press("Escape")
        untouched(page, dialogs, marker)


def test_replay_shows_hostile_blackboard_as_text(hostile: tuple[Viewer, Path, Path],
                                                 page: Page, marker: list[str]) -> None:
    viewer, _, task = hostile
    dialogs = watch(page)
    page.goto(viewer.url + "/replay?" + urlencode({"path": "replay.fsa.yaml",
                                                   "task": str(task)}))
    wait_for(lambda: page.page.get_by_test_id("episode-summary").count(), what="the episode")
    for _ in range(2):
        page.page.get_by_test_id("forward").click()
        page.page.wait_for_timeout(300)
    assert SHOWN in page.page.get_by_test_id("blackboard").inner_text()
    assert NAME in page.page.get_by_test_id("step-label").inner_text()
    untouched(page, dialogs, marker)


def test_live_page_shows_hostile_files_as_text(hostile: tuple[Viewer, Path, Path],
                                               page: Page, marker: list[str]) -> None:
    viewer, _, _ = hostile
    dialogs = watch(page)
    page.goto(viewer.url + "/live")
    wait_for(lambda: page.page.get_by_test_id("live-card").count() == 4, what="the cards")
    wait_for(lambda: page.page.locator("[data-testid=live-graph] svg").count() == 4,
             what="their graphs")
    statuses = "\n".join(page.page.get_by_test_id("live-status").all_inner_texts())
    assert "a bad.live.json cannot be shown: its blackboard is of type list" in statuses
    assert "b text.live.json cannot be shown: it holds text that is not Unicode" in statuses
    untouched(page, dialogs, marker)
    body = page.page.inner_text("body")
    assert FILE in body and f"ended: {TEXT}" in body
    names = page.page.locator("[data-testid=live-card]").evaluate_all(
        "els => els.map(e => e.dataset.file)")
    assert sorted(names) == sorted([f"{FILE}.live.json", f"{FILE} ended.live.json",
                                    "a bad.live.json", "b text.live.json"])


def test_hostile_addresses_are_shown_as_text(hostile: tuple[Viewer, Path, Path], page: Page,
                                             marker: list[str]) -> None:
    viewer, _, _ = hostile
    dialogs = watch(page)
    page.goto(viewer.url + "/fsa?" + urlencode({"path": TEXT, "task": TEXT}))
    wait_for(lambda: page.page.get_by_test_id("task-refused").count(), what="the refusal")
    assert f"task {SHOWN}" in page.page.get_by_test_id("task-refused").inner_text()
    address = {"path": "replay.fsa.yaml", "task": TEXT, "settings": f"a={TEXT}",
               "backend": TEXT}
    page.goto(viewer.url + "/replay?" + urlencode(address | {"seed": TEXT}))
    wait_for(lambda: page.page.get_by_test_id("error").count(), what="the seed's message")
    assert f"seed '{SHOWN}" in page.page.get_by_test_id("error").inner_text()
    page.goto(viewer.url + "/replay?" + urlencode(address))
    wait_for(lambda: page.page.get_by_test_id("task-refused").count(), what="the refusal")
    assert "not imported" in page.page.get_by_test_id("task-refused").inner_text()
    untouched(page, dialogs, marker)
