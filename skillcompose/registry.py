"""The registry: which skills an FSA may name, and which implementation (backend) runs.

A :class:`Registry` is an instance; nothing registers itself globally. One skill name may
have several implementations, one per *backend* (``"sim"``, ``"kinematic"``...), all with the
same outcomes and parameters (ranges, units, scales, defaults). An FSA file names skills
only; the caller picks the backend when it compiles or runs the FSA, so one file runs on any
backend and means the same on each.

Skills are collected from Python modules (a dotted name or a ``.py`` path): a module either
defines ``register(registry)`` or has its :class:`~skillcompose.skill.Skill` objects picked
up from its top level. Installed packages advertise modules in the ``skillcompose.skills``
entry-point group.
"""

from __future__ import annotations

import difflib
import graphlib
import importlib
import importlib.util
import inspect
import sys
import traceback
from collections.abc import Callable, Iterable, Iterator
from importlib import metadata
from pathlib import Path
from types import ModuleType

from .errors import RegistryError, UnknownSkillError, exception_text, one_line
from .fsa import FSA
from .fsafile import load_fsa
from .nested import fsa_skill
from .origins import on_path, use_import_path
from .params import check_declared
from .skill import Skill, SkillSpec

__all__ = ["DEFAULT_BACKEND", "ENTRY_POINT_GROUP", "Registry", "check_backend"]

DEFAULT_BACKEND = "default"
ENTRY_POINT_GROUP = "skillcompose.skills"


