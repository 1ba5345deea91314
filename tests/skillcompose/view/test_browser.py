"""``skillcompose view`` in a real headless Chromium: what the rendered pages show.

The viewer runs as ``python -m skillcompose view DIR`` on a free 127.0.0.1 port over a
fixture folder (a toy evolution made by ``skillcompose evolve``, a run being written, the
pour-water FSA); each test reads the page as a person sees it (tables, the chart's series,
the graph's nodes and edges, the active state) and fails on any error in the browser's
console or any failed request. The viewer fixture stops the server with Ctrl-C and fails if
it printed a traceback.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any
from urllib.parse import urlencode

import pytest

from examples.live_patrol import dock, drive_to_next, patrol_fsa, scan_room
from skillcompose import Blackboard, Registry, load_fsa, load_task
from skillcompose.executor import compile_fsa
from skillcompose.view.data import fresh_text
from skillcompose.view.live import LivePublisher

from .conftest import REPO, Page, Viewer, append_generation, start_viewer, wait_for

pytestmark = [pytest.mark.slow, pytest.mark.browser]


def runs_table(page: Page) -> dict[str, list[str]]:
    """The runs table's rows by run name: name, task, status, generations (the last one's
    index), best (and its note, on a line of its own), fresh success, seed, settings (read in
    one go, so a refresh cannot tear it)."""
    rows = page.page.evaluate("""() => [...document.querySelectorAll(
            '[data-testid=runs-table] tbody tr')].map(tr => {
        const tds = [...tr.querySelectorAll('td')];
        const name = tds.length > 1 ? tds[1].querySelector('span') : null;
        return name ? [name.textContent.trim(), ...tds.slice(2).map(td => td.innerText.trim())]
                    : null;
    }).filter(r => r)""")
    return {r[0]: r for r in rows}


def chart_points(page: Page) -> dict[str, int]:
    return page.page.evaluate("""() => {
        const el = document.querySelector('.fitness-chart');
        const chart = getElement(el).chart;
        return Object.fromEntries(chart.getOption().series.map(s => [s.name, s.data.length]));
    }""")


def graph(page: Page, testid: str) -> dict[str, Any]:
    """The nodes' texts, the edge labels and the active node's text of a Mermaid graph."""
    return page.page.evaluate("""(testid) => {
        const root = document.querySelector(`[data-testid=${testid}]`);
        if (!root || !root.querySelector('svg')) return null;
        const nodes = [...root.querySelectorAll('g.node')].map(n => n.textContent.trim());
        const edges = [...root.querySelectorAll('g.edgeLabel')].map(n => n.textContent.trim())
            .filter(t => t);
        const active = [...root.querySelectorAll('g.node.active')].map(n => n.textContent.trim());
        const paths = root.querySelectorAll('path.flowchart-link').length;
        return {nodes, edges, active, paths};
    }""", testid)


def test_runs_table_lists_runs_and_chart_grows(viewer: Viewer, runs_dir: Path,
                                               page: Page) -> None:
    page.goto(viewer.url + "/")
    table = wait_for(lambda: runs_table(page), what="the runs table")
    assert set(table) == {"toy", "grow"}
    toy_history = (runs_dir / "toy" / "history.jsonl").read_text().splitlines()
    toy_info = json.loads((runs_dir / "toy" / "run.json").read_text())
    assert table["toy"][1] == "toy_fetch"
    assert table["toy"][2] == "finished"
    assert table["toy"][3] == str(toy_info["result"]["generations"]) == str(
        len(toy_history) - 1)  # the last generation's index, as evolve says it
    assert table["toy"][4].split("\n")[0] == f"{toy_info['result']['best_fitness']:.4g}"
    assert table["toy"][5] == fresh_text(toy_info["result"]["fresh"])  # rate, bounds, verdict
    assert "(" in table["toy"][5] and "hold" in table["toy"][5]
    assert table["grow"][2] == "running"  # its lock names this (live) process
    assert table["grow"][3] == "2"  # generations 0, 1 and 2
    assert "p_fail=0.1" in table["grow"][7]
    points = wait_for(lambda: chart_points(page) or None, what="the chart")
    assert points == {"toy": len(toy_history), "grow": 3}

    append_generation(runs_dir / "grow", 3)  # the evolution writes a generation
    wait_for(lambda: chart_points(page).get("grow") == 4, what="the chart to grow")
    wait_for(lambda: runs_table(page)["grow"][3] == "3", what="the table to follow")
    with (runs_dir / "grow" / "history.jsonl").open("a") as f:
        f.write('{"generation": 4, "be')  # a line being written: not a point yet
    page.page.wait_for_timeout(2500)
    assert chart_points(page)["grow"] == 4
    assert page.errors == []


def test_fsa_page_draws_states_edges_and_units(viewer: Viewer, runs_dir: Path,
                                               page: Page) -> None:
    path = runs_dir / "pour.fsa.yaml"
    fsa = load_fsa(path)
    page.goto(viewer.url + "/fsa?" + urlencode({"path": str(path),
                                                "task": "examples.pour_water"}))
    g = wait_for(lambda: graph(page, "fsa-graph"), what="the graph")
    assert len(g["nodes"]) == len(fsa.states) + len(fsa.terminals)
    for name, st in fsa.states.items():
        assert sum(n.startswith(f"{name}{st.skill}") for n in g["nodes"]) == 1, (name, g)
    pairs = {(s, t) for s, st in fsa.states.items() for t in st.transitions.values()}
    assert g["paths"] == len(pairs)
    expected = sorted(", ".join(o for o, t2 in st.transitions.items() if t2 == t)
                      for s, st in fsa.states.items() for t in dict.fromkeys(
                          st.transitions.values()))
    assert sorted(g["edges"]) == expected
    text = page.page.get_by_test_id("fsa-graph").inner_text()
    assert "x = 0.58 m (float in [0.2, 1])" in text  # the value with its unit and range
    assert "valid; checked against task pour_water" in page.page.inner_text("body")
    assert page.errors == []


def test_fsa_page_flags_unreachable_and_trap_states(viewer: Viewer, runs_dir: Path,
                                                    page: Page) -> None:
    path = runs_dir / "flags.fsa.yaml"
    path.write_text(
        "format: 1\nstart: A\nterminals: [done]\nstates:\n"
        "  A: {skill: X, transitions: {ok: B}}\n"
        "  B: {skill: X, transitions: {ok: B}}\n"
        "  C: {skill: X, transitions: {ok: done}}\n")
    page.goto(viewer.url + "/fsa?" + urlencode({"path": str(path)}))
    wait_for(lambda: graph(page, "fsa-graph"), what="the graph")
    classes = page.page.evaluate("""() => Object.fromEntries(
        [...document.querySelectorAll('[data-testid=fsa-graph] g.node')].map(
            n => [n.textContent.trim(), n.getAttribute('class')]))""")
    assert "unreachable" in classes["CX"] and "trap" in classes["BX"]
    assert "start" in classes["AX"]
    flags = page.page.get_by_test_id("flag").all_inner_texts()
    assert any(f.startswith("C:") and "unreachable" in f for f in flags)
    assert any(f.startswith("B, A:") or f.startswith("A, B:") or f.startswith("B:")
               for f in flags), flags
    assert page.errors == []


def test_broken_file_shows_its_errors_at_their_lines(viewer: Viewer, runs_dir: Path,
                                                     page: Page) -> None:
    good = (runs_dir / "pour.fsa.yaml").read_text()
    bad_line = good.splitlines().index("      success: Grasp") + 1
    path = runs_dir / "broken.fsa.yaml"
    path.write_text(good.replace("      success: Grasp", "      success: Grsap", 1))
    page.goto(viewer.url + "/fsa?" + urlencode({"path": str(path)}))
    problems = wait_for(lambda: page.page.get_by_test_id("problem").all_inner_texts(),
                        what="the problems")
    assert len(problems) == 1 and f"broken.fsa.yaml:{bad_line}:" in problems[0]
    assert "did you mean 'Grasp'" in problems[0]
    marked = page.page.locator(".yaml-line.bad").evaluate_all(
        "els => els.map(e => e.dataset.line)")
    assert marked == [str(bad_line)]
    path.write_text("states: [\n")  # not even YAML
    page.goto(viewer.url + "/fsa?" + urlencode({"path": str(path)}))
    wait_for(lambda: page.page.get_by_test_id("problem").count() > 0, what="the problem")
    assert "Traceback" not in page.page.inner_text("body")
    assert page.errors == []


def test_app_survives_runs_written_and_vanishing(viewer: Viewer, runs_dir: Path,
                                                 page: Page) -> None:
    doomed = runs_dir / "doomed"
    shutil.copytree(runs_dir / "toy", doomed)
    half = runs_dir / "half"
    half.mkdir()
    (half / "run.json").write_text('{"task": "toy_fe')  # being written
    page.goto(viewer.url + "/")
    wait_for(lambda: {"doomed", "half"} <= set(runs_table(page)), what="the new runs")
    assert runs_table(page)["half"][2] == "unreadable"
    shutil.rmtree(doomed)  # a run deleted while shown
    wait_for(lambda: "doomed" not in runs_table(page), what="the vanished run to go")
    page.goto(viewer.url + "/fsa?" + urlencode({"path": str(doomed / "best.yaml")}))
    problems = wait_for(lambda: page.page.get_by_test_id("problem").all_inner_texts(),
                        what="file not found")
    assert "file not found" in problems[0]
    page.goto(viewer.url + "/fsa?" + urlencode({"path": "/etc/passwd"}))
    assert "not below" in page.page.get_by_test_id("error").inner_text()
    shutil.rmtree(half)
    assert "Traceback" not in page.page.inner_text("body")
    assert page.errors == []


def trace_of(path: Path, task_target: str, seed: int) -> list[str]:
    """The states of the first trial of ``seed``, as ``skillcompose run --trace`` runs it."""
    task = load_task(task_target)
    trial = next(iter(task.each_trial(task.compile(load_fsa(path)), seed, 1,
                                      trace_first=True)))
    assert trial.result.trace is not None
    return [ev.state for ev in trial.result.trace]


def test_replay_active_state_follows_the_trace(viewer: Viewer, runs_dir: Path,
                                               page: Page) -> None:
    path = runs_dir / "pour.fsa.yaml"
    seed = 4
    states = trace_of(path, "examples.pour_water", seed)
    assert len(states) >= 6
    page.goto(viewer.url + "/replay?" + urlencode({
        "path": str(path), "task": "examples.pour_water", "seed": seed}))
    summary = wait_for(lambda: page.page.get_by_test_id("episode-summary").inner_text(),
                       what="the episode")
    assert f"after {len(states)} step(s)" in summary

    def active() -> tuple[str, list[str]]:
        g = graph(page, "replay-graph") or {"active": []}
        return page.page.get_by_test_id("active-state").inner_text(), g["active"]

    start = load_fsa(path).start
    wait_for(lambda: active()[0] == start, what="step 0")
    for k, state in enumerate(states, start=1):
        page.page.get_by_test_id("forward").click()
        skill = load_fsa(path).states[state].skill

        def shown(s: str = state, sk: str = skill) -> bool:
            return active() == (s, [f"{s}{sk}"])

        wait_for(shown, what=f"step {k}: {state}")
        wanted = f"step {k} of {len(states)}: {state} "  # the label may follow the graph

        def labelled(text: str = wanted) -> bool:
            return page.page.get_by_test_id("step-label").inner_text().startswith(text)

        wait_for(labelled, what=f"the label of step {k}")
    assert page.page.get_by_test_id("forward").is_disabled()
    page.page.get_by_test_id("back").click()
    wait_for(lambda: active()[0] == states[-2], what="one step back")
    assert page.errors == []


def test_live_page_follows_a_running_fsa(viewer: Viewer, runs_dir: Path, page: Page) -> None:
    page.goto(viewer.url + "/live")
    out = runs_dir / "live"
    proc = subprocess.Popen([sys.executable, "-m", "examples.live_patrol", "--out", str(out),
                             "--time-scale", "0.25"], cwd=REPO, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    seen: list[str] = []
    try:
        def watch() -> bool:
            if page.page.get_by_test_id("live-active").count():
                state = page.page.get_by_test_id("live-active").first.inner_text()
                if state and (not seen or seen[-1] != state):
                    seen.append(state)
            return bool(seen) and seen[-1] == "success"

        wait_for(watch, timeout=40, what="the patrol to end")
        assert proc.wait(timeout=20) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    # the page shows the run's states as it goes (a state shorter than the page's refresh,
    # such as Dock's quarter of a second here, may pass unseen on a loaded machine), in the
    # run's order, and its end
    assert {"Drive", "Scan"} <= set(seen) <= {"Drive", "Scan", "Dock", "success"}, seen
    assert seen[-1] == "success" and seen.count("success") == 1, seen
    last_drive = len(seen) - 1 - seen[::-1].index("Drive")
    assert all(s != "Dock" for s in seen[:last_drive]), seen  # Dock only after the patrol
    status = page.page.get_by_test_id("live-status").first.inner_text()
    assert status == "ended: success after 7 step(s)"
    assert page.errors == []


def test_live_file_of_a_dead_process_says_so(viewer: Viewer, runs_dir: Path,
                                             page: Page) -> None:
    fsa = patrol_fsa()
    bb = Blackboard()
    bb["position_m"], bb["time_scale"] = (0.0, 0.0), 1.0
    run = compile_fsa(fsa, Registry([drive_to_next, scan_room, dock])).start(bb, 0, trace=True)
    run.tick()  # Drive has started
    path = runs_dir / "ghost" / "ghost.live.json"
    LivePublisher(path, fsa).publish(run, bb)
    run.preempt()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    record = json.loads(path.read_text())
    record["pid"] = dead.pid  # as if the program had been killed
    path.write_text(json.dumps(record))
    page.goto(viewer.url + "/live")
    card = page.page.locator("[data-testid=live-card][data-file='ghost.live.json']")
    wait_for(lambda: "stopped: process" in card.get_by_test_id("live-status").inner_text(),
             what="the dead process")
    assert "it was in Drive (DriveToNext)" in card.get_by_test_id("live-status").inner_text()
    shutil.rmtree(runs_dir / "ghost")
    wait_for(lambda: card.count() == 0, what="the vanished live file to go")
    assert page.errors == []


def test_view_of_one_file_with_its_task(runs_dir: Path, page: Page,
                                        tmp_path: Path) -> None:
    path = runs_dir / "pour.fsa.yaml"
    one = start_viewer([str(path), "--task", "examples.pour_water"], tmp_path / "one.log",
                       REPO)
    try:
        page.goto(one.url + "/fsa")
        g = wait_for(lambda: graph(page, "fsa-graph"), what="the graph")
        assert len(g["nodes"]) == 8
        assert "checked against task pour_water's 6 skills" in page.page.inner_text("body")
    finally:
        code, text = one.stop()
    assert code in (0, 130) and "Traceback" not in text, text
    assert f"on http://127.0.0.1:{one.url.rsplit(':', 1)[1]}/fsa" in text
    assert page.errors == []


@pytest.mark.kinematics
def test_replay_shows_the_pr2_with_its_meshes(viewer: Viewer, runs_dir: Path,
                                              page: Page) -> None:
    from skillcompose.view.robot3d import pieces

    meshes = {p.mesh for p in pieces() if p.kind == "mesh"}
    loaded: set[str] = set()
    page.page.on("response", lambda r: loaded.add(r.url.split("/pr2-meshes/", 1)[1])
                 if "/pr2-meshes/" in r.url and r.status == 200 else None)
    page.goto(viewer.url + "/replay?" + urlencode({
        "path": str(runs_dir / "pour.fsa.yaml"), "task": "examples.kinematic_pour"}))
    wait_for(lambda: page.page.get_by_test_id("robot-scene").count() == 1, what="the scene")
    wait_for(lambda: loaded >= meshes, timeout=30, what="every mesh of the PR2")
    page.page.get_by_test_id("forward").click()
    page.page.wait_for_timeout(1000)
    assert page.page.locator("[data-testid=robot-scene] canvas").count() >= 1
    assert page.errors == []


@pytest.mark.kinematics
@pytest.mark.physics
def test_a_dynamic_replay_steps_through_the_simulation(viewer: Viewer, runs_dir: Path,
                                                        page: Page) -> None:
    page.goto(viewer.url + "/replay?" + urlencode({
        "path": str(runs_dir / "pour.fsa.yaml"), "task": "examples.pour_water",
        "settings": "backend=dynamic"}), timeout_s=300)  # the viewer's REPLAY_TIMEOUT_S
    wait_for(lambda: page.page.get_by_test_id("robot-scene").count() == 1, timeout=120,
             what="the scene of the simulated pour")
    summary = page.page.get_by_test_id("episode-summary").inner_text()
    assert "backend dynamic" in summary and "success after 6 step(s)" in summary
    label = page.page.get_by_test_id("substep-label")
    page.page.get_by_test_id("forward").click()  # step 1: RecogniseObject moves nothing
    page.page.get_by_test_id("forward").click()  # step 2: the arm moves to the jug
    step = page.page.get_by_test_id("step-label")  # step 1 has a sub-step label too: wait for 2
    wait_for(lambda: step.inner_text().startswith("step 2 of") and "t = " in label.inner_text(),
             what="the sub-step label of step 2")
    end = label.inner_text()  # the step's last sample: "t = T s (n of n)"
    n = int(end.rsplit(" of ", 1)[1].rstrip(")"))
    assert n > 4, end  # a motion of seconds, sampled every 0.25 s
    slider = page.page.get_by_test_id("substep")
    box = slider.bounding_box()
    assert box is not None
    page.page.mouse.click(box["x"] + 1, box["y"] + box["height"] / 2)  # its left end
    wait_for(lambda: label.inner_text().endswith(f"(1 of {n})"), what="the first sample")
    first_t = float(label.inner_text().split()[2])
    assert first_t < float(end.split()[2])
    assert page.errors == []
