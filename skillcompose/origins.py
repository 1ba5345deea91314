"""Where importing a module would read code from, found without running any: so that code
that came with a directory received from someone else (a run directory, a folder of runs
being viewed) is never imported from it by accident."""

from __future__ import annotations

import importlib.machinery
import os
import sys
from pathlib import Path

__all__ = ["inside", "is_file_target", "module_origins"]


def is_file_target(module: str) -> bool:
    """Whether ``module`` (as ``--task`` takes it) names a file rather than a module."""
    return module.endswith(".py") or "/" in module or "\\" in module


def module_origins(module: str) -> list[Path]:
    """The files and folders importing ``module`` (a dotted name, or a ``.py`` path) would
    read code from, found without running any: its top-level package's or module's, as the
    runtime's import finds them (the current directory included)."""
    if is_file_target(module):
        return [Path(module)]
    top = module.split(".")[0]
    if top in sys.modules:  # imported already: nothing new is read from disk for its top
        spec = getattr(sys.modules[top], "__spec__", None)
    else:
        path = [p or os.getcwd() for p in sys.path]
        if os.getcwd() not in path:  # the runtime's import adds the current directory
            path.append(os.getcwd())
        try:
            spec = importlib.machinery.PathFinder.find_spec(top, path)
        except (ImportError, ValueError):
            spec = None
    if spec is None:
        return []
    places = [Path(spec.origin)] if spec.origin and spec.has_location else []
    places += [Path(p) for p in (spec.submodule_search_locations or [])]
    return places


def inside(path: Path, directory: Path) -> bool:
    """Whether ``path`` is ``directory`` or below it, links resolved."""
    try:
        path.resolve().relative_to(directory.resolve())
    except (ValueError, OSError):
        return False
    return True
