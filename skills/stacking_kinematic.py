"""The kinematic side of the stacking experiment (section 4.3) that
:mod:`skillcompose.skills.kinematic` does not hold: MoveToReach's terminating Push as a check
on the PR2 model.

GraspParam, MoveGripperToStack and OpenGripper are the twins in
:mod:`skillcompose.skills.kinematic`;
RecogniseObject and CheckSuccess of :mod:`skillcompose.skills.stacking` serve both backends.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from skillcompose import Blackboard
from skillcompose.skills.kinematic_world import (
    DETAIL_KEY,
    GRASP_KEY,
    GRASP_KINDS,
    REASON_KEY,
    ROBOT_READS,
    WORLD_READS,
    GraspKind,
    KinematicWorld,
    fail,
    kinematic_skill,
    reach_grasp,
    read_state,
    scene_world,
)
from skillcompose.skills.stacking_world import held, reach_arms, reach_goal

__all__ = ["reach_check"]


@kinematic_skill(name="Push", reads=(*ROBOT_READS, *WORLD_READS, "grasp_target"),
                 writes=(REASON_KEY, DETAIL_KEY))
def reach_check(
    world: KinematicWorld, bb: Blackboard, rng: np.random.Generator
) -> Literal["success", "failure"]:
    """MoveToReach's Push on the PR2 model, moving nothing: ``success`` when IK finds a grasp
    (:data:`skillcompose.skills.kinematic_world.GRASP_KINDS`; holding, the kind it holds with) by
    an arm of
    :func:`skillcompose.skills.stacking.reach_arms` (the holding one, else the arm MoveBase chose
    and then
    the other) of an object centred on the point of
    :func:`skillcompose.skills.stacking.reach_goal`. The
    arms stay where they are."""
    goal = reach_goal(bb)
    if goal is None:
        return fail(bb, "no_object", "Push (MoveToReach): object_positions_world needs two "
                    "objects")
    state = read_state(bb)
    arms = sorted(reach_arms(bb), key=lambda a: a != state.arm_in_use)
    kinds: tuple[GraspKind, ...] = GRASP_KINDS if held(bb) is None else \
        (bb.get(GRASP_KEY) or "top",)
    _, answer = reach_grasp(world, state, arms, goal[1], scene_world(bb), rng, kinds,
                            diagnose=False)
    if answer.state is None:
        return fail(bb, answer.reason, f"Push (MoveToReach): {answer.detail}")
    return "success"
