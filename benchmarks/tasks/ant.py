"""The artificial ant: Jefferson et al.'s John Muir trail and Koza's Santa Fe trail.

Jefferson, Collins, Cooper, Dyer, Flowers, Korf, Taylor and Wang, "Evolution as a theme in
artificial life: the Genesys/Tracker system", Artificial Life II (1991): an ant on a 32 x 32
toroidal grid must eat the 89 food pellets of a broken trail (the "John Muir trail") within
200 time steps. Its one sensor says whether the cell ahead holds food; each time step it moves
one cell forward, or turns left or right, in place. Tracker evolved finite state automata
whose transitions read that sensor. The trail below is the public copy of the John Muir
world (32 x 32, 89 pellets, the ant at the top left corner facing east, the trail wrapping
round the grid's edges). ``trail="santa_fe"`` gives Koza's Santa Fe trail instead, the
best-known benchmark of genetic programming, with 600 time steps.

Here each action is a skill whose outcome is the sensor after the action (``food`` or
``empty`` ahead), so the FSA's transitions on those outcomes are the classic controller: a
state is an action, an edge the next action given what the ant sees. The run never ends by
itself; it stops at 200 steps (the task's step limit), and the fitness is the number of
pellets eaten (maximised; 89 solves it). Nothing is random: the task is deterministic.

A hand-written FSA of 5 states that looks left and right at each gap eats 81 pellets
(:data:`REFERENCE`); eating all 89 in 200 steps needs a controller that crosses the gaps
efficiently, with all but a few of the 200 steps: the 12-state :data:`SOLUTION`, found by
evolution, eats the last pellet at the 200th.

Usage: ``skillcompose evolve benchmarks.tasks.ant``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from skillcompose import FSA, Blackboard, Registry, State, skill
from skillcompose.task import Task

MUIR_TRAIL = (
    ".##########.....................",
    "..........#.....................",
    "..........#.....................",
    "..........#.....................",
    "..........#.....................",
    "####......#....#.........#######",
    "...#......#.............#.......",
    "...#......#...#.........#.......",
    "...#......#.#...........#.......",
    "...#......#.............#.......",
    "...########.............#.......",
    "...........#.......#####........",
    "..............#...#.............",
    "..................#.............",
    "...............#..#.............",
    "............#.....#.............",
    "..................#.............",
    "...........#......#.............",
    "........#.......................",
    "................................",
    "..................#.............",
    ".......#..........#.............",
    ".....#............#.............",
    "..................#.............",
    "....#.............#.............",
    "....#.............#.............",
    "....#...........................",
    "....#..####.######..............",
    "................................",
    "................................",
    "................................",
    "................................",
)
"""The John Muir trail, row 0 at the top; ``#`` is a food pellet. The ant starts at row 0,
column 0, facing east (towards growing columns)."""

SANTA_FE_TRAIL = (
    ".###............................",
    "...#............................",
    "...#.....................###....",
    "...#....................#....#..",
    "...#....................#....#..",
    "...####.#####........##.........",
    "............#................#..",
    "............#.......#...........",
    "............#.......#...........",
    "............#.......#........#..",
    "....................#...........",
    "............#...................",
    "............#................#..",
    "............#.......#...........",
    "............#.......#.....###...",
    ".................#.....#........",
    "................................",
    "............#...................",
    "............#...#.......#.......",
    "............#...#..........#....",
    "............#...#...............",
    "............#...#...............",
    "............#.............#.....",
    "............#..........#........",
    "...##..#####....#...............",
    ".#..............#...............",
    ".#..............#...............",
    ".#......#######.................",
    ".#.....#........................",
    ".......#........................",
    "..####..........................",
    "................................",
)
"""Koza's Santa Fe trail (Genetic Programming, 1992, chapter 7), drawn the same way: 89
pellets, the ant at the top left corner facing east."""

TRAILS = {"john_muir": MUIR_TRAIL, "santa_fe": SANTA_FE_TRAIL}
STEPS = {"john_muir": 200, "santa_fe": 600}
"""Time steps per trail: Jefferson et al.'s 200 on the John Muir trail; 600 on the Santa Fe
trail, the limit of the usual GP benchmark code (DEAP's example among them)."""
_HEADINGS = ((0, 1), (1, 0), (0, -1), (-1, 0))  # east, south, west, north (row, column)


@dataclass
class Ant:
    """The ant's world during one run: where it is, where it faces, what is left to eat."""

    food: set[tuple[int, int]]
    rows: int
    cols: int
    row: int = 0
    col: int = 0
    heading: int = 0  # index into _HEADINGS
    eaten: int = 0

    def ahead(self) -> tuple[int, int]:
        dr, dc = _HEADINGS[self.heading]
        return (self.row + dr) % self.rows, (self.col + dc) % self.cols

    def sense(self) -> Literal["food", "empty"]:
        return "food" if self.ahead() in self.food else "empty"


def parse_trail(lines: tuple[str, ...]) -> Ant:
    """A fresh ant at the top left corner facing east on the trail drawn by ``lines``."""
    food = {(r, c) for r, line in enumerate(lines) for c, ch in enumerate(line) if ch == "#"}
    return Ant(food=food, rows=len(lines), cols=len(lines[0]))


@skill(writes={"ant": Ant})
def move(bb: Blackboard, rng: np.random.Generator) -> Literal["food", "empty"]:
    """Step one cell forward (eating a pellet there); outcome: food ahead or not."""
    ant: Ant = bb["ant"]
    ant.row, ant.col = ant.ahead()
    if (ant.row, ant.col) in ant.food:
        ant.food.discard((ant.row, ant.col))
        ant.eaten += 1
    bb["ant"] = ant
    return ant.sense()


@skill(writes={"ant": Ant})
def turn_left(bb: Blackboard, rng: np.random.Generator) -> Literal["food", "empty"]:
    """Turn 90 degrees left in place; outcome: food ahead or not."""
    ant: Ant = bb["ant"]
    ant.heading = (ant.heading - 1) % 4
    bb["ant"] = ant
    return ant.sense()


@skill(writes={"ant": Ant})
def turn_right(bb: Blackboard, rng: np.random.Generator) -> Literal["food", "empty"]:
    """Turn 90 degrees right in place; outcome: food ahead or not."""
    ant: Ant = bb["ant"]
    ant.heading = (ant.heading + 1) % 4
    bb["ant"] = ant
    return ant.sense()


SKILLS = (move, turn_left, turn_right)


def _reference() -> FSA:
    # Move while food is ahead; otherwise look left, then right (twice: back and to the
    # other side), then left again and step on across the gap.
    return FSA(
        name="ant_reference",
        start="Move",
        states={
            "Move": State("Move", transitions={"food": "Move", "empty": "Left"}),
            "Left": State("TurnLeft", transitions={"food": "Move", "empty": "Right1"}),
            "Right1": State("TurnRight", transitions={"food": "Move", "empty": "Right2"}),
            "Right2": State("TurnRight", transitions={"food": "Move", "empty": "Back"}),
            "Back": State("TurnLeft", transitions={"food": "Move", "empty": "Move"}),
        },
        step_limit=STEPS["john_muir"],
    )


REFERENCE = _reference()
"""A 5-state hand-written ant (move while food is ahead, else look left and right): eats
81 of the 89 pellets of the John Muir trail in 200 steps."""


def _solution() -> FSA:
    # Found by evolution with --neutral (population 5, elitism 1, tournaments of 40, no
    # crossover, initial FSAs of 12 nodes, cache and unique children; seed 1, generation
    # 4,690), its states renamed: M* move, L* turn left, R* turn right.
    def st(skill: str, food: str, empty: str) -> State:
        return State(skill, transitions={"food": food, "empty": empty})

    return FSA(
        name="ant_john_muir_solution",
        start="M1",
        states={
            "M1": st("Move", "M2", "M3"),
            "M2": st("Move", "M4", "M1"),
            "M3": st("Move", "M3", "R1"),
            "M4": st("Move", "M5", "L1"),
            "M5": st("Move", "M3", "M1"),
            "M6": st("Move", "M7", "M4"),
            "M7": st("Move", "M6", "M1"),
            "L1": st("TurnLeft", "M6", "L1"),
            "R1": st("TurnRight", "M2", "R2"),
            "R2": st("TurnRight", "M6", "R3"),
            "R3": st("TurnRight", "M7", "R4"),
            "R4": st("TurnRight", "M2", "M3"),
        },
        step_limit=STEPS["john_muir"],
    )


SOLUTION = _solution()
"""A 12-state FSA that eats all 89 pellets of the John Muir trail within its 200 steps (each
move or turn one step), found by evolution: the trail is solvable in this encoding."""


def make_task(trail: str = "john_muir", steps: int | None = None) -> Task:
    """The ant task on ``trail`` (one of :data:`TRAILS`) with ``steps`` time steps (default:
    the trail's, :data:`STEPS`)."""
    if trail not in TRAILS:
        raise ValueError(f"trail={trail!r}: choose one of {', '.join(sorted(TRAILS))}")
    steps = STEPS[trail] if steps is None else steps
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ValueError(f"steps={steps!r}: expected a whole number of time steps >= 1")
    lines = TRAILS[trail]
    total = sum(line.count("#") for line in lines)
    registry = Registry()
    for s in SKILLS:
        registry.add(s)

    def setup(rng: np.random.Generator) -> Blackboard:
        return Blackboard({"ant": parse_trail(lines)})

    def fitness(outcome: str, bb: Blackboard, steps_run: int) -> float:
        return float(bb["ant"].eaten)

    return Task(
        name=f"ant_{trail}",
        registry=registry,
        setup=setup,
        fitness=fitness,
        minimize=False,
        target=float(total),
        step_limit=steps,
        trials=1,
        error_fitness=0.0,
        terminal_skills=(),
        deterministic=True,
        settings={"trail": trail, "steps": steps},
    )
