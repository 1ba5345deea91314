"""The viewer reads only regular files inside the folder it serves, bounded, and one bad file
costs only its own row: links leading outside, task settings naming files, large and
growing histories, values of the wrong type, odd values in a page's address."""

from __future__ import annotations

import itertools
import json
import os
import time
import urllib.request
from pathlib import Path
from urllib.parse import urlencode

import pytest

from skillcompose.view import history as history_module
from skillcompose.view.data import Budget, HistoryReader, find_runs, read_fsa, read_run
from skillcompose.view.folder import OutsideFolder, read_below, walk_below
from skillcompose.view.live import live_problem, read_live
from skillcompose.view.trust import (
    ViewerConfig,
    address_problem,
    checked_settings,
    file_below,
    seed_of,
)

from .conftest import REPO, Page, start_viewer
from .test_browser import runs_table

SECRET = "SECRET-CONTENT root:x:0:0:root:/root:/bin/bash"
POUR = REPO / "examples" / "pour_water_reference.fsa.yaml"
LIVE = {"format": "skillcompose live state", "name": "patrol", "pid": 1, "state": "A",
        "steps": 1, "done": False, "outcome": None, "blackboard": {"x": "1"},
        "fsa": "format: 1\nstart: A\nstates:\n  A: {skill: X, transitions: {ok: success}}\n"}


@pytest.fixture
def folders(tmp_path: Path) -> tuple[Path, Path]:
    """A folder served (``root``) and, beside it, one that is not (``outside``), holding a
    secret of every kind the viewer reads."""
    root, outside = tmp_path / "root", tmp_path / "outside"
    root.mkdir()
    outside.mkdir()
    for name in ("run.json", "history.jsonl", "best.yaml", "x.live.json", "secret.fsa.yaml"):
        (outside / name).write_text(SECRET)
    (outside / "good.fsa.yaml").write_text(POUR.read_text())
    return root, outside


def everything_shown(summary: object) -> str:
    return json.dumps(summary, default=lambda o: getattr(o, "__dict__", str(o)))


def test_links_leading_outside_are_refused_for_every_file(folders: tuple[Path, Path]) -> None:
    root, outside = folders
    run = root / "run"
    run.mkdir()
    for name in ("run.json", "history.jsonl", "best.yaml"):
        (run / name).symlink_to(outside / name)
    (root / "x.live.json").symlink_to(outside / "x.live.json")
    (root / "linked.fsa.yaml").symlink_to(outside / "good.fsa.yaml")  # a valid FSA, outside
    summary = read_run(run, root)
    assert summary is not None and summary.status == "unreadable"
    assert "outside the folder served" in summary.problem
    assert SECRET not in everything_shown(summary)
    assert [r.name for r in find_runs(root)] == ["run"]  # listed, with its problem
    view = read_fsa(run / "best.yaml", root=root)
    assert view.fsa is None and view.text == ""
    assert "outside the folder served" in view.problems[0].message
    assert read_fsa(root / "linked.fsa.yaml", root=root).fsa is None
    assert read_live(root / "x.live.json", root) is None
    with pytest.raises(OutsideFolder):
        read_below(run / "run.json", root, 1000)
    config = ViewerConfig(root=root)
    assert file_below(config, root / "linked.fsa.yaml") is None  # ?path=linked.fsa.yaml
    assert file_below(config, root / ".." / "outside" / "good.fsa.yaml") is None  # ?path=../
    assert file_below(config, Path("/etc/passwd")) is None
    listed = list(walk_below(root, lambda n: True, max_depth=4, max_files=100))
    assert root / "linked.fsa.yaml" not in listed and root / "x.live.json" not in listed


def test_links_inside_the_folder_are_read(folders: tuple[Path, Path]) -> None:
    root, _ = folders
    (root / "real.fsa.yaml").write_text(POUR.read_text())
    (root / "alias.fsa.yaml").symlink_to(root / "real.fsa.yaml")
    assert read_fsa(root / "alias.fsa.yaml", root=root).fsa is not None
    assert file_below(ViewerConfig(root=root), root / "alias.fsa.yaml") == root


def test_linked_folders_are_not_entered(folders: tuple[Path, Path]) -> None:
    root, outside = folders
    (outside / "run.json").write_text(json.dumps({"task": "t"}))
    (root / "elsewhere").symlink_to(outside, target_is_directory=True)
    assert find_runs(root) == []
    assert list(walk_below(root, lambda n: True, max_depth=4, max_files=100)) == []


