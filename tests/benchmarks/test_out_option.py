"""Every benchmark script that writes a page takes ``--out`` through
``skillcompose.arguments``: a file or an unwritable place is a one-line usage error before
anything is measured, never a traceback after hours of runs."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = sorted(p for p in (ROOT / "benchmarks").glob("*.py") if '"--out"' in p.read_text())


def out_type(script: Path) -> str | None:
    """The name given as ``type=`` to the script's ``add_argument("--out", ...)``."""
    for node in ast.walk(ast.parse(script.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "add_argument" \
                and node.args and getattr(node.args[0], "value", None) == "--out":
            for kw in node.keywords:
                if kw.arg == "type" and isinstance(kw.value, ast.Name):
                    return kw.value.id
    return None


def test_the_scripts_that_write_pages_are_found() -> None:
    assert {"bench_search.py", "calibrate_solved.py", "transfer.py"} <= {p.name for p in SCRIPTS}


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.stem)
def test_out_is_checked_as_it_is_parsed(script: Path) -> None:
    assert out_type(script) in ("output_dir", "output_folder")


def test_a_file_given_as_out_is_a_one_line_error_before_any_run(tmp_path: Path) -> None:
    page = tmp_path / "search.md"
    page.write_text("kept\n", encoding="utf-8")
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_search.py"),
                           "--only", "maze", "--out", str(page)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines()[-1].endswith("is a file; give a directory")
    assert page.read_text(encoding="utf-8") == "kept\n"
