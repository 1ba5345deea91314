"""Skills of the paper's second experiment, moving to push (section 4.2), on the ``sim`` backend.

- ``RecogniseObject``: writes where the one object on the table is
  (``object_location_world``); only ``success`` (the object is always visible).
- ``MoveBase(weights)``: a neural network (:mod:`skillcompose.skills.network`) maps the recognised
  object,
  seen from the robot, to a new base pose, a torso height and an arm. ``failure`` when the
  object was not recognised, or when the base at that pose would come closer than
  :data:`SAFETY_M` to the table or leave the room; else ``success``, and the robot is there.
- ``Push``: ``success`` when the reachability classifier (:mod:`skillcompose.robots.reachability`,
  the
  paper's RBF network) says the object is reachable with the arm MoveBase chose, else
  ``failure``. A task makes it terminating: the run ends with its outcome.

The network's inputs, each scaled to about [-1, 1]: the object's x, y [m] in the robot frame
over :data:`INPUT_SCALE_M`, its height z [m] over 1.5 m, its bearing atan2(y, x) over π, and
the torso height over its range. Its five outputs o in (0, 1) mean: the base moves by
``(2 o0 - 1, 2 o1 - 1) · BASE_STEP_M`` in the robot's current frame and turns by
``(2 o2 - 1) · π``; the torso goes to ``o3 · 0.31 m``; the left arm is chosen when
``o4 >= 0.5``, else the right. The same mapping is used by the kinematic twin
(:mod:`skillcompose.skills.kinematic`), so an FSA file means the same pose on both backends.

Keys, shared with the kinematic backend (:mod:`skillcompose.skills.kinematic_world`): the robot's
``base_pose_world`` (x, y, yaw), ``torso_height_m``, ``arm_in_use``; the world's
``table_world`` (a :class:`skillcompose.robots.collision.Box`), ``object_position_world`` (the
object's
centre) and ``room_half_m`` (the room is the square ``|x|, |y| <= room_half_m``).

The weights' length depends on the network topology, so these skills are built for one
topology by :func:`make_skills`; ``register(registry, topology=...)`` adds them.
"""

import functools
import math
from collections.abc import Sequence
from typing import Annotated, Any, Literal

import numpy as np

from skillcompose import Blackboard, Param, Registry, Skill, skill
from skillcompose.robots.collision import BASE_HALF_EXTENTS_M, Box
from skillcompose.robots.reachability import RBFClassifier
from skillcompose.skills.network import (
    TOPOLOGIES,
    WEIGHT_RANGE,
    Topology,
    make_network,
    weight_count,
)

__all__ = [
    "ARM_CODES",
    "BASE_STEP_M",
    "INPUT_SCALE_M",
    "SAFETY_M",
    "TORSO_RANGE_M",
    "BaseGoal",
    "base_goal",
    "base_hits_table",
    "base_in_room",
    "base_table_distance",
    "make_skills",
    "network_inputs",
    "object_in_robot_frame",
    "recognise_object",
    "register",
    "start_pose_near",
    "weights_parameter",
]

SAFETY_M = 0.05
"""MoveBase keeps its base footprint this far from the table [m], as the robot's navigation
did (the paper: most failures on the robot came from its "safety constraints")."""
BASE_STEP_M = 2.5
"""Largest base move along each axis of the robot frame that MoveBase can ask for [m]."""
INPUT_SCALE_M = 2.5
"""The object's x and y in the robot frame are divided by this before the network [m]."""
TORSO_RANGE_M = (0.0, 0.31)
ARM_CODES = {"left": 1, "right": 2}
"""The reachability classifier's label for each arm (0 is unreachable)."""
_KEYS_ROBOT = ("base_pose_world", "torso_height_m", "arm_in_use")

BaseGoal = tuple[tuple[float, float, float], float, Literal["left", "right"]]
"""(base pose (x [m], y [m], yaw [rad]) in world, torso height [m], arm)."""


def object_in_robot_frame(
    base_pose_world: Sequence[float], position_world: Sequence[float]
) -> tuple[float, float, float]:
    """A world point in the robot frame of a base at (x, y, yaw) [m, m, rad]."""
    x, y, yaw = (float(v) for v in base_pose_world)
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = float(position_world[0]) - x, float(position_world[1]) - y
    return c * dx + s * dy, -s * dx + c * dy, float(position_world[2])


def network_inputs(object_robot: Sequence[float], torso_m: float) -> np.ndarray:
    """The network's five scaled inputs (see the module's docstring)."""
    x, y, z = object_robot
    return np.array([
        x / INPUT_SCALE_M, y / INPUT_SCALE_M, z / 1.5, math.atan2(y, x) / math.pi,
        torso_m / TORSO_RANGE_M[1],
    ])


