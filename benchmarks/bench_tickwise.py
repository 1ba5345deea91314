"""Tick-wise mode overhead per tick, next to py_trees' per-behaviour tick, in one run.

``bench_tickwise()`` returns rows ``{"name", "per_tick_us", "ratio"}``; ``ratio`` is the row's
time per tick over py_trees' time per behaviour tick measured in the same process. Rows:

- ``py_trees behaviour tick``: a ``Sequence`` (memory) of ``n`` ``Success`` behaviours ticked
  with ``tick_once``; time per child tick (the reference, ratio 1).
- ``run-to-completion step``: ``CompiledFSA.outcome`` on a chain of ``n`` instant skills; time
  per step (one skill call + transition).
- ``tick-wise, instant skill``: ``FSARun.tick`` on the same chain; time per tick.
- ``tick-wise, start/tick class`` and ``tick-wise, generator``: one long-running skill that
  runs ``n`` ticks; time per tick.
- ``FSABehaviour in a tree``: the instant chain as an ``FSABehaviour`` ticked by py_trees,
  blackboard bridge included; time per tree tick.

Run: ``python -m benchmarks.bench_tickwise``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Generator
from typing import Annotated, Any, Literal

import numpy as np
import py_trees

from skillcompose import FSA, Blackboard, Param, Registry, State, compile_fsa, skill
from skillcompose.bt import FSABehaviour


@skill(writes=("k",))
def _step(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    bb["k"] = 1
    return "success"


@skill(writes=("k",))
class _Spin:
    def start(self, bb: Blackboard, rng: np.random.Generator, *,
              n: Annotated[int, Param(1, 10**7)] = 10) -> None:
        self.left = n

    def tick(self, bb: Blackboard, rng: np.random.Generator
             ) -> Literal["running", "success"]:
        self.left -= 1
        bb["k"] = 1
        return "running" if self.left > 0 else "success"


@skill(writes=("k",))
def _spin_gen(bb: Blackboard, rng: np.random.Generator, *,
              n: Annotated[int, Param(1, 10**7)] = 10
              ) -> Generator[str, None, Literal["success"]]:
    for _ in range(n - 1):
        bb["k"] = 1
        yield "running"
    bb["k"] = 1
    return "success"


def _best(fn: Callable[[], Any], count: int, repeats: int) -> float:
    """Best of ``repeats`` timings of ``fn``, in µs per unit (``count`` units per call)."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best / count * 1e6


def _best_ticks(start: Callable[[], Any], count: int, repeats: int) -> float:
    """Like :func:`_best`, timing only the ticks of a run that ``start()`` begins."""
    best = float("inf")
    for _ in range(repeats):
        run = start()
        t0 = time.perf_counter()
        while run.tick() == "running":
            pass
        best = min(best, time.perf_counter() - t0)
        if run.result.outcome != "success" or run.ticks != count:
            raise RuntimeError(f"benchmark run ended badly: {run!r}")
    return best / count * 1e6


def _chain(n: int) -> FSA:
    return FSA({f"S{i}": State("Step", {}, {"success": f"S{i + 1}" if i + 1 < n else "success"})
                for i in range(n)}, "S0", step_limit=n + 1, name="chain")


def bench_tickwise(n: int = 20_000, repeats: int = 3) -> list[dict[str, Any]]:
    """Time per tick [µs] of each mode and its ratio to py_trees' per-behaviour tick."""
    spin_skill: Any = _Spin  # mypy ignores class decorators: it is a Skill
    reg = Registry([_step, spin_skill, _spin_gen])
    compiled = compile_fsa(_chain(n), reg)

    py_trees.blackboard.Blackboard.clear()
    seq = py_trees.composites.Sequence(
        "Seq", memory=True,
        children=[py_trees.behaviours.Success(name=f"b{i}") for i in range(n)],
    )

    def tree_once() -> None:
        seq.tick_once()
        assert seq.status == py_trees.common.Status.SUCCESS

    def fast() -> None:
        compiled.outcome(Blackboard(), np.random.default_rng(0))

    def ticked(c: Any) -> Callable[[], Any]:
        return lambda: c.start(Blackboard(), 0)

    spin = compile_fsa(FSA({"L": State("_Spin", {"n": n}, {"success": "success"})}, "L"), reg)
    gen = compile_fsa(FSA({"L": State("SpinGen", {"n": n}, {"success": "success"})}, "L"), reg)

    fb = FSABehaviour(compile_fsa(_chain(1000), reg), name="chain", show_states=False)

    def in_tree() -> None:
        fb.tick_once()
        while fb.status == py_trees.common.Status.RUNNING:
            fb.tick_once()

    ref = _best(tree_once, n, repeats)
    rows = [
        ("py_trees behaviour tick", ref),
        ("run-to-completion step", _best(fast, n, repeats)),
        ("tick-wise, instant skill", _best_ticks(ticked(compiled), n, repeats)),
        ("tick-wise, start/tick class", _best_ticks(ticked(spin), n, repeats)),
        ("tick-wise, generator", _best_ticks(ticked(gen), n, repeats)),
        ("FSABehaviour in a tree", _best(in_tree, 1000, repeats)),
    ]
    fb.shutdown()
    py_trees.blackboard.Blackboard.clear()
    return [{"name": name, "per_tick_us": us, "ratio": us / ref} for name, us in rows]


def main() -> None:
    for row in bench_tickwise():
        print(f"{row['name']:<30} {row['per_tick_us']:8.3f} µs/tick   "
              f"{row['ratio']:6.2f} × py_trees")


if __name__ == "__main__":
    main()
