"""Stacking on the dynamic backend (the PR2 in MuJoCo): a grasped box stays in the fingers
while it is carried and rests on the other after the release, physics' failures are
outcomes, the shipped FSA stacks, and runs repeat exactly."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

pytest.importorskip("mujoco")

from skillcompose import Blackboard, compile_fsa, load_fsa
from skillcompose.executor import trial_rngs
from skillcompose.robots.model import ARMS, Arm
from skillcompose.skills import kinematic as skills_kinematic
from skillcompose.skills import stacking_dynamic as sd
from skillcompose.skills import stacking_transits as transits
from skillcompose.skills.dynamic_world import (
    DYNAMIC_FAILURE_REASONS,
    arm_touches_table,
    execute,
    sync,
    world_of,
)
from skillcompose.skills.kinematic_world import (
    FAILURE_REASONS,
    GRASP_KEY,
    KinematicSkill,
    grasp_pose_world,
    read_state,
)
from skillcompose.skills.move_to_push_dynamic import unfolded
from skillcompose.skills.stacking_world import stacked
from skillcompose.task import Task, load_task

pytestmark = [pytest.mark.physics, pytest.mark.kinematics]

SHIPPED = "docs/results/stacking_best.fsa.yaml"
SEED = 30_000  # the reproduction's scenes
# the shipped file's states' parameters
WHICH_GRASP = 0.7818458873531227
STACK = {"which": 0.07814379907208957, "dx": -0.013029712019154538,
         "dy": -0.005102085712462706, "dz": 0.13963042514898763}


def _scene(k: int) -> tuple[Task, Blackboard, np.random.Generator]:
    task = load_task("examples.stacking", backend="dynamic", trials=1)
    rng = list(trial_rngs(SEED, k + 1))[k]
    return task, task.setup(rng), rng


def _call(task: Task, bb: Blackboard, rng: np.random.Generator, name: str,
          **params: Any) -> str:
    return str(task.registry.resolve(name, "dynamic").bind(task.registry, "dynamic")(
        bb, rng, **params))


def _grasp(task: Task, bb: Blackboard, rng: np.random.Generator) -> Arm:
    """GraspParam on the scene's grasp target, asserted to succeed; the arm in use."""
    assert _call(task, bb, rng, "GraspParam", which=WHICH_GRASP) == "success", \
        bb.get("last_failure_detail")
    arm: Arm = bb["arm_in_use"]
    return arm


def test_a_grasped_box_is_carried_and_rests_on_the_other() -> None:
    task, bb, rng = _scene(1)
    assert _call(task, bb, rng, "RecogniseObject") == "success"
    assert _call(task, bb, rng, "MoveToReach") == "success"
    arm = _grasp(task, bb, rng)
    carried = bb[f"held_object_{arm}"]
    assert carried is not None
    world = world_of(task.registry)
    assert world is not None and world.physics is not None
    assert world.physics.held_object(arm) == carried
    assert _call(task, bb, rng, "MoveGripperToStack", **STACK) == "success", \
        bb.get("last_failure_detail")
    assert world.physics.held_object(arm) == carried  # held by friction all the way
    assert _call(task, bb, rng, "OpenGripper") == "success"
    assert bb[f"held_object_{arm}"] is None and stacked(bb)
    assert all(world.physics.upright(n) for n in bb["object_positions_world"])
    assert _call(task, bb, rng, "CheckSuccess") == "success"


def test_a_transit_through_the_table_goes_over_it() -> None:
    # scene 9: the joint-space line to the grasp's first waypoint passes the upper arm
    # through the table's edge; the arm goes with its shoulder lifted first
    task, bb, rng = _scene(9)
    world = world_of(task.registry)
    assert world is not None and world.physics is not None
    assert _call(task, bb, rng, "RecogniseObject") == "success"
    assert _call(task, bb, rng, "MoveToReach") == "success"
    before = unfolded(read_state(bb), ARMS)
    arm = _grasp(task, bb, rng)
    assert world.physics.held_object(arm) == bb["grasp_target"]
    planned = read_state(bb)
    route = sd.clear_transits(world.physics, arm, before, [planned])
    assert route[-1] is planned and len(route) <= 3
    assert not any(arm_touches_table(world.physics, s, arm) for s in route[:-1])
    if len(route) > 1:  # inserted only where the direct motion touches the table
        assert sd.line_touches_table(world.physics, before, planned, arm)


