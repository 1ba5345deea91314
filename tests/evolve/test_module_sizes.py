"""Modules and functions short enough to read in one sitting, read from the source.

No module of the package (every folder ``pyproject.toml``'s ``package-dir`` maps) is over
700 lines, and no function or method over 80 lines, unless a comment on its ``def`` line,
or on the line before it (before its decorators, if any), says why: ``# long: ...``. The
function rule holds for every function of ``evolve/``; elsewhere, and for modules, today's
longer ones are listed below with their length, which may only shrink: an entry that has
grown fails, and one that is back within the limit must be removed.
"""

from __future__ import annotations

import ast
from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parents[2]
MAX_MODULE_LINES = 700
MAX_FUNCTION_LINES = 80
STRICT = ("evolve/",)
"""Folders where every function keeps the rule: none of them may be listed below."""

MODULES_ALLOWED = {
    "skillcompose/fsafile.py": 1049,
    "skills/kinematic.py": 760,
    "skills/kinematic_world.py": 705,
}
"""Modules over the limit today, with their length in lines."""

FUNCTIONS_ALLOWED = {
    "robots/ik.py::IKSolver.solve": 93,
    "skillcompose/cli.py::build_parser": 82,
    "skillcompose/cli.py::cmd_run": 93,
    "skillcompose/executor.py::FSARun.tick": 114,
    "skillcompose/fsa.py::FSA.structure_problems": 82,
    "skillcompose/robustness.py::robustness_sweep": 90,
    "skillcompose/skill.py::_make_skill": 140,
}
"""Functions over the limit today, without a ``long:`` comment, with their length."""


def _modules() -> dict[str, Path]:
    """Every module of the package, by its path in the repository, from pyproject's
    package-dir."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    folders: dict[str, str] = config["tool"]["setuptools"]["package-dir"]
    found: dict[str, Path] = {}
    for folder in folders.values():
        for path in sorted((ROOT / folder).rglob("*.py")):
            found.setdefault(path.relative_to(ROOT).as_posix(), path)
    return found


def _has_reason(lines: list[str], number: int) -> bool:
    """Whether line ``number`` (1-based) carries a ``# long: reason`` comment."""
    if not 1 <= number <= len(lines):
        return False
    line = lines[number - 1]
    if "#" not in line:
        return False
    comment = line[line.index("#"):]
    return "long:" in comment and bool(comment.split("long:", 1)[1].strip())


def long_functions(text: str) -> dict[str, tuple[int, bool]]:
    """Each function or method (``Class.method``, ``outer.inner``) over the limit: its
    length in lines (decorators and docstring included) and whether it says why."""
    lines = text.splitlines()
    found: dict[str, tuple[int, bool]] = {}

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                first = min([child.lineno] + [d.lineno for d in child.decorator_list])
                length = (child.end_lineno or child.lineno) - first + 1
                if length > MAX_FUNCTION_LINES:
                    reason = any(_has_reason(lines, n)
                                 for n in (child.lineno, child.lineno - 1, first - 1))
                    found[prefix + child.name] = (length, reason)
                visit(child, f"{prefix}{child.name}.")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            else:
                visit(child, prefix)

    visit(ast.parse(text), "")
    return found


_MODULES = _modules()


def test_the_package_is_found_whole() -> None:
    for name in ("skillcompose/task.py", "evolve/algorithm.py", "skillcompose/view/app.py",
                 "robots/model.py", "skills/stacking.py"):
        assert name in _MODULES


def test_no_module_is_over_the_limit() -> None:
    too_long = []
    for name, path in _MODULES.items():
        length = len(path.read_text(encoding="utf-8").splitlines())
        if length > MODULES_ALLOWED.get(name, MAX_MODULE_LINES):
            allowed = MODULES_ALLOWED.get(name)
            too_long.append(f"{name}: {length} lines" + (
                f" (listed at {allowed}: it may only shrink)" if allowed else ""))
    assert not too_long, (
        f"modules over {MAX_MODULE_LINES} lines: {'; '.join(too_long)}; split them by concern")


def test_no_function_is_over_the_limit_without_a_reason() -> None:
    too_long = []
    for name, path in _MODULES.items():
        for function, (length, reason) in long_functions(
                path.read_text(encoding="utf-8")).items():
            key = f"{name}::{function}"
            if reason or length <= FUNCTIONS_ALLOWED.get(key, MAX_FUNCTION_LINES):
                continue
            allowed = FUNCTIONS_ALLOWED.get(key)
            too_long.append(f"{key}: {length} lines" + (
                f" (listed at {allowed}: it may only shrink)" if allowed else ""))
    assert not too_long, (
        f"functions over {MAX_FUNCTION_LINES} lines: {'; '.join(too_long)}; break them into "
        "named steps, or say why one must stay whole with a comment `# long: REASON` on its "
        "def line or the line before")


def test_the_lists_only_shrink() -> None:
    """An entry back within the limit (or gone) is removed, so that it cannot grow again;
    ``evolve/`` has none."""
    stale = []
    for name in MODULES_ALLOWED:
        path = _MODULES.get(name)
        if path is None or len(path.read_text(encoding="utf-8").splitlines()) \
                <= MAX_MODULE_LINES:
            stale.append(name)
    lengths: dict[str, dict[str, tuple[int, bool]]] = {}
    for key in FUNCTIONS_ALLOWED:
        name, function = key.split("::")
        assert not name.startswith(STRICT), f"{key}: every function of {name} keeps the rule"
        if name not in lengths and name in _MODULES:
            lengths[name] = long_functions(_MODULES[name].read_text(encoding="utf-8"))
        length, reason = lengths.get(name, {}).get(function, (0, False))
        if length <= MAX_FUNCTION_LINES or reason:
            stale.append(key)
    assert not stale, f"within the limits now: remove {', '.join(stale)} from the lists above"


def test_a_reason_is_read_from_the_def_line_or_the_line_before() -> None:
    body = "".join(f"    x = {i}\n" for i in range(MAX_FUNCTION_LINES))
    assert long_functions(f"def f():\n{body}") == {"f": (MAX_FUNCTION_LINES + 1, False)}
    assert long_functions(f"def f():  # long: a table\n{body}")["f"][1]
    assert long_functions(f"# long: a table\ndef f():\n{body}")["f"][1]
    assert long_functions(f"# long: a table\n@cache\ndef f():\n{body}") == {
        "f": (MAX_FUNCTION_LINES + 2, True)}
    assert not long_functions(f"# long:\ndef f():\n{body}")["f"][1]  # no reason given
    nested = "".join(f"        x = {i}\n" for i in range(MAX_FUNCTION_LINES))
    assert set(long_functions(f"class A:\n    def m(self):\n{nested}")) == {"A.m"}
    assert set(long_functions(f"def f():\n    def g():\n{nested}")) == {"f", "f.g"}
