"""Skill parameters: their kind, range, unit, default and the search scale evolution uses.

A skill declares its parameters as keyword-only arguments::

    def move(bb, rng, *,
             approach: Annotated[float, Param(0.05, 0.30, unit="m")] = 0.1,
             arm: Literal["left", "right"] = "left",
             tries: Annotated[int, Param(1, 5)] = 2,
             careful: bool = False,
             weights: Annotated[tuple[float, ...], Param(-3, 3, size=38)] = (0.0,) * 38,
             ) -> Literal["success", "failure"]: ...

Every parameter maps to and from the unit interval [0, 1] so that evolution can hold a genome
of normalised numbers while files and users see values in the skill's own units. A vector
parameter (``size=n``, e.g. a network's weights) is ``n`` such numbers, each with the same
range: ``n`` genes of the genome, one list in a file.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, get_args, get_origin

from .errors import ParamError, Problem, clip

__all__ = [
    "Choice", "Param", "ParamKind", "ParamSpec", "Scale", "param_problems", "time_limit_problem",
]

ParamKind = Literal["float", "int", "bool", "choice"]
Scale = Literal["linear", "log"]


@dataclass(frozen=True)
class Param:
    """Declaration of a numeric parameter's range, used inside ``Annotated[...]``.

    ``low``/``high`` are inclusive bounds in the parameter's ``unit``. ``scale="log"`` makes
    evolution search the range geometrically (both bounds must then be positive). ``size=n``
    declares a vector of ``n`` floats, each in the range (the parameter is then a
    ``tuple[float, ...]`` of that length).
    """

    low: float
    high: float
    unit: str = ""
    scale: Scale = "linear"
    doc: str = ""
    size: int | None = None


@dataclass(frozen=True)
class Choice:
    """Declaration of a categorical parameter: one of ``options`` (strings, numbers)."""

    options: tuple[Any, ...]
    doc: str = ""

    def __init__(self, *options: Any, doc: str = "") -> None:
        if len(options) == 1 and isinstance(options[0], (list, tuple)):
            options = tuple(options[0])
        object.__setattr__(self, "options", tuple(options))
        object.__setattr__(self, "doc", doc)


@dataclass(frozen=True)
class ParamSpec:
    """A fully resolved parameter of a skill."""

    name: str
    kind: ParamKind
    default: Any
    low: float | None = None
    high: float | None = None
    unit: str = ""
    scale: Scale = "linear"
    choices: tuple[Any, ...] = field(default=())
    doc: str = ""
    size: int | None = None
    """``n`` for a vector of ``n`` floats (each in [low, high]); None for a single value."""

    @property
    def genes(self) -> int:
        """How many numbers in [0, 1] this parameter takes in a genome."""
        return 1 if self.size is None else self.size

    # -- checking -------------------------------------------------------------------------
    def describe_range(self) -> str:
        if self.kind == "choice":
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.kind == "bool":
            return "true or false"
        unit = f" {self.unit}" if self.unit else ""
        if self.size is not None:
            return f"{self.size} floats, each in [{self.low:g}, {self.high:g}]{unit}"
        return f"{self.kind} in [{self.low:g}, {self.high:g}]{unit}"

    def check(self, value: Any, where: str = "") -> Any:
        """Return ``value`` as this parameter's Python type, or raise :class:`ParamError`."""
        prefix = f"{where}: " if where else ""
        if self.size is not None:
            return self._check_vector(value, prefix)
        bad = (
            f"{prefix}parameter {self.name!r} = {value!r} is not valid; "
            f"expected {self.describe_range()}"
        )
        if self.kind == "bool":
            if isinstance(value, bool):
                return value
            raise ParamError(bad + "; write true or false")
        if self.kind == "choice":
            for c in self.choices:
                if value == c and type(value) is type(c):
                    return c
            raise ParamError(bad)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParamError(bad + " (a number)")
        if self.kind == "int" and isinstance(value, float):
            if not value.is_integer():
                raise ParamError(bad + " (a whole number)")
            value = int(value)
        elif self.kind == "float":
            value = float(value)
            if math.isnan(value):
                raise ParamError(bad + " (not NaN)")
        assert self.low is not None and self.high is not None
        if not (self.low <= value <= self.high):
            raise ParamError(
                bad + f"; set it between {self.low:g} and {self.high:g}"
                " or widen the skill's declared range"
            )
        return value

    def _check_vector(self, value: Any, prefix: str) -> tuple[float, ...]:
        n = self.size
        assert n is not None and self.low is not None and self.high is not None
        head = f"{prefix}parameter {self.name!r} is not valid; expected {self.describe_range()}"
        if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
            raise ParamError(
                f"{head}, got {clip(repr(value), 60)}; write a list such as [0.1, -0.5, ...]"
            )
        if len(value) != n:
            raise ParamError(
                f"{head}, got a list of {len(value)}; give exactly {n} numbers (the skill "
                "declares the length)"
            )
        out: list[float] = []
        for i, v in enumerate(value):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or \
                    not math.isfinite(float(v)):
                raise ParamError(f"{head}; item {i} = {clip(repr(v), 60)} is not a finite number")
            if not self.low <= v <= self.high:
                raise ParamError(
                    f"{head}; item {i} = {v!r} is outside; set it between {self.low:g} and "
                    f"{self.high:g} or widen the skill's declared range"
                )
            out.append(float(v))
        return tuple(out)

    # -- genes: what evolution holds -------------------------------------------------------
    def from_genes(self, xs: Sequence[float]) -> Any:
        """The value that ``self.genes`` numbers in [0, 1] encode (a tuple for a vector)."""
        if self.size is None:
            return self.from_unit(xs[0])
        return tuple(self._scalar_from_unit(x) for x in xs)

    def to_genes(self, value: Any) -> list[float]:
        """Inverse of :meth:`from_genes`: ``self.genes`` numbers in [0, 1]."""
        if self.size is None:
            return [self.to_unit(value)]
        return [self._scalar_to_unit(v) for v in value]

    # -- the unit interval used by evolution ----------------------------------------------
    def from_unit(self, x: float) -> Any:
        """Map ``x`` in [0, 1] (clipped) to a value of this parameter."""
        x = 0.0 if x < 0.0 else 1.0 if x > 1.0 else float(x)
        if self.kind == "bool":
            return x >= 0.5
        if self.kind == "choice":
            n = len(self.choices)
            return self.choices[min(int(x * n), n - 1)]
        if self.size is not None:
            raise ParamError(f"parameter {self.name!r} is a vector; use from_genes")
        v = self._scalar_from_unit(x)
        if self.kind == "int":
            assert self.low is not None and self.high is not None
            return int(min(max(round(v), math.ceil(self.low)), math.floor(self.high)))
        return v

    def _scalar_from_unit(self, x: float) -> float:
        assert self.low is not None and self.high is not None
        x = 0.0 if x < 0.0 else 1.0 if x > 1.0 else float(x)
        if self.scale == "log":
            v = math.exp(math.log(self.low) + x * (math.log(self.high) - math.log(self.low)))
        else:
            v = self.low + x * (self.high - self.low)
        return min(max(v, self.low), self.high)

    def to_unit(self, value: Any) -> float:
        """Map a value of this parameter to [0, 1] (inverse of :meth:`from_unit`)."""
        if self.kind == "bool":
            return 0.75 if value else 0.25
        if self.kind == "choice":
            return (self.choices.index(value) + 0.5) / len(self.choices)
        if self.size is not None:
            raise ParamError(f"parameter {self.name!r} is a vector; use to_genes")
        return self._scalar_to_unit(value)

    def _scalar_to_unit(self, value: Any) -> float:
        assert self.low is not None and self.high is not None
        if self.high == self.low:
            return 0.5
        if self.scale == "log":
            u = (math.log(value) - math.log(self.low)) / (math.log(self.high) - math.log(self.low))
        else:
            u = (float(value) - self.low) / (self.high - self.low)
        return min(max(u, 0.0), 1.0)


