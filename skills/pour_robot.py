"""Whether the PR2 can pour from a pose: what the abstract pour skills ask the robot model.

The abstract skills of :mod:`skillcompose.skills.pour_water` would pour with any tilt in the
band over the glass, but the PR2's arm reaches only some of those rotations at a given
spout position (about half of the band at the glass's centre, fewer near the rim, more
higher up; measured by running the kinematic twins). An FSA evolved on rotations the arm
cannot take pours in the abstract world and never on the robot, so an abstract skill asks
the robot first, as the paper's move-to-push experiment asks its reachability classifier
(section 4.2). Here the answer is exact rather than learned: the pour world is fixed, so
whether the robot can pour depends on the FSA's six parameters only, and an evolution run
asks about a few hundred distinct poses (the answers are cached per process).

:func:`pr2_can_pour` runs the kinematic twins (:mod:`skillcompose.skills.kinematic`) the way
an FSA that pours does: RecogniseObject, MoveToObject, GraspObject, MoveGripperToParam to the
spout position, RotateGripperToParam to the rotation, from the episode's starting world and
with a fixed seed, and answers whether the gripper took that rotation there. Different
paths to the same pose may end in other arm configurations; ``benchmarks/transfer_pour.py``
measures how often an FSA found this way pours on the kinematic and dynamic backends.
"""

from __future__ import annotations

import functools

import numpy as np

from skillcompose import Blackboard, Registry
from skillcompose.skills.pour_geometry import Vec3

__all__ = ["CHECK_SEED", "can_pour", "physics_can_pour", "pr2_can_pour"]

CHECK_SEED = 0
"""The seed of the IK's random restarts in the check (the answer is the same in every
process and run)."""

_PATH = ("RecogniseObject", "MoveToObject", "GraspObject")


@functools.cache
def _registry() -> Registry:
    from skillcompose.skills import kinematic

    registry = Registry(backend="kinematic")
    kinematic.register(registry)
    return registry


def _start_board(start: tuple[Vec3, Vec3, Vec3]) -> Blackboard:
    jug, glass, home = start
    return Blackboard({
        "p_fail": 0.0, "jug_position_world": jug, "glass_position_world": glass,
        "gripper_position_world": home, "gripper_rotation": (0.0, 0.0, 0.0),
        "holding_jug": False, "water": "jug",
    })


@functools.cache
def _dynamic() -> tuple[Registry, object]:
    from skillcompose.skills import pour_water_dynamic

    registry = Registry(backend="dynamic")
    world = pour_water_dynamic.register(registry)
    return registry, world


def _take_pose(registry: Registry, backend: str, bb: Blackboard, position: Vec3,
               rotation: Vec3) -> bool:
    """Run ``backend``'s twins along the path of an FSA that pours: RecogniseObject,
    MoveToObject, GraspObject, MoveGripperToParam to ``position`` and, when all of those
    succeed (else False), RotateGripperToParam to ``rotation`` (then True; its outcome is
    always ``success``: ``last_failure_reason``, cleared before it, and the world say what
    it did)."""
    rng = np.random.default_rng(CHECK_SEED)
    for name in _PATH:
        if registry.resolve(name, backend)(bb, rng) != "success":
            return False
    x, y, z = position
    if registry.resolve("MoveGripperToParam", backend)(bb, rng, x=x, y=y, z=z) != "success":
        return False
    rho, phi, theta = rotation
    bb["last_failure_reason"] = None
    registry.resolve("RotateGripperToParam", backend)(bb, rng, rho=rho, phi=phi, theta=theta)
    return True


@functools.lru_cache(maxsize=1 << 14)
def physics_can_pour(start: tuple[Vec3, Vec3, Vec3], position: Vec3, rotation: Vec3) -> bool:
    """Whether the PR2 simulated in MuJoCo (the ``dynamic`` twins,
    :mod:`skillcompose.skills.pour_water_dynamic`) pours the water into the glass by the
    path of :func:`pr2_can_pour`: at least 80 % of the particles in the glass once they
    rest. About 3 s of CPU per pose (an evolution run asks about a few hundred)."""
    from skillcompose.skills import pour_water_dynamic

    registry, world = _dynamic()
    bb = _start_board(start)
    pour_water_dynamic.start_episode(world, bb)  # type: ignore[arg-type]
    return _take_pose(registry, "dynamic", bb, position, rotation) and bb["water"] == "glass"


@functools.lru_cache(maxsize=1 << 16)
def pr2_can_pour(start: tuple[Vec3, Vec3, Vec3], position: Vec3, rotation: Vec3) -> bool:
    """Whether the PR2, from the world ``start`` (the jug's spout, the glass's rim, the
    gripper's home, all in world [m]), grasps the jug, brings the spout to ``position`` and
    rotates the gripper to ``rotation`` (roll, pitch, yaw [rad]) with its kinematic skills."""
    bb = _start_board(start)
    return _take_pose(_registry(), "kinematic", bb, position, rotation) and \
        bb.get("last_failure_reason") is None and \
        tuple(bb["gripper_rotation"]) == tuple(rotation)


def can_pour(kind: str, start: tuple[Vec3, Vec3, Vec3], position: Vec3,
             rotation: Vec3) -> bool:
    """The check the pour task's ``reach`` setting names: ``"pr2"``
    (:func:`pr2_can_pour`) or ``"physics"`` (:func:`physics_can_pour`)."""
    if kind == "physics":
        return physics_can_pour(start, position, rotation)
    if kind == "pr2":
        return pr2_can_pour(start, position, rotation)
    raise ValueError(f"robot check {kind!r}: expected pr2 or physics")
