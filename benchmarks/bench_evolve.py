"""Benchmark of evolve: evaluations per second serial vs a process pool, and time to solve.

    python benchmarks/bench_evolve.py                      # the pour-water task, full
    python benchmarks/bench_evolve.py --quick              # a short run for CI
    python benchmarks/bench_evolve.py --task examples.toy_task --set p_fail=0.2

Prints (1) evaluations (episodes) per second of one generation's jobs, serially and on 2
worker processes (the same jobs, so the same work and the same fitnesses), best of
``--repeats`` back-to-back pairs, next to what this machine gives a CPU-bound loop run by 2
processes at once over one alone (the ceiling any pool can reach here, measured after each
pair); (2) whole runs of 25 generations, breeding and checkpoints included, serial vs the
pool (identical runs); (3) over 10 seeds, generations and wall time to solve. ``--ray``
adds a row on a local Ray cluster to (1), and whole runs beside Ray, streaming and taking
each generation whole (``--ray-only``: those alone), after (1).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

from skillcompose.evolve import (
    PRESETS,
    EvolutionConfig,
    Job,
    ProcessEvaluator,
    RayEvaluator,
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


def _spin(stop: Any) -> None:
    while not stop.is_set():
        s = 0
        for i in range(10000):
            s += i * i % 7


@contextlib.contextmanager
def busy_core() -> Iterator[None]:
    """One CPU-bound process (not pinned, normal priority) running in the background, as
    another user's work on a shared machine; stopped on leaving."""
    import multiprocessing

    ctx = multiprocessing.get_context("fork")
    stop = ctx.Event()
    proc = ctx.Process(target=_spin, args=(stop,), daemon=True)
    proc.start()
    try:
        time.sleep(0.2)
        yield
    finally:
        stop.set()
        proc.join(timeout=5)
        if proc.is_alive():
            proc.kill()
            proc.join()


def throughput(
    serial: SerialEvaluator, evaluators: dict[str, Any], jobs: list[Job], rounds: int,
    workers: int, ceiling_s: float,
) -> tuple[float, dict[str, tuple[float, list[float]]], tuple[float, float]]:
    """Each round evaluates ``jobs`` serially, then on each evaluator (checking the
    fitnesses are the serial ones), then measures the CPU loop's ceiling. Returns the best
    serial time, per evaluator its best time and its per-round speed-ups, and the
    ceiling's best and median."""
    serial.evaluate(jobs)  # warm up, and start the workers
    for ev in evaluators.values():
        ev.evaluate(jobs)
    t_serial: list[float] = []
    times: dict[str, list[float]] = {name: [] for name in evaluators}
    ceilings = []
    for _ in range(rounds):
        t = time.perf_counter()
        expected = serial.evaluate(jobs)
        t_serial.append(time.perf_counter() - t)
        for name, ev in evaluators.items():
            t = time.perf_counter()
            got = ev.evaluate(jobs)
            times[name].append(time.perf_counter() - t)
            if got != expected:
                raise SystemExit(f"{name}: fitnesses differ from the serial ones")
        ceilings.append(cpu_ceiling(workers, ceiling_s))
    rows = {name: (min(ts), [s / t for s, t in zip(t_serial, ts, strict=True)])
            for name, ts in times.items()}
    best = max(many for _, many in ceilings) / max(one for one, _ in ceilings)
    return min(t_serial), rows, (best, statistics.median(m / o for o, m in ceilings))


@contextlib.contextmanager
def _pool_options(**options: Any) -> Iterator[None]:
    """Have ``evolve()``'s process pool made with ``options`` (the old defaults, to compare
    them with the current ones in the same run)."""
    if not options:
        yield
        return
    from unittest import mock

    import skillcompose.evolve.backends as backends

    made = backends.ProcessEvaluator
    with mock.patch.object(backends, "ProcessEvaluator",
                           lambda *a, **k: made(*a, **{**k, **options})):
        yield


_IN_PRIVATE_NET = "SKILLCOMPOSE_BENCH_PRIVATE_NET"


