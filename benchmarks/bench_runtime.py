"""Runtime speed: FSA transitions per second next to py_trees, `transitions` and a bare loop.

Every row runs the same work, a ring of 20 no-op skills (each returns one outcome that leads
to the next), and is timed in the same process, best of ``--repeats``:

- ``dict-lookup loop (ceiling)``: a plain Python loop that calls a no-op function and looks
  its outcome up in a dict, the least an interpreter of FSAs in Python can do per step.
- ``skillcompose, trace off``: ``CompiledFSA.outcome`` with a step limit of ``--steps``
  (the run ends with ``timeout``): declared-access bookkeeping and outcome checks included.
- ``skillcompose, trace on``: ``CompiledFSA.run(trace=True)``, which records a blackboard
  diff per step.
- ``skillcompose, 20-step runs``: whole runs of a 20-state chain ending in ``success``:
  per-run overhead (a generator, a result) included.
- ``py_trees``: a ``Sequence`` of 20 ``Success`` behaviours, ticked with ``tick_once``; the
  rate counts behaviour ticks.
- ``transitions``: a ``Machine`` of 20 states, one trigger cycling through them.
- then the tick-wise rows of :mod:`benchmarks.bench_tickwise` (per tick, against py_trees).

Run: ``python benchmarks/bench_runtime.py`` (``--quick`` for a smoke run). Targets: at least
2,000,000 transitions/s with the trace off, at least 10x py_trees.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Literal

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from skillcompose import FSA, Blackboard, Registry, State, compile_fsa, skill

N_STATES = 20


@skill
def noop(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    return "success"


def _best(fn: Callable[[], int], repeats: int) -> float:
    """Best rate (events per second) over ``repeats`` calls of ``fn`` (returns #events)."""
    best = 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        n = fn()
        dt = time.perf_counter() - t0
        best = max(best, n / dt)
    return best


def ring(step_limit: int) -> FSA:
    states = {
        f"Noop_{k}": State("Noop", {}, {"success": f"Noop_{(k + 1) % N_STATES}"})
        for k in range(N_STATES)
    }
    return FSA(states, "Noop_0", step_limit=step_limit)


def chain() -> FSA:
    states = {
        f"Noop_{k}": State(
            "Noop", {}, {"success": f"Noop_{k + 1}" if k + 1 < N_STATES else "success"}
        )
        for k in range(N_STATES)
    }
    return FSA(states, "Noop_0", step_limit=N_STATES)


def bench_dict_loop(steps: int) -> int:
    def f(bb: object, rng: object) -> str:
        return "success"

    table = [(f, {"success": (k + 1) % N_STATES}) for k in range(N_STATES)]
    bb, rng = object(), object()
    i = 0
    n = 0
    while n < steps:
        fn, nxt = table[i]
        out = fn(bb, rng)
        i = nxt[out]
        n += 1
    return n


def bench_skillcompose(steps: int, trace: bool) -> Callable[[], int]:
    registry = Registry([noop])
    compiled = compile_fsa(ring(steps), registry)
    rng = np.random.default_rng(0)

    def go() -> int:
        bb = Blackboard()
        if trace:
            return compiled.run(bb, rng, trace=True).steps
        outcome, n = compiled.outcome(bb, rng)
        assert outcome == "timeout"
        return n

    return go


def bench_runs(runs: int) -> Callable[[], int]:
    compiled = compile_fsa(chain(), Registry([noop]))
    rng = np.random.default_rng(0)

    def go() -> int:
        total = 0
        for _ in range(runs):
            total += compiled.run(Blackboard(), rng).steps
        return total

    return go


def bench_py_trees(ticks: int) -> Callable[[], int]:
    import py_trees

    root = py_trees.composites.Sequence("chain", memory=False)
    root.add_children([py_trees.behaviours.Success(f"s{k}") for k in range(N_STATES)])
    tree = py_trees.trees.BehaviourTree(root)
    tree.setup()

    def go() -> int:
        for _ in range(ticks):
            root.tick_once()
        return ticks * N_STATES

    return go


def bench_transitions(steps: int) -> Callable[[], int] | None:
    try:
        from transitions import Machine
    except ImportError:
        return None
    states = [f"s{k}" for k in range(N_STATES)]

    class Model:
        pass

    model = Model()
    machine = Machine(model=model, states=states, initial="s0")
    for k in range(N_STATES):
        machine.add_transition("step", states[k], states[(k + 1) % N_STATES])

    def go() -> int:
        step = model.step  # type: ignore[attr-defined]
        for _ in range(steps):
            step()
        return steps

    return go


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a short smoke run")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    steps = 200_000 if args.quick else 1_000_000  # at most MAX_STEP_LIMIT
    repeats = 2 if args.quick else args.repeats

    rows: list[tuple[str, float]] = []
    ceiling = _best(lambda: bench_dict_loop(steps), repeats)
    rows.append(("dict-lookup loop (ceiling)", ceiling))
    ours = _best(bench_skillcompose(steps, trace=False), repeats)
    rows.append(("skillcompose, trace off", ours))
    rows.append(("skillcompose, trace on", _best(bench_skillcompose(steps // 10, True), repeats)))
    rows.append(("skillcompose, 20-step runs", _best(bench_runs(steps // 200), repeats)))
    pyt = _best(bench_py_trees(steps // (10 * N_STATES)), repeats)
    rows.append(("py_trees Sequence, per behaviour tick", pyt))
    tr = bench_transitions(steps // 20)
    if tr is not None:
        rows.append(("transitions Machine", _best(tr, repeats)))
    else:
        print("(transitions not installed: pip install transitions to compare)")

    print(f"Transitions per second, ring of {N_STATES} no-op states, best of {repeats}\n")
    print(f"{'':40} {'per second':>12} {'µs each':>9} {'vs ours':>8} {'vs ceiling':>10}")
    for name, rate in rows:
        print(f"{name:40} {rate:12,.0f} {1e6 / rate:9.3f} {rate / ours:8.2f}x "
              f"{rate / ceiling:9.1%}")
    print()
    print(f"skillcompose (trace off) vs py_trees: {ours / pyt:.1f}x  (target >= 10x)")
    print(f"skillcompose (trace off): {ours / 1e6:.2f} M transitions/s (target >= 2.00 M/s), "
          f"{ours / ceiling:.0%} of the dict-lookup ceiling")

    try:
        from benchmarks.bench_tickwise import bench_tickwise
    except ImportError as exc:  # pragma: no cover - the module ships with the repository
        print(f"(tick-wise rows unavailable: {exc})")
        return 0
    print("\nTick-wise mode: time per tick next to py_trees' per-behaviour tick\n")
    print(f"{'':45} {'µs per tick':>11} {'x py_trees':>10}")
    for row in bench_tickwise(n=steps // 100, repeats=repeats):
        print(f"{row['name']:45} {row['per_tick_us']:11.3f} {row['ratio']:10.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
