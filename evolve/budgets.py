"""A run's budgets: generations, genome evaluations and episodes, and what ends a run.

Every budget holds at once; a run stops at whichever comes first, or when it is solved
(:func:`stop_reason`). What counts:

- ``generations``: the index of the last generation evaluated (0 is the first).
- ``evaluations`` (``max_evaluations``): genomes evaluated to rank them, one per job the
  evaluator runs; an elite kept, a cache hit or a genome's second copy in a generation cost
  none, a cache refresh costs one. Confirmations and holds tests are not evaluations.
- ``episodes`` (``max_episodes``): the episodes of evaluations, confirmations and holds
  tests (``RunState.evaluations``, the name older runs gave it). Simplification and the
  final fresh check of the exported FSA, a measurement after the search, are outside it.

A budget is never overrun. A generation is evaluated whole or not at all: when the next one
could overrun a budget, it is bred apart first, its jobs counted and, if they do not fit,
the breeding undone (:func:`next_generation`), so the run's state is that of its last
generation and an extended run breeds the same one. The checks of a generation that reached
the target run only when the most episodes they can take fit; else the run stops before them
(``RunState.checks_pending``) and an extended run runs them first. Either way the run is the
one an uninterrupted run to the larger budget gives.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

from skillcompose.stats import SequentialRateTest

from .breeding import breed, next_size
from .generation import cost
from .genome import Genome
from .holds import required_rate
from .solution_checks import HOLDS_CANDIDATES, holds_candidates
from .state import RunState

__all__ = ["BUDGETS", "checks_due", "checks_episodes", "next_generation", "overrun",
           "stop_reason"]

BUDGETS = ("generations", "evaluations", "episodes")
"""The budgets' names, as ``stopped_by`` and ``RunState.budget_use`` give them."""


def overrun(run: RunState, evaluations: int, episodes: int) -> str | None:
    """The budget that ``evaluations`` and ``episodes`` more would overrun, else None."""
    cfg = run.cfg
    if cfg.max_evaluations is not None and \
            run.genome_evaluations + evaluations > cfg.max_evaluations:
        return "evaluations"
    if cfg.max_episodes is not None and run.evaluations + episodes > cfg.max_episodes:
        return "episodes"
    return None


def _most(run: RunState) -> tuple[int, int]:
    """The most evaluations and episodes a generation can take: every individual a job."""
    cfg = run.cfg
    trials = max(run.trials, cfg.cache_refresh) if cfg.cache else run.trials
    size = next_size(run)  # larger than the population when the next one restarts
    return size, size * trials


class _Undo:
    """What breeding a generation changes in a run, to put back."""

    def __init__(self, run: RunState) -> None:
        self.rng = run.rng.bit_generator.state
        self.kept: dict[str, Any] = {
            "population": run.population, "generation": run.generation,
            "next_uid": run.next_uid, "elite_fitness": run.elite_fitness,
            "island_best": list(run.island_best), "restarts": run.restarts}

    def __call__(self, run: RunState) -> None:
        run.rng.bit_generator.state = self.rng
        for name, value in self.kept.items():
            setattr(run, name, value)


def _counted(run: RunState, fitness: list[float], undo_always: bool) -> str | None:
    """Breed the next generation whole and count its jobs: the budget it would overrun (its
    breeding undone), else None (undone too when ``undo_always``)."""
    undo = _Undo(run)
    for _ in breed(run, fitness):
        pass
    over = overrun(run, *cost(run))
    if over is not None or undo_always:
        undo(run)
    return over


def next_generation(
    run: RunState, fitness: list[float], bred: Callable[[], None] | None = None
) -> tuple[Iterator[Genome] | None, str | None]:
    """The next generation, as :func:`~skillcompose.evolve.breeding.breed` gives it child by
    child (``None``: it is bred already, evaluate the population), or the budget it would
    overrun (then nothing is bred). Far from the budgets it streams; near them it is bred
    whole and counted first (the same children either way); ``bred`` is called once it is
    (to save a checkpoint)."""
    if overrun(run, *_most(run)) is None:
        return breed(run, fitness, bred), None
    over = _counted(run, fitness, undo_always=False)
    if over is None and bred is not None:
        bred()
    return None, over


def checks_due(run: RunState) -> bool:
    """Whether the last generation's best at the target is to be confirmed or tested for
    holding before the run is called solved."""
    assert run.best is not None
    cfg = run.cfg
    return run.task.solved(run.best[1]) and bool(
        cfg.confirm_trials or (cfg.require_holds and not run.fault_totals.lost))


def checks_episodes(run: RunState, fitness: list[float]) -> int:
    """The most episodes the last generation's confirmations and holds tests can take:
    each candidate failing, each holds test running to its last look."""
    cfg, task = run.cfg, run.task
    most = 0
    if cfg.confirm_trials:
        trials = 1 if task.deterministic else cfg.confirm_trials
        keys = {run.population[i].key() for i, f in enumerate(fitness) if task.solved(f)}
        tries = min(cfg.confirm_candidates, len(keys - set(run.confirm_failed))) \
            if cfg.confirm_candidates else 1
        most += tries * trials
    if cfg.require_holds and not run.fault_totals.lost:
        test = SequentialRateTest(required_rate(task, cfg), confidence=cfg.holds_confidence,
                                  max_episodes=cfg.holds_max_episodes,
                                  deterministic=task.deterministic)
        tries = min(HOLDS_CANDIDATES, len(holds_candidates(run, fitness)))
        most += tries * 2 * test.max_episodes  # as evolved, then as exported
    return most


def stop_reason(run: RunState, fitness: list[float] | None) -> str | None:
    """What ends a run that has evaluated its generation (``fitness``) before it goes on:
    ``"solved"``, or the budget that its next step (the pending checks, else the next
    generation) would overrun; None: it goes on. Changes nothing."""
    if fitness is None:
        return None
    if run.checks_pending:
        return overrun(run, 0, checks_episodes(run, fitness))
    assert run.best is not None
    if run.task.solved(run.best[1]):
        return "solved"
    if run.generation >= run.cfg.generations:
        return "generations"
    if overrun(run, *_most(run)) is None:
        return None
    return _counted(run, fitness, undo_always=True)
