"""Skills: the ``@skill`` decorator and what it produces.

A skill is a function ``f(bb, rng, *, p1=..., p2=...) -> outcome`` (or a class whose instances
are such callables, for skills with set-up or state). The decorator reads its declaration once
and returns a :class:`Skill`, which holds an immutable :class:`SkillSpec` (name, outcomes,
parameters, blackboard keys) and the implementation. The executor calls the implementation
directly, so a skill costs one Python call per step and nothing more.

A *long-running* skill (a grasp, a base move) is declared the same way, as either

- a class with ``start(self, bb, rng, *, params...)``, ``tick(self, bb, rng) ->
  Literal["running", outcomes...]`` and optionally ``cancel(self, bb)``: one instance per
  activation (its ``__init__`` takes no arguments); or
- a generator function ``f(bb, rng, *, params...) -> Generator[str, None, Literal[...]]``
  that yields ``"running"`` (or nothing) until it returns its outcome; cancelling it closes
  the generator, so its ``finally:`` blocks are its cancel hook.
"""

from __future__ import annotations

import collections.abc
import contextlib
import copy
import functools
import inspect
import re
import typing
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, get_args, get_origin

import numpy as np

from .activation import RUNNING, Starter, driven, start_generator, start_instance
from .blackboard import Access, Blackboard
from .errors import ParamError, SkillDefinitionError, UndeclaredOutcomeError
from .params import _MISSING, Choice, Param, ParamSpec, make_param_spec, param_problems

__all__ = [
    "GeneratorSkill",
    "InstanceSkill",
    "Skill",
    "SkillFn",
    "SkillSpec",
    "TickingSkill",
    "skill",
]

SkillFn = Callable[..., str]
"""``f(bb, rng, **params) -> outcome``."""

KeyDecl = Iterable[str] | Mapping[str, type | tuple[type, ...]]


@dataclass(frozen=True)
class SkillSpec:
    """What a skill promises: everything an FSA needs to know without running it."""

    name: str
    outcomes: tuple[str, ...]
    params: tuple[ParamSpec, ...] = ()
    reads: frozenset[str] = frozenset()
    writes: frozenset[str] = frozenset()
    key_types: Mapping[str, type | tuple[type, ...]] = field(default_factory=dict)
    doc: str = ""

    def param(self, name: str) -> ParamSpec:
        for p in self.params:
            if p.name == name:
                return p
        raise ParamError(
            f"skill {self.name} has no parameter {name!r}; "
            f"its parameters are {[p.name for p in self.params] or 'none'}"
        )

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    def defaults(self) -> dict[str, Any]:
        return {p.name: p.default for p in self.params}

    def resolve_params(self, given: Mapping[str, Any], where: str = "") -> dict[str, Any]:
        """Defaults overlaid with ``given``, each checked against its range; raises
        :class:`ParamError` naming ``where`` (a state, say) and every problem."""
        values, problems = param_problems(self.name, self.params, given)
        if problems:
            raise ParamError((f"{where}: " if where else "") + "; ".join(
                p.message for p in problems))
        return values

    def access(self) -> Access:
        return Access(self.name, self.reads, self.writes)

    def same_signature(self, other: SkillSpec) -> bool:
        """True when two implementations are interchangeable in an FSA file."""
        def sig(spec: SkillSpec) -> list[tuple[Any, ...]]:
            return [(p.name, p.kind, p.low, p.high, p.choices, p.size, p.unit, p.scale,
                     _plain(p.default)) for p in spec.params]

        return self.outcomes == other.outcomes and sig(self) == sig(other)


