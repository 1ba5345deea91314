"""Skills and FSAs shared by the behaviour-tree and tick-wise tests (``test_bt``,
``test_ticking``): instant, start/tick/cancel and generator skills in one registry."""

from __future__ import annotations

from collections.abc import Generator
from typing import Annotated, Any, Literal

import numpy as np

from skillcompose import FSA, Blackboard, Param, Registry, Skill, State, skill


class Calls:
    """Counts cancel hooks by skill name; one per test (no global state)."""

    def __init__(self) -> None:
        self.cancels: dict[str, int] = {}

    def cancel(self, name: str) -> None:
        self.cancels[name] = self.cancels.get(name, 0) + 1


def as_skill(obj: Any) -> Skill:
    """A decorated class, typed as what ``@skill`` made of it (mypy ignores class
    decorators' return types, so it still sees the class)."""
    if not isinstance(obj, Skill):
        raise TypeError(f"{obj!r} is not a skill")
    return obj


def make_registry(calls: Calls) -> Registry:
    """Instant, start/tick/cancel and generator skills; random outcomes and writes."""

    @skill(writes=("count",))
    def bump(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
        bb["count"] = bb.get("count", 0) + 1
        return "success" if rng.random() < 0.8 else "failure"

    @skill(reads=("count",), writes=("pos",))
    class Move:
        def start(
            self, bb: Blackboard, rng: np.random.Generator, *,
            n: Annotated[int, Param(1, 10)] = 3,
        ) -> None:
            self.left = n
            bb["pos"] = 0.0

        def tick(
            self, bb: Blackboard, rng: np.random.Generator
        ) -> Literal["running", "success", "failure"]:
            self.left -= 1
            bb["pos"] = bb["pos"] + float(rng.normal(1.0, 0.1))
            if self.left > 0:
                return "running"
            return "success" if rng.random() < 0.7 else "failure"

        def cancel(self, bb: Blackboard) -> None:
            calls.cancel("Move")
            bb["pos"] = -1.0

    @skill(writes=("waited",))
    def wait(
        bb: Blackboard, rng: np.random.Generator, *,
        n: Annotated[int, Param(1, 5)] = 2,
    ) -> Generator[str, None, Literal["success", "failure"]]:
        try:
            for i in range(n):
                bb["waited"] = i
                yield "running"
            return "success" if rng.random() < 0.9 else "failure"
        except GeneratorExit:
            calls.cancel("Wait")
            bb["waited"] = -1
            raise

    return Registry([bump, as_skill(Move), wait])


def mixed_fsa(name: str = "mixed") -> FSA:
    return FSA(
        {
            "A": State("Bump", {}, {"success": "B", "failure": "A"}),
            "B": State("Move", {"n": 3}, {"success": "C", "failure": "A"}),
            "C": State("Wait", {"n": 2}, {"success": "success", "failure": "B"}),
        },
        "A", step_limit=5, name=name,
    )
