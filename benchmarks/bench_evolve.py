"""Benchmark of evolve: evaluations per second serial vs a process pool, and time to solve.

    python benchmarks/bench_evolve.py                      # the pour-water task, full
    python benchmarks/bench_evolve.py --quick              # a short run for CI
    python benchmarks/bench_evolve.py --task examples.toy_task --set p_fail=0.2

Prints (1) a table of evaluations (episodes) per second of the evaluation phase for the
serial backend and for 2 worker processes on the same generations (the runs are identical,
so the work is the same), best of ``--repeats`` interleaved runs, with their ratio, next to
the speed-up this machine gives a plain CPU-bound loop split over 2 processes (the ceiling
any pool can reach here); (2) over 10 seeds, generations and wall time to solve.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import statistics
import time

from evolve import PRESETS, EvolutionConfig, EvolutionResult, evolve
from skillcompose.task import load_task, parse_settings


def eval_rate(result: EvolutionResult, skip_first: bool = False) -> float:
    """Episodes per second of the evaluation phase (generation 0, with the pool's start-up,
    left out when ``skip_first``)."""
    hist = result.history[1:] if skip_first and len(result.history) > 1 else result.history
    episodes = sum(r.evaluations for r in hist)
    seconds = sum(r.evaluations / r.evals_per_s for r in hist if r.evals_per_s > 0)
    return episodes / seconds if seconds > 0 else 0.0


def _spin(n: int) -> int:
    s = 0
    for i in range(n):
        s += i * i % 7
    return s


def cpu_ceiling(workers: int, n: int) -> float:
    """Speed-up of ``workers`` processes over one on a CPU-bound loop with no traffic."""
    from concurrent.futures import ProcessPoolExecutor

    t = time.perf_counter()
    for _ in range(workers):
        _spin(n)
    serial = time.perf_counter() - t
    with ProcessPoolExecutor(workers) as ex:
        list(ex.map(_spin, [10] * workers))  # start the workers first
        t = time.perf_counter()
        list(ex.map(_spin, [n] * workers))
        parallel = time.perf_counter() - t
    return serial / parallel


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--task", default="examples.pour_water")
    ap.add_argument("--set", dest="settings", action="append", default=[])
    ap.add_argument("--quick", action="store_true", help="small sizes, for CI")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=3, help="interleaved throughput runs")
    args = ap.parse_args(argv)
    settings = parse_settings(args.settings)
    task = load_task(args.task, **settings)
    quick = args.quick

    # 1. throughput: the same run (no early stop) serial and on a pool, interleaved repeats
    speed_cfg = EvolutionConfig(
        population=100 if quick else 300, initial_nodes=50,
        generations=3 if quick else 15, trials=2 if quick else 3,
    )
    # never solved (workers rebuild the task; only this process judges solved)
    unsolvable = dataclasses.replace(task, target=-math.inf if task.minimize else math.inf)
    rates: dict[str, float] = {}
    episodes = 0
    for _ in range(1 if quick else args.repeats):
        for backend, workers in (("serial", 1), ("process", args.workers)):
            r = evolve(unsolvable, speed_cfg, seed=0, backend=backend, workers=workers,
                       simplify_result=False)
            rates[backend] = max(rates.get(backend, 0.0), eval_rate(r, skip_first=True))
            episodes = r.evaluations
    ceiling = cpu_ceiling(args.workers, 2_000_000 if quick else 20_000_000)
    print(f"Evaluation throughput, task {task.name}: population {speed_cfg.population}, "
          f"{speed_cfg.trials} trials, {speed_cfg.generations} generations "
          f"({episodes} episodes a run), best of {1 if quick else args.repeats}\n")
    print(f"{'':34} {'evaluations/s':>14} {'speed-up':>9}")
    print(f"{'serial':34} {rates['serial']:14,.0f} {1.0:8.2f}x")
    print(f"{f'process pool, {args.workers} workers':34} {rates['process']:14,.0f} "
          f"{rates['process'] / rates['serial']:8.2f}x")
    print(f"{f'plain CPU loop, {args.workers} processes':34} {'':>14} {ceiling:8.2f}x  "
          "(this machine's ceiling)")
    print(f"\npool efficiency: {rates['process'] / rates['serial'] / ceiling:.0%} of the "
          f"ceiling; target >= 1.80x with 2 workers\n")

    # 2. time to solve, over seeds, with the paper's settings and with our robust preset
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
