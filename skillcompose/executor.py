"""The engine: compile an FSA once against a registry and a backend, then run it many times.

:func:`compile_fsa` validates an :class:`~skillcompose.fsa.FSA` against a registry and builds
a :class:`CompiledFSA`, the one program representation (its public constructor takes the FSA
and, per state, the implementation and its parameters; evolution's genome compiler uses it).
:class:`FSARun` is the one interpreter: :meth:`FSARun.tick` advances the current state's skill
by one tick and, when it finishes, takes the transition; :meth:`FSARun.run`,
:meth:`CompiledFSA.run` and :meth:`CompiledFSA.outcome` are the same loop going on to the
run's end, with or without a trace. One skill completion is one step toward ``step_limit``; a
run ends with a terminal outcome, ``timeout`` after ``step_limit`` steps, ``error`` when a
skill raises, or ``preempted``.

Wall-clock limits per state (``time_limit`` in the file, or ``time_limits={"Grasp": 2.0}`` in
seconds) end a state that runs too long with ``timeout``: the state's ``timeout`` transition
when its skill declares that outcome, else the run's end. A long-running skill's limit is
checked before each tick; an instant skill under a limit runs in a worker thread
(:class:`~skillcompose.activation.ThreadActivation`).
"""
from __future__ import annotations

import contextlib
import functools
import os
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from .activation import RUNNING, Activation, Starter, ThreadActivation
from .blackboard import Access, Blackboard, _same
from .errors import (
    ParamError,
    SkillProtocolError,
    UndeclaredOutcomeError,
    clip,
    exception_text,
    one_line,
)
from .fsa import ERROR, FSA, PREEMPTED, TIMEOUT
from .params import time_limit_problem

if TYPE_CHECKING:
    from .lookup import SkillLookup
    from .skill import Skill

__all__ = [
    "CompiledFSA",
    "FSARun",
    "RunResult",
    "TraceStep",
    "compile_fsa",
    "error_summary",
    "run_fsa",
    "run_ticking",
    "trial_seeds",
]


class TraceStep(NamedTuple):
    """One step of a run: which state ran, what it returned, what it changed."""

    step: int
    state: str
    skill: str
    outcome: str
    target: str  # the next state, or the terminal outcome that ended the run
    changes: Mapping[str, tuple[Any, Any]]  # key -> (old, new); see blackboard.DELETED; read-only


_NO_CHANGES: dict[str, tuple[Any, Any]] = {}
"""The changes of every traced step that wrote nothing (one shared mapping: read it only)."""
_new = tuple.__new__  # a TraceStep or RunResult without the keyword machinery (hot path)


class RunResult(NamedTuple):
    """How one run ended."""

    outcome: str
    steps: int
    last_state: str | None
    trace: tuple[TraceStep, ...] | None = None
    error: BaseException | None = None

    @property
    def ok(self) -> bool:
        return self.error is None

    def format_error(self) -> str:
        if self.error is None:
            return ""
        return "".join(traceback.format_exception(self.error))

    def _repr_html_(self) -> str:
        """In a notebook: how the run ended and its trace as a table."""
        from .display import run_result_html

        return run_result_html(self)


def error_summary(exc: BaseException, frames: int = 3) -> str:
    """``Type: message`` and, below it, the innermost ``frames`` frames of its traceback;
    each line escaped (:func:`~skillcompose.errors.one_line`): a message's line breaks and
    control characters never reach the terminal as they are."""
    head = one_line(exception_text(exc))
    stack = traceback.extract_tb(exc.__traceback__)[-frames:]
    body = "\n".join(one_line(line) for line in
                     "".join(traceback.format_list(stack)).rstrip().split("\n"))
    return f"{head}\n{body}" if body else head


# per state: (instant call, starter or None, access, outcome -> next, time limit [s] or None).
# A next state is its index; a run's end is coded -(k + 1) for the k-th of `ends`.
_Entry = tuple[Callable[..., Any], "Starter | None", Access, dict[str, int], "float | None"]


