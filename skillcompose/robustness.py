"""Robustness analysis: run one FSA many times under a sweep of a task setting.

The paper's figures 7 and 12 run an evolved FSA 5000 times for each failure probability
from 0 to 1 and plot the mean fitness with standard-deviation bars. :func:`robustness_sweep`
does that for any FSA and any task module with a numeric setting (``p_fail`` by default)::

    from skillcompose.robustness import robustness_sweep, write_csv, plot_sweep

    rows = robustness_sweep("examples/pour_water_reference.fsa.yaml", "examples.pour_water",
                            p_fail=[0.0, 0.25, 0.5], reps=1000, seed=0, workers=2)
    write_csv(rows, "robustness.csv")
    plot_sweep(rows, "robustness.png")

and ``skillcompose robustness FILE --task T --p-fail 0:1:21 --reps 5000 -o fig.png`` from the
command line.

How it runs:

- Each sweep point rebuilds the task with ``make_task(**settings, p_fail=value)`` (its
  :class:`~skillcompose.task.TaskRef`), in the calling process or in worker processes.
- Repetition ``r`` uses the generator of ``SeedSequence(seed).spawn(reps)[r]`` at *every*
  point (common random numbers): the curve is smooth, a point's numbers do not depend on
  which other points are swept, and the table is identical for any number of workers.
- The FSA runs with the task's ``step_limit`` (as in evolution and ``skillcompose run
  --task``; the file's own applies only without a task) unless ``step_limit`` is given.
- ``std`` is the sample standard deviation (``ddof=1``) of the fitness over the repetitions.
"""

from __future__ import annotations

import csv
import itertools
import math
import os
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .errors import SkillcomposeError, clip
from .fsa import ERROR, FSA, TIMEOUT

if TYPE_CHECKING:
    import numpy as np

    from .task import Task, TaskRef

# numpy and the runtime (executor, files, tasks) are imported where they are used, so that
# registering the `robustness` subcommand (which `skillcompose --help` does) stays cheap.

__all__ = [
    "MAX_SWEEP_POINTS",
    "RobustnessError",
    "SweepRow",
    "format_table",
    "parse_values",
    "plot_sweep",
    "robustness_sweep",
    "table",
    "write_csv",
]


MAX_SWEEP_POINTS = 1000
"""The most values one sweep may have."""


class RobustnessError(SkillcomposeError, ValueError):
    """A robustness sweep cannot run as asked (bad values, reps, workers or task)."""


@dataclass(frozen=True)
class SweepRow:
    """The statistics of ``reps`` runs at one value of the swept setting."""

    setting: str
    value: float
    reps: int
    mean: float
    std: float
    min: float
    max: float
    mean_steps: float
    solved: int
    outcomes: Mapping[str, int] = field(default_factory=dict)

    @property
    def solved_rate(self) -> float:
        """Fraction of the runs whose fitness reached the task's target (``task.solved``):
        for pouring water, the water is in the glass. A run can end in ``success`` without
        solving the task when an FSA routes an outcome straight to the terminal."""
        return self.solved / self.reps

    def rate(self, outcome: str) -> float:
        """Fraction of the runs that ended in ``outcome``."""
        return self.outcomes.get(outcome, 0) / self.reps

    @property
    def success_rate(self) -> float:
        return self.rate("success")

    @property
    def timeout_rate(self) -> float:
        return self.rate(TIMEOUT)


