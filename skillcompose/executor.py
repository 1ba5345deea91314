"""Running FSAs: compile once against a registry and a backend, then run many times.

:func:`compile_fsa` validates an :class:`~skillcompose.fsa.FSA` against a registry, binds each
state's skill implementation to its parameters, and turns the transition function into
integer tables. :meth:`CompiledFSA.run` then executes it on a blackboard with a
``numpy.random.Generator``: each step calls one skill and follows the outcome, until a
terminal outcome, or ``timeout`` after ``step_limit`` steps, or ``error`` when a skill raises.

That is the run-to-completion mode. :meth:`CompiledFSA.start` begins a tick-wise run instead
(:class:`~skillcompose.ticking.FSARun`): each tick advances the current skill by one tick, so
long-running skills do not block the caller, and the run can be preempted between ticks.
"""

from __future__ import annotations

import functools
import traceback
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .blackboard import Access, Blackboard
from .errors import UndeclaredOutcomeError
from .fsa import ERROR, FSA, TIMEOUT

if TYPE_CHECKING:
    from .registry import Registry
    from .skill import Skill, SkillFn
    from .ticking import FSARun

__all__ = [
    "CompiledFSA",
    "RunResult",
    "TraceStep",
    "compile_fsa",
    "error_summary",
    "run_fsa",
    "trial_seeds",
]


@dataclass(frozen=True)
class TraceStep:
    """One step of a run: which state ran, what it returned, what it changed."""

    step: int
    state: str
    skill: str
    outcome: str
    target: str  # the next state, or the terminal outcome that ended the run
    changes: Mapping[str, tuple[Any, Any]]  # key -> (old, new); see blackboard.DELETED


@dataclass(frozen=True)
class RunResult:
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


def error_summary(exc: BaseException, frames: int = 3) -> str:
    """``Type: message`` and, below it, the innermost ``frames`` frames of its traceback."""
    head = "".join(traceback.format_exception_only(type(exc), exc)).strip()
    stack = traceback.extract_tb(exc.__traceback__)[-frames:]
    body = "".join(traceback.format_list(stack)).rstrip()
    return f"{head}\n{body}" if body else head


class _Raised(Exception):
    """Internal: carries a skill's exception and the state it happened in."""

    def __init__(self, exc: BaseException, state_index: int, steps: int) -> None:
        self.exc = exc
        self.state_index = state_index
        self.steps = steps