class CompiledFSA:
    """An FSA bound to skill implementations: cheap to run, safe to reuse across runs.

    ``impls[k]`` is the ``k``-th state's (implementation, parameters in the skill's units),
    states in the FSA's order; :func:`compile_fsa` resolves them from a registry and checks
    them. One compiled FSA may run on many blackboards one after another; it holds no per-run
    state. ``time_limits`` [s] add to (and override) the states' own ``time_limit``.
    """

    __slots__ = (
        "_ends", "_limited", "_start", "_table", "backend", "fsa", "impls", "key_types", "names",
        "skills", "step_limit", "terminals", "time_limits",
    )

    def __init__(
        self,
        fsa: FSA,
        impls: Sequence[tuple[Skill, Mapping[str, Any]]],
        backend: str,
        *,
        time_limits: Mapping[str, float] | None = None,
    ) -> None:
        names = list(fsa.states)
        if len(impls) != len(names):
            raise ValueError(
                f"CompiledFSA: {len(impls)} implementations for {len(names)} states; give "
                "one (skill, params) per state, in the FSA's order"
            )
        self.fsa = fsa
        self.impls = [(impl, dict(params)) for impl, params in impls]
        self.names = names
        self.skills = [fsa.states[n].skill for n in names]
        self._start = names.index(fsa.start)
        self.step_limit = fsa.step_limit
        self.terminals = fsa.terminals
        self._ends = (*fsa.terminals, TIMEOUT)  # the last: a time limit with no transition
        self.backend = backend
        limits = {n: st.time_limit for n, st in fsa.states.items() if st.time_limit is not None}
        limits.update(_check_limits(fsa, names, time_limits or {}))
        self.time_limits = limits
        self._limited: dict[frozenset[tuple[str, float]], CompiledFSA] = {}
        index = {n: k for k, n in enumerate(names)}
        code = {t: -(k + 1) for k, t in enumerate(self._ends)}
        self.key_types: dict[str, Any] = {}
        self._table: list[_Entry] = []
        for name, (impl, params) in zip(names, self.impls, strict=True):
            spec = impl.spec
            access = spec.access()
            limit = limits.get(name)
            start = impl.starter(backend)
            if start is None:
                call: Callable[..., Any] = impl.bind(None, backend)
                if params:
                    call = functools.partial(call, **params)
                if limit is not None:
                    start = functools.partial(
                        ThreadActivation, call, access=access, hook=impl.cancel_hook(backend)
                    )
            else:
                if params:
                    start = functools.partial(start, **params)
                call = start
            nxt = {
                o: index[t] if t in index else code[t]
                for o, t in fsa.states[name].transitions.items()
            }
            self._table.append((call, start, access, nxt, limit))
            for k, t in spec.key_types.items():
                self.key_types.setdefault(k, t)

    # -- running ---------------------------------------------------------------------------
    def run(
        self,
        bb: Blackboard | None = None,
        rng: np.random.Generator | int | None = None,
        *,
        trace: bool = False,
        propagate: bool = False,
    ) -> RunResult:
        """Run once. ``rng`` is a Generator or a seed; ``propagate`` re-raises skill errors."""
        run = FSARun(self, bb, rng, trace=trace, propagate=propagate)
        run.tick(True)
        return run._result  # type: ignore[return-value]  # set: the run has ended

    def outcome(self, bb: Blackboard, rng: np.random.Generator) -> tuple[str, int]:
        """(outcome, steps) of one run, raising on skill errors: the evaluation hot path."""
        run = FSARun(self, bb, rng, propagate=True)
        return run.tick(True), run.steps

    def start(
        self,
        bb: Blackboard | None = None,
        rng: np.random.Generator | int | None = None,
        *,
        trace: bool = False,
        propagate: bool = False,
        time_limits: Mapping[str, float] | None = None,
        clock: Callable[[], float] | None = None,
    ) -> FSARun:
        """Begin a tick-wise run: call ``.tick()`` on the result until it is not ``"running"``.

        ``time_limits`` maps state names to wall-clock limits [s], over the states' own
        ``time_limit``; see :class:`FSARun`.
        """
        return FSARun(
            self, bb, rng, trace=trace, propagate=propagate, time_limits=time_limits,
            clock=clock,
        )

    def with_limits(self, time_limits: Mapping[str, float]) -> CompiledFSA:
        """This program with more wall-clock limits [s] (built once per set of limits)."""
        if not time_limits:
            return self
        key = frozenset(time_limits.items())
        out = self._limited.get(key)
        if out is None:
            out = CompiledFSA(
                self.fsa, self.impls, self.backend, time_limits={**self.time_limits, **time_limits}
            )
            self._limited[key] = out
        return out

    def undeclared(self, i: int, out: object) -> UndeclaredOutcomeError:
        """The error for state ``i``'s skill returning ``out``, which it did not declare."""
        return UndeclaredOutcomeError(
            f"state {self.names[i]}: skill {self.skills[i]} returned {_shown(out)}, which is not "
            f"one of its declared outcomes {list(self.impls[i][0].spec.outcomes)}; return a "
            "declared outcome or add it to the skill's outcomes"
        )

    def __repr__(self) -> str:
        return (
            f"<CompiledFSA {self.fsa.name or ''} states={len(self.names)} "
            f"start={self.fsa.start} backend={self.backend}>"
        )


