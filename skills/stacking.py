"""Skills of the paper's third experiment, stacking (section 4.3), on the ``sim`` backend.

Two objects stand on a table; the robot must put one on the other. The world uses the keys
of the kinematic backend (:mod:`skillcompose.skills.kinematic_world`), so the kinematic twins of
:mod:`skillcompose.skills.kinematic` run on the same blackboard:

=============================== ===========================================================
key                             meaning
=============================== ===========================================================
``p_fail``                      probability of a random ``failure`` of GraspParam,
                                MoveToReach and MoveGripperToStack (the paper's 0.3)
``object_positions_world``      {name: centre (x, y, z) [m]}: the first and second object
``object_half_extents_m``       {name: half sizes [m]}: each object is an upright box
``object_locations_world``      where RecogniseObject saw both objects (absent until then)
``table_world``                 the table, a :class:`skillcompose.robots.collision.Box`
``base_pose_world``             the robot's base (x [m], y [m], yaw [rad]) in world
``torso_height_m``              the torso lift [m]
``held_object_left`` / _right   the object in that gripper, or None
``arm_in_use``                  the arm of "the gripper", or None
``gripper_position_world``      the gripper in use; a held object's centre sits there [m]
``objects_grasped``             names of the objects grasped so far in this run
``grasp_target``                the object GraspParam last tried to grasp (absent until then)
=============================== ===========================================================

- ``RecogniseObject``: stores where both objects are (``object_locations_world``); only
  ``success``. One implementation for both backends (perception is not kinematics).
- ``GraspParam(which)``: grasps the first object (``which`` > 0.5) or the second, with the arm
  the reachability classifier names for it. ``failure`` when the objects were not recognised,
  a gripper already holds one, the object carries the other, the classifier says no arm
  reaches it, or at random with ``p_fail``.
- ``MoveGripperToStack(which, dx, dy, dz)``: the gripper (and the held object) to the chosen
  object's centre + (dx, dy, dz) [m]. ``failure`` when the objects were not recognised, the
  chosen object is the held one, the gripper point would be inside the table or an object, the
  held object would sink into the table or the other object (touching is stacking), the
  classifier says the arm in use (or, empty-handed, any arm) does not reach the point, or at
  random with ``p_fail``.
- ``OpenGripper``: only ``success``; a held object falls straight down onto the highest
  surface under it (the other object, the table, or the floor at z = 0).
- ``CheckSuccess``: ``success`` when neither object is held and one stands on the other:
  its bottom on the other's top (within :data:`STACK_TOLERANCE_M`) and its centre over the
  other's top face; else ``failure``. One implementation for both backends; a task makes it
  terminating.
- ``MoveToReach``: the FSA evolved for moving to push (section 4.2), loaded from its file and
  run as a nested FSA (:func:`make_move_to_reach`), after a random ``failure`` with
  ``p_fail``. Its target is :func:`reach_target`: with an object held, the other object
  (where it will be stacked); empty-handed, the object GraspParam last tried to grasp (the first
  before any). Its skills are compiled against
  its own registry (:func:`reach_registry`): RecogniseObject writes that target to
  ``object_location_world``, MoveBase is section 4.2's network, and Push is a check that
  moves nothing (:func:`reach_check`: the classifier on ``sim``, IK on ``kinematic``) of
  the point of :func:`reach_goal` by an arm of :func:`reach_arms`. By default
  (``shortcut``) the same check, as a one-state FSA, runs first: when the target is already
  in reach MoveToReach succeeds without moving (the evolved network never started in reach
  in section 4.2, and from there it drove the robot away); with ``shortcut=False`` the
  nested FSA runs whatever the start (as the paper's MoveToReach). It shares the caller's
  blackboard and generator and counts as one step of the caller; its own steps are bounded
  by its file's ``step_limit``. A held object moves with the base, and the arm in use stays
  the arm that holds it.

Randomness comes only from the run's generator: a skill whose preconditions hold draws one
number and fails when it is below ``p_fail``; one whose preconditions fail draws nothing.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np

from skillcompose import Blackboard, BlackboardKeyError, Registry, Skill, skill
from skillcompose.errors import RegistryError
from skillcompose.fsa import FSA, State
from skillcompose.fsafile import load_fsa
from skillcompose.nested import FSASkill, fsa_skill
from skillcompose.robots.collision import Box
from skillcompose.skill import SkillFn, SkillSpec
from skillcompose.skills import move_to_push as skills_push
from skillcompose.skills.move_to_push import ARM_CODES
from skillcompose.skills.network import Topology
from skillcompose.skills.stacking_world import (
    DEFAULT_HALF_EXTENTS_M,
    HELD_KEYS,
    STACK_TOLERANCE_M,
    TOUCH_M,
    Arm,
    StackDX,
    StackDY,
    StackDZ,
    Vec3,
    Which,
    as_vec3,
    held,
    landing_z,
    object_boxes,
    reach_arms,
    reach_goal,
    reach_label,
    reach_target,
    stacked,
    supports,
    which_name,
)

__all__ = [
    "DEFAULT_HALF_EXTENTS_M",
    "HELD_KEYS",
    "STACK_TOLERANCE_M",
    "MoveToReach",
    "check_success",
    "grasp_param",
    "held",
    "landing_z",
    "make_move_to_reach",
    "move_gripper_to_stack",
    "object_boxes",
    "open_gripper",
    "reach_registry",
    "reach_target",
    "recognise_objects",
    "register",
    "stacked",
]

_LABEL_ARMS: dict[int, Arm] = {code: arm for arm, code in ARM_CODES.items()}  # type: ignore[misc]
_WHICH = Which
_WORLD = ("object_positions_world", "object_half_extents_m", "table_world")
_ROBOT = ("base_pose_world", "torso_height_m", "arm_in_use", *HELD_KEYS.values())

def _random_failure(bb: Blackboard, rng: np.random.Generator) -> bool:
    return bool(rng.random() < float(bb.get("p_fail", 0.0)))


# -- the stacking skills ---------------------------------------------------------------------
@skill(name="RecogniseObject", reads=("object_positions_world",),
       writes=("object_locations_world",))
def recognise_objects(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    """Find both objects on the table: their positions go to ``object_locations_world``."""
    bb["object_locations_world"] = {
        str(n): as_vec3(p) for n, p in bb["object_positions_world"].items()
    }
    return "success"


@skill(name="GraspParam", reads=(*_WORLD, *_ROBOT, "object_locations_world", "p_fail",
                                 "objects_grasped"),
       writes=("arm_in_use", *HELD_KEYS.values(), "gripper_position_world", "objects_grasped",
               "grasp_target"),
       backend="sim")
def grasp_param(
    bb: Blackboard, rng: np.random.Generator, *, which: _WHICH = 1.0
) -> Literal["success", "failure"]:
    """Grasp the first (``which`` > 0.5) or the second object (module docstring)."""
    name = which_name(bb, which)
    if name is None or bb.get("object_locations_world") is None or held(bb) is not None:
        return "failure"
    bb["grasp_target"] = name
    boxes = object_boxes(bb)
    if any(supports(boxes[name], b) for n, b in boxes.items() if n != name):
        return "failure"  # the other object stands on it
    label = reach_label(bb, boxes[name].center_m)
    if label == 0 or _random_failure(bb, rng):
        return "failure"
    arm = _LABEL_ARMS[label]
    bb[HELD_KEYS[arm]] = name
    bb["arm_in_use"] = arm
    bb["gripper_position_world"] = as_vec3(boxes[name].center_m)
    bb["objects_grasped"] = (*(bb.get("objects_grasped") or ()), name)
    return "success"


@skill(name="MoveGripperToStack",
       reads=(*_WORLD, *_ROBOT, "object_locations_world", "p_fail"),
       writes=("object_positions_world", "gripper_position_world", "arm_in_use"),
       backend="sim")
def move_gripper_to_stack(
    bb: Blackboard,
    rng: np.random.Generator,
    *,
    which: _WHICH = 1.0,
    dx: StackDX = 0.0,
    dy: StackDY = 0.0,
    dz: StackDZ = 0.1,
) -> Literal["success", "failure"]:
    """Move the gripper to the chosen object's centre + (dx, dy, dz) (module docstring)."""
    name = which_name(bb, which)
    if name is None or bb.get("object_locations_world") is None:
        return "failure"
    holding = held(bb)
    if holding is not None and holding[1] == name:
        return "failure"
    boxes = object_boxes(bb)
    anchor = boxes[name].center_m
    goal = (anchor[0] + dx, anchor[1] + dy, anchor[2] + dz)
    solid = [b for n, b in boxes.items() if holding is None or n != holding[1]]
    table = bb.get("table_world")
    if table is not None:
        solid.append(table)
    point = np.array(goal)
    if any(float(b.signed_distance_m(point)[0]) < 0.0 for b in solid):
        return "failure"
    if holding is not None:
        carried = boxes[holding[1]]
        moved = Box(goal, tuple(max(h - TOUCH_M, 1e-4)  # type: ignore[arg-type]
                                for h in carried.half_extents_m), 0.0, carried.name)
        if any(moved.overlaps(b) for b in solid):
            return "failure"
    label = reach_label(bb, goal)
    if label == 0 or (holding is not None and _LABEL_ARMS[label] != holding[0]):
        return "failure"
    if _random_failure(bb, rng):
        return "failure"
    bb["gripper_position_world"] = goal
    bb["arm_in_use"] = holding[0] if holding is not None else _LABEL_ARMS[label]
    if holding is not None:
        positions = dict(bb["object_positions_world"])
        positions[holding[1]] = goal
        bb["object_positions_world"] = positions
    return "success"


