"""Skill contracts: does a skill do what its ``@skill`` declaration says, on any input?

:func:`check_skill` runs a skill on many generated inputs (``hypothesis`` draws them): its
parameters anywhere within their declared ranges (:func:`skill_params`), and blackboards
holding the keys it declares it reads (:func:`skill_blackboards`: from the values you give,
from a task's worlds, or from the keys' declared types). It runs each input twice with the
same seed and reports, with the first input that shows it:

- a read or a write of a key the skill does not declare (even one whose error the skill
  caught), and a value of the wrong type written to a typed key;
- an outcome it does not declare;
- a result (outcome, error or blackboard afterwards) that differs for the same seed;
- an exception on in-range parameters.

``hypothesis`` is a test tool, not a dependency of the runtime: it is imported when a
strategy is built.
"""

from __future__ import annotations

import copy
import importlib.util
import math
import traceback
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numpy as np

from ..blackboard import Blackboard, diff
from ..errors import BlackboardAccessError, BlackboardTypeError, clip, exception_text, one_line
from ..params import ParamSpec
from ..skill import Skill, SkillSpec
from .assertions import CheckFailed

if TYPE_CHECKING:
    from hypothesis.strategies import SearchStrategy

__all__ = [
    "ContractReport",
    "SkillContractError",
    "Violation",
    "ViolationKind",
    "check_skill",
    "skill_blackboards",
    "skill_params",
]

ViolationKind = Literal["undeclared read", "undeclared write", "undeclared outcome",
                        "wrong type", "differs for the same seed", "raised"]
World = Callable[[np.random.Generator], Blackboard]
"""A task's ``setup``: the world of one episode, drawn with its generator."""

_SEEDS = 2**32 - 1
_PAST = {"read": "read", "write": "wrote"}
_ORDER: tuple[ViolationKind, ...] = ("undeclared read", "undeclared write", "undeclared outcome",
                                     "wrong type", "raised", "differs for the same seed")
_MAGNITUDE = 1e6  # a typed number the caller gave no values for is drawn within ±this


def _require_hypothesis() -> None:
    if importlib.util.find_spec("hypothesis") is None:
        raise ModuleNotFoundError(
            "skillcompose.testing's skill checks need hypothesis, a test tool: pip install "
            "hypothesis (or pip install -e '.[test]')")


# -- strategies ------------------------------------------------------------------------------
def skill_params(skill: Skill | SkillSpec) -> SearchStrategy[dict[str, Any]]:
    """A ``hypothesis`` strategy of a skill's parameters: ``{name: value}``, each value
    anywhere within its declared range (bounds included), of its declared kind."""
    _require_hypothesis()
    import hypothesis.strategies as st

    spec = skill.spec if isinstance(skill, Skill) else skill
    return st.fixed_dictionaries({p.name: _param(p) for p in spec.params})


def _param(p: ParamSpec) -> SearchStrategy[Any]:
    import hypothesis.strategies as st

    if p.kind == "bool":
        return st.booleans()
    if p.kind == "choice":
        return st.sampled_from(p.choices)
    low, high = float(p.low or 0.0), float(p.high or 0.0)  # a number's bounds are set
    if p.kind == "int":
        return st.integers(math.ceil(low), math.floor(high))
    # the bounds as often as hypothesis's own floats, which seldom reach them
    number = st.one_of(st.sampled_from(sorted({low, high})),
                       st.floats(low, high, allow_nan=False, allow_infinity=False))
    if p.size is None:
        return number
    return st.lists(number, min_size=p.size, max_size=p.size).map(tuple)


