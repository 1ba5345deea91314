"""Screenshots of every page of ``skillcompose view`` for the documentation.

::

    python -m skillcompose.view.screenshots --out docs/viewer

makes a folder with two short evolutions of the toy task, starts the viewer on it, runs the
live patrol example, and has a headless Chromium (Debian's ``chromium``, driven by
Playwright) save ``runs.png``, ``fsa.png``, ``fsa_errors.png``, ``replay.png``,
``replay_pr2.png`` and ``live.png``. Every process it starts is stopped before it returns.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from collections.abc import Sequence
from pathlib import Path
from urllib.parse import urlencode

REPO = Path(__file__).resolve().parents[2]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _run(*args: str) -> None:
    subprocess.run([sys.executable, "-m", *args], check=True, cwd=REPO, capture_output=True,
                   env={**os.environ, "PYTHONPATH": str(REPO)})


def _stop(proc: subprocess.Popen[bytes]) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _wait_http(url: str, timeout: float = 40.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(url, timeout=2):
                return
        except OSError:
            time.sleep(0.2)
    raise SystemExit(f"the viewer did not answer at {url}")


def make_folder(root: Path) -> None:
    """Two toy evolutions, the example FSAs and a broken FSA file."""
    for seed, gens in ((1, 12), (2, 8)):
        _run("skillcompose", "evolve", "examples.toy_task", "--generations", str(gens),
             "--population", "30", "--backend", "serial", "--quiet", "--seed", str(seed),
             "--set", "p_fail=0.1", "--out", str(root / f"toy_seed{seed}"),
             "--check-trials", "50", "--simplify-trials", "50")
    for name in ("pour_water_reference", "stacking_reference"):
        shutil.copy(REPO / "examples" / f"{name}.fsa.yaml", root / f"{name}.fsa.yaml")
    text = (REPO / "examples" / "pour_water_reference.fsa.yaml").read_text(encoding="utf-8")
    broken = text.replace("success: Grasp", "success: Grsap", 1).replace(
        "z: 0.95", "z: high", 1)
    (root / "broken.fsa.yaml").write_text(broken, encoding="utf-8")


def shoot(out: Path, chromium: str) -> list[Path]:
    from playwright.sync_api import sync_playwright

    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "runs"  # the pages show it as "runs", the name given below
        root.mkdir()
        make_folder(root)
        port = _free_port()
        env = {**os.environ, "PYTHONPATH": str(REPO)}
        viewer = subprocess.Popen(
            [sys.executable, "-m", "skillcompose", "view", "runs", "--port", str(port)],
            cwd=root.parent, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        patrol = None
        try:
            base = f"http://127.0.0.1:{port}"
            _wait_http(base + "/live")
            with sync_playwright() as pw:
                browser = pw.chromium.launch(
                    executable_path=chromium, headless=True,
                    args=["--no-sandbox", "--use-gl=angle", "--use-angle=swiftshader",
                          "--enable-unsafe-swiftshader"])
                try:
                    page = browser.new_page(viewport={"width": 1400, "height": 900})

                    def snap(name: str, url: str, settle: float = 1.5) -> None:
                        page.goto(base + url, wait_until="networkidle")
                        time.sleep(settle)
                        path = out / f"{name}.png"
                        page.screenshot(path=str(path), full_page=True)
                        written.append(path)

                    snap("runs", "/")
                    snap("fsa", "/fsa?" + urlencode({
                        "path": str(root / "pour_water_reference.fsa.yaml"),
                        "task": "examples.pour_water"}))
                    snap("fsa_errors", "/fsa?" + urlencode({
                        "path": str(root / "broken.fsa.yaml")}))
                    page.goto(base + "/replay?" + urlencode({
                        "path": str(root / "pour_water_reference.fsa.yaml"),
                        "task": "examples.pour_water", "seed": 3}), wait_until="networkidle")
                    for _ in range(3):
                        page.get_by_test_id("forward").click()
                    time.sleep(1.5)
                    page.screenshot(path=str(out / "replay.png"), full_page=True)
                    written.append(out / "replay.png")
                    page.goto(base + "/replay?" + urlencode({
                        "path": str(root / "pour_water_reference.fsa.yaml"),
                        "task": "examples.kinematic_pour", "seed": 0}),
                        wait_until="networkidle")
                    for _ in range(5):
                        page.get_by_test_id("forward").click()
                    time.sleep(4.0)
                    page.screenshot(path=str(out / "replay_pr2.png"), full_page=True)
                    written.append(out / "replay_pr2.png")
                    patrol = subprocess.Popen(
                        [sys.executable, "-m", "examples.live_patrol", "--out",
                         str(root / "live"), "--rounds", "3"], cwd=REPO, env=env,
                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                    time.sleep(5.0)
                    snap("live", "/live", settle=2.0)
                finally:
                    browser.close()
        finally:
            if patrol is not None:
                _stop(patrol)
            _stop(viewer)
    return written


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m skillcompose.view.screenshots",
                                description=__doc__.split("\n")[0])
    p.add_argument("--out", type=Path, default=REPO / "docs" / "viewer",
                   help="folder for the PNG files (default docs/viewer)")
    p.add_argument("--chromium", default=shutil.which("chromium") or "",
                   help="the Chromium executable (default: chromium on PATH)")
    args = p.parse_args(argv)
    if not args.chromium:
        p.error("no chromium on PATH; install Debian's chromium or give --chromium PATH")
    for path in shoot(args.out, args.chromium):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