def _shown(value: object) -> str:
    """``repr(value)`` for a message: at most 80 characters, never raising."""
    try:
        text = repr(value)
    except Exception:  # a value whose repr fails is still named
        text = f"a {type(value).__name__}"
    return clip(text, 80)


def _check_limits(fsa: FSA, names: list[str], limits: Mapping[str, float]) -> dict[str, float]:
    out: dict[str, float] = {}
    for state, value in limits.items():
        if state not in names:
            raise ParamError(
                f"time_limits: FSA {fsa.name or ''} has no state {state!r}; "
                f"its states are {names}"
            )
        problem = time_limit_problem(value, state, "the limit", f"write e.g. {{{state!r}: 2.0}}")
        if problem is not None:
            raise ParamError(f"time_limits: {problem.render()}")
        out[state] = float(value)
    return out


class _Raised(NamedTuple):
    """What a running activation's tick raised, handed from the hot path to the loop."""

    exc: BaseException


_EXPIRED: Any = object()
"""What a state's activation gives when its time limit ran out."""


class FSARun:
    """One run of a compiled FSA on a blackboard: the engine.

    Build it with :meth:`CompiledFSA.start`::

        run = compiled.start(bb, seed)
        while run.tick() == "running":
            do_other_work()
        print(run.result.outcome)

    :meth:`tick` returns ``"running"`` until the run ends, then its outcome (also on every
    later call). :meth:`preempt` stops it: the running skill's cancel hook is called exactly
    once and the run ends with ``preempted``. ``time_limits`` maps state names to wall-clock
    limits [s] (module docstring); ``clock`` (default ``time.monotonic``) measures them.
    """

    __slots__ = (
        "_act", "_clock", "_events", "_handed", "_i", "_limit", "_numbers", "_pending",
        "_propagate", "_record", "_result", "_t0", "_table", "bb", "compiled", "rng", "steps",
        "ticks",
    )

    def __init__(
        self,
        compiled: CompiledFSA,
        bb: Blackboard | None = None,
        rng: np.random.Generator | int | None = None,
        *,
        trace: bool = False,
        propagate: bool = False,
        time_limits: Mapping[str, float] | None = None,
        clock: Callable[[], float] | None = None,
    ) -> None:
        if bb is None:
            bb = Blackboard()
        elif not isinstance(bb, Blackboard):
            raise TypeError(f"a run takes a Blackboard (or None), got {type(bb).__name__}; "
                            "wrap it: Blackboard({...})")
        if not isinstance(rng, np.random.Generator):
            rng = np.random.default_rng(rng)
        types = bb._types  # the program's typed keys, declared on the run's blackboard
        for k, t in compiled.key_types.items():
            if types.get(k) is not t:
                bb.declare(k, t)
        self.compiled = compiled
        self.bb = bb
        self.rng = rng
        self._table = compiled.with_limits(time_limits)._table if time_limits else \
            compiled._table
        self._clock = clock or time.monotonic
        self._propagate = propagate
        self._i = compiled._start
        self._act: Activation | None = None
        self._handed: Any = None  # an activation's outcome taken by tick's hot path
        self._t0 = 0.0
        self._result: RunResult | None = None
        self._events: list[TraceStep] | None = [] if trace else None
        self._record = self._events.append if self._events is not None else None
        self._limit = compiled.step_limit
        self._numbers = iter(range(1, compiled.step_limit + 1))  # the steps still to run
        self._pending: dict[str, tuple[Any, Any]] = {}
        self.steps = 0
        """Skill completions so far (the count ``step_limit`` bounds)."""
        self.ticks = 0
        """Ticks that advanced the run."""
        if trace:
            bb.start_log()

    # -- state -------------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        return self._result is not None

    @property
    def result(self) -> RunResult:
        """How the run ended; raises :class:`SkillProtocolError` while it is running."""
        if self._result is None:
            raise SkillProtocolError(
                f"the run of FSA {self.compiled.fsa.name or ''} is still running (state "
                f"{self.state}); tick() it until it returns an outcome, or preempt() it"
            )
        return self._result

    @property
    def state(self) -> str:
        """The current state (the last one once the run has ended)."""
        if self._result is not None and self._result.last_state is not None:
            return self._result.last_state
        return self.compiled.names[self._i]

    @property
    def trace(self) -> tuple[TraceStep, ...] | None:
        """The steps so far of a traced run (None when the run is not traced)."""
        return tuple(self._events) if self._events is not None else None

    @property
    def active(self) -> bool:
        """True while a long-running skill is between ticks (it would be cancelled)."""
        return self._act is not None

    # -- running -----------------------------------------------------------------------------

    def run(self, *, max_ticks: int | None = None, period: float = 0.0) -> RunResult:
        """Tick until the run ends (or preempt it after ``max_ticks``); sleep ``period`` [s]
        between ticks, which a run waiting on a worker thread or hardware should do."""
        if max_ticks is None and period <= 0 and self._result is None:
            self.tick(_to_the_end=True)
        while self._result is None:
            if max_ticks is not None and self.ticks >= max_ticks:
                return self.preempt()
            if self.tick() == RUNNING and period > 0:
                time.sleep(period)
        return self._result

    def tick(self, _to_the_end: bool = False) -> str:
        """Advance the current skill by one tick; :data:`RUNNING` or the run's outcome.

        This is the engine's interpreter. :meth:`run` passes ``_to_the_end``: the same loop
        goes on, tick after tick, until the run ends."""
        if self._result is not None:
            return self._result.outcome
        bb = self.bb
        out: Any
        act: Activation | None
        if self._act is not None and not _to_the_end and self._record is None:
            # The next tick of a running activation, untraced: the hot path of tick-wise
            # runs. While it keeps running this is the whole tick; its outcome (or what it
            # raised) is handed to the loop below, which takes the transition.
            act = self._act
            _, _, access, _, limit = self._table[self._i]
            if limit is None:
                bb._client = access
                try:
                    out = act.tick()
                except BaseException as exc:  # handed to the loop, which ends the run
                    out = _Raised(exc)
                finally:
                    bb._client = None
                if out == RUNNING:
                    self.ticks += 1
                    return RUNNING
                self._handed = out
        record = self._record
        if record is not None:
            bb.take_log()  # drop writes made between ticks by others (a tree, a bridge)
            c = self.compiled
            names, skills, ends, new, step, nothing = (
                c.names, c.skills, c._ends, _new, TraceStep, _NO_CHANGES
            )
        table = self._table
        rng = self.rng
        i = self._i
        done = self.steps  # (done < step_limit: the loop below runs at least once)
        n = -done  # + steps: the ticks of this call (n counts an activation's further ticks)
        steps = done + 1
        try:
            for steps in self._numbers:
                call, start, access, nxt, limit = table[i]
                bb._client = access
                if start is None:
                    out = call(bb, rng)
                else:  # a long-running skill: start its activation, tick it
                    act = self._act
                    if act is None:
                        act = self._act = start(bb, rng)
                        if limit is not None:
                            self._t0 = self._clock()
                        out = act.tick()
                    elif self._handed is not None:
                        out, self._handed = self._handed, None
                        if type(out) is _Raised:
                            raise out.exc
                    elif limit is not None and self._clock() - self._t0 > limit:
                        out = self._expire(act)
                    else:
                        out = act.tick()
                    while out == RUNNING:
                        if not _to_the_end:
                            self._numbers = iter(range(steps, self._limit + 1))  # not done
                            self.ticks += 1
                            if record is not None:
                                self._collect()
                            return RUNNING
                        n += 1
                        if limit is not None and self._clock() - self._t0 > limit:
                            out = self._expire(act)
                        else:
                            out = act.tick()
                    self._act = None
                    if out is _EXPIRED:  # the state's timeout transition, else the run's end
                        ends = self.compiled._ends
                        out, nxt = TIMEOUT, {TIMEOUT: nxt.get(TIMEOUT, -len(ends))}
                try:
                    j = nxt[out]
                except Exception:  # not an outcome (a KeyError), not even hashable (a list)
                    raise self.compiled.undeclared(i, out) from None
                if record is not None:
                    record(new(step, (
                        steps, names[i], skills[i], out, ends[-j - 1] if j < 0 else names[j],
                        self._changes() if bb._log or self._pending else nothing,
                    )))
                if j < 0:
                    self.steps = steps
                    self.ticks += steps + n
                    return self._finish(self.compiled._ends[-j - 1], i)
                i = j
                if not _to_the_end:
                    break
        except Exception as exc:  # (the finally below clears the blackboard's client)
            self._fail(i, steps, n, exc)
            if self._propagate:
                raise
            return ERROR
        except BaseException as exc:
            # Not an error a skill returns from: sys.exit() in a skill, GeneratorExit, a
            # Ctrl-C, a caller's time limit. The run ends here in error all the same (its
            # result says where), and the exception goes on to the caller, who decides.
            with contextlib.suppress(Exception):
                self._fail(i, steps, n, exc)
            raise
        finally:
            bb._client = None
        self.steps = steps
        self.ticks += steps + n
        self._i = i
        if steps >= self._limit:
            return self._finish(TIMEOUT, i)
        return RUNNING

    def _fail(self, i: int, steps: int, n: int, exc: BaseException) -> None:
        """End the run in error: state ``i``'s skill raised ``exc`` in step ``steps``."""
        self._act = None
        self.steps = steps
        self.ticks += steps + n
        if self._record is not None:
            c = self.compiled
            self._record(TraceStep(steps, c.names[i], c.skills[i], ERROR, ERROR,
                                   self._changes()))
        self._finish(ERROR, i, exc)

    def _expire(self, act: Activation) -> Any:
        """The state's time limit ran out: cancel its activation."""
        self._act = None
        act.cancel()
        return _EXPIRED

    def preempt(self) -> RunResult:
        """Stop now: cancel the running skill (once) and end with ``preempted``.

        Writes the skill made before it was cancelled stay; its cancel hook runs with the
        skill's declared access. A run that has ended already is left as it was.
        """
        if self._result is not None:
            return self._result
        act = self._act
        self._act = None
        i = self._i
        bb = self.bb
        exc: Exception | None = None
        events = self._events
        if events is not None:
            bb.take_log()
        if act is not None:
            bb._client = self._table[i][2]
            try:
                act.cancel()
            except Exception as e:
                exc = e
            finally:
                bb._client = None
            if events is not None:
                events.append(TraceStep(
                    self.steps + 1, self.compiled.names[i], self.compiled.skills[i],
                    PREEMPTED, PREEMPTED, self._changes(),
                ))
        self._finish(PREEMPTED, i, exc)
        if exc is not None and self._propagate:
            raise exc
        return self.result

    # -- internals ---------------------------------------------------------------------------
    def _collect(self) -> None:
        pending = self._pending
        for k, (old, new) in self.bb.take_log().items():
            pending[k] = (pending[k][0] if k in pending else old, new)

    def _changes(self) -> dict[str, tuple[Any, Any]]:
        """The current state's changes (over all its ticks), and a fresh record."""
        if not self._pending:
            return self.bb.take_log()
        self._collect()
        out = {k: v for k, v in self._pending.items() if not _same(v[0], v[1])}
        self._pending = {}
        return out

    def _finish(self, outcome: str, i: int, exc: BaseException | None = None) -> str:
        """End the run with ``outcome`` after ``self.steps`` steps, in state ``i``."""
        events = self._events
        trace = None
        if events is not None:
            trace = tuple(events)
            self.bb.stop_log()
        self._result = _new(RunResult, (outcome, self.steps, self.compiled.names[i], trace, exc))
        return outcome

    def __repr__(self) -> str:
        status = self._result.outcome if self._result is not None else RUNNING
        return (
            f"<FSARun {self.compiled.fsa.name or ''} state={self.state} steps={self.steps} "
            f"ticks={self.ticks} {status}>"
        )


