"""A maze robot with one wall-ahead sensor: the wall-following FSA benchmark.

Wall following is the classic controller a finite state machine with a single bumper or
range sensor can run (Koza 1992, section 13.1, evolved one for a robot in an irregular room;
evolutionary robotics has used mazes with such robots since). Here a robot on the grid
of :data:`MAZE`, a perfect maze of 7 x 7 cells (every two cells joined by exactly one path),
must reach the exit ``E`` from each of the four corners in turn: when it reaches the exit it
is carried to the next start, and after the last one its ``Forward`` ends the run in
``success``. Its skills move one cell forward (not at all into a wall) or turn 90 degrees in
place; each outcome says whether a wall is ahead after the action. No path can be learnt by
heart for all four starts in the step budget: the FSA has to follow a wall (a 3-state
hand-written FSA, :data:`REFERENCE`, keeps its left hand on the wall and solves it).

Fitness (maximised): the starts finished, plus, for the start under way, the share of its
distance to the exit (along the maze) it has covered; 4 solves it. Deterministic.

Usage: ``skillcompose evolve benchmarks.tasks.maze``.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Literal

import numpy as np

from skillcompose import FSA, Blackboard, Registry, State, skill
from skillcompose.task import Task

MAZE = (
    "###############",
    "#...#.......#.#",
    "###.#.#.###.#.#",
    "#...#.#.#.#.#.#",
    "#.###.#.#.#.#.#",
    "#.#...#.#.#.#.#",
    "#.#####.#.#.#.#",
    "#.#.....#...#.#",
    "#.#.#####.###.#",
    "#.#...#E..#...#",
    "#.###.#.###.#.#",
    "#...#.#.....#.#",
    "###.#.#######.#",
    "#.....#.......#",
    "###############",
)
"""``#`` wall, ``.`` floor, ``E`` the exit (row 0 at the top)."""

STARTS = ((1, 1, 0), (1, 13, 1), (13, 13, 3), (13, 1, 0))
"""(row, column, heading) of each start, in order; headings index :data:`_HEADINGS`."""

_HEADINGS = ((0, 1), (1, 0), (0, -1), (-1, 0))  # east, south, west, north (row, column)
STEPS = 1000


def _distances(maze: tuple[str, ...]) -> dict[tuple[int, int], int]:
    """Steps along the maze from every floor cell to the exit."""
    exit_cell = next((r, c) for r, line in enumerate(maze) for c, ch in enumerate(line)
                     if ch == "E")
    dist = {exit_cell: 0}
    queue = deque([exit_cell])
    while queue:
        r, c = queue.popleft()
        for dr, dc in _HEADINGS:
            n = (r + dr, c + dc)
            if maze[n[0]][n[1]] != "#" and n not in dist:
                dist[n] = dist[(r, c)] + 1
                queue.append(n)
    return dist


DISTANCE = _distances(MAZE)


@dataclass
class Robot:
    """The robot during one run: its cell, its heading, and which start it is on."""

    row: int
    col: int
    heading: int
    leg: int = 0  # index into STARTS of the start under way; len(STARTS): all done

    def ahead(self) -> tuple[int, int]:
        dr, dc = _HEADINGS[self.heading]
        return self.row + dr, self.col + dc

    def sense(self) -> Literal["wall", "open"]:
        r, c = self.ahead()
        return "wall" if MAZE[r][c] == "#" else "open"

    def progress(self) -> float:
        """Starts finished plus the covered share of the current one's distance."""
        if self.leg >= len(STARTS):
            return float(len(STARTS))
        r, c, _ = STARTS[self.leg]
        return self.leg + 1.0 - DISTANCE[(self.row, self.col)] / DISTANCE[(r, c)]


def _start(leg: int) -> Robot:
    r, c, h = STARTS[leg]
    return Robot(r, c, h, leg)


@skill(writes={"robot": Robot})
def forward(bb: Blackboard, rng: np.random.Generator) -> Literal["wall", "open", "success"]:
    """Move one cell forward unless a wall is there; at the exit, go on to the next start
    (``success`` after the last); outcome: a wall ahead or not."""
    robot: Robot = bb["robot"]
    r, c = robot.ahead()
    if MAZE[r][c] != "#":
        robot.row, robot.col = r, c
    if MAZE[robot.row][robot.col] == "E":
        if robot.leg + 1 >= len(STARTS):
            robot.leg = len(STARTS)
            bb["robot"] = robot
            return "success"
        robot = _start(robot.leg + 1)
    bb["robot"] = robot
    return robot.sense()


@skill(writes={"robot": Robot})
def turn_left(bb: Blackboard, rng: np.random.Generator) -> Literal["wall", "open"]:
    """Turn 90 degrees left in place; outcome: a wall ahead or not."""
    robot: Robot = bb["robot"]
    robot.heading = (robot.heading - 1) % 4
    bb["robot"] = robot
    return robot.sense()


@skill(writes={"robot": Robot})
def turn_right(bb: Blackboard, rng: np.random.Generator) -> Literal["wall", "open"]:
    """Turn 90 degrees right in place; outcome: a wall ahead or not."""
    robot: Robot = bb["robot"]
    robot.heading = (robot.heading + 1) % 4
    bb["robot"] = robot
    return robot.sense()


SKILLS = (forward, turn_left, turn_right)

REFERENCE = FSA(
    name="maze_reference",
    start="Left",
    states={
        # keep the left hand on the wall: after each step look left; go where it is open,
        # else turn right until it is
        "Forward": State("Forward", transitions={"wall": "Left", "open": "Left",
                                                 "success": "success"}),
        "Left": State("TurnLeft", transitions={"open": "Forward", "wall": "Right"}),
        "Right": State("TurnRight", transitions={"open": "Forward", "wall": "Right"}),
    },
    step_limit=STEPS,
)
"""A hand-written left-hand wall follower (3 states) that solves the maze."""


def make_task(steps: int = STEPS) -> Task:
    """The maze task with ``steps`` actions for all four starts."""
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ValueError(f"steps={steps!r}: expected a whole number of actions >= 1")
    registry = Registry()
    for s in SKILLS:
        registry.add(s)

    def setup(rng: np.random.Generator) -> Blackboard:
        return Blackboard({"robot": _start(0)})

    def fitness(outcome: str, bb: Blackboard, steps_run: int) -> float:
        return bb["robot"].progress()

    return Task(
        name="maze",
        registry=registry,
        setup=setup,
        fitness=fitness,
        minimize=False,
        target=float(len(STARTS)),
        step_limit=steps,
        trials=1,
        error_fitness=0.0,
        terminal_skills=("Forward",),
        deterministic=True,
        settings={"steps": steps},
    )
