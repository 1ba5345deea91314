"""Speed of the MuJoCo world of the PR2 (skillcompose.robots.physics): simulated seconds
per wall-clock second on one core, for four representative episodes.

    python benchmarks/bench_physics.py            # full run
    python benchmarks/bench_physics.py --quick    # smoke run

Cases (the scenes of tests/robots/test_physics.py):

- idle: the robot tucked, a box on the table, nothing moving;
- arm move: the right arm from a pose before the box to a pose beside it and back, empty;
- grasp + lift: approach, close on a 0.3 kg box, lift it 15 cm, carry it 20 cm sideways and
  back (the target of >= 10x real time is for this one);
- particles pouring: a jug holding 40 water particles grasped, lifted, carried over a glass
  and tipped; the particles land in the glass.

MuJoCo runs single-threaded; the numbers are for one core. ``cpu s`` is the process's CPU
time, which a shared machine's load disturbs less than the wall clock.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable, Sequence

import numpy as np

from skillcompose.robots.ik import IKSolver, IKTarget
from skillcompose.robots.model import TUCKED_ARM_RAD, load_pr2
from skillcompose.robots.physics import PhysicsWorld
from skillcompose.robots.physics_model import ObjectSpec, SceneSpec

TORSO_M = 0.2
BOX = ObjectSpec("box", "box", (0.03, 0.03, 0.06), 0.3)
BOX_AT = np.array([0.62, -0.2, 0.81])
JUG = ObjectSpec("jug", "cup", (0.03, 0.03, 0.08), 0.15)
GLASS = ObjectSpec("glass", "cup", (0.045, 0.045, 0.06), 0.2)


class _IK:
    def __init__(self) -> None:
        self.solver = IKSolver(chain=load_pr2().chain("right_arm_torso"), arm="right")

    def __call__(self, position: Sequence[float], initial: np.ndarray | None = None
                 ) -> np.ndarray:
        start = initial if initial is not None else np.array([TORSO_M, *TUCKED_ARM_RAD["right"]])
        result = self.solver.solve(
            IKTarget(np.asarray(position, float), np.eye(3)), initial=start,
            fixed={"torso_lift_joint": TORSO_M}, max_restarts=20, time_budget_s=5.0,
            rng=np.random.default_rng(1))
        if not result.success or result.coordinates is None:
            raise RuntimeError(f"benchmark IK failed for {position}: {result.message}")
        return np.asarray(result.coordinates)[1:]


def idle(world: PhysicsWorld, ik: _IK, repeats: int) -> None:
    world.reset(torso_m=TORSO_M, object_poses={"box": tuple(BOX_AT)})
    world.step(5.0 * repeats)


def arm_move(world: PhysicsWorld, ik: _IK, repeats: int) -> None:
    before = ik(BOX_AT + np.array([-0.15, 0.0, 0.03]))
    beside = ik(BOX_AT + np.array([-0.05, -0.15, 0.15]))
    world.reset(torso_m=TORSO_M, q_arm_rad={"right": before},
                object_poses={"box": tuple(BOX_AT)})
    for _ in range(repeats):
        world.track_arm("right", beside, 1.5)
        world.track_arm("right", before, 1.5)


def grasp_lift(world: PhysicsWorld, ik: _IK, repeats: int) -> None:
    at = BOX_AT + np.array([0.0, 0.0, 0.03])
    before, grasp = ik(at + np.array([-0.12, 0.0, 0.0])), ik(at)
    lift, aside = ik(at + np.array([0.0, 0.0, 0.15])), ik(at + np.array([0.0, -0.2, 0.15]))
    for _ in range(repeats):
        world.reset(torso_m=TORSO_M, q_arm_rad={"right": before},
                    object_poses={"box": tuple(BOX_AT)})
        world.track_arm("right", grasp, 1.5)
        if world.close_gripper("right") != "box":
            raise RuntimeError("benchmark: the box was not grasped")
        world.track_arm("right", lift, 1.5)
        world.track_arm("right", aside, 1.5)
        world.track_arm("right", lift, 1.5)
        if world.held_object("right") != "box":
            raise RuntimeError("benchmark: the box was dropped")


def pour(world: PhysicsWorld, ik: _IK, repeats: int) -> None:
    jug_at, glass_at = np.array([0.60, -0.05, 0.83]), np.array([0.60, -0.30, 0.81])
    before = ik(jug_at + np.array([-0.12, 0.0, 0.03]))
    grasp = ik(jug_at + np.array([0.0, 0.0, 0.03]))
    lift, over = ik(jug_at + np.array([0.0, 0.0, 0.19])), ik([0.60, glass_at[1] + 0.07, 0.96])
    tilted = over.copy()
    tilted[6] += 2.2
    for _ in range(repeats):
        world.reset(torso_m=TORSO_M, q_arm_rad={"right": before},
                    object_poses={"jug": tuple(jug_at), "glass": tuple(glass_at)},
                    particles_in="jug")
        world.step(0.5)
        world.track_arm("right", grasp, 1.5)
        world.close_gripper("right")
        world.track_arm("right", lift, 1.5)
        world.track_arm("right", over, 1.5)
        world.track_arm("right", tilted, 3.0)
        world.step(1.0)
    print(f"(pour: {world.particles_in('glass')} of {world.physics.scene.n_particles} "
          "particles in the glass)")


def measure(name: str, scene: SceneSpec, run: Callable[[PhysicsWorld, _IK, int], None],
            ik: _IK, repeats: int) -> tuple[str, float, float, float, int]:
    world = PhysicsWorld(scene)
    simulated = 0.0
    steps = 0
    wall = cpu = 0.0
    for _ in range(repeats):
        start_wall, start_cpu = time.perf_counter(), time.process_time()
        run(world, ik, 1)
        wall += time.perf_counter() - start_wall
        cpu += time.process_time() - start_cpu
        simulated += world.time_s  # each run starts with a reset
        steps += round(world.time_s / world.model.opt.timestep)
    return name, simulated, wall, cpu, steps


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one repeat per case")
    args = parser.parse_args(argv)
    repeats = 1 if args.quick else 5
    ik = _IK()
    box_scene = SceneSpec(objects=(BOX,))
    rows = [
        measure("idle", box_scene, idle, ik, repeats),
        measure("arm move", box_scene, arm_move, ik, repeats),
        measure("grasp + lift (0.3 kg box)", box_scene, grasp_lift, ik, repeats),
        measure("particles pouring (40)", SceneSpec(objects=(JUG, GLASS), n_particles=40),
                pour, ik, repeats),
    ]
    timestep = SceneSpec().timestep_s
    print(f"\n### MuJoCo PR2 world, time step {timestep * 1000:g} ms, one core "
          f"(machine: {os.cpu_count()} cores)\n")
    print("| case                       | sim s  | wall s | sim s / wall s | sim s / cpu s "
          "| steps / wall s |")
    print("|----------------------------|--------|--------|----------------|---------------"
          "|----------------|")
    for name, simulated, wall, cpu, steps in rows:
        print(f"| {name:26s} | {simulated:6.1f} | {wall:6.2f} | {simulated / wall:14.1f} "
              f"| {simulated / cpu:13.1f} | {steps / wall:14.0f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