# -- the sweep -----------------------------------------------------------------------------
def robustness_sweep(
    fsa: FSA | str | os.PathLike[str],
    task: str | Task,
    p_fail: Iterable[float],
    *,
    reps: int = 5000,
    seed: int = 0,
    workers: int = 1,
    setting: str = "p_fail",
    settings: Mapping[str, Any] | None = None,
    backend: str | None = None,
    step_limit: int | None = None,
    progress: bool = True,
    skills: Sequence[str] = (),
) -> list[SweepRow]:
    """Run ``fsa`` ``reps`` times at each value of the task setting ``setting``.

    - ``fsa``: an FSA or the path of an FSA file.
    - ``task``: a task module (dotted name or ``.py`` path), or a :class:`Task` made by
      :func:`~skillcompose.task.load_task` (it knows how to rebuild itself).
    - ``p_fail``: the values of ``setting`` to sweep (the failure probability by default).
    - ``settings``: the task's other settings, kept fixed.
    - ``workers``: processes; the rows are the same for any number.
    - ``skills``: modules and FSA files whose skills to add to the task's (nested FSAs, as
      ``--skills`` gives them), loaded in every worker.
    - ``progress``: a progress bar on a terminal (see :func:`~skillcompose.progress.progress_bar`).

    Returns one :class:`SweepRow` per value, in the order given.
    """
    import numpy as np

    from .executor import compile_fsa
    from .fsafile import load_fsa
    from .progress import progress_bar

    values = [_check_value(v, setting) for v in p_fail]
    if not values:
        raise RobustnessError(f"no values of {setting} to sweep; give at least one")
    for what, count, low in (("reps", reps, 1), ("workers", workers, 1), ("seed", seed, 0)):
        if isinstance(count, bool) or not isinstance(count, int) or count < low:
            raise RobustnessError(f"{what}={count!r} must be a whole number >= {low}")
    ref = _task_ref(task, settings)
    machine = fsa if isinstance(fsa, FSA) else load_fsa(fsa)
    if step_limit is not None:
        machine = machine.replace(step_limit=step_limit)
    # Compile once here so that an FSA that does not fit the task fails before any work
    # (with its file's lines and columns in the error).
    skills = tuple(str(s) for s in skills)
    first = _build(ref, setting, values[0], skills)
    compile_fsa(machine, first.registry, backend or first.backend)
    machine = machine.replace(source=None)  # plain data, cheap to send to workers

    jobs = [
        _Chunk(machine, ref, setting, v, backend, seed, start, stop, step_limit is None,
               skills)
        for v in values
        for start, stop in _chunks(reps, workers, len(values))
    ]
    parts = []
    with ExitStack() as stack:
        bar = stack.enter_context(progress_bar(len(values) * reps, "run", f"sweep of {setting}",
                                               disable=not progress))
        run = map if workers == 1 or len(jobs) == 1 else \
            stack.enter_context(ProcessPoolExecutor(min(workers, len(jobs)))).map
        try:
            for job, part in zip(jobs, run(_run_chunk, jobs), strict=True):
                parts.append(part)
                bar.update(job.stop - job.start)
        except BrokenProcessPool:
            raise RobustnessError(
                f"a worker process running task {first.name} died in the sweep of {setting} "
                "(os._exit in the task or a skill, a crash in C code, or the out-of-memory "
                "killer); nothing was measured"
            ) from None

    rows = []
    per_value = len(jobs) // len(values)
    for k, v in enumerate(values):
        mine = parts[k * per_value:(k + 1) * per_value]
        fit = np.concatenate([p[0] for p in mine])
        steps = np.concatenate([p[1] for p in mine])
        counts = sum((p[2] for p in mine), Counter[str]())
        with np.errstate(invalid="ignore", over="ignore"):  # a run in error scores inf
            mean, std = float(np.mean(fit)), float(np.std(fit, ddof=1)) if reps > 1 else 0.0
        rows.append(SweepRow(
            setting=setting, value=v, reps=reps, mean=mean, std=std, min=float(np.min(fit)),
            max=float(np.max(fit)), mean_steps=float(np.mean(steps)),
            solved=sum(p[3] for p in mine), outcomes=dict(sorted(counts.items())),
        ))
    return rows


