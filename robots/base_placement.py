"""Base placement: where to put the base (x, y, yaw) and torso so an arm reaches a target.

The fast path samples base poses around the target (biased to the arm's
comfortable zone in front of its shoulder), rejects those whose base collides
with the scene, and solves IK for the arm and torso with the base fixed,
rejecting solutions whose arm collides. The constrained optimisation path over
base, torso and arm together is :func:`skillcompose.robots.optimisation.place_base_optimised`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from skillcompose.robots.collision import (
    BASE_HALF_EXTENTS_M,
    BODY_HEIGHT_M,
    Box,
    Scene,
    check_collisions,
)
from skillcompose.robots.ik import IKSolver, IKStatus, IKTarget
from skillcompose.robots.model import BASE_JOINT, Arm, FloatArray, RobotModel, RobotPose


@dataclass(frozen=True)
class BasePlacementResult:
    """Outcome of a base placement request.

    Attributes:
        status: ``success``, or why not (``unreachable``, ``collision``, ``not_converged``).
        arm: the arm used.
        base_xy_yaw: base pose in world (x [m], y [m], yaw [rad]) or ``None``.
        torso_height_m: torso lift [m] or ``None``.
        arm_rad: the 7 arm joint angles [rad] or ``None``.
        candidates: base poses tried.
        time_s: wall-clock time [s].
        message: a human-readable reason.
    """

    status: IKStatus
    arm: Arm
    base_xy_yaw: tuple[float, float, float] | None
    torso_height_m: float | None
    arm_rad: tuple[float, ...] | None
    candidates: int
    time_s: float
    message: str = ""

    @property
    def success(self) -> bool:
        """Whether a collision-free reaching configuration was found."""
        return self.status is IKStatus.SUCCESS

    def pose(self, model: RobotModel) -> RobotPose | None:
        """The whole-robot pose (other arm tucked), or ``None`` on failure."""
        if self.base_xy_yaw is None or self.arm_rad is None or self.torso_height_m is None:
            return None
        tucked = dict(model.tucked_pose().arm_rad)
        tucked[self.arm] = self.arm_rad
        return RobotPose(self.base_xy_yaw, self.torso_height_m, tucked)


def _target_in_robot_frame(target: IKTarget, base: FloatArray) -> IKTarget:
    c, s = np.cos(base[2]), np.sin(base[2])
    rot_t = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # world -> robot
    rel = target.position_m - np.array([base[0], base[1], 0.0])
    rotation = None if target.rotation is None else rot_t @ target.rotation
    return IKTarget(rot_t @ rel, rotation)


def _scene_in_robot_frame(scene: Scene, base: FloatArray) -> Scene:
    c, s = np.cos(base[2]), np.sin(base[2])
    boxes = []
    for box in scene.boxes:
        dx, dy = box.center_m[0] - base[0], box.center_m[1] - base[1]
        boxes.append(
            Box(
                (c * dx + s * dy, -s * dx + c * dy, box.center_m[2]),
                box.half_extents_m,
                box.yaw_rad - float(base[2]),
                box.name,
            )
        )
    return Scene(tuple(boxes))


@dataclass
class BasePlacer:
    """Sampling base placement for one arm (keyword-only; ``seed`` seeds the sampler).

    Attributes:
        model: the robot model.
        arm: the arm that must reach.
        seed: seed of the candidate sampler and IK restarts.
        margin_m: clearance required between robot and boxes [m].
        ik_budget_s: IK budget per base candidate [s].
        time_budget_s: total budget [s].
        reach_x_m / reach_y_m: where the target should lie in the robot frame [m]
            (y for the left arm; mirrored for the right).
    """

    model: RobotModel
    arm: Arm
    seed: int = 0
    margin_m: float = 0.02
    ik_budget_s: float = 0.003
    time_budget_s: float = 0.2
    reach_x_m: tuple[float, float] = (0.35, 0.75)
    reach_y_m: tuple[float, float] = (-0.05, 0.45)
    rng: np.random.Generator = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)
        self.chain = self.model.chain(f"{self.arm}_arm_torso")
        self.solver = IKSolver(chain=self.chain, arm=self.arm, seed=self.seed)
        self._sign = 1.0 if self.arm == "left" else -1.0

    def _candidate(self, target: IKTarget, index: int) -> FloatArray:
        if target.rotation is not None:
            approach = target.rotation[:, 0]
            heading = float(np.arctan2(approach[1], approach[0]))
        else:
            heading = float(np.arctan2(target.position_m[1], target.position_m[0]))
        if index == 0:
            yaw, x_r, y_r = heading, 0.55, self._sign * 0.2
        else:
            yaw = heading + self.rng.uniform(-0.7, 0.7)
            x_r = self.rng.uniform(*self.reach_x_m)
            y_r = self._sign * self.rng.uniform(*self.reach_y_m)
        c, s = np.cos(yaw), np.sin(yaw)
        x = target.position_m[0] - (c * x_r - s * y_r)
        y = target.position_m[1] - (s * x_r + c * y_r)
        return np.array([x, y, yaw])

    def place(self, target: IKTarget, scene: Scene | None = None) -> BasePlacementResult:
        """Find a base pose, torso height and arm angles reaching ``target`` (world)."""
        start = time.perf_counter()
        scene = scene or Scene()
        deadline = start + self.time_budget_s
        candidates = 0
        saw_reach = saw_base_ok = False
        while time.perf_counter() < deadline:
            base = self._candidate(target, candidates)
            candidates += 1
            body = Box(
                (float(base[0]), float(base[1]), BODY_HEIGHT_M / 2),
                (*BASE_HALF_EXTENTS_M, BODY_HEIGHT_M / 2),
                float(base[2]),
            )
            if any(body.overlaps(box, self.margin_m) for box in scene.boxes):
                continue
            saw_base_ok = True
            local_target = _target_in_robot_frame(target, base)
            local_scene = _scene_in_robot_frame(scene, base)

            def collides(chain: object, theta: FloatArray, sc: Scene = local_scene) -> bool:
                return check_collisions(self.chain, theta, sc, margin_m=self.margin_m).collides

            result = self.solver.solve(
                local_target,
                collides=collides,
                time_budget_s=min(self.ik_budget_s, max(0.0, deadline - time.perf_counter())),
                diagnose=False,
            )
            if result.status is IKStatus.COLLISION:
                saw_reach = True
            if result.success and result.coordinates is not None:
                theta = result.coordinates
                return BasePlacementResult(
                    IKStatus.SUCCESS,
                    self.arm,
                    (float(base[0]), float(base[1]), float(base[2])),
                    float(theta[0]),
                    tuple(float(v) for v in theta[1:]),
                    candidates,
                    time.perf_counter() - start,
                )
        if not saw_base_ok:
            status, why = IKStatus.COLLISION, "every base pose tried collides with the scene"
        elif saw_reach:
            status, why = IKStatus.COLLISION, "reaching configurations found all collide"
        else:
            status, why = IKStatus.UNREACHABLE, "no base pose tried lets the arm reach the target"
        return BasePlacementResult(
            status, self.arm, None, None, None, candidates, time.perf_counter() - start, why
        )


def place_base(
    model: RobotModel,
    arm: Arm,
    target: IKTarget,
    scene: Scene | None = None,
    *,
    seed: int = 0,
    margin_m: float = 0.02,
    time_budget_s: float = 0.2,
) -> BasePlacementResult:
    """Sampling base placement (see :class:`BasePlacer`)."""
    placer = BasePlacer(
        model=model, arm=arm, seed=seed, margin_m=margin_m, time_budget_s=time_budget_s
    )
    return placer.place(target, scene)


__all__ = ["BASE_JOINT", "BasePlacementResult", "BasePlacer", "place_base", "random_table_scene"]


def random_table_scene(
    rng: np.random.Generator, *, obstacle: bool = False
) -> tuple[Scene, IKTarget]:
    """A random table (0.6-1.2 m by 0.6-1.0 m, top 0.6-0.85 m high, anywhere within 1 m of
    the world origin, any yaw) and a grasp target 10 cm above it near one long edge, gripper
    along the table's x axis [m, rad]; with ``obstacle``, a 4 x 4 x 10 cm box beside the
    target. For tests and benchmarks of base placement."""
    w, d, h = rng.uniform(0.6, 1.2), rng.uniform(0.6, 1.0), rng.uniform(0.6, 0.85)
    cx, cy, yaw = rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-np.pi, np.pi)
    u, v = -w / 2 + rng.uniform(0.05, 0.3), rng.uniform(-d / 2 + 0.1, d / 2 - 0.1)
    c, s = np.cos(yaw), np.sin(yaw)
    position = np.array([cx + c * u - s * v, cy + s * u + c * v, h + 0.1])
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    boxes = [Box.table((cx, cy), (w, d), h, yaw)]
    if obstacle:  # a second object beside the target
        ou, ov = u + 0.15, v + rng.choice([-1, 1]) * rng.uniform(0.15, 0.3)
        boxes.append(Box(
            (cx + c * ou - s * ov, cy + s * ou + c * ov, h + 0.1), (0.04, 0.04, 0.1), yaw, "box"
        ))
    return Scene(tuple(boxes)), IKTarget(position, rotation)