def skill_blackboards(
    skill: Skill | SkillSpec, *, world: World | None = None,
    values: Mapping[str, Any] | None = None,
) -> SearchStrategy[dict[str, Any]]:
    """A ``hypothesis`` strategy of a skill's blackboard contents (``{key: value}``, for
    ``Blackboard(...)``): every key it declares it reads, and the other declared keys a
    world holds.

    A key's value comes from ``values`` (a strategy or a value per key), else from
    ``world`` (a task's ``setup``: its worlds, drawn with random seeds), else from the type
    the skill declares for it (``bool``, ``int``, ``float``, ``str``; numbers within
    ±1e6). A key read with none of these is refused, in one line naming it.
    """
    _require_hypothesis()
    import hypothesis.strategies as st

    spec = skill.spec if isinstance(skill, Skill) else skill
    declared = spec.reads | spec.writes
    given = {k: v if isinstance(v, st.SearchStrategy) else st.just(v)
             for k, v in (values or {}).items()}
    from_world = set() if world is None else set(_world_values(world, declared, 0))
    typed = {k: s for k in spec.reads if (s := _typed(spec.key_types.get(k))) is not None}
    missing = sorted(spec.reads - set(given) - from_world - set(typed))
    if missing:
        raise ValueError(
            f"skill {spec.name} reads {', '.join(map(repr, missing))}, for which no values "
            f"are known: give values={{{missing[0]!r}: <strategy or value>, ...}}, a world "
            f"(world=task.setup), or a type in its declaration (reads={{{missing[0]!r}: "
            "float}})")
    fixed = st.fixed_dictionaries({**{k: s for k, s in typed.items() if k not in from_world},
                                   **given})
    if world is None:
        return fixed
    worlds = st.integers(0, _SEEDS).map(lambda s: _world_values(world, declared, s))
    return st.tuples(worlds, fixed).map(lambda pair: {**pair[0], **pair[1]})


def _world_values(world: World, keys: frozenset[str], seed: int) -> dict[str, Any]:
    bb = world(np.random.default_rng(seed))
    contents = bb.to_dict() if isinstance(bb, Blackboard) else dict(bb)
    return {k: v for k, v in contents.items() if k in keys}


def _typed(kind: type | tuple[type, ...] | None) -> SearchStrategy[Any] | None:
    import hypothesis.strategies as st

    if kind is None:
        return None
    if isinstance(kind, tuple):
        parts = [s for k in kind if (s := _typed(k)) is not None]
        return st.one_of(*parts) if len(parts) == len(kind) else None
    if kind is bool:
        return st.booleans()
    if kind is int:
        return st.integers(-int(_MAGNITUDE), int(_MAGNITUDE))
    if kind is float:
        return st.floats(-_MAGNITUDE, _MAGNITUDE, allow_nan=False)
    if kind is str:
        return st.text(max_size=20)
    return None


# -- what one input shows --------------------------------------------------------------------
@dataclass(frozen=True)
class Violation:
    """One way a skill broke its contract: the kind, what (a key, an outcome, an error),
    the message for its first input, that input, and on how many inputs it showed."""

    kind: ViolationKind
    what: str
    message: str
    params: Mapping[str, Any]
    blackboard: Mapping[str, Any]
    rng_seed: int
    count: int = 1

    def describe(self, call: str) -> str:
        """The violation, and the call that shows it (``call``: the skill's Python name)."""
        return (f"- {self.kind}: {self.message} (on {self.count} input(s); the first: "
                f"{call}(Blackboard({clip(repr(dict(self.blackboard)), 200)}), "
                f"{self.rng_seed}{_kwargs(self.params)}))")


def _kwargs(params: Mapping[str, Any]) -> str:
    return "".join(f", {k}={clip(repr(v), 60)}" for k, v in params.items())


