"""Episodes: one FSA run on one seeded world of a task, as ``skillcompose run`` makes it.

The episode of seed ``k`` is trial 0 of ``SeedSequence(k)`` in the task's trial loop
(:meth:`~skillcompose.task.Task.each_trial`): the world its ``setup`` draws, the run, the
score. So ``skillcompose run FILE --task TASK --seed k --trace`` shows the same episode, step
for step. As on the command line, a skill that raises or exits ends its episode in ``error``
(scored as the task's worst), and the task's own setup or fitness failing stops the caller
with a :class:`~skillcompose.task.TaskError` naming the task.
"""

from __future__ import annotations

import os
import shlex
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from ..blackboard import Blackboard
from ..display import trace_lines
from ..executor import CompiledFSA, RunResult, TraceStep, error_summary, trial_rngs
from ..fsa import FSA
from ..fsafile import load_fsa
from ..limits import MAX_SEED
from ..task import Task, skill_fault

__all__ = ["Episode", "FSALike", "compile_for", "episode_world", "run_episode", "run_episodes"]

FSALike = FSA | str | os.PathLike[str]
"""An FSA, or the path of its file."""


@dataclass(frozen=True)
class Episode:
    """One run of an FSA on the world of ``seed``: how it ended, its fitness, whether that
    reaches the task's target, and the blackboard it ended with (None when it is not kept)."""

    seed: int
    result: RunResult
    fitness: float
    success: bool
    fsa: str
    task: str
    backend: str
    blackboard: Blackboard | None = None
    rerun: str = ""
    """The command line that shows this episode, when the FSA is a file (else empty)."""

    @property
    def outcome(self) -> str:
        return self.result.outcome

    @property
    def steps(self) -> int:
        return self.result.steps

    @property
    def trace(self) -> tuple[TraceStep, ...] | None:
        return self.result.trace

    def headline(self) -> str:
        """``seed 3: failure after 2 step(s), fitness 10 (not at the target)``."""
        reached = "at the target" if self.success else "not at the target"
        return (f"seed {self.seed}: {self.outcome} after {self.steps} step(s), fitness "
                f"{self.fitness:g} ({reached})")

    def describe(self) -> str:
        """The headline, the error when a skill raised, and the trace (when traced), as
        ``skillcompose run --trace`` prints it."""
        lines = [self.headline()]
        if self.result.error is not None:
            lines.append(f"state {self.result.last_state} raised: "
                         f"{error_summary(self.result.error)}")
        if self.result.trace is not None:
            lines += trace_lines(self.result)
        if self.rerun:
            lines.append(f"rerun: {self.rerun}")
        return "\n".join(lines)


def compile_for(fsa: FSALike, task: Task, backend: str | None = None) -> CompiledFSA:
    """``fsa`` (or the file at that path) compiled for ``task``, as ``skillcompose run
    --task`` compiles it: the task's skills, its step limit, its backend unless ``backend``."""
    if isinstance(fsa, (str, os.PathLike)):
        fsa = load_fsa(fsa)
    if not isinstance(fsa, FSA):
        raise TypeError(f"expected an FSA or the path of its file, got {type(fsa).__name__}")
    if not isinstance(task, Task):
        raise TypeError(f"expected a Task (load_task('module') or make_task()), got "
                        f"{type(task).__name__}")
    return task.compile(fsa, backend)


def check_seed(seed: object) -> int:
    """``seed`` when it is a whole number from 0 to 2**63 - 1; else a ValueError."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or \
            not 0 <= int(seed) <= MAX_SEED:
        raise ValueError(f"seed {seed!r}: expected a whole number from 0 to {MAX_SEED}")
    return int(seed)


def run_episodes(
    fsa: FSALike, task: Task, seeds: Iterable[int], *, backend: str | None = None,
    trace: bool = False, keep_blackboard: bool = False,
) -> Iterator[Episode]:
    """The episodes of ``fsa`` on ``task``, one per seed, made as they are asked for (a
    caller may stop early). ``trace``: record every step of each; ``keep_blackboard``: keep
    each episode's final blackboard."""
    compiled = compile_for(fsa, task, backend)
    guarded = task.guarded()
    command = _rerun_command(fsa, task, backend)
    for seed in seeds:
        k = check_seed(seed)
        (trial,) = guarded.each_trial(compiled, np.random.SeedSequence(k), 1,
                                      trace_first=trace, catch=skill_fault)
        yield Episode(k, trial.result, trial.fitness, task.solved(trial.fitness),
                      compiled.fsa.name or "(unnamed)", task.name, compiled.backend,
                      trial.blackboard if keep_blackboard else None,
                      f"{command} --seed {k} --trace" if command else "")


def run_episode(
    fsa: FSALike, task: Task, seed: int = 0, *, backend: str | None = None, trace: bool = True,
) -> Episode:
    """The episode of ``seed`` (traced unless ``trace=False``), with its final blackboard."""
    (episode,) = run_episodes(fsa, task, (seed,), backend=backend, trace=trace,
                              keep_blackboard=True)
    return episode


def episode_world(task: Task, seed: int = 0) -> Blackboard:
    """The world the episode of ``seed`` starts from: what the task's ``setup`` draws with
    that episode's generator (the same numbers a run of that seed sees first)."""
    return task.guarded().setup(next(trial_rngs(check_seed(seed), 1)))


def _rerun_command(fsa: FSALike, task: Task, backend: str | None) -> str:
    """``skillcompose run FILE --task MODULE [--set k=v ...] [--backend B]``, when the FSA is
    a file (an FSA object may have been edited since it was read) and the task comes from a
    module; else empty."""
    if not isinstance(fsa, (str, os.PathLike)) or task.ref is None:
        return ""
    words = ["skillcompose", "run", os.fspath(fsa), "--task", task.ref.module]
    for name, value in task.ref.settings.items():
        words += ["--set", f"{name}={value}"]
    if backend:
        words += ["--backend", backend]
    return " ".join(shlex.quote(w) for w in words)
