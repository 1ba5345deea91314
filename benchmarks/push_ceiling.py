"""How often can moving to push succeed at all? The share of worlds in which some base pose
lets Push succeed, found by a robot that sees the whole world.

Moving to push (``examples.move_to_push``) succeeds when MoveBase puts the base where the
reachability classifier labels the object reachable with the chosen arm, with the base's
footprint in the room and at least :data:`~skillcompose.skills.move_to_push.SAFETY_M` from
the table's. In some worlds no such pose exists: an object deep in a wide table, say, is
out of the arm's reach from every side. No FSA, however evolved, pushes there, so the
share of worlds that have such a pose bounds every FSA's success rate from above; the
issue's target of 90 % of fresh worlds on the paper's world is reachable only if this
share is higher.

For each world (drawn by the task's own ``random_world``) the script searches base poses
as an omniscient planner would: the object at every point of a grid in the robot's frame
(``--step`` apart, 10 cm to 1.2 m ahead, up to 0.9 m to either side), every torso height
of a grid (4 values), every heading (``--headings``), the object's height rounded to 1 cm
for the classifier (its grid is computed once per height); a pose counts when the classifier
labels the object reachable (with either arm: MoveBase chooses the arm) and the base is
clear of the table and in the room. A grid can miss a pose that exists, so each share is a
lower estimate of the ceiling; the script runs the same worlds at half the step and twice
the headings, and the table gives both: where they agree, the grid is fine enough.
A second question: how much of that can an FSA reach *without seeing the table*, as the
task's FSAs must? A *placement* puts the base so that the object stands at a fixed point of
the robot's new frame (``ahead``, ``side``), the robot turned by a fixed angle from the
line to the object, at a fixed torso height and arm: what a MoveBase whose network gave
the exact answer for one fixed placement would do, from the inputs MoveBase has. An FSA
that tries placements in order, going to the next one when MoveBase fails (the pose is on
the table or out of the room; the robot then stays where it is), pushes in the worlds where
the first placement it can take lets Push succeed. The script picks such an order greedily
(:func:`blind_order`) on ``--worlds`` worlds of the paper's kind and measures it on as many
other worlds. Then it fits the paper's network (the layered 5-3-5, 38 weights in [-3, 3])
to each chosen placement by least squares (CasADi and IPOPT, :func:`fit_network`) and runs
the FSA of those networks, as the task runs it, on ``--worlds`` fresh worlds: the gap
between the two is what the network's precision costs. The same is done with 12 hidden
units in place of 3 (``network=layered-12``, not the paper's), to tell the network's size
from the placements as the cause. Last, the paper's network in two stages
(:func:`measure_staged`): a *staging* move that puts the robot at a fixed pose relative to
the object, then placements tried in order from there, every move fitted the same way; the
FSA of them runs on fresh worlds and on the PR2 model, and is written beside the page
(``push_ceiling_staged.fsa.yaml``).

``--worlds`` worlds of each kind, seed ``--seed``::

    python benchmarks/push_ceiling.py                  # 2,000 worlds of each kind
    python benchmarks/push_ceiling.py --worlds 50 --out /tmp/pc   # a quick look

Writes ``push_ceiling.md``, ``push_ceiling.json`` and ``push_ceiling_staged.fsa.yaml`` in
``--out`` (default ``docs/results``).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from skillcompose.arguments import output_dir
from skillcompose.files import atomic_write
from skillcompose.skills.network import Topology
from skillcompose.stats import rate_bounds

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # the task module (examples.move_to_push), run from anywhere
    sys.path.insert(0, str(ROOT))
TORSO_GRID = 4
"""Torso heights searched, evenly over the torso's range."""
AHEAD_M = (0.10, 1.20)
SIDE_M = 0.90
KINDS = (
    ("facing", False, "the task's default world (`facing`): the robot faces the table, the "
                      "object within 30 cm of the facing edge"),
    ("paper", False, "the paper's world (`world=paper`): the object anywhere on the top, the "
                     "robot anywhere within 2 m of the table, any heading"),
    ("paper", True, "the paper's world, judged placements (`world=paper`, `judge=true`): "
                    "the object at most 1.5 m from the robot and not behind it, as the "
                    "paper's robot was tested"),
)


def reachable_cells(z: float, step: float) -> np.ndarray:
    """The grid points ``(x, y)`` of the robot frame where the classifier labels an object
    at height ``z`` reachable with some arm at some torso height of the grid."""
    from skillcompose.skills.move_to_push import TORSO_RANGE_M, _classifier

    xs = np.arange(AHEAD_M[0], AHEAD_M[1] + 1e-9, step)
    ys = np.arange(-SIDE_M, SIDE_M + 1e-9, step)
    gx, gy = (a.ravel() for a in np.meshgrid(xs, ys, indexing="ij"))
    found = np.zeros(len(gx), dtype=bool)
    for torso in np.linspace(TORSO_RANGE_M[0], TORSO_RANGE_M[1], TORSO_GRID):
        rows = np.column_stack([gx, gy, np.full_like(gx, z), np.arctan2(gy, gx),
                                np.full_like(gx, torso)])
        found |= _classifier().predict(rows) != 0
    return np.column_stack([gx[found], gy[found]])