@skill(name="OpenGripper", reads=(*_WORLD, *_ROBOT),
       writes=("object_positions_world", *HELD_KEYS.values()), backend="sim")
def open_gripper(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    """Open the gripper; a held object falls onto the highest surface under it."""
    holding = held(bb)
    if holding is None:
        return "success"
    arm, name = holding
    boxes = object_boxes(bb)
    others = [b for n, b in boxes.items() if n != name]
    table = bb.get("table_world")
    if table is not None:
        others.append(table)
    box = boxes[name]
    positions = dict(bb["object_positions_world"])
    positions[name] = (box.center_m[0], box.center_m[1], landing_z(box, others))
    bb["object_positions_world"] = positions
    bb[HELD_KEYS[arm]] = None
    return "success"


@skill(name="CheckSuccess", reads=("object_positions_world", "object_half_extents_m",
                                   *HELD_KEYS.values()))
def check_success(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    """``success`` when one object stands on the other and neither is held."""
    return "success" if stacked(bb) else "failure"


# -- MoveToReach: the section 4.2 FSA as a skill ---------------------------------------------
@skill(name="RecogniseObject", reads=("object_positions_world", "grasp_target",
                                      *HELD_KEYS.values()),
       writes=("object_location_world",))
def recognise_target(bb: Blackboard, rng: np.random.Generator) -> Literal["success"]:
    """MoveToReach's RecogniseObject: its one object is :func:`reach_target`."""
    target = reach_target(bb)
    if target is None:
        raise BlackboardKeyError(
            "skill RecogniseObject (in MoveToReach): object_positions_world needs two "
            "objects; run it with a stacking world (examples.stacking)")
    bb["object_location_world"] = target[1]
    return "success"


@skill(name="Push", reads=("object_positions_world", "object_half_extents_m", "grasp_target",
                           *_ROBOT), backend="sim")
def reach_check(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    """MoveToReach's terminating Push, which moves nothing: ``success`` when the classifier
    says an arm of :func:`reach_arms` reaches the point of :func:`reach_goal`."""
    goal = reach_goal(bb)
    if goal is None:
        return "failure"
    label = reach_label(bb, goal[1])
    return "success" if label and _LABEL_ARMS[label] in reach_arms(bb) else "failure"


def reach_registry(topology: Topology = "layered", *, kinematic: bool = True) -> Registry:
    """The skills MoveToReach's states run on: RecogniseObject (:func:`recognise_target`),
    MoveBase for a ``topology`` network (both backends) and Push (:func:`reach_check`; on
    the kinematic backend :func:`skillcompose.skills.stacking_kinematic.reach_check`)."""
    registry = Registry(backend="sim")
    registry.add(recognise_target)
    for s in skills_push.make_skills(topology):
        if s.name == "MoveBase":
            registry.add(s)
    registry.add(reach_check)
    if kinematic:
        from skillcompose.skills import kinematic as skills_kinematic
        from skillcompose.skills import kinematic_world, stacking_kinematic

        world = kinematic_world.KinematicWorld()
        registry.add(skills_kinematic.make_move_base(topology).in_world(world))
        registry.add(stacking_kinematic.reach_check.in_world(world))
    return registry


class MoveToReach(Skill):
    """A nested FSA (:class:`skillcompose.nested.FSASkill`) behind a random failure with the
    blackboard's ``p_fail``; a held object moves with the base (module docstring). With
    ``shortcut`` (default) it succeeds without running the nested FSA when the target is
    already in reach; without, the nested FSA always runs."""

    __slots__ = ("guard", "nested", "shortcut")

    def __init__(self, nested: FSASkill, *, shortcut: bool = True) -> None:
        spec = nested.spec
        reads = spec.reads | {"p_fail", "object_positions_world", "gripper_position_world",
                              *_ROBOT}
        writes = spec.writes | {"object_positions_world", "gripper_position_world",
                                "arm_in_use"}
        super().__init__(SkillSpec(
            name="MoveToReach", outcomes=("success", "failure"), params=(),
            reads=frozenset(reads), writes=frozenset(writes), key_types=dict(spec.key_types),
            doc=f"MoveToReach: {spec.doc}, failing at random with p_fail"
                + ("" if shortcut else ", run even when the target is already in reach"),
        ), None, backend="default")
        self.nested = nested
        self.shortcut = shortcut
        self.guard = fsa_skill(FSA({"InReach": State("Push", transitions={
            "success": "success", "failure": "failure"})}, start="InReach",
            name="InReach"), nested.registry, name="InReach")

    def bind(self, registry: Any = None, backend: str | None = None) -> SkillFn:
        run = self.nested.bind(None, backend)
        in_reach = self.guard.bind(None, backend) if self.shortcut else None

        def move_to_reach(bb: Blackboard, rng: np.random.Generator) -> str:
            if _random_failure(bb, rng):
                return "failure"
            if in_reach is not None and in_reach(bb, rng) == "success":
                return "success"  # already in reach: nothing to move
            holding = held(bb)
            before = (bb.get("base_pose_world") or (0.0, 0.0, 0.0),
                      float(bb.get("torso_height_m", 0.0)))
            position = (as_vec3(bb["object_positions_world"][holding[1]])
                        if holding is not None else None)
            outcome = run(bb, rng)
            if holding is not None and position is not None:
                _carry(bb, holding, position, before)
            return "failure" if outcome != "success" else "success"

        return move_to_reach


def _carry(bb: Blackboard, holding: tuple[Arm, str], position_before: Vec3,
           before: tuple[Sequence[float], float]) -> None:
    """After MoveToReach with an object held: the arm in use is the holding arm again and the
    gripper is at the held object. On the kinematic backend the base motion already moved
    the object with the tool; on ``sim`` (where nothing else moves it) it follows the base."""
    arm, name = holding
    bb["arm_in_use"] = arm
    position = as_vec3(bb["object_positions_world"][name])
    (x0, y0, yaw0), torso0 = before
    x1, y1, yaw1 = bb.get("base_pose_world") or (0.0, 0.0, 0.0)
    torso1 = float(bb.get("torso_height_m", 0.0))
    if position == position_before and (x0, y0, yaw0, torso0) != (x1, y1, yaw1, torso1):
        c0, s0 = math.cos(yaw0), math.sin(yaw0)
        dx, dy = position[0] - x0, position[1] - y0
        rx, ry = c0 * dx + s0 * dy, -s0 * dx + c0 * dy
        c1, s1 = math.cos(yaw1), math.sin(yaw1)
        position = (x1 + c1 * rx - s1 * ry, y1 + s1 * rx + c1 * ry,
                    position[2] + torso1 - torso0)
        positions = dict(bb["object_positions_world"])
        positions[name] = position
        bb["object_positions_world"] = positions
    bb["gripper_position_world"] = position


def make_move_to_reach(
    path: str | Path, *, topology: Topology = "layered", kinematic: bool = True,
    shortcut: bool = True, registry: Registry | None = None,
) -> MoveToReach:
    """MoveToReach from an evolved move-to-push FSA file (``examples/move_to_reach.fsa.yaml``):
    validated against :func:`reach_registry` (or ``registry``, e.g. one with the dynamic
    twins too) when loaded; its ``timeout`` becomes ``failure``. ``shortcut``: succeed
    without moving when the target is already in reach (:class:`MoveToReach`)."""
    machine = load_fsa(path)
    if sorted(machine.terminals) != ["failure", "success"]:  # else renamed ends go unseen
        at = machine.source.at("terminals") if machine.source is not None else ""
        raise RegistryError(
            f"{path}{at}: MoveToReach ends in success or failure (what stacking reads of "
            f"it), but this FSA's terminals are {list(machine.terminals)}; set `terminals: "
            "[success, failure]` and route its states' outcomes to them"
        )
    nested = fsa_skill(machine, registry if registry is not None else
                       reach_registry(topology, kinematic=kinematic),
                       name="MoveToReach", on_timeout="failure")
    return MoveToReach(nested, shortcut=shortcut)


def register(
    registry: Registry, *, move_to_reach: str | Path | None = None,
    topology: Topology = "layered", kinematic: bool = True, shortcut: bool = True,
) -> None:
    """Add the stacking skills (``sim`` backend, plus the two shared by both backends) and,
    given its file, MoveToReach (``shortcut``: see :class:`MoveToReach`)."""
    for s in (recognise_objects, grasp_param, move_gripper_to_stack, open_gripper,
              check_success):
        registry.add(s)
    if move_to_reach is not None:
        registry.add(make_move_to_reach(move_to_reach, topology=topology, kinematic=kinematic,
                                        shortcut=shortcut))