class _Watched(Blackboard):
    """A blackboard that notes each undeclared access, even one whose error the skill
    catches."""

    __slots__ = ("undeclared",)

    def __init__(self, initial: Mapping[str, Any], types: Mapping[str, Any]) -> None:
        super().__init__(initial, types=types)
        self.undeclared: set[tuple[str, str]] = set()

    def _note(self, key: object, write: bool) -> None:
        c = self._client
        if c is not None and isinstance(key, str) and \
                not (key in c.writes if write else c.can_read(key)):
            self.undeclared.add(("write" if write else "read", key))

    def __getitem__(self, key: str) -> Any:
        self._note(key, False)
        return super().__getitem__(key)

    def get(self, key: str, default: Any = None) -> Any:
        self._note(key, False)
        return super().get(key, default)

    def __contains__(self, key: object) -> bool:
        self._note(key, False)
        return super().__contains__(key)

    def __setitem__(self, key: str, value: Any) -> None:
        self._note(key, True)
        super().__setitem__(key, value)

    def __delitem__(self, key: str) -> None:
        self._note(key, True)
        super().__delitem__(key)


class _Run(NamedTuple):
    outcome: Any
    error: BaseException | None
    after: dict[str, Any]
    undeclared: frozenset[tuple[str, str]]


def _run(skill: Skill, params: Mapping[str, Any], contents: Mapping[str, Any],
         rng_seed: int) -> _Run:
    spec = skill.spec
    bb = _Watched(copy.deepcopy(dict(contents)), spec.key_types)
    kwargs = spec.resolve_params(params)
    call = skill.bind()
    out: Any = None
    error: BaseException | None = None
    bb._client = spec.access()
    try:
        out = call(bb, np.random.default_rng(rng_seed), **kwargs)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # sys.exit() in a skill ends its run in error too
        error = exc
    finally:
        bb._client = None
    return _Run(out, error, bb.to_dict(), frozenset(bb.undeclared))


def _found(skill: Skill, first: _Run, second: _Run) -> list[tuple[ViolationKind, str, str]]:
    """(kind, what, message) for each way these two runs of one input break the contract."""
    spec = skill.spec
    found: list[tuple[ViolationKind, str, str]] = []
    for op, key in sorted(first.undeclared):
        declared = sorted(spec.reads) if op == "read" else sorted(spec.writes)
        kind: ViolationKind = "undeclared read" if op == "read" else "undeclared write"
        found.append((kind, key,
                      f"{_PAST[op]} blackboard key {key!r}, which it does not declare ({op}s: "
                      f"{declared}); add it to {op}s=(...) in its @skill declaration"))
    exc = first.error
    if exc is None and first.outcome not in spec.outcomes:
        found.append(("undeclared outcome", clip(repr(first.outcome), 60),
                      f"returned {clip(repr(first.outcome), 60)}, which is not one of its "
                      f"declared outcomes {list(spec.outcomes)}"))
    elif isinstance(exc, BlackboardTypeError):
        found.append(("wrong type", type(exc).__name__, one_line(str(exc))))
    elif exc is not None and not (isinstance(exc, BlackboardAccessError) and first.undeclared):
        found.append(("raised", type(exc).__name__,
                      f"raised {_where(exc)} on in-range parameters"))
    change = _difference(first, second)
    if change:
        found.append(("differs for the same seed", "",
                      f"{change} when run twice on the same input and seed; draw randomness "
                      "only from the generator it is given, and keep no state between runs"))
    return found


def _where(exc: BaseException) -> str:
    """``ZeroDivisionError: boom (skills.py:33, in carry)``: the error and the innermost
    frame of its traceback."""
    frames = traceback.extract_tb(exc.__traceback__)
    at = f" ({Path(frames[-1].filename).name}:{frames[-1].lineno}, in {frames[-1].name})" \
        if frames else ""
    return clip(one_line(exception_text(exc)), 200) + at


def _difference(a: _Run, b: _Run) -> str:
    """How two runs of one input differ ('' when they do not)."""
    if (a.error is None) != (b.error is None) or (
            a.error is not None and b.error is not None and
            exception_text(a.error) != exception_text(b.error)):
        shown = [exception_text(r.error) if r.error is not None else f"returned {r.outcome!r}"
                 for r in (a, b)]
        return f"{clip(shown[0], 80)}, then {clip(shown[1], 80)}"
    if a.outcome != b.outcome:
        return f"returned {a.outcome!r}, then {b.outcome!r}"
    changed = diff(a.after, b.after)
    if changed:
        key, (first, second) = next(iter(changed.items()))
        return (f"left blackboard key {key!r} = {clip(repr(first), 60)}, then "
                f"{clip(repr(second), 60)}")
    return ""


