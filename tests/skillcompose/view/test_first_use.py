"""What a new user sees first: the rough edges one found, each checked where it showed.

- the runs table's *generations* is the N of ``skillcompose evolve``'s "after N
  generations" and of ``run.json``'s ``result.generations`` (the last generation's index),
  not the history's line count;
- its *best fitness* (the run's result) and the chart (each generation's best evaluation)
  tell one story: a note says what differs, and the chart marks the result;
- a file is called valid only once checked against a task's skills: a broken one never,
  one checked for its structure alone says so, and the FSA page has a task field;
- the replay page opens on a file that loads (and says which it skipped, or that none
  does); a broken one shows its problems;
- no warning icon where nothing is wrong (step 0 of a replay, an empty blackboard);
- a long line of YAML wraps, every character on screen.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlencode, urlsplit

import pytest

from examples.live_patrol import dock, drive_to_next, patrol_fsa, scan_room
from skillcompose import Blackboard, Registry, load_task
from skillcompose.executor import compile_fsa
from skillcompose.view.app import first_loading
from skillcompose.view.data import find_runs, read_fsa, read_run
from skillcompose.view.fsa_parts import check_status
from skillcompose.view.live import LivePublisher
from skillcompose.view.runs_page import best_note, chart_options, run_row
from skillcompose.view.trust import ViewerConfig

from .conftest import REPO, Page, Viewer, child_env, start_viewer, wait_for
from .test_browser import runs_table

POUR = REPO / "examples" / "pour_water_reference.fsa.yaml"
BROKEN = POUR.read_text().replace("success: Grasp", "success: Grsap", 1)
TRAP = ("format: 1\nstart: A\nterminals: [done]\nstates:\n"
        "  A: {skill: NoSuchSkill, params: {x: 3}, transitions: {ok: B}}\n"
        "  B: {skill: X, transitions: {ok: B}}\n")
LONG = "# " + "-".join(f"w{k:03d}" for k in range(150)) + " THE-END"  # 750 characters


def write_run(path: Path, info: dict[str, Any], bests: list[float]) -> None:
    path.mkdir(parents=True)
    (path / "run.json").write_text(json.dumps(info))
    with (path / "history.jsonl").open("w") as f:
        for g, best in enumerate(bests):
            f.write(json.dumps({"generation": g, "best": best}) + "\n")


def make_folder(root: Path) -> Path:
    """A confirmed run (its result's best, 0.5, is not its last generation's best
    evaluation, 0.25), a run without a result, a broken FSA file (first by name), the
    pour-water FSA with a long comment line, and an FSA whose skills no task has."""
    write_run(root / "runs" / "confirmed", {
        "task": "toy_fetch", "task_module": "examples.toy_task", "seed": 3,
        "result": {"best_fitness": 0.5, "generations": 2, "solved": True}}, [2.0, 1.0, 0.25])
    write_run(root / "runs" / "going", {"task": "toy_fetch", "seed": 4}, [3.0, 1.5])
    (root / "a_broken.fsa.yaml").write_text(BROKEN)
    lines = POUR.read_text().splitlines()
    (root / "b_pour.fsa.yaml").write_text("\n".join([LONG, *lines]) + "\n")
    (root / "c_trap.fsa.yaml").write_text(TRAP)
    return root


# ---------------------------------------------------------------------------------------
# without a browser
# ---------------------------------------------------------------------------------------
def test_generations_is_the_last_generations_index(tmp_path: Path) -> None:
    root = make_folder(tmp_path)
    runs = {r.name: r for r in find_runs(root)}
    confirmed, going = runs["runs/confirmed"], runs["runs/going"]
    assert (confirmed.last_generation, confirmed.generations) == (2, 3)  # as run.json says
    assert (going.last_generation, going.generations) == (1, 2)  # the last record's index
    assert run_row(confirmed)["generations"] == "2" and run_row(going)["generations"] == "1"
    write_run(tmp_path / "fresh", {"task": "t"}, [])
    assert run_row(find_runs(tmp_path / "fresh")[0])["generations"] == "–"  # none yet
    write_run(tmp_path / "odd", {"task": "t", "result": {"generations": True}}, [1.0])
    odd = find_runs(tmp_path / "odd")[0]
    assert odd.status == "unreadable" and "result.generations is true or false" in odd.problem


def test_best_fitness_and_chart_tell_one_story(tmp_path: Path) -> None:
    root = make_folder(tmp_path)
    confirmed = read_run(root / "runs" / "confirmed", root)
    going = read_run(root / "runs" / "going", root)
    assert confirmed is not None and going is not None
    assert (confirmed.best, confirmed.generation_best, confirmed.best_is_result) == \
        (0.5, 0.25, True)
    note = best_note(confirmed)
    assert "result" in note and "0.25" in note  # the chart's other number, named
    assert run_row(confirmed)["best"] == "0.5"
    assert "so far" in best_note(going) and run_row(going)["best"] == "1.5"
    options = chart_options([confirmed, going], {"runs/confirmed", "runs/going"})
    marked = {s["name"]: s.get("markPoint") for s in options["series"]}
    assert marked["runs/going"] is None  # no result: nothing to mark
    point = marked["runs/confirmed"]["data"][0]
    assert point["coord"] == [2, 0.5] and "result" in point["name"]
    assert [len(s["data"]) for s in options["series"]] == [3, 2]  # a point a generation


def test_a_file_is_valid_only_checked_against_skills(tmp_path: Path) -> None:
    trap = tmp_path / "trap.fsa.yaml"
    trap.write_text(TRAP)
    view = read_fsa(trap)  # its structure only
    assert view.fsa is not None and view.problems == () and view.checked_against == ""
    text, colour = check_status(view)
    assert text.startswith("structure only") and "not checked" in text
    assert "valid" not in text and "green" not in colour
    task = load_task("examples.pour_water")
    checked = read_fsa(trap, task.registry, "task pour_water")
    assert checked.problems and "NoSuchSkill" in " ".join(p.message for p in checked.problems)
    good = read_fsa(POUR, task.registry, "task pour_water")
    text, colour = check_status(good)
    assert text == "valid; checked against task pour_water's 6 skills" and "green" in colour
    bad = tmp_path / "bad.fsa.yaml"
    bad.write_text(BROKEN)
    assert read_fsa(bad).fsa is None and read_fsa(bad).problems  # never a status


def test_the_replay_opens_on_a_file_that_loads(tmp_path: Path) -> None:
    root = make_folder(tmp_path)
    config = ViewerConfig(root=root)
    files = [root / "a_broken.fsa.yaml", root / "b_pour.fsa.yaml"]
    assert first_loading(config, files) == (files[1], [files[0]])
    assert first_loading(config, files[:1]) == (None, files[:1])  # none loads


# ---------------------------------------------------------------------------------------
# in a browser
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_folder(tmp_path_factory.mktemp("first"))


@pytest.fixture(scope="module")
def first(folder: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Viewer]:
    v = start_viewer([str(folder)], tmp_path_factory.mktemp("log") / "view.log", REPO)
    try:
        yield v
    finally:
        code, text = v.stop()
        assert code in (0, 130), text
        assert "Traceback" not in text, text


def drawn(page: Page) -> None:
    """Wait for the FSA's graph and the page's fonts (leaving a page before they have loaded
    cancels their requests, which the tests count as errors)."""
    wait_for(lambda: page.page.locator("[data-testid=fsa-graph] svg").count() == 1,
             what="the graph")
    settled(page)


def settled(page: Page) -> None:
    """Wait for the fonts the page has asked for so far."""
    page.page.evaluate("() => document.fonts.ready.then(() => true)")


def icons(page: Page) -> list[str]:
    return [t.strip() for t in page.page.locator("i.q-icon").all_inner_texts()]


@pytest.mark.slow
@pytest.mark.browser
def test_runs_table_says_what_the_cli_and_the_chart_say(first: Viewer, folder: Path,
                                                        page: Page) -> None:
    page.goto(first.url + "/")
    table = wait_for(lambda: runs_table(page), what="the runs table")
    info = json.loads((folder / "runs" / "confirmed" / "run.json").read_text())
    confirmed = table["runs/confirmed"]
    assert confirmed[3] == str(info["result"]["generations"]) == "2"  # "after 2 generations"
    best, note = confirmed[4].split("\n", 1)
    assert best == "0.5" and "result" in note and "0.25" in note
    going = table["runs/going"]
    assert going[3] == "1" and going[4].startswith("1.5\n") and "so far" in going[4]
    assert "the index of the last generation" in page.page.get_by_test_id(
        "runs-explained").inner_text()
    marks = wait_for(lambda: page.page.evaluate("""() => {
        const chart = getElement(document.querySelector('.fitness-chart')).chart;
        return Object.fromEntries(chart.getOption().series.map(
            s => [s.name, s.markPoint && s.markPoint.data.length ? s.markPoint.data[0].coord
                                                                 : null]));
    }""") or None, what="the chart")
    assert marks == {"runs/confirmed": [2, 0.5], "runs/going": None}
    settled(page)
    assert page.errors == []


@pytest.mark.slow
@pytest.mark.browser
def test_fsa_page_checks_against_a_task_typed_there(first: Viewer, page: Page) -> None:
    page.goto(first.url + "/fsa?" + urlencode({"path": "c_trap.fsa.yaml"}))
    status = page.page.get_by_test_id("check-status")
    wait_for(lambda: status.count() == 1, what="what was checked")
    assert status.inner_text().startswith("structure only")
    assert "green" not in (status.get_attribute("class") or "")
    assert "valid" not in page.page.inner_text("body")
    drawn(page)
    field = page.page.get_by_test_id("fsa-task-input")
    field.fill("examples.pour_water")
    page.page.get_by_test_id("check-button").click()
    # Playwright's own wait: the page fixture's routing of requests runs while it waits
    page.page.wait_for_url(lambda url: "task=examples.pour_water" in url)
    query = parse_qs(urlsplit(page.page.url).query)
    assert query["path"][0].endswith("c_trap.fsa.yaml")
    problems = wait_for(lambda: page.page.get_by_test_id("problem").all_inner_texts(),
                        what="the problems against the task's skills")
    assert any("NoSuchSkill" in p for p in problems)
    assert page.page.get_by_test_id("check-status").count() == 0
    assert page.page.get_by_test_id("fsa-task-input").input_value() == "examples.pour_water"
    drawn(page)
    page.goto(first.url + "/fsa?" + urlencode({"path": "b_pour.fsa.yaml"}))
    wait_for(lambda: status.count() == 1, what="what was checked")
    drawn(page)
    page.page.get_by_test_id("fsa-task-input").fill("examples.pour_water")
    page.page.get_by_test_id("fsa-task-input").press("Enter")  # Enter checks too
    wait_for(lambda: status.count() == 1 and status.inner_text().startswith("valid; checked"),
             what="the file checked against the task")
    assert "green" in (status.get_attribute("class") or "")
    drawn(page)
    assert page.errors == []


@pytest.mark.slow
@pytest.mark.browser
def test_a_long_yaml_line_can_be_read_whole(first: Viewer, page: Page) -> None:
    page.goto(first.url + "/fsa?" + urlencode({"path": "b_pour.fsa.yaml"}))
    line = page.page.locator(".yaml-line[data-line='1']")
    wait_for(lambda: line.count() == 1, what="the file's lines")
    assert line.inner_text().split(None, 1)[1].replace("\n", "") == LONG
    line.scroll_into_view_if_needed()
    seen = page.page.evaluate("""() => {
        const span = document.querySelector(".yaml-line[data-line='1']");
        const pre = span.closest('pre');
        const text = span.lastChild;  // the line's text, after its number
        const range = document.createRange();
        range.setStart(text, text.length - 1);
        range.setEnd(text, text.length);
        const r = range.getBoundingClientRect(), box = pre.getBoundingClientRect();
        const hit = document.elementFromPoint((r.left + r.right) / 2, (r.top + r.bottom) / 2);
        return {inside: r.right <= box.right + 0.5 && r.left >= box.left - 0.5,
                onScreen: r.right <= window.innerWidth && r.width > 0,
                hidden: pre.scrollWidth - pre.clientWidth, visible: span.contains(hit)};
    }""")
    assert seen == {"inside": True, "onScreen": True, "hidden": 0, "visible": True}, seen
    drawn(page)
    assert page.errors == []


@pytest.mark.slow
@pytest.mark.browser
def test_replay_opens_on_a_file_that_loads_and_warns_of_nothing(first: Viewer,
                                                                  page: Page) -> None:
    page.goto(first.url + "/replay?" + urlencode({"task": "examples.pour_water"}))
    summary = wait_for(lambda: page.page.get_by_test_id("episode-summary").count() and
                       page.page.get_by_test_id("episode-summary").inner_text(),
                       what="the episode of the first file that loads")
    assert summary.startswith("b_pour.fsa.yaml on task pour_water")
    note = page.page.get_by_test_id("broken-files").inner_text()
    assert "Skipped 1" in note and "a_broken.fsa.yaml" in note
    assert page.page.get_by_test_id("step-label").inner_text().startswith("step 0 of")
    assert "warning" not in icons(page)  # nothing ran yet: nothing is wrong
    assert page.page.get_by_test_id("changes").get_by_test_id("no-rows").inner_text() == \
        "nothing has run yet"
    page.page.get_by_test_id("forward").click()
    wait_for(lambda: page.page.get_by_test_id("step-label").inner_text().startswith(
        "step 1 of"), what="step 1")
    assert "warning" not in icons(page)
    settled(page)
    page.goto(first.url + "/replay?" + urlencode({"path": "a_broken.fsa.yaml",
                                                  "task": "examples.pour_water"}))
    problems = wait_for(lambda: page.page.get_by_test_id("problem").all_inner_texts(),
                        what="the broken file's problems")
    assert len(problems) == 1 and "did you mean 'Grasp'" in problems[0]
    settled(page)
    page.goto(first.url + "/replay?" + urlencode({"path": "a_broken.fsa.yaml"}))  # no task
    wait_for(lambda: page.page.get_by_test_id("problem").count() == 1, what="its problems")
    settled(page)
    assert page.errors == []


@pytest.mark.slow
@pytest.mark.browser
def test_an_empty_live_blackboard_is_no_warning(first: Viewer, folder: Path,
                                                page: Page) -> None:
    fsa = patrol_fsa()
    bb = Blackboard()
    bb["position_m"], bb["time_scale"] = (0.0, 0.0), 1.0
    run = compile_fsa(fsa, Registry([drive_to_next, scan_room, dock])).start(bb, 0, trace=True)
    run.tick()
    path = folder / "live" / "quiet.live.json"
    LivePublisher(path, fsa).publish(run)  # no blackboard published
    run.preempt()
    try:
        page.goto(first.url + "/live")
        card = page.page.get_by_test_id("live-card")
        wait_for(lambda: card.count() == 1 and "running" in card.get_by_test_id(
            "live-status").inner_text(), what="the live card")
        assert card.get_by_test_id("no-rows").inner_text() == \
            "nothing published on the blackboard"
        assert "warning" not in icons(page)
        settled(page)
    finally:
        path.unlink()
    assert page.errors == []


@pytest.mark.slow
@pytest.mark.browser
def test_a_broken_file_alone_is_never_valid(tmp_path: Path, page: Page) -> None:
    """``skillcompose view broken.fsa.yaml``, no task: its problems, no word of valid; the
    replay page says no file loads."""
    alone = tmp_path / "alone"
    alone.mkdir()
    path = alone / "broken.fsa.yaml"
    path.write_text(BROKEN)
    one = start_viewer([str(path)], tmp_path / "alone.log", REPO)
    try:
        page.goto(one.url + "/fsa")
        wait_for(lambda: page.page.get_by_test_id("problem").count() == 1, what="its problem")
        body = page.page.inner_text("body")
        assert "not valid: 1 problem(s)" in body and "valid;" not in body
        assert page.page.get_by_test_id("check-status").count() == 0
        assert page.page.get_by_test_id("fsa-task-input").count() == 1
        settled(page)
        page.goto(one.url + "/replay")
        note = wait_for(lambda: page.page.get_by_test_id("broken-files").count() and
                        page.page.get_by_test_id("broken-files").inner_text(),
                        what="no file loads")
        assert note.startswith("No FSA file under") and "loads: broken.fsa.yaml" in note
        settled(page)
    finally:
        code, text = one.stop()
    assert code in (0, 130) and "Traceback" not in text, text
    assert page.errors == []


@pytest.mark.slow
def test_the_cli_and_the_table_count_alike(tmp_path: Path) -> None:
    """A real evolution: the table's generations is what ``evolve`` printed."""
    out = tmp_path / "toy"
    done = subprocess.run(
        [sys.executable, "-m", "skillcompose", "evolve", "examples.toy_task",
         "--generations", "3", "--population", "12", "--backend", "serial", "--out",
         str(out), "--check-trials", "0", "--seed", "2"],
        check=True, cwd=REPO, capture_output=True, text=True, env=child_env())
    run = find_runs(tmp_path)[0]
    assert f"after {run_row(run)['generations']} generations" in done.stdout
    assert len((out / "history.jsonl").read_text().splitlines()) == run.generations
