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
from .checks import real_in, whole_in
from .errors import SkillcomposeError, clip, control_characters
from .executor import CompiledFSA, FSARun, RunResult, compile_fsa, trial_rngs
from .fsa import DEFAULT_TERMINALS, ERROR, FSA, MAX_STEP_LIMIT
from .limits import MAX_TRIALS
from .registry import Registry, describe_exception, import_target

__all__ = ["Task", "TaskError", "TaskRef", "Trial", "load_task", "skill_fault", "trials"]

Fitness = Callable[[str, Blackboard, int], float]
"""``fitness(outcome, blackboard, steps) -> float``."""


class TaskError(SkillcomposeError):
    """A task module or its settings are unusable.

    ``settings`` holds the settings given to the task when its own code failed (they may be
    why), so that the command line can say which ``--set`` to check.
    """

    def __init__(self, message: str, *, settings: Mapping[str, Any] | None = None) -> None:
        super().__init__(message)
        self.settings: dict[str, Any] = dict(settings or {})


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
        run: FSARun | None = None
        try:
            with each() if each is not None else nullcontext():
                bb = _blackboard(setup(rng)) if setup is not None else Blackboard()
                run = FSARun(compiled, bb, rng, trace=trace_first and k == start,
                             propagate=propagate)
                run.tick(True)  # to the run's end (as CompiledFSA.run)
                result = run.result
                fitness = score(result, bb) if score is not None else math.nan
        except BaseException as exc:
            if catch is None or not catch(exc):
                raise
            # the run's own end when a skill raised it (sys.exit() in a skill, say): its
            # state, steps and trace; else (the world's setup, the score) an empty one
            ended = run.result if run is not None and run.done and run.result.error is exc \
                else RunResult(ERROR, 0, None, None, exc)
            yield Trial(k, ended, bb, worst)
            continue
        yield Trial(k, result, bb, fitness)


def _blackboard(bb: Any) -> Blackboard:
    """What a world setup gave back, which must be a blackboard."""
    if not isinstance(bb, Blackboard):
        raise TypeError(f"the world setup returned {clip(repr(bb), 40)}, not a Blackboard; "
                        "return one: Blackboard({...})")
    return bb


def _number(value: Any, task: str) -> float:
    """What the fitness of ``task`` gave back, which must be a number (anything ``float()``
    takes but text and truth values: numpy scalars and 0-d arrays, ``Decimal``) and not
    NaN."""
    shown = clip(repr(value), 40)
    if isinstance(value, (str, bytes, bool, np.bool_)):
        raise TypeError(f"the fitness of task {task} returned {shown}, not a number; return "
                        "a float")
    try:
        f = float(value)
    except OverflowError:
        raise ValueError(f"the fitness of task {task} returned {shown}, beyond ±1.8e308; "
                         "return a smaller number (inf or -inf for the worst)") from None
    except (TypeError, ValueError):
        raise TypeError(f"the fitness of task {task} returned {shown}, not a number; return "
                        "a float") from None
    if math.isnan(f):
        raise ValueError(f"the fitness of task {task} returned NaN; return a number (inf or "
                         "-inf for the worst)")
    return f


