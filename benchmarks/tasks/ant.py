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

Two forms (:mod:`benchmarks.tasks.forms`), chosen by ``form``:

- ``form="reporting"`` (the default, as above, Jefferson-style): the actions ``Move``,
  ``TurnLeft``, ``TurnRight`` report ``food`` / ``empty`` ahead; one FSA step is one time
  step and the task's step limit is the trail's time limit.
- ``form="sensing"`` (Koza's ant: ``IF-FOOD-AHEAD`` costs no time, only ``MOVE``, ``LEFT``
  and ``RIGHT`` do): the sensing skill ``FoodAhead`` (``yes`` / ``no``, no time step) and the
  actions ``Move``, ``TurnLeft``, ``TurnRight`` whose outcome is ``done``. The ant counts its
  actions and the last one of the trail's budget (600 on the Santa Fe trail, Koza's) ends
  the run in ``time_up``; the engine's step limit is set far above (every action preceded by
  500 sensing steps), so it never cuts a run short. :func:`sensing` turns a reporting FSA
  into the sensing FSA that acts the same: both eat the same pellets.

Reference results (tested): :data:`REFERENCE` eats 81 pellets of the John Muir trail in 200
steps and all 89 of the Santa Fe trail in 600, in either form; :data:`SOLUTION` eats all 89
of the John Muir trail in 200, in either form.

Usage: ``skillcompose evolve benchmarks.tasks.ant --set trail=santa_fe --set form=sensing``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from skillcompose import FSA, Blackboard, Registry, State, skill
from skillcompose.task import Task

from .forms import MAX_SENSES, TIME_UP, check_form, sensing_step_limit, to_sensing

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
    actions: int = 0  # time steps used (the sensing form counts them here)
    senses: int = 0  # sensing steps since the last action (the sensing form)
    budget: int = 0  # time steps of the sensing form (0: the engine's step limit ends it)

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


def _act(ant: Ant) -> Literal["done", "time_up"]:
    """Count a time step of the sensing form: ``time_up`` after the budget's last."""
    ant.actions += 1
    ant.senses = 0
    return TIME_UP if ant.actions >= ant.budget else "done"


@skill(writes={"ant": Ant})
def food_ahead(bb: Blackboard, rng: np.random.Generator) -> Literal["yes", "no", "time_up"]:
    """Whether the cell ahead holds food; no time step (``time_up`` only after
    :data:`~benchmarks.tasks.forms.MAX_SENSES` sensing steps in a row: a loop that never
    acts)."""
    ant: Ant = bb["ant"]
    ant.senses += 1
    bb["ant"] = ant
    if ant.senses > MAX_SENSES:
        return TIME_UP
    return "yes" if ant.sense() == "food" else "no"


@skill(name="Move", writes={"ant": Ant})
def move_done(bb: Blackboard, rng: np.random.Generator) -> Literal["done", "time_up"]:
    """Step one cell forward, eating a pellet there; one time step."""
    ant: Ant = bb["ant"]
    ant.row, ant.col = ant.ahead()
    if (ant.row, ant.col) in ant.food:
        ant.food.discard((ant.row, ant.col))
        ant.eaten += 1
    bb["ant"] = ant
    return _act(ant)


@skill(name="TurnLeft", writes={"ant": Ant})
def turn_left_done(bb: Blackboard, rng: np.random.Generator) -> Literal["done", "time_up"]:
    """Turn 90 degrees left in place; one time step."""
    ant: Ant = bb["ant"]
    ant.heading = (ant.heading - 1) % 4
    bb["ant"] = ant
    return _act(ant)


@skill(name="TurnRight", writes={"ant": Ant})
def turn_right_done(bb: Blackboard, rng: np.random.Generator) -> Literal["done", "time_up"]:
    """Turn 90 degrees right in place; one time step."""
    ant: Ant = bb["ant"]
    ant.heading = (ant.heading + 1) % 4
    bb["ant"] = ant
    return _act(ant)


SENSING_SKILLS = (food_ahead, move_done, turn_left_done, turn_right_done)
"""The skills of ``form="sensing"``."""


def sensing(fsa: FSA, steps: int) -> FSA:
    """The sensing-form FSA that takes the same actions as the reporting-form ``fsa`` (each
    action followed by ``FoodAhead``), for ``steps`` time steps."""
    return to_sensing(fsa, "FoodAhead", {"food": "yes", "empty": "no"},
                      sensing_step_limit(steps))


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


def make_task(trail: str = "john_muir", steps: int | None = None,
              form: str = "reporting") -> Task:
    """The ant task on ``trail`` (one of :data:`TRAILS`) with ``steps`` time steps (default:
    the trail's, :data:`STEPS`), written in ``form`` (``reporting`` or ``sensing``; see the
    module's docstring)."""
    if trail not in TRAILS:
        raise ValueError(f"trail={trail!r}: choose one of {', '.join(sorted(TRAILS))}")
    form = check_form(form)
    steps = STEPS[trail] if steps is None else steps
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ValueError(f"steps={steps!r}: expected a whole number of time steps >= 1")
    lines = TRAILS[trail]
    total = sum(line.count("#") for line in lines)
    registry = Registry()
    for s in SKILLS if form == "reporting" else SENSING_SKILLS:
        registry.add(s)
    budget = steps if form == "sensing" else 0

    def setup(rng: np.random.Generator) -> Blackboard:
        ant = parse_trail(lines)
        ant.budget = budget
        return Blackboard({"ant": ant})

    def fitness(outcome: str, bb: Blackboard, steps_run: int) -> float:
        return float(bb["ant"].eaten)

    sensing_form = form == "sensing"
    return Task(
        name=f"ant_{trail}" + ("_sensing" if sensing_form else ""),
        registry=registry,
        setup=setup,
        fitness=fitness,
        minimize=False,
        target=float(total),
        step_limit=sensing_step_limit(steps) if sensing_form else steps,
        trials=1,
        error_fitness=0.0,
        # the sensing form: every skill's time_up ends the run, every other edge is a state's
        terminal_skills=tuple(s.name for s in SENSING_SKILLS) if sensing_form else (),
        terminals=(TIME_UP,) if sensing_form else ("success", "failure"),
        deterministic=True,
        settings={"trail": trail, "steps": steps, "form": form},
    )
