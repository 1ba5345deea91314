"""The viewer imports a task module named by a page's address or a run's ``run.json`` only
as a module name found outside the folder viewed, and only for a request of its own pages or
the person's: opening a page never runs code that came with the runs viewed, and another
site's page cannot make it import anything."""

from __future__ import annotations

import json
import urllib.request
from pathlib import Path

import pytest

from skillcompose.view.app import ViewerConfig, request_refusal, task_refusal

from .conftest import REPO, start_viewer

EVIL = 'open(__file__ + ".RAN", "w").write("ran")\nfrom examples.toy_task import make_task\n'


def test_a_request_from_another_site_or_host_name_may_import_nothing() -> None:
    assert request_refusal({"host": "127.0.0.1:8765", "sec-fetch-site": "same-origin"}) is None
    assert request_refusal({"host": "127.0.0.1:8765", "sec-fetch-site": "none"}) is None
    assert request_refusal({"host": "localhost:8765"}) is None  # curl: no fetch metadata
    assert request_refusal({"host": "[::1]:8765"}) is None
    assert request_refusal({"host": "192.168.1.4"}) is None  # --host on a network address
    assert "another site" in str(request_refusal(
        {"host": "127.0.0.1:8765", "sec-fetch-site": "cross-site"}))
    assert "another site" in str(request_refusal(
        {"host": "127.0.0.1:8765", "sec-fetch-site": "same-site"}))
    assert "'rebound.example.com'" in str(request_refusal(  # a name made to point here
        {"host": "rebound.example.com:8765", "sec-fetch-site": "same-origin"}))


def test_which_task_modules_the_viewer_may_import(tmp_path: Path) -> None:
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "evil.py").write_text(EVIL)
    (tmp_path / "mypkg").mkdir()
    (tmp_path / "mypkg" / "__init__.py").write_text(EVIL)
    config = ViewerConfig(root=tmp_path)
    assert task_refusal(config, "examples.toy_task", None) is None
    refused = task_refusal(config, str(tmp_path / "run" / "evil.py"), None)
    assert refused is not None and "given on its command line" in refused
    assert "--task" in refused and "\n" not in refused
    refused = task_refusal(config, "/elsewhere/task.py", None)  # any file, not only inside
    assert refused is not None and "given on its command line" in refused
    with pytest.MonkeyPatch.context() as mp:  # a package found in the folder viewed
        mp.chdir(tmp_path)
        refused = task_refusal(config, "mypkg", None)
    assert refused is not None and "inside the folder being viewed" in refused
    refused = task_refusal(config, "examples.toy_task", "the request came from another site")
    assert refused is not None and "another site" in refused
    given = ViewerConfig(root=tmp_path, task=str(tmp_path / "run" / "evil.py"))
    assert task_refusal(given, str(tmp_path / "run" / "evil.py"), "any") is None  # chosen
    assert not (tmp_path / "run" / "evil.py.RAN").exists()  # nothing was imported


def test_code_inside_the_folder_is_found_at_every_level_of_a_name(tmp_path: Path) -> None:
    """A dotted name reaching into the folder viewed through a package above it
    (``runs.theirrun.evil`` with ``runs`` in the current directory), or through a namespace
    package imported already (``ruamel``, whose folders an import computes afresh once
    the current directory is on the path): refused, and nothing imported."""
    import ruamel.yaml  # noqa: F401 - a namespace package this process has imported

    run = tmp_path / "runs" / "theirrun"
    (run / "ruamel").mkdir(parents=True)
    for module in (run / "evil.py", run / "ruamel" / "evil.py"):
        module.write_text(EVIL)
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(tmp_path)
        refused = task_refusal(ViewerConfig(root=run), "runs.theirrun.evil", None)
        assert refused is not None and "inside the folder being viewed" in refused
        mp.chdir(run)  # viewing the folder one is in: `skillcompose view .`
        refused = task_refusal(ViewerConfig(root=run), "ruamel.evil", None)
        assert refused is not None and "inside the folder being viewed" in refused
        assert task_refusal(ViewerConfig(root=run), "ruamel.yaml", None) is None
    assert not list(run.rglob("*.RAN"))


def _get(url: str, headers: dict[str, str] | None = None) -> str:
    request = urllib.request.Request(url, headers=headers or {})
    with urllib.request.urlopen(request, timeout=60) as r:
        return str(r.read().decode("utf-8", errors="replace"))


@pytest.mark.slow
def test_opening_pages_runs_no_code_that_came_with_the_runs(tmp_path: Path) -> None:
    """A run received from someone else names a task file inside itself; a page address
    names another file: the viewer, asked for both pages, imports neither, and says why;
    a run naming a module found elsewhere still has its task checked."""
    runs = tmp_path / "runs"
    for name, module in (("received", str(runs / "received" / "evil_task.py")),
                         ("ours", "examples.toy_task")):
        (runs / name).mkdir(parents=True)
        (runs / name / "run.json").write_text(json.dumps(
            {"task": "toy_fetch", "task_module": module, "task_settings": {}, "seed": 1}))
        (runs / name / "best.yaml").write_text(
            (REPO / "tests" / "evolve" / "data" / "toy_solution.yaml").read_text())
    (runs / "received" / "evil_task.py").write_text(EVIL)
    elsewhere = tmp_path / "elsewhere.py"
    elsewhere.write_text(EVIL)
    viewer = start_viewer([str(runs)], tmp_path / "view.log", REPO)
    try:
        page = _get(viewer.url + "/fsa?path=received/best.yaml")
        assert "inside the folder being viewed" not in page  # a file: refused as a file
        assert "given on its command line" in page
        page = _get(viewer.url + f"/fsa?path=ours/best.yaml&task={elsewhere}")
        assert "given on its command line" in page
        page = _get(viewer.url + f"/replay?path=ours/best.yaml&task={elsewhere}")
        assert "given on its command line" in page
        page = _get(viewer.url + "/fsa?path=ours/best.yaml&task=examples.toy_task",
                    {"Sec-Fetch-Site": "cross-site"})
        assert "another site" in page
        # the refused task is not offered to the page's Run button either
        page = _get(viewer.url + "/replay?path=ours/best.yaml&task=examples.toy_task",
                    {"Sec-Fetch-Site": "cross-site"})
        assert "another site" in page and '"value":"",' in page
        assert '"value":"examples.toy_task"' not in page
        page = _get(viewer.url + "/replay?path=ours/best.yaml&task=examples.toy_task",
                    {"Sec-Fetch-Site": "same-origin"})
        assert '"value":"examples.toy_task"' in page
        with urllib.request.urlopen(viewer.url + "/", timeout=60) as r:  # never in a frame
            assert r.headers["X-Frame-Options"] == "DENY"
            csp = r.headers["Content-Security-Policy"].split("; ")
            assert "frame-ancestors 'none'" in csp
            assert csp[1].startswith("script-src 'self'") and "'unsafe-inline'" not in csp[1]
        page = _get(viewer.url + "/fsa?path=ours/best.yaml")
        assert "checked against task toy_fetch" in page
    finally:
        code, text = viewer.stop()
    assert code in (0, 130), text
    assert not (runs / "received" / "evil_task.py.RAN").exists()
    assert not (tmp_path / "elsewhere.py.RAN").exists()