@dataclass(frozen=True)
class _Chunk:
    fsa: FSA
    ref: TaskRef
    setting: str
    value: float
    backend: str | None
    seed: int
    start: int
    stop: int
    task_step_limit: bool = True  # the task's step limit, not the FSA's (not overridden)
    skills: tuple[str, ...] = ()  # modules and FSA files added to the task's skills


def _run_chunk(job: _Chunk) -> tuple[np.ndarray, np.ndarray, Counter[str], int]:
    """Repetitions ``start..stop-1`` at one value: fitness, steps, outcome counts, solved."""
    import numpy as np

    from .executor import compile_fsa
    from .task import skill_fault

    task = _build(job.ref, job.setting, job.value, job.skills)
    compiled = task.compile(job.fsa, job.backend) if job.task_step_limit else \
        compile_fsa(job.fsa, task.registry, job.backend or task.backend)
    n = job.stop - job.start
    fit, steps, counts = np.empty(n), np.empty(n, dtype=np.int64), Counter[str]()
    # a skill that exits ends its run in error; the task's own setup or fitness failing
    # stops the sweep with a TaskError naming it
    runs = task.guarded().each_trial(compiled, job.seed, n, start=job.start, catch=skill_fault)
    for k, (_, result, _, f) in enumerate(runs):
        fit[k], steps[k] = f, result.steps
        counts[result.outcome] += 1
    return fit, steps, counts, sum(task.solved(f) for f in fit.tolist())


