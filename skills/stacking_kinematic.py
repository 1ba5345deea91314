"""The kinematic side of the stacking experiment (section 4.3) that :mod:`skills.kinematic`
does not hold: MoveToReach's terminating Push as a check on the PR2 model.

GraspParam, MoveGripperToStack and OpenGripper are the twins in :mod:`skills.kinematic`;
RecogniseObject and CheckSuccess of :mod:`skills.stacking` serve both backends.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from skillcompose import Blackboard, skill
from skills.kinematic_world import (
    DETAIL_KEY,
    REASON_KEY,
    ROBOT_READS,
    WORLD_READS,
    fail,
    reach,
    read_state,
    scene_world,
    top_down_grasp_world,
)
from skills.stacking import reach_arms, reach_goal

__all__ = ["reach_check"]


@skill(name="Push", reads=(*ROBOT_READS, *WORLD_READS),
       writes=(REASON_KEY, DETAIL_KEY), backend="kinematic")
def reach_check(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    """MoveToReach's Push on the PR2 model, moving nothing: ``success`` when IK puts the tool
    of an arm of :func:`skills.stacking.reach_arms` (the holding one, else the arm MoveBase
    chose and then the other) from above on the point of :func:`skills.stacking.reach_goal`.
    The arms stay where they are."""
    goal = reach_goal(bb)
    if goal is None:
        return fail(bb, "no_object", "Push (MoveToReach): object_positions_world needs two "
                    "objects")
    state = read_state(bb)
    arms = sorted(reach_arms(bb), key=lambda a: a != state.arm_in_use)
    answer = None
    for arm in arms:
        answer = reach(state, arm, top_down_grasp_world(state.base_pose_world, goal[1]),
                       scene_world(bb), rng, diagnose=False)
        if answer.state is not None:
            return "success"
    assert answer is not None
    return fail(bb, answer.reason, f"Push (MoveToReach): {answer.detail}")