def test_a_box_too_wide_for_the_fingers_is_an_outcome() -> None:
    task, bb, rng = _scene(1)
    world = world_of(task.registry)
    assert world is not None
    wide = {name: (0.06, 0.06, 0.06) for name in bb["object_positions_world"]}
    bb["object_half_extents_m"] = wide  # 12 cm across: the open fingers span 9 cm
    bb["object_positions_world"] = {n: (p[0], p[1], p[2]) for n, p in
                                    bb["object_positions_world"].items()}
    sd.start_episode(world, bb)
    _call(task, bb, rng, "RecogniseObject")
    outcomes = [_call(task, bb, rng, "GraspParam", which=WHICH_GRASP) for _ in range(2)]
    assert "failure" in outcomes
    assert bb["last_failure_reason"] in (*DYNAMIC_FAILURE_REASONS, *FAILURE_REASONS)


def _runs(n: int, first: int = 0, trace: bool = False) -> list[tuple[object, ...]]:
    task = load_task("examples.stacking", backend="dynamic", trials=1)
    compiled = compile_fsa(load_fsa(SHIPPED), task.registry, "dynamic")
    out: list[tuple[object, ...]] = []
    for rng in list(trial_rngs(SEED, first + n))[first:]:
        bb = task.setup(rng)
        result = compiled.run(bb, rng, trace=trace)
        out.append((task.score(result, bb), result.outcome, bb.get("last_failure_reason"),
                    bb["object_positions_world"],
                    [(s.state, s.outcome) for s in result.trace or ()]))
    return out


@pytest.mark.slow
def test_the_shipped_fsa_stacks_on_most_scenes() -> None:
    scores = [o[0] for o in _runs(4, first=1)]
    assert sum(s == 0.0 for s in scores) >= 3, scores  # measured: all 4


@pytest.mark.slow
def test_same_seed_same_episode() -> None:
    assert _runs(1, first=1, trace=True) == _runs(1, first=1, trace=True)


def _prepared(k: int) -> tuple[Task, Blackboard, np.random.Generator, Any]:
    task, bb, rng = _scene(k)
    world = world_of(task.registry)
    assert world is not None and world.physics is not None
    assert _call(task, bb, rng, "RecogniseObject") == "success"
    assert _call(task, bb, rng, "MoveToReach") == "success"
    return task, bb, rng, world


def test_sync_keeps_a_limited_joints_angle_beyond_pi() -> None:
    # the upper arm roll's limits are -0.8 to 3.9 rad: wrapped to [-pi, pi], 3.7 rad became
    # -2.58, outside them, and every IK warm-started from the synced arm jumped or failed
    _, bb, _, world = _prepared(1)
    physics = world.physics
    state = read_state(bb)
    q = list(state.q_arm_rad["left"])
    q[2], q[4] = 3.7, 3.0  # upper arm roll (limited); forearm roll (continuous)
    physics.reset(base_pose_world=state.base_pose_world, torso_m=0.3,
                  q_arm_rad={"left": q, "right": state.q_arm_rad["right"]})
    physics.step(0.1)
    synced = sync(physics, bb, planned=state)
    assert synced.q_arm_rad["left"][2] == pytest.approx(3.7, abs=0.02)
    assert -np.pi <= synced.q_arm_rad["left"][4] <= np.pi


def test_the_arm_moves_at_the_higher_torso() -> None:
    # lowering: the arm first, then the torso (a held box was driven into the table when
    # the torso went down first); raising: the torso first
    _, bb, _, world = _prepared(1)
    physics = world.physics
    calls: list[str] = []
    track, torso = physics.track_arm, physics.move_torso

    def on_arm(*a: Any, **k: Any) -> Any:
        calls.append("arm")
        return track(*a, **k)

    def on_torso(*a: Any, **k: Any) -> Any:
        calls.append("torso")
        return torso(*a, **k)

    physics.track_arm, physics.move_torso = on_arm, on_torso
    now = read_state(bb)
    q = list(now.q_arm_rad["left"])
    q[0] += 0.1
    high = dataclasses.replace(now, torso_height_m=0.3)
    execute(world, physics, now, high.with_arm("left", 0.3, q))
    low = dataclasses.replace(high.with_arm("left", 0.3, q), torso_height_m=0.1)
    done = execute(world, physics, high.with_arm("left", 0.3, q),
                   low.with_arm("left", 0.1, now.q_arm_rad["left"]))
    assert calls == ["torso", "arm", "arm", "torso"]
    assert [name for name, _ in done.motions] == ["torso", "left"]


def test_unfolding_near_the_table_leaves_the_base_where_it_is() -> None:
    # scene 11: the base stands near the table; the unfolded arms lowered with the torso
    # were pressed onto the table, which shoved the base 6 cm away
    _, bb, rng, world = _prepared(11)
    base = np.array(world.physics.base_pose())
    assert sd._unfold(world.physics, bb, rng, {}) is None
    assert np.abs(np.array(world.physics.base_pose()) - base).max() < 0.01
    assert world.physics.torso_m() > 0.25  # kept up: lowered, the arms press on the table


