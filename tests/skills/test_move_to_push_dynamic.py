"""Moving to push on the dynamic backend (the PR2 in MuJoCo): a push moves the object through
contact, physics' failures are outcomes, the shipped FSA pushes, and runs repeat exactly."""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin
import pytest

pytest.importorskip("mujoco")

from skillcompose import Blackboard, Registry, compile_fsa, load_fsa
from skillcompose.executor import trial_rngs
from skillcompose.robots.model import Arm
from skillcompose.robots.physics_model import ObjectSpec, SceneSpec
from skillcompose.skills import move_to_push_dynamic as mtp
from skillcompose.skills.dynamic_world import (
    DYNAMIC_FAILURE_REASONS,
    DynamicWorld,
    arm_touches_table,
    cartesian_path,
    in_dynamic_world,
    tool_world,
    world_of,
)
from skillcompose.skills.kinematic_world import (
    DEFAULT_TABLE_WORLD,
    FAILURE_REASONS,
    Reach,
    RobotState,
    reach,
    read_state,
    scene_world,
)
from skillcompose.task import load_task

pytestmark = [pytest.mark.physics, pytest.mark.kinematics]

SHIPPED = "examples/move_to_reach.fsa.yaml"
HALF = (0.03, 0.03, 0.10)


def _facing_bb() -> Blackboard:
    """The robot at the origin facing the default table, the object on it."""
    return Blackboard({
        "table_world": DEFAULT_TABLE_WORLD, "object_position_world": (0.60, -0.20, 0.85),
        "object_half_extents_m": HALF, "base_pose_world": (0.0, 0.0, 0.0),
        "torso_height_m": 0.2, "arm_in_use": "right", "room_half_m": 2.5,
    })


def _push(world: DynamicWorld, bb: Blackboard) -> str:
    (bound,) = in_dynamic_world((mtp.push,), world)
    return str(bound.bind()(bb, np.random.default_rng(3)))


def _first_world(scene: SceneSpec | None = None) -> tuple[Blackboard, object, object]:
    """The shipped FSA on the first judged placement of the reproduction (seed 20 000),
    optionally with another scene: (blackboard after the run, outcome, object at start)."""
    task = load_task("examples.move_to_push", backend="dynamic", judge=True)
    world = world_of(task.registry)
    assert world is not None
    compiled = compile_fsa(load_fsa(SHIPPED), task.registry, "dynamic")
    rng = next(iter(trial_rngs(20_000, 1)))
    bb = task.setup(rng)
    if scene is not None:
        world.start(bb, scene, object_poses={"object": tuple(bb["object_position_world"])})
    assert world.physics is not None
    start = np.array(world.physics.object_pose("object")[:3])
    result = compiled.run(bb, rng)
    return bb, result.outcome, start


def test_a_push_moves_the_object_5_cm_and_it_stands() -> None:
    bb, outcome, start = _first_world()
    assert outcome == "success" and bb["pushed"] is True, bb.get("last_failure_detail")
    moved = np.array(bb["object_position_world"]) - np.asarray(start)
    assert float(np.linalg.norm(moved[:2])) >= mtp.PUSHED_M
    assert abs(float(moved[2])) < 0.01  # it slid on the table, upright


def test_a_grippy_object_topples_and_that_is_an_outcome() -> None:
    bb = load_task("examples.move_to_push", judge=True).setup(next(iter(trial_rngs(20_000, 1))))
    grippy = SceneSpec(table=bb["table_world"], objects=(
        ObjectSpec("object", "box", HALF, 0.3, 3.0),))  # friction 3: it tips, not slides
    after, outcome, _ = _first_world(grippy)
    assert outcome == "failure"
    assert after["last_failure_reason"] in (*DYNAMIC_FAILURE_REASONS, *FAILURE_REASONS)
    assert "pushed" not in after


def test_a_skill_without_an_episode_refuses_with_the_fix() -> None:
    from skillcompose.errors import BlackboardKeyError

    with pytest.raises(BlackboardKeyError, match="backend=dynamic"):
        _push(DynamicWorld(), _facing_bb())


