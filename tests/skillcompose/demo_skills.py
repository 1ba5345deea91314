"""Skills used by the core tests (and loadable with --skills tests.skillcompose.demo_skills)."""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np

from skillcompose import Blackboard, Choice, Param, skill


@skill(writes={"jug": tuple})
def recognise(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    """Write where the jug is."""
    bb["jug"] = (0.5, 0.0, 0.8)
    return "success"


@skill(reads=("jug",), writes=("gripper",))
def move_to_object(
    bb: Blackboard,
    rng: np.random.Generator,
    *,
    approach: Annotated[float, Param(0.05, 0.30, unit="m")] = 0.1,
    p_fail: Annotated[float, Param(0.0, 1.0)] = 0.2,
) -> Literal["success", "failure"]:
    """Move the gripper near the jug; fails at random."""
    if "jug" not in bb or rng.random() < p_fail:
        return "failure"
    x, y, z = bb["jug"]
    bb["gripper"] = (x - approach, y, z)
    return "success"


@skill(outcomes=("success", "failure"), reads=("gripper",), writes=("held",))
class GraspObject:
    """A class skill: counts its own calls (state kept across runs)."""

    def __init__(self) -> None:
        self.calls = 0

    def __call__(
        self,
        bb: Blackboard,
        rng: np.random.Generator,
        *,
        force: Annotated[int, Param(1, 10, unit="N")] = 5,
        arm: Annotated[str, Choice("left", "right")] = "left",
        careful: bool = False,
    ) -> str:
        self.calls += 1
        if bb.get("gripper") is None:
            return "failure"
        bb["held"] = arm
        return "success"


@skill
def noop(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    return "success"


@skill(writes=("count",))
def count(bb: Blackboard, rng: np.random.Generator) -> Literal["again", "done"]:
    n = bb.get("count", 0) + 1
    bb["count"] = n
    return "done" if n >= 3 else "again"


@skill
def explode(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    raise RuntimeError("motor fault")


@skill
def liar(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    return "sucess"  # type: ignore[return-value]


@skill(reads=("jug",))
def sneaky(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    bb["gripper"] = 1
    return "success"


@skill
def coin(
    bb: Blackboard, rng: np.random.Generator, *, p: Annotated[float, Param(0.0, 1.0)] = 0.5
) -> Literal["heads", "tails"]:
    return "heads" if rng.random() < p else "tails"
