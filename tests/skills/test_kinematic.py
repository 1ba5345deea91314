"""Kinematic skills on the PR2: twins' signatures, kinematic failures, the reference FSA."""

from __future__ import annotations

import math

import numpy as np
import pytest

from examples.pour_water import fitness, setup
from skillcompose import Blackboard, Registry, compile_fsa, load_fsa
from skillcompose.robots import IKSolver, IKTarget, load_pr2
from skillcompose.robots.collision import Box
from skillcompose.robots.reachability import ReachabilityOracle
from skillcompose.skills import kinematic as kn
from skillcompose.skills import kinematic_world as kw
from skillcompose.skills import pour_water as pw

pytestmark = pytest.mark.kinematics

REFERENCE = "examples/pour_water_reference.fsa.yaml"


def pour_world() -> Blackboard:
    bb = setup(np.random.default_rng(0), p_fail=0.2)
    kn.recognise_object(bb, 0)
    return bb


def reason(bb: Blackboard) -> str | None:
    return bb.get(kw.REASON_KEY)


# -- signatures ------------------------------------------------------------------------------
@pytest.mark.parametrize("sim", pw.SKILLS, ids=lambda s: s.name)
def test_twin_has_the_abstract_skills_signature(sim: object) -> None:
    twin = {s.name: s for s in kn.SKILLS}[sim.name]  # type: ignore[attr-defined]
    assert twin.backend == "kinematic"
    assert twin.spec.outcomes == sim.spec.outcomes  # type: ignore[attr-defined]
    assert twin.spec.params == sim.spec.params  # type: ignore[attr-defined]


def test_register_beside_the_abstract_skills() -> None:
    registry = Registry()
    pw.register(registry)
    added = registry.load_module("skillcompose.skills.kinematic")
    assert {s.name for s in added} == {s.name for s in kn.SKILLS}
    for s in pw.SKILLS:
        assert sorted(registry.backends(s.name)) == ["kinematic", "sim"]
    bound = registry.resolve("MoveBasePose", "kinematic")
    assert isinstance(bound, kw.KinematicSkill) and bound.impl is kn.move_base_pose.impl
    push = registry.resolve("Push", "kinematic")
    assert isinstance(push, kw.KinematicSkill) and push.world is bound.world  # one per register
    other = Registry()
    assert kn.register(other) is not bound.world  # another registry, another world
    push = other.resolve("Push")
    assert isinstance(push, kw.KinematicSkill) and push.world is not bound.world
    assert kn.register(Registry(), world=bound.world) is bound.world  # or the one given


# -- the pour-water twins ------------------------------------------------------------------
def test_pour_sequence_writes_kinematic_keys() -> None:
    bb = pour_world()
    assert kn.move_to_object(bb, 1) == "success"
    assert bb["arm_in_use"] == "right"  # the jug is on the right
    tool = bb["tool_pose_right_world"]
    assert np.allclose(tool[:3], (0.54, -0.20, 0.95), atol=1e-5)
    assert np.allclose(bb["gripper_position_world"], tool[:3])
    assert len(bb["q_right_arm_rad"]) == 7
    assert kn.grasp_object(bb, 2) == "success"
    assert bb["holding_jug"] and bb["held_object_right"] == "jug"
    assert kn.move_gripper_to_param(bb, 3, x=0.58, y=0.2, z=0.95) == "success"
    assert np.allclose(bb["jug_position_world"], (0.58, 0.2, 0.95), atol=1e-5)
    assert bb["water"] == "jug"
    assert kn.rotate_gripper_to_param(bb, 4, rho=0.0, phi=1.6, theta=0.0) == "success"
    assert bb["water"] == "glass"
    assert kn.check_success(bb, 5) == "success"
    # the stored joint angles put the tool where the blackboard says
    kin = kw.KinematicWorld()
    tool_robot = kin.transform_tool_to_robot("right", bb["torso_height_m"], bb["q_right_arm_rad"])
    assert np.allclose(tool_robot.translation, bb["gripper_position_world"], atol=1e-9)
    assert kin.chains["right"].within_limits(np.array([bb["torso_height_m"],
                                                       *bb["q_right_arm_rad"]]))


def test_move_to_object_fails_for_kinematic_reasons() -> None:
    bb = setup(np.random.default_rng(0))
    assert kn.move_to_object(bb, 0) == "failure" and reason(bb) == "not_recognised"
    far = pour_world()
    far["jug_location_world"] = (2.0, 0.0, 0.95)
    assert kn.move_to_object(far, 0) == "failure" and reason(far) == "unreachable"
    assert "gripper_position_world" in far and far["gripper_position_world"] == (0.30, -0.40, 1.10)
    sunk = pour_world()
    sunk["jug_location_world"] = (0.60, -0.20, 0.70)  # the approach pose is inside the table
    assert kn.move_to_object(sunk, 0) == "failure" and reason(sunk) == "collision"
    assert "q_right_arm_rad" not in sunk  # nothing moved


def test_grasp_needs_the_gripper_near_the_jug() -> None:
    bb = pour_world()
    assert kn.grasp_object(bb, 0) == "failure" and reason(bb) == "too_far"
    assert not bb["holding_jug"]


