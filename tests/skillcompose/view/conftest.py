"""Fixtures of the viewer's tests: a run directory, the app as a subprocess on a free port,
and a headless Chromium (Debian's ``chromium``) driven by Playwright.

Every process a fixture starts is stopped by it (``finally``), the browser included.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import pytest

from skillcompose.evolve.rundir import RunDir

REPO = Path(__file__).resolve().parents[3]
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
START_TIMEOUT_S = 40.0


def child_env() -> dict[str, str]:
    """The environment of a child process: this checkout first on the path, and no pytest
    marker (NiceGUI would take the child for its own screen tests)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTEST_CURRENT_TEST"}
    env["PYTHONPATH"] = str(REPO)
    return env


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Viewer:
    url: str
    process: subprocess.Popen[str]
    log: Path

    def stop(self) -> tuple[int, str]:
        """Ctrl-C, as a person stops it; its exit status and what it printed."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        return self.process.returncode, self.log.read_text(encoding="utf-8", errors="replace")


REFRESH_S = 0.25
"""The viewers the tests start list their folder four times a second (``--refresh``; a
user's lists it once a second), so that a test waiting for the runs page to follow a run
waits a quarter of the time."""


def start_viewer(args: list[str], log: Path, cwd: Path, ready_status: int = 200) -> Viewer:
    """``skillcompose view ARGS`` on a free 127.0.0.1 port, once it answers (with
    ``ready_status``: 403 for a viewer that needs a token)."""
    port = free_port()
    out = log.open("w", encoding="utf-8")
    if "--refresh" not in args:
        args = [*args, "--refresh", str(REFRESH_S)]
    proc = subprocess.Popen(
        [sys.executable, "-m", "skillcompose", "view", *args, "--port", str(port)],
        cwd=cwd, stdout=out, stderr=subprocess.STDOUT, text=True,
        env=child_env())
    out.close()
    viewer = Viewer(f"http://127.0.0.1:{port}", proc, log)
    deadline = time.monotonic() + START_TIMEOUT_S
    while True:
        try:
            with urllib.request.urlopen(viewer.url + "/live", timeout=2) as r:
                if r.status == ready_status:
                    return viewer
        except urllib.error.HTTPError as exc:
            if exc.code == ready_status:
                return viewer
        except OSError:
            pass
        if proc.poll() is not None or time.monotonic() > deadline:
            code, text = viewer.stop()
            raise AssertionError(f"the viewer did not start (status {code}):\n{text}")
        time.sleep(0.2)


@pytest.fixture(scope="module")
def runs_dir(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A folder with one finished evolution of the toy task (5 generations, made by
    ``skillcompose evolve``), one run being written (``grow``: run.json without a result, a
    lock held by this process, 3 generations) and the pour-water reference FSA."""
    root = tmp_path_factory.mktemp("runs")
    subprocess.run(
        [sys.executable, "-m", "skillcompose", "evolve", "examples.toy_task",
         "--generations", "4", "--population", "16", "--backend", "serial", "--out",
         str(root / "toy"), "--quiet", "--check-trials", "10", "--simplify-trials", "10",
         "--seed", "1"],
        check=True, cwd=REPO, capture_output=True, text=True,
        env=child_env())
    grow = root / "grow"
    grow.mkdir()
    (grow / "run.json").write_text(json.dumps({
        "task": "toy_fetch", "task_module": "examples.toy_task", "task_settings":
        {"p_fail": 0.1}, "seed": 7, "config": {"population": 30, "generations": 50}}))
    held = RunDir(grow)
    held.lock()  # as evolve holds it while it runs
    for g in range(3):
        append_generation(grow, g)
    shutil.copy(REPO / "examples" / "pour_water_reference.fsa.yaml", root / "pour.fsa.yaml")
    try:
        yield root
    finally:
        held.unlock()


def append_generation(run: Path, g: int) -> None:
    with (run / "history.jsonl").open("a", encoding="utf-8") as f:
        f.write(json.dumps({"generation": g, "best": 5.0 / (g + 1), "mean": 6.0,
                            "median": 6.0, "best_size": 4, "evaluations": 30}) + "\n")


@pytest.fixture(scope="module")
def viewer(runs_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Viewer]:
    v = start_viewer([str(runs_dir)], tmp_path_factory.mktemp("log") / "view.log", REPO)
    try:
        yield v
    finally:
        code, text = v.stop()
        assert code in (0, 130), text
        assert "Traceback" not in text, text


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    if CHROMIUM is None:
        pytest.skip("no chromium on PATH: install Debian's chromium (apt-get install -y "
                    "chromium; .ci/run does it when it runs as root)")
    from playwright.sync_api import sync_playwright

    # no GPU process: pages are composited in software, WebGL (the robot's scene) runs on
    # SwiftShader all the same; each page load costs Chromium about a fifth less CPU than
    # compositing through SwiftShader's GL (--use-gl=angle --use-angle=swiftshader)
    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=CHROMIUM, headless=True,
                               args=["--no-sandbox", "--disable-gpu",
                                     "--enable-unsafe-swiftshader"])
        try:
            yield b
        finally:
            b.close()


@dataclass
class Page:
    """A browser page and what went wrong in it: console errors, page errors, failed
    requests."""

    page: Any
    errors: list[str] = field(default_factory=list)

    def goto(self, url: str, timeout_s: float | None = None) -> None:
        """Open ``url`` and wait for the network to go quiet (``timeout_s`` beyond the
        page's default, for a page the server builds slowly: a simulated episode)."""
        self.page.goto(url, wait_until="networkidle",
                       timeout=None if timeout_s is None else 1000 * timeout_s)


@pytest.fixture
def page(browser: Any) -> Iterator[Page]:
    context = browser.new_context(viewport={"width": 1500, "height": 1100})
    p = Page(context.new_page())
    p.page.set_default_timeout(10_000)
    p.page.on("console", lambda m: p.errors.append(f"console {m.type}: {m.text}")
              if m.type == "error" else None)
    p.page.on("pageerror", lambda e: p.errors.append(f"page error: {e}"))
    p.page.on("requestfailed", lambda r: p.errors.append(f"request failed: {r.url}"))
    p.page.on("response", lambda r: p.errors.append(f"HTTP {r.status}: {r.url}")
              if r.status >= 400 else None)

    def offline(route: Any) -> None:
        """The network is off: anything not asked of this machine is an error."""
        host = urlsplit(route.request.url).hostname
        if host == "127.0.0.1" or route.request.url.startswith(("data:", "blob:")):
            route.continue_()
        else:
            p.errors.append(f"asked another host: {route.request.url}")
            route.abort()

    context.route("**/*", offline)
    try:
        yield p
    finally:
        context.close()


def wait_for(check: Callable[[], Any], timeout: float = 10.0, what: str = "") -> Any:
    deadline = time.monotonic() + timeout
    last: Any = None
    while time.monotonic() < deadline:
        last = check()
        if last:
            return last
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what or check}: last {last!r}")