def base_goal(
    outputs: Sequence[float] | np.ndarray, base_pose_world: Sequence[float]
) -> BaseGoal:
    """Where the five network outputs send the robot (see the module's docstring)."""
    x, y, yaw = (float(v) for v in base_pose_world)
    dx = (2.0 * outputs[0] - 1.0) * BASE_STEP_M
    dy = (2.0 * outputs[1] - 1.0) * BASE_STEP_M
    turn = (2.0 * outputs[2] - 1.0) * math.pi
    c, s = math.cos(yaw), math.sin(yaw)
    new_yaw = math.remainder(yaw + turn, 2.0 * math.pi)
    torso = min(max(float(outputs[3]), 0.0), 1.0) * TORSO_RANGE_M[1]
    arm: Literal["left", "right"] = "left" if outputs[4] >= 0.5 else "right"
    return (x + c * dx - s * dy, y + s * dx + c * dy, new_yaw), torso, arm


def base_table_distance(pose: tuple[float, float, float], table: Box) -> float:
    """Distance [m] between the base footprint at ``pose`` (a square turned by its yaw) and
    the axis-aligned table's footprint, exact when they do not overlap: two disjoint convex
    polygons are nearest at a corner of one of them."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    bx, by = BASE_HALF_EXTENTS_M
    tx, ty = table.center_m[0], table.center_m[1]
    hx, hy = table.half_extents_m[0], table.half_extents_m[1]

    def to_rect(px: float, py: float, ex: float, ey: float) -> float:
        return math.hypot(max(abs(px) - ex, 0.0), max(abs(py) - ey, 0.0))

    corners = [(a, b) for a in (-1.0, 1.0) for b in (-1.0, 1.0)]
    base = min(to_rect(x + c * a * bx - s * b * by - tx, y + s * a * bx + c * b * by - ty,
                       hx, hy) for a, b in corners)
    top = min(to_rect(c * (tx + a * hx - x) + s * (ty + b * hy - y),
                      -s * (tx + a * hx - x) + c * (ty + b * hy - y), bx, by)
              for a, b in corners)
    return min(base, top)


def start_pose_near(rng: np.random.Generator, table: Box, room_half_m: float,
                    within_m: float, tries: int = 1000) -> tuple[float, float, float] | None:
    """A base pose drawn uniformly over the room with any heading, whose footprint is wholly
    in the room, clear of ``table`` and at most ``within_m`` from its footprint (the paper's
    "a robot which starts within 2m of the table", §4.2 and §4.3); None after ``tries``
    draws."""
    for _ in range(tries):
        x, y = (float(v) for v in rng.uniform(-room_half_m, room_half_m, size=2))
        pose = (x, y, float(rng.uniform(-math.pi, math.pi)))
        if not base_in_room(pose, room_half_m) or base_hits_table(pose, table):
            continue
        if base_table_distance(pose, table) <= within_m:
            return pose
    return None


def base_hits_table(
    base_pose_world: Sequence[float], table: Box | None, margin_m: float = 0.0
) -> bool:
    """Whether the base footprint (a square, :data:`BASE_HALF_EXTENTS_M`, grown by
    ``margin_m`` on every side) at a pose overlaps the table's footprint: exact, by
    separating axes in the floor plane."""
    if table is None:
        return False
    x, y, yaw = (float(v) for v in base_pose_world)
    hx, hy = BASE_HALF_EXTENTS_M[0] + margin_m, BASE_HALF_EXTENTS_M[1] + margin_m
    tx, ty = float(table.center_m[0]), float(table.center_m[1])
    tw, tl = float(table.half_extents_m[0]), float(table.half_extents_m[1])
    ta = float(table.yaw_rad)
    dx, dy = tx - x, ty - y
    if dx * dx + dy * dy > (hx + hy + tw + tl) ** 2:  # far apart: no trigonometry needed
        return False
    c, s = math.cos(yaw), math.sin(yaw)
    tc, ts = math.cos(ta), math.sin(ta)
    for ax, ay in ((c, s), (-s, c), (tc, ts), (-ts, tc)):
        r_base = hx * abs(ax * c + ay * s) + hy * abs(-ax * s + ay * c)
        r_table = tw * abs(ax * tc + ay * ts) + tl * abs(-ax * ts + ay * tc)
        if abs(dx * ax + dy * ay) > r_base + r_table:
            return False
    return True


def base_in_room(base_pose_world: Sequence[float], room_half_m: float) -> bool:
    """Whether the whole base footprint is inside the square room ``|x|, |y| <= half``."""
    x, y, yaw = (float(v) for v in base_pose_world)
    hx, hy = BASE_HALF_EXTENTS_M
    ex = hx * abs(math.cos(yaw)) + hy * abs(math.sin(yaw))
    ey = hx * abs(math.sin(yaw)) + hy * abs(math.cos(yaw))
    return abs(x) + ex <= room_half_m and abs(y) + ey <= room_half_m


def network_goal(
    bb: Blackboard, rng: np.random.Generator, topology: Topology, weights: Sequence[float]
) -> BaseGoal | Literal["no_object", "too_close"]:
    """The base goal MoveBase's network gives on this blackboard, or why MoveBase refuses
    to go: ``no_object`` without a recognised object, ``too_close`` when the base would come
    closer than :data:`SAFETY_M` to the table. Both backends' MoveBase start here, so the
    network, its outputs' meaning and the safety distance are one rule."""
    location = bb.get("object_location_world")
    if location is None:
        return "no_object"
    base = bb.get("base_pose_world") or (0.0, 0.0, 0.0)
    torso = float(bb.get("torso_height_m", 0.0))
    net = make_network(topology, weights)
    outputs = net(network_inputs(object_in_robot_frame(base, location), torso), rng)
    goal = base_goal(outputs, base)
    if base_hits_table(goal[0], bb.get("table_world"), SAFETY_M):
        return "too_close"
    return goal