# -- the check -------------------------------------------------------------------------------
@dataclass(frozen=True)
class ContractReport:
    """What :func:`check_skill` found: the inputs run, the outcomes seen, the violations."""

    skill: str
    examples: int
    outcomes: Mapping[str, int] = field(default_factory=dict)
    violations: tuple[Violation, ...] = ()
    call: str = ""
    """The skill's name in Python (the decorated function's or class's), to rerun an input."""

    @property
    def ok(self) -> bool:
        return not self.violations

    def describe(self) -> str:
        if self.ok:
            seen = ", ".join(f"{o} {n}" for o, n in self.outcomes.items()) or "none"
            return (f"skill {self.skill} kept its contract on {self.examples} generated "
                    f"input(s) (outcomes: {seen})")
        return "\n".join([f"skill {self.skill} broke its contract on {self.examples} "
                          "generated input(s), each run twice with the same seed:",
                          *(v.describe(self.call or self.skill) for v in self.violations)])


class SkillContractError(CheckFailed):
    """A skill broke its declared contract; ``report`` holds what was found."""

    def __init__(self, report: ContractReport) -> None:
        super().__init__(report.describe())
        self.report = report


def check_skill(
    skill: Skill, *, world: World | None = None, values: Mapping[str, Any] | None = None,
    examples: int = 100, seed: int = 0,
) -> ContractReport:
    """Run ``skill`` on ``examples`` generated inputs, each twice with one seed, and raise
    :class:`SkillContractError` listing every kind of violation found (see the module's
    docstring) with the first input showing it; return the :class:`ContractReport`
    otherwise. ``world`` and ``values`` supply the blackboard's keys (see
    :func:`skill_blackboards`); ``seed`` makes the inputs the same on every call."""
    __tracebackhide__ = True
    if not isinstance(skill, Skill):
        raise TypeError(f"check_skill takes a skill made by @skill, got "
                        f"{type(skill).__name__}")
    if isinstance(examples, bool) or not isinstance(examples, int) or examples < 1:
        raise ValueError(f"examples = {examples!r}: expected a whole number of at least 1")
    params, contents = skill_params(skill), skill_blackboards(skill, world=world,
                                                               values=values)
    import hypothesis
    import hypothesis.strategies as st

    found: dict[tuple[str, str], Violation] = {}
    outcomes: Counter[str] = Counter()
    ran = 0

    @hypothesis.seed(seed)
    @hypothesis.settings(max_examples=examples, database=None, deadline=None,
                         phases=[hypothesis.Phase.generate], print_blob=False,
                         suppress_health_check=list(hypothesis.HealthCheck))
    @hypothesis.given(params=params, contents=contents, rng_seed=st.integers(0, _SEEDS))
    def one(params: dict[str, Any], contents: dict[str, Any], rng_seed: int) -> None:
        nonlocal ran
        ran += 1
        first, second = (_run(skill, params, contents, rng_seed) for _ in range(2))
        outcomes[str(first.outcome) if first.error is None else "error"] += 1
        for kind, what, message in _found(skill, first, second):
            old = found.get((kind, what))
            found[(kind, what)] = replace(old, count=old.count + 1) if old else \
                Violation(kind, what, message, params, contents, rng_seed)

    one()
    ordered = sorted(found.values(), key=lambda v: _ORDER.index(v.kind))
    report = ContractReport(skill.name, ran, dict(outcomes.most_common()), tuple(ordered),
                            getattr(skill.impl, "__name__", skill.name))
    if not report.ok:
        raise SkillContractError(report)
    return report
