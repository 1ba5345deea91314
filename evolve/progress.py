"""A run's progress on a stream: a live line on a terminal, a line every 5 s otherwise."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, TextIO

if TYPE_CHECKING:
    from .result import GenerationRecord
    from .state import RunState

__all__ = ["Progress"]


class Progress:
    """Shows a run's generations on ``stream`` (None: nowhere): a tqdm line on a terminal,
    else a line of the same text every 5 s and one for the last generation."""

    def __init__(self, stream: TextIO | None) -> None:
        self.stream = stream
        self._bar: Any = None  # a tqdm bar on a terminal
        self._last_line = -math.inf  # wall time of the last progress line (not a terminal)

    def show(self, run: RunState, rec: GenerationRecord, final: bool = False) -> None:
        """What is known: generations done (of the budget), their rate, the best fitness and
        size, evaluations/s, and the faults so far. No time to the end: a run stops when it
        solves the task, which nobody can foresee (the budget only bounds it)."""
        if self.stream is None or (final and self._last_line == rec.wall_time):
            return
        from tqdm import tqdm

        done = len(run.history)
        # the best evaluation so far, which never goes back (the run's own best may: a
        # candidate that fails its confirmation or holds test is demoted)
        bests = [r.best for r in run.history if not math.isnan(r.best)] or [rec.best]
        so_far = min(bests) if run.task.minimize else max(bests)
        postfix = (f"best {so_far:.4g} (this generation {rec.best:.4g}, size "
                   f"{rec.best_size}), {rec.evals_per_s:,.0f} evals/s")
        faults = run.fault_totals.describe()
        if faults:
            postfix += f", faults: {faults}"
        desc = f"gen {rec.generation}/{run.cfg.generations}"
        cfg = run.cfg
        if cfg.max_evaluations is not None:
            desc += f", evals {run.genome_evaluations:,}/{cfg.max_evaluations:,}"
        if cfg.max_episodes is not None:
            desc += f", episodes {run.evaluations:,}/{cfg.max_episodes:,}"
        if getattr(self.stream, "isatty", lambda: False)():
            if self._bar is None:
                self._bar = tqdm(
                    total=None, initial=done, unit="gen", file=self.stream,
                    dynamic_ncols=True, leave=True, desc=desc, postfix=postfix,
                    bar_format="{desc}: {elapsed}, {rate_fmt}{postfix}",
                )
            else:
                self._bar.set_description_str(desc, refresh=False)
                self._bar.set_postfix_str(postfix, refresh=False)
                self._bar.update(1)
        elif rec.wall_time - self._last_line >= 5.0 or final:  # a log: a line per 5 s
            self._last_line = rec.wall_time
            rate = done / rec.wall_time if rec.wall_time > 0 else 0.0
            line = tqdm.format_meter(
                done, None, rec.wall_time, prefix=desc, unit="gen", rate=rate,
                bar_format="{desc}: {elapsed}, {rate_fmt}{postfix}", postfix=postfix,
            )
            self.stream.write(line + "\n")
            self.stream.flush()

    def bred(self, run: RunState) -> None:
        """A listener of the loop (:mod:`skillcompose.evolve.listeners`): nothing to show."""

    def generation(self, run: RunState, rec: GenerationRecord) -> None:
        self.show(run, rec)

    def close(self, run: RunState) -> None:
        if self._bar is None and run.history:  # a log ends with the last generation
            self.show(run, run.history[-1], final=True)
        if self._bar is not None:
            self._bar.close()
            self._bar = None