def compile_fsa(fsa: FSA, registry: SkillLookup, backend: str | None = None) -> CompiledFSA:
    """Validate ``fsa`` against ``registry`` and bind it to ``backend``'s implementations.

    Raises :class:`~skillcompose.errors.FSAValidationError` listing every problem.
    """
    if not isinstance(fsa, FSA):
        raise TypeError(f"compile_fsa takes an FSA, got {type(fsa).__name__}"
                        + ("; load the file with load_fsa(path)"
                           if isinstance(fsa, (str, os.PathLike)) else ""))
    if not hasattr(registry, "resolve") or not hasattr(registry, "spec"):
        raise TypeError(f"compile_fsa takes a Registry, got {type(registry).__name__}")
    fsa.validate(registry)
    be = backend or registry.backend
    impls = []
    for sname, st in fsa.states.items():
        impl = registry.resolve(st.skill, be)
        impls.append((impl, impl.spec.resolve_params(st.params, f"state {sname}")))
    return CompiledFSA(fsa, impls, be)


def run_fsa(
    fsa: FSA | CompiledFSA,
    registry: SkillLookup | None = None,
    bb: Blackboard | None = None,
    rng: np.random.Generator | int | None = None,
    *,
    backend: str | None = None,
    trace: bool = False,
    propagate: bool = False,
) -> RunResult:
    """Compile (when needed) and run once: the one-call form of :meth:`CompiledFSA.run`."""
    if not isinstance(fsa, CompiledFSA):
        if registry is None:
            raise TypeError("run_fsa(fsa, registry, ...) needs the registry to find skills")
        fsa = compile_fsa(fsa, registry, backend)  # says what else it could be
    return fsa.run(bb, rng, trace=trace, propagate=propagate)


