"""Whether a solution stands before the run stops: its confirmation on fresh worlds, or the
test that its exported FSA holds.

An evaluation that reaches the task's target may be luck. With ``confirm_trials`` the best
genome (or, with ``confirm_candidates``, several genomes at the target) is run again on
fresh worlds (:func:`confirm`); with ``require_holds`` the FSA the run would export must
hold at the required rate on fresh episodes (:func:`holds`). A genome that fails is demoted
(:func:`demote`): its fitness, in the population and the cache, takes the failed check's
mean, and it is never checked again.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from skillcompose import FSA
from skillcompose.stats import SequentialRateTest
from skillcompose.task import Task

from .evaluation import Faults, Guard, error_summary, iter_episodes
from .export import ExportSettings, make_export
from .genome import Genome, GenomeCompiler
from .holds import FreshCheck, holds_test, required_rate
from .state import CONFIRM_STREAM, RunState, fold

__all__ = ["HOLDS_CANDIDATES", "confirm", "confirm_candidates", "confirmation", "demote", "holds",
           "holds_candidates", "holds_check"]

HOLDS_CANDIDATES = 3  # genomes at the target whose FSA is tested for holding, a generation


def confirm(run: RunState, fitness: list[float]) -> bool:
    """Re-run the best genome on ``confirm_trials`` fresh worlds; it stays the best (and
    the task solved) only if it reaches the target there too (its mean, or, with
    ``confirm_rate``, that share of the episodes), else its fitness becomes that measured
    mean and evolution goes on. With ``confirm_feedback`` a genome that fails also takes,
    in ``fitness`` (this generation's, which breeds the next) and in the cache, the mean
    of its evaluation's and its confirmation's episodes, wherever it is in the
    population."""
    assert run.best is not None
    if run.cfg.confirm_candidates:
        return confirm_candidates(run, fitness)
    g, evaluated, gen = run.best
    # By share: the same worlds for every confirmation of the run, so that an FSA (or a
    # neutral variant of it) re-confirmed generation after generation cannot pass by
    # drawing a lucky sample at last. By mean: fresh worlds each generation (as before).
    passed, mean, trials = confirmation(
        run, g, (CONFIRM_STREAM,) if run.cfg.confirm_rate > 0.0 else
        (CONFIRM_STREAM, run.generation))
    if passed:
        return True
    run.best = (g, mean, gen)
    if run.cfg.confirm_feedback:
        demote(run, g, fitness, evaluated, mean, trials)
    return False


def confirmation(run: RunState, g: Genome, worlds: tuple[int, ...]) -> tuple[bool, float, int]:
    """Run ``g`` on the ``confirm_trials`` worlds drawn from ``worlds`` (one world on a
    deterministic task): whether it passes (its mean at the target, or, with
    ``confirm_rate``, that share of the episodes), its mean, and the episodes run.

    Each episode runs under ``eval_time_limit`` on its own (as a holds test's do), so a
    confirmation of many slow episodes is not cut off as a whole; an episode that raises
    or runs past the limit scores the task's worst fitness and is counted in the run's
    faults (:attr:`RunState.check_faults`)."""
    task, rate = run.task, run.cfg.confirm_rate
    trials = 1 if task.deterministic else run.cfg.confirm_trials
    got = run.check(confirmation_episodes, g, run.seed, worlds, trials,
                    run.cfg.eval_time_limit)
    if got is None:  # the check killed the process running it: worst (counted by check)
        scores = [task.worst] * trials
    else:
        scores, faults = got
        run.note_check_faults(faults)
    run.evaluations += trials
    mean = sum(scores) / trials
    if rate > 0.0 and not task.deterministic:
        return sum(map(task.solved, scores)) >= rate * trials, mean, trials
    return task.solved(mean), mean, trials


def confirmation_episodes(
    task: Task, compiler: GenomeCompiler, g: Genome, seed: int, worlds: tuple[int, ...],
    trials: int, time_limit: float | None,
) -> tuple[list[float], Faults]:
    """The episodes of a confirmation (:func:`confirmation`): ``g``'s fitness on ``trials``
    worlds of the stream ``worlds`` of ``seed``, and their faults. The same wherever it
    runs (:mod:`.isolated`)."""
    scores: list[float] = []
    faults = Faults()
    seq = np.random.SeedSequence(seed, spawn_key=worlds)
    try:
        compiled = compiler.compile(g)
    except Exception as exc:  # the genome compiled for its evaluation; a skill's factory
        scores = [task.worst] * trials  # that fails now fails every episode
        faults.raised, faults.first_error = trials, error_summary(exc)
    else:
        with Guard(time_limit) as guard:
            for f, code in iter_episodes(task, compiled, seq, trials, guard):
                faults.add_episode(code)
                scores.append(f)
    return scores, faults


def confirm_candidates(run: RunState, fitness: list[float]) -> bool:
    """``confirm_candidates``: confirm up to that many genomes of the population at the
    target, the most tested first, each on fresh worlds of its own, skipping those that
    failed before, until one passes; it becomes the best. Else the run's best takes the
    last failed confirmation's mean (evolution goes on)."""
    assert run.best is not None
    cfg, task = run.cfg, run.task
    sizes = [len(x) for x in run.population]
    keys = [x.key() for x in run.population]

    def tested(i: int) -> int:
        return run.cache.get(keys[i], (0.0, 0))[1]

    order = sorted((i for i, f in enumerate(fitness) if task.solved(f)),
                   key=lambda i: (*run.rank_key(fitness[i], sizes[i]), -tested(i), i))
    tried: set[tuple[Any, ...]] = set()
    for i in order:
        key = keys[i]
        if key in run.confirm_failed or key in tried:
            continue
        if len(tried) == cfg.confirm_candidates:
            break
        g = run.population[i]
        passed, mean, trials = confirmation(
            run, g, (CONFIRM_STREAM, run.generation, len(tried)))
        tried.add(key)
        if passed:
            run.best = (g.copy(), fitness[i], run.generation)
            return True
        run.confirm_failed[key] = mean
        run.best = (g.copy(), mean, run.generation)
        if cfg.confirm_feedback:
            demote(run, g, fitness, fitness[i], mean, trials)
    if not tried:  # every genome at the target failed a confirmation before
        g, _, gen = run.best
        run.best = (g, run.confirm_failed.get(g.key(), task.worst), gen)
    return False


def holds_candidates(run: RunState, fitness: list[float]) -> list[tuple[Genome, float, int]]:
    """The genomes at the target a holds test would try, in order (the run's best first,
    then the population's by rank), each once, none that failed before: (genome, fitness,
    generation found)."""
    assert run.best is not None
    task = run.task
    sizes = [len(x) for x in run.population]
    order = sorted((i for i, f in enumerate(fitness) if task.solved(f)),
                   key=lambda i: (*run.rank_key(fitness[i], sizes[i]), i))
    candidates = [run.best] + [(run.population[i], fitness[i], run.generation)
                               for i in order]
    seen: set[tuple[Any, ...]] = set()
    out = []
    for g, f, gen in candidates:
        key = g.key()
        if task.solved(f) and key not in seen and key not in run.holds_failed:
            seen.add(key)
            out.append((g, f, gen))
    return out


def holds(run: RunState, fitness: list[float]) -> bool:
    """``require_holds``: test the genomes at the target (the run's best first, then the
    population's by rank), skipping those that failed before, up to
    ``HOLDS_CANDIDATES`` a generation, until one holds; it becomes the best. A genome
    that fails is demoted to the mean of its test's episodes and never tested again."""
    for k, (g, f, gen) in enumerate(holds_candidates(run, fitness)[:HOLDS_CANDIDATES]):
        check = holds_check(run, g, k)
        if check.passed:
            run.best = (g.copy(), f, gen)
            run.holds_passed = {"generation": run.generation,
                                "fresh": check.to_dict()}
            return True
        run.holds_failed[g.key()] = check.mean_fitness
        demote(run, g, fitness, f, check.mean_fitness, check.episodes)
    assert run.best is not None
    g, _, gen = run.best
    if g.key() in run.holds_failed:  # not taken for solved, by resume either
        run.best = (g, run.holds_failed[g.key()], gen)
    return False


def holds_check(run: RunState, g: Genome, k: int) -> FreshCheck:
    """Whether ``g`` holds: its FSA as evolved first (an FSA far below the bar fails in
    a few episodes), then, if it held, the FSA the run would export, on other worlds:
    that second check is the statement."""
    cfg, task = run.cfg, run.task
    got = run.check(holds_checks, run.export_settings, g, run.seed, (run.generation, 2 * k),
                    required_rate(task, cfg), cfg.holds_confidence, cfg.holds_max_episodes,
                    cfg.eval_time_limit)
    if got is None:  # the check killed the process running it: failed (counted by check)
        return FreshCheck(SequentialRateTest(required_rate(task, cfg),
                                             confidence=cfg.holds_confidence,
                                             deterministic=task.deterministic).result(),
                          task.worst, 0, 0, run.seed, "holds", task.deterministic)
    for check in got:
        run.evaluations += check.episodes
        run.note_check_faults(Faults(raised=check.raised, timeouts=check.timeouts))
    return got[-1]


def holds_checks(
    task: Task, compiler: GenomeCompiler, export: ExportSettings,
    g: Genome, seed: int, key: tuple[int, int], required: float, confidence: float,
    max_episodes: int, time_limit: float | None,
) -> list[FreshCheck]:
    """The holds tests of :func:`holds_check`: ``g``'s FSA as evolved on the worlds of
    stream ``key`` of ``seed``, then, if it held, the FSA ``export`` makes of it on the
    next stream (``export``: :func:`~.export.make_export`'s settings). The same wherever it
    runs (:mod:`.isolated`)."""
    generation, stream = key

    def test(fsa: FSA, stream: int) -> FreshCheck:
        return holds_test(task, fsa, seed, (generation, stream), required,
                          confidence=confidence, max_episodes=max_episodes,
                          time_limit=time_limit)

    evolved = compiler.fsa(g, name=f"{task.name}_evolved")
    first = test(evolved, stream)
    if not first.passed:
        return [first]
    return [first, test(make_export(task, *export)(evolved), stream + 1)]


def demote(run: RunState, g: Genome, fitness: list[float], evaluated: float, mean: float,
           trials: int) -> None:
    """Fold a failed confirmation (``mean`` over ``trials``) into the fitness of ``g``
    (every copy of it in the population; ``evaluated`` is the fitness its evaluation
    gave it) and into the cache."""
    key = g.key()
    if run.cfg.cache and key in run.cache:
        total, count = run.cache[key]
    else:
        total, count = evaluated * run.trials, run.trials
    total, count = fold(total, count, mean, trials)
    if run.cfg.cache:
        run.cache[key] = (total, count)
    for i, ind in enumerate(run.population):
        if ind.key() == key:
            fitness[i] = total / count