class Skill:
    """A declared skill: its :class:`SkillSpec`, its implementation and its backend label.

    This class is the function kind; each other kind (:class:`InstanceSkill`,
    :class:`TickingSkill`, :class:`GeneratorSkill`, nested FSAs, py_trees subtrees) is a
    subclass that says how it runs through :meth:`starter`, :meth:`bind` and
    :meth:`cancel_hook`, so the engine never asks what kind a skill is. Calling a ``Skill``
    runs it once with the blackboard's access limited to its declared keys, which is handy
    in tests: ``move_to_object(bb, rng, approach=0.2)``.
    """

    __slots__ = ("backend", "impl", "spec")
    long_running = False
    """True for skills ticked until they finish (start/tick classes, generators, FSAs)."""

    def __init__(self, spec: SkillSpec, impl: Any, *, backend: str = "default") -> None:
        self.spec = spec
        self.impl = impl
        self.backend = backend

    @property
    def name(self) -> str:
        return self.spec.name

    def with_backend(self, backend: str) -> Skill:
        """A copy labelled with another backend (same implementation, same subclass)."""
        twin = copy.copy(self)
        twin.backend = backend
        return twin

    def starter(self, backend: str | None = None) -> Starter | None:
        """``start(bb, rng, **params) -> Activation`` for a long-running skill, else None."""
        return None

    def cancel_hook(self, backend: str | None = None) -> Callable[[Blackboard], Any] | None:
        """``cancel(bb)`` called when a state's time limit abandons this instant skill, if
        it has one (long-running skills cancel through their activation)."""
        return None

    def bind(self, registry: Any = None, backend: str | None = None) -> SkillFn:
        """The callable that runs the skill to completion: the function itself, or, for a
        long-running skill, a function that ticks it until it finishes."""
        start = self.starter(backend)
        if start is not None:
            return driven(start)
        return typing.cast(SkillFn, self.impl)

    def __call__(
        self, bb: Blackboard, rng: np.random.Generator | int | None = None, **params: Any
    ) -> str:
        """Run the skill once, outside an FSA, with its parameters checked."""
        kwargs = self.spec.resolve_params(params)
        rng = np.random.default_rng(rng)  # a Generator is returned as it is
        prev = bb._client
        bb._client = self.spec.access()
        try:
            out = self.bind()(bb, rng, **kwargs)
        finally:
            bb._client = prev
        if out not in self.spec.outcomes:
            raise UndeclaredOutcomeError(
                f"skill {self.name} returned {out!r}, which is not one of its declared "
                f"outcomes {list(self.spec.outcomes)}"
            )
        return out

    def __repr__(self) -> str:
        return f"<Skill {self.name} [{self.backend}] outcomes={list(self.spec.outcomes)}>"


class InstanceSkill(Skill):
    """A class with ``__call__``: one instance, made on first use, runs every activation."""

    __slots__ = ("_instance",)

    def __init__(self, spec: SkillSpec, impl: Any, *, backend: str = "default") -> None:
        super().__init__(spec, impl, backend=backend)
        self._instance: Any = None

    def with_backend(self, backend: str) -> Skill:
        twin = typing.cast(InstanceSkill, super().with_backend(backend))
        twin._instance = None
        return twin

    def bind(self, registry: Any = None, backend: str | None = None) -> SkillFn:
        if self._instance is None:
            try:
                self._instance = self.impl()
            except Exception as exc:
                raise SkillDefinitionError(
                    f"skill {self.name}: creating its instance ({self.impl.__name__}()) "
                    f"failed: {exc!r}"
                ) from exc
        return typing.cast(SkillFn, self._instance)

    def cancel_hook(self, backend: str | None = None) -> Callable[[Blackboard], Any] | None:
        hook = getattr(self.bind(None, backend), "cancel", None)
        return hook if callable(hook) else None


class TickingSkill(Skill):
    """A class with ``start`` / ``tick`` / ``cancel``: a fresh instance per activation."""

    __slots__ = ()
    long_running = True

    def starter(self, backend: str | None = None) -> Starter:
        return functools.partial(start_instance, self.impl)


class GeneratorSkill(Skill):
    """A generator function that yields ``"running"`` until it returns its outcome."""

    __slots__ = ()
    long_running = True

    def starter(self, backend: str | None = None) -> Starter:
        return functools.partial(start_generator, self.impl, self.name)