class Registry:
    """Maps skill names to their implementations, one per backend."""

    def __init__(self, skills: Iterable[Skill] = (), *, backend: str = DEFAULT_BACKEND) -> None:
        self._impls: dict[str, dict[str, Skill]] = {}
        self.backend = backend
        for s in skills:
            self.add(s)

    # -- adding ------------------------------------------------------------------------------
    def add(self, s: Skill, *, backend: str | None = None, replace: bool = False) -> Skill:
        """Add one implementation; ``backend`` overrides the skill's own label."""
        if not isinstance(s, Skill):
            raise RegistryError(
                f"registry.add() takes a Skill made by @skill, got {type(s).__name__}"
            )
        for spec in s.spec.params:  # a spec built by hand, not by @skill, is checked here
            check_declared(spec, s.name)
        label = backend or s.backend
        if backend is not None and backend != s.backend:
            s = s.with_backend(backend)
        impls = self._impls.setdefault(s.name, {})
        for other in impls.values():
            if not s.spec.same_signature(other.spec):
                raise RegistryError(
                    f"skill {s.name}: backend {label!r} declares outcomes "
                    f"{list(s.spec.outcomes)} and parameters {_sig(s.spec)}, but backend "
                    f"{other.backend!r} declares {list(other.spec.outcomes)} and "
                    f"{_sig(other.spec)}; every backend of a skill needs the same signature"
                )
        if label in impls and impls[label] is not s and not replace:
            raise RegistryError(
                f"skill {s.name} already has a {label!r} implementation; "
                "pass replace=True to swap it"
            )
        impls[label] = s
        return s

    def add_fsa(
        self, fsa: FSA | str | Path, *, name: str | None = None, on_timeout: str | None = None
    ) -> Skill:
        """Register an FSA (in memory or a file) as a skill of other FSAs.

        Its terminal outcomes become the skill's outcomes; it shares the caller's blackboard
        and random generator. ``on_timeout`` names the outcome its timeout maps to (default:
        ``"failure"`` when that is a terminal, else a ``timeout`` outcome is added).
        """
        machine = fsa if isinstance(fsa, FSA) else load_fsa(fsa)
        self._check_free(machine, name or machine.name)
        return self.add(fsa_skill(machine, self, name=name, on_timeout=on_timeout))

    def _check_free(self, machine: FSA, name: str) -> None:
        """Refuse an FSA's skill name that a skill has already (its states could run the
        FSA again: a recursion)."""
        if name and name in self._impls:
            where = one_line(machine.path) + ": " if machine.path else ""
            raise RegistryError(
                f"{where}the FSA's name {name} is a skill already; an FSA used as a skill "
                "needs a name of its own: rename it (its `name:`)"
            )

    def load_modules(self, targets: Iterable[str | ModuleType]) -> list[Skill]:
        """:meth:`load_module` for each target: skills modules in their order, then FSA
        files in the order their nesting needs (one that uses the skill another defines
        after it, whatever order they were given in); FSA files that use each other in a
        circle are refused in one line."""
        targets = list(targets)
        files = [t for t in targets if isinstance(t, str) and t.endswith((".yaml", ".yml"))]
        added: list[Skill] = []
        for t in targets:
            if not (isinstance(t, str) and t in files):
                added += self.load_module(t)
        by_place = {Path(f).resolve(): f for f in reversed(files)}  # one file, one load,
        machines = {f: load_fsa(f) for f in dict.fromkeys(  # however it was named
            by_place[Path(f).resolve()] for f in files)}
        for m in machines.values():
            self._check_free(m, m.name)
        defines = {m.name: f for f, m in reversed(machines.items()) if m.name}
        needs = {f: {defines[st.skill] for st in m.states.values() if st.skill in defines}
                 for f, m in machines.items()}
        try:
            order = list(graphlib.TopologicalSorter(needs).static_order())
        except graphlib.CycleError as exc:
            circle = [str(f) for f in reversed(exc.args[1])]  # each uses the next
            if len(set(circle)) == 1:
                raise RegistryError(
                    f"{one_line(circle[0])}: the FSA {machines[circle[0]].name} uses itself as "
                    "a skill: an FSA cannot contain itself; use another skill there"
                ) from None
            raise RegistryError(
                "the FSA files " + " -> ".join(
                    f"{one_line(f)} ({machines[f].name})" for f in circle)
                + " use each other in a circle: an FSA cannot contain itself; break the "
                "circle"
            ) from None
        for f in order:
            added.append(self.add_fsa(machines[f]))
        return added

    def load_module(self, target: str | ModuleType) -> list[Skill]:
        """Import a module (dotted name, ``.py`` path, or FSA file) and add its skills."""
        if isinstance(target, str) and target.endswith((".yaml", ".yml")):
            return [self.add_fsa(target)]
        module = target if isinstance(target, ModuleType) else import_target(target)
        # the module as the person named it (a file loaded by path has an internal name)
        where = target if isinstance(target, str) else module.__name__
        before = {(n, b) for n, impls in self._impls.items() for b in impls}
        reg = getattr(module, "register", None)
        if callable(reg) and not isinstance(reg, Skill):
            _call_register(reg, self, f"skills module {where}")
        else:
            found = [v for v in vars(module).values() if isinstance(v, Skill)]
            if not found:
                raise RegistryError(
                    f"skills module {where} defines no skills: decorate functions with "
                    "@skill, or define register(registry)"
                )
            for s in found:
                if self._impls.get(s.name, {}).get(s.backend) is not s:
                    self.add(s)
        return [s for n, impls in self._impls.items() for b, s in impls.items()
                if (n, b) not in before]

    def load_entry_points(self, group: str = ENTRY_POINT_GROUP) -> list[Skill]:
        """Add the skills of every installed package that advertises them in ``group``."""
        added: list[Skill] = []
        for ep in metadata.entry_points(group=group):
            where = f"entry point {ep.name} = {ep.value} (group {group})"
            try:
                obj = ep.load()
            except KeyboardInterrupt:
                raise
            except BaseException as exc:
                raise RegistryError(
                    f"{where}: cannot import it: {describe_exception(exc)}; fix or uninstall "
                    "the package that declares it"
                ) from exc
            if isinstance(obj, ModuleType):
                added += self.load_module(obj)
            elif callable(obj):
                _call_register(obj, self, where)
            else:
                raise RegistryError(
                    f"entry point {ep.name} = {ep.value} in group {group} must be a module "
                    "or a register(registry) function"
                )
        return added

    @classmethod
    def from_modules(
        cls, targets: Iterable[str | ModuleType], *, backend: str = DEFAULT_BACKEND
    ) -> Registry:
        reg = cls(backend=backend)
        reg.load_modules(targets)
        return reg

    # -- looking up --------------------------------------------------------------------------
    def __contains__(self, name: object) -> bool:
        return name in self._impls

    def __iter__(self) -> Iterator[str]:
        return iter(self._impls)

    def __len__(self) -> int:
        return len(self._impls)

    def names(self) -> list[str]:
        return list(self._impls)

    def backends(self, name: str) -> list[str]:
        return list(self._get_impls(name))

    def spec(self, name: str) -> SkillSpec:
        """The declaration shared by every backend of ``name``."""
        return next(iter(self._get_impls(name).values())).spec

    def resolve(self, name: str, backend: str | None = None) -> Skill:
        """The implementation of ``name`` to run on ``backend``.

        Looks for ``backend`` (default: this registry's backend), then ``"default"``, then
        the only implementation when there is just one.
        """
        impls = self._get_impls(name)
        want = backend or self.backend
        if want in impls:
            return impls[want]
        if DEFAULT_BACKEND in impls:
            return impls[DEFAULT_BACKEND]
        if len(impls) == 1:
            return next(iter(impls.values()))
        raise UnknownSkillError(
            f"skill {name} has no {want!r} implementation; it has {sorted(impls)}. "
            f"Run with --backend one of {sorted(impls)}"
        )

    def _get_impls(self, name: str) -> dict[str, Skill]:
        try:
            return self._impls[name]
        except KeyError:
            close = difflib.get_close_matches(name, list(self._impls), n=3)
            hint = f"; did you mean {' or '.join(close)}?" if close else ""
            known = ", ".join(sorted(self._impls)) or "none (load skills with --skills MODULE)"
            raise UnknownSkillError(
                f"unknown skill {name!r}{hint or '; load the module or FSA file that defines it'}"
                f" (--skills, or the task's registry). Known skills: {known}") from None

    def __repr__(self) -> str:
        return f"Registry({sorted(self._impls)}, backend={self.backend!r})"


