"""Constrained inverse kinematics with CasADi and IPOPT.

For problems the fast path cannot express: collision margins to boxes, base
placement (base x, y, yaw, torso and arm solved together), both arms at once.
Decision variables are the chain coordinates [m, rad] with the URDF limits as
bounds; tool targets are equality constraints; every arm sphere keeps
``radius + margin`` from every box and the base circle keeps its radius plus the
margin from every box footprint. Every answer is re-checked numerically
(pose error, limits, exact collision geometry) before it is called a success.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from skillcompose.robots.casadi_kinematics import CasadiKinematics
from skillcompose.robots.collision import _ARM_SEGMENTS, BASE_RADIUS_M, Box, Scene, check_collisions
from skillcompose.robots.errors import InvalidConfiguration
from skillcompose.robots.ik import IKResult, IKStatus, IKTarget
from skillcompose.robots.model import (
    ARM_JOINTS,
    ARMS,
    ROBOT_FRAME,
    TOOL_FRAMES,
    Arm,
    FloatArray,
    KinematicChain,
    RobotModel,
)

_TOLERANCE = 1e-5


def _smooth_abs(x: ca.SX) -> ca.SX:
    return ca.sqrt(x * x + 1e-12)


def _box_distance_squared(point: ca.SX, box: ca.SX, planar: bool = False) -> ca.SX:
    """Squared distance from a point to a box (0 inside); ``box`` = centre(3), half(3), yaw."""
    c, s = ca.cos(box[6]), ca.sin(box[6])
    dx, dy, dz = point[0] - box[0], point[1] - box[1], point[2] - box[2]
    local = [c * dx + s * dy, -s * dx + c * dy, dz]
    total = ca.SX(0)
    for axis in range(2 if planar else 3):
        gap = ca.fmax(_smooth_abs(local[axis]) - box[3 + axis], 0)
        total = total + gap * gap
    return total


@dataclass
class ConstrainedIK:
    """An IPOPT problem for a chain, built once and solved many times.

    Attributes:
        chain: the chain whose coordinates are optimised.
        arms: arms with a tool target.
        orientation: whether targets include the tool orientation.
        n_boxes: number of box obstacles the problem accepts.
        margin_m: clearance kept from every box [m].
        max_iterations: IPOPT iteration cap.
    """

    chain: KinematicChain
    arms: tuple[Arm, ...]
    orientation: bool = True
    n_boxes: int = 1
    margin_m: float = 0.02
    max_iterations: int = 150
    _solver: ca.Function = field(init=False, repr=False)

    def __post_init__(self) -> None:
        for arm in self.arms:
            self.chain.tool_frame_id(arm)
        sym = CasadiKinematics(self.chain)
        theta = sym.coordinates
        n = self.chain.n_coordinates
        params = []
        reference = ca.SX.sym("reference", n)
        params.append(reference)
        constraints: list[ca.SX] = []
        lower: list[float] = []
        upper: list[float] = []
        for arm in self.arms:
            tool = sym.transform_tool_to_world(arm)
            goal_p = ca.SX.sym(f"{arm}_position", 3)
            params.append(goal_p)
            constraints.append(tool.translation_m - goal_p)
            lower += [0.0] * 3
            upper += [0.0] * 3
            if self.orientation:
                goal_r = ca.SX.sym(f"{arm}_rotation", 3, 3)
                params.append(ca.vec(goal_r))
                rel = goal_r.T @ tool.rotation
                constraints.append(
                    ca.vertcat(rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1])
                )
                lower += [0.0] * 3
                upper += [0.0] * 3
                constraints.append(ca.trace(rel))
                lower.append(1.0)
                upper.append(ca.inf)
        boxes = ca.SX.sym("boxes", 7, self.n_boxes)
        params.append(ca.vec(boxes))
        spheres = self._symbolic_spheres(sym)
        for b in range(self.n_boxes):
            for centre, radius in spheres:
                constraints.append(_box_distance_squared(centre, boxes[:, b]))
                lower.append((radius + self.margin_m) ** 2)
                upper.append(ca.inf)
            if self.chain.has_base:
                base = sym.transform_frame_to_world(ROBOT_FRAME).translation_m
                constraints.append(_box_distance_squared(base, boxes[:, b], planar=True))
                lower.append((BASE_RADIUS_M + self.margin_m) ** 2)
                upper.append(ca.inf)
        # stay close to the reference (weights: arm joints 1, base and torso 0.1)
        weights = np.ones(n)
        if self.chain.has_base:
            weights[:3] = 0.1
        cost = ca.sumsqr(ca.DM(np.sqrt(weights)) * (theta - reference)) * 1e-3
        nlp = {"x": theta, "p": ca.vertcat(*params), "f": cost, "g": ca.vertcat(*constraints)}
        options: dict[str, bool | int | float | str] = {
            "print_time": False,
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "ipopt.max_iter": self.max_iterations,
            "ipopt.tol": 1e-9,
            "ipopt.constr_viol_tol": 1e-9,
        }
        self._solver = ca.nlpsol("constrained_ik", "ipopt", nlp, options)
        self._lbg = np.array(lower)
        self._ubg = np.array(upper)

    def _symbolic_spheres(self, sym: CasadiKinematics) -> list[tuple[ca.SX, float]]:
        model = self.chain.model
        out: list[tuple[ca.SX, float]] = []
        neutral = np.zeros(self.chain.n_coordinates)
        for arm in self.arms:
            prefix = ARM_JOINTS[arm][0][:2]
            points = {
                name: sym.joint_placements_world[model.getJointId(prefix + name)].translation_m
                for name in ("shoulder_lift_joint", "elbow_flex_joint", "wrist_flex_joint")
            }
            points["tool"] = sym.transform_tool_to_world(arm).translation_m
            numeric = self.chain.joint_origins_world(neutral)
            numeric_tool = self.chain.transform_tool_to_world(arm, neutral).translation
            for start, end, radius in _ARM_SEGMENTS:
                a = numeric[prefix + start]
                b = numeric_tool if end == "tool" else numeric[prefix + end]
                count = max(2, int(np.ceil(np.linalg.norm(b - a) / radius)) + 1)
                for t in np.linspace(0.0, 1.0, count):
                    out.append((points[start] + t * (points[end] - points[start]), radius))
        return out

    def solve(
        self,
        targets: Mapping[Arm, IKTarget],
        scene: Scene,
        initial: FloatArray,
        *,
        fixed: Mapping[str, float] | None = None,
    ) -> IKResult:
        """Solve from ``initial``; the result is verified numerically."""
        start = time.perf_counter()
        if set(targets) != set(self.arms):
            raise InvalidConfiguration(f"targets for arms {sorted(targets)}, expected {self.arms}")
        if len(scene.boxes) > self.n_boxes:
            raise InvalidConfiguration(
                f"the problem was built for {self.n_boxes} boxes, scene has {len(scene.boxes)}"
            )
        params: list[FloatArray] = [np.asarray(initial, dtype=float)]
        for arm in self.arms:
            target = targets[arm]
            params.append(target.position_m)
            if self.orientation:
                if target.rotation is None:
                    raise InvalidConfiguration(f"arm {arm!r} target needs a rotation")
                params.append(target.rotation.flatten(order="F"))
        boxes = list(scene.boxes)
        # pad with far-away dummy boxes so the problem's shape is fixed
        boxes += [Box((1e3, 1e3, -1e3), (0.1, 0.1, 0.1), 0.0, "pad")] * (self.n_boxes - len(boxes))
        box_values = np.array([[*b.center_m, *b.half_extents_m, b.yaw_rad] for b in boxes]).T
        params.append(box_values.flatten(order="F"))
        lbx = self.chain.lower_limits.copy()
        ubx = self.chain.upper_limits.copy()
        for name, value in (fixed or {}).items():
            index = self.chain.coordinate_index(name)
            lbx[index] = ubx[index] = value
        x0 = np.clip(initial, lbx, ubx)
        solution = self._solver(
            x0=x0, p=np.concatenate(params), lbx=lbx, ubx=ubx, lbg=self._lbg, ubg=self._ubg
        )
        stats = self._solver.stats()
        theta = self.chain.normalise(np.array(solution["x"]).ravel())
        return self._verify(theta, targets, scene, stats, start)

    def _verify(
        self,
        theta: FloatArray,
        targets: Mapping[Arm, IKTarget],
        scene: Scene,
        stats: dict[str, object],
        start: float,
    ) -> IKResult:
        pos_err = rot_err = 0.0
        for arm, target in targets.items():
            reached = self.chain.transform_tool_to_world(arm, theta)
            pos_err = max(pos_err, float(np.linalg.norm(reached.translation - target.position_m)))
            if target.rotation is not None and self.orientation:
                rel = target.rotation.T @ reached.rotation
                angle = np.arccos(np.clip((np.trace(rel) - 1) / 2, -1, 1))
                rot_err = max(rot_err, float(angle))
        iterations = int(stats.get("iter_count", 0))  # type: ignore[call-overload]
        report = check_collisions(self.chain, theta, scene)
        if pos_err > _TOLERANCE or rot_err > _TOLERANCE:
            status, why = IKStatus.UNREACHABLE, f"IPOPT: {stats.get('return_status')}"
        elif not self.chain.within_limits(theta, 1e-7):
            status, why = IKStatus.JOINT_LIMITS, "solution outside the joint limits"
        elif report.collides:
            status, why = IKStatus.COLLISION, f"collides: {report.pairs}"
        else:
            status, why = IKStatus.SUCCESS, ""
        return IKResult(
            status, theta, pos_err, rot_err, iterations, 0, time.perf_counter() - start, why
        )


def _nominal_arm(arm: Arm) -> FloatArray:
    """A bent, forward-reaching arm [rad] used as the optimiser's starting guess."""
    sign = 1.0 if arm == "left" else -1.0
    return np.array([sign * 0.3, 0.2, sign * 0.0, -1.2, 0.0, -0.8, 0.0])