def run_ticking(
    compiled: CompiledFSA,
    bb: Blackboard | None = None,
    rng: np.random.Generator | int | None = None,
    *,
    trace: bool = False,
    propagate: bool = False,
    time_limits: Mapping[str, float] | None = None,
    max_ticks: int | None = None,
    period: float = 0.0,
) -> RunResult:
    """Run once in tick-wise mode, ticking until the end: the one-call form of :class:`FSARun`."""
    run = compiled.start(bb, rng, trace=trace, propagate=propagate, time_limits=time_limits)
    return run.run(max_ticks=max_ticks, period=period)


def trial_seeds(
    seed: int | Sequence[int] | np.random.SeedSequence | None, trials: int, start: int = 0
) -> list[np.random.SeedSequence]:
    """Independent child seeds of ``seed``, one per trial: the same for the same seed.

    They are the children ``start .. start + trials - 1`` that ``seed.spawn`` would give, so
    a range of trials can be drawn alone (in a worker, say) with the same numbers. A
    ``SeedSequence`` is read, never spawned from: calling this twice gives the same children.
    """
    seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    return [
        np.random.SeedSequence(seq.entropy, spawn_key=(*seq.spawn_key, k),
                               pool_size=seq.pool_size)
        for k in range(start, start + trials)
    ]


def trial_rngs(
    seed: int | Sequence[int] | np.random.SeedSequence | None, trials: int, start: int = 0
) -> Iterator[np.random.Generator]:
    return (np.random.default_rng(s) for s in trial_seeds(seed, trials, start))


def summarize(results: Sequence[RunResult]) -> dict[str, Any]:
    """Outcome counts and mean steps over many runs."""
    n = len(results)
    return {
        "trials": n,
        "outcomes": dict(Counter(r.outcome for r in results).most_common()),
        "mean_steps": (sum(r.steps for r in results) / n) if n else 0.0,
    }