def test_the_base_drives_round_the_table() -> None:
    bb = Blackboard({"table_world": DEFAULT_TABLE_WORLD})
    straight = mtp.base_route(bb, (0.0, 0.0, 0.0), (0.0, 1.5, 0.0))
    assert straight == [(0.0, 1.5, 0.0)]
    around = mtp.base_route(bb, (0.0, 0.0, 0.0), (1.6, 0.0, np.pi))
    assert len(around) >= 2 and around[-1] == (1.6, 0.0, np.pi)


def _outcomes(n: int, seed: int = 20_000, trace: bool = False) -> list[tuple[object, ...]]:
    task = load_task("examples.move_to_push", backend="dynamic", judge=True)
    compiled = compile_fsa(load_fsa(SHIPPED), task.registry, "dynamic")
    out: list[tuple[object, ...]] = []
    for rng in trial_rngs(seed, n):
        bb = task.setup(rng)
        result = compiled.run(bb, rng, trace=trace)
        out.append((task.score(result, bb), result.outcome, bb.get("last_failure_reason"),
                    bb["object_position_world"], bb["base_pose_world"],
                    [(s.state, s.outcome) for s in result.trace or ()]))
    return out


@pytest.mark.slow
def test_the_shipped_fsa_pushes_on_most_judged_placements() -> None:
    scores = [o[0] == 1.0 for o in _outcomes(6)]
    assert sum(scores) >= 5, scores  # measured: 6 of these 6 (94 of the first 100)


def test_same_seed_same_episode() -> None:
    assert _outcomes(1, seed=20_003, trace=True) == _outcomes(1, seed=20_003, trace=True)


def test_the_task_takes_backend_dynamic() -> None:
    task = load_task("examples.move_to_push", backend="dynamic", world="paper")
    assert task.backend == "dynamic"
    assert isinstance(task.registry, Registry)


# -- the motion's mechanisms -------------------------------------------------------------------
def _episode() -> tuple[DynamicWorld, Blackboard]:
    world, bb = DynamicWorld(), _facing_bb()
    mtp.start_episode(world, bb)
    return world, bb


def _pushing_state(world: DynamicWorld, bb: Blackboard) -> tuple[RobotState, pin.SE3]:
    """The arm with its finger tips on the object's face (the push's contact), and that
    pose."""
    assert world.physics is not None
    state = read_state(bb)
    touch, _ = mtp._touch_pose(world.physics, state, bb["object_position_world"], HALF, 0.10)
    answer = reach(world.kinematic, mtp.unfolded(state, ("right",)), "right", touch,
                   scene_world(bb), np.random.default_rng(0), move_torso=False)
    assert answer.state is not None
    return answer.state, touch


def test_a_cartesian_segment_keeps_the_tool_within_1_cm_of_the_line() -> None:
    world, bb = _episode()
    state, touch = _pushing_state(world, bb)
    start = np.array(touch.translation)
    goal = pin.SE3(touch.rotation, start + np.array([0.06, -0.04, 0.03]))
    path = cartesian_path(world, state, "right", goal, scene_world(bb),
                          np.random.default_rng(1))
    assert len(path) >= 3 and path[-1][1] == pytest.approx(np.linalg.norm(goal.translation
                                                                          - start))
    end = tool_world(world, path[-1][0], "right").translation
    assert np.linalg.norm(end - goal.translation) < 1e-3
    qs = [state.q_arm_rad["right"], *(s.q_arm_rad["right"] for s, _ in path)]
    b = np.asarray(goal.translation)
    for q0, q1 in itertools.pairwise(qs):  # the servo's straight line in joint space between steps
        for t in np.linspace(0.0, 1.0, 6):
            q = np.asarray(q0) + t * (np.asarray(q1) - np.asarray(q0))
            p = np.asarray(tool_world(world, path[0][0], "right", tuple(q)).translation)
            s = np.clip((p - start) @ (b - start) / ((b - start) @ (b - start)), 0.0, 1.0)
            assert np.linalg.norm(p - (start + s * (b - start))) < 0.01