def test_move_gripper_fails_on_collision_and_reach() -> None:
    bb = pour_world()
    assert kn.move_to_object(bb, 0) == "success"
    assert kn.grasp_object(bb, 0) == "success"
    before = bb["q_right_arm_rad"]
    assert kn.move_gripper_to_param(bb, 0, x=0.8, y=0.0, z=0.75) == "failure"
    assert reason(bb) == "collision"  # the gripper would be in the table top
    assert kn.move_gripper_to_param(bb, 0, x=0.2, y=0.6, z=1.5) == "failure"
    assert reason(bb) in ("unreachable", "joint_limits")  # far to the other side, high
    assert bb["q_right_arm_rad"] == before


def test_impossible_rotation_keeps_the_gripper_and_says_why() -> None:
    bb = pour_world()
    assert kn.move_to_object(bb, 0) == "success"
    assert kn.grasp_object(bb, 0) == "success"
    bb["table_world"] = None
    assert kn.move_gripper_to_param(bb, 0, x=0.92, y=-0.2, z=1.0) == "success"
    rotation = bb["gripper_rotation"]
    # the arm stretched ahead cannot turn the tool back: its wrist would be out of reach
    assert kn.rotate_gripper_to_param(bb, 0, rho=0.0, phi=0.0, theta=math.pi) == "success"
    assert reason(bb) in ("unreachable", "joint_limits", "collision")
    assert bb["gripper_rotation"] == rotation


def test_joint_limits_reason_is_checked_against_unlimited_ik() -> None:
    pose = {"x": 0.48, "y": -0.4, "z": 1.5, "roll": 2.89, "pitch": 1.11, "yaw": 0.9}
    bb = Blackboard({"table_world": None})
    assert kn.move_gripper_to_pose(bb, 0, arm="right", **pose) == "failure"
    assert reason(bb) == "joint_limits"
    import pinocchio as pin

    target = IKTarget(np.array([pose["x"], pose["y"], pose["z"]]),
                      pin.rpy.rpyToMatrix(pose["roll"], pose["pitch"], pose["yaw"]))
    kin = kw.KinematicWorld()
    limited = IKSolver(chain=kin.chains["right"], arm="right", seed=7)
    assert not limited.solve(target, time_budget_s=10.0, max_restarts=60, diagnose=False).success
    unlimited = IKSolver(chain=kin.free_solvers["right"].chain, arm="right", seed=7)
    assert unlimited.solve(target, time_budget_s=10.0, max_restarts=60, diagnose=False).success


# -- new skills ------------------------------------------------------------------------------
def test_move_gripper_to_pose_and_reachable() -> None:
    bb = Blackboard({"glass_position_world": (0.6, 0.2, 0.87)})
    assert kn.reachable(bb, 0, arm="left", object="glass") == "yes"
    assert "q_left_arm_rad" not in bb  # a condition moves nothing
    assert kn.reachable(bb, 0, arm="left", object="jug") == "no" and reason(bb) == "no_object"
    bb["glass_position_world"] = (1.6, 0.2, 0.87)
    assert kn.reachable(bb, 0, arm="left", object="glass") == "no"
    assert reason(bb) == "unreachable"
    assert kn.move_gripper_to_pose(bb, 0, arm="left", x=0.6, y=0.3, z=1.0) == "success"
    assert np.allclose(bb["tool_pose_left_world"], (0.6, 0.3, 1.0, 0, 0, 0), atol=1e-5)
    assert bb["arm_in_use"] == "left"


def test_reachable_agrees_with_ik_ground_truth() -> None:
    """Reachable (no table) against the reachability oracle's IK on seeded points."""
    oracle = ReachabilityOracle(load_pr2(), seed=3)
    rng = np.random.default_rng(11)
    agree = n = 0
    for i in range(40):
        position = (rng.uniform(0.2, 1.0), rng.uniform(-0.8, 0.8), rng.uniform(0.5, 1.4))
        torso = float(rng.uniform(0.0, 0.31))
        bb = Blackboard({"object_position_world": position, "torso_height_m": torso,
                         "table_world": None})
        for k, arm in enumerate(("left", "right")):
            said = kn.reachable(bb, 100 * i + k, arm=arm, object="object") == "yes"
            truth = oracle.arms_reaching(np.array(position), torso, i)[k]
            agree += said == truth
            n += 1
    assert agree / n >= 0.9, f"Reachable agreed with IK on {agree}/{n}"


def test_move_base_collides_with_the_table() -> None:
    table = Box.table((1.4, 0.3), (0.6, 0.8), 0.75)
    bb = Blackboard({"object_position_world": (1.2, 0.3, 0.83), "table_world": table})
    assert kn.move_base_pose(bb, 0, x=1.2, y=0.4, yaw=0.0, torso=0.2, arm="left") == "failure"
    assert reason(bb) == "collision" and "base_pose_world" not in bb
    assert kn.move_base_pose(bb, 0, x=0.5, y=0.4, yaw=0.0, torso=0.2, arm="left") == "success"
    assert bb["base_pose_world"] == (0.5, 0.4, 0.0) and bb["torso_height_m"] == 0.2
    assert bb["arm_in_use"] == "left"


