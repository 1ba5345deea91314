"""One generation's evaluation and its record.

:func:`evaluate` makes a job for each genome the cache does not know (elites keep their
fitness, a genome twice in a generation is run once), hands the jobs to the evaluator as the
genomes are bred, and folds the results into the cache; :func:`record` takes the
generation's statistics, the run's best so far, and writes ``history.jsonl`` and, when the
best improved, ``best.yaml``.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterable, Iterator
from typing import Any

from .breeding import next_size, note_islands
from .evaluation import Evaluator, Job
from .genome import Genome
from .result import GenerationRecord
from .state import EVAL_STREAM, RunState, fold

__all__ = ["cost", "evaluate", "record"]


def _nan_safe(f: float, minimize: bool) -> float:
    return (math.inf if minimize else -math.inf) if math.isnan(f) else f


class _Jobs:
    """The jobs of generation ``g``, made as its individuals come: a job for each genome
    the cache does not know (elites keep their fitness with the cache, a genome twice in the
    generation is run once, a cached one runs ``cache_refresh`` trials when asked)."""

    def __init__(self, run: RunState, g: int) -> None:
        self.run, self.g = run, g
        self.fitness: list[float | None] = []
        self.jobs: list[Job] = []
        self.slots: list[list[int]] = []  # the individuals each job stands for
        self.keys: list[tuple[Any, ...] | None] = []
        self._by_key: dict[tuple[Any, ...], int] = {}

    def make(self, individuals: Iterable[Genome]) -> Iterator[Job]:
        run, cfg, fitness, keys = self.run, self.run.cfg, self.fitness, self.keys
        for i, ind in enumerate(individuals):
            fitness.append(None)
            keys.append(None)
            uid = ind.origin.get("uid")
            if uid in run.elite_fitness and cfg.cache and cfg.cache_refresh == 0:
                fitness[i] = run.elite_fitness[uid]
                continue
            spawn = (EVAL_STREAM, self.g) if cfg.common_random_numbers else \
                (EVAL_STREAM, self.g, i)
            trials = run.trials
            if cfg.cache:
                k = ind.key()
                keys[i] = k
                if k in self._by_key:  # the same genome twice in this generation
                    self.slots[self._by_key[k]].append(i)
                    continue
                if k in run.cache:
                    if cfg.cache_refresh == 0:
                        total, count = run.cache[k]
                        fitness[i] = total / count
                        continue
                    trials = cfg.cache_refresh
                self._by_key[k] = len(self.jobs)
            self.jobs.append(Job.of(ind, run.seed, spawn, trials))
            self.slots.append([i])
            yield self.jobs[-1]


def cost(run: RunState) -> tuple[int, int]:
    """The evaluations and episodes that evaluating the population (bred, not evaluated
    yet) will take."""
    batch = _Jobs(run, run.generation)
    jobs = list(batch.make(run.population))
    return len(jobs), sum(j.trials for j in jobs)


def evaluate(
    run: RunState, evaluator: Evaluator, bred: Iterator[Genome] | None = None
) -> tuple[list[float], int]:
    """Fitness of every individual of this generation; episodes run. ``bred`` is the
    next generation as :func:`~skillcompose.evolve.breeding.breed` makes it: each child is
    handed to the evaluator as soon as it is born, so a pool evaluates while the rest are
    bred."""
    cfg = run.cfg
    g = run.generation + 1 if bred is not None else run.generation
    batch = _Jobs(run, g)
    expected = next_size(run) if bred is not None else len(run.population)
    results = evaluator.evaluate(batch.make(bred if bred is not None else run.population),
                                 expected=expected)
    fitness, jobs, keys = batch.fitness, batch.jobs, batch.keys
    assert run.generation == g and len(fitness) == len(run.population)
    run.gen_faults = evaluator.faults
    if run.first_error is None and run.gen_faults.first_error is not None:
        run.first_error = f"in generation {g}: {run.gen_faults.first_error}"
    episodes = sum(j.trials for j in jobs)
    for job, idx, f in zip(jobs, batch.slots, results, strict=True):
        f = _nan_safe(float(f), run.task.minimize)
        if cfg.cache:
            key = keys[idx[0]]
            assert key is not None
            total, count = fold(*run.cache.get(key, (0.0, 0)), f, job.trials)
            run.cache[key] = (total, count)
            f = total / count
        for i in idx:
            fitness[i] = f
    return [float(f) for f in fitness if f is not None], episodes


def record(
    run: RunState, fitness: list[float], episodes: int, gen_time: float
) -> GenerationRecord:
    """Note the generation: its statistics, the run's best (``run.best``, with this
    generation's index when it improved), its faults and each island's progress."""
    sizes = [len(g) for g in run.population]
    bi = min(range(len(fitness)), key=lambda i: (*run.rank_key(fitness[i], sizes[i]), i))
    bf = fitness[bi]
    improved = run.best is None or run.rank_key(bf, sizes[bi]) < run.rank_key(
        run.best[1], len(run.best[0])
    )
    if improved:
        run.best = (run.population[bi].copy(), bf, run.generation)
    run.evaluations += episodes
    finite = [f for f in fitness if math.isfinite(f)] or [run.task.worst]  # none: the worst
    rec = GenerationRecord(
        generation=run.generation,
        best=float(bf),
        mean=float(statistics.fmean(finite)),
        median=float(statistics.median(finite)),
        best_size=sizes[bi],
        evaluations=episodes,
        total_evaluations=run.evaluations,
        evals_per_s=episodes / gen_time if gen_time > 0 else 0.0,
        wall_time=run.wall(),
        faults=run.gen_faults.to_dict(),
        population=len(fitness),
    )
    run.fault_totals.add(run.gen_faults)
    note_islands(run, fitness)
    run.history.append(rec)  # the run directory writes it (listeners.RunDirWriter)
    return rec
