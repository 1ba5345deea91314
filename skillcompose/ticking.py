"""Long-running skills and the tick-wise executor.

Real skills take seconds, so a runtime that shares the thread with a behaviour tree, a GUI or
a control loop must *tick* them, not block on them. This module holds both halves:

- the protocol: a long-running skill is started once per activation and returns an
  :class:`Activation`, whose ``tick()`` returns ``"running"`` (:data:`RUNNING`) until it
  returns an outcome, and whose ``cancel()`` is its cancel hook. :mod:`skillcompose.skill`
  turns start / tick / cancel classes and generator functions into such starters.
- :class:`FSARun`, one tick-wise run of a compiled FSA: each :meth:`FSARun.tick` advances the
  current state's skill by one tick and, when it finishes, takes the transition. An instant
  (function) skill finishes in the tick that calls it. :meth:`FSARun.preempt` cancels the
  running skill (once) and ends the run with ``preempted``; nested FSAs pass it down.

Both modes agree: one skill completion is one step toward ``step_limit``, and for the same seed
a tick-wise run and a run-to-completion run give the same outcome, steps and trace.

Wall-clock limits per state (``time_limits={"Grasp": 2.0}``, in seconds) end a state that
runs too long with the outcome ``timeout``: the state's ``timeout`` transition when its skill
declares that outcome, else the run ends with ``timeout``. For a long-running skill the limit
is checked before each tick (a single tick that never returns cannot be interrupted in
Python). An instant skill under a limit runs in a worker thread on a private copy of its
declared keys and a copy of the random generator; its writes and generator state are
committed when it returns in time. When it does not, the thread is abandoned (Python cannot
kill it: it runs on, daemonised, against its private copy, so the run's blackboard and
generator stay consistent) and the skill's ``cancel(bb)`` method, if its class has one, is
called once.
"""

from __future__ import annotations

import copy
import math
import threading
import time
from collections.abc import Callable, Generator, Mapping
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from .blackboard import DELETED, Access, Blackboard
from .errors import SkillProtocolError
from .executor import RunResult, TraceStep
from .fsa import ERROR, PREEMPTED, TIMEOUT

if TYPE_CHECKING:
    from .executor import CompiledFSA
    from .skill import Skill

__all__ = [
    "RUNNING",
    "Activation",
    "FSARun",
    "Starter",
    "run_ticking",
]

RUNNING = "running"
"""What ``tick()`` returns while a skill (or an FSA run) has not finished."""


class Activation(Protocol):
    """One activation of a long-running skill, bound to its blackboard and generator."""

    def tick(self) -> str:
        """Advance by one tick: :data:`RUNNING`, or the outcome when finished."""

    def cancel(self) -> None:
        """Stop early. Called at most once, and never after ``tick`` returned an outcome."""


Starter = Callable[..., Activation]
"""``start(bb, rng, **params) -> Activation``."""


# ---------------------------------------------------------------------------------------
# activations of user skills
# ---------------------------------------------------------------------------------------
class InstanceActivation:
    """A start / tick / cancel object: ``tick(bb, rng)``, ``cancel(bb)`` (optional)."""

    __slots__ = ("bb", "obj", "rng")

    def __init__(self, obj: Any, bb: Blackboard, rng: np.random.Generator) -> None:
        self.obj = obj
        self.bb = bb
        self.rng = rng

    def tick(self) -> str:
        out: str = self.obj.tick(self.bb, self.rng)
        return out

    def cancel(self) -> None:
        hook = getattr(self.obj, "cancel", None)
        if hook is not None:
            hook(self.bb)


class GeneratorActivation:
    """A generator skill: each tick resumes it; ``cancel`` closes it (runs its ``finally``)."""

    __slots__ = ("gen", "name")

    def __init__(self, gen: Generator[Any, None, Any], name: str) -> None:
        self.gen = gen
        self.name = name

    def tick(self) -> str:
        try:
            y = next(self.gen)
        except StopIteration as stop:
            if stop.value == RUNNING:
                raise SkillProtocolError(
                    f"skill {self.name} returned {RUNNING!r}; a generator skill yields "
                    f"{RUNNING!r} while it works and returns its outcome when done"
                ) from None
            out: str = stop.value
            return out
        if y is None or y == RUNNING:
            return RUNNING
        raise SkillProtocolError(
            f"skill {self.name} yielded {y!r}; a generator skill yields {RUNNING!r} (or "
            "nothing) while it works and returns its outcome: `return 'success'`"
        )

    def cancel(self) -> None:
        self.gen.close()