def _sig(spec: SkillSpec) -> list[str]:
    return [
        f"{p.name}: {p.describe_range()}{', log scale' if p.scale == 'log' else ''}, "
        f"default {p.default!r}" for p in spec.params
    ]


def _call_register(register: Callable[..., object], registry: Registry, where: str) -> None:
    """Call a module's ``register(registry)``; whatever goes wrong becomes one
    :class:`RegistryError` naming ``where`` (the module as the person named it)."""
    try:
        inspect.signature(register).bind(registry)
    except TypeError:
        raise RegistryError(
            f"{where}: register{_signature(register)} cannot be called as "
            "register(registry); define it as `def register(registry): registry.add(...)`"
        ) from None
    except ValueError:  # no signature to read (a builtin): the call will tell
        pass
    try:
        register(registry)
    except KeyboardInterrupt:
        raise
    except RegistryError as exc:
        raise RegistryError(f"{where}: register(registry): {exc}") from exc
    except BaseException as exc:
        raise RegistryError(
            f"{where}: register(registry) raised {describe_exception(exc)}; fix its register()"
        ) from exc


def _signature(fn: Callable[..., object]) -> str:
    try:
        return str(inspect.signature(fn))
    except (TypeError, ValueError):
        return "(...)"


def import_target(target: str) -> ModuleType:
    """Import a dotted module name or a ``.py`` file path.

    A file's own directory is put on the import path, so that it imports the modules
    beside it. A dotted name is looked up from the current directory too (as ``python -m``
    does) and, when this is a source checkout, from its root (``examples.pour_water`` from
    anywhere). Whatever the module raises while it is imported becomes a
    :class:`RegistryError` naming its file and line.
    """
    try:
        return _import_target(target)
    except (RegistryError, KeyboardInterrupt):
        raise
    except BaseException as exc:  # sys.exit() at import too: the module does not load
        raise RegistryError(f"cannot import {target}: {describe_exception(exc)}") from exc


