"""Where importing a module would read code from, found without running any: so that code
that came with a directory received from someone else (a run directory, a folder of runs
being viewed) is never imported from it by accident.

The runtime imports a dotted module name with the current directory on the path (as
``python -m`` does) and, for a source checkout's own packages (``examples.*``), the
checkout's root: :func:`import_path` is that path, which :func:`module_origins` searches and
the registry's import sets up, so the check and the import can never see different paths.
"""

from __future__ import annotations

import importlib.machinery
import os
import sys
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path
from typing import Any

__all__ = ["SOURCE_ROOT", "import_path", "inside", "is_file_target", "module_origins",
           "on_path", "use_import_path"]

SOURCE_ROOT = Path(__file__).resolve().parents[1]
"""The folder holding this package: in a source checkout, its root (``examples`` beside)."""


def is_file_target(module: str) -> bool:
    """Whether ``module`` (as ``--task`` takes it) names a file rather than a module."""
    return module.endswith(".py") or "/" in module or "\\" in module


def _find(name: str, path: list[str]) -> Any:
    try:
        return importlib.machinery.PathFinder.find_spec(name, path)
    except (ImportError, ValueError, KeyError):
        return None


def _locate(part: str, search: list[str]) -> tuple[Path | None, list[str]] | None:
    """Where the path-based import finds module ``part`` in the folders ``search``, as its
    finder looks (entry by entry: a package's ``__init__``, else a module file, else a
    folder as a portion of a namespace package): the file it runs (None for a namespace
    package) and the folders of its submodules; None when it finds nothing."""
    portions: list[str] = []
    for entry in search:
        folder = Path(entry) / part
        for suffix in importlib.machinery.all_suffixes():
            init = folder / f"__init__{suffix}"
            if init.is_file():
                return init, [str(folder)]
        for suffix in importlib.machinery.all_suffixes():
            if (Path(entry) / f"{part}{suffix}").is_file():
                return Path(entry) / f"{part}{suffix}", []
        if folder.is_dir():
            portions.append(str(folder))
    return (None, portions) if portions else None


def import_path(top: str) -> list[str]:
    """``sys.path`` as the runtime's import of a module whose top-level name is ``top``
    sees it: the current directory added when ``top`` is there (as ``python -m`` would find
    it; a folder that does not hold the module named adds nothing, so a received folder's
    stray ``winreg.py`` is never found by a library's optional import), and the checkout's
    root when only it has ``top``."""
    path = [p or os.getcwd() for p in sys.path]
    cwd = os.getcwd()
    if cwd not in path and _locate(top, [cwd]) is not None:
        path.append(cwd)
    root = str(SOURCE_ROOT)
    if root not in path and top not in sys.modules and top not in sys.builtin_module_names \
            and _find(top, path) is None and (
                (SOURCE_ROOT / top / "__init__.py").is_file()
                or (SOURCE_ROOT / f"{top}.py").is_file()):
        path.append(root)
    return path


@contextmanager
def on_path(entries: list[str], *, first: bool = False) -> Iterator[None]:
    """``sys.path`` with ``entries`` added (at its end, or at its start when ``first``) for
    the ``with`` block only: the folders a user named (the current directory, a task file's
    own folder) serve the one import they were named for, and no later import reads code
    from them by accident."""
    added = [e for e in dict.fromkeys(entries) if e not in sys.path]
    if first:
        sys.path[0:0] = added
    else:
        sys.path.extend(added)
    try:
        yield
    finally:
        for entry in added:
            if entry in sys.path:
                sys.path.remove(entry)
        importlib.invalidate_caches()


def use_import_path(top: str) -> AbstractContextManager[None]:
    """A ``with`` block in which ``sys.path`` is :func:`import_path`, to import ``top``'s
    module as the runtime does; the path is as it was afterwards."""
    return on_path(import_path(top))


def module_origins(module: str) -> list[Path]:
    """Every file whose code importing ``module`` (a dotted name, or a ``.py`` path) runs,
    found without running any: at each level of the name (``a``, ``a.b``, ``a.b.c``) the
    module's file or its package's ``__init__`` (and, when the module itself is a
    namespace package, its folders), looked for as :func:`import_path` and the import's
    finder look. A level imported already is taken as it is, but for a namespace package,
    whose folders an import computes afresh from the path: they are found as the import
    would find them."""
    if is_file_target(module):
        return [Path(module)]
    parts = module.split(".")
    search = import_path(parts[0])
    places: list[Path] = []
    for k, part in enumerate(parts):
        loaded = sys.modules.get(".".join(parts[:k + 1]))
        spec = getattr(loaded, "__spec__", None) if loaded is not None else None
        if spec is not None and spec.has_location and spec.origin:
            places.append(Path(spec.origin))  # imported already: its code is what runs
            folders = [str(p) for p in getattr(loaded, "__path__", None) or []]
        else:  # not imported yet, or a namespace package, whose folders the import
            found = _locate(part, search)  # computes afresh from the path: as it would
            if found is None:
                break
            origin, folders = found
            if origin is not None:
                places.append(origin)
            elif k == len(parts) - 1:  # the module asked for is a namespace package
                places += [Path(p) for p in folders]
        if not folders:
            break
        search = folders  # where the next level is looked for: its origin says where
    return places


def inside(path: Path, directory: Path) -> bool:
    """Whether ``path`` is ``directory`` or below it, links resolved."""
    try:
        path.resolve().relative_to(directory.resolve())
    except (ValueError, OSError):
        return False
    return True
