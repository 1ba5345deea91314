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
import difflib
import math
import numbers
import re
import unicodedata
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, get_args, get_origin

from .errors import ParamError, Problem, clip

__all__ = [
    "MAX_WHOLE_BOUND", "Choice", "Param", "ParamKind", "ParamSpec", "Scale", "check_declared",
    "param_problems", "time_limit_problem",
]

ParamKind = Literal["float", "int", "bool", "choice"]
Scale = Literal["linear", "log"]

MAX_WHOLE_BOUND = 2**49
"""The largest magnitude of a whole-number parameter's bounds. Evolution holds a parameter
as a float in [0, 1]; within ±2**49 every whole number of the range maps to its gene and back
exactly (and FSA files hold whole numbers within 64 bits)."""
_INT64_MIN, _INT64_MAX = -(2**63), 2**63 - 1  # the whole numbers an FSA file holds


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
        if isinstance(value, numbers.Integral) and not isinstance(value, (bool, int)):
            value = int(value)  # numpy's whole numbers: Python's
        elif isinstance(value, numbers.Real) and not isinstance(value, (bool, int, float)):
            value = float(value)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParamError(bad + _number_hint(value))
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
            try:
                v = math.exp(math.log(self.low) + x * (math.log(self.high) - math.log(self.low)))
            except OverflowError:  # a last rounding beyond the largest float: the bound
                v = self.high
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
            close = difflib.get_close_matches(str(name), list(by_name), n=1)
            problems.append(Problem(
                f"skill {skill} has no parameter {name!r}; its parameters are "
                f"{list(by_name) or 'none'}", state, name,
                f"did you mean {close[0]!r}?" if close else None,
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
        for option in options:
            _check_option(option, where)
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
        whole = base_type is int or (base_type is None and isinstance(default, int))
        _check_bounds(decl.low, decl.high, decl.scale, where, whole and decl.size is None)
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


def check_declared(spec: ParamSpec, owner: str) -> None:
    """Raise :class:`ParamError` (naming skill ``owner``, the parameter and the limit) when
    ``spec`` declares values that evolution could write but an FSA file could not hold, or
    read back as a different value; a registry checks every skill it is given with this."""
    where = f"skill {owner}, parameter {spec.name!r}"
    if spec.kind == "choice":
        for option in spec.choices:
            _check_option(option, where)
    elif spec.kind in ("int", "float"):
        _check_bounds(spec.low, spec.high, spec.scale, where, spec.kind == "int")


def _check_bounds(low: Any, high: Any, scale: str, where: str, whole: bool) -> None:
    """Refuse a range that evolution cannot search or whose values an FSA file cannot hold:
    bounds that are not finite numbers in order, a span beyond the largest float, a log
    scale without a positive low bound, whole-number bounds beyond ±:data:`MAX_WHOLE_BOUND`."""
    for bound in (low, high):
        if isinstance(bound, bool) or not isinstance(bound, numbers.Real):
            raise ParamError(f"{where}: the bounds must be numbers, got low "
                             f"{clip(repr(low))}, high {clip(repr(high))}; declare "
                             "Param(low, high)")
    try:
        lo, hi = float(low), float(high)
    except OverflowError:  # a whole number beyond the largest float
        lo, hi = math.inf, math.inf
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ParamError(
            f"{where}: the bounds must be finite numbers (every value of the range must be "
            f"one that evolution can write and FSA files hold), got low {_num(low)}, high "
            f"{_num(high)}; declare a finite range"
        )
    if not low <= high:
        raise ParamError(f"{where}: low {_num(low)} is above high {_num(high)}")
    if whole and max(abs(low), abs(high)) > MAX_WHOLE_BOUND:
        raise ParamError(
            f"{where}: range [{_num(low)}, {_num(high)}] of a whole number goes beyond "
            f"±2**49 ({MAX_WHOLE_BOUND}), the largest whole numbers evolution maps to its "
            "genes and back exactly; keep both bounds within it"
        )
    if scale not in ("linear", "log"):
        raise ParamError(f"{where}: scale must be 'linear' or 'log', got {scale!r}")
    if scale == "log" and low <= 0:
        raise ParamError(f"{where}: scale='log' needs a positive low bound, got {_num(low)}")
    if scale == "linear" and not math.isfinite(hi - lo):
        raise ParamError(
            f"{where}: range [{_num(low)}, {_num(high)}] spans more than the largest float "
            f"({2**1024 - 2**971:.4g}), so evolution cannot map it to [0, 1]; narrow it, or "
            "use scale='log' for a positive range"
        )


def _num(value: Any) -> str:
    """A bound in a message: short even when it is a whole number of a thousand digits."""
    try:
        return f"{value:.6g}"
    except OverflowError:
        return f"a whole number of {len(str(abs(value)))} digits"


def _check_option(option: Any, where: str) -> None:
    """Refuse a choice's option that an FSA file cannot hold and give back as the same value:
    options are text (without control characters), whole numbers within 64 bits, numbers
    that are not NaN, true/false or None."""
    ok = option is None or isinstance(option, bool)
    if type(option) is int:
        ok = _INT64_MIN <= option <= _INT64_MAX
    elif type(option) is float:
        ok = not math.isnan(option)
    elif type(option) is str:
        ok = not any(unicodedata.category(c) in ("Cc", "Cs") for c in option)
    if not ok:
        raise ParamError(
            f"{where}: option {clip(repr(option), 60)} cannot be written to an FSA file and "
            "read back as itself; options are text without control characters, whole "
            "numbers within 64 bits, numbers other than NaN, true/false or None"
        )


_MISSING: Any = object()  # the default of a parameter declared without one (None is a value)


def _number_hint(value: Any) -> str:
    """What to change when text stands where a number goes: the forms people write."""
    if not isinstance(value, str):
        return " (a number)"
    text = value.strip()
    for sign in ("\u2212", "\u2013"):  # minus sign, en dash
        if text.startswith(sign):
            return (f" (a number): replace the sign {sign} (U+{ord(sign):04X}) with the ASCII "
                    "minus -")
    head = re.match(r"[-+]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][-+]?[0-9]+)?", text)
    if head is None:
        return " (a number)"
    rest = text[head.end():]
    if not rest:
        return " (a number, not text): remove the quotes"
    if rest.startswith("#"):
        return " (a number): put a space before # to start a comment"
    if re.fullmatch(r",[0-9]+", rest) and "." not in head.group(0):
        return f" (a number): write the decimal point as a point: {head.group(0)}.{rest[1:]}"
    if re.match(r"\s*[^\W\d_]|\s*[%\u00b0]", rest):  # a unit: letters, % or a degree sign
        return (f" (a number): write {head.group(0)} alone, without "
                f"{clip(repr(rest.strip()), 30)} (the unit is the skill's)")
    return " (a number)"
