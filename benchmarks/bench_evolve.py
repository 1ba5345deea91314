"""Benchmark of evolve: evaluations per second serial vs a process pool, and time to solve.

    python benchmarks/bench_evolve.py                      # the pour-water task, full
    python benchmarks/bench_evolve.py --quick              # a short run for CI
    python benchmarks/bench_evolve.py --task examples.toy_task --set p_fail=0.2

Prints (1) evaluations (episodes) per second of one generation's jobs, serially and on 2
worker processes (the same jobs, so the same work and the same fitnesses), best of
``--repeats`` back-to-back pairs, next to what this machine gives a CPU-bound loop run by 2
processes at once over one alone (the ceiling any pool can reach here, measured after each
pair); (2) whole runs of 25 generations, breeding and checkpoints included, serial vs the
pool (identical runs); (3) over 10 seeds, generations and wall time to solve.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from typing import Any

import numpy as np

from evolve import (
    PRESETS,
    EvolutionConfig,
    Job,
    ProcessEvaluator,
    SerialEvaluator,
    SkillSet,
    evolve,
    initialize,
)
from skillcompose.task import load_task, parse_settings


def _count_until(cpu: int | None, start: float, stop: float, out: Any) -> None:
    """Spin from ``start`` to ``stop`` (this machine's monotonic clock, shared by all
    processes) and report how many loop blocks ran."""
    if cpu is not None:
        os.sched_setaffinity(0, {cpu})
    while time.perf_counter() < start:
        pass
    blocks = 0
    while time.perf_counter() < stop:
        s = 0
        for i in range(1000):
            s += i * i % 7
        blocks += 1
    out.send(blocks)


def cpu_ceiling(workers: int, seconds: float) -> tuple[int, int]:
    """How much of a CPU-bound loop one process alone, then ``workers`` processes together,
    get done in a fixed time: their ratio is the most any pool that shares its work out (as
    ours does, so a slower core simply does less) can reach here. Each process is pinned to
    its own core as the pool's workers are."""
    import multiprocessing

    try:
        cpus: list[int | None] = list(sorted(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - platforms without CPU affinity
        cpus = [None]
    ctx = multiprocessing.get_context("fork")

    def blocks(count: int) -> int:
        start = time.perf_counter() + 0.02  # all started and pinned by then
        pipes = [ctx.Pipe(duplex=False) for _ in range(count)]
        procs = [ctx.Process(target=_count_until,
                             args=(cpus[k % len(cpus)], start, start + seconds, pipes[k][1]))
                 for k in range(count)]
        for p in procs:
            p.start()
        total = sum(r.recv() for r, _ in pipes)
        for p in procs:
            p.join()
        return total

    return blocks(1), blocks(workers)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--task", default="examples.pour_water")
    ap.add_argument("--set", dest="settings", action="append", default=[])
    ap.add_argument("--quick", action="store_true", help="small sizes, for CI")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=15,
                    help="back-to-back serial/pool pairs for the throughput")
    ap.add_argument("--throughput-only", action="store_true",
                    help="print the throughput table only, not the time to solve")
    args = ap.parse_args(argv)
    settings = parse_settings(args.settings)
    task = load_task(args.task, **settings)
    quick = args.quick

    # 1. throughput: the same jobs (one generation of random genomes) evaluated serially and
    # on the pool, back to back, many times; this machine's speed drifts by up to 2x over
    # seconds, so each pair is compared on its own and the median ratio is reported
    skills = SkillSet.from_task(task)
    rng = np.random.default_rng(0)
    population = 100 if quick else 300
    trials = 2 if quick else 3
    jobs = [Job.of(initialize(skills, rng, 12), 0, (1, 0, i), trials)
            for i in range(population)]
    episodes = population * trials
    serial = SerialEvaluator(task, skills)
    pool = ProcessEvaluator(task, skills, workers=args.workers)
    pairs = 3 if quick else args.repeats
    ceiling_s = 0.05 if quick else 0.1
    t_serial, t_pool, ceilings = [], [], []
    try:
        pool.evaluate(jobs)  # start the workers and warm both up
        serial.evaluate(jobs)
        for _ in range(pairs):
            t = time.perf_counter()
            a = serial.evaluate(jobs)
            t_serial.append(time.perf_counter() - t)
            t = time.perf_counter()
            b = pool.evaluate(jobs)
            t_pool.append(time.perf_counter() - t)
            if a != b:
                raise SystemExit("the pool's fitnesses differ from the serial ones")
            ceilings.append(cpu_ceiling(args.workers, ceiling_s))
    finally:
        pool.close()
    ratios = [ts / tp for ts, tp in zip(t_serial, t_pool, strict=True)]
    loop_ratios = [many / one for one, many in ceilings]
    speedup = min(t_serial) / min(t_pool)
    ceiling = max(many for _, many in ceilings) / max(one for one, _ in ceilings)
    print(f"Evaluation throughput, task {task.name}: {population} random genomes of 12 nodes, "
          f"{trials} trials each ({episodes} episodes), {pairs} back-to-back pairs\n")
    print(f"{'':34} {'evaluations/s (best)':>21} {'speed-up (best)':>16} "
          f"{'speed-up (median of pairs)':>27}")
    print(f"{'serial':34} {episodes / min(t_serial):21,.0f} {1.0:15.2f}x {1.0:26.2f}x")
    print(f"{f'process pool, {args.workers} workers':34} {episodes / min(t_pool):21,.0f} "
          f"{speedup:15.2f}x {statistics.median(ratios):26.2f}x")
    print(f"{f'CPU loop, {args.workers} processes (ceiling)':34} {'':>21} "
          f"{ceiling:15.2f}x {statistics.median(loop_ratios):26.2f}x")
    print(f"\nspeed-up per pair: {', '.join(f'{r:.2f}' for r in ratios)}\n"
          f"ceiling per pair:  {', '.join(f'{c:.2f}' for c in loop_ratios)}\n"
          f"best of {pairs}: pool {speedup:.2f}x = {speedup / ceiling:.0%} of the ceiling "
          f"{ceiling:.2f}x; target >= 1.80x with {args.workers} workers\n")

    if args.throughput_only:
        return 0

    # 2. whole runs: what a user waits for, breeding and checkpoints included (the pool
    # evaluates each child as it is born, so breeding overlaps evaluation)
    whole_gens = 5 if quick else 25
    runs = 2 if quick else 5
    print(f"Whole runs, {whole_gens} generations from seed 1000 (no simplification), "
          f"best of {runs} interleaved runs each\n")
    print(f"{'preset':8} {'population x trials':>19} {'serial s':>9} "
          f"{f'pool ({args.workers}) s':>10} {'speed-up':>9}")
    for name in ("paper", "robust"):
        cfg = EvolutionConfig(**{**PRESETS[name], "generations": whole_gens})
        whole_walls: dict[str, list[float]] = {"serial": [], "process": []}
        histories: dict[str, list[tuple[float, ...]]] = {}
        for _ in range(runs):
            for backend in ("serial", "process"):
                t = time.perf_counter()
                r = evolve(task, cfg, seed=1000, backend=backend,
                           workers=1 if backend == "serial" else args.workers,
                           simplify_result=False)
                whole_walls[backend].append(time.perf_counter() - t)
                histories[backend] = [(h.best, h.mean, h.total_evaluations) for h in r.history]
        if histories["serial"] != histories["process"]:
            raise SystemExit(f"preset {name}: the pool's run differs from the serial one")
        s, p = min(whole_walls["serial"]), min(whole_walls["process"])
        shape = f"{cfg.population} x {cfg.trials or task.trials}"
        print(f"{name:8} {shape:>19} {s:9.2f} {p:10.2f} {s / p:8.2f}x")
    print()

    # 3. time to solve, over seeds, with the paper's settings and with our robust preset
    seeds = 3 if quick else args.seeds
    budget = 150 if quick else 2000
    print(f"Time to solve, {seeds} seeds (budget {budget} generations, serial)\n")
    print(f"{'preset':8} {'solved':>7} {'generations median (min-max)':>30} "
          f"{'wall time median (max)':>24}")
    for name in ("paper", "robust"):
        cfg = EvolutionConfig(**{**PRESETS[name], "generations": budget})
        gens, walls, solved = [], [], 0
        for seed in range(seeds):
            r = evolve(task, cfg, seed=seed, simplify_result=False)
            solved += r.solved
            gens.append(r.generations if r.solved else budget)
            walls.append(r.wall_time)
        print(f"{name:8} {f'{solved}/{seeds}':>7} "
              f"{f'{statistics.median(gens):g} ({min(gens)}-{max(gens)})':>30} "
              f"{f'{statistics.median(walls):.1f} s ({max(walls):.1f} s)':>24}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
