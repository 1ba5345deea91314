"""Kinematics benchmark for the PR2: IK paths, unreachable answers, base placement,
reachability classifier. One run prints every table.

    python benchmarks/bench_kinematics.py            # full run (1000 targets per chain)
    python benchmarks/bench_kinematics.py --quick    # smoke run

IK targets are the tool poses of uniform in-limit configurations (seeded); every
solver starts from the configuration midway between the limits. Success =
position and orientation error below 1e-5 and the solution inside the limits;
times include failures. TRAC-IK (``pytracik``) runs on the same targets when it
is installed (an optional reference, never a runtime dependency).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from skillcompose.robots.base_placement import BasePlacer, random_table_scene
from skillcompose.robots.collision import Scene, check_collisions
from skillcompose.robots.ik import IKSolver, IKTarget
from skillcompose.robots.model import (
    FloatArray,
    KinematicChain,
    RobotModel,
    find_pr2_urdf,
    load_pr2,
)
from skillcompose.robots.optimisation import ConstrainedIK, OptimisedBasePlacer
from skillcompose.robots.reachability import (
    DATASET_PATH,
    WEIGHTS_PATH,
    RBFClassifier,
    ReachabilityOracle,
    evaluate,
    load_dataset,
    split,
)

TOL = 1e-5
CHAINS = (
    ("left_arm", "left"),
    ("right_arm", "right"),
    ("left_arm_torso", "left"),
    ("right_arm_torso", "right"),
)


def _pose_error(
    chain: KinematicChain, arm: str, theta: FloatArray, target: IKTarget
) -> tuple[float, float]:
    reached = chain.transform_tool_to_world(arm, theta)  # type: ignore[arg-type]
    rel = target.rotation.T @ reached.rotation  # type: ignore[union-attr]
    angle = float(np.arccos(np.clip((np.trace(rel) - 1) / 2, -1, 1)))
    return float(np.linalg.norm(reached.translation - target.position_m)), angle


def _ok(chain: KinematicChain, arm: str, theta: FloatArray | None, target: IKTarget) -> bool:
    if theta is None or not chain.within_limits(theta, 1e-9):
        return False
    pos, rot = _pose_error(chain, arm, theta, target)
    return pos < TOL and rot < TOL


def _row(name: str, oks: list[bool], times: list[float]) -> str:
    t = np.array(times) * 1e3
    return (
        f"| {name:<44} | {100 * np.mean(oks):7.2f}% | {np.median(t):8.3f} | "
        f"{np.percentile(t, 95):8.3f} | {len(oks):5d} |"
    )


def _header(title: str) -> None:
    print(f"\n### {title}\n")
    print(f"| {'case':<44} | success  | median ms | p95 ms   |     n |")
    print(f"|{'-' * 46}|----------|-----------|----------|-------|")


def _targets(chain: KinematicChain, arm: str, n: int, seed: int) -> list[IKTarget]:
    rng = np.random.default_rng(seed)
    return [
        IKTarget.from_transform(chain.transform_tool_to_world(arm, chain.sample_coordinates(rng)))  # type: ignore[arg-type]
        for _ in range(n)
    ]


def bench_ik(model: RobotModel, n: int, n_ipopt: int) -> None:
    _header(f"IK on {n} reachable pose targets per chain (seed from the limits' midpoint)")
    try:
        import trac_ik
    except ImportError:
        trac_ik = None
    for name, arm in CHAINS:
        chain = model.chain(name)
        targets = _targets(chain, arm, n, seed=1234)
        for budget in (0.005, 0.020):
            solver = IKSolver(chain=chain, arm=arm, seed=0, time_budget_s=budget)  # type: ignore[arg-type]
            oks, times = [], []
            for target in targets:
                start = time.perf_counter()
                result = solver.solve(target, diagnose=False).coordinates
                dt = time.perf_counter() - start
                times.append(dt)
                oks.append(_ok(chain, arm, result, target))
            print(_row(f"{name} DLS (Pinocchio), {budget * 1e3:.0f} ms budget", oks, times))
        problem = ConstrainedIK(chain=chain, arms=(arm,), n_boxes=1)  # type: ignore[arg-type]
        mid = IKSolver(chain=chain, arm=arm).midpoint()  # type: ignore[arg-type]
        oks, times = [], []
        for target in targets[:n_ipopt]:
            start = time.perf_counter()
            out = problem.solve({arm: target}, Scene(), mid).coordinates  # type: ignore[dict-item]
            dt = time.perf_counter() - start
            times.append(dt)
            oks.append(_ok(chain, arm, out, target))
        print(_row(f"{name} CasADi/IPOPT", oks, times))
        if trac_ik is not None:
            base_link = "torso_lift_link" if "torso" not in name else "base_link"
            base_in_world = chain.transform_frame_to_world(base_link, mid)
            solver_ref = trac_ik.TracIK(
                base_link,
                f"{arm[0]}_gripper_tool_frame",
                str(find_pr2_urdf()),
                timeout=0.005,
                epsilon=1e-5,
            )
            # pytracik reads this URDF's revolute limits as [0, 0]: give it the URDF limits
            big = 3.4e38
            solver_ref.joint_limits = (
                np.where(np.isfinite(chain.lower_limits), chain.lower_limits, -big).tolist(),
                np.where(np.isfinite(chain.upper_limits), chain.upper_limits, big).tolist(),
            )
            oks, times = [], []
            for target in targets:
                local = base_in_world.actInv(
                    __import__("pinocchio").SE3(target.rotation, target.position_m)
                )
                start = time.perf_counter()
                out = solver_ref.ik(local.translation, local.rotation, mid)
                dt = time.perf_counter() - start
                times.append(dt)
                oks.append(
                    _ok(
                        chain,
                        arm,
                        None if out is None else chain.normalise(np.asarray(out)),
                        target,
                    )
                )
            print(_row(f"{name} TRAC-IK (pytracik, C++), 5 ms", oks, times))
    if trac_ik is None:
        print("\n(TRAC-IK reference skipped: `pip install pytracik` to include it)")


def bench_unreachable(model: RobotModel, n: int) -> None:
    _header(f"Answering 'unreachable' ({n} targets)")
    rng = np.random.default_rng(99)
    for name, arm in (("left_arm", "left"), ("left_arm_torso", "left")):
        chain = model.chain(name)
        solver = IKSolver(chain=chain, arm=arm, seed=0, time_budget_s=0.005)  # type: ignore[arg-type]
        far, infeasible = [], []
        shoulder = chain.joint_origins_world(np.zeros(chain.n_coordinates))["l_shoulder_pan_joint"]
        for _ in range(n):
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            far.append(IKTarget(shoulder + rng.uniform(1.2, 2.0) * d, np.eye(3)))
            # in reach of the arm's length but pointing back at the shoulder from close by
            infeasible.append(
                IKTarget(
                    shoulder + np.array([rng.uniform(0.05, 0.15), 0, 0]), np.diag([-1.0, -1.0, 1.0])
                )
            )
        groups = [("beyond the arm's length", far)]
        if "torso" not in name:  # with the torso this pose becomes feasible
            groups.append(("within length, infeasible pose", infeasible))
        for label, group in groups:
            oks, times = [], []
            for target in group:
                result = solver.solve(target)
                times.append(result.time_s)
                oks.append(not result.success)
            print(_row(f"{name}: {label}", oks, times))
    print(
        "\n(success = answered 'not reachable'; includes the <= 5 ms diagnosis"
        " that tells limits from reach)"
    )


def bench_base_placement(model: RobotModel, n: int, n_ipopt: int) -> None:
    _header(f"Base placement, object on a random table edge + an obstacle box ({n} scenes per arm)")
    for arm in ("left", "right"):
        chain = model.chain(f"{arm}_arm_torso_base")
        placer = BasePlacer(model=model, arm=arm, seed=0, time_budget_s=0.2)
        optimiser = OptimisedBasePlacer(model=model, arm=arm, seed=0, n_boxes=2)
        rng = np.random.default_rng(2024)
        scenes = [random_table_scene(rng, obstacle=True) for _ in range(n)]
        oks, times = [], []
        for scene, target in scenes:
            result = placer.place(target, scene)
            pose = result.pose(model)
            good = pose is not None
            if pose is not None:
                theta = model.coordinates_for(chain, pose)
                good = (
                    _ok(chain, arm, theta, target)
                    and not check_collisions(chain, theta, scene).collides
                )
            oks.append(good)
            times.append(result.time_s)
        print(_row(f"{arm}: sampling + DLS (collisions, 2 cm margin)", oks, times))
        oks, times = [], []
        for scene, target in scenes[:n_ipopt]:
            res = optimiser.place(target, scene)
            good = res.coordinates is not None and res.success
            if good and res.coordinates is not None:
                good = (
                    _ok(chain, arm, res.coordinates, target)
                    and not check_collisions(chain, res.coordinates, scene).collides
                )
            oks.append(good)
            times.append(res.time_s)
        print(_row(f"{arm}: CasADi/IPOPT (collisions, 2 cm margin)", oks, times))


def bench_classifier(model: RobotModel, n_ik: int) -> None:
    print("\n### Reachability classifier (RBF network) against IK\n")
    if not DATASET_PATH.is_file() or not WEIGHTS_PATH.is_file():
        print("(skipped: shipped data set or weights missing)")
        return
    inputs, labels, seed = load_dataset()
    _, held_out = split(len(labels), seed)
    classifier = RBFClassifier.load()
    report = evaluate(classifier, inputs[held_out], labels[held_out])
    sample = inputs[held_out[:n_ik]]
    start = time.perf_counter()
    for row in sample:
        classifier.predict(row[None, :])
    t_rbf = (time.perf_counter() - start) / len(sample)
    start = time.perf_counter()
    classifier.predict(inputs[held_out])
    t_batch = (time.perf_counter() - start) / len(held_out)
    oracle = ReachabilityOracle(model, seed=seed)
    start = time.perf_counter()
    for i, row in enumerate(sample):
        oracle.label(row[:3], float(row[4]), i)
    t_ik = (time.perf_counter() - start) / len(sample)
    print("| metric | value |\n|---|---|")
    print(
        f"| held-out points (classes 0/1/2) | {report.n_held_out} "
        f"({'/'.join(map(str, report.class_counts))}) |"
    )
    print(f"| agreement with IK | {100 * report.accuracy:.2f}% |")
    print(f"| unreachable points called reachable | {100 * report.false_reachable_rate:.2f}% |")
    print(f"| RBF time per query (single) | {t_rbf * 1e6:.1f} us |")
    print(f"| RBF time per query (batch of {len(held_out)}) | {t_batch * 1e6:.2f} us |")
    print(f"| IK ground truth per query (both arms, {len(sample)} queries) | {t_ik * 1e3:.2f} ms |")
    print(f"| speed-up single / batch | {t_ik / t_rbf:.0f}x / {t_ik / t_batch:.0f}x |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help="small smoke run")
    args = parser.parse_args(argv)
    n, n_ipopt, n_base, n_base_ipopt = (40, 10, 10, 5) if args.quick else (1000, 200, 200, 100)
    model = load_pr2()
    start = time.perf_counter()
    bench_ik(model, n, n_ipopt)
    bench_unreachable(model, 20 if args.quick else 200)
    bench_base_placement(model, n_base, n_base_ipopt)
    bench_classifier(model, 20 if args.quick else 300)
    print(f"\n(total {time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