def start_instance(cls: type, bb: Blackboard, rng: np.random.Generator, **params: Any) -> Any:
    """Starter of a start / tick / cancel class: a fresh instance per activation."""
    obj = cls()
    obj.start(bb, rng, **params)
    return InstanceActivation(obj, bb, rng)


def start_generator(
    fn: Callable[..., Any], name: str, bb: Blackboard, rng: np.random.Generator, **params: Any
) -> Any:
    """Starter of a generator skill."""
    return GeneratorActivation(fn(bb, rng, **params), name)


def driven(start: Starter) -> Callable[..., str]:
    """Run-to-completion form of a long-running skill: start it and tick it until it ends."""

    def drive(bb: Blackboard, rng: np.random.Generator, **params: Any) -> str:
        act = start(bb, rng, **params)
        out = act.tick()
        while out == RUNNING:
            out = act.tick()
        return out

    drive.__qualname__ = drive.__name__ = f"driven_{getattr(start, '__name__', 'skill')}"
    return drive


class _NestedActivation:
    """A nested FSA ticked state by state; cancelling it preempts the child run."""

    __slots__ = ("run", "timeout_outcome")

    def __init__(self, run: FSARun, timeout_outcome: str) -> None:
        self.run = run
        self.timeout_outcome = timeout_outcome

    def tick(self) -> str:
        out = self.run.tick()
        if out == TIMEOUT and self.run.done:
            return self.timeout_outcome
        return out

    def cancel(self) -> None:
        self.run.preempt()


class _ThreadActivation:
    """An instant skill under a wall-clock limit, run in a worker thread (see module doc)."""

    __slots__ = (
        "_done", "_exc", "_hook", "_out", "_rng_copy", "_staged", "_thread", "bb", "rng",
    )

    def __init__(
        self,
        fn: Callable[..., str],
        bb: Blackboard,
        rng: np.random.Generator,
        access: Access,
        hook: Callable[[Blackboard], Any] | None,
    ) -> None:
        self.bb = bb
        self.rng = rng
        self._hook = hook
        staged = Blackboard(types=bb.types)
        data = bb._data
        for k in access.reads | access.writes:
            if k in data:
                staged._data[k] = copy.deepcopy(data[k])
        staged._client = access
        staged.start_log()
        self._staged = staged
        self._rng_copy = copy.deepcopy(rng)
        self._out: Any = None
        self._exc: BaseException | None = None
        self._done = threading.Event()
        self._thread = threading.Thread(
            target=self._work, args=(fn,), name=f"skillcompose-{access.owner}", daemon=True
        )
        self._thread.start()

    def _work(self, fn: Callable[..., str]) -> None:
        try:
            self._out = fn(self._staged, self._rng_copy)
        except BaseException as exc:  # handed to the ticking thread
            self._exc = exc
        finally:
            self._done.set()

    def tick(self) -> str:
        if not self._done.is_set():
            return RUNNING
        if self._exc is not None:
            raise self._exc
        bb = self.bb
        for k, (_, new) in self._staged.take_log().items():
            if new is DELETED:
                if k in bb._data:
                    del bb[k]
            else:
                bb[k] = new
        self.rng.bit_generator.state = self._rng_copy.bit_generator.state
        out: str = self._out
        return out

    def cancel(self) -> None:
        if self._hook is not None:
            self._hook(self.bb)


# ---------------------------------------------------------------------------------------
# the tick-wise executor
# ---------------------------------------------------------------------------------------
# per state: (instant fn or None, starter or None, access, transitions, limit [s] or None)
_TickState = tuple[
    Callable[..., str], "Starter | None", Access, dict[str, int], "float | None"
]


