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

Two forms (:mod:`benchmarks.tasks.forms`), chosen by ``form``:

- ``form="reporting"`` (the default, as above): ``Forward``, ``TurnLeft`` and ``TurnRight``
  report ``wall`` / ``open`` ahead; one FSA step is one action, and the task's step limit
  (1000) ends the run in ``timeout``.
- ``form="sensing"``: the sensing skill ``WallAhead`` (``yes`` / ``no``, no time step) and the
  actions ``Forward`` (``done``, or ``success`` after the last exit), ``TurnLeft`` and
  ``TurnRight`` (``done``). The robot counts its actions; the 1000th ends the run in
  ``time_up``, and the engine's step limit is set far above it, so it never cuts a run short.
  :func:`sensing` turns a reporting FSA into the sensing FSA that acts the same.

Reference result (tested): :data:`REFERENCE` finishes all four starts (fitness 4) in either
form, with the same actions.

Usage: ``skillcompose evolve benchmarks.tasks.maze --set form=sensing``.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Literal

import numpy as np

from skillcompose import FSA, Blackboard, Registry, State, skill
from skillcompose.task import Task

from .forms import MAX_SENSES, TIME_UP, check_form, sensing_step_limit, to_sensing

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
    actions: int = 0  # time steps used (the sensing form counts them here)
    senses: int = 0  # sensing steps since the last action (the sensing form)
    budget: int = 0  # time steps of the sensing form (0: the engine's step limit ends it)

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


def _start(leg: int, robot: Robot | None = None) -> Robot:
    """A robot at start ``leg``, keeping the clock of ``robot`` (the one carried there)."""
    r, c, h = STARTS[leg]
    new = Robot(r, c, h, leg)
    if robot is not None:
        new.actions, new.budget = robot.actions, robot.budget
    return new


def _step(robot: Robot) -> Literal["done", "success"] | None:
    """Forward's move: one cell unless a wall is there; at the exit, on to the next start.
    ``success`` after the last exit, ``done`` after another, else ``None``."""
    r, c = robot.ahead()
    if MAZE[r][c] != "#":
        robot.row, robot.col = r, c
    if MAZE[robot.row][robot.col] != "E":
        return None
    if robot.leg + 1 >= len(STARTS):
        robot.leg = len(STARTS)
        return "success"
    return "done"


@skill(writes={"robot": Robot})
def forward(bb: Blackboard, rng: np.random.Generator) -> Literal["wall", "open", "success"]:
    """Move one cell forward unless a wall is there; at the exit, go on to the next start
    (``success`` after the last); outcome: a wall ahead or not."""
    robot: Robot = bb["robot"]
    moved = _step(robot)
    if moved == "success":
        bb["robot"] = robot
        return "success"
    if moved == "done":
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


def _act(robot: Robot) -> Literal["done", "time_up"]:
    """Count a time step of the sensing form: ``time_up`` after the budget's last."""
    robot.actions += 1
    robot.senses = 0
    return TIME_UP if robot.actions >= robot.budget else "done"


@skill(writes={"robot": Robot})
def wall_ahead(bb: Blackboard, rng: np.random.Generator) -> Literal["yes", "no", "time_up"]:
    """Whether a wall is ahead; no time step (``time_up`` only after
    :data:`~benchmarks.tasks.forms.MAX_SENSES` sensing steps in a row: a loop that never
    acts)."""
    robot: Robot = bb["robot"]
    robot.senses += 1
    bb["robot"] = robot
    if robot.senses > MAX_SENSES:
        return TIME_UP
    return "yes" if robot.sense() == "wall" else "no"


@skill(name="Forward", writes={"robot": Robot})
def forward_done(bb: Blackboard,
                 rng: np.random.Generator) -> Literal["done", "success", "time_up"]:
    """Move one cell forward unless a wall is there; at the exit, go on to the next start
    (``success`` after the last); one time step."""
    robot: Robot = bb["robot"]
    moved = _step(robot)
    if moved == "done":
        robot = _start(robot.leg + 1, robot)
    bb["robot"] = robot
    end = _act(robot)
    return "success" if moved == "success" else end


@skill(name="TurnLeft", writes={"robot": Robot})
def turn_left_done(bb: Blackboard, rng: np.random.Generator) -> Literal["done", "time_up"]:
    """Turn 90 degrees left in place; one time step."""
    robot: Robot = bb["robot"]
    robot.heading = (robot.heading - 1) % 4
    bb["robot"] = robot
    return _act(robot)


@skill(name="TurnRight", writes={"robot": Robot})
def turn_right_done(bb: Blackboard, rng: np.random.Generator) -> Literal["done", "time_up"]:
    """Turn 90 degrees right in place; one time step."""
    robot: Robot = bb["robot"]
    robot.heading = (robot.heading + 1) % 4
    bb["robot"] = robot
    return _act(robot)


SENSING_SKILLS = (wall_ahead, forward_done, turn_left_done, turn_right_done)
"""The skills of ``form="sensing"``."""

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


def sensing(fsa: FSA, steps: int = STEPS) -> FSA:
    """The sensing-form FSA that takes the same actions as the reporting-form ``fsa`` (each
    action followed by ``WallAhead``), for ``steps`` time steps."""
    return to_sensing(fsa, "WallAhead", {"wall": "yes", "open": "no"},
                      sensing_step_limit(steps), keep=("success",))


def make_task(steps: int = STEPS, form: str = "reporting") -> Task:
    """The maze task with ``steps`` actions for all four starts, written in ``form``
    (``reporting`` or ``sensing``; see the module's docstring)."""
    form = check_form(form)
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ValueError(f"steps={steps!r}: expected a whole number of actions >= 1")
    registry = Registry()
    sensing_form = form == "sensing"
    for s in SENSING_SKILLS if sensing_form else SKILLS:
        registry.add(s)

    def setup(rng: np.random.Generator) -> Blackboard:
        robot = _start(0)
        robot.budget = steps if sensing_form else 0
        return Blackboard({"robot": robot})

    def fitness(outcome: str, bb: Blackboard, steps_run: int) -> float:
        return bb["robot"].progress()

    return Task(
        name="maze" + ("_sensing" if sensing_form else ""),
        registry=registry,
        setup=setup,
        fitness=fitness,
        minimize=False,
        target=float(len(STARTS)),
        step_limit=sensing_step_limit(steps) if sensing_form else steps,
        trials=1,
        error_fitness=0.0,
        # the sensing form: every skill's time_up (and Forward's success) ends the run
        terminal_skills=tuple(s.name for s in SENSING_SKILLS) if sensing_form
        else ("Forward",),
        terminals=("success", TIME_UP) if sensing_form else ("success", "failure"),
        deterministic=True,
        settings={"steps": steps, "form": form},
    )
