"""What Ray's runtime environment ships to a cluster's nodes, so that they need Python, Ray
and the task's libraries but not this project: the package ``skillcompose`` as it installs
(:func:`_project_package`), the task's module and the modules its skills come from
(:func:`ray_runtime_env`)."""

from __future__ import annotations

import atexit
import functools
import sys
from pathlib import Path
from typing import Any

from skillcompose.task import Task, TaskRef

from .errors import EvolutionError

__all__ = ["ray_runtime_env"]

_PROJECT_PACKAGES = ("skillcompose",)


@functools.lru_cache(maxsize=1)
def _project_package() -> str:
    """The folder of the ``skillcompose`` package as it installs, to ship to a cluster: the
    package's own folder when its subpackages lie inside it (an installed wheel); else (a
    source checkout, whose ``evolve/``, ``robots/`` and ``skills/`` are mapped into the
    package by ``package-dir``) a copy laid out as installed, kept until the process ends
    (Ray hashes the folder again for each actor it starts)."""
    import importlib.util
    import shutil
    import tempfile

    root = Path(str(sys.modules["skillcompose"].__file__)).resolve().parent
    outside: dict[str, Path] = {}
    for sub in ("evolve", "robots", "skills", "view"):
        spec = importlib.util.find_spec(f"skillcompose.{sub}")
        if spec is not None and spec.submodule_search_locations:
            where = Path(next(iter(spec.submodule_search_locations))).resolve()
            if not where.is_relative_to(root):
                outside[sub] = where
    if not outside:
        return str(root)
    stage = Path(tempfile.mkdtemp(prefix="skillcompose-ship-"))
    atexit.register(shutil.rmtree, stage, True)
    skip = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(root, stage / "skillcompose", ignore=skip)
    for sub, where in outside.items():
        shutil.copytree(where, stage / "skillcompose" / sub, ignore=skip)
    return str(stage / "skillcompose")


def _installed(path: str) -> bool:
    """Whether a module at ``path`` comes with the interpreter or an installed distribution
    (which a cluster's nodes are expected to have, like numpy), not from user code."""
    import sysconfig

    parts = Path(path).resolve().parts
    if "site-packages" in parts or "dist-packages" in parts:
        return True
    stdlib = Path(sysconfig.get_paths()["stdlib"]).resolve()
    return Path(path).resolve().is_relative_to(stdlib)


def ray_runtime_env(task: Task) -> tuple[dict[str, Any], TaskRef]:
    """What a Ray cluster's workers need to rebuild ``task``, shipped through Ray's runtime
    environment rather than installed on the nodes: this project's packages, the task's
    module and the modules its skills come from (each top-level package, or a single-file
    module, that is not part of an installed distribution), as ``py_modules``. A task
    loaded from a ``.py`` path ships that file's directory as the ``working_dir`` and is
    rebuilt there by module name. Returns the runtime environment and the reference the
    workers rebuild the task from."""
    if task.ref is None:
        raise EvolutionError(
            f"backend 'ray' rebuilds task {task.name} in each actor from its module: "
            "load the task with skillcompose.task.load_task(module, **settings)"
        )
    ref = task.ref
    env: dict[str, Any] = {}
    names: list[str] = list(_PROJECT_PACKAGES)
    module = ref.module
    if module.endswith(".py") or "/" in module or "\\" in module:
        path = Path(module).resolve()
        env["working_dir"] = str(path.parent)
        ref = TaskRef(path.stem, dict(ref.settings))
    else:
        names.append(module.split(".", 1)[0])
    for name in task.registry:
        for backend in task.registry.backends(name):
            impl = getattr(task.registry.resolve(name, backend), "impl", None)
            owner = getattr(impl, "__module__", None) or ""
            if owner and not owner.startswith("_skillcompose_user_"):
                names.append(owner.split(".", 1)[0])
    modules: list[str] = []
    for top in dict.fromkeys(names):
        found = sys.modules.get(top)
        if found is None:
            continue
        if top in _PROJECT_PACKAGES:
            modules.append(_project_package())
            continue
        paths = list(getattr(found, "__path__", []))
        where = paths[0] if len(paths) == 1 else getattr(found, "__file__", None)
        if where and not _installed(where):
            modules.append(where)
    env["py_modules"] = modules
    return env, ref