def _tick_table(
    compiled: CompiledFSA, time_limits: Mapping[str, float] | None
) -> list[_TickState]:
    from functools import partial

    limits = _check_limits(compiled, time_limits or {})
    table: list[_TickState] = []
    for i, ((fn, access, nxt), (impl, params)) in enumerate(
        zip(compiled._table, compiled._impls, strict=True)
    ):
        limit = limits.get(compiled.names[i])
        start = _starter(impl, compiled.backend)
        if start is not None:
            if params:
                start = partial(start, **params)
        elif limit is not None:
            hook = _cancel_hook(impl, compiled.backend)
            start = partial(_ThreadActivation, fn, access=access, hook=hook)
        table.append((fn, start, access, nxt, limit))
    return table


def _starter(impl: Skill, backend: str) -> Starter | None:
    from .nested import FSASkill

    if isinstance(impl, FSASkill):
        impl.bind(None, backend)  # compiles the child once per backend
        child = impl._compiled[backend]
        timeout_outcome = impl.timeout_outcome

        def start_nested(bb: Blackboard, rng: np.random.Generator) -> Activation:
            return _NestedActivation(FSARun(child, bb, rng, propagate=True), timeout_outcome)

        return start_nested
    return impl.starter(backend)


def _cancel_hook(impl: Skill, backend: str) -> Callable[[Blackboard], Any] | None:
    if impl.kind != "instance":
        return None
    hook = getattr(impl.bind(None, backend), "cancel", None)
    return hook if callable(hook) else None


def _check_limits(compiled: CompiledFSA, limits: Mapping[str, float]) -> dict[str, float]:
    from .errors import ParamError

    out: dict[str, float] = {}
    for state, value in limits.items():
        if state not in compiled.names:
            raise ParamError(
                f"time_limits: FSA {compiled.fsa.name or ''} has no state {state!r}; "
                f"its states are {compiled.names}"
            )
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                not math.isfinite(value) or value <= 0:
            raise ParamError(
                f"time_limits: state {state}: the limit must be a positive number of "
                f"seconds, got {value!r}; write e.g. {{{state!r}: 2.0}}"
            )
        out[state] = float(value)
    return out


