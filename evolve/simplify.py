"""Simplification: remove the states of an evolved FSA that do not help.

The paper found redundant duplicate states in every evolved FSA (section 5). After a run,
:func:`simplify`

1. drops the states the start cannot reach;
2. merges exact duplicates: states with the same skill and parameters whose outcomes lead
   to equivalent states (partition refinement), which cannot change any run;
3. tries removing each state, re-routing its incoming edges to one of its successors
   (and a state to another state of the same skill; never to a terminal outcome when the
   task names its terminating skills), and keeps a removal when the mean
   fitness over ``trials`` fresh worlds is not worse than before and no fewer of those
   worlds are solved (a rare success is not traded for a slightly better mean). Every
   candidate meets the same worlds (common random numbers), so the comparison is paired.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from skillcompose import FSA
from skillcompose.task import Task

from .evaluation import Guard, evaluate_episodes

__all__ = ["merge_duplicates", "simplify"]


def merge_duplicates(fsa: FSA) -> FSA:
    """Merge states that behave identically (same skill, parameters and, outcome by outcome,
    equivalent targets): the coarsest such partition, found by refinement."""
    names = list(fsa.states)

    def sig(s: str) -> tuple[Any, ...]:
        st = fsa.states[s]
        return (st.skill, tuple(sorted((k, repr(v)) for k, v in st.params.items())))

    block = {s: sig(s) for s in names}
    while True:
        new: dict[str, Any] = {}
        for s in names:
            tr = fsa.states[s].transitions
            new[s] = (block[s], tuple(
                (o, ("state", block[t]) if t in fsa.states else ("end", t))
                for o, t in sorted(tr.items())
            ))
        if len(set(new.values())) == len(set(block.values())):
            break
        block = new
    keep: dict[Any, str] = {}
    alias: dict[str, str] = {}
    for s in fsa.reachable() + [s for s in names if s not in set(fsa.reachable())]:
        alias[s] = keep.setdefault(block[s], s)
    if all(alias[s] == s for s in names):
        return fsa
    states = {
        s: dataclasses.replace(
            st, transitions={o: alias.get(t, t) for o, t in st.transitions.items()}
        )
        for s, st in fsa.states.items() if alias[s] == s
    }
    return fsa.replace(states=states, start=alias[fsa.start]).pruned()


def _remove(fsa: FSA, victim: str, target: str) -> FSA:
    """``fsa`` without ``victim``, its incoming edges (and the start) sent to ``target``."""
    states = {
        s: dataclasses.replace(st, transitions={
            o: (target if t == victim else t) for o, t in st.transitions.items()
        })
        for s, st in fsa.states.items() if s != victim
    }
    start = target if fsa.start == victim else fsa.start
    if start not in states:
        return fsa
    return fsa.replace(states=states, start=start).pruned()


def simplify(
    task: Task, fsa: FSA, seed: int = 0, trials: int = 200, tolerance: float = 0.0,
    time_limit: float | None = None,
) -> FSA:
    """Remove states that do not help ``fsa`` on ``task`` (see the module docstring).

    A change is kept when the mean fitness over ``trials`` worlds drawn from ``seed`` is no
    worse than the current FSA's plus ``tolerance`` and its solved rate is no lower. The
    result records what was removed and the fitness before and after under
    ``meta['simplified']``. An episode that raises (``SystemExit`` included) or runs past
    ``time_limit`` seconds scores the task's worst fitness.
    """
    def measure(f: FSA) -> tuple[float, float]:
        """Mean fitness and solved rate (share of worlds at the task's target)."""
        try:
            compiled = task.compile(f)
        except Exception:
            return task.worst, 0.0
        with Guard(time_limit) as guard:
            scores = [f for f, _ in evaluate_episodes(task, compiled, seed, trials, guard)]
        return float(sum(scores) / len(scores)), sum(map(task.solved, scores)) / len(scores)

    def no_worse(a: tuple[float, float], b: tuple[float, float]) -> bool:
        fit = a[0] <= b[0] + tolerance if task.minimize else a[0] >= b[0] - tolerance
        return fit and a[1] >= b[1]  # never trade solved worlds for a better mean

    start_size = len(fsa.states)
    current = merge_duplicates(fsa.pruned())
    merged = start_size - len(current.states)
    before = measure(fsa)
    best = measure(current)
    removed: list[str] = [s for s in fsa.states if s not in current.states]
    changed = True
    while changed and len(current.states) > 1:
        changed = False
        for victim in list(current.states):
            if victim not in current.states:
                continue
            st = current.states[victim]
            targets = [t for t in dict.fromkeys(st.transitions.values()) if t != victim]
            targets += [
                s for s, o in current.states.items()
                if s != victim and o.skill == st.skill and s not in targets
            ]
            for target in targets:
                if target not in current.states and target not in current.terminals:
                    continue
                if target in current.terminals and (
                    current.start == victim or task.terminal_skills is not None
                ):
                    continue  # only the task's terminating skills may end a run
                cand = _remove(current, victim, target)
                if cand is current or len(cand.states) >= len(current.states):
                    continue
                f = measure(cand)
                if no_worse(f, best):
                    removed += [s for s in current.states if s not in cand.states]
                    current, best, changed = cand, f, True
                    break
    meta = {
        **dict(current.meta),
        "simplified": {
            "states_before": start_size,
            "states_after": len(current.states),
            "merged_duplicates": merged,
            "removed": removed,
            "fitness_before": before[0],
            "fitness_after": best[0],
            "solved_rate_before": before[1],
            "solved_rate_after": best[1],
            "trials": trials,
            "seed": seed,
        },
    }
    return current.replace(meta=meta)
