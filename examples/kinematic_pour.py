"""Pour water on the PR2: the hand-written pour-water FSA, unchanged, on kinematic skills.

The reference FSA ``examples/pour_water_reference.fsa.yaml`` was written (and evolved FSAs
are found) against the abstract ``"sim"`` skills of :mod:`skillcompose.skills.pour_water`.
This task is ``examples.pour_water`` with ``backend=kinematic`` (that world, setup and
fitness, equation (1)) under its own name: the same FSA on the ``"kinematic"`` skills of
:mod:`skillcompose.skills.kinematic`, where IK, joint limits and the table decide whether a
motion succeeds, not ``p_fail``. The robot stands at the world origin facing +x; the table
is :data:`skillcompose.skills.kinematic_world.DEFAULT_TABLE_WORLD`.

Run it::

    python -m examples.kinematic_pour --runs 50
    skillcompose run examples/pour_water_reference.fsa.yaml --task examples.kinematic_pour

Settings (``make_task(**settings)``): ``trials`` (default 1), ``step_limit`` (default 20).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections import Counter
from pathlib import Path

from examples import pour_water as pour_water_task
from skillcompose import Registry, compile_fsa, load_fsa
from skillcompose.skills import kinematic, pour_water
from skillcompose.task import Task

__all__ = ["REFERENCE_FSA", "main", "make_task", "register", "run_reference"]

REFERENCE_FSA = Path(__file__).with_name("pour_water_reference.fsa.yaml")


def register(registry: Registry) -> None:
    """Both backends of the pour-water skills (and the other kinematic skills)."""
    pour_water.register(registry)
    kinematic.register(registry)


def make_task(*, trials: int = 1, step_limit: int = 20) -> Task:
    """The pour-water task of :mod:`examples.pour_water` on the kinematic backend
    (``make_task(backend="kinematic")``: the same world, fitness and terminating skill, with
    the kinematic skills' registry), named ``kinematic_pour``."""
    base = pour_water_task.make_task(backend="kinematic", trials=trials, step_limit=step_limit)
    return dataclasses.replace(
        base, name="kinematic_pour", settings={"trials": trials, "step_limit": step_limit})


def run_reference(runs: int, seed: int = 0) -> tuple[int, Counter[str], float]:
    """Run the reference FSA ``runs`` times on the kinematic backend.

    Returns (runs solved, i.e. fitness 0; outcome counts; mean seconds per run).
    """
    task = make_task()
    compiled = compile_fsa(load_fsa(REFERENCE_FSA), task.registry, "kinematic")
    solved = 0
    outcomes: Counter[str] = Counter()
    start = time.perf_counter()
    for result, score in task.run_trials(compiled, seed, runs):
        outcomes[result.outcome] += 1
        solved += task.solved(score)
    return solved, outcomes, (time.perf_counter() - start) / max(runs, 1)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20, help="runs of the reference FSA")
    parser.add_argument("--seed", type=int, default=0, help="seed of the runs' generators")
    args = parser.parse_args(argv)
    if args.runs < 1:
        parser.error("--runs must be at least 1")
    solved, outcomes, seconds = run_reference(args.runs, args.seed)
    print(f"reference FSA on the kinematic backend: solved {solved}/{args.runs} "
          f"({100.0 * solved / args.runs:.1f}%), outcomes {dict(outcomes)}, "
          f"{1e3 * seconds:.1f} ms per run")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