def describe_exception(exc: BaseException) -> str:
    """``file:line: Type: message`` of the innermost frame (or of a syntax error)."""
    if isinstance(exc, SyntaxError):
        where = f"{exc.filename}:{exc.lineno}: " if exc.filename else ""
        return f"{where}{type(exc).__name__}: {exc.msg}"
    frames = traceback.extract_tb(exc.__traceback__)
    where = f"{frames[-1].filename}:{frames[-1].lineno}: " if frames else ""
    return f"{where}{exception_text(exc)}"


def _import_in_package(path: Path) -> ModuleType | None:
    """A ``.py`` file inside a package (its folder has an ``__init__.py``), imported by its
    dotted name with the folder above the package on the path for this import only, so that
    it imports its package as ``python -m`` would (``examples/kinematic_pour.py`` imports
    ``from examples import pour_water``); None when it is not in a package, or when that name
    already means another file."""
    file = path.resolve()
    parts, folder = [file.stem], file.parent
    while (folder / "__init__.py").is_file() and folder.name.isidentifier():
        parts.insert(0, folder.name)
        folder = folder.parent
    if len(parts) == 1 or not all(p.isidentifier() for p in parts):
        return None
    name = ".".join(parts)
    loaded = sys.modules.get(name)
    if loaded is None:
        top = sys.modules.get(parts[0])
        if top is not None and not any(
                Path(p).resolve() == folder / parts[0] for p in getattr(top, "__path__", [])):
            return None  # the package's name belongs to another folder already
        with on_path([str(folder), str(file.parent)], first=True):
            loaded = importlib.import_module(name)
    origin = getattr(loaded, "__file__", None)
    return loaded if origin and Path(origin).resolve() == file else None


def _import_target(target: str) -> ModuleType:
    if target.endswith(".py") or "/" in target or "\\" in target:
        path = Path(target)
        if not path.is_file():
            raise RegistryError(f"skills module file {target} does not exist")
        packaged = _import_in_package(path)
        if packaged is not None:
            return packaged
        mod_name = "_skillcompose_user_" + path.stem + f"_{abs(hash(str(path.resolve())))}"
        if mod_name in sys.modules:
            return sys.modules[mod_name]
        spec = importlib.util.spec_from_file_location(mod_name, path)
        if spec is None or spec.loader is None:
            raise RegistryError(f"cannot import {target} as a Python module")
        module = importlib.util.module_from_spec(spec)
        sys.modules[mod_name] = module
        try:  # the modules beside the file, for this import only
            with on_path([str(path.resolve().parent)], first=True):
                spec.loader.exec_module(module)
        except BaseException:
            del sys.modules[mod_name]
            raise
        return module
    # the current directory, as `python -m` has it, and a source checkout's own packages
    # (examples.*), for this import only: the path skillcompose.origins checks before a
    # run's module is imported
    try:
        with use_import_path(target.split(".", 1)[0]):
            return importlib.import_module(target)
    except ModuleNotFoundError as exc:
        if exc.name and target.startswith(exc.name):
            raise RegistryError(
                f"cannot import skills module {target!r}: {exc}. Give a dotted module "
                "name importable from the current directory, or a path to a .py file"
            ) from exc
        raise


def check_backend(registry: Registry, backend: str) -> None:
    """Raise :class:`RegistryError` unless some skill of ``registry`` has ``backend``
    (the command line's ``--backend``, the viewer's replay, a robustness sweep)."""
    known = sorted({b for name in registry.names() for b in registry.backends(name)})
    if backend not in known:
        raise RegistryError(
            f"--backend {backend!r}: no loaded skill has this backend; the loaded skills "
            f"have {', '.join(known) or 'none'}"
        )