def test_push_after_move_base() -> None:
    table = Box.table((1.4, 0.3), (0.6, 0.8), 0.75)
    bb = Blackboard({"object_position_world": (1.2, 0.3, 0.83), "table_world": table})
    assert kn.move_base_pose(bb, 0, x=0.5, y=0.4, yaw=0.0, torso=0.2, arm="left") == "success"
    assert kn.push(bb, 0) == "success"
    moved = np.subtract(bb["object_position_world"], (1.2, 0.3, 0.83))
    assert math.isclose(float(np.linalg.norm(moved)), kn.PUSH_DISTANCE_M, rel_tol=1e-9)
    far = Blackboard({"object_position_world": (1.2, 0.3, 0.83), "table_world": table})
    assert kn.move_base_pose(far, 0, x=-0.5, y=0.4, yaw=0.0, torso=0.2, arm="left") == "success"
    assert kn.push(far, 0) == "failure" and reason(far) == "unreachable"
    assert far["object_position_world"] == (1.2, 0.3, 0.83)


def test_place_base_then_reachable() -> None:
    table = Box.table((1.4, 0.3), (0.6, 0.8), 0.75)
    bb = Blackboard({"object_position_world": (1.2, 0.3, 0.83), "table_world": table})
    assert kn.reachable(bb, 0, arm="right", object="object") == "no"
    assert kn.place_base(bb, 0, arm="right", object="object") == "success"
    assert kw.base_collides(bb["base_pose_world"], kw.scene_world(bb)) is None
    assert kn.reachable(bb, 1, arm="right", object="object") == "yes"
    inside = Blackboard({"object_position_world": (1.4, 0.3, 0.83),
                         "table_world": Box.table((1.4, 0.3), (2.4, 2.4), 0.75)})
    assert kn.place_base(inside, 0, arm="right", object="object") == "failure"
    assert reason(inside) in ("unreachable", "collision")


def test_stacking_skills() -> None:
    positions = {"a": (0.6, -0.15, 0.81), "b": (0.6, 0.15, 0.81)}
    bb = Blackboard({"object_positions_world": positions})
    assert kn.grasp_param(bb, 0, which=1.0) == "failure" and reason(bb) == "not_recognised"
    bb["object_locations_world"] = dict(positions)  # what RecogniseObject writes
    assert kn.grasp_param(bb, 0, which=1.0) == "success"
    assert bb["held_object_right"] == "a"
    assert kn.grasp_param(bb, 0, which=0.0) == "failure" and reason(bb) == "already_holding"
    # a's bottom would be 4 cm inside b
    assert kn.move_gripper_to_stack(bb, 0, which=0.0, dx=0.0, dy=0.0, dz=0.08) == "failure"
    assert reason(bb) == "collision"
    assert kn.move_gripper_to_stack(bb, 0, which=0.0, dx=0.0, dy=0.0, dz=0.15) == "success"
    assert np.allclose(bb["object_positions_world"]["a"], (0.6, 0.15, 0.96), atol=1e-5)
    assert kn.open_gripper(bb, 0) == "success"
    assert bb["held_object_right"] is None
    assert np.allclose(bb["object_positions_world"]["a"], (0.6, 0.15, 0.93), atol=1e-5)  # on b
    bb["object_positions_world"] = {**bb["object_positions_world"], "b": (1.6, 0.15, 0.81)}
    assert kn.move_gripper_to_stack(bb, 0, which=0.0, dx=0.0, dy=0.0, dz=0.3) == "failure"
    assert reason(bb) == "unreachable"


# -- the reference FSA on both backends ------------------------------------------------------
def test_reference_fsa_runs_unchanged_on_both_backends() -> None:
    registry = Registry()
    pw.register(registry)
    kn.register(registry)
    fsa = load_fsa(REFERENCE)
    sim = compile_fsa(fsa, registry, "sim")
    kinematic = compile_fsa(fsa, registry, "kinematic")
    bb = setup(np.random.default_rng(0), p_fail=0.0)
    assert sim.run(bb, 0).outcome == "success" and fitness("success", bb, 6) == 0.0
    wins = 0
    seeds = 10
    for seed in range(seeds):
        bb = setup(np.random.default_rng(seed), p_fail=0.2)
        result = kinematic.run(bb, seed)
        assert result.error is None
        assert "q_right_arm_rad" in bb  # the kinematic skills ran, not the abstract ones
        wins += fitness(result.outcome, bb, result.steps) == 0.0
    assert wins == seeds, f"reference FSA solved {wins}/{seeds} kinematic runs"


def test_same_seed_same_run() -> None:
    registry = Registry()
    kn.register(registry)
    compiled = compile_fsa(load_fsa(REFERENCE), registry, "kinematic")
    runs = []
    for _ in range(2):
        bb = setup(np.random.default_rng(0))
        compiled.run(bb, 5)
        runs.append(bb.to_dict())
    assert runs[0] == runs[1]
