"""The runtime's modules import each other in layers: no circle, and no function-level import
that would hide one (an import inside a function counts as an edge like any other)."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import networkx as nx
import pytest

import skillcompose

PACKAGE = Path(skillcompose.__file__).resolve().parent


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST, module: str, modules: set[str]) -> set[str]:
    """Modules of the package that ``module`` imports when it runs (at any level), leaving
    out the imports under ``if TYPE_CHECKING:``, which only the type checker follows."""
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _type_checking(node):
            for statement in node.orelse:
                visit(statement)
            return
        if isinstance(node, ast.ImportFrom):
            if node.level == 1:
                base = node.module or ""
            elif node.level == 0 and (node.module or "").startswith("skillcompose."):
                base = (node.module or "").removeprefix("skillcompose.")
            else:
                base = None
            if base is not None:
                if base in modules:
                    found.add(base)
                elif not base:  # from . import x
                    found.update(a.name for a in node.names if a.name in modules)
        elif isinstance(node, ast.Import):
            for a in node.names:
                name = a.name.removeprefix("skillcompose.")
                if a.name.startswith("skillcompose.") and name in modules:
                    found.add(name)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    found.discard(module)
    return found


def import_graph() -> nx.DiGraph:
    modules = {p.stem for p in PACKAGE.glob("*.py")}
    graph = nx.DiGraph()
    graph.add_nodes_from(modules)
    for m in modules:
        tree = ast.parse((PACKAGE / f"{m}.py").read_text(encoding="utf-8"))
        for target in _imports(tree, m, modules):
            graph.add_edge(m, target)
    return graph


def test_the_runtime_has_no_import_circle() -> None:
    graph = import_graph()
    graph.remove_node("__init__")  # the package's re-exports import everything, once
    cycles = list(nx.simple_cycles(graph))
    assert not cycles, f"import circles inside skillcompose: {cycles}"


def test_the_engine_knows_skills_only_through_their_methods() -> None:
    graph = import_graph()
    below = nx.descendants(graph, "executor")
    assert not below & {"skill", "nested", "registry", "fsafile", "bt", "task", "cli"}, below
    assert "executor" not in nx.descendants(graph, "activation")
    source = (PACKAGE / "executor.py").read_text(encoding="utf-8")
    assert "isinstance(impl" not in source and "FSASkill" not in source


def test_the_graph_sees_function_level_imports() -> None:
    tree = ast.parse("def f():\n    from .b import x\nif TYPE_CHECKING:\n    from .c import y\n")
    assert _imports(tree, "a", {"a", "b", "c"}) == {"b"}


@pytest.mark.parametrize(
    "package", ["skillcompose", "skillcompose.evolve",
                pytest.param("skillcompose.robots", marks=pytest.mark.kinematics)]
)
def test_the_lazy_name_table_equals_the_imports_the_type_checker_reads(package: str) -> None:
    """A package's ``__init__.py`` lists its public names twice: as imports only the type
    checker runs, and as the table that imports a name's module on first use."""
    pkg = importlib.import_module(package)
    tree = ast.parse(Path(str(pkg.__file__)).read_text("utf-8"))
    typed_names = {(str(a.asname), f".{node.module}") for node in ast.walk(tree)
                   if isinstance(node, ast.ImportFrom) and node.level == 1 for a in node.names}
    table = {(name, f".{module}") for module, names in pkg._EXPORTS.items()
             for name in names.split()}
    assert typed_names == table
    extra = {"__version__"} if package == "skillcompose" else set()
    assert set(pkg.__all__) == {name for name, _ in table} | extra
    for name in pkg.__all__:
        assert getattr(pkg, name) is not None


def test_a_public_name_is_not_replaced_by_the_submodule_of_the_same_name() -> None:
    code = ("import skillcompose, skillcompose.skill, skillcompose.registry;"
            "import types; print(isinstance(skillcompose.skill, types.FunctionType))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == "True"
    code = ("import skillcompose.evolve, skillcompose.evolve.simplify, types;"
            "print(isinstance(skillcompose.evolve.simplify, types.FunctionType))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == "True"
