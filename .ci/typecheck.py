"""Run mypy on the package as it installs: ``skillcompose.evolve`` and its siblings.

``pyproject.toml`` maps ``skillcompose.evolve``, ``.robots`` and ``.skills`` to the top-level
folders ``evolve/``, ``robots/`` and ``skills/`` (setuptools ``package-dir``). An editable
install finds them through an import hook, which mypy does not run, so mypy alone cannot
find them. This script lays the installed layout out of symbolic links in ``.mypy_tree/``
(the folders themselves are linked, so nothing is copied), runs mypy there with the given
arguments, and writes its paths back as the repository's own::

    python .ci/typecheck.py              # the packages of [tool.mypy]
    python .ci/typecheck.py tests        # any mypy arguments
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parents[1]
TREE = ROOT / ".mypy_tree"


def package_dirs() -> dict[str, str]:
    """The subpackages of ``skillcompose`` that live in a folder of their own."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    mapping: dict[str, str] = config["tool"]["setuptools"]["package-dir"]
    return {name.split(".", 1)[1]: folder for name, folder in mapping.items()
            if name.startswith("skillcompose.")}


def build_tree(mapped: dict[str, str]) -> None:
    if TREE.exists():
        shutil.rmtree(TREE)
    package = TREE / "skillcompose"
    package.mkdir(parents=True)
    for entry in (ROOT / "skillcompose").iterdir():
        if entry.name != "__pycache__":
            (package / entry.name).symlink_to(entry)
    for sub, folder in mapped.items():
        (package / sub).symlink_to(ROOT / folder)
    skip = {"skillcompose", ".git", ".venv", ".mypy_tree", ".mypy_cache", *mapped.values()}
    for entry in ROOT.iterdir():
        if entry.name not in skip:
            (TREE / entry.name).symlink_to(entry)


def main(argv: list[str]) -> int:
    mapped = package_dirs()
    build_tree(mapped)
    result = subprocess.run(
        [sys.executable, "-m", "mypy", "--cache-dir", str(ROOT / ".mypy_cache"), *argv],
        cwd=TREE, capture_output=True, text=True, env={**os.environ, "MYPYPATH": str(TREE)},
    )
    names = "|".join(map(re.escape, mapped))
    back = re.compile(rf"^skillcompose/({names})/", re.M)
    sys.stdout.write(back.sub(lambda m: f"{mapped[m.group(1)]}/", result.stdout))
    sys.stderr.write(result.stderr)
    return result.returncode


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
