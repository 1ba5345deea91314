"""Tartarus: a bulldozer pushes boxes to the walls of a 6 x 6 board (Teller 1994).

Teller, "The evolution of mental models", Advances in Genetic Programming (1994); evolved
finite state controllers for it were studied by Ashlock and others. Rules as used here: a
6 x 6 board walled round; 6 boxes placed at random in its inner 4 x 4 cells, never four in a
2 x 2 block (such a block could never be moved); the bulldozer on another inner cell, facing
north, east, south or west at random. Each time step it turns 90 degrees left or right in
place, or moves forward one cell; a box ahead is pushed one cell if the cell beyond it is
free (neither wall nor box), else nothing moves. After 80 time steps each box on an edge cell
scores 1 and each box in a corner 2 (at most 10: four corners and two edges).

Representation (sensing, the natural one for Tartarus's eight sensors): eight sensing skills,
one per cell around the dozer relative to its heading (``Front``, ``FrontLeft``,
``FrontRight``, ``Left``, ``Right``, ``BackLeft``, ``Back``, ``BackRight``), each with the
outcomes ``empty`` / ``box`` / ``wall`` and no time step, and the actions ``Forward``,
``TurnLeft``, ``TurnRight`` (``done``), one time step each; the world counts them (see
:mod:`benchmarks.tasks.forms`: ``time_up`` ends the run, the engine's step limit set far
above).

Boards: ``boards`` boards (default 10) drawn once from ``board_seed`` (default 0), played one
after another in one episode, 80 time steps each; the FSA is not reset between boards (its
state carries over, as the maze's does between its starts; Teller's and Ashlock's runs
started each board afresh). The task is deterministic; fitness (maximised) is the mean score
per board, and "solved" is a mean of ``target`` (default 4.0, our choice, made before any
run: no published threshold applies) or more. :data:`REFERENCE` (a hand-written pusher:
forward, push a box four times, turn right at walls) scores 1.5 on the default boards
(:data:`REFERENCE_SCORE`, tested).

Usage: ``skillcompose evolve benchmarks.tasks.tartarus``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from skillcompose import FSA, Blackboard, Registry, Skill, State, skill
from skillcompose.task import Task

from .forms import MAX_SENSES, TIME_UP, sensing_step_limit

SIZE = 6
BOXES = 6
STEPS = 80
"""Time steps per board."""
_HEADINGS = ((-1, 0), (0, 1), (1, 0), (0, -1))  # north, east, south, west (row, column)
Cell = Literal["empty", "box", "wall"]


def draw_board(rng: np.random.Generator) -> tuple[frozenset[tuple[int, int]], int, int, int]:
    """A board: its boxes, and the dozer's row, column and heading (Teller's rules)."""
    inner = [(r, c) for r in range(1, SIZE - 1) for c in range(1, SIZE - 1)]
    while True:
        picks = rng.choice(len(inner), size=BOXES + 1, replace=False)
        boxes = frozenset(inner[int(k)] for k in picks[:BOXES])
        if not any({(r, c), (r + 1, c), (r, c + 1), (r + 1, c + 1)} <= boxes
                   for r, c in inner):
            row, col = inner[int(picks[BOXES])]
            return boxes, row, col, int(rng.integers(4))


def score(boxes: frozenset[tuple[int, int]] | set[tuple[int, int]]) -> int:
    """Each box on an edge cell scores 1, in a corner 2."""
    edge = (0, SIZE - 1)
    return sum((r in edge) + (c in edge) for r, c in boxes)


@dataclass
class Dozer:
    """The dozer's world: the boards still to play, the one under way, the scores so far."""

    boards: list[tuple[frozenset[tuple[int, int]], int, int, int]]
    boxes: set[tuple[int, int]] = field(default_factory=set)
    row: int = 0
    col: int = 0
    heading: int = 0
    board: int = -1  # index of the board under way
    actions: int = 0  # time steps used on this board
    senses: int = 0  # sensing steps since the last action
    scores: list[int] = field(default_factory=list)

    def next_board(self) -> bool:
        """Score the board under way (if any) and set up the next; False after the last."""
        if self.board >= 0:
            self.scores.append(score(self.boxes))
        self.board += 1
        if self.board >= len(self.boards):
            return False
        boxes, self.row, self.col, self.heading = self.boards[self.board]
        self.boxes, self.actions = set(boxes), 0
        return True

    def cell(self, dr: int, dc: int) -> Cell:
        r, c = self.row + dr, self.col + dc
        if not (0 <= r < SIZE and 0 <= c < SIZE):
            return "wall"
        return "box" if (r, c) in self.boxes else "empty"

    def look(self, forward: int, right: int) -> Cell:
        """The cell ``forward`` cells ahead and ``right`` to the right, relative to the
        heading."""
        fr, fc = _HEADINGS[self.heading]
        rr, rc = _HEADINGS[(self.heading + 1) % 4]
        return self.cell(forward * fr + right * rr, forward * fc + right * rc)

    def act(self) -> Literal["done", "time_up"]:
        """Count a time step; at the board's last, go on to the next (``time_up`` after the
        last board)."""
        self.actions += 1
        self.senses = 0
        if self.actions >= STEPS and not self.next_board():
            return TIME_UP
        return "done"


