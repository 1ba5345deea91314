"""The MuJoCo world of the PR2 (skillcompose.robots.physics): model, control, grasp, push,
pour, determinism. Every number asserted is measured in the simulation."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import pinocchio as pin
import pytest

pytest.importorskip("mujoco")

from skillcompose.robots.errors import InvalidConfiguration
from skillcompose.robots.ik import IKSolver, IKTarget
from skillcompose.robots.model import (
    ARM_JOINTS,
    ARMS,
    TOOL_FRAMES,
    TUCKED_ARM_RAD,
    Arm,
    RobotModel,
    RobotPose,
)
from skillcompose.robots.physics import PhysicsWorld, PoseRecorder
from skillcompose.robots.physics_model import (
    BASE_JOINTS,
    ROBOT_BIT,
    WORLD_BIT,
    ObjectSpec,
    SceneSpec,
    compile_scene,
)

pytestmark = [pytest.mark.physics, pytest.mark.kinematics]

TORSO_M = 0.2
BOX = ObjectSpec("box", "box", (0.03, 0.03, 0.06), 0.3)
BOX_SCENE = SceneSpec(objects=(BOX,))
BOX_CENTRE = np.array([0.62, -0.2, 0.81])  # on the table (top at 0.75 m)
SIDE_RISE_M = 0.03  # a side grasp holds the box 3 cm above its centre
JUG = ObjectSpec("jug", "cup", (0.03, 0.03, 0.08), 0.15)
GLASS = ObjectSpec("glass", "cup", (0.045, 0.045, 0.06), 0.2, rgba=(0.7, 0.9, 1.0, 0.5))
N_PARTICLES = 40
POUR_SCENE = SceneSpec(objects=(JUG, GLASS), n_particles=N_PARTICLES)


Solve = Callable[..., np.ndarray]


@pytest.fixture(scope="module")
def solve(pr2: RobotModel) -> Solve:
    """IK of the right arm (torso held at TORSO_M) for a horizontal tool pose in world."""
    solver = IKSolver(chain=pr2.chain("right_arm_torso"), arm="right")

    def run(position: Sequence[float], initial: np.ndarray | None = None,
            roll: float = 0.0) -> np.ndarray:
        start = initial if initial is not None else np.array([TORSO_M, *TUCKED_ARM_RAD["right"]])
        result = solver.solve(
            IKTarget(np.array(position, float), np.asarray(pin.rpy.rpyToMatrix(roll, 0.0, 0.0))),
            initial=start, fixed={"torso_lift_joint": TORSO_M}, max_restarts=20,
            time_budget_s=5.0, rng=np.random.default_rng(1))
        assert result.success and result.coordinates is not None, result
        return np.asarray(result.coordinates)

    return run


def test_model_has_the_pr2_joints_actuators_and_couplings() -> None:
    physics = compile_scene(BOX_SCENE)
    model = physics.model
    names = {model.joint(j).name for j in range(model.njnt)}
    for arm in ("left", "right"):
        assert set(ARM_JOINTS[arm]) <= names
    assert {"torso_lift_joint", *BASE_JOINTS} <= names
    assert model.njnt == 30 + 3 + 1  # the URDF's 30, the planar root, the box's free joint
    actuated = {model.actuator(a).name for a in range(model.nu)}
    assert actuated == {*BASE_JOINTS, "torso_lift_joint", *ARM_JOINTS["left"],
                        *ARM_JOINTS["right"], "l_gripper_l_finger_joint",
                        "r_gripper_l_finger_joint"}
    assert model.neq == 10  # five mimic couplings per gripper
    # no robot geom collides with another robot geom; each can touch the world
    for geom in physics.robot_geoms:
        assert model.geom_contype[geom] == ROBOT_BIT
        assert model.geom_conaffinity[geom] == WORLD_BIT
    assert compile_scene(BOX_SCENE) is physics  # cached per scene


def test_tool_frames_agree_with_pinocchio(pr2: RobotModel) -> None:
    world = PhysicsWorld(SceneSpec(table=None))
    rng = np.random.default_rng(7)
    full = pr2.full_model
    data = full.createData()
    for _ in range(5):
        base = (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), float(rng.uniform(-3, 3)))
        torso = float(rng.uniform(0.0, 0.31))
        q: dict[Arm, tuple[float, ...]] = {
            arm: tuple(pr2.chain(f"{arm}_arm").sample_coordinates(rng)) for arm in ARMS}
        world.reset(base_pose_world=base, torso_m=torso, q_arm_rad=q)
        pin.framesForwardKinematics(full, data, pr2.full_q(RobotPose(base, torso, q)))
        for arm in ARMS:
            expected = data.oMf[full.getFrameId(TOOL_FRAMES[arm])]
            simulated = world.tool_transform(arm)
            assert np.linalg.norm(simulated.translation - expected.translation) < 1e-6
            assert np.linalg.norm(pin.log3(expected.rotation.T @ simulated.rotation)) < 1e-6


def test_arm_tracks_an_ik_target_under_control(solve: Solve) -> None:
    world = PhysicsWorld(SceneSpec(table=None))
    target = np.array([0.6, -0.25, 0.95])
    q = solve(target)
    world.reset(torso_m=TORSO_M)
    motion = world.track_arm("right", q[1:], 2.0)
    assert motion.reached, motion
    tool = world.tool_transform("right")
    assert np.linalg.norm(tool.translation - target) < 0.002
    assert np.linalg.norm(pin.log3(tool.rotation)) < 0.01  # target rotation: identity
    assert np.max(np.abs(np.array(world.base_pose()))) < 1e-3  # the base held still


def test_arm_driven_into_the_table_stops_on_it(solve: Solve) -> None:
    world = PhysicsWorld(BOX_SCENE)
    above = solve([0.6, -0.25, 0.85])
    inside = solve([0.6, -0.25, 0.68], above)  # 7 cm under the table top
    world.reset(torso_m=TORSO_M, q_arm_rad={"right": above[1:]})
    motion = world.track_arm("right", inside[1:], 1.5)
    assert not motion.reached
    assert any(other == "table" for _, other in motion.contacts), motion.contacts
    assert world.robot_contacts("table")
    assert world.tool_pose("right")[2] > 0.70


def _grasped_box(solve: Solve) -> tuple[PhysicsWorld, np.ndarray]:
    grasp_at = BOX_CENTRE + np.array([0.0, 0.0, SIDE_RISE_M])
    before = solve(grasp_at + np.array([-0.12, 0.0, 0.0]))
    grasp = solve(grasp_at, before)
    world = PhysicsWorld(BOX_SCENE)
    world.reset(torso_m=TORSO_M, q_arm_rad={"right": before[1:]},
                object_poses={"box": tuple(BOX_CENTRE)})
    assert world.track_arm("right", grasp[1:], 1.5).reached
    assert world.held_object("right") is None  # open fingers around it touch nothing
    return world, grasp


def test_grasped_box_stays_in_the_gripper_when_lifted_and_falls_when_released(
        solve: Solve) -> None:
    world, grasp = _grasped_box(solve)
    assert world.close_gripper("right") == "box"
    assert 0.2 < world.gripper_opening_rad("right") < 0.45  # stopped by the 6 cm box
    lift = solve(BOX_CENTRE + np.array([0.0, 0.0, SIDE_RISE_M + 0.15]), grasp)
    box_z0, tool_z0 = world.object_pose("box")[2], world.tool_pose("right")[2]
    assert world.track_arm("right", lift[1:], 1.5).reached
    box_z1, tool_z1 = world.object_pose("box")[2], world.tool_pose("right")[2]
    assert tool_z1 - tool_z0 > 0.14
    assert abs((box_z1 - box_z0) - (tool_z1 - tool_z0)) < 0.002  # slipped < 2 mm lifting
    world.step(2.0)
    assert abs(world.object_pose("box")[2] - box_z1) < 0.001  # < 1 mm while held 2 s
    assert world.held_object("right") == "box"
    assert world.upright("box")
    assert world.open_gripper("right") is None
    world.step(1.0)
    x, y, z = world.object_pose("box")[:3]
    assert abs(z - BOX_CENTRE[2]) < 0.003  # back on the table
    assert np.hypot(x - BOX_CENTRE[0], y - BOX_CENTRE[1]) < 0.02
    assert world.upright("box")


def test_closing_on_nothing_holds_nothing() -> None:
    world = PhysicsWorld(BOX_SCENE)
    world.reset(torso_m=TORSO_M, object_poses={"box": tuple(BOX_CENTRE)})
    assert world.close_gripper("right") is None
    assert world.gripper_opening_rad("right") < 0.02


@pytest.mark.parametrize(("friction", "topples"), [(0.3, False), (1.0, True)])
def test_pushing_through_a_box_moves_it(solve: Solve, friction: float, topples: bool) -> None:
    # pushed at its centre, 6 cm up: a 6 cm wide box slides while friction < 0.5, else tips
    world = PhysicsWorld(SceneSpec(objects=(ObjectSpec("box", "box", BOX.size_m, 0.3,
                                                       friction=friction),)))
    start = solve(BOX_CENTRE + np.array([-0.09, 0.0, 0.0]))
    through = solve(BOX_CENTRE + np.array([0.02, 0.0, 0.0]), start)
    world.reset(torso_m=TORSO_M, q_arm_rad={"right": start[1:]},
                object_poses={"box": tuple(BOX_CENTRE)}, gripper_open=False)
    world.track_arm("right", through[1:], 2.0)
    assert world.robot_contacts("box")
    world.step(1.0)
    x, y, z = world.object_pose("box")[:3]
    assert x - BOX_CENTRE[0] > 0.03  # pushed along the tool's way
    assert abs(y - BOX_CENTRE[1]) < 0.02
    assert world.upright("box") is not topples
    if not topples:
        assert abs(z - BOX_CENTRE[2]) < 0.003


@pytest.mark.slow
def test_water_poured_from_a_tilted_jug_lands_in_the_glass_and_stays(
        solve: Solve) -> None:
    jug_at, glass_at = np.array([0.60, -0.05, 0.83]), np.array([0.60, -0.30, 0.81])
    before = solve(jug_at + np.array([-0.12, 0.0, SIDE_RISE_M]))
    grasp = solve(jug_at + np.array([0.0, 0.0, SIDE_RISE_M]), before)
    lift = solve(jug_at + np.array([0.0, 0.0, 0.19]), grasp)
    over = solve([0.60, glass_at[1] + 0.07, 0.96], lift)  # the mouth will be over the glass
    world = PhysicsWorld(POUR_SCENE)
    world.reset(torso_m=TORSO_M, q_arm_rad={"right": before[1:]},
                object_poses={"jug": tuple(jug_at), "glass": tuple(glass_at)},
                particles_in="jug")
    world.step(0.5)
    assert world.particles_in("jug") == N_PARTICLES
    assert world.track_arm("right", grasp[1:], 1.5).reached
    assert world.close_gripper("right") == "jug"
    assert world.track_arm("right", lift[1:], 1.5).reached
    assert world.track_arm("right", over[1:], 1.5).reached
    assert world.particles_in("jug") == N_PARTICLES  # carried upright: nothing spilled
    tilted = over[1:].copy()
    tilted[6] += 2.2  # wrist roll: the jug tipped 126 degrees towards the glass
    world.track_arm("right", tilted, 3.0)
    world.step(1.0)
    assert world.particles_in("jug") == 0
    in_glass = world.particles_in("glass")
    assert in_glass >= 0.8 * N_PARTICLES
    world.step(2.0)
    assert world.particles_in("glass") == in_glass  # they stay
    assert world.upright("glass")


def _grasp_and_lift_record(solve: Solve) -> tuple[np.ndarray, PoseRecorder]:
    recorder = PoseRecorder(every_s=0.1)
    grasp_at = BOX_CENTRE + np.array([0.0, 0.0, SIDE_RISE_M])
    before = solve(grasp_at + np.array([-0.12, 0.0, 0.0]))
    grasp = solve(grasp_at, before)
    lift = solve(grasp_at + np.array([0.0, 0.0, 0.1]), grasp)
    world = PhysicsWorld(BOX_SCENE, recorder=recorder)
    world.reset(torso_m=TORSO_M, q_arm_rad={"right": before[1:]},
                object_poses={"box": tuple(BOX_CENTRE)})
    world.track_arm("right", grasp[1:], 1.0)
    world.close_gripper("right")
    world.track_arm("right", lift[1:], 1.0)
    return np.array(world.data.qpos), recorder


def test_same_inputs_give_bit_identical_runs(solve: Solve) -> None:
    first_q, first = _grasp_and_lift_record(solve)
    second_q, second = _grasp_and_lift_record(solve)
    assert np.array_equal(first_q, second_q)
    assert first.times_s == second.times_s
    assert len(first.positions) > 30
    assert all(np.array_equal(a, b) for a, b in zip(first.positions, second.positions,
                                                    strict=True))
    assert first.bodies[0] == "box"
    box_z = [float(p[0, 2]) for p in first.positions]
    assert max(box_z) - box_z[0] > 0.08  # the recording shows the lift


def test_bad_inputs_are_refused() -> None:
    with pytest.raises(InvalidConfiguration, match="needs 3 sizes"):
        ObjectSpec("b", "box", (0.1, 0.1), 1.0)
    with pytest.raises(InvalidConfiguration, match="unique names"):
        SceneSpec(objects=(BOX, BOX))
    world = PhysicsWorld(BOX_SCENE)
    with pytest.raises(InvalidConfiguration, match="no objects"):
        world.reset(object_poses={"jug": (0.6, 0.0, 0.8)})
    with pytest.raises(InvalidConfiguration, match="torso"):
        world.reset(torso_m=0.5)
    with pytest.raises(InvalidConfiguration, match="7 finite"):
        world.track_arm("left", (0.0,) * 6, 1.0)


def test_the_recording_holds_the_robot_as_it_moved(solve: Solve) -> None:
    _, recorder = _grasp_and_lift_record(solve)
    assert len(recorder.robot) == len(recorder.times_s)
    assert recorder.objects == ("box",)
    start, last = recorder.robot[0], recorder.robot[-1]
    assert start.torso_height_m == pytest.approx(TORSO_M, abs=1e-6)
    moved = np.abs(np.subtract(last.arm_rad["right"], start.arm_rad["right"]))
    assert moved.max() > 0.05  # the arm went from the pre-grasp to the lift
    assert last.arm_rad["left"] == pytest.approx(start.arm_rad["left"], abs=1e-3)
