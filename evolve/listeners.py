"""What happens around the generational loop, as listeners the loop calls: persistence
(the run directory's), progress (the command line's) and a caller's own callback.

The loop (:func:`skillcompose.evolve.algorithm.evolve`'s) breeds, evaluates, records and
checks; it knows nothing of files or terminals. At three moments it calls every listener
it was given, in order:

- ``bred(run)``: the generation's last child is born and its jobs are with the evaluator
  (the pool works meanwhile): the run directory writes its checkpoint here, every
  ``checkpoint_every`` generations, and redraws its plots at most every 30 s;
- ``generation(run, rec)``: the generation is evaluated and recorded: the run directory
  appends its line to ``history.jsonl`` and writes ``best.yaml`` when the best improved;
  the progress line shows it; a caller's ``on_generation`` receives ``rec``;
- ``close(run)``: the loop ends, however it ends.

Same seed, same run: listeners only read the run.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Protocol

from .export import best_fsa, header, named
from .result import GenerationRecord
from .rundir import RunDir
from .state import RunState

__all__ = ["PLOT_EVERY_S", "OnGeneration", "RunDirWriter", "RunListener"]

PLOT_EVERY_S = 30.0
"""Redraw ``best.png`` / ``fitness.png`` at checkpoints at most this often [s]."""


class RunListener(Protocol):
    """Called by the generational loop; see the module docstring."""

    def bred(self, run: RunState) -> None: ...

    def generation(self, run: RunState, rec: GenerationRecord) -> None: ...

    def close(self, run: RunState) -> None: ...


class RunDirWriter:
    """The run directory's listener: checkpoints and plots as a generation is bred, the
    history line and ``best.yaml`` as it is recorded."""

    def __init__(self, rundir: RunDir) -> None:
        self.rundir = rundir
        self._last_plot = time.perf_counter()

    def bred(self, run: RunState) -> None:
        if run.generation % run.cfg.checkpoint_every == 0:
            self.rundir.save_checkpoint(run.checkpoint())
            if time.perf_counter() - self._last_plot > PLOT_EVERY_S:  # drawing is slow
                self.rundir.plots([r.to_dict() for r in run.history],
                                  named(run, best_fsa(run)))
                self._last_plot = time.perf_counter()

    def generation(self, run: RunState, rec: GenerationRecord) -> None:
        self.rundir.append_history(rec.to_dict())
        if run.best is not None and run.best[2] == rec.generation:  # improved just now
            self.rundir.write_best(named(run, best_fsa(run)), run.task.registry, header(run))

    def close(self, run: RunState) -> None:
        pass


class OnGeneration:
    """A caller's callback (``evolve(on_generation=...)``) as a listener."""

    def __init__(self, callback: Callable[[GenerationRecord], None]) -> None:
        self.callback = callback

    def bred(self, run: RunState) -> None:
        pass

    def generation(self, run: RunState, rec: GenerationRecord) -> None:
        self.callback(rec)

    def close(self, run: RunState) -> None:
        pass
