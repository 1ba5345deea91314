"""Koza's lawnmower: mow every cell of an 8 x 8 toroidal lawn, with a jump whose vector matters.

Koza, Genetic Programming II (1994), chapter 8: a mower on a toroidal lawn of 8 x 8 cells
starts at row 4, column 4 facing north; ``MOW`` moves it one cell forward and mows the cell
it arrives on, ``LEFT`` turns it 90 degrees left in place, and ``FROG(v)`` jumps it by the
vector ``v`` (wrapping round the lawn) and mows the cell it lands on. Koza's programs ran
until 100 ``LEFT``\\s or 100 ``MOW``\\s were done; how ``FROG`` was counted was not read here:
here a ``Frog`` counts as a ``Mow`` (it moves and mows), so a run ends after 100 moving
actions (``Mow`` or ``Frog``) or 100 turns, whichever comes first, with the outcome
``time_up``. The start cell is not mown until the mower comes back to it.

Representation (one form: Koza's mower has no sensor): the skills ``Mow``, ``Left`` and
``Frog(dx, dy)``, each one time step, whose only outcome is ``done`` (``time_up`` after the
budget's last action ends the run). An FSA is then a fixed cycle of actions. ``Frog``'s two
real parameters ``dx``, ``dy`` in [0, 8] cells are the jump east and south, each rounded
down and taken modulo 8: they matter (a cycle of ``Frog(1, 0)`` and seven ``Mow``\\s mows the
lawn column by column; ``Frog(0, 0)`` mows nothing new). Deterministic.

Fitness (maximised): the cells mown, 64 solves it. :data:`REFERENCE` (8 states: the jump and
seven mows) mows all 64 in 64 moving actions (tested).

Usage: ``skillcompose evolve benchmarks.tasks.lawnmower``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated, Literal

import numpy as np

from skillcompose import FSA, Blackboard, Param, Registry, State, skill
from skillcompose.task import Task

from .forms import TIME_UP

SIZE = 8
"""The lawn is SIZE x SIZE cells, wrapping round its edges."""
START = (4, 4)
"""(row, column) of the start cell; the mower faces north (towards row 0)."""
BUDGET = 100
"""Moving actions (Mow, Frog) or turns (Left) after which the run ends, Koza's 100."""
_HEADINGS = ((-1, 0), (0, -1), (1, 0), (0, 1))  # north, west, south, east: each Left the next


@dataclass
class Mower:
    """The mower during one run: its cell, its heading, the cells mown and its counts."""

    row: int = START[0]
    col: int = START[1]
    heading: int = 0  # index into _HEADINGS
    mown: set[tuple[int, int]] = field(default_factory=set)
    moves: int = 0
    turns: int = 0

    def arrive(self, row: int, col: int) -> Literal["done", "time_up"]:
        """Move to (row, col) (wrapped), mow it, and count a moving action."""
        self.row, self.col = row % SIZE, col % SIZE
        self.mown.add((self.row, self.col))
        self.moves += 1
        return self.clock()

    def clock(self) -> Literal["done", "time_up"]:
        return TIME_UP if max(self.moves, self.turns) >= BUDGET else "done"


@skill(writes={"mower": Mower})
def mow(bb: Blackboard, rng: np.random.Generator) -> Literal["done", "time_up"]:
    """Move one cell forward and mow it; one moving action."""
    m: Mower = bb["mower"]
    dr, dc = _HEADINGS[m.heading]
    out = m.arrive(m.row + dr, m.col + dc)
    bb["mower"] = m
    return out


@skill(writes={"mower": Mower})
def left(bb: Blackboard, rng: np.random.Generator) -> Literal["done", "time_up"]:
    """Turn 90 degrees left in place; one turn."""
    m: Mower = bb["mower"]
    m.heading = (m.heading + 1) % 4
    m.turns += 1
    bb["mower"] = m
    return m.clock()


@skill(writes={"mower": Mower})
def frog(
    bb: Blackboard, rng: np.random.Generator, *,
    dx: Annotated[float, Param(0.0, 8.0, unit="cells")] = 1.0,
    dy: Annotated[float, Param(0.0, 8.0, unit="cells")] = 0.0,
) -> Literal["done", "time_up"]:
    """Jump ``floor(dx)`` cells east and ``floor(dy)`` south (modulo 8) and mow the cell
    landed on; one moving action."""
    m: Mower = bb["mower"]
    out = m.arrive(m.row + int(dy), m.col + int(dx))
    bb["mower"] = m
    return out


SKILLS = (mow, left, frog)


def _reference() -> FSA:
    # the jump to the next column, then seven mows north: the column mown, the mower one row
    # further south each round, back on the start column at the eighth
    states = {"Jump": State("Frog", params={"dx": 1.0, "dy": 0.0},
                            transitions={"done": "Mow1", TIME_UP: TIME_UP})}
    for k in range(1, 8):
        states[f"Mow{k}"] = State("Mow", transitions={
            "done": f"Mow{k + 1}" if k < 7 else "Jump", TIME_UP: TIME_UP})
    return FSA(name="lawnmower_reference", start="Jump", states=states,
               terminals=(TIME_UP,), step_limit=2 * BUDGET)


REFERENCE = _reference()
"""An 8-state hand-written mower: ``Frog(1, 0)`` and seven ``Mow``\\s, round and round; mows
all 64 cells."""


def make_task() -> Task:
    """Koza's lawnmower on the 8 x 8 lawn."""
    registry = Registry()
    for s in SKILLS:
        registry.add(s)

    def setup(rng: np.random.Generator) -> Blackboard:
        return Blackboard({"mower": Mower()})

    def fitness(outcome: str, bb: Blackboard, steps_run: int) -> float:
        return float(len(bb["mower"].mown))

    return Task(
        name="lawnmower",
        registry=registry,
        setup=setup,
        fitness=fitness,
        minimize=False,
        target=float(SIZE * SIZE),
        step_limit=2 * BUDGET,  # 100 of one kind ends it: at most 199 actions
        trials=1,
        error_fitness=0.0,
        terminal_skills=tuple(s.name for s in SKILLS),
        terminals=(TIME_UP,),
        deterministic=True,
        settings={},
    )
