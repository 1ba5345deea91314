"""A behaviour tree that retries a pick FSA, then falls back to a recovery subtree.

The pick FSA (hand-written here; an evolved FSA file loads the same way with ``load_fsa``)
runs inside the tree as an :class:`~skillcompose.bt.FSABehaviour`, one FSA tick per tree
tick. Its skills are long-running: ``MoveArm`` is a start / tick / cancel class and ``Grasp``
a generator. Its ``CheckHold`` state is itself a small py_trees subtree registered as a skill
(tree in an FSA in a tree). The FSA's keys live under ``/pick`` on py_trees' blackboard, so
the recovery subtree reads ``/pick/attempts`` written by the FSA::

    python examples/bt_recovery.py --seed 3 --p-fail 0.6

prints the tree with py_trees' ASCII rendering (the FSA's states are shown inside its
behaviour), ticks it to the end and prints it again with each behaviour's status.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Generator
from typing import Annotated, Literal

import numpy as np
import py_trees
from py_trees.common import Status

from skillcompose import Blackboard, Param, Registry, loads_fsa, skill
from skillcompose.bt import FSABehaviour, SkillBehaviour, tree_skill

PICK_FSA = """\
format: 1
name: pick
start: Detect
step_limit: 12
states:
  Detect:
    skill: DetectObject
    transitions: {success: Reach, failure: failure}
  Reach:
    skill: MoveArm
    params:
      speed: 0.25        # m/tick
    transitions: {success: Grasp, failure: Detect}
  Grasp:
    skill: Grasp
    params:
      p_fail: 0.3
    transitions: {success: CheckHold, failure: failure}
  CheckHold:
    skill: CheckHold
    transitions: {success: success, failure: failure}
"""


@skill(writes={"object": np.ndarray, "attempts": int})
def detect_object(
    bb: Blackboard, rng: np.random.Generator
) -> Literal["success", "failure"]:
    """See the object: its position [m] in the robot frame, with noise."""
    bb["attempts"] = bb.get("attempts", 0) + 1
    bb["object"] = np.array([0.6, 0.1, 0.8]) + rng.normal(0.0, 0.01, 3)
    return "success"


@skill(reads=("object",), writes={"hand": np.ndarray})
class MoveArm:
    """Move the hand toward the object at ``speed`` [m/tick]; long-running."""

    def start(
        self, bb: Blackboard, rng: np.random.Generator, *,
        speed: Annotated[float, Param(0.05, 0.5, unit="m/tick")] = 0.2,
    ) -> None:
        self.speed = speed
        if "hand" not in bb:
            bb["hand"] = np.zeros(3)

    def tick(
        self, bb: Blackboard, rng: np.random.Generator
    ) -> Literal["running", "success", "failure"]:
        gap = bb["object"] - bb["hand"]
        dist = float(np.linalg.norm(gap))
        if dist <= self.speed:
            bb["hand"] = bb["object"].copy()
            return "success"
        bb["hand"] = bb["hand"] + gap / dist * self.speed
        return "running"

    def cancel(self, bb: Blackboard) -> None:
        bb["hand"] = bb["hand"].copy()  # stop where we are: nothing is left half-written


@skill(reads=("object", "hand"), writes=("holding",))
def grasp(
    bb: Blackboard, rng: np.random.Generator, *,
    p_fail: Annotated[float, Param(0.0, 1.0)] = 0.2,
) -> Generator[str, None, Literal["success", "failure"]]:
    """Close the gripper over two ticks; fails with probability ``p_fail``."""
    bb["holding"] = False
    try:
        yield "running"
        yield "running"
        bb["holding"] = bool(rng.random() >= p_fail)
        return "success" if bb["holding"] else "failure"
    except GeneratorExit:
        bb["holding"] = False  # cancelled: open the gripper again
        raise


@skill(writes={"hand": np.ndarray, "holding": bool})
def reset_arm(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    """Open the gripper and bring the hand home."""
    bb["hand"] = np.zeros(3)
    bb["holding"] = False
    return "success"


def check_hold_tree() -> py_trees.behaviour.Behaviour:
    """A py_trees subtree used as the FSA's ``CheckHold`` skill."""
    return py_trees.behaviours.CheckBlackboardVariableValue(
        name="Holding?",
        check=py_trees.common.ComparisonExpression("/pick/holding", True, lambda a, b: a == b),
    )


def build_tree(
    *, seed: int, p_fail: float, retries: int = 2
) -> tuple[py_trees.behaviour.Behaviour, FSABehaviour]:
    """The fallback ``Retry(pick FSA) || Recovery``; returns the root and the FSA behaviour."""
    registry = Registry()
    registry.load_module(sys.modules[__name__])  # the @skill objects defined above
    registry.add(tree_skill(check_hold_tree, name="CheckHold", reads=("holding",),
                            namespace="/pick"))
    fsa = loads_fsa(PICK_FSA, "bt_recovery:PICK_FSA").with_params("Grasp", p_fail=p_fail)
    pick = FSABehaviour(fsa, registry, name="Pick (FSA)", namespace="/pick", seed=seed)
    retry = py_trees.decorators.Retry("Retry", pick, num_failures=retries)
    gave_up = py_trees.behaviours.CheckBlackboardVariableValue(
        name="Tried?",
        check=py_trees.common.ComparisonExpression("/pick/attempts", 1, lambda a, b: a >= b),
    )
    home = SkillBehaviour(reset_arm, name="ResetArm", namespace="/pick", seed=seed)
    ask = py_trees.behaviours.SetBlackboardVariable(
        name="AskForHelp", variable_name="/recovery/help", variable_value=True,
        overwrite=True,
    )
    recovery = py_trees.composites.Sequence("Recovery", memory=True,
                                            children=[gave_up, home, ask])
    root = py_trees.composites.Selector("PickOrRecover", memory=False,
                                        children=[retry, recovery])
    return root, pick


def run(*, seed: int, p_fail: float, max_ticks: int = 200, show: bool = True
        ) -> tuple[Status, int, FSABehaviour]:
    """Tick the tree to its end; returns its final status, the ticks and the FSA behaviour."""
    py_trees.blackboard.Blackboard.clear()  # py_trees' blackboard is process-global
    root, pick = build_tree(seed=seed, p_fail=p_fail)
    tree = py_trees.trees.BehaviourTree(root)
    tree.setup()
    if show:
        print(py_trees.display.ascii_tree(root))
    ticks = 0
    while ticks < max_ticks:
        tree.tick()
        ticks += 1
        if root.status != Status.RUNNING:
            break
    if show:
        print(py_trees.display.ascii_tree(root, show_status=True))
        print(f"tree: {root.status.value} after {ticks} ticks; "
              f"FSA activations: {pick.activations}; last FSA run: {pick.last_result}")
        print(f"py_trees blackboard: {sorted(py_trees.blackboard.Blackboard.keys())}")
    tree.shutdown()
    return root.status, ticks, pick


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--p-fail", type=float, default=0.3,
                    help="failure probability of the grasp [0, 1]")
    ap.add_argument("--max-ticks", type=int, default=200)
    args = ap.parse_args(argv)
    status, _, _ = run(seed=args.seed, p_fail=args.p_fail, max_ticks=args.max_ticks)
    return 0 if status == Status.SUCCESS else 1


if __name__ == "__main__":
    raise SystemExit(main())