def test_a_cartesian_segment_stops_where_clear_refuses() -> None:
    world, bb = _episode()
    state, touch = _pushing_state(world, bb)
    goal = pin.SE3(touch.rotation, np.array(touch.translation) + np.array([0.10, 0.0, 0.0]))
    x0 = float(touch.translation[0])

    def clear(s: RobotState) -> bool:
        return float(tool_world(world, s, "right").translation[0]) < x0 + 0.045

    path = cartesian_path(world, state, "right", goal, scene_world(bb),
                          np.random.default_rng(1), clear=clear)
    assert path and 0.03 <= path[-1][1] < 0.045


def test_the_simulated_table_check_sees_an_arm_on_the_table() -> None:
    world, bb = _episode()
    assert world.physics is not None
    state = read_state(bb)
    assert arm_touches_table(world.physics, state, "right") == ()  # tucked, clear
    down = dict(state.q_arm_rad)
    down["right"] = (0.0, 1.2, 0.0, -0.3, 0.0, 0.0, 0.0)  # the upper arm down, onto the table
    moved = type(state)(state.base_pose_world, state.torso_height_m, down, state.held,
                        state.arm_in_use)
    assert arm_touches_table(world.physics, moved, "right")


def test_a_shorter_stroke_is_used_when_the_full_one_ends_on_the_table(
        monkeypatch: pytest.MonkeyPatch) -> None:
    world, bb = _episode()
    assert world.physics is not None
    state, touch = _pushing_state(world, bb)
    direction = np.asarray(touch.rotation[:, 0])
    x0 = float(touch.translation @ direction)

    def wall(beyond: float) -> object:  # the "table" begins this far along the push
        def touches(physics: object, s: RobotState, arm: Arm, **_: object) -> tuple[str, ...]:
            at = float(tool_world(world, s, arm).translation @ direction)
            return ("r_gripper_palm_link",) if at > x0 + beyond else ()
        return touches

    args = (world, world.physics, "right", state, touch, direction, scene_world(bb),
            np.random.default_rng(2))
    assert mtp._stroke(*args) is not None  # type: ignore[arg-type]
    monkeypatch.setattr(mtp, "arm_touches_table", wall(0.062))
    lines = mtp._stroke(*args)  # type: ignore[arg-type]
    assert lines is not None
    end = float(tool_world(world, lines[1][-1], "right").translation @ direction)
    assert mtp.MIN_STROKE_M - 1e-6 <= end - x0 < mtp.PUSH_STROKE_M
    monkeypatch.setattr(mtp, "arm_touches_table", wall(0.04))  # shorter than the minimum
    assert mtp._stroke(*args) is None  # type: ignore[arg-type]


def test_the_other_arm_pushes_when_the_one_in_use_would_touch_the_table(
        monkeypatch: pytest.MonkeyPatch) -> None:
    world, bb = _episode()
    assert world.physics is not None
    state = read_state(bb)
    position = bb["object_position_world"]
    plan = mtp._plan(world, world.physics, bb, state, position, ("right", "left"),
                     np.random.default_rng(4))
    assert not isinstance(plan, Reach) and plan[0] == "right"

    def right_on_table(physics: object, s: object, arm: str, **_: object) -> tuple[str, ...]:
        return ("r_shoulder_pan_link",) if arm == "right" else ()

    monkeypatch.setattr(mtp, "arm_touches_table", right_on_table)
    plan = mtp._plan(world, world.physics, bb, state, position, ("right", "left"),
                     np.random.default_rng(4))
    assert not isinstance(plan, Reach) and plan[0] == "left"
    plan = mtp._plan(world, world.physics, bb, state, position, ("right",),
                     np.random.default_rng(4))
    assert isinstance(plan, Reach) and plan.reason in FAILURE_REASONS
