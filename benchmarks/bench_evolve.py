"""Benchmark of evolve: evaluations per second serial vs a process pool, and time to solve.

    python benchmarks/bench_evolve.py                      # the toy task, full
    python benchmarks/bench_evolve.py --quick              # a short run for CI
    python benchmarks/bench_evolve.py --task examples.pour_water --set p_fail=0.2

Prints (1) evaluations (episodes) per second of the evaluation phase for the serial backend
and for 2 worker processes on the same generations (the runs are identical, so the work is
the same) and their ratio; (2) over 10 seeds, generations and wall time to solve.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import statistics
import time

from evolve import EvolutionConfig, EvolutionResult, evolve
from skillcompose.task import load_task, parse_settings


def eval_rate(result: EvolutionResult, skip_first: bool = False) -> float:
    """Episodes per second of the evaluation phase (generation 0, with the pool's start-up,
    left out when ``skip_first``)."""
    hist = result.history[1:] if skip_first and len(result.history) > 1 else result.history
    episodes = sum(r.evaluations for r in hist)
    seconds = sum(r.evaluations / r.evals_per_s for r in hist if r.evals_per_s > 0)
    return episodes / seconds if seconds > 0 else 0.0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--task", default="examples.toy_task")
    ap.add_argument("--set", dest="settings", action="append", default=[])
    ap.add_argument("--quick", action="store_true", help="small sizes, for CI")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seeds", type=int, default=10)
    args = ap.parse_args(argv)
    settings = parse_settings(args.settings)
    task = load_task(args.task, **settings)
    quick = args.quick

    # 1. throughput: the same run (no early stop) serial and on a pool
    speed_cfg = EvolutionConfig(
        population=100 if quick else 300, initial_nodes=50,
        generations=3 if quick else 8, trials=2 if quick else 4,
    )
    # never solved (workers rebuild the task; only this process judges solved)
    unsolvable = dataclasses.replace(task, target=-math.inf if task.minimize else math.inf)
    rates = {}
    for backend, workers in (("serial", 1), ("process", args.workers)):
        t = time.perf_counter()
        r = evolve(unsolvable, speed_cfg, seed=0, backend=backend, workers=workers,
                   simplify_result=False)
        rates[backend] = eval_rate(r, skip_first=True)
        print(f"{backend:>8} x{workers}: {rates[backend]:10,.0f} evaluations/s "
              f"(evaluation phase; {r.evaluations} episodes, {time.perf_counter() - t:.1f} s "
              f"total with breeding, {r.generations + 1} generations)")
    print(f"speed-up with {args.workers} workers: {rates['process'] / rates['serial']:.2f}x")

    # 2. time to solve, over seeds
    solve_cfg = EvolutionConfig(
        population=100 if quick else 300, initial_nodes=15 if quick else 50,
        generations=100 if quick else 500,
    )
    seeds = 3 if quick else args.seeds
    gens, walls, solved = [], [], 0
    for seed in range(seeds):
        r = evolve(task, solve_cfg, seed=seed, simplify_result=False)
        solved += r.solved
        if r.solved:
            gens.append(r.generations)
            walls.append(r.wall_time)
        print(f"seed {seed}: {'solved' if r.solved else 'not solved'} in {r.generations} "
              f"generations, {r.wall_time:.1f} s, best fitness {r.best_fitness:.4g}")
    print(f"solved {solved}/{seeds}", end="")
    if gens:
        print(f"; generations median {statistics.median(gens)} (min {min(gens)}, max "
              f"{max(gens)}); wall time median {statistics.median(walls):.1f} s")
    else:
        print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
