"""The FSA model: frozen dataclasses for states and automata, with validation.

An FSA is the paper's quadruple (actions, outcomes, transition on outcome, start state): each
:class:`State` runs one skill with fixed parameters, and maps each outcome of that skill to the
next state or to a *terminal outcome* that ends the run (``success`` / ``failure`` by
default). A run that takes more than ``step_limit`` transitions ends with ``timeout``.

Structure is checked when an :class:`FSA` is built (the start exists, every target exists);
what depends on the skills (every outcome routed, parameters in range) is checked against a
:class:`~skillcompose.lookup.SkillLookup` (a registry) by :meth:`FSA.check` /
:meth:`FSA.validate`, which compiling and loading do for you.
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Final

from .errors import FSAValidationError, Problem, UnknownSkillError, clip, control_characters
from .params import param_problems, time_limit_problem

if TYPE_CHECKING:
    from .lookup import SkillLookup

__all__ = [
    "DEFAULT_STEP_LIMIT",
    "DEFAULT_TERMINALS",
    "ERROR",
    "FSA",
    "MAX_STEP_LIMIT",
    "PREEMPTED",
    "RESERVED_OUTCOMES",
    "TIMEOUT",
    "Source",
    "State",
]

TIMEOUT: Final = "timeout"
ERROR: Final = "error"
PREEMPTED = "preempted"
RESERVED_OUTCOMES = (TIMEOUT, ERROR, PREEMPTED)
DEFAULT_TERMINALS = ("success", "failure")
DEFAULT_STEP_LIMIT = 100
MAX_STEP_LIMIT = 1_000_000
"""The largest step limit: a run of an FSA that loops ends (``timeout``) within seconds."""


@dataclass(frozen=True)
class State:
    """One state: a skill, its parameters (in the skill's units) and its transitions.

    ``time_limit`` [s], when set, bounds the state's wall-clock time (for hardware skills that
    can hang): a state that overruns ends with ``timeout`` (see :mod:`skillcompose.executor`).
    """

    skill: str
    params: Mapping[str, Any] = field(default_factory=dict)
    transitions: Mapping[str, str] = field(default_factory=dict)
    time_limit: float | None = None


@dataclass(frozen=True)
class Source:
    """Where an FSA came from, in plain data: the file's path and the positions of its keys,
    so that errors point at lines. A file format's reader may hand a subclass that also
    keeps what its writer needs (:class:`skillcompose.fsafile.FileOrigin`)."""

    path: str | None
    positions: Mapping[tuple[str, ...], tuple[int, int]] = field(default_factory=dict)

    def where(self, *keys: str) -> tuple[int | None, int | None]:
        """1-based (line, column) of the deepest known key on the path ``keys``."""
        for n in range(len(keys), -1, -1):
            pos = self.positions.get(tuple(keys[:n]))
            if pos is not None:
                return pos
        return None, None

    def at(self, *keys: str) -> str:
        """``:line:column`` of the key path ``keys`` (as :meth:`where`), to follow a file's
        name in a message; empty when unknown."""
        line, col = self.where(*keys)
        return "" if line is None else f":{line}" if col is None else f":{line}:{col}"

    def renamed(self, old: str, new: str) -> Source:
        """This source once state ``old`` is called ``new`` (a writer's handle notes it)."""
        return self


@dataclass(frozen=True)
class FSA:
    """A finite state automaton over named skills."""

    states: Mapping[str, State]
    start: str
    terminals: tuple[str, ...] = DEFAULT_TERMINALS
    step_limit: int = DEFAULT_STEP_LIMIT
    name: str = ""
    meta: Mapping[str, Any] = field(default_factory=dict)
    source: Source | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "terminals", tuple(self.terminals))
        problems = self.structure_problems()
        if problems:
            raise FSAValidationError(problems, self.path)

    @classmethod
    def trusted(
        cls, states: Mapping[str, State], start: str, terminals: tuple[str, ...],
        step_limit: int, name: str = "",
    ) -> FSA:
        """An FSA built without the structural checks, for code that builds valid FSAs by
        construction many times a second (evolution's compiler). Users build FSAs normally."""
        fsa = object.__new__(cls)
        fsa.__dict__.update(states=states, start=start, terminals=terminals,
                            step_limit=step_limit, name=name, meta={}, source=None)
        return fsa

    # -- identity ----------------------------------------------------------------------------
    @property
    def path(self) -> str | None:
        return self.source.path if self.source is not None else None

    def _problem(
        self, message: str, state: str | None = None, key: str | None = None,
        fix: str | None = None, at: tuple[str, ...] = (),
    ) -> Problem:
        return self._at(Problem(message, state=state, key=key, fix=fix), *at)

    def _at(self, problem: Problem, *keys: str) -> Problem:
        """``problem`` placed at the file position of the key path ``keys``, if known."""
        if self.source is None:
            return problem
        line, col = self.source.where(*keys)
        return dataclasses.replace(problem, line=line, column=col)

    # -- validation ------------------------------------------------------------------------
    def structure_problems(self) -> list[Problem]:
        """Problems visible without knowing the skills."""
        out: list[Problem] = []
        if isinstance(self.name, str) and control_characters(self.name):
            out.append(self._problem(
                _control_message(f"name {self.name!r}", self.name),
                fix="write the name without it", at=("name",),
            ))
        problem = step_limit_problem(self.step_limit)
        if problem is not None:
            out.append(self._at(problem, "step_limit"))
        if not self.terminals:
            out.append(self._problem(
                "no terminal outcomes", fix="set `terminals: [success, failure]`",
                at=("terminals",),
            ))
        for k, t in enumerate(self.terminals):
            if t in self.terminals[:k]:
                out.append(self._problem(
                    f"terminal outcome {t!r} is listed twice", fix="keep one",
                    at=("terminals",),
                ))
            elif not isinstance(t, str) or not t.isidentifier():
                out.append(self._problem(
                    f"terminal outcome {t!r} must be an identifier", at=("terminals",)
                ))
            elif t in RESERVED_OUTCOMES:
                out.append(self._problem(
                    f"terminal outcome {t!r} is reserved for the executor "
                    f"({', '.join(RESERVED_OUTCOMES)})", at=("terminals",),
                ))
        if not self.states:
            out.append(self._problem(
                "the FSA has no states", fix="add at least one state under `states:`",
                at=("states",),
            ))
        if self.start not in self.states:
            out.append(self._problem(
                f"start state {self.start!r} does not exist",
                fix=f"set `start:` to one of {list(self.states)[:8]}", at=("start",),
            ))
        for sname, st in self.states.items():
            if not isinstance(sname, str) or not sname or any(c.isspace() for c in sname):
                out.append(self._problem(
                    f"state name {sname!r} must be a non-empty string without spaces",
                    state=str(sname), at=("states", str(sname)),
                ))
                continue
            if control_characters(sname):
                out.append(self._problem(
                    _control_message(f"state name {sname!r}", sname), state=sname,
                    fix="rename the state without it", at=("states", sname),
                ))
                continue
            if sname in self.terminals or sname in RESERVED_OUTCOMES:
                out.append(self._problem(
                    f"a state cannot be named {sname!r}: that is a terminal outcome",
                    state=sname, fix="rename the state", at=("states", sname),
                ))
            problem = None if st.time_limit is None else time_limit_problem(st.time_limit, sname)
            if problem is not None:
                out.append(self._at(problem, "states", sname, "time_limit"))
            for what, text, at in (
                ("skill name", st.skill, ("skill",)),
                *(("parameter name", k, ("params", k)) for k in st.params),
                *(("outcome", k, ("transitions", k)) for k in st.transitions),
            ):
                if isinstance(text, str) and control_characters(text):
                    out.append(self._problem(
                        _control_message(f"{what} {text!r}", text), state=sname, key=text,
                        fix=f"write the {what} without it", at=("states", sname, *at),
                    ))
            for outcome, target in st.transitions.items():
                if target not in self.states and target not in self.terminals:
                    out.append(self._problem(
                        f"outcome {outcome!r} goes to {target!r}, which is neither a state "
                        f"nor a terminal outcome {list(self.terminals)}",
                        state=sname, key=outcome,
                        fix=_fix_target(target, list(self.states), self.terminals),
                        at=("states", sname, "transitions", outcome),
                    ))
        return out

    def check(self, registry: SkillLookup) -> list[Problem]:
        """Problems of this FSA against the skills of ``registry`` (empty when valid)."""
        out: list[Problem] = []
        for sname, st in self.states.items():
            base = ("states", sname)
            try:
                spec = registry.spec(st.skill)
            except UnknownSkillError as exc:
                out.append(self._problem(
                    str(exc), state=sname, key="skill", at=(*base, "skill"),
                ))
                continue
            for outcome in spec.outcomes:
                if outcome not in st.transitions:
                    out.append(self._problem(
                        f"outcome {outcome!r} of skill {spec.name} has no transition",
                        state=sname, key=outcome,
                        fix=f"add `{outcome}: <state or {'/'.join(self.terminals)}>` "
                        f"under {sname}.transitions",
                        at=(*base, "transitions"),
                    ))
            for outcome in st.transitions:
                if outcome not in spec.outcomes:
                    out.append(self._problem(
                        f"{outcome!r} is not an outcome of skill {spec.name} "
                        f"(its outcomes are {list(spec.outcomes)})",
                        state=sname, key=outcome,
                        fix=f"remove it or rename it to one of {list(spec.outcomes)}",
                        at=(*base, "transitions", outcome),
                    ))
            _, problems = param_problems(spec.name, spec.params, st.params, sname)
            out.extend(self._at(p, *base, "params", p.key or "") for p in problems)
        return out

    def validate(self, registry: SkillLookup) -> FSA:
        """Raise :class:`FSAValidationError` listing every problem; return ``self`` if none."""
        problems = self.check(registry)
        if problems:
            raise FSAValidationError(problems, self.path)
        return self

    # -- graph queries ---------------------------------------------------------------------
    def successors(self, state: str) -> list[str]:
        return [t for t in self.states[state].transitions.values() if t in self.states]

    def reachable(self) -> list[str]:
        """States reachable from the start, in breadth-first order."""
        order = [self.start]
        seen = set(order)
        for s in order:  # the list grows as it is read: a breadth-first queue
            for t in self.successors(s):
                if t not in seen:
                    seen.add(t)
                    order.append(t)
        return order

    def unreachable(self) -> list[str]:
        reach = set(self.reachable())
        return [s for s in self.states if s not in reach]

    def _repr_svg_(self) -> str:
        """In a notebook: the FSA's drawing (see :func:`skillcompose.draw.to_svg`)."""
        from .draw import to_svg

        return to_svg(self)

    def trap_states(self) -> list[str]:
        """States reachable from the start from which no terminal outcome can be reached: a
        run that enters one ends in timeout (breadth-first order)."""
        predecessors: dict[str, list[str]] = {s: [] for s in self.states}
        ending = []
        for name, st in self.states.items():
            for target in st.transitions.values():
                if target in self.states:
                    predecessors[target].append(name)
                elif target in self.terminals:
                    ending.append(name)
        can_end = set(ending)
        for s in ending:  # grows as it is read, as in reachable()
            for p in predecessors[s]:
                if p not in can_end:
                    can_end.add(p)
                    ending.append(p)
        return [s for s in self.reachable() if s not in can_end]

    def pruned(self) -> FSA:
        """This FSA without the states the start cannot reach."""
        reach = set(self.reachable())
        return self.replace(states={k: v for k, v in self.states.items() if k in reach})

    def skills_used(self) -> list[str]:
        return sorted({st.skill for st in self.states.values()})

    # -- editing (each returns a new FSA; a file's comments survive a later save) ---------------
    def replace(self, **changes: Any) -> FSA:
        return dataclasses.replace(self, **changes)

    def with_params(self, state: str, **params: Any) -> FSA:
        st = self._state(state)
        return self.with_state(state, dataclasses.replace(st, params={**st.params, **params}))

    def route(self, state: str, outcome: str, target: str) -> FSA:
        st = self._state(state)
        tr = {**st.transitions, outcome: target}
        return self.with_state(state, dataclasses.replace(st, transitions=tr))

    def with_state(self, name: str, state: State) -> FSA:
        return self.replace(states={**self.states, name: state})

    def without_state(self, name: str) -> FSA:
        self._state(name)
        return self.replace(states={k: v for k, v in self.states.items() if k != name})

    def rename_state(self, old: str, new: str) -> FSA:
        """Rename a state and every transition (and the start) that points at it."""
        self._state(old)
        if new in self.states:
            raise FSAValidationError([Problem(f"state {new!r} exists already", state=old)])
        states: dict[str, State] = {}
        for k, st in self.states.items():
            tr = {o: (new if t == old else t) for o, t in st.transitions.items()}
            states[new if k == old else k] = dataclasses.replace(st, transitions=tr)
        return self.replace(
            states=states, start=new if self.start == old else self.start,
            source=self.source and self.source.renamed(old, new),
        )

    def _state(self, name: str) -> State:
        try:
            return self.states[name]
        except KeyError:
            raise FSAValidationError([Problem(
                f"no state named {name!r}; states are {list(self.states)}"
            )]) from None

    # -- construction helpers --------------------------------------------------------------
    @classmethod
    def chain(
        cls, skills: Iterable[str], *, registry: SkillLookup | None = None,
        on_other: str = "failure", step_limit: int = DEFAULT_STEP_LIMIT,
        name: str = "",
    ) -> FSA:
        """A straight line of states: each ``success`` goes to the next, the last ends in
        ``success``; every other outcome (known from ``registry``) ends in ``on_other``."""
        names = list(skills)
        labels = [f"{s}_{i + 1}" for i, s in enumerate(names)]
        states: dict[str, State] = {}
        for s, label, nxt in zip(names, labels, [*labels[1:], "success"], strict=False):
            outs = registry.spec(s).outcomes if registry is not None else ("success",)
            states[label] = State(s, {}, {o: (nxt if o == "success" else on_other) for o in outs})
        return cls(states, labels[0], step_limit=step_limit, name=name)


def _control_message(what: str, text: str) -> str:
    """``what`` (a name, quoted) holds characters a terminal acts on instead of showing."""
    chars = ", ".join(dict.fromkeys(f"U+{ord(c):04X}" for c in control_characters(text)))
    return (f"{what} holds a control character ({chars}), which would act on a terminal or "
            "a drawing instead of showing")


def step_limit_problem(value: Any) -> Problem | None:
    """None when ``value`` is a valid step limit (a whole number in [1, MAX_STEP_LIMIT])."""
    if isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= MAX_STEP_LIMIT:
        return None
    return Problem(f"step_limit must be a positive whole number, got {clip(repr(value), 60)} "
                   f"(at most {MAX_STEP_LIMIT})", key="step_limit",
                   fix="for example `step_limit: 20`")


def _fix_target(target: str, states: list[str], terminals: tuple[str, ...]) -> str:
    close = difflib.get_close_matches(str(target), states + list(terminals), n=1)
    return f"did you mean {close[0]!r}?" if close else \
        f"use a state name or one of {list(terminals)}"
