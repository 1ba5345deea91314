"""Breeding: algorithm 1's next generation, island by island, with migration and restarts.

A generation is bred child by child (so that the evaluator can take each as it is born):
the elites first, then pairs of children of parents picked by tournament, crossed with
probability ``p_cross`` and mutated (:mod:`skillcompose.evolve.operators`). Islands
(``islands`` > 1) are slices of the one population, bred one after the other from the run's
one breeding generator; migration draws nothing at random, and a stagnant island restarts
from random genomes around its best (``restart_after``). With ``restart_patience`` the whole
population restarts so when the run's best stalls, and grows by ``restart_growth`` each time.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

from .config import EvolutionConfig
from .genome import Genome
from .operators import crossover, initialize, mutate
from .state import RunState

__all__ = ["breed", "grows", "island_bounds", "migrate", "next_size", "note_islands",
           "stagnant"]

_RETRIES = 8  # at most this many extra mutations make a duplicate child new


def breed(
    run: RunState, fitness: list[float], bred: Callable[[], None] | None = None
) -> Iterator[Genome]:
    """Algorithm 1's next generation, child by child, island by island (one island
    unless ``islands`` says more); once all are born it becomes the population and
    ``bred`` is called (to save a checkpoint)."""
    population, fitness = migrate(run, run.population, fitness)
    nxt: list[Genome] = []
    run.elite_fitness = {}
    seen: set[tuple[Any, ...]] = set()
    g = run.generation + 1
    grow = grows(run)
    restarts = {0} if grow else stagnant(run)
    now = island_bounds(run.cfg, len(population))
    for k, ((lo, hi), (_, end)) in enumerate(zip(now, island_bounds(run.cfg, next_size(run)),
                                                 strict=True)):
        keep = None if k not in restarts else _kept(run.cfg, grow)
        yield from _breed_island(run, population[lo:hi], fitness[lo:hi], nxt, end, g, seen,
                                 keep)
    run.population = nxt
    run.generation = g
    run.restarts += grow
    for k in restarts:
        run.island_best[k] = (run.island_best[k][0], g)
    if bred is not None:
        bred()


def _breed_island(
    run: RunState, population: list[Genome], fitness: list[float], nxt: list[Genome], end: int,
    g: int, seen: set[tuple[Any, ...]], keep: int | None,
) -> Iterator[Genome]:
    """One island's children, appended to ``nxt`` until it holds ``end`` individuals;
    ``keep``: a restart, which keeps that many of the best (None: no restart)."""
    restart = keep is not None
    cfg, rng, n = run.cfg, run.rng, len(population)
    sizes = [len(x) for x in population]
    # neutral (or a drift stage): at equal rank the newer genome (higher uid) goes first, so
    # a child as good as the elite takes its place (neutral drift)
    drift = cfg.neutral or cfg.drifting(run.restarts)
    newer = [-x.origin["uid"] if drift else 0 for x in population]
    order = sorted(range(n),
                   key=lambda i: (*run.rank_key(fitness[i], sizes[i]), newer[i], i))
    rank = [0] * n
    for r, i in enumerate(order):
        rank[i] = r
    if cfg.skill_bias > 0.0:  # what the island's best quarter uses, drawn more often
        run.skills.learn((population[i] for i in order[:max(1, n // 4)]), cfg.skill_bias)
    for i in order[:cfg.elitism if keep is None else keep]:
        e = population[i].copy()
        e.origin = {**e.origin, "elite": True}
        run.elite_fitness[e.origin["uid"]] = fitness[i]
        nxt.append(e)
        if cfg.unique_children:
            seen.add(e.key())
        yield e
    if restart:  # a stagnant island starts afresh around its best
        while len(nxt) < end:
            c = initialize(run.skills, rng, cfg.initial_nodes, cfg.terminal_weight)
            c.origin = {"uid": run.uid(), "born": g, "parents": [], "ops": ["restart"]}
            nxt.append(c)
            yield c
        return

    def pick() -> Genome:
        cands = rng.integers(n, size=cfg.tournament)
        return population[min(cands, key=lambda c: rank[int(c)])]

    while len(nxt) < end:
        p1, p2 = pick(), pick()
        c1, c2 = p1.copy(), p2.copy()
        ops1: list[str] = []
        ops2: list[str] = []
        if rng.random() < cfg.p_cross:
            crossover(c1, c2, run.skills, rng, cfg.terminal_weight)
            ops1.append("crossover")
            ops2.append("crossover")
        ops1 += mutate(c1, run.skills, rng, cfg)
        ops2 += mutate(c2, run.skills, rng, cfg)
        for c, ops, parent, mate in ((c1, ops1, p1, p2), (c2, ops2, p2, p1)):
            if cfg.unique_children:
                ops += _made_new(run, c, seen)
            parents = [parent.origin["uid"]]
            if "crossover" in ops:
                parents.append(mate.origin["uid"])
            c.origin = {"uid": run.uid(), "born": g, "parents": parents, "ops": ops}
            nxt.append(c)
        yield from nxt[len(nxt) - 2:end]
    del nxt[end:]


def _made_new(run: RunState, child: Genome, seen: set[tuple[Any, ...]]) -> list[str]:
    """Mutate a child met before again until it is new (up to 8 times); the operators
    applied. A new child's key joins ``seen``."""
    ops: list[str] = []
    key = child.key()
    for _ in range(_RETRIES):
        if key not in seen and key not in run.cache:
            break
        ops += mutate(child, run.skills, run.rng, run.cfg)
        key = child.key()
    seen.add(key)
    return ops