def base_fits(pose: tuple[float, float, float], world: dict[str, Any]) -> bool:
    """Whether MoveBase can take ``pose`` in ``world``: the base's footprint in the room
    and at least the safety distance from the table's (the skill's own rule)."""
    from examples.move_to_push import ROOM_HALF_M
    from skillcompose.skills.move_to_push import SAFETY_M, base_hits_table, base_in_room

    return base_in_room(pose, ROOM_HALF_M) and \
        not base_hits_table(pose, world["table_world"], SAFETY_M)


def pose_exists(world: dict[str, Any], cells: np.ndarray, headings: int) -> bool:
    """Whether a base pose puts the object at one of ``cells`` (robot frame) with the base
    clear of the table (by the safety distance) and in the room, at one of ``headings``
    evenly spaced headings."""
    ox, oy, _ = world["object_position_world"]
    for yaw in np.linspace(-math.pi, math.pi, headings, endpoint=False):
        c, s = math.cos(yaw), math.sin(yaw)
        for x, y in cells:
            if base_fits((ox - (c * x - s * y), oy - (s * x + c * y), float(yaw)), world):
                return True
    return False


def measure(kind: str, judge: bool, worlds: int, seed: int, step: float,
            headings: int) -> dict[str, Any]:
    """The share of ``worlds`` worlds of ``kind`` that have a pose, on a grid of ``step``
    and ``headings``."""
    from examples.move_to_push import random_world

    rng = np.random.default_rng(seed)
    cells_at: dict[float, np.ndarray] = {}
    found = 0
    for _ in range(worlds):
        world = random_world(rng, judge=judge, world=kind)  # type: ignore[arg-type]
        z = round(float(world["object_position_world"][2]), 2)  # the classifier's height
        if z not in cells_at:
            cells_at[z] = reachable_cells(z, step)
        found += pose_exists(world, cells_at[z], headings)
    low, high = rate_bounds(found, worlds, 0.025)
    return {"world": kind, "judge": judge, "step_m": step, "headings": headings,
            "worlds": worlds, "with_pose": found, "share": found / worlds,
            "ci95": [low, high]}


PLACE_AHEAD_M = tuple(round(0.3 + 0.1 * i, 1) for i in range(7))
"""Where a placement puts the object ahead of the base [m]: 0.3 to 0.9."""
PLACE_SIDE_M = tuple(round(-0.5 + 0.1 * i, 1) for i in range(11))
"""... and to its left (negative: right) [m]: -0.5 to 0.5."""
PLACE_TURN_DEG = (-90, -60, -30, 0, 30, 60, 90)
"""How far the robot's new heading is turned from the line to the object [degrees]."""
BLIND_STEPS = 4
"""Placements tried in order, at most."""
MARGIN_M = 0.10
"""The second order of placements is chosen so that a move landing this far from a
placement still pushes (:func:`blind_outcomes`) [m]: one fitted network lands within a few
centimetres, and placements chosen for exact moves sit at the edge of the arm's reach."""


STAGE_AHEAD_M = 1.6
"""A *staging* move puts the object this far ahead of the base, on the line from the robot to
the object [m]: far enough from the table that the coarse move seldom lands on it."""
STAGE_TURNS_DEG = (0, 180)
"""The staging moves tried in order: the near side of the object, then the far side."""
STAGED_STEPS = 6
"""Placements tried in order after a staging move, at most."""
STAGED_MARGIN_M = 0.05
"""The margin the placements after a staging move are chosen with (:func:`blind_outcomes`)
[m]. The staging constants were chosen in short exploratory runs (300 and 1,000 worlds of
``seed + 2``); the page measures them on worlds of ``seed + 3``, which no choice saw."""


def placements() -> list[tuple[float, float, float, float, str]]:
    """Every placement searched: (ahead [m], side [m], turn [rad], torso [m], arm)."""
    from skillcompose.skills.move_to_push import TORSO_RANGE_M

    torsos = np.linspace(TORSO_RANGE_M[0], TORSO_RANGE_M[1], 3)
    return [(a, sd, math.radians(t), float(h), arm) for a in PLACE_AHEAD_M
            for sd in PLACE_SIDE_M for t in PLACE_TURN_DEG for h in torsos
            for arm in ("left", "right")]


def placement_pose(world: dict[str, Any], place: tuple[float, float, float, float, str]
                   ) -> tuple[float, float, float]:
    """The base pose in the world where ``place`` puts the robot of ``world``."""
    from skillcompose.skills.move_to_push import object_in_robot_frame

    ox, oy, _ = world["object_position_world"]
    yaw0 = world["base_pose_world"][2]
    rx, ry, _ = object_in_robot_frame(world["base_pose_world"], world["object_position_world"])
    yaw = yaw0 + math.atan2(ry, rx) + place[2]
    c, s = math.cos(yaw), math.sin(yaw)
    return (ox - (c * place[0] - s * place[1]), oy - (s * place[0] + c * place[1]),
            math.remainder(yaw, 2.0 * math.pi))