class Declaration(typing.TypedDict, total=False):
    """The keywords of :func:`skill`."""

    name: str | None
    outcomes: Iterable[str] | None
    reads: KeyDecl
    writes: KeyDecl
    backend: str


@typing.overload
def skill(fn: Callable[..., Any], **declaration: typing.Unpack[Declaration]) -> Skill: ...


@typing.overload
def skill(
    fn: None = None, **declaration: typing.Unpack[Declaration]
) -> Callable[[Callable[..., Any]], Skill]: ...


def skill(
    fn: Callable[..., Any] | None = None,
    *,
    name: str | None = None,
    outcomes: Iterable[str] | None = None,
    reads: KeyDecl = (),
    writes: KeyDecl = (),
    backend: str = "default",
) -> Skill | Callable[[Callable[..., Any]], Skill]:
    """Declare a skill.

    Use as ``@skill`` or ``@skill(reads=(...), writes=(...), outcomes=(...), name=...,
    backend=...)`` on a function ``f(bb, rng, *, params...) -> Literal[outcomes]`` or on a
    class whose ``__call__`` has that signature (its ``__init__`` takes no arguments).
    Long-running skills (see the module docstring) use the same declarations: a class with
    ``start`` / ``tick`` / ``cancel`` takes its parameters from ``start`` and its outcomes from
    ``tick``'s ``Literal`` (without ``"running"``); a generator function takes its outcomes
    from the return type of ``Generator[str, None, Literal[...]]``.

    - ``name`` defaults to the function name in CamelCase (``move_to_object`` →
      ``MoveToObject``), or the class name.
    - ``outcomes`` defaults to the ``Literal[...]`` of the return annotation.
    - ``reads`` / ``writes`` list blackboard keys, or map them to types.
    - ``backend`` labels this implementation (``"sim"``, ``"kinematic"``, ...): a registry
      may hold one implementation per backend under the same name.
    """

    def wrap(obj: Callable[..., Any]) -> Skill:
        return _make_skill(obj, name, outcomes, reads, writes, backend)

    return wrap(fn) if fn is not None else wrap


_CAMEL = re.compile(r"(?:^|_)([a-z0-9])")


def camel_name(name: str) -> str:
    """``move_to_object`` → ``MoveToObject``; names already in CamelCase stay."""
    if "_" not in name and name[:1].isupper():
        return name
    return _CAMEL.sub(lambda m: m.group(1).upper(), name)


def _keys(decl: KeyDecl, what: str, owner: str) -> tuple[frozenset[str], dict[str, Any]]:
    if isinstance(decl, str):
        raise SkillDefinitionError(
            f"skill {owner}: {what}={decl!r} is a string; write {what}=({decl!r},)"
        )
    if not isinstance(decl, Iterable):
        raise SkillDefinitionError(
            f"skill {owner}: {what}={decl!r}: write the blackboard keys as a tuple of names "
            f"(or a mapping of name to type), e.g. {what}=('jug',)"
        )
    types = {k: t for k, t in decl.items() if t is not None} if isinstance(decl, Mapping) \
        else {}
    for k, t in types.items():
        try:
            isinstance(None, t)
        except TypeError:
            raise SkillDefinitionError(
                f"skill {owner}: {what} key {k!r} has type {t!r}, which is not a type; "
                "write a class such as float, or None for any"
            ) from None
    keys = frozenset(decl)
    for k in keys:
        if not isinstance(k, str) or not k:
            raise SkillDefinitionError(f"skill {owner}: blackboard key {k!r} must be a string")
    return keys, types