def _chunks(reps: int, workers: int, points: int) -> list[tuple[int, int]]:
    """Split ``reps`` so that the points times their chunks keep ``workers`` busy."""
    if workers == 1:
        return [(0, reps)]
    per_point = max(1, min(reps // 500 or 1, math.ceil(4 * workers / points)))
    bounds = [k * reps // per_point for k in range(per_point + 1)]
    return [(a, b) for a, b in itertools.pairwise(bounds) if b > a]


def _build(ref: TaskRef, setting: str, value: float, skills: Sequence[str] = ()) -> Task:
    from .task import TaskRef

    task = TaskRef(ref.module, {**ref.settings, setting: value}).build()
    if skills:
        task.registry.load_modules(skills)
    return task


def _task_ref(task: str | Task, settings: Mapping[str, Any] | None) -> TaskRef:
    from .task import Task, TaskRef

    if isinstance(task, str):
        return TaskRef(task, dict(settings or {}))
    if isinstance(task, Task):
        if task.ref is None:
            raise RobustnessError(
                f"task {task.name!r} cannot be rebuilt for each sweep point: it was not made "
                "by load_task(); pass the task module's name instead, e.g. "
                "robustness_sweep(fsa, 'examples.pour_water', ...)"
            )
        return TaskRef(task.ref.module, {**task.ref.settings, **(settings or {})})
    raise RobustnessError(
        f"task must be a task module name or a Task, got {type(task).__name__}"
    )


def _check_value(v: Any, setting: str) -> float:
    import numpy as np

    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or \
            not math.isfinite(float(v)):
        raise RobustnessError(f"sweep value {v!r} of {setting} must be a finite number")
    return float(v)


def parse_values(text: str) -> list[float]:
    """``"0:1:21"`` → 21 evenly spaced values from 0 to 1 inclusive; ``"0,0.2,0.5"`` → those.

    Raises :class:`RobustnessError` with the accepted forms on anything else.
    """
    import numpy as np

    forms = (f"write START:STOP:COUNT (e.g. 0:1:21) or a comma-separated list (e.g. "
             f"0,0.2,0.5) of finite numbers, at most {MAX_SWEEP_POINTS} values")
    text = text.strip()
    shown = clip(text)
    try:
        if ":" in text:
            parts = text.split(":")
            if len(parts) != 3 or len(parts[2].strip()) > 12:
                raise ValueError(text)
            start, stop, count = float(parts[0]), float(parts[1]), int(parts[2])
            if not (1 <= count <= MAX_SWEEP_POINTS and math.isfinite(start)
                    and math.isfinite(stop)):
                raise ValueError(text)
            if count == 1:
                return [start]
            return [round(float(v), 12) for v in np.linspace(start, stop, count)]
        values = [float(p) for p in text.split(",", MAX_SWEEP_POINTS) if p.strip()]
        if len(values) > MAX_SWEEP_POINTS or not all(math.isfinite(v) for v in values):
            raise ValueError(text)
    except ValueError:
        raise RobustnessError(f"cannot read the sweep {shown!r}; {forms}") from None
    if not values:
        raise RobustnessError(f"the sweep {shown!r} has no values; {forms}")
    return values


# -- output --------------------------------------------------------------------------------
_FIRST_OUTCOMES = ("success", "failure", TIMEOUT, ERROR)


def table(rows: Sequence[SweepRow]) -> tuple[list[str], list[list[str]]]:
    """Header and formatted cells of the CSV table."""
    if not rows:
        raise RobustnessError("no rows to write")
    rest = {o for r in rows for o in r.outcomes} - set(_FIRST_OUTCOMES)
    outs = [*_FIRST_OUTCOMES, *sorted(rest)]
    header = [rows[0].setting, "reps", "mean", "std", "min", "max", "mean_steps", "solved_rate"]
    header += [f"{o}_rate" for o in outs]
    body = [[f"{r.value:.10g}", str(r.reps),
             *(f"{x:.6g}" for x in (r.mean, r.std, r.min, r.max, r.mean_steps, r.solved_rate)),
             *(f"{r.rate(o):.6g}" for o in outs)] for r in rows]
    return header, body


def write_csv(rows: Sequence[SweepRow], path: str | os.PathLike[str]) -> Path:
    """Write the sweep as CSV: the setting, reps, mean, std, min, max, mean_steps,
    solved_rate, and the rate of each outcome (success, failure, timeout, error, then any
    other)."""
    header, body = table(rows)
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with p.open("w", newline="", encoding="utf-8") as f:
        csv.writer(f).writerows([header, *body])
    return p


def format_table(rows: Sequence[SweepRow]) -> str:
    """The table as aligned text, for a terminal."""
    header, body = table(rows)
    keep = [0, 1, 2, 3, 6, *range(7, len(header))]  # leave min and max to the CSV
    cols = [[header[i], *[b[i] for b in body]] for i in keep]
    widths = [max(len(c) for c in col) for col in cols]
    return "\n".join("  ".join(col[k].rjust(w) for col, w in zip(cols, widths, strict=True))
                     for k in range(len(body) + 1))


def plot_sweep(
    rows: Sequence[SweepRow], path: str | os.PathLike[str], *, title: str | None = None
) -> Path:
    """Plot mean fitness with standard-deviation bars against the swept setting (figure 7),
    and the solved rate (runs that reached the task's target) on a second axis. The format
    follows the suffix (.png, .svg, .pdf).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if not rows:
        raise RobustnessError("no rows to plot")
    x = [r.value for r in rows]
    fig = Figure(figsize=(6.4, 4.2), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.errorbar(x, [r.mean for r in rows], yerr=[r.std for r in rows], fmt="o-", ms=4,
                capsize=3, color="tab:blue", label="fitness, mean ± std")
    ax.set_xlabel(f"{rows[0].setting} (failure probability of the skills)"
                  if rows[0].setting == "p_fail" else rows[0].setting)
    ax.set_ylabel(f"fitness (mean ± std of {rows[0].reps} runs)")
    ax.grid(True, alpha=0.3)
    ax2 = ax.twinx()
    ax2.plot(x, [r.solved_rate for r in rows], "s--", ms=3, color="tab:green",
             label="solved rate")
    ax2.set_ylim(-0.02, 1.02)
    ax2.set_ylabel("fraction of runs solved")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, loc="center left")
    if title:
        ax.set_title(title)
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=120)
    return p