@dataclass(frozen=True)
class Task:
    """A problem for FSAs: the skills, a random world per trial, and a fitness.

    - ``name``: the task's name, written into every evolved FSA and message about the task
      (text without control characters).
    - ``settings``: the settings the task was made with (``make_task(**settings)``), recorded
      in run folders so that a run can rebuild its task (default: none).
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
      names a terminal to that terminal, and every other edge to a state, as in the paper:
      a terminating skill's ``failure`` ends the run and is never retried, so a skill that
      fails at random should not be one.
      ``None`` (default) lets any outcome of any state end the run.
    - ``deterministic``: the world and the skills draw nothing at random, so every episode
      of an FSA is the same: evolution then runs one trial per evaluation and one per
      simplification test and check, whatever ``trials`` says.
    - ``success_rate``: the share of episodes at the target an FSA must reach to count as
      holding on this task (default 0.95): evolution's "solved" (every preset but
      ``paper``) asks that the one-sided 95 % lower confidence bound of that share, on
      fresh episodes, is at least this (see :mod:`skillcompose.stats`).
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
    success_rate: float = 0.95
    ref: TaskRef | None = None

    def __post_init__(self) -> None:
        # the name goes into every evolved FSA and line that names the task: shown as it is
        if not isinstance(self.name, str) or not self.name.strip() or \
                control_characters(self.name):
            raise TaskError(
                f"task name {clip(repr(self.name), 60)} must be non-empty text without "
                "control characters (line breaks, escapes); give Task(name=...) another name"
            )
        me = f"task {self.name}"
        for field_, most in (("trials", MAX_TRIALS), ("step_limit", MAX_STEP_LIMIT)):
            value = getattr(self, field_)
            if not whole_in(value, 1, most, numpy=True):
                raise TaskError(f"{me}: {field_} = {clip(repr(value), 40)}: expected a whole "
                                f"number from 1 to {most:,}")
            object.__setattr__(self, field_, int(value))
        for field_ in ("minimize", "deterministic"):
            if isinstance(getattr(self, field_), np.bool_):  # numpy's: Python's
                object.__setattr__(self, field_, bool(getattr(self, field_)))
            if not isinstance(getattr(self, field_), bool):
                raise TaskError(f"{me}: {field_} = {clip(repr(getattr(self, field_)), 40)}: "
                                "expected True or False")
        for field_ in ("skills", "terminal_skills", "terminals"):
            value = getattr(self, field_)
            if value is None and field_ != "terminals":
                continue
            if isinstance(value, str) or not isinstance(value, Sequence) or \
                    not all(isinstance(v, str) for v in value):
                raise TaskError(f"{me}: {field_} = {clip(repr(value), 40)}: expected a tuple "
                                f"of names, e.g. {field_}=('success', 'failure')"
                                if field_ == "terminals" else
                                f"{me}: {field_} = {clip(repr(value), 40)}: expected a tuple "
                                f"of skill names, e.g. {field_}=('Carry',)")
            object.__setattr__(self, field_, tuple(value))
        if not isinstance(self.registry, Registry):
            raise TaskError(f"{me}: registry = {clip(repr(self.registry), 40)}: expected a "
                            "skillcompose.Registry holding the task's skills")
        if not real_in(self.target, -math.inf, math.inf, low_open=True, high_open=True,
                       numpy=True):
            # NaN, and an infinite target every fitness reaches (solved in generation 0)
            raise TaskError(f"{me}: target = {clip(repr(self.target), 40)}: expected a "
                            "finite number")
        worst = self.error_fitness
        if worst is not None and not real_in(worst, -math.inf, math.inf, numpy=True):
            raise TaskError(f"{me}: error_fitness = {clip(repr(worst), 40)}: expected a "
                            "number (inf or -inf for the worst), or None")
        if not isinstance(self.settings, Mapping) or not all(
                isinstance(k, str) for k in self.settings):
            raise TaskError(f"{me}: settings = {clip(repr(self.settings), 40)}: expected a "
                            "mapping of setting names to values, e.g. {'p_fail': 0.2}")
        if self.backend is not None:
            known = sorted({b for n in self.registry.names()
                            for b in self.registry.backends(n)})
            if not isinstance(self.backend, str) or self.backend not in known:
                raise TaskError(f"{me}: backend = {clip(repr(self.backend), 40)}: no skill "
                                f"of its registry has it; choose one of {known or 'none'}")
        rate = self.success_rate
        if not real_in(rate, 0.0, 1.0, low_open=True, high_open=True, numpy=True):
            raise TaskError(f"{me}: success_rate = {clip(repr(rate), 40)}: expected a rate "
                            "between 0 and 1 (exclusive), e.g. 0.95")
        object.__setattr__(self, "success_rate", float(rate))
        if not callable(self.setup) or not callable(self.fitness):
            which = "setup" if not callable(self.setup) else "fitness"
            raise TaskError(f"{me}: {which} = {clip(repr(getattr(self, which)), 40)}: "
                            "expected a function")

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
        return _number(self.fitness(result.outcome, bb, result.steps), self.name)

    def guarded(self) -> Task:
        """This task with its world setup and fitness guarded: whatever they raise (an
        exception, ``sys.exit()``; not a Ctrl-C) becomes a :class:`TaskError` naming the
        task, the place in its code and the settings it was given. Runs and sweeps of the
        command line use it (the task's code failing is not the FSA's fault); evolution
        counts such an episode as a fault instead."""
        where = self.ref.module if self.ref is not None else self.name
        settings = dict(self.ref.settings) if self.ref is not None else {}
        setup, fitness = self.setup, self.fitness

        def fail(what: str, exc: BaseException) -> TaskError:
            given = f" (settings: {_args(settings)})" if settings else ""
            return TaskError(f"task {where}: {what} raised {describe_exception(exc)}{given}",
                             settings=settings)

        def wrong(exc: Exception) -> TaskError:  # what came back, not where: the task's
            given = f" (settings: {_args(settings)})" if settings else ""
            return TaskError(f"task {where}: {exc}{given}", settings=settings)

        def guarded_setup(rng: np.random.Generator) -> Blackboard:
            try:
                bb = setup(rng)
            except KeyboardInterrupt:
                raise
            except BaseException as exc:
                raise fail("setting up the world", exc) from exc
            try:
                return _blackboard(bb)
            except TypeError as exc:
                raise wrong(exc) from None

        def guarded_fitness(outcome: str, bb: Blackboard, steps: int) -> float:
            try:
                value = fitness(outcome, bb, steps)
            except KeyboardInterrupt:
                raise
            except BaseException as exc:
                raise fail("its fitness", exc) from exc
            try:
                return _number(value, self.name)
            except (TypeError, ValueError) as exc:
                raise wrong(exc) from None

        return replace(self, setup=guarded_setup, fitness=guarded_fitness)

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


def skill_fault(exc: BaseException) -> bool:
    """``catch`` for :func:`trials`: true for what a skill stops its run with that is not an
    error (``sys.exit()``, ``GeneratorExit``, another ``BaseException``), so that the run ends
    in ``error`` as when a skill raises one; false for a Ctrl-C (``KeyboardInterrupt``) and
    for errors, which only the world's setup or the fitness let through (an error a skill
    raises ends its run in ``error`` already)."""
    return not isinstance(exc, (Exception, KeyboardInterrupt))


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
    except KeyboardInterrupt:  # a Ctrl-C: the command's to handle
        raise
    except SkillcomposeError as exc:
        raise TaskError(f"task {target}: make_task({_args(settings)}): {exc}",
                        settings=settings) from exc
    except TypeError as exc:
        raise TaskError(
            f"task {target}: make_task() rejected settings {dict(settings)}: {exc}",
            settings=settings,
        ) from exc
    except BaseException as exc:  # the task's own code failed (or exited): say where
        raise TaskError(
            f"task {target}: make_task({_args(settings)}) raised {describe_exception(exc)}",
            settings=settings,
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
        if isinstance(val, float) and not math.isfinite(val):
            raise TaskError(f"task setting {item!r}: {v!r} is not a finite number; give a "
                            "number within about ±1.8e308 (no inf, no nan)")
        if v.lower() in ("true", "false"):
            val = v.lower() == "true"
        out[k.strip()] = val
    return out