def _make_skill(
    obj: Any,
    name: str | None,
    outcomes: Iterable[str] | None,
    reads: KeyDecl,
    writes: KeyDecl,
    backend: str,
) -> Skill:
    is_class = inspect.isclass(obj)
    outcome_source: Any = None  # the function whose return annotation lists the outcomes
    tick = getattr(obj, "tick", None) if is_class else None
    if callable(tick):
        if not callable(getattr(obj, "start", None)):
            raise SkillDefinitionError(
                f"class {obj.__name__}: a long-running skill defines both "
                "`def start(self, bb, rng, *, params...) -> None` and "
                "`def tick(self, bb, rng) -> Literal['running', 'success', ...]`"
            )
        tick_args = [p.name for p in _positional(tick)][1:]
        if len(tick_args) != 2:
            raise SkillDefinitionError(
                f"class {obj.__name__}: tick must be `def tick(self, bb, rng)`, found "
                f"arguments {tick_args}; parameters belong to start()"
            )
        func = obj.start
        outcome_source = tick
    elif is_class:
        # the class's own __call__ (or a base's): getattr would find the metaclass's
        call = next((vars(c)["__call__"] for c in obj.__mro__ if "__call__" in vars(c)), None)
        if call is None:
            raise SkillDefinitionError(
                f"class {obj.__name__} cannot be a skill: define "
                "`def __call__(self, bb, rng, *, params...) -> Literal[...]`, or "
                "start / tick / cancel for a long-running skill"
            )
        func = call
    elif callable(obj):
        func = obj
    else:
        raise SkillDefinitionError(f"@skill needs a function or a class, got {obj!r}")
    if inspect.iscoroutinefunction(func) or inspect.isasyncgenfunction(func):
        raise SkillDefinitionError(
            f"skill {name or getattr(obj, '__name__', '?')}: an async function is not a skill "
            "(nothing awaits it); write a plain function, or a generator that yields "
            "'running' while it waits"
        )
    skip = 1 if is_class else 0  # self
    skill_name = name or (obj.__name__ if is_class else
                          camel_name(getattr(obj, "__name__", "skill")))
    if not isinstance(skill_name, str) or not skill_name.isidentifier():
        raise SkillDefinitionError(
            f"skill name {skill_name!r} must be an identifier (letters, digits, _)"
        )

    sig = inspect.signature(func)
    hints = _annotations(func)
    positional = _positional(func)[skip:]
    if len(positional) != 2:
        raise SkillDefinitionError(
            f"skill {skill_name}: signature must be (bb, rng, *, params...), "
            f"found positional arguments {[p.name for p in positional]}; "
            "make parameters keyword-only by putting them after `*`"
        )
    params: list[ParamSpec] = []
    for p in sig.parameters.values():
        if p.kind is p.VAR_KEYWORD or p.kind is p.VAR_POSITIONAL:
            raise SkillDefinitionError(
                f"skill {skill_name}: *args/**kwargs cannot be declared as parameters; "
                "list each parameter after `*`"
            )
        if p.kind is not p.KEYWORD_ONLY:
            continue
        base, decl = _split_annotation(hints.get(p.name, inspect.Parameter.empty))
        default = _MISSING if p.default is p.empty else p.default
        if decl is None and base is inspect.Parameter.empty and isinstance(default, bool):
            base = bool
        params.append(make_param_spec(p.name, base, decl, default, skill_name))

    if outcomes is None:
        ret_hints = hints if outcome_source is None else _annotations(outcome_source)
        ret = hints_return = ret_hints.get("return", inspect.Parameter.empty)
        if inspect.isgeneratorfunction(func) and get_origin(ret) is collections.abc.Generator:
            ret = get_args(ret)[2]
        if get_origin(ret) is Literal:
            outs = tuple(get_args(ret))
            if outcome_source is not None:  # tick() -> Literal["running", ...]
                outs = tuple(o for o in outs if o != RUNNING)
        else:
            where = "tick's return" if outcome_source is not None else "the return"
            raise SkillDefinitionError(
                f"skill {skill_name}: declare its outcomes, either in {where} annotation "
                "(`-> Literal['success', 'failure']`; a generator: "
                "`-> Generator[str, None, Literal['success', 'failure']]`) or with "
                f"@skill(outcomes=('success', 'failure')); found {hints_return!r}"
            )
    else:
        if isinstance(outcomes, str):
            raise SkillDefinitionError(
                f"skill {skill_name}: outcomes={outcomes!r} is a string; "
                f"write outcomes=({outcomes!r},)"
            )
        outs = tuple(outcomes)
    if not outs:
        raise SkillDefinitionError(f"skill {skill_name}: needs at least one outcome")
    for o in outs:
        if not isinstance(o, str) or not o.isidentifier():
            raise SkillDefinitionError(
                f"skill {skill_name}: outcome {o!r} must be an identifier string"
            )
        if o == RUNNING:
            raise SkillDefinitionError(
                f"skill {skill_name}: {RUNNING!r} cannot be an outcome, it means "
                "'not finished yet'; make the skill long-running (start / tick / cancel, or "
                "a generator) and return it from tick instead"
            )
    if len(set(outs)) != len(outs):
        raise SkillDefinitionError(f"skill {skill_name}: outcomes {list(outs)} repeat")

    r, rt = _keys(reads, "reads", skill_name)
    w, wt = _keys(writes, "writes", skill_name)
    for k in set(rt) & set(wt):
        if rt[k] != wt[k]:
            raise SkillDefinitionError(
                f"skill {skill_name}: key {k!r} typed differently in reads and writes"
            )
    spec = SkillSpec(
        name=skill_name,
        outcomes=outs,
        params=tuple(params),
        reads=r,
        writes=w,
        key_types={**rt, **wt},
        doc=inspect.cleandoc(obj.__doc__ or ""),
    )
    kind: type[Skill] = Skill
    if is_class:
        kind = TickingSkill if outcome_source is not None else InstanceSkill
    elif inspect.isgeneratorfunction(obj):
        kind = GeneratorSkill
    return kind(spec, obj, backend=backend)