@contextlib.contextmanager
def ray_address(nodes: int) -> Iterator[None]:
    """A local Ray cluster of ``nodes`` nodes of one CPU each, started here, named by
    ``RAY_ADDRESS`` (so ``backend="ray"`` connects to it) and stopped on leaving."""
    from skillcompose.evolve.ray_local import local_cluster

    with local_cluster(nodes) as cluster:
        os.environ.update(cluster.env)  # before Ray is imported: it reads them then
        os.environ["RAY_ADDRESS"] = cluster.address
        try:
            yield
        finally:
            import ray

            ray.shutdown()
            del os.environ["RAY_ADDRESS"]


@contextlib.contextmanager
def ray_cluster(task: Any, skills: SkillSet, nodes: int) -> Iterator[RayEvaluator]:
    """A Ray evaluator on a local cluster of ``nodes`` nodes of one CPU each, started here
    and stopped on leaving."""
    with ray_address(nodes):
        ev = RayEvaluator(task, skills)
        try:
            yield ev
        finally:
            ev.close()


@contextlib.contextmanager
def _whole_generations() -> Iterator[None]:
    """Have ``evolve()``'s evaluators take each generation whole, bred first (as the Ray
    backend did before it streamed), to compare in the same run."""
    from unittest import mock

    import skillcompose.evolve.algorithm as algorithm

    made = algorithm.make_evaluator

    def whole(*a: Any, **k: Any) -> Any:
        ev = made(*a, **k)
        evaluate = ev.evaluate
        ev.evaluate = lambda jobs, expected=None: evaluate(list(jobs), expected)  # type: ignore[method-assign]
        return ev

    with mock.patch.object(algorithm, "make_evaluator", whole):
        yield