def blind_outcomes(worlds: list[dict[str, Any]],
                   places: list[tuple[float, float, float, float, str]],
                   margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """For each placement and world: whether MoveBase can take it (``free``: the base
    clear of the table by the safety distance and in the room) and whether Push then
    succeeds (``pushed``: the classifier labels the object reachable with its arm). With a
    ``margin`` [m], ``pushed`` asks more: the classifier's label holds with the object
    ``margin`` ahead, behind and to either side of the placement's point too, and the base
    is clear of the table by the safety distance plus ``margin``, so that a move that lands
    within ``margin`` of the placement still pushes."""
    from skillcompose.skills.move_to_push import ARM_CODES, SAFETY_M, _classifier, base_hits_table

    free = np.zeros((len(places), len(worlds)), dtype=bool)
    pushed = np.zeros_like(free)
    arms = np.array([ARM_CODES[p[4]] for p in places])
    shifts = [(0.0, 0.0)] + ([(margin, 0.0), (-margin, 0.0), (0.0, margin), (0.0, -margin)]
                             if margin > 0 else [])
    for j, world in enumerate(worlds):
        z = float(world["object_position_world"][2])
        clear = np.ones(len(places), dtype=bool)
        for i, place in enumerate(places):
            pose = placement_pose(world, place)
            free[i, j] = base_fits(pose, world)
            if margin > 0:
                clear[i] = not base_hits_table(pose, world["table_world"], SAFETY_M + margin)
        labelled = np.ones(len(places), dtype=bool)
        for da, ds in shifts:
            rows = np.array([[p[0] + da, p[1] + ds, z, math.atan2(p[1] + ds, p[0] + da), p[3]]
                             for p in places])
            labelled &= _classifier().predict(rows) == arms
        pushed[:, j] = free[:, j] & clear & labelled
    return free, pushed


def blind_order(free: np.ndarray, pushed: np.ndarray, steps: int) -> list[int]:
    """A greedy order of at most ``steps`` placements: each the one that pushes in the most
    worlds the earlier ones left undecided (none of them could be taken) less those where
    it is taken and Push fails (a run that ends there)."""
    undecided = np.ones(free.shape[1], dtype=bool)
    order: list[int] = []
    for _ in range(steps):
        gain = (pushed & undecided).sum(axis=1) - (free & ~pushed & undecided).sum(axis=1)
        best = int(np.argmax(gain))
        if gain[best] <= 0:
            break
        order.append(best)
        undecided &= ~free[best]
    return order


def chain_pushes(free: np.ndarray, pushed: np.ndarray, order: list[int]) -> np.ndarray:
    """Per world, whether the FSA that tries ``order`` pushes."""
    done = np.zeros(free.shape[1], dtype=bool)
    out = np.zeros_like(done)
    for i in order:
        out |= pushed[i] & ~done
        done |= free[i]
    return out


def ideal_outputs(world: dict[str, Any], place: tuple[float, float, float, float, str]
                  ) -> np.ndarray:
    """The five outputs in (0, 1) that would send the robot of ``world`` exactly to
    ``place`` (skillcompose.skills.move_to_push's mapping), clipped to what a sigmoid
    gives."""
    from skillcompose.skills.move_to_push import BASE_STEP_M, TORSO_RANGE_M

    x, y, yaw0 = world["base_pose_world"]
    px, py, yaw = placement_pose(world, place)
    c, s = math.cos(yaw0), math.sin(yaw0)
    dx, dy = c * (px - x) + s * (py - y), -s * (px - x) + c * (py - y)
    turn = math.remainder(yaw - yaw0, 2.0 * math.pi)
    out = np.array([(dx / BASE_STEP_M + 1) / 2, (dy / BASE_STEP_M + 1) / 2,
                    (turn / math.pi + 1) / 2, place[3] / TORSO_RANGE_M[1],
                    0.9 if place[4] == "left" else 0.1])
    return np.clip(out, 0.02, 0.98)


def fit_network(worlds: list[dict[str, Any]],
                place: tuple[float, float, float, float, str],
                topology: Topology = "layered") -> tuple[list[float], float]:
    """The weights (in [-3, 3]) of a layered network of ``topology`` (``layered``, the
    paper's 38, or ``layered-12``, 137) nearest, in least squares, to the outputs that take
    each robot of ``worlds`` exactly to ``place``, and the root mean square error of the
    base's position that remains [m]. By CasADi's IPOPT from a fixed start, so the same
    worlds give the same weights; the larger network is given more iterations (1000
    against 400) to converge. A world's ``torso_m`` (where a move before left the torso;
    0 when absent) is the network's torso input."""
    import casadi as ca

    from skillcompose.skills.move_to_push import BASE_STEP_M, network_inputs, object_in_robot_frame
    from skillcompose.skills.network import HIDDEN, N_INPUTS, N_OUTPUTS, WEIGHT_RANGE

    n_hidden = HIDDEN[topology]
    inputs = np.array([network_inputs(object_in_robot_frame(
        w["base_pose_world"], w["object_position_world"]), w.get("torso_m", 0.0))
        for w in worlds]).T
    target = np.array([ideal_outputs(w, place) for w in worlds]).T
    n1 = n_hidden * (N_INPUTS + 1)
    opti = ca.Opti()
    w = opti.variable(n1 + N_OUTPUTS * (n_hidden + 1))
    first = ca.reshape(w[:n1], N_INPUTS + 1, n_hidden).T  # rows as LayeredNetwork reads them
    second = ca.reshape(w[n1:], n_hidden + 1, N_OUTPUTS).T
    ones = ca.DM.ones(1, inputs.shape[1])
    hidden = 1 / (1 + ca.exp(-(first @ ca.vertcat(ca.DM(inputs), ones))))
    out = 1 / (1 + ca.exp(-(second @ ca.vertcat(hidden, ones))))
    opti.minimize(ca.sumsqr(out - ca.DM(target)))
    opti.subject_to(opti.bounded(WEIGHT_RANGE[0], w, WEIGHT_RANGE[1]))
    opti.set_initial(w, np.random.default_rng(0).uniform(-1.0, 1.0, w.shape[0]))
    opti.solver("ipopt", {"print_time": False},
                {"print_level": 0, "sb": "yes",
                 "max_iter": 400 if topology == "layered" else 1000})
    try:
        weights = np.asarray(opti.solve().value(w)).ravel()
    except RuntimeError:  # out of iterations: the last iterate is still a network
        weights = np.asarray(opti.debug.value(w)).ravel()
    weights = np.clip(weights, *WEIGHT_RANGE)
    got = np.asarray(ca.Function("f", [w], [out])(weights))
    error_m = 2 * BASE_STEP_M * np.sqrt(np.mean((got[:2] - target[:2]) ** 2) * 2)
    return [float(v) for v in weights], float(error_m)


def fsa_text(moves: list[tuple[str, list[float], str, str]], first: str) -> str:
    """The FSA file RecogniseObject → ``first``, then MoveBase states (name, weights, where
    success goes, where failure goes; ``P`` is Push, whose outcome ends the run)."""
    lines = ["format: 1", "start: R", "states:",
             f"  R: {{skill: RecogniseObject, transitions: {{success: {first}}}}}"]
    lines += [f"  {name}: {{skill: MoveBase, params: {{weights: {weights}}}, "
              f"transitions: {{success: {on_success}, failure: {on_failure}}}}}"
              for name, weights, on_success, on_failure in moves]
    lines.append("  P: {skill: Push, transitions: {success: success, failure: failure}}")
    return "\n".join(lines) + "\n"


def fsa_rate(text: str, worlds: int, seed: int, network: Topology = "layered",
             **settings: Any) -> tuple[int, int]:
    """Successes of the FSA ``text`` on ``worlds`` episodes of the task's paper world drawn
    from ``seed`` (``settings``: more of the task's settings, e.g. the PR2 model's)."""
    from skillcompose import loads_fsa
    from skillcompose.task import load_task

    task = load_task("examples.move_to_push", world="paper", network=network, **settings)
    rate = task.evaluate(task.compile(loads_fsa(text)), seed, trials=worlds)
    return round(rate * worlds), worlds


def network_chain_rate(nets: list[list[float]], worlds: int, seed: int,
                       on: str = "failure", network: Topology = "layered"
                       ) -> tuple[int, int]:
    """Pushes of the FSA RecogniseObject → MoveBase(nets[0]) → MoveBase(nets[1]) → ... →
    Push on ``worlds`` worlds of the task's paper world (drawn by the task from ``seed``):
    a MoveBase's outcome ``on`` goes to the next MoveBase, its other outcome to Push;
    MoveBase's network of topology ``network``."""
    moves = []
    for i, weights in enumerate(nets):
        after = f"M{i + 1}" if i + 1 < len(nets) else "P"
        moves.append((f"M{i}", weights, *((after, "P") if on == "success" else ("P", after))))
    return fsa_rate(fsa_text(moves, "M0"), worlds, seed, network)


def moved_worlds(worlds: list[dict[str, Any]], weights: list[float]
                 ) -> list[tuple[int, dict[str, Any]]]:
    """Where MoveBase's own rule, with the paper's network of ``weights``, sends the robot
    of each world, for the worlds where it may go there (index, moved world: its base pose
    and ``torso_m`` where the move left them)."""
    from skillcompose import Blackboard
    from skillcompose.skills.move_to_push import network_goal

    rng = np.random.default_rng(0)  # the layered network draws nothing
    out = []
    for i, w in enumerate(worlds):
        goal = network_goal(Blackboard({
            "object_location_world": w["object_position_world"],
            "base_pose_world": w["base_pose_world"], "table_world": w["table_world"],
            "torso_height_m": w.get("torso_m", 0.0)}), rng, "layered", weights)
        if not isinstance(goal, str) and base_fits(goal[0], w):
            out.append((i, {**w, "base_pose_world": goal[0], "torso_m": goal[1]}))
    return out


def refining_chain(worlds: list[dict[str, Any]],
                   place: tuple[float, float, float, float, str], moves: int
                   ) -> list[tuple[list[float], float]]:
    """Networks fitted to ``place`` one after another, each on the worlds where the ones
    before it moved the robot (a MoveBase that fails leaves the chain for Push), from where
    they left it: a MoveBase after a MoveBase. Each with its fit's error."""
    fits = []
    for _ in range(moves):
        if not worlds:
            break
        weights, error = fit_network(worlds, place)
        fits.append((weights, error))
        worlds = [w for _, w in moved_worlds(worlds, weights)]
    return fits


def measure_staged(chosen: list[dict[str, Any]],
                   places: list[tuple[float, float, float, float, str]],
                   worlds: int, seed: int, judged: int = 395) -> dict[str, Any]:
    """The paper's network in two stages: a *staging* move (the object
    :data:`STAGE_AHEAD_M` ahead, on the line from the robot to it; on the far side if that
    fails), then placements tried in order from there (chosen on ``chosen`` with
    :data:`STAGED_MARGIN_M`). From a staging pose the object is nearly where it always is,
    so a network fitted there is precise where one fitted from anywhere is not. Each network
    is fitted on ``chosen`` (the staging moves) or on the worlds the staging moves reached
    (the placements); the FSA of them runs on ``worlds`` fresh worlds (``seed + 3``) and on
    the PR2 model (the kinematic backend, ``judged`` judged placements: 395 as the paper's
    robot was tested; ``seed + 3``)."""
    free, pushed = blind_outcomes(chosen, places, STAGED_MARGIN_M)
    order = blind_order(free, pushed, STAGED_STEPS)
    stages: list[tuple[list[float], float, int]] = []
    staged: list[dict[str, Any]] = []
    left = list(range(len(chosen)))
    for turn in STAGE_TURNS_DEG:
        weights, error = fit_network(chosen, (STAGE_AHEAD_M, 0.0, math.radians(turn), 0.0,
                                              "left"))
        reached = moved_worlds([chosen[i] for i in left], weights)
        stages.append((weights, error, len(reached)))
        staged += [w for _, w in reached]
        took = {left[k] for k, _ in reached}
        left = [i for i in left if i not in took]
    fines = [fit_network(staged, places[i]) for i in order] if staged else []
    moves = [(f"S{k}", weights, "F0" if fines else "P",
              f"S{k + 1}" if k + 1 < len(stages) else "P")
             for k, (weights, _, _) in enumerate(stages)]
    moves += [(f"F{k}", weights, "P", f"F{k + 1}" if k + 1 < len(fines) else "P")
              for k, (weights, _) in enumerate(fines)]
    text = fsa_text(moves, "S0")
    pushed_fresh, n = fsa_rate(text, worlds, seed + 3)
    pushed_pr2, _ = fsa_rate(text, judged, seed + 3, backend="kinematic", judge=True)
    return {
        "stage_ahead_m": STAGE_AHEAD_M, "stage_turns_deg": list(STAGE_TURNS_DEG),
        "margin_m": STAGED_MARGIN_M, "chosen": len(chosen),
        "stages": [{"turn_deg": t, "error_m": e, "reached": r}
                   for t, (_, e, r) in zip(STAGE_TURNS_DEG, stages, strict=True)],
        "placements": [{"ahead_m": places[i][0], "side_m": places[i][1],
                        "turn_deg": round(math.degrees(places[i][2])),
                        "torso_m": places[i][3], "arm": places[i][4], "error_m": e}
                       for i, (_, e) in zip(order, fines, strict=True)],
        "pushed": pushed_fresh, "worlds": n, "pr2_pushed": pushed_pr2, "pr2_judged": judged,
        "fsa": text}


def measure_blind(worlds: int, seed: int, judged: int = 395) -> dict[str, Any]:
    """The table-blind placements (module docstring): chosen on ``worlds`` worlds of the
    paper's kind from ``seed``, measured on as many others (``seed + 1``), then the paper's
    network fitted to them and run by the task on fresh worlds (``seed + 2``); then the same
    network in two stages (:func:`measure_staged`, ``judged`` placements on the PR2 model)."""
    from examples.move_to_push import random_world

    def draw(s: int) -> list[dict[str, Any]]:
        rng = np.random.default_rng(s)
        return [random_world(rng, world="paper") for _ in range(worlds)]

    places = placements()
    chosen, fresh = draw(seed), draw(seed + 1)

    def placement_rows(margin: float) -> tuple[list[int], list[dict[str, Any]]]:
        """The order chosen with ``margin`` and, for each prefix of it, the exact moves on
        the other worlds (judged without a margin) and the fitted networks on fresh ones."""
        free, pushed = blind_outcomes(chosen, places, margin)
        order = blind_order(free, pushed, BLIND_STEPS)
        fresh_free, fresh_pushed = blind_outcomes(fresh, [places[i] for i in order])
        fits = [fit_network(chosen, places[i]) for i in order]
        wide = [fit_network(chosen, places[i], "layered-12") for i in order]
        rows = []
        for k in range(1, len(order) + 1):
            exact = chain_pushes(free, pushed, order[:k])
            held = chain_pushes(fresh_free, fresh_pushed, list(range(k)))
            by_net, n = network_chain_rate([f[0] for f in fits[:k]], worlds, seed + 2)
            by_wide, _ = network_chain_rate([f[0] for f in wide[:k]], worlds, seed + 2,
                                            network="layered-12")
            a, sd, turn, torso, arm = places[order[k - 1]]
            rows.append({"placement": {"ahead_m": a, "side_m": sd,
                                       "turn_deg": round(math.degrees(turn)),
                                       "torso_m": torso, "arm": arm},
                         "chosen_on": int(exact.sum()), "fresh": int(held.sum()),
                         "network_error_m": fits[k - 1][1], "network_pushed": by_net,
                         "wide_error_m": wide[k - 1][1], "wide_pushed": by_wide,
                         "worlds": n})
        return order, rows

    order, rows = placement_rows(0.0)
    _, margin_rows = placement_rows(MARGIN_M)
    refine = []
    if order:
        chain = refining_chain(chosen, places[order[0]], BLIND_STEPS)
        for k in range(1, len(chain) + 1):
            by_net, _ = network_chain_rate([f[0] for f in chain[:k]], worlds, seed + 2,
                                           on="success")
            refine.append({"moves": k, "network_error_m": chain[k - 1][1],
                           "network_pushed": by_net})
    return {"worlds": worlds, "placements_searched": len(places), "rows": rows,
            "margin_m": MARGIN_M, "margin_rows": margin_rows,
            "refine": refine, "staged": measure_staged(chosen, places, worlds, seed, judged)}


def report(rows: list[dict[str, Any]], args: argparse.Namespace, seconds: float,
           blind: dict[str, Any]) -> str:
    """The page."""
    lines = [
        "# Moving to push: how often a push is possible at all",
        "",
        "Written by `benchmarks/push_ceiling.py`; every number below was measured by that "
        "run. Do not edit by hand: rerun the script.",
        "",
        f"Command: `python benchmarks/push_ceiling.py {' '.join(args.argv)}`".rstrip() + "  ",
        f"Run of {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC; machine: "
        f"{platform.machine()}, Python {platform.python_version()}; {seconds / 60:.1f} min.",
        "",
        "A world *has a pose* when some base pose puts the object where the reachability "
        "classifier (the sim backend's Push) labels it reachable with some arm, with the "
        "base's footprint in the room and at least 5 cm from the table's (MoveBase's "
        "safety distance). No FSA pushes in a world without one, so the share of worlds "
        "that have one bounds the success rate of every FSA from above, whatever it "
        "evolved; an FSA reaches it only by finding such a pose from the object's position "
        "alone (MoveBase's network sees nothing of the table; a MoveBase that fails tells "
        "the FSA only that it failed). The poses are searched on a grid (the script's "
        "docstring), so each share is a lower estimate of that bound: the finer grid shows "
        "how much the grid misses. Intervals: two-sided 95 % Clopper–Pearson.",
        "",
        "| world | worlds | grid: step, headings | worlds with a pose | share [95 % CI] |",
        "|---|---:|---|---:|---|",
    ]
    for r in rows:
        about = next(a for k, j, a in KINDS if k == r["world"] and j == r["judge"])
        lines.append(
            f"| {about} | {r['worlds']:,} | {100 * r['step_m']:.1f} cm, {r['headings']} | "
            f"{r['with_pose']:,} | {100 * r['share']:.1f} % [{100 * r['ci95'][0]:.1f}, "
            f"{100 * r['ci95'][1]:.1f}] |")
    lines += ["", "## Against the targets", ""]
    for kind, judge, _ in KINDS:
        mine = sorted((r for r in rows if r["world"] == kind and r["judge"] == judge),
                      key=lambda r: -r["step_m"])
        if not mine:
            continue
        coarse, fine = mine[0], mine[-1]
        what = "fresh worlds" if not judge else "judged placements (as on the PR2 model)"
        agree = abs(fine["share"] - coarse["share"]) <= 0.01
        if 100 * fine["ci95"][1] < 90 and agree:
            verdict = ("below 90 % on both grids: no FSA of these skills meets the issue's "
                       "90 % target on these worlds")
        elif fine["share"] >= 0.9:
            verdict = ("the geometry allows the 90 % target: an FSA that misses it misses "
                       "poses that exist")
        else:
            verdict = "the grids disagree: search finer before concluding"
        lines.append(f"- {kind}{', judged' if judge else ''}: {100 * coarse['share']:.1f} % of "
                     f"{what} have a pose on the coarse grid, {100 * fine['share']:.1f} % on "
                     f"the fine one; {verdict}.")
    return "\n".join(lines + blind_section(blind)) + "\n"


def _placement_table(rows: list[dict[str, Any]], share: Any, n: int,
                     chosen_on: str = "exact, worlds chosen on") -> list[str]:
    """The table of one order of placements: exact moves and the fitted networks;
    ``chosen_on`` heads the column of the worlds the order was chosen on."""
    lines = [
        "| placements tried | last placement: ahead, side [m], turn [°], torso [m], arm | "
        f"{chosen_on} | exact, other worlds [95 % CI] | fitted network: "
        "position error, RMS [m] | fitted networks, fresh worlds [95 % CI] | 12 hidden "
        "units: position error, RMS [m] | 12 hidden units, fresh worlds [95 % CI] |",
        "|---:|---|---:|---:|---:|---:|---:|---:|"]
    for k, r in enumerate(rows, 1):
        p = r["placement"]
        lines.append(
            f"| {k} | {p['ahead_m']:.1f}, {p['side_m']:+.1f}, {p['turn_deg']:+d}, "
            f"{p['torso_m']:.2f}, {p['arm']} | {r['chosen_on']:,}/{n:,} | {share(r['fresh'])} "
            f"| {r['network_error_m']:.2f} | {share(r['network_pushed'])} "
            f"| {r['wide_error_m']:.2f} | {share(r['wide_pushed'])} |")
    return lines


def _wide_finding(rows: list[dict[str, Any]], n: int) -> list[str]:
    """What the network with 12 hidden units says of an order of placements, as measured."""
    if not rows:
        return []
    last = rows[-1]
    return [
        "- The same network with 12 hidden units in place of 3, fitted the same way: "
        f"{100 * last['wide_pushed'] / n:.1f} % of fresh worlds (the paper's: "
        f"{100 * last['network_pushed'] / n:.1f} %), its base "
        f"{min(r['wide_error_m'] for r in rows):.2f}–{max(r['wide_error_m'] for r in rows):.2f}"
        " m (RMS) from each placement"
        + (f": within a tenth of the exact moves ({100 * last['fresh'] / n:.1f} %)."
           if last["wide_pushed"] >= 0.9 * last["fresh"] else
           f": still short of the exact moves ({100 * last['fresh'] / n:.1f} %).")]


def share_of(k: int, n: int) -> str:
    """``k`` of ``n`` as the page writes it, with its two-sided 95 % Clopper–Pearson
    interval."""
    low, high = rate_bounds(k, n, 0.025)
    return f"{k:,}/{n:,} = {100 * k / n:.1f} % [{100 * low:.1f}, {100 * high:.1f}]"


def blind_section(blind: dict[str, Any]) -> list[str]:
    """The page's section on the table-blind placements."""
    n = blind["worlds"]

    def share(k: int) -> str:
        return share_of(k, n)

    lines = [
        "", "## Without seeing the table", "",
        "An FSA of these skills sees the object, never the table. The best it can do with "
        "exact moves: try *placements* in order (the object at a fixed point of the robot's "
        "new frame, the robot turned by a fixed angle from the line to the object, a fixed "
        "torso height and arm), going to the next when MoveBase fails, as the script's "
        f"docstring says. Of {blind['placements_searched']:,} placements, the script chose an "
        f"order greedily on {n:,} worlds of the paper's kind and measured it on {n:,} "
        "others. Then it fitted the paper's network (layered, 38 weights) to each chosen "
        "placement by least squares and ran the FSA of those networks (a MoveBase's "
        "failure goes to the next one, its success to Push) as the task runs it, on "
        f"{n:,} fresh worlds; and the same with 12 hidden units in place of the paper's 3 "
        "(`network=layered-12`, 137 weights in the same range; not the paper's network).", "",
        *_placement_table(blind["rows"], share, n),
    ]
    if blind["rows"]:
        last = blind["rows"][-1]
        errors = [r["network_error_m"] for r in blind["rows"]]
        lines += ["", f"- Exact placements, {len(blind['rows'])} tried in order: "
                  f"{100 * last['fresh'] / n:.1f} % of other worlds; "
                  + ("a table-blind FSA can meet the 90 % target with exact moves."
                     if last["fresh"] >= 0.9 * n else
                     "below the 90 % target even with exact moves."),
                  f"- The paper's network fitted to them: {100 * last['network_pushed'] / n:.1f}"
                  f" % of fresh worlds, its base {min(errors):.2f}–{max(errors):.2f} m (RMS) "
                  "from where "
                  "each placement puts it: one move of the 5-3-5 network from anywhere within "
                  "2 m of the table is that coarse.",
                  *_wide_finding(blind["rows"], n)]
    margin_rows = blind.get("margin_rows") or []
    if margin_rows:
        m = blind["margin_m"]
        last = margin_rows[-1]
        lines += [
            "", f"Placements chosen for exact moves sit where a few centimetres off loses "
            f"the push: at the edge of the arm's reach, or just clear of the table. A second "
            f"order was chosen on the same worlds asking that a move landing {100 * m:.0f} cm "
            "from the placement (ahead, behind, to either side, and no closer to the table) "
            "still push; the exact moves to it are judged as before, without the margin:", "",
            *_placement_table(margin_rows, share, n,
                              f"with the {100 * m:.0f} cm margin, worlds chosen on"), "",
            f"- With the {100 * m:.0f} cm margin: exact moves {100 * last['fresh'] / n:.1f} %, "
            f"the paper's network {100 * last['network_pushed'] / n:.1f} %, 12 hidden units "
            f"{100 * last['wide_pushed'] / n:.1f} % of fresh worlds."]
    if blind.get("refine"):
        first = blind["rows"][0]
        lines += [
            "", "A MoveBase after a MoveBase corrects it: networks fitted one after another "
            "to the first placement, each from where the ones before it left the robot (a "
            "MoveBase's success goes to the next, its failure to Push), on the same fresh "
            f"worlds (the first placement, exact: {share(first['fresh'])} of other worlds):",
            "", "| moves | position error of the last fit, RMS [m] | fresh worlds pushed "
            "[95 % CI] |", "|---:|---:|---:|"]
        lines += [f"| {r['moves']} | {r['network_error_m']:.2f} | {share(r['network_pushed'])} |"
                  for r in blind["refine"]]
    return lines + staged_section(blind.get("staged"))


STAGED_FILE = "push_ceiling_staged.fsa.yaml"
"""The staged FSA, written beside the page, so that anyone can run and edit it."""


def staged_section(staged: dict[str, Any] | None) -> list[str]:
    """The page's section on the paper's network in two stages (:func:`measure_staged`)."""
    if not staged:
        return []

    n, judged = staged["worlds"], staged["pr2_judged"]
    moves = len(staged["stages"]) + len(staged["placements"])
    lines = [
        "", "## The paper's network in two stages", "",
        "One move of the paper's network from anywhere is coarse, but a move from a pose the "
        "robot always reaches the same way is not. Here a *staging* move first puts the "
        f"object {staged['stage_ahead_m']:.1f} m ahead of the robot on the line from the "
        "robot to it (on the far side of the object if that pose is on the table); from "
        "there, placements chosen with a "
        f"{100 * staged['margin_m']:.0f} cm margin are tried in order, as above. Every move "
        "is the paper's 5-3-5 network (38 weights in [-3, 3]) fitted by least squares: the "
        f"staging moves on the {staged['chosen']:,} worlds the orders were chosen on, the "
        "placements on the worlds the staging moves reached, from where they left the "
        f"robot. The FSA of these {moves} MoveBase states (a staging move's success goes to "
        "the first placement, its failure to the next staging move; a placement's success "
        "goes to Push, its failure to the next placement; the last failures to Push) is "
        f"written to [`{STAGED_FILE}`]({STAGED_FILE}), and ran as the task runs it on fresh "
        "worlds no choice saw, and unchanged on the PR2 model (the kinematic backend) on "
        f"{judged} judged placements, as the paper's robot was tested.", "",
        "| move | aims at: ahead, side [m], turn [°], torso [m], arm | fitted on | position "
        "error, RMS [m] |", "|---|---|---|---:|"]
    for k, st in enumerate(staged["stages"]):
        lines.append(f"| staging {k + 1} | {staged['stage_ahead_m']:.1f}, +0.0, "
                     f"{st['turn_deg']:+d}, 0.00, left | {staged['chosen']:,} worlds; it "
                     f"reached {st['reached']:,} of those still left | {st['error_m']:.2f} |")
    reached = sum(st["reached"] for st in staged["stages"])
    for k, pl in enumerate(staged["placements"]):
        lines.append(f"| placement {k + 1} | {pl['ahead_m']:.1f}, {pl['side_m']:+.1f}, "
                     f"{pl['turn_deg']:+d}, {pl['torso_m']:.2f}, {pl['arm']} | the "
                     f"{reached:,} staged worlds | {pl['error_m']:.2f} |")
    fresh, pr2 = staged["pushed"] / n, staged["pr2_pushed"] / judged
    low_fresh = rate_bounds(staged["pushed"], n, 0.025)[0]
    low_pr2 = rate_bounds(staged["pr2_pushed"], judged, 0.025)[0]

    def against(rate: float, low: float) -> str:
        if low >= 0.9:
            return "above the issue's 90 % target, interval and all"
        if rate >= 0.9:
            return "at the issue's 90 % target, its interval reaching below it"
        return "below the issue's 90 % target"

    lines += [
        "", f"- Fresh paper worlds: {share_of(staged['pushed'], n)}, {against(fresh, low_fresh)}.",
        f"- The PR2 model, {judged} judged placements: {share_of(staged['pr2_pushed'], judged)}, "
        f"{against(pr2, low_pr2)} (the paper's real robot: 82 %).",
        "- So the one-move figures above bound FSAs that move once per placement, not the "
        "paper's network: in an FSA of "
        f"{moves} MoveBase states it pushes {100 * fresh:.1f} % of fresh worlds. An evolved "
        "FSA that pushes far less (`paper_comparison.md`) falls short of what these skills "
        "allow: what it lacks is the search, not the network."]
    return lines


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--worlds", type=int, default=2000, help="worlds of each kind (2000)")
    p.add_argument("--seed", type=int, default=0, help="seed of the worlds (0)")
    p.add_argument("--step", type=float, default=0.04,
                   help="grid step in the robot frame [m] (0.04; also half of it)")
    p.add_argument("--headings", type=int, default=36,
                   help="headings searched (36; also twice as many)")
    p.add_argument("--judged", type=int, default=395,
                   help="judged placements on the PR2 model for the staged FSA (395, the "
                        "paper's real-robot count)")
    p.add_argument("--out", type=output_dir, default=None,
                   help="output folder (default docs/results)")
    args = p.parse_args(argv)
    if args.worlds < 1 or args.headings < 1 or args.judged < 1 or not 0.0 < args.step <= 0.5:
        p.error("--worlds, --headings and --judged must be at least 1, --step in (0, 0.5] m")
    args.argv = list(sys.argv[1:] if argv is None else argv)
    out = Path(args.out) if args.out else ROOT / "docs" / "results"
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    rows = []
    for kind, judge, _ in KINDS:
        for step, headings in ((args.step, args.headings),
                               (args.step / 2, 2 * args.headings)):
            row = measure(kind, judge, args.worlds, args.seed, step, headings)
            rows.append(row)
            print(f"{kind}{' judged' if judge else ''}, step {step:.3f} m, {headings} "
                  f"headings: {row['with_pose']}/{args.worlds}", file=sys.stderr)
    blind = measure_blind(args.worlds, args.seed, args.judged)
    print(f"without the table: {[r['fresh'] for r in blind['rows']]} exact, "
          f"{[r['network_pushed'] for r in blind['rows']]} by the fitted networks, of "
          f"{args.worlds}; in two stages {blind['staged']['pushed']}", file=sys.stderr)
    seconds = time.perf_counter() - t0
    atomic_write(out / "push_ceiling.json", json.dumps(
        {"argv": args.argv, "seconds": seconds, "rows": rows, "blind": blind},
        indent=1).encode() + b"\n")
    atomic_write(out / "push_ceiling.md", report(rows, args, seconds, blind).encode())
    atomic_write(out / STAGED_FILE, (
        "# The paper's network in two stages, fitted by benchmarks/push_ceiling.py (its page:\n"
        "# push_ceiling.md). Run it: skillcompose run " + STAGED_FILE + " --task\n"
        "# examples.move_to_push --set world=paper --trials 1000\n"
        + blind["staged"]["fsa"]).encode())
    print(f"wrote {out / 'push_ceiling.md'}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