def test_a_setting_naming_a_file_must_name_one_inside_the_folder(
        folders: tuple[Path, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    root, outside = folders
    config = ViewerConfig(root=root)
    (root / "reach.fsa.yaml").write_text(POUR.read_text())
    (root / "sub").mkdir()
    (root / "sub" / "link.fsa.yaml").symlink_to(outside / "secret.fsa.yaml")
    for value in ("/etc/passwd", "../outside/secret.fsa.yaml", "sub/link.fsa.yaml",
                  str(outside / "good.fsa.yaml"), "~/x.fsa.yaml"):
        settings, refusal = checked_settings(config, {"move_to_reach": value})
        assert settings == {} and refusal is not None, value
        assert "move_to_reach" in refusal and "\n" not in refusal and SECRET not in refusal
    monkeypatch.chdir(outside)  # a bare name the task would read from the current folder
    assert checked_settings(config, {"move_to_reach": "secret.fsa.yaml"})[1] is not None
    settings, refusal = checked_settings(config, {"move_to_reach": "reach.fsa.yaml",
                                                  "backend": "kinematic", "p_fail": 0.2})
    assert refusal is None
    assert settings == {"move_to_reach": str((root / "reach.fsa.yaml").resolve()),
                        "backend": "kinematic", "p_fail": 0.2}
    assert checked_settings(config, {"m": "./reach.fsa.yaml"})[0] == {
        "m": str((root / "reach.fsa.yaml").resolve())}
    given = ViewerConfig(root=root, settings={"move_to_reach": "/etc/passwd"})  # --set
    assert checked_settings(given, {"move_to_reach": "/etc/passwd"}) == (
        {"move_to_reach": "/etc/passwd"}, None)


def test_odd_address_values_get_one_line() -> None:
    assert "control character (U+0000)" in str(address_problem("path", "\x00"))
    assert "control character (U+202E)" in str(address_problem("task", "a\u202eb"))
    assert "at most 4096" in str(address_problem("path", "x" * 5000))
    assert address_problem("path", "runs/a b/best.yaml") is None
    assert seed_of("") == 0 and seed_of(" 12 ") == 12
    for bad in ("²", "-1", "1e3", "9" * 30, "x"):
        assert isinstance(seed_of(bad), str) and "whole number" in str(seed_of(bad))


def test_one_bad_value_costs_only_its_own_row(tmp_path: Path) -> None:
    for name, info in (("bad", {"task": "t", "task_settings": [1, 2]}),
                       ("bad_seed", {"task": "t", "seed": "x", "config": [1]}),
                       ("good", {"task": "t", "task_settings": {"p": 1}})):
        (tmp_path / name).mkdir()
        (tmp_path / name / "run.json").write_text(json.dumps(info))
    runs = {r.name: r for r in find_runs(tmp_path)}
    assert set(runs) == {"bad", "bad_seed", "good"}
    assert runs["bad"].status == "unreadable"
    assert runs["bad"].problem == "run.json: task_settings is a list, not an object"
    assert runs["bad_seed"].status == "unreadable" and "seed is a text" in runs[
        "bad_seed"].problem
    assert runs["good"].status == "interrupted" and runs["good"].settings == "p=1"
    assert live_problem(dict(LIVE)) is None
    assert live_problem(LIVE | {"blackboard": [1]}) == (
        "its blackboard is of type list; expected dict")
    assert "steps is missing" in str(live_problem({k: v for k, v in LIVE.items()
                                                   if k != "steps"}))


def write_history(path: Path, generations: int, pad: int = 0) -> int:
    extra = "x" * pad
    with path.open("w") as f:
        for g in range(generations):
            f.write(json.dumps({"generation": g, "best": 1.0 / (g + 1), "pad": extra}) + "\n")
    return path.stat().st_size


def test_history_is_read_incrementally(tmp_path: Path) -> None:
    """Each read takes only the bytes added since the last one (a line being written is
    read again once whole); a file rewritten is read again from its start."""
    path = tmp_path / "history.jsonl"
    size = write_history(path, 10)
    reader = HistoryReader()
    assert reader.read(path).generations == 10 and reader.bytes_read == size
    assert reader.read(path).generations == 10 and reader.bytes_read == size  # unchanged
    with path.open("a") as f:
        f.write(json.dumps({"generation": 10, "best": 0.01}) + "\n" + '{"generation": 11, ')
    grown = path.stat().st_size
    history = reader.read(path)
    assert (history.generations, history.best) == (11, 0.01)
    assert reader.bytes_read <= grown + 64  # the new bytes, and a check of the last ones
    before = reader.bytes_read
    with path.open("a") as f:
        f.write('"best": 0.005}\n')
    assert reader.read(path).generations == 12
    assert reader.bytes_read - before <= len('{"generation": 11, "best": 0.005}\n') + 64
    write_history(path, 3)  # rewritten in place (shorter): read again from the start
    assert reader.read(path).generations == 3
    path.unlink()
    write_history(path, 5)  # replaced by another file
    assert reader.read(path).generations == 5


@pytest.mark.slow
def test_a_100_mb_history_is_read_in_bounded_pieces(tmp_path: Path) -> None:
    """A ~100 MB history: each read takes at most MAX_HISTORY_READ new bytes (a bounded
    piece of work, in the runs page's worker thread), the whole file is read once, the
    summary keeps at most MAX_POINTS points, and a generation appended afterwards costs
    only its own bytes."""
    run = tmp_path / "big"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"task": "t"}))
    n = 400_000
    size = write_history(run / "history.jsonl", n, pad=200)
    assert size > 95_000_000
    reader = HistoryReader()
    reads = 0
    while True:
        before = reader.bytes_read
        history = reader.read(run / "history.jsonl", tmp_path, Budget(1))
        reads += 1
        assert reader.bytes_read - before <= history_module.MAX_HISTORY_READ + 64
        if history.complete:
            break
        assert reads < 100
    assert reads >= size // history_module.MAX_HISTORY_READ
    assert history.generations == n and history.best == 1.0 / n
    assert reader.bytes_read <= size + reads * (64 + 300)  # each byte once (and a line cut)
    assert len(history.points) <= history_module.MAX_POINTS + 1
    assert history.points[0] == (0, 1.0) and history.points[-1] == (n - 1, 1.0 / n)
    gens = [g for g, _ in history.points]
    assert gens == sorted(gens) and max(b - a for a, b in itertools.pairwise(gens)) <= 512
    with (run / "history.jsonl").open("a") as f:
        line = json.dumps({"generation": n, "best": 0.0}) + "\n"
        f.write(line)
    before = reader.bytes_read
    assert reader.read(run / "history.jsonl", tmp_path).generations == n + 1
    assert reader.bytes_read - before <= len(line) + 64


