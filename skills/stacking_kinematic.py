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
from skills.stacking import held, object_boxes, reach_target

__all__ = ["reach_check"]


@skill(name="Push", reads=(*ROBOT_READS, *WORLD_READS),
       writes=(REASON_KEY, DETAIL_KEY), backend="kinematic")
def reach_check(bb: Blackboard, rng: np.random.Generator) -> Literal["success", "failure"]:
    """MoveToReach's Push on the PR2 model, moving nothing: ``success`` when IK puts the tool
    of the arm holding an object (else the arm MoveBase chose) from above on the target of
    :func:`skills.stacking.reach_target`: on its centre empty-handed, with an object held
    where that object would stand on the target. The arms stay where they are."""
    target = reach_target(bb)
    if target is None:
        return fail(bb, "no_object", "Push (MoveToReach): object_positions_world needs two "
                    "objects")
    name, position = target
    holding = held(bb)
    state = read_state(bb)
    arm = holding[0] if holding is not None else state.arm_in_use
    if arm is None:
        return fail(bb, "not_recognised", "Push (MoveToReach): no arm chosen; run MoveBase "
                    "first")
    goal = position
    if holding is not None:
        boxes = object_boxes(bb)
        rise = boxes[name].half_extents_m[2] + boxes[holding[1]].half_extents_m[2]
        goal = (position[0], position[1], position[2] + rise)
    answer = reach(state, arm, top_down_grasp_world(state.base_pose_world, goal),
                   scene_world(bb), rng, diagnose=False)
    if answer.state is None:
        return fail(bb, answer.reason, f"Push (MoveToReach): {answer.detail}")
    return "success"