@dataclass
class OptimisedBasePlacer:
    """Base placement by IPOPT over base, torso and arm together, with collision margins.

    ``seed`` seeds the restarts (random starting bases around the target).
    """

    model: RobotModel
    arm: Arm
    seed: int = 0
    margin_m: float = 0.02
    n_boxes: int = 2
    restarts: int = 3
    rng: np.random.Generator = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)
        self.chain = self.model.chain(f"{self.arm}_arm_torso_base")
        self.problem = ConstrainedIK(
            chain=self.chain, arms=(self.arm,), n_boxes=self.n_boxes, margin_m=self.margin_m
        )

    def place(self, target: IKTarget, scene: Scene) -> IKResult:
        """Solve base (x, y, yaw), torso and arm so the tool reaches ``target`` (world)."""
        start = time.perf_counter()
        approach = target.rotation[:, 0] if target.rotation is not None else target.position_m
        heading = float(np.arctan2(approach[1], approach[0]))
        sign = 1.0 if self.arm == "left" else -1.0
        best: IKResult | None = None
        for attempt in range(self.restarts):
            yaw = heading + (0.0 if attempt == 0 else self.rng.uniform(-0.5, 0.5))
            x_r = 0.6 if attempt == 0 else self.rng.uniform(0.45, 0.7)
            y_r = sign * (0.2 if attempt == 0 else self.rng.uniform(0.0, 0.35))
            c, s = np.cos(yaw), np.sin(yaw)
            base = [
                target.position_m[0] - (c * x_r - s * y_r),
                target.position_m[1] - (s * x_r + c * y_r),
                yaw,
            ]
            initial = np.concatenate([base, [0.15], _nominal_arm(self.arm)])
            result = self.problem.solve({self.arm: target}, scene, initial)
            if best is None or result.success or result.position_error_m < best.position_error_m:
                best = result
            if result.success:
                break
        assert best is not None
        return IKResult(
            best.status,
            best.coordinates,
            best.position_error_m,
            best.orientation_error_rad,
            best.iterations,
            attempt,
            time.perf_counter() - start,
            best.message,
        )


def solve_both_arms(
    model: RobotModel,
    targets: Mapping[Arm, IKTarget],
    scene: Scene | None = None,
    *,
    base_xy_yaw: tuple[float, float, float] | None = None,
    margin_m: float = 0.02,
) -> IKResult:
    """Both tool frames on their targets at once (chain ``both_arms_torso_base``).

    With ``base_xy_yaw`` the base is held there; otherwise it is optimised too.
    """
    scene = scene or Scene()
    chain = model.chain("both_arms_torso_base")
    problem = ConstrainedIK(
        chain=chain, arms=ARMS, n_boxes=max(1, len(scene.boxes)), margin_m=margin_m
    )
    initial = np.concatenate([[0.0, 0.0, 0.0], [0.15], _nominal_arm("left"), _nominal_arm("right")])
    fixed: dict[str, float] = {}
    if base_xy_yaw is not None:
        initial[:3] = base_xy_yaw
        fixed = {chain.coordinate_names[i]: float(base_xy_yaw[i]) for i in range(3)}
    return problem.solve(targets, scene, initial, fixed=fixed)


__all__ = ["TOOL_FRAMES", "ConstrainedIK", "OptimisedBasePlacer", "solve_both_arms"]