def _found_by(monkeypatch: pytest.MonkeyPatch, name: str) -> list[bool]:
    """Spy on ``stacking_dynamic``'s search ``name``: whether each call found something."""
    search = getattr(sd, name)
    found: list[bool] = []

    def spy(*a: Any, **k: Any) -> Any:
        out = search(*a, **k)
        found.append(out is not None)
        return out

    monkeypatch.setattr(sd, name, spy)
    return found


def test_a_grasp_without_a_straight_approach_to_its_plan_is_replanned(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # scene 1: from the kinematic plan's arm no straight line leads back to the pre-grasp
    # (a joint limit); another arm for the same grasp pose has one, and the grasp holds
    task, bb, rng, world = _prepared(1)
    replanned = _found_by(monkeypatch, "_regrasp")
    _grasp(task, bb, rng)
    assert replanned == [True]
    arm = bb["arm_in_use"]
    assert world.physics.held_object(arm) == bb["grasp_target"]


def test_a_carried_box_is_lifted_above_the_other_and_the_check_sees_it() -> None:
    # a 12 cm box carried 10 cm up swept the other off (scene 16); it goes up until its
    # bottom clears the other's top by CLEAR_M (scene 3), and a carried object is checked
    task, bb, rng, world = _prepared(3)
    arm = _grasp(task, bb, rng)
    carried = bb[f"held_object_{arm}"]
    other = next(n for n in bb["object_positions_world"] if n != carried)
    physics = world.physics
    lift = sd._lift_m(physics, bb, carried)
    assert physics.object_pose(carried)[2] + lift - 0.06 >= \
        physics.object_pose(other)[2] + 0.06 + sd.CLEAR_M - 1e-9
    assert lift > sd.LIFT_M
    state = read_state(bb)
    path = sd._lift_line(world, bb, rng, state, arm, lift, (other,))
    assert path and sd.tool_world(world, path[-1], arm).translation[2] == pytest.approx(
        sd.tool_world(world, state, arm).translation[2] + lift, abs=0.01)
    # moved over the other at grasp height, the carried box meets it; the arm need not
    towards = np.array(physics.object_pose(other)[:3]) - np.array(physics.object_pose(carried)[:3])
    shifted = sd.cartesian_path(world, state, arm, pin.SE3(
        sd.tool_world(world, state, arm).rotation,
        sd.tool_world(world, state, arm).translation + towards * [1.0, 1.0, 0.0]),
        sd.Scene(()), rng)
    assert shifted
    assert any(carried in arm_touches_table(physics, s, arm, objects=(other,), carried=carried)
               for s, _ in shifted)
    assert not any(carried in arm_touches_table(physics, s, arm, objects=(other,))
                   for s, _ in shifted)


def _upright_near(world: Any, name: str, at: np.ndarray, within_m: float = 0.01) -> bool:
    pose = np.array(world.physics.object_pose(name)[:3])
    return bool(world.physics.upright(name)) and float(np.linalg.norm(pose - at)) < within_m


def test_a_missed_grasp_opens_and_backs_out_along_its_approach_and_the_retry_holds(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # the fingers closed on nothing used to stay shut, and the retry pushed the box ahead
    # with their tips until it was out of reach (scenes 20, 65, 70, 92): a failed grasp now
    # opens them and backs the gripper out along the approach, and the retry grasps
    task, bb, rng, world = _prepared(1)
    physics = world.physics
    close = physics.close_gripper
    at_close: list[Any] = []

    def miss_once(arm: Any, *a: Any, **k: Any) -> Any:
        got = close(arm, *a, **k)
        if not at_close:  # the first grasp: report nothing held (the fingers did close)
            at_close.append((arm, physics.tool_transform(arm), physics.gripper_opening_rad(arm)))
            return None
        return got

    monkeypatch.setattr(physics, "close_gripper", miss_once)
    assert _call(task, bb, rng, "GraspParam", which=WHICH_GRASP) == "failure"
    assert bb["last_failure_reason"] == "missed"
    arm, grasp, closed = at_close[0]
    assert closed < 0.5  # they had closed on the box
    assert physics.gripper_opening_rad(arm) > 0.5  # open again
    assert bb[f"held_object_{arm}"] is None and physics.held_object(arm) is None
    moved = np.array(physics.tool_transform(arm).translation - grasp.translation)
    along = float(moved @ grasp.rotation[:, 0])
    assert along == pytest.approx(-sd.BACK_OUT_M, abs=0.015)  # backed out along the approach
    assert float(np.linalg.norm(moved - along * grasp.rotation[:, 0])) < 0.015  # on its line
    target = bb["grasp_target"]
    box = np.array(physics.object_pose(target)[:3])
    assert physics.upright(target)
    _grasp(task, bb, rng)
    assert physics.held_object(arm) == target
    assert float(np.linalg.norm(np.array(physics.object_pose(target)[:2]) - box[:2])) < 0.02


def test_a_grasp_whose_approach_passes_the_other_object_comes_from_another_bearing(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # scene 13: the planned bearing's approach passes the other object (no clear straight
    # line, nor from another arm); the open fingers came down on it and knocked it over.
    # The grasp turned about the target's axis has a clear line, and the other stays put
    task, bb, rng, world = _prepared(13)
    turned = _found_by(monkeypatch, "_turned")
    target = bb["object_positions_world"]
    other = {n: np.array(world.physics.object_pose(n)[:3]) for n in target}
    _grasp(task, bb, rng)
    assert turned == [True]
    arm = bb["arm_in_use"]
    held_name = bb["grasp_target"]
    assert world.physics.held_object(arm) == held_name
    (name,) = [n for n in target if n != held_name]
    assert _upright_near(world, name, other[name])
    planned = grasp_pose_world("side", read_state(bb).base_pose_world,
                               world.physics.object_pose(held_name)[:3])
    yaw = float(pin.rpy.matrixToRpy(world.physics.tool_transform(arm).rotation)[2])
    bearing = float(pin.rpy.matrixToRpy(planned.rotation)[2])
    assert abs((yaw - bearing + np.pi) % (2 * np.pi) - np.pi) > 0.2  # another bearing


def test_unfolding_beside_the_table_goes_round_it_and_the_objects() -> None:
    # scene 11: unfolded straight, the left hand knocked the bottle over and the right
    # elbow swept into the table's edge, where the arm stayed jammed
    _, bb, rng, world = _prepared(11)
    physics = world.physics
    names = tuple(bb["object_positions_world"])
    start = {n: np.array(physics.object_pose(n)[:3]) for n in names}
    state = read_state(bb)
    high = dataclasses.replace(state, torso_height_m=0.3)
    ready = unfolded(state, ARMS)
    goal = transits.with_arm(high, "right", ready.q_arm_rad["right"])
    assert sd.line_touches_table(physics, high, goal, "right", objects=names)
    route = transits.unfold_route(physics, "right", high, goal, names)
    assert len(route) > 1 and route[-1] is goal
    assert sd._unfold(physics, bb, rng, {}) is None
    assert all(_upright_near(world, n, start[n]) for n in names)
    assert not physics.robot_contacts("table")
    for arm in ARMS:
        assert np.abs(np.array(physics.arm_q(arm)) - ready.q_arm_rad[arm]).max() < 0.05


def test_a_stack_goal_out_of_the_arms_limits_is_reached_with_the_gripper_turned() -> None:
    # scene 81: the side grasp's pose along the bearing from the base is reachable only
    # outside the joint limits; turned about the vertical it is reached, and the box is
    # carried there in the fingers
    task, bb, rng, world = _prepared(81)
    arm = _grasp(task, bb, rng)
    carried = bb[f"held_object_{arm}"]
    assert skills_kinematic.move_gripper_to_stack.impl(world.kinematic, bb, rng, **STACK) \
        == "failure"
    assert bb["last_failure_reason"] == "joint_limits"
    assert _call(task, bb, rng, "MoveGripperToStack", **STACK) == "success", \
        bb.get("last_failure_detail")
    assert world.physics.held_object(arm) == carried
    assert _call(task, bb, rng, "OpenGripper") == "success"
    assert stacked(bb)


def test_a_grasp_planned_from_above_is_retried_from_the_side(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # scene 42: the kinematic plan's IK missed the side grasp and took the box from above;
    # held so, the other object (1 m from the base) was beyond reach. A side grasp exists
    # and replaces it, and the box is then carried onto the other
    task, bb, rng, world = _prepared(42)
    kinds: list[str] = []
    plan = skills_kinematic.grasp_param

    def spy(*a: Any, **k: Any) -> Any:
        out = plan.impl(*a, **k)
        kinds.append(a[1].get(GRASP_KEY))
        return out

    monkeypatch.setattr(skills_kinematic, "grasp_param", KinematicSkill(plan.spec, spy))
    _grasp(task, bb, rng)
    assert kinds == ["top"] and bb[GRASP_KEY] == "side"
    arm = bb["arm_in_use"]
    assert world.physics.held_object(arm) == bb["grasp_target"]
    assert _call(task, bb, rng, "MoveGripperToStack", **STACK) == "success", \
        bb.get("last_failure_detail")