class CompiledFSA:
    """An FSA bound to skill implementations: cheap to run, safe to reuse across runs.

    One compiled FSA may run on many blackboards one after another; it holds no per-run
    state. Build it with :func:`compile_fsa`.
    """

    __slots__ = (
        "_impls",
        "_key_types",
        "_start",
        "_table",
        "_time_limits",
        "backend",
        "fsa",
        "names",
        "skills",
        "step_limit",
        "terminals",
    )

    def __init__(
        self,
        fsa: FSA,
        table: list[tuple[Callable[..., str], Access, dict[str, int]]],
        names: list[str],
        skills: list[str],
        key_types: dict[str, Any],
        backend: str,
        impls: list[tuple[Skill, dict[str, Any]]] | None = None,
    ) -> None:
        self.fsa = fsa
        self._impls = impls or []  # per state: (implementation, resolved params)
        self._table = table
        self.names = names
        self.skills = skills
        self._start = names.index(fsa.start)
        self.step_limit = fsa.step_limit
        self.terminals = fsa.terminals
        self._key_types = key_types
        self.backend = backend
        self._time_limits = {
            n: st.time_limit for n, st in fsa.states.items() if st.time_limit is not None
        }

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
        bb, rng = self._prepare(bb, rng)
        if self._time_limits:  # wall-clock limits need the tick-wise engine
            return self.start(bb, rng, trace=trace, propagate=propagate).run()
        try:
            if trace:
                return self._run_traced(bb, rng, propagate)
            outcome, steps, last = self._run_fast(bb, rng)
            return RunResult(outcome, steps, last)
        except _Raised as r:
            exc = r.exc
            if propagate:
                raise exc from None
            return RunResult(ERROR, r.steps, self.names[r.state_index], error=exc)
        finally:
            bb._client = None

    def _prepare(
        self, bb: Blackboard | None, rng: np.random.Generator | int | None
    ) -> tuple[Blackboard, np.random.Generator]:
        """The blackboard and generator a run uses (new ones when not given), with the FSA's
        typed keys declared on the blackboard."""
        if bb is None:
            bb = Blackboard()
        if not isinstance(rng, np.random.Generator):
            rng = np.random.default_rng(rng)
        for k, t in self._key_types.items():
            if bb._types.get(k) is not t:
                bb.declare(k, t)
        return bb, rng

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
        ``time_limit``; see :class:`~skillcompose.ticking.FSARun`.
        """
        from .ticking import FSARun

        return FSARun(
            self, bb, rng, trace=trace, propagate=propagate, time_limits=time_limits,
            clock=clock,
        )

    def outcome(self, bb: Blackboard, rng: np.random.Generator) -> tuple[str, int]:
        """(outcome, steps) of one run, raising on skill errors: the evaluation hot path."""
        if self._time_limits:
            result = self.start(bb, rng, propagate=True).run()
            return result.outcome, result.steps
        try:
            outcome, steps, _ = self._run_fast(bb, rng)
        except _Raised as r:
            raise r.exc from None
        finally:
            bb._client = None
        return outcome, steps

    def _run_fast(
        self, bb: Blackboard, rng: np.random.Generator
    ) -> tuple[str, int, str | None]:
        table = self._table
        i = self._start
        steps = 0
        limit = self.step_limit
        try:
            while steps < limit:
                fn, access, nxt = table[i]
                bb._client = access
                steps += 1  # counted before the call: a step that raises counts too
                out = fn(bb, rng)
                j = nxt.get(out)
                if j is None:
                    raise self._undeclared(i, out)
                if j < 0:
                    return self.terminals[-j - 1], steps, self.names[i]
                i = j
        except _Raised:
            raise
        except Exception as exc:
            raise _Raised(exc, i, steps) from exc
        return TIMEOUT, steps, self.names[i]

    def _run_traced(
        self, bb: Blackboard, rng: np.random.Generator, propagate: bool
    ) -> RunResult:
        table = self._table
        i = self._start
        steps = 0
        events: list[TraceStep] = []
        bb.start_log()
        try:
            while steps < self.step_limit:
                fn, access, nxt = table[i]
                bb._client = access
                try:
                    out = fn(bb, rng)
                    j = nxt.get(out)
                    if j is None:
                        raise self._undeclared(i, out)
                except Exception as exc:
                    if propagate:
                        raise
                    bb._client = None
                    events.append(TraceStep(
                        steps + 1, self.names[i], self.skills[i], ERROR, ERROR, bb.take_log()
                    ))
                    return RunResult(ERROR, steps + 1, self.names[i], tuple(events), exc)
                steps += 1
                bb._client = None
                target = self.terminals[-j - 1] if j < 0 else self.names[j]
                events.append(
                    TraceStep(steps, self.names[i], self.skills[i], out, target, bb.take_log())
                )
                if j < 0:
                    return RunResult(target, steps, self.names[i], tuple(events))
                i = j
            return RunResult(TIMEOUT, steps, self.names[i], tuple(events))
        finally:
            bb.stop_log()

    def _undeclared(self, i: int, out: object) -> UndeclaredOutcomeError:
        return UndeclaredOutcomeError(
            f"state {self.names[i]}: skill {self.skills[i]} returned {out!r}, which is not "
            f"one of its declared outcomes {list(self._table[i][2])}; return a declared "
            "outcome or add it to the skill's outcomes"
        )

    def run_many(
        self,
        setup: Callable[[np.random.Generator], Blackboard] | None,
        seed: int | np.random.SeedSequence | None,
        trials: int,
        *,
        propagate: bool = False,
    ) -> list[RunResult]:
        """Run ``trials`` times; trial ``k`` uses the ``k``-th child seed of ``seed``.

        ``setup(rng)`` builds each trial's blackboard (the world); it draws from the same
        generator the skills then use, so a trial is reproducible from ``(seed, k)``.
        """
        results = []
        for rng in trial_rngs(seed, trials):
            bb = setup(rng) if setup is not None else Blackboard()
            results.append(self.run(bb, rng, propagate=propagate))
        return results

    def __repr__(self) -> str:
        return (
            f"<CompiledFSA {self.fsa.name or ''} states={len(self.names)} "
            f"start={self.fsa.start} backend={self.backend}>"
        )


def compile_fsa(fsa: FSA, registry: Registry, backend: str | None = None) -> CompiledFSA:
    """Validate ``fsa`` against ``registry`` and bind it to ``backend``'s implementations.

    Raises :class:`~skillcompose.errors.FSAValidationError` listing every problem.
    """
    fsa.validate(registry)
    be = backend or registry.backend
    names = list(fsa.states)
    index = {n: k for k, n in enumerate(names)}
    term = {t: -(k + 1) for k, t in enumerate(fsa.terminals)}
    table: list[tuple[Callable[..., str], Access, dict[str, int]]] = []
    skills: list[str] = []
    key_types: dict[str, Any] = {}
    bound: dict[str, SkillFn] = {}
    impls: list[tuple[Skill, dict[str, Any]]] = []
    for sname in names:
        st = fsa.states[sname]
        impl = registry.resolve(st.skill, be)
        spec = impl.spec
        if st.skill not in bound:
            bound[st.skill] = impl.bind(registry, be)
        fn = bound[st.skill]
        params = spec.resolve_params(st.params, f"state {sname}")
        call: Callable[..., str] = functools.partial(fn, **params) if params else fn
        nxt = {o: (index[t] if t in index else term[t]) for o, t in st.transitions.items()}
        table.append((call, spec.access(), nxt))
        impls.append((impl, params))
        skills.append(st.skill)
        for k, t in spec.key_types.items():
            key_types.setdefault(k, t)
    return CompiledFSA(fsa, table, names, skills, key_types, be, impls)


def run_fsa(
    fsa: FSA | CompiledFSA,
    registry: Registry | None = None,
    bb: Blackboard | None = None,
    rng: np.random.Generator | int | None = None,
    *,
    backend: str | None = None,
    trace: bool = False,
    propagate: bool = False,
) -> RunResult:
    """Compile (when needed) and run once: the one-call form of :meth:`CompiledFSA.run`."""
    if isinstance(fsa, FSA):
        if registry is None:
            raise TypeError("run_fsa(fsa, registry, ...) needs the registry to find skills")
        fsa = compile_fsa(fsa, registry, backend)
    return fsa.run(bb, rng, trace=trace, propagate=propagate)


def trial_seeds(
    seed: int | Sequence[int] | np.random.SeedSequence | None, trials: int
) -> list[np.random.SeedSequence]:
    """Independent child seeds of ``seed``, one per trial: the same for the same seed.

    A ``SeedSequence`` is copied first, so calling this twice gives the same children.
    """
    if isinstance(seed, np.random.SeedSequence):
        seq = np.random.SeedSequence(seed.entropy, spawn_key=seed.spawn_key)
    else:
        seq = np.random.SeedSequence(seed)
    return seq.spawn(trials)


def trial_rngs(
    seed: int | Sequence[int] | np.random.SeedSequence | None, trials: int
) -> Iterator[np.random.Generator]:
    for s in trial_seeds(seed, trials):
        yield np.random.default_rng(s)


def summarize(results: Sequence[RunResult]) -> dict[str, Any]:
    """Outcome counts and mean steps over many runs."""
    counts: dict[str, int] = {}
    for r in results:
        counts[r.outcome] = counts.get(r.outcome, 0) + 1
    n = len(results)
    return {
        "trials": n,
        "outcomes": dict(sorted(counts.items(), key=lambda kv: -kv[1])),
        "mean_steps": (sum(r.steps for r in results) / n) if n else 0.0,
    }