def island_bounds(cfg: EvolutionConfig, population: int | None = None) -> list[tuple[int, int]]:
    """Each island's slice ``[lo, hi)`` of a population of ``population`` individuals (the
    config's)."""
    size = (population or cfg.population) // cfg.islands
    return [(k * size, (k + 1) * size) for k in range(cfg.islands)]


def _kept(cfg: EvolutionConfig, whole: bool) -> int:
    """How many of the best a restart keeps: the elites (at least the best), or, at a restart
    of the whole population, ``restart_keep`` when it is set."""
    if whole and cfg.restart_keep is not None:
        return cfg.restart_keep
    return max(cfg.elitism, 1)


def grows(run: RunState) -> bool:
    """Whether the next generation restarts the whole population, larger
    (``restart_patience``): the run's best has not improved for that many generations
    (``drift_patience`` in a drift stage)."""
    patience = run.cfg.patience_after(run.restarts)
    return patience > 0 and bool(run.island_best) and \
        run.generation - run.island_best[0][1] >= patience


def next_size(run: RunState) -> int:
    """The individuals of the next generation: the population grows at a restart."""
    return run.cfg.population_after(run.restarts + grows(run))


def migrate(
    run: RunState, population: list[Genome], fitness: list[float]
) -> tuple[list[Genome], list[float]]:
    """The population after this generation's migration (copies; the same lists when
    none is due): each island's worst are replaced by its neighbours' best, with their
    fitness. Only ranks decide, so it draws no random numbers."""
    cfg = run.cfg
    if cfg.islands < 2 or cfg.migrants == 0 or run.generation == 0 or \
            run.generation % cfg.migration_interval:
        return population, fitness
    bounds = island_bounds(run.cfg, len(population))
    sizes = [len(x) for x in population]

    def ranked(lo: int, hi: int) -> list[int]:
        return sorted(range(lo, hi),
                      key=lambda i: (*run.rank_key(fitness[i], sizes[i]), i))

    best = [ranked(lo, hi)[:cfg.migrants] for lo, hi in bounds]
    worst = [ranked(lo, hi)[::-1] for lo, hi in bounds]
    before, fitness_before = population, fitness
    population, fitness = list(population), list(fitness)
    k_all = len(bounds)
    for k, (lo, hi) in enumerate(bounds):
        sources = [(k - 1) % k_all] if cfg.topology == "ring" else \
            [j for j in range(k_all) if j != k]
        incoming = [i for j in sources for i in best[j]][:(hi - lo) // 2]
        for dest, src in zip(worst[k], incoming, strict=False):
            m = before[src].copy()
            m.origin = {**m.origin, "migrant_from": src // (hi - lo)}
            population[dest], fitness[dest] = m, fitness_before[src]
    return population, fitness


def stagnant(run: RunState) -> set[int]:
    """The islands to restart this generation: no better best for ``restart_after``
    generations."""
    after = run.cfg.restart_after
    if after == 0:
        return set()
    return {k for k, (_, since) in enumerate(run.island_best)
            if run.generation - since >= after}


def note_islands(run: RunState, fitness: list[float]) -> None:
    """Track each island's best and the generation it last improved (for restarts)."""
    if run.cfg.restart_after == 0 and run.cfg.restart_patience == 0:
        return
    sizes = [len(x) for x in run.population]
    bounds = island_bounds(run.cfg, len(run.population))
    for k, (lo, hi) in enumerate(bounds):
        key = min(run.rank_key(fitness[i], sizes[i])[0] for i in range(lo, hi))
        if k >= len(run.island_best):
            run.island_best.append((key, run.generation))
        elif key < run.island_best[k][0]:
            run.island_best[k] = (key, run.generation)