def _plain(value: Any) -> Any:
    """A parameter default in a form that compares by value (vectors as tuples)."""
    return tuple(np.asarray(value).ravel().tolist()) if isinstance(value, np.ndarray) else value


def _positional(func: Callable[..., Any]) -> list[inspect.Parameter]:
    return [p for p in inspect.signature(func).parameters.values()
            if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]


def _annotations(func: Any) -> dict[str, Any]:
    """Evaluate a function's annotations, tolerating ``Param(...)`` used as an annotation."""
    # fails e.g. on `x: Param(0, 1) = 0.5` under `from __future__ import annotations`
    with contextlib.suppress(Exception):
        return typing.get_type_hints(func, include_extras=True)
    # only parameters after `*` and the return type matter to a skill (the caller has read
    # the signature already)
    needed = {n for n, p in inspect.signature(func).parameters.items()
              if p.kind is p.KEYWORD_ONLY} | {"return"}
    out: dict[str, Any] = {}
    for k, v in (getattr(func, "__annotations__", None) or {}).items():
        if isinstance(v, str):
            try:
                v = eval(v, dict(getattr(func, "__globals__", {})), {})
            except Exception as exc:
                if k not in needed:  # e.g. `bb: Blackboard` imported inside a function
                    continue
                raise SkillDefinitionError(
                    f"{getattr(func, '__qualname__', func)}: cannot evaluate the annotation "
                    f"of {k!r} ({v!r}): {exc}; with `from __future__ import annotations`, "
                    "names in parameter and return annotations must be importable at module "
                    "level"
                ) from exc
        out[k] = v
    return out


def _split_annotation(ann: Any) -> tuple[Any, Param | Choice | None]:
    """``Annotated[float, Param(...)]`` → (float, Param); ``Param(...)`` → (None, Param)."""
    if isinstance(ann, (Param, Choice)):
        return None, ann
    if get_origin(ann) is typing.Annotated:
        base, *extras = get_args(ann)
        return base, next((a for a in extras if isinstance(a, (Param, Choice))), None)
    return ann, None