@skill(name="RecogniseObject", reads=("object_position_world",),
       writes=("object_location_world",))
def recognise_object(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    """Find the one object on the table: its location goes to ``object_location_world``."""
    bb["object_location_world"] = tuple(float(v) for v in bb["object_position_world"])
    return "success"


@functools.lru_cache(maxsize=1)
def _classifier() -> RBFClassifier:
    """The shipped weights, read once per process (a read-only table, not run state)."""
    return RBFClassifier.load()


def classifier_label(
    base_pose_world: Sequence[float], torso_m: float, position_world: Sequence[float]
) -> int:
    """The reachability classifier's label (0 none, 1 left, 2 right) of an object."""
    x, y, z = object_in_robot_frame(base_pose_world, position_world)
    return _classifier().predict_one(np.array([x, y, z, math.atan2(y, x), torso_m]))


def weights_parameter(topology: Topology) -> tuple[Any, tuple[float, ...]]:
    """MoveBase's ``weights`` declaration for a ``topology`` network: its annotation and
    default. Both backends' MoveBase use this one declaration, so they cannot differ."""
    if topology not in TOPOLOGIES:
        raise ValueError(f"unknown network topology {topology!r}; use one of {TOPOLOGIES}")
    n = weight_count(topology)
    annotation = Annotated[
        tuple[float, ...],
        Param(*WEIGHT_RANGE, size=n, doc=f"the {topology} network's {n} weights"),
    ]
    return annotation, (0.0,) * n


def make_skills(topology: Topology) -> tuple[Skill, ...]:
    """RecogniseObject, MoveBase (a ``topology`` network) and Push on the ``sim`` backend."""
    weights_type: Any  # a run-time Annotated[...]: its length depends on the topology
    weights_type, zeros = weights_parameter(topology)

    def move_base(
        bb: Blackboard, rng: np.random.Generator, *, weights: weights_type = zeros
    ) -> Literal["success", "failure"]:
        goal = network_goal(bb, rng, topology, weights)
        if isinstance(goal, str):
            return "failure"
        pose, torso, arm = goal
        if not base_in_room(pose, float(bb["room_half_m"])):
            return "failure"
        bb["base_pose_world"] = pose
        bb["torso_height_m"] = torso
        bb["arm_in_use"] = arm
        return "success"

    move_base.__doc__ = (
        f"Move the base where a {topology} network of the object's position sends it "
        "(module docstring); failure on the table or out of the room."
    )

    def push(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
        """Success when the classifier says the object is reachable with the chosen arm."""
        arm = bb.get("arm_in_use")
        if arm not in ARM_CODES:
            return "failure"
        base = bb.get("base_pose_world") or (0.0, 0.0, 0.0)
        label = classifier_label(base, float(bb.get("torso_height_m", 0.0)),
                                 bb["object_position_world"])
        if label != ARM_CODES[arm]:
            return "failure"
        bb["pushed"] = True
        return "success"

    reads = ("object_location_world", "table_world", "room_half_m", *_KEYS_ROBOT)
    return (
        recognise_object,
        skill(move_base, name="MoveBase", reads=reads, writes=_KEYS_ROBOT, backend="sim"),
        skill(push, name="Push", reads=("object_position_world", *_KEYS_ROBOT),
              writes=("pushed",), backend="sim"),
    )


def register(registry: Registry, *, topology: Topology = "layered") -> None:
    """Add the move-to-push skills for a ``topology`` network to ``registry``."""
    for s in make_skills(topology):
        registry.add(s)
