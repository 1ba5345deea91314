"""Which part of the package may import which (docs/ARCHITECTURE.md, "Imports"), read from the
source: the core runtime imports none of the other parts, and no module but a command-line
module imports a command-line module (the core owns its limits and rules)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
import tomllib

ROOT = Path(__file__).resolve().parents[2]

ALLOWED = {
    "skillcompose": set(),
    "skillcompose.robots": {"skillcompose"},
    "skillcompose.skills": {"skillcompose", "skillcompose.robots"},
    "skillcompose.evolve": {"skillcompose"},
    "skillcompose.view": {"skillcompose", "skillcompose.robots", "skillcompose.skills"},
}
"""Each part and the other parts it may import (at any level: in functions too)."""

CLI_MODULES = {
    "skillcompose.__main__", "skillcompose.cli", "skillcompose.arguments",
    "skillcompose.robustness_cli", "skillcompose.evolve.cli", "skillcompose.robots.cli",
    "skillcompose.view.cli",
}
"""The command line: argument parsing and subcommands. Only they import one another."""


def _modules() -> dict[str, Path]:
    """Every module of the package, by its installed name, from pyproject's package-dir."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    folders: dict[str, str] = config["tool"]["setuptools"]["package-dir"]
    found: dict[str, Path] = {}
    for package, folder in folders.items():
        for path in (ROOT / folder).rglob("*.py"):
            parts = list(path.relative_to(ROOT / folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            name = ".".join([package, *parts])
            found.setdefault(name, path)
    return found


def _part(module: str) -> str:
    for part in sorted(ALLOWED, key=len, reverse=True):
        if module == part or module.startswith(part + "."):
            return part
    raise AssertionError(module)


def _type_only(tree: ast.AST) -> set[int]:
    """The ids of the import statements under ``if TYPE_CHECKING:``."""
    ids: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            ids.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    return ids


def _imported(module: str, path: Path, *, runtime: bool = False) -> set[str]:
    """The package modules ``module`` imports, anywhere in it (under ``TYPE_CHECKING`` too,
    unless ``runtime``: a type-only import still ties the parts together)."""
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    found: set[str] = set()
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = _type_only(tree) if runtime else set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
                names = [f"{target}.{a.name}" for a in node.names]
            else:
                target = node.module or ""
                names = [f"{target}.{a.name}" for a in node.names]
            if target.startswith("skillcompose"):
                found.add(target)
                found.update(n for n in names if n in _MODULES)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("skillcompose"))
    return found


_MODULES = _modules()


def test_the_package_is_found_whole() -> None:
    for name in ("skillcompose.task", "skillcompose.evolve.algorithm", "skillcompose.view.app",
                 "skillcompose.robots.model", "skillcompose.skills.stacking"):
        assert name in _MODULES


@pytest.mark.parametrize("module", sorted(_MODULES))
def test_each_module_imports_only_the_parts_its_part_may(module: str) -> None:
    mine = _part(module)
    for target in _imported(module, _MODULES[module]):
        other = _part(target)
        assert other == mine or other in ALLOWED[mine], (
            f"{module} imports {target}: {mine} may import only "
            f"{sorted(ALLOWED[mine]) or 'nothing else'}")


@pytest.mark.parametrize("module", sorted(set(_MODULES) - CLI_MODULES))
def test_no_core_module_imports_the_command_line(module: str) -> None:
    bad = _imported(module, _MODULES[module]) & CLI_MODULES
    assert not bad, f"{module} imports the command line: {sorted(bad)}"


def test_the_rules_see_an_import_inside_a_function(tmp_path: Path) -> None:
    path = tmp_path / "m.py"
    path.write_text("def f():\n    from skillcompose.cli import main\n", encoding="utf-8")
    assert "skillcompose.cli" in _imported("skillcompose.task", path)
    path.write_text("from ..arguments import whole\n", encoding="utf-8")
    assert "skillcompose.arguments" in _imported("skillcompose.evolve.config", path)


@pytest.mark.parametrize("part", sorted(ALLOWED))
def test_no_part_has_an_import_circle(part: str) -> None:
    """Within a part, modules import each other in layers when they run (imports inside
    functions count: the stacking skills and their kinematic twins used to import each
    other; type-only imports do not)."""
    import networkx as nx

    graph = nx.DiGraph()
    for module, path in _MODULES.items():
        if _part(module) != part or path.name == "__init__.py":
            continue
        graph.add_node(module)
        for target in _imported(module, path, runtime=True):
            if target in _MODULES and _part(target) == part and target != module and \
                    _MODULES[target].name != "__init__.py":
                graph.add_edge(module, target)
    cycles = list(nx.simple_cycles(graph))
    assert not cycles, f"import circles in {part}: {cycles}"


LOOKUP_ONLY = ("skillcompose.fsa", "skillcompose.executor", "skillcompose.nested",
               "skillcompose.fsafile")
"""The model, the engine and the file layer: they look skills up (``skillcompose.lookup``)
and do not know the loader, not even for typing."""


@pytest.mark.parametrize("module", LOOKUP_ONLY)
def test_model_engine_and_files_do_not_know_the_loader(module: str) -> None:
    found = _imported(module, _MODULES[module])
    assert "skillcompose.registry" not in found, (
        f"{module} imports skillcompose.registry: ask skillcompose.lookup.SkillLookup instead")


def test_a_registry_is_a_skill_lookup() -> None:
    from skillcompose.lookup import SkillLookup
    from skillcompose.registry import Registry

    assert isinstance(Registry(), SkillLookup)
    assert not isinstance(object(), SkillLookup)