def param_problems(
    skill: str, specs: Sequence[ParamSpec], given: Mapping[str, Any], state: str | None = None
) -> tuple[dict[str, Any], list[Problem]]:
    """The one check of a state's parameters, for the model, the file reader and the genome.

    Returns the values (the defaults overlaid with each valid value of ``given``, as its
    parameter's type) and a :class:`~skillcompose.errors.Problem` (``key``: the parameter)
    per unknown name or bad value; callers add where it is (a file's line, a state).
    """
    values = {p.name: p.default for p in specs}
    by_name = {p.name: p for p in specs}
    problems: list[Problem] = []
    for name, value in given.items():
        spec = by_name.get(name)
        if spec is None:
            problems.append(Problem(
                f"skill {skill} has no parameter {name!r}; its parameters are "
                f"{list(by_name) or 'none'}", state, name,
            ))
            continue
        try:
            values[name] = spec.check(value)
        except ParamError as exc:
            problems.append(Problem(f"skill {skill}: {exc}", state, name))
    return values, problems


def time_limit_problem(
    value: Any, state: str | None = None, what: str = "time_limit",
    fix: str = "for example `time_limit: 2.0`",
) -> Problem | None:
    """The one check of a state's wall-clock limit [s] (a positive finite number): None when
    ``value`` passes, else the problem, ``what`` naming the limit as the caller knows it."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value) or value <= 0:
        return Problem(f"{what} must be a positive number of seconds, got {value!r}", state,
                       "time_limit", fix)
    return None


def make_param_spec(
    name: str, base_type: Any, decl: Param | Choice | None, default: Any, owner: str
) -> ParamSpec:
    """Build a :class:`ParamSpec` from a signature entry; raise ``ParamError`` if unusable."""
    where = f"skill {owner}, parameter {name!r}"
    if isinstance(decl, Choice) or get_origin(base_type) is Literal:
        options: Sequence[Any] = decl.options if isinstance(decl, Choice) else get_args(base_type)
        if not options:
            raise ParamError(f"{where}: a choice needs at least one option")
        spec = ParamSpec(
            name, "choice", default, choices=tuple(options),
            doc=decl.doc if isinstance(decl, Choice) else "",
        )
    elif base_type is bool or (decl is None and isinstance(default, bool)):
        spec = ParamSpec(name, "bool", default)
    elif isinstance(decl, Param):
        if decl.size is not None:  # a vector of floats
            if isinstance(decl.size, bool) or not isinstance(decl.size, int) or decl.size < 1:
                raise ParamError(f"{where}: size must be a whole number >= 1, got {decl.size!r}")
            if base_type not in (None, tuple, list) and \
                    get_origin(base_type) not in (tuple, list):
                raise ParamError(
                    f"{where}: a vector parameter (size={decl.size}) is annotated "
                    f"`Annotated[tuple[float, ...], Param(low, high, size={decl.size})]`, "
                    f"got {base_type!r}"
                )
        if not decl.low <= decl.high:
            raise ParamError(f"{where}: low {decl.low} is above high {decl.high}")
        if decl.scale == "log" and decl.low <= 0:
            raise ParamError(f"{where}: scale='log' needs a positive low bound, got {decl.low}")
        if decl.scale not in ("linear", "log"):
            raise ParamError(f"{where}: scale must be 'linear' or 'log', got {decl.scale!r}")
        whole = base_type is int or (base_type is None and isinstance(default, int))
        spec = ParamSpec(
            name, "int" if whole and decl.size is None else "float", default,
            low=float(decl.low), high=float(decl.high), unit=decl.unit, scale=decl.scale,
            doc=decl.doc, size=decl.size,
        )
    else:
        raise ParamError(
            f"{where}: has no range; declare it as "
            f"`{name}: Annotated[float, Param(low, high, unit=...)] = default`, "
            "a Literal[...] / Choice(...) of options, or a bool"
        )
    if default is _MISSING:
        raise ParamError(f"{where}: needs a default value (evolution and files may omit it)")
    return dataclasses.replace(spec, default=spec.check(default, f"skill {owner}"))


_MISSING: Any = object()  # the default of a parameter declared without one (None is a value)