class FSARun:
    """One tick-wise run of a compiled FSA on a blackboard.

    Build it with :meth:`CompiledFSA.start <skillcompose.executor.CompiledFSA.start>`::

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
        "_act",
        "_clock",
        "_events",
        "_i",
        "_pending",
        "_propagate",
        "_result",
        "_t0",
        "_table",
        "bb",
        "compiled",
        "rng",
        "steps",
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
        bb, rng = compiled._prepare(bb, rng)
        self.compiled = compiled
        self.bb = bb
        self.rng = rng
        limits = {**compiled._time_limits, **(time_limits or {})}  # the caller's win
        self._table = _tick_table(compiled, limits)
        self._clock = clock or time.monotonic
        self._propagate = propagate
        self._i = compiled._start
        self._act: Activation | None = None
        self._t0 = 0.0
        self._result: RunResult | None = None
        self._events: list[TraceStep] | None = [] if trace else None
        self._pending: dict[str, tuple[Any, Any]] = {}
        self.steps = 0
        """Skill completions so far (the count ``step_limit`` bounds)."""
        self.ticks = 0
        """Calls of :meth:`tick` that advanced the run."""
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
    def active(self) -> bool:
        """True while a long-running skill is between ticks (it would be cancelled)."""
        return self._act is not None

    # -- ticking -----------------------------------------------------------------------------
    def tick(self) -> str:
        """Advance the current skill by one tick; :data:`RUNNING` or the run's outcome."""
        if self._result is not None:
            return self._result.outcome
        self.ticks += 1
        bb = self.bb
        i = self._i
        fn, start, access, nxt, limit = self._table[i]
        act = self._act
        events = self._events
        if events is not None:
            bb.take_log()  # drop writes made between ticks by others (a tree, a bridge)
        try:
            bb._client = access
            if act is None:
                if start is None:
                    out = fn(bb, self.rng)
                else:
                    act = start(bb, self.rng)
                    self._act = act
                    if limit is not None:
                        self._t0 = self._clock()
                    out = act.tick()
            elif limit is not None and self._clock() - self._t0 > limit:
                self._act = None
                act.cancel()
                out = TIMEOUT
                if TIMEOUT not in nxt:
                    self.steps += 1
                    return self._end_state(i, TIMEOUT, TIMEOUT, None)
            else:
                out = act.tick()
            if out == RUNNING and act is not None:
                if events is not None:
                    self._collect()
                return RUNNING
            self._act = None
            j = nxt.get(out)
            if j is None:
                raise self.compiled._undeclared(i, out)
        except Exception as exc:
            self._act = None
            bb._client = None
            return self._error(i, exc)
        finally:
            bb._client = None
        self.steps += 1
        if j < 0:
            term = self.compiled.terminals[-j - 1]
            return self._end_state(i, out, term, term)
        self._i = j
        if events is not None:
            self._collect()
            events.append(TraceStep(
                self.steps, self.compiled.names[i], self.compiled.skills[i], out,
                self.compiled.names[j], self._take(),
            ))
        if self.steps >= self.compiled.step_limit:
            self._finish(RunResult(TIMEOUT, self.steps, self.compiled.names[j], self._trace()))
            return TIMEOUT
        return RUNNING

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
        if self._events is not None:
            bb.take_log()
        if act is not None:
            bb._client = self._table[i][2]
            try:
                act.cancel()
            except Exception as e:
                exc = e
            finally:
                bb._client = None
        if self._events is not None and act is not None:
            self._collect()
            self._events.append(TraceStep(
                self.steps + 1, self.compiled.names[i], self.compiled.skills[i],
                PREEMPTED, PREEMPTED, self._take(),
            ))
        result = self._finish(RunResult(
            PREEMPTED, self.steps, self.compiled.names[i], self._trace(), exc
        ))
        if exc is not None and self._propagate:
            raise exc
        return result

    def run(self, *, max_ticks: int | None = None, period: float = 0.0) -> RunResult:
        """Tick until the run ends (or preempt it after ``max_ticks``); sleep ``period`` [s]
        between ticks, which a run waiting on a worker thread or hardware should do."""
        while self._result is None:
            if max_ticks is not None and self.ticks >= max_ticks:
                return self.preempt()
            if self.tick() == RUNNING and period > 0:
                time.sleep(period)
        return self._result

    # -- internals ---------------------------------------------------------------------------
    def _collect(self) -> None:
        pending = self._pending
        for k, (old, new) in self.bb.take_log().items():
            pending[k] = (pending[k][0] if k in pending else old, new)

    def _take(self) -> dict[str, tuple[Any, Any]]:
        from .blackboard import _same

        out = {k: v for k, v in self._pending.items() if not _same(v[0], v[1])}
        self._pending = {}
        return out

    def _trace(self) -> tuple[TraceStep, ...] | None:
        return tuple(self._events) if self._events is not None else None

    def _end_state(self, i: int, out: str, target: str, terminal: str | None) -> str:
        """The state ``i`` finished with ``out`` and the run ends with ``target``."""
        events = self._events
        if events is not None:
            self._collect()
            events.append(TraceStep(
                self.steps, self.compiled.names[i], self.compiled.skills[i], out, target,
                self._take(),
            ))
        self._finish(RunResult(target, self.steps, self.compiled.names[i], self._trace()))
        return target

    def _error(self, i: int, exc: Exception) -> str:
        events = self._events
        steps = self.steps + 1  # the step that raised counts, as in CompiledFSA.run
        if events is not None:
            self._collect()
            events.append(TraceStep(
                steps, self.compiled.names[i], self.compiled.skills[i], ERROR, ERROR,
                self._take(),
            ))
        self._finish(RunResult(ERROR, steps, self.compiled.names[i], self._trace(), exc))
        if self._propagate:
            raise exc
        return ERROR

    def _finish(self, result: RunResult) -> RunResult:
        self._result = result
        if self._events is not None:
            self.bb.stop_log()
        return result

    def __repr__(self) -> str:
        status = self._result.outcome if self._result is not None else RUNNING
        return (
            f"<FSARun {self.compiled.fsa.name or ''} state={self.state} steps={self.steps} "
            f"ticks={self.ticks} {status}>"
        )


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
    run = FSARun(
        compiled, bb, rng, trace=trace, propagate=propagate, time_limits=time_limits
    )
    return run.run(max_ticks=max_ticks, period=period)
