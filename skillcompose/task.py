"""Tasks: what an FSA is for, stated so that runs, sweeps and evolution can score it.

A task module defines ``make_task(**settings) -> Task``. ``settings`` are the task's knobs
(for instance ``p_fail``, the failure probability of the pour-water skills), so that a
robustness sweep or a worker process can rebuild the same task from its module name and
settings alone (:class:`TaskRef`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import AbstractContextManager, nullcontext, suppress
from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np

from .blackboard import Blackboard
from .errors import SkillcomposeError
from .executor import CompiledFSA, RunResult, compile_fsa, trial_rngs
from .fsa import DEFAULT_TERMINALS, ERROR, FSA
from .registry import Registry, describe_exception, import_target

__all__ = ["Task", "TaskError", "TaskRef", "Trial", "load_task", "trials"]

Fitness = Callable[[str, Blackboard, int], float]
"""``fitness(outcome, blackboard, steps) -> float``."""


class TaskError(SkillcomposeError):
    """A task module or its settings are unusable."""


class Trial(NamedTuple):
    """One trial of :func:`trials`: its number, how the run ended, its world's blackboard
    (``None`` when setting it up raised) and its fitness (``nan`` without a score)."""

    number: int
    result: RunResult
    blackboard: Blackboard | None
    fitness: float


def trials(
    compiled: CompiledFSA,
    seed: int | np.random.SeedSequence | None,
    count: int,
    *,
    setup: Callable[[np.random.Generator], Blackboard] | None = None,
    score: Callable[[RunResult, Blackboard], float] | None = None,
    start: int = 0,
    trace_first: bool = False,
    propagate: bool = False,
    catch: Callable[[BaseException], bool] | None = None,
    worst: float = math.nan,
    each: Callable[[], AbstractContextManager[Any]] | None = None,
) -> Iterator[Trial]:
    """The trial loop that runs, evaluations, simplification and sweeps share.

    Trial ``k`` (``start`` to ``start + count - 1``) draws its generator from the ``k``-th
    child of ``seed`` (:func:`~skillcompose.executor.trial_seeds`), sets up its world with it
    (``setup``; default: an empty blackboard), runs ``compiled`` on that world with the same
    generator, and scores it (``score``). The numbers drawn depend on ``seed`` and ``k``
    only, so a range of trials run alone gives the same trials as the whole loop.

    - ``trace_first``: trace the run of trial ``start``; ``propagate``: as in
      :meth:`CompiledFSA.run`.
    - ``catch``: an exception of setup, run or score for which ``catch(exc)`` is true ends
      that trial in ``error`` with fitness ``worst`` (the exception is the result's
      ``error``); any other leaves the loop.
    - ``each``: a context manager entered around each trial (a time limit, say).
    """
    for k, rng in enumerate(trial_rngs(seed, count, start), start):
        bb: Blackboard | None = None
        try:
            with each() if each is not None else nullcontext():
                bb = setup(rng) if setup is not None else Blackboard()
                result = compiled.run(bb, rng, trace=trace_first and k == start,
                                      propagate=propagate)
                fitness = score(result, bb) if score is not None else math.nan
        except BaseException as exc:
            if catch is None or not catch(exc):
                raise
            yield Trial(k, RunResult(ERROR, 0, None, None, exc), bb, worst)
            continue
        yield Trial(k, result, bb, fitness)


@dataclass(frozen=True)
class Task:
    """A problem for FSAs: the skills, a random world per trial, and a fitness.

    - ``registry`` holds the skills; ``skills`` restricts which of them evolution may place
      (default: all); ``backend`` picks the implementation.
    - ``setup(rng)`` draws a world and returns the trial's blackboard.
    - ``fitness(outcome, bb, steps)``: lower is better when ``minimize`` (the paper's
      equations 1 and 2), higher otherwise. ``error_fitness`` scores a run whose skill
      raised (default: the worst possible).
    - ``target``: a mean fitness at least this good counts as solved.
    - ``step_limit``: the paper's timeout. It is the task's: whenever an FSA runs for the
      task (evolution, simplification, ``skillcompose run FILE --task``, robustness) more
      steps than this end the run in ``timeout``, whatever the file's own ``step_limit``
      (which applies when a file runs without a task). See :meth:`compile`.
    - ``trials``: runs averaged per evaluation.
    - ``terminals``: the outcomes that end a run (default ``success``, ``failure``), as an
      FSA file's ``terminals:``; the fitness sees which one ended it.
    - ``terminal_skills``: the skills whose outcomes end a run, as the paper's CheckSuccess
      (4.1, 4.3) and Push (4.2) do. Evolution then routes each outcome of those skills that
      names a terminal to that terminal, and every other edge to a state, as in the paper.
      ``None`` (default) lets any outcome of any state end the run.
    - ``deterministic``: the world and the skills draw nothing at random, so every episode
      of an FSA is the same: evolution then runs one trial per evaluation and one per
      simplification test and check, whatever ``trials`` says.
    """

    name: str
    registry: Registry
    setup: Callable[[np.random.Generator], Blackboard]
    fitness: Fitness
    minimize: bool = True
    target: float = 0.0
    step_limit: int = 20
    trials: int = 1
    backend: str | None = None
    skills: tuple[str, ...] | None = None
    settings: Mapping[str, Any] = field(default_factory=dict)
    error_fitness: float | None = None
    terminal_skills: tuple[str, ...] | None = None
    terminals: tuple[str, ...] = DEFAULT_TERMINALS
    deterministic: bool = False
    ref: TaskRef | None = None

    @property
    def worst(self) -> float:
        if self.error_fitness is not None:
            return self.error_fitness
        return math.inf if self.minimize else -math.inf

    def skill_names(self) -> tuple[str, ...]:
        return self.skills if self.skills is not None else tuple(self.registry.names())

    def solved(self, fitness: float) -> bool:
        return fitness <= self.target if self.minimize else fitness >= self.target

    def compile(self, fsa: FSA, backend: str | None = None) -> CompiledFSA:
        """``fsa`` compiled for this task: its skills, its backend, and its step limit."""
        if fsa.step_limit != self.step_limit:
            fsa = fsa.replace(step_limit=self.step_limit)
        return compile_fsa(fsa, self.registry, backend or self.backend)

    def score(self, result: RunResult, bb: Blackboard) -> float:
        if result.outcome == ERROR:
            return self.worst
        return float(self.fitness(result.outcome, bb, result.steps))

    def each_trial(
        self, compiled: CompiledFSA, seed: int | np.random.SeedSequence | None,
        trials: int | None = None, **options: Any,
    ) -> Iterator[Trial]:
        """:func:`trials` of this task: its worlds, its score, its worst fitness; ``trials``
        defaults to the task's, ``options`` are :func:`trials`' keywords."""
        return _trials(compiled, seed, self.trials if trials is None else trials,
                       setup=self.setup, score=self.score, worst=self.worst, **options)

    def run_trials(
        self, compiled: CompiledFSA, seed: int | np.random.SeedSequence | None, trials: int
    ) -> list[tuple[RunResult, float]]:
        """Run ``trials`` fresh worlds from ``seed``; each result with its fitness."""
        return [(t.result, t.fitness) for t in self.each_trial(compiled, seed, trials)]

    def evaluate(
        self, compiled: CompiledFSA, seed: int | np.random.SeedSequence | None,
        trials: int | None = None,
    ) -> float:
        """Mean fitness over ``trials`` (default: the task's) worlds drawn from ``seed``."""
        runs = self.each_trial(compiled, seed, trials or self.trials)
        return float(np.mean([t.fitness for t in runs]))


_trials = trials  # Task's field ``trials`` hides the function inside the class


@dataclass(frozen=True)
class TaskRef:
    """How to rebuild a task elsewhere (another process): its module and its settings."""

    module: str
    settings: Mapping[str, Any] = field(default_factory=dict)

    def build(self) -> Task:
        return load_task(self.module, **dict(self.settings))


def load_task(target: str, **settings: Any) -> Task:
    """Import a task module (dotted name or ``.py`` path) and call its ``make_task``."""
    try:
        module = import_target(target)
    except SkillcomposeError as exc:
        raise TaskError(f"cannot load task {target!r}: {exc}") from exc
    make = getattr(module, "make_task", None)
    if not callable(make):
        raise TaskError(
            f"task module {target} has no make_task(**settings) -> Task function; define one"
        )
    try:
        task = make(**settings)
    except SkillcomposeError as exc:
        raise TaskError(f"task {target}: make_task({_args(settings)}): {exc}") from exc
    except TypeError as exc:
        raise TaskError(
            f"task {target}: make_task() rejected settings {dict(settings)}: {exc}"
        ) from exc
    except Exception as exc:  # the task's own code failed: say where, not a traceback
        raise TaskError(
            f"task {target}: make_task({_args(settings)}) raised {describe_exception(exc)}"
        ) from exc
    if not isinstance(task, Task):
        raise TaskError(f"task {target}: make_task() returned {type(task).__name__}, not Task")
    return replace(task, ref=TaskRef(target, dict(settings)))


def _args(settings: Mapping[str, Any]) -> str:
    return ", ".join(f"{k}={v!r}" for k, v in settings.items())


def parse_settings(items: Sequence[str]) -> dict[str, Any]:
    """``["p_fail=0.3", "trials=4"]`` → ``{"p_fail": 0.3, "trials": 4}``."""
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise TaskError(f"task setting {item!r} must look like name=value")
        k, v = item.split("=", 1)
        val: Any = v
        for conv in (float, int):  # a whole number stays an int
            with suppress(ValueError):
                val = conv(v)
        if v.lower() in ("true", "false"):
            val = v.lower() == "true"
        out[k.strip()] = val
    return out