def _sensor(name: str, forward: int, right: int) -> Skill:
    def sense(bb: Blackboard, rng: np.random.Generator) -> Literal[
            "empty", "box", "wall", "time_up"]:
        d: Dozer = bb["dozer"]
        d.senses += 1
        bb["dozer"] = d
        if d.senses > MAX_SENSES:
            return TIME_UP
        return d.look(forward, right)

    sense.__doc__ = (f"What the cell {name} holds (relative to the heading); no time step "
                     "(``time_up`` only after MAX_SENSES sensing steps in a row).")
    return skill(sense, name=name, writes={"dozer": Dozer})


SENSORS = {"Front": (1, 0), "FrontLeft": (1, -1), "FrontRight": (1, 1), "Left": (0, -1),
           "Right": (0, 1), "BackLeft": (-1, -1), "Back": (-1, 0), "BackRight": (-1, 1)}
"""Each sensing skill's cell: (cells ahead, cells to the right), relative to the heading."""


@skill(writes={"dozer": Dozer})
def forward(bb: Blackboard, rng: np.random.Generator) -> Literal["done", "time_up"]:
    """Move one cell forward, pushing a box there if the cell beyond it is free; one time
    step."""
    d: Dozer = bb["dozer"]
    dr, dc = _HEADINGS[d.heading]
    ahead, beyond = d.look(1, 0), d.look(2, 0)
    if ahead == "empty":
        d.row, d.col = d.row + dr, d.col + dc
    elif ahead == "box" and beyond == "empty":
        d.boxes.discard((d.row + dr, d.col + dc))
        d.boxes.add((d.row + 2 * dr, d.col + 2 * dc))
        d.row, d.col = d.row + dr, d.col + dc
    out = d.act()
    bb["dozer"] = d
    return out


@skill(writes={"dozer": Dozer})
def turn_left(bb: Blackboard, rng: np.random.Generator) -> Literal["done", "time_up"]:
    """Turn 90 degrees left in place; one time step."""
    d: Dozer = bb["dozer"]
    d.heading = (d.heading - 1) % 4
    out = d.act()
    bb["dozer"] = d
    return out


@skill(writes={"dozer": Dozer})
def turn_right(bb: Blackboard, rng: np.random.Generator) -> Literal["done", "time_up"]:
    """Turn 90 degrees right in place; one time step."""
    d: Dozer = bb["dozer"]
    d.heading = (d.heading + 1) % 4
    out = d.act()
    bb["dozer"] = d
    return out


SKILLS = (*(_sensor(n, f, r) for n, (f, r) in SENSORS.items()), forward, turn_left,
          turn_right)


def _reference() -> FSA:
    # go forward while the way is free; push a box ahead four times (at most the board's
    # width, whether it moves or is stuck), and turn right at a wall or after pushing
    def st(skill: str, **edges: str) -> State:
        return State(skill, transitions={**edges, TIME_UP: TIME_UP})

    return FSA(
        name="tartarus_reference",
        start="Look",
        states={
            "Look": st("Front", empty="Go", box="Push1", wall="Turn"),
            "Go": st("Forward", done="Look"),
            "Push1": st("Forward", done="Push2"),
            "Push2": st("Forward", done="Push3"),
            "Push3": st("Forward", done="Push4"),
            "Push4": st("Forward", done="Turn"),
            "Turn": st("TurnRight", done="Look"),
        },
        terminals=(TIME_UP,),
        step_limit=sensing_step_limit(STEPS * 10),
    )


REFERENCE = _reference()
"""A hand-written 7-state bulldozer (go forward, push a box four times, turn right at
walls)."""
REFERENCE_SCORE = 1.5
""":data:`REFERENCE`'s mean score per board on the default 10 boards (tested)."""


def make_task(boards: int = 10, board_seed: int = 0, target: float = 4.0) -> Task:
    """Tartarus on ``boards`` boards drawn from ``board_seed``, solved at a mean score of
    ``target`` per board (see the module's docstring)."""
    for name, value, low in (("boards", boards, 1), ("board_seed", board_seed, 0)):
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise ValueError(f"{name}={value!r}: expected a whole number >= {low}")
    if isinstance(target, bool) or not isinstance(target, (int, float)) or \
            not 0 < target <= 10:
        raise ValueError(f"target={target!r}: expected a mean score in (0, 10]")
    draw = np.random.default_rng(board_seed)
    chosen = [draw_board(draw) for _ in range(boards)]
    registry = Registry()
    for s in SKILLS:
        registry.add(s)

    def setup(rng: np.random.Generator) -> Blackboard:
        dozer = Dozer(boards=chosen)
        dozer.next_board()
        return Blackboard({"dozer": dozer})

    def fitness(outcome: str, bb: Blackboard, steps_run: int) -> float:
        d: Dozer = bb["dozer"]
        # boards not reached (a run ended by the step limit or a sensing loop) score as
        # they stand now, the rest as drawn
        unplayed = [score(b[0]) for b in d.boards[len(d.scores) + 1:]]
        now = [score(d.boxes)] if d.board < len(d.boards) else []
        return float(np.mean([*d.scores, *now, *unplayed]))

    return Task(
        name="tartarus",
        registry=registry,
        setup=setup,
        fitness=fitness,
        minimize=False,
        target=float(target),
        step_limit=sensing_step_limit(STEPS * boards),
        trials=1,
        error_fitness=0.0,
        terminal_skills=tuple(s.name for s in SKILLS),
        terminals=(TIME_UP,),
        deterministic=True,
        settings={"boards": boards, "board_seed": board_seed, "target": target},
    )