def test_the_runs_listing_reads_a_big_history_over_several_refreshes(tmp_path: Path) -> None:
    run = tmp_path / "big"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"task": "t"}))
    size = write_history(run / "history.jsonl", 60_000, pad=300)  # ~20 MB
    first = find_runs(tmp_path, Budget(history_module.MAX_HISTORY_READ))
    assert first[0].reading and 0 < first[0].generations < 60_000
    for _ in range(size // history_module.MAX_HISTORY_READ + 2):
        last = find_runs(tmp_path, Budget(history_module.MAX_HISTORY_READ))
        if not last[0].reading:
            break
    assert not last[0].reading and last[0].generations == 60_000


def test_a_line_too_long_is_skipped(tmp_path: Path) -> None:
    path = tmp_path / "history.jsonl"
    long = json.dumps({"generation": 1, "best": 1.0, "pad": "x" * (3 << 20)})
    path.write_text(json.dumps({"generation": 0, "best": 2.0}) + "\n" + long + "\n"
                    + json.dumps({"generation": 2, "best": 0.5}) + "\n")
    reader = HistoryReader(max_read=1 << 20)
    history = reader.read(path)
    while not history.complete:
        history = reader.read(path)
    assert history.generations == 2 and history.points == ((0, 2.0), (2, 0.5))


def _get(url: str) -> str:
    with urllib.request.urlopen(url, timeout=120) as r:
        return str(r.read().decode("utf-8", errors="replace"))


@pytest.mark.slow
def test_pages_read_no_file_outside_the_folder(folders: tuple[Path, Path],
                                               tmp_path: Path) -> None:
    """Over HTTP: a setting naming a file outside (the stacking task's move_to_reach), a
    link to an FSA outside, odd address values: each a line in the page, no file's
    content, no "unexpected" error, no traceback."""
    root, outside = folders
    (root / "stack.fsa.yaml").write_text(
        (REPO / "examples" / "stacking_reference.fsa.yaml").read_text())
    (root / "linked.fsa.yaml").symlink_to(outside / "secret.fsa.yaml")
    viewer = start_viewer([str(root)], tmp_path / "view.log", REPO)
    try:
        for target in ("/etc/passwd", str(outside / "secret.fsa.yaml")):
            page = _get(viewer.url + "/replay?" + urlencode({
                "task": "examples.stacking", "path": "stack.fsa.yaml",
                "settings": f"move_to_reach={target}"}))
            assert "move_to_reach" in page and "outside the folder served" in page
            assert "root:x:0:0" not in page and SECRET not in page
        page = _get(viewer.url + "/fsa?path=linked.fsa.yaml")
        assert "not below" in page and SECRET not in page
        for pages, query, expected in (
                (("fsa", "replay"), "path=%00", "control character (U+0000)"),
                (("fsa", "replay"), "path=a%00b&task=examples.toy_task", "control character"),
                (("fsa", "replay"), "task=%00", "control character"),
                (("replay",), "path=stack.fsa.yaml&task=examples.toy_task&seed=%C2%B2",
                 "not a whole number"),
                (("fsa", "replay"), "path=stack.fsa.yaml&task=..&seed=1", "not a module name"),
                (("fsa", "replay"), "path=" + "x" * 5000, "at most 4096")):
            for name in pages:
                page = _get(f"{viewer.url}/{name}?{query}")
                assert expected in page and "unexpected" not in page, (name, query)
    finally:
        code, text = viewer.stop()
    assert code in (0, 130) and "Traceback" not in text, text


def test_the_history_reader_keeps_its_files_open_only_while_reading(tmp_path: Path) -> None:
    path = tmp_path / "history.jsonl"
    write_history(path, 3)
    fds = len(os.listdir("/proc/self/fd")) if Path("/proc/self/fd").exists() else None
    HistoryReader().read(path)
    if fds is not None:
        assert len(os.listdir("/proc/self/fd")) == fds


def _rss_mb(pid: int) -> float | None:
    try:
        text = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return None
    kb = next((int(line.split()[1]) for line in text.splitlines()
               if line.startswith("VmRSS:")), None)
    return None if kb is None else kb / 1024


@pytest.mark.slow
@pytest.mark.browser
def test_a_100_mb_history_does_not_hold_up_other_requests(tmp_path: Path, page: Page) -> None:
    """The runs page open on a run with a ~100 MB history: the history is read a bounded
    piece per refresh, in a worker thread, so other requests are answered meanwhile (the
    time is checked loosely: this machine may be loaded), the server's memory stays
    bounded, and the table says it is still reading until it has read it all."""
    run = tmp_path / "runs" / "big"
    run.mkdir(parents=True)
    (run / "run.json").write_text(json.dumps({"task": "t"}))
    n = 400_000
    write_history(run / "history.jsonl", n, pad=200)
    viewer = start_viewer([str(tmp_path / "runs")], tmp_path / "view.log", REPO)
    try:
        before = _rss_mb(viewer.process.pid)
        page.goto(viewer.url + "/")
        latencies, seen = [], []
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline:
            start = time.monotonic()
            _get(viewer.url + "/fsa")  # another page, while the history is being read
            latencies.append(time.monotonic() - start)
            table = runs_table(page)
            if "big" in table:
                seen.append(table["big"][3])
                if table["big"][3] == str(n - 1):  # the last generation's index
                    break
            time.sleep(0.2)
        assert seen and seen[-1] == str(n - 1), seen[-5:]
        assert any("reading" in s for s in seen)  # it said so while it read
        after = _rss_mb(viewer.process.pid)
        print(f"latency max {max(latencies):.2f} s over {len(latencies)} requests; "
              f"RSS {before} -> {after} MB")
        assert max(latencies) < 5.0, latencies  # loose: about 0.1 s on an idle machine
        if before is not None and after is not None:
            assert after - before < 300, (before, after)
        assert page.errors == []
    finally:
        code, text = viewer.stop()
    assert code in (0, 130) and "Traceback" not in text, text


def test_what_is_kept_of_a_file_is_bounded(tmp_path: Path) -> None:
    """A run.json or live file made large on purpose costs its row, or is kept cut: the
    viewer keeps only what the page shows of each, between reads."""
    (tmp_path / "many").mkdir()
    (tmp_path / "many" / "run.json").write_text(json.dumps(
        {"task": "t", "task_settings": {f"s{k}": k for k in range(1000)}}))
    (tmp_path / "long").mkdir()
    (tmp_path / "long" / "run.json").write_text(json.dumps(
        {"task": "t", "task_module": "m" * 10_000, "extra": ["x" * 1000] * 1000}))
    runs = {r.name: r for r in find_runs(tmp_path)}
    assert "task_settings has 1000 entries" in runs["many"].problem
    assert "task_module is longer than 4096" in runs["long"].problem
    live = tmp_path / "big.live.json"
    live.write_text(json.dumps(LIVE | {"blackboard": {f"k{k}": "v" * 1000 for k in range(3000)},
                                       "extra": ["x"] * 10_000}))
    record = read_live(live)
    assert record is not None and live_problem(record) is None
    assert len(record["blackboard"]) == 500 and "extra" not in record
    assert all(len(v) <= 200 for v in record["blackboard"].values())