def ray_whole_runs(task: Any, workers: int, generations: int, runs: int) -> None:
    """Whole runs on a local Ray cluster beside serial and the pool: seconds from the end of
    generation 0 to the end of the last (breeding, checkpoints and evaluation; not the
    start of the workers, which on Ray includes shipping the code), best of ``runs``
    interleaved runs, each run checked equal to the serial one."""
    backends: dict[str, tuple[str, bool]] = {
        "serial": ("serial", False), "pool": ("process", False),
        "Ray": ("ray", False), "Ray, bred first": ("ray", True)}
    print(f"Whole runs on a local Ray cluster of {workers} nodes, {generations} generations "
          f"from seed 1000: seconds after generation 0, best of {runs} interleaved runs; "
          "'Ray, bred first' takes each generation whole (breeding does not overlap "
          "evaluation), as the Ray backend did before\n")
    print(f"{'preset':8} {'population x trials':>19} " + " ".join(
        f"{b + ' s':>17}" for b in backends) + f" {'pool':>7} {'Ray':>7} {'bred first':>11}")
    with ray_address(workers):
        for name in ("paper", "robust"):
            cfg = EvolutionConfig(**{**PRESETS[name], "generations": generations,
                                     "require_holds": False})  # evaluation throughput
            walls: dict[str, list[float]] = {b: [] for b in backends}
            histories: dict[str, list[tuple[float, ...]]] = {}
            for _ in range(runs):
                for label, (backend, whole) in backends.items():
                    ends: list[float] = []

                    def ended(_: Any, ends: list[float] = ends) -> None:
                        ends.append(time.perf_counter())

                    with _whole_generations() if whole else contextlib.nullcontext():
                        r = evolve(task, cfg, seed=1000, backend=backend,
                                   workers=1 if backend == "serial" else workers,
                                   simplify_result=False, on_generation=ended)
                    walls[label].append(ends[-1] - ends[0])
                    histories[label] = [(h.best, h.mean, h.total_evaluations)
                                        for h in r.history]
            if any(h != histories["serial"] for h in histories.values()):
                raise SystemExit(f"preset {name}: a run differs from the serial one")
            best = {b: min(w) for b, w in walls.items()}
            shape = f"{cfg.population} x {cfg.trials or task.trials}"
            print(f"{name:8} {shape:>19} " + " ".join(f"{best[b]:17.2f}" for b in backends)
                  + f" {best['serial'] / best['pool']:6.2f}x {best['serial'] / best['Ray']:6.2f}x"
                  f" {best['serial'] / best['Ray, bred first']:10.2f}x")
    print()


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
    ap.add_argument("--trials", type=int, default=None,
                    help="episodes per genome in the throughput rounds (default 3): more makes "
                         "each round longer, and a backend's cost per round smaller beside it")
    ap.add_argument("--no-busy", action="store_true",
                    help="skip the rows measured beside a background CPU-bound process")
    ap.add_argument("--ray", action="store_true",
                    help="add a row on a local Ray cluster of --workers nodes of 1 CPU each, "
                    "started and stopped by this script")
    ap.add_argument("--ray-runs", type=int, default=5,
                    help="interleaved whole runs per backend on Ray (default 5)")
    ap.add_argument("--ray-only", action="store_true",
                    help="with --ray: only the whole runs beside Ray, not the throughput "
                         "table, the other whole runs or the time to solve")
    ap.add_argument("--no-solve", action="store_true",
                    help="skip the time to solve over seeds")
    ap.add_argument("--throughput-only", action="store_true",
                    help="print the throughput table only, not the time to solve")
    args = ap.parse_args(argv)
    if args.ray and not os.environ.get(_IN_PRIVATE_NET):
        # the cluster listens on ports: run in a network namespace of our own (loopback
        # only), so nothing of it can be reached from elsewhere
        import subprocess
        import sys

        from skillcompose.evolve.ray_local import PRIVATE_NET, private_network

        if not private_network():
            raise SystemExit("bench_evolve.py --ray: needs a private network namespace "
                             "(unshare --net, run as root); run without --ray")
        argv = sys.argv[1:] if argv is None else argv
        env = {**os.environ, _IN_PRIVATE_NET: "1"}
        return subprocess.run([*PRIVATE_NET, sys.executable, __file__, *argv], env=env,
                              check=False).returncode
    settings = parse_settings(args.settings)
    task = load_task(args.task, **settings)
    quick = args.quick
    if args.ray and args.ray_only:
        ray_whole_runs(task, args.workers, 5 if quick else 25, 2 if quick else args.ray_runs)
        return 0

    # 1. throughput: the same jobs (one generation of random genomes) evaluated serially and
    # on each parallel evaluator, back to back, many times; this machine's speed drifts by up
    # to 2x over seconds, so each round is compared on its own and the median ratio reported
    skills = SkillSet.from_task(task)
    rng = np.random.default_rng(0)
    population = 100 if quick else 300
    trials = args.trials or (2 if quick else 3)
    jobs = [Job.of(initialize(skills, rng, 12), 0, (1, 0, i), trials)
            for i in range(population)]
    episodes = population * trials
    pairs = 3 if quick else args.repeats
    ceiling_s = 0.05 if quick else 0.1
    print(f"Evaluation throughput, task {task.name}: {population} random genomes of 12 nodes, "
          f"{trials} trials each ({episodes} episodes), {pairs} back-to-back rounds; "
          f"this machine has {os.cpu_count()} cores, shared with whatever else runs on it\n")
    conditions = [("idle", False)] + ([] if args.no_busy else [("busy", True)])
    for label, busy in conditions:
        evaluators: dict[str, Any] = {
            f"process pool, {args.workers} workers (pinned)": ProcessEvaluator(
                task, skills, workers=args.workers),
            f"pool, {args.workers} not pinned": ProcessEvaluator(
                task, skills, workers=args.workers, pin=False),
            f"pool, {args.workers} pinned at nice 10 (old)": ProcessEvaluator(
                task, skills, workers=args.workers, pin=True, nice=10),
        }
        if args.ray and not busy:
            evaluators[f"Ray, local cluster of {args.workers} nodes"] = "ray"
        with contextlib.ExitStack() as stack:
            if "ray" in evaluators.values():
                key = next(k for k, v in evaluators.items() if v == "ray")
                evaluators[key] = stack.enter_context(ray_cluster(task, skills, args.workers))
            for ev in evaluators.values():
                stack.callback(ev.close)
            if busy:
                stack.enter_context(busy_core())
            t_serial, rows, (ceiling_best, ceiling_median) = throughput(
                SerialEvaluator(task, skills), evaluators, jobs, pairs, args.workers, ceiling_s)
        title = ("as the machine is" if not busy else
                 "with one background CPU-bound process (nice 0, not pinned) running")
        print(f"{label}: {title}\n")
        print(f"{'':38} {'evaluations/s (best)':>21} {'speed-up (best)':>16} "
              f"{'speed-up (median of rounds)':>28} {'of ceiling':>11}")
        print(f"{'serial':38} {episodes / t_serial:21,.0f} {1.0:15.2f}x {1.0:27.2f}x")
        for name, (t_best, ratios) in rows.items():
            speedup = t_serial / t_best
            median = statistics.median(ratios)
            print(f"{name:38} {episodes / t_best:21,.0f} {speedup:15.2f}x {median:27.2f}x "
                  f"{speedup / ceiling_best:10.0%}")
        print(f"{f'CPU loop, {args.workers} processes (ceiling)':38} {'':>21} "
              f"{ceiling_best:15.2f}x {ceiling_median:27.2f}x\n")

    if args.throughput_only:
        return 0

    if args.ray:
        ray_whole_runs(task, args.workers, 5 if quick else 25, 2 if quick else args.ray_runs)

    # 2. whole runs: what a user waits for, breeding and checkpoints included (the pool
    # evaluates each child as it is born, so breeding overlaps evaluation)
    whole_gens = 5 if quick else 25
    runs = 2 if quick else 5
    backends: dict[str, dict[str, Any]] = {"serial": {}, "pool": {},
                                           "not pinned": {"pin": False},
                                           "old pool": {"pin": True, "nice": 10}}
    print(f"Whole runs, {whole_gens} generations from seed 1000 (no simplification), "
          f"best of {runs} interleaved runs each; pool: {args.workers} workers (pinned, the "
          "default), not pinned, and the old pool: pinned at nice 10\n")
    print(f"{'preset':8} {'machine':6} {'population x trials':>19} {'serial s':>9} "
          f"{'pool s':>7} {'not pinned s':>13} {'old pool s':>11} {'speed-up':>9} "
          f"{'not pinned':>11} {'old':>6}")
    for name in ("paper", "robust"):
        cfg = EvolutionConfig(**{**PRESETS[name], "generations": whole_gens,
                                 "require_holds": False})  # evaluation throughput
        for label, busy in conditions:
            walls: dict[str, list[float]] = {b: [] for b in backends}
            histories: dict[str, list[tuple[float, ...]]] = {}
            with busy_core() if busy else contextlib.nullcontext():
                for _ in range(runs):
                    for backend, options in backends.items():
                        t = time.perf_counter()
                        with _pool_options(**options):
                            r = evolve(task, cfg, seed=1000,
                                       backend="serial" if backend == "serial" else "process",
                                       workers=1 if backend == "serial" else args.workers,
                                       simplify_result=False)
                        walls[backend].append(time.perf_counter() - t)
                        histories[backend] = [(h.best, h.mean, h.total_evaluations)
                                              for h in r.history]
            if any(h != histories["serial"] for h in histories.values()):
                raise SystemExit(f"preset {name}: a pool's run differs from the serial one")
            s, p, u, o = (min(walls[b]) for b in backends)
            shape = f"{cfg.population} x {cfg.trials or task.trials}"
            print(f"{name:8} {label:6} {shape:>19} {s:9.2f} {p:7.2f} {u:13.2f} {o:11.2f} "
                  f"{s / p:8.2f}x {s / u:10.2f}x {s / o:5.2f}x")
    print()

    if args.no_solve:
        return 0

    # 3. time to solve, over seeds, with the paper's settings and with our robust preset
    seeds = 3 if quick else args.seeds
    budget = 150 if quick else 2000
    print(f"Time to solve, {seeds} seeds (budget {budget} generations, serial)\n")
    print(f"{'preset':8} {'solved':>7} {'generations median (min-max)':>30} "
          f"{'wall time median (max)':>24}")
    for name in ("paper", "robust"):
        cfg = EvolutionConfig(**{**PRESETS[name], "generations": budget,
                                 "require_holds": False})  # evaluation throughput
        gens: list[int] = []
        times: list[float] = []
        solved = 0
        for seed in range(seeds):
            r = evolve(task, cfg, seed=seed, simplify_result=False)
            solved += r.solved
            gens.append(r.generations if r.solved else budget)
            times.append(r.wall_time)
        print(f"{name:8} {f'{solved}/{seeds}':>7} "
              f"{f'{statistics.median(gens):g} ({min(gens)}-{max(gens)})':>30} "
              f"{f'{statistics.median(times):.1f} s ({max(times):.1f} s)':>24}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
