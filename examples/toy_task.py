"""A small fetch-and-place task with its own skills, for tests and benchmarks of evolution.

The robot must find a block, pick it up, carry it to the goal at ``goal`` metres along a
rail and put it down there, then end the run with ``success``. Picking and moving fail at
random with probability ``p_fail`` (the paper's noise, section 3.8), so a good FSA retries.
Only one order of skills and one carry distance (within ``tolerance``) solve it; the fitness
(minimised, shaped like the paper's equation 1) rewards getting the block close::

    f = 0        if the run ends in success with the block put down at the goal
        10       if the block was never picked up
        2 * e    if the run timed out
        e        otherwise, where e = |block - goal| (+ 1 while the block is still held)

A hand-written solution::

    FindBlock -> PickBlock (failure: retry) -> Carry(distance=0.7) (failure: retry)
              -> PutDown -> success

Usage: ``skillcompose evolve examples.toy_task --set p_fail=0.1``.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np

from skillcompose import Blackboard, Param, Registry, skill
from skillcompose.task import Task

GOAL_M = 0.7


@skill(writes={"block_seen": bool})
def find_block(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    """Look for the block; always finds it."""
    bb["block_seen"] = True
    return "success"


@skill(reads=("block_seen", "p_fail"), writes={"holding": bool})
def pick_block(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    """Grasp the block; fails when it was not seen, or at random."""
    if not bb.get("block_seen", False) or rng.random() < bb["p_fail"]:
        return "failure"
    bb["holding"] = True
    return "success"


@skill(reads=("holding", "p_fail"), writes={"gripper_m": float, "block_m": float})
def carry(
    bb: Blackboard, rng: np.random.Generator, *,
    distance: Annotated[float, Param(0.0, 1.0, unit="m")] = 0.5,
) -> Literal["success", "failure"]:
    """Move the gripper (and the block, when held) to ``distance`` along the rail."""
    if rng.random() < bb["p_fail"]:
        return "failure"
    bb["gripper_m"] = float(distance)
    if bb.get("holding", False):
        bb["block_m"] = float(distance)
    return "success"


@skill(reads=("holding",), writes={"holding": bool, "placed": bool})
def put_down(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    """Release the block where the gripper is; fails when nothing is held."""
    if not bb.get("holding", False):
        return "failure"
    bb["holding"] = False
    bb["placed"] = True
    return "success"


@skill(writes=("waited",))
def wait(
    bb: Blackboard, rng: np.random.Generator, *,
    seconds: Annotated[float, Param(0.1, 5.0, unit="s")] = 1.0,
) -> Literal["success"]:
    """Do nothing useful (a distractor evolution must learn to leave out)."""
    bb["waited"] = float(seconds)
    return "success"


SKILLS = (find_block, pick_block, carry, put_down, wait)


def register(registry: Registry) -> None:
    for s in SKILLS:
        registry.add(s)


def make_task(
    p_fail: float = 0.1, goal: float = GOAL_M, tolerance: float = 0.05, trials: int = 1,
    step_limit: int = 20,
) -> Task:
    """The toy task. ``p_fail``: failure probability of picking and carrying."""
    registry = Registry()
    register(registry)

    def setup(rng: np.random.Generator) -> Blackboard:
        return Blackboard({"p_fail": float(p_fail), "block_m": float(rng.uniform(0.0, 0.2)),
                           "holding": False, "placed": False})

    def fitness(outcome: str, bb: Blackboard, steps: int) -> float:
        d = abs(float(bb["block_m"]) - goal)
        if outcome == "success" and bb["placed"] and d <= tolerance:
            return 0.0
        if not (bb["holding"] or bb["placed"]):
            return 10.0
        base = d if bb["placed"] else d + 1.0
        return 2 * base if outcome == "timeout" else base

    return Task(
        name="toy_fetch",
        registry=registry,
        setup=setup,
        fitness=fitness,
        minimize=True,
        target=0.0,
        step_limit=step_limit,
        trials=trials,
        settings={"p_fail": p_fail, "goal": goal, "tolerance": tolerance, "trials": trials,
                  "step_limit": step_limit},
    )
