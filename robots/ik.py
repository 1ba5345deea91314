"""Fast numerical inverse kinematics on Pinocchio.

Damped least squares (Levenberg-Marquardt) on the tool frame's ``log6`` pose
error in the tool frame, damping proportional to the squared error (Newton steps
once close), joint limits enforced by clamping and re-solving the rest of the
step, the mirrored solution of PR2's roll-flex-roll elbow and wrist taken when a
flex joint hits its limit, early restarts when progress stalls (alternately
uniform and around the seed), and a wall-clock budget. A result
always comes back, never an exception for an unsolved target: its status says
``success``, ``unreachable`` (outside the arm's reach, or no solution even
without joint limits), ``joint_limits`` (solvable only outside the limits),
``collision`` (solutions exist but collide) or ``not_converged``.
"""

from __future__ import annotations

import enum
import math
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from skillcompose.robots.errors import InvalidConfiguration
from skillcompose.robots.model import (
    ARM_JOINTS,
    TORSO_JOINT,
    Arm,
    FloatArray,
    KinematicChain,
    _wrap_rad,
)

#: Default convergence tolerances: position [m] and orientation [rad].
POSITION_TOLERANCE_M = 1e-6
ORIENTATION_TOLERANCE_RAD = 1e-6


class IKStatus(enum.Enum):
    """Outcome of an IK request."""

    SUCCESS = "success"
    UNREACHABLE = "unreachable"
    JOINT_LIMITS = "joint_limits"
    COLLISION = "collision"
    NOT_CONVERGED = "not_converged"


@dataclass(frozen=True)
class IKTarget:
    """A tool-frame target in the chain's world frame.

    Attributes:
        position_m: tool origin in world [m], shape (3,).
        rotation: tool-to-world rotation matrix (3x3); ``None`` for position only.
    """

    position_m: FloatArray
    rotation: FloatArray | None = None

    def __post_init__(self) -> None:
        pos = np.asarray(self.position_m, dtype=np.float64)
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise InvalidConfiguration(f"target position_m must be 3 finite values [m], got {pos}")
        object.__setattr__(self, "position_m", pos)
        if self.rotation is not None:
            rot = np.asarray(self.rotation, dtype=np.float64)
            if rot.shape != (3, 3) or not np.allclose(rot @ rot.T, np.eye(3), atol=1e-6):
                raise InvalidConfiguration(
                    f"target rotation must be a 3x3 rotation matrix, got {rot}"
                )
            object.__setattr__(self, "rotation", rot)

    @classmethod
    def from_transform(cls, transform_tool_to_world: pin.SE3) -> IKTarget:
        """A full-pose target from a Pinocchio placement."""
        return cls(
            np.array(transform_tool_to_world.translation),
            np.array(transform_tool_to_world.rotation),
        )


@dataclass(frozen=True)
class IKResult:
    """What an IK request returned.

    Attributes:
        status: the outcome; ``success`` only if within tolerance, limits and collision-free.
        coordinates: chain coordinates [m, rad] of the best configuration found
            (the solution on success), or ``None`` if none was computed.
        position_error_m / orientation_error_rad: residual of ``coordinates``.
        iterations / restarts: work done.
        time_s: wall-clock time [s].
        message: a human-readable reason.
    """

    status: IKStatus
    coordinates: FloatArray | None
    position_error_m: float
    orientation_error_rad: float
    iterations: int
    restarts: int
    time_s: float
    message: str = ""

    @property
    def success(self) -> bool:
        """Whether the target was reached within tolerance, limits and collision-free."""
        return self.status is IKStatus.SUCCESS


CollisionCheck = Callable[[KinematicChain, FloatArray], bool]

try:  # numpy's solve gufunc without the wrapper's per-call checks (~8 us of 10 on 6x6)
    from numpy.linalg._umath_linalg import solve1 as _solve_gufunc

    def _solve(matrix: FloatArray, rhs: FloatArray) -> FloatArray:
        return np.asarray(_solve_gufunc(matrix, rhs))

except ImportError:  # pragma: no cover - other numpy layouts

    def _solve(matrix: FloatArray, rhs: FloatArray) -> FloatArray:
        return np.asarray(np.linalg.solve(matrix, rhs), dtype=np.float64)


@dataclass
class IKSolver:
    """Damped-least-squares IK for one arm of one chain.

    Keyword-only construction; ``seed`` seeds the restart sampler held by the solver.

    Attributes:
        chain: the kinematic chain (its locked joints fix the rest of the robot).
        arm: which tool frame to drive.
        seed: seed of the solver's random restarts.
        time_budget_s: wall-clock budget per request [s].
        max_iterations_per_attempt: iterations before a restart.
        damping: Levenberg-Marquardt damping added to ``J J^T`` (times ``|err|^2``).
        max_step_rad: largest coordinate change per iteration [rad or m].
        stall_iterations: restart after this many iterations without a 1% error decrease
            (not counted once ``|err|^2 <= precise_error_sq``, the Newton phase).
        check_iteration / check_error_sq: restart if ``|err|^2`` is still above
            ``check_error_sq`` after ``check_iteration`` iterations.
        restart_spread: odd restarts are uniform in the limits, even ones Gaussian
            around the initial coordinates with this fraction of each range.
        mirror_wrists: at a flex limit, jump to the mirrored roll-flex-roll solution.
        prismatic_scale: step weight of the torso [m per rad-equivalent]; small values
            make the descent prefer the arm joints over the 0.31 m torso travel.
    """

    chain: KinematicChain
    arm: Arm
    seed: int = 0
    time_budget_s: float = 0.005
    max_iterations_per_attempt: int = 40
    damping: float = 1e-3
    max_step_rad: float = 0.6
    stall_iterations: int = 4
    check_iteration: int = 12
    check_error_sq: float = 1e-2
    restart_spread: float = 0.25
    mirror_wrists: bool = True
    prismatic_scale: float = 0.1
    precise_error_sq: float = 1e-8
    position_tolerance_m: float = POSITION_TOLERANCE_M
    orientation_tolerance_rad: float = ORIENTATION_TOLERANCE_RAD
    rng: np.random.Generator = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)
        self._fid = self.chain.tool_frame_id(self.arm)
        self._model = self.chain.model
        self._local = threading.local()  # per thread: Pinocchio data, configuration
        self._has_planar = self.chain.has_base
        self._sample_low = np.where(
            np.isfinite(self.chain.lower_limits), self.chain.lower_limits, -np.pi
        )
        self._sample_high = np.where(
            np.isfinite(self.chain.upper_limits), self.chain.upper_limits, np.pi
        )
        self._reach = _ReachBound.build(self.chain, self.arm)
        self._scalar_q, self._scalar_v = self.chain._scalar_q, self.chain._scalar_v
        self._unbounded_q, self._unbounded_v = self.chain._unbounded_q, self.chain._unbounded_v
        prismatic = np.array([n == TORSO_JOINT for n in self.chain.coordinate_names], dtype=bool)
        self._scale = np.where(prismatic, self.prismatic_scale, 1.0)
        self._scaled = bool(np.any(self._scale != 1.0))
        self._mirrors = _find_mirrors(self.chain, self.arm) if self.mirror_wrists else ()

    def midpoint(self) -> FloatArray:
        """Coordinates midway between the limits (0 for unlimited ones) [m, rad]."""
        low, high = self.chain.lower_limits, self.chain.upper_limits
        finite = np.isfinite(low) & np.isfinite(high)
        return np.where(
            finite, 0.5 * (np.where(finite, low, 0.0) + np.where(finite, high, 0.0)), 0.0
        )

    def _work(self) -> tuple[pin.Data, FloatArray]:
        """This thread's Pinocchio data and configuration vector: threads sharing a solver
        (a skill thread left running past its state's time limit, say) never share them."""
        local = self._local
        try:
            return local.work
        except AttributeError:
            local.work = (self._model.createData(), pin.neutral(self._model))
            return local.work

    def _load_q(self, theta: FloatArray, q: FloatArray) -> FloatArray:
        """Fill this thread's Pinocchio configuration ``q`` from chain coordinates."""
        if self._has_planar:
            return self.chain.q_from_coordinates(theta)
        q[self._scalar_q] = theta[self._scalar_v]
        angles = theta[self._unbounded_v]
        q[self._unbounded_q] = np.cos(angles)
        q[self._unbounded_q + 1] = np.sin(angles)
        return q

    def _residual(
        self, theta: FloatArray, target: IKTarget, goal: pin.SE3 | None
    ) -> tuple[FloatArray, FloatArray, float, float]:
        """Error, its Jacobian w.r.t. the coordinates, and the position [m] and
        orientation [rad] errors at ``theta``.

        Pose targets: the error is ``log6(current^-1 * goal)`` in the tool frame and the
        Jacobian ``Jlog6 @ J_local`` (a step ``d`` with ``jac @ d = err`` reaches the goal
        to first order). Position targets: world position error, world-axes Jacobian.
        """
        model, fid = self._model, self._fid
        data, q = self._work()
        pin.computeJointJacobians(model, data, self._load_q(theta, q))
        placement = pin.updateFramePlacement(model, data, fid)
        if goal is None:
            jac = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
            err = target.position_m - placement.translation
            if self._has_planar:
                jac = jac @ self.chain.velocity_from_coordinate_rates(theta)
            return err, jac, math.sqrt(err @ err), 0.0
        current_to_goal = placement.actInv(goal)
        err = pin.log6(current_to_goal).vector
        jac = pin.Jlog6(current_to_goal.inverse()) @ pin.getFrameJacobian(
            model, data, fid, pin.LOCAL
        )
        if self._has_planar:
            jac = jac @ self.chain.velocity_from_coordinate_rates(theta)
        translation = current_to_goal.translation
        angular = err[3:]
        return err, jac, math.sqrt(translation @ translation), math.sqrt(angular @ angular)

    def _converged(self, position_error_m: float, orientation_error_rad: float) -> bool:
        return (
            position_error_m <= self.position_tolerance_m
            and orientation_error_rad <= self.orientation_tolerance_rad
        )

    def _attempt(
        self,
        theta: FloatArray,
        target: IKTarget,
        goal: pin.SE3 | None,
        free: FloatArray,
        low: FloatArray,
        high: FloatArray,
        deadline: float,
    ) -> tuple[FloatArray, FloatArray, int, bool]:
        """One damped-least-squares descent; returns (theta, error, iterations, converged).

        Damping ``lambda = damping * |err|^2 + 1e-9``: large far from the goal, vanishing
        near it (Newton steps once close: quadratic convergence). Coordinates a step
        pushes past a limit are clamped there and the rest of the step is re-solved
        without them. The attempt gives up early when the error stops shrinking or is
        still large after ``check_iteration`` iterations.
        """
        best_norm = math.inf
        stall = 0
        theta = theta.copy()
        all_free = bool(free.all())
        free_index = np.flatnonzero(free)
        for iteration in range(1, self.max_iterations_per_attempt + 1):
            err, jac, pos_err, rot_err = self._residual(theta, target, goal)
            if pos_err <= self.position_tolerance_m and rot_err <= self.orientation_tolerance_rad:
                return theta, err, iteration, True
            norm = float(err @ err)
            if norm < 0.99 * best_norm:
                best_norm, stall = norm, 0
            elif norm > self.precise_error_sq:
                stall += 1
                if stall >= self.stall_iterations:
                    return theta, err, iteration, False
            if iteration >= self.check_iteration and norm > self.check_error_sq:
                return theta, err, iteration, False
            if time.perf_counter() > deadline:
                return theta, err, iteration, False
            damping = self.damping * norm + 1e-9
            if self._scaled:
                jac = jac * self._scale
            # the common case (nothing fixed, no limit hit) avoids fancy indexing
            index: slice | NDArray[np.intp] = slice(None) if all_free else free_index
            jac_active = jac if all_free else jac[:, free_index]
            for clamp_pass in range(3):
                gram = jac_active @ jac_active.T
                gram.flat[:: gram.shape[0] + 1] += damping
                step = jac_active.T @ _solve(gram, err)
                if self._scaled:
                    step *= self._scale[index]
                largest = float(np.abs(step).max())
                if largest > self.max_step_rad:
                    step *= self.max_step_rad / largest
                moved = theta[index] + step
                if self._mirrors and clamp_pass == 0:
                    if all_free:
                        self._mirror(moved, low, high)
                    else:  # fixed coordinates have low == high: never mirrored
                        full = theta.copy()
                        full[index] = moved
                        self._mirror(full, low, high)
                        moved = full[index]
                lo, hi = low[index], high[index]
                clipped = (moved < lo) | (moved > hi)
                if clamp_pass == 2 or not clipped.any():
                    theta[index] = np.minimum(np.maximum(moved, lo), hi)
                    break
                # clamp the coordinates the step pushes past a limit, then re-solve the
                # error they leave (linear prediction) with the others
                indices = free_index if isinstance(index, slice) else index
                held = indices[clipped]
                clamped = np.minimum(np.maximum(moved[clipped], lo[clipped]), hi[clipped])
                err = err - jac[:, held] @ ((clamped - theta[held]) / self._scale[held])
                theta[held] = clamped
                index = indices[~clipped]
                if index.size == 0:
                    break
                jac_active = jac[:, index]
        err, _, pos_err, rot_err = self._residual(theta, target, goal)
        return theta, err, self.max_iterations_per_attempt, self._converged(pos_err, rot_err)

    def solve(
        self,
        target: IKTarget,
        *,
        initial: FloatArray | None = None,
        fixed: Mapping[str, float] | None = None,
        collides: CollisionCheck | None = None,
        time_budget_s: float | None = None,
        diagnose: bool = True,
        max_restarts: int | None = None,
        rng: np.random.Generator | None = None,
    ) -> IKResult:
        """Solve for the chain coordinates that put the tool frame on ``target``.

        Args:
            target: tool target in world.
            initial: starting coordinates; the midpoint of the limits by default.
            fixed: coordinates held at a value, e.g. ``{"torso_lift_joint": 0.1}`` [m, rad].
            collides: optional check; a converged configuration that collides is rejected.
            time_budget_s: overrides the solver's budget [s].
            diagnose: on failure, spend a little more time to tell ``joint_limits``
                from ``unreachable``.
            max_restarts: stop after this many restarts; with a generous time budget
                this makes the answer independent of the machine's speed.
            rng: the generator of this call's restarts, so that callers sharing a solver
                (threads included) never share its draws; by default the solver's own
                (``rng``, seeded from ``seed``).
        """
        draws = self.rng if rng is None else rng
        start = time.perf_counter()
        budget = self.time_budget_s if time_budget_s is None else time_budget_s
        deadline = start + budget
        chain = self.chain
        low, high = chain.lower_limits.copy(), chain.upper_limits.copy()
        theta = self.midpoint() if initial is None else chain.check_coordinates(initial).copy()
        free = np.ones(chain.n_coordinates, dtype=bool)
        for name, value in (fixed or {}).items():
            index = chain.coordinate_index(name)
            free[index] = False
            theta[index] = value
            low[index] = high[index] = value
        theta = np.clip(theta, low, high)

        if not self._reach.may_reach(target, low, high, chain):
            return IKResult(
                IKStatus.UNREACHABLE,
                None,
                np.inf,
                np.inf,
                0,
                0,
                time.perf_counter() - start,
                "the target is farther from the shoulder than the arm's length",
            )

        goal = None if target.rotation is None else pin.SE3(target.rotation, target.position_m)
        seed_theta = theta.copy()
        iterations = restarts = 0
        best: tuple[float, FloatArray, FloatArray] | None = None
        saw_collision = False
        while True:
            theta, err, its, ok = self._attempt(theta, target, goal, free, low, high, deadline)
            iterations += its
            theta = chain.normalise(theta)
            if ok:
                if collides is None or not collides(chain, theta):
                    return self._result(
                        IKStatus.SUCCESS, theta, err, iterations, restarts, start, ""
                    )
                saw_collision = True
            score = float(err @ err)
            if best is None or score < best[0]:
                best = (score, theta, err)
            if time.perf_counter() > deadline or (
                max_restarts is not None and restarts >= max_restarts
            ):
                break
            restarts += 1
            theta = np.where(free, self._restart(seed_theta, restarts, draws), theta)
            if chain.has_base:
                theta[:3] = np.where(free[:3], best[1][:3], theta[:3])

        assert best is not None  # the loop runs at least once
        _, theta, err = best
        if saw_collision:
            status, why = IKStatus.COLLISION, "every solution found collides with the scene"
        elif diagnose and self._solvable_without_limits(target, theta, free, draws):
            status, why = IKStatus.JOINT_LIMITS, "solutions exist only outside the joint limits"
        elif diagnose:
            status, why = IKStatus.UNREACHABLE, "no solution found even without joint limits"
        else:
            status, why = IKStatus.NOT_CONVERGED, f"no solution within {budget * 1e3:.1f} ms"
        return self._result(status, theta, err, iterations, restarts, start, why)

    def _mirror(self, moved: FloatArray, low: FloatArray, high: FloatArray) -> None:
        """Where a step pushes a flex joint past a limit, switch to the mirrored
        solution ``(roll + pi, -flex, roll + pi)`` of its roll-flex-roll triple when
        that lies inside the limits (same tool pose; see :func:`_find_mirrors`)."""
        for first, flex, last in self._mirrors:
            value = moved[flex]
            if low[flex] <= value <= high[flex] or not low[flex] <= -value <= high[flex]:
                continue
            rolled = []
            for roll in (first, last):
                options = [moved[roll] + math.pi, moved[roll] - math.pi]
                if self.chain.continuous[roll]:
                    options = [float(_wrap_rad(np.array(options[0])))]
                inside = [v for v in options if low[roll] <= v <= high[roll]]
                if not inside:
                    break
                rolled.append(min(inside, key=abs))
            else:
                moved[first], moved[flex], moved[last] = rolled[0], -value, rolled[1]

    def _restart(
        self, seed_theta: FloatArray, restart: int, rng: np.random.Generator
    ) -> FloatArray:
        """Restart coordinates: odd restarts uniform inside the limits, even ones
        near the seed (Gaussian, ``restart_spread`` of each range, clipped)."""
        if restart % 2 == 1 or self.restart_spread <= 0.0:
            return rng.uniform(self._sample_low, self._sample_high)
        spread = self.restart_spread * (self._sample_high - self._sample_low)
        near = seed_theta + spread * rng.standard_normal(seed_theta.shape[0])
        return np.clip(near, self._sample_low, self._sample_high)

    def _solvable_without_limits(
        self, target: IKTarget, theta: FloatArray, free: FloatArray, rng: np.random.Generator
    ) -> bool:
        inf = np.full_like(theta, np.inf)
        low = np.where(free, -inf, theta)
        high = np.where(free, inf, theta)
        goal = None if target.rotation is None else pin.SE3(target.rotation, target.position_m)
        deadline = time.perf_counter() + 0.005
        for attempt in range(4):
            start = (
                theta
                if attempt == 0
                else np.where(free, rng.uniform(self._sample_low, self._sample_high), theta)
            )
            _, _, _, ok = self._attempt(start, target, goal, free, low, high, deadline)
            if ok:
                return True
        return False

    def _result(
        self,
        status: IKStatus,
        theta: FloatArray,
        err: FloatArray,
        iterations: int,
        restarts: int,
        start: float,
        message: str,
    ) -> IKResult:
        return IKResult(
            status,
            theta,
            float(np.linalg.norm(err[:3])),
            float(np.linalg.norm(err[3:])) if err.shape[0] == 6 else 0.0,
            iterations,
            restarts,
            time.perf_counter() - start,
            message,
        )


def _find_mirrors(chain: KinematicChain, arm: Arm) -> tuple[tuple[int, int, int], ...]:
    """Coordinate triples ``(roll, flex, roll)`` with ``(a, b, c)`` and
    ``(a + pi, -b, c + pi)`` giving the same tool pose (PR2's elbow and wrist:
    two parallel roll axes through the flex axis), verified numerically on
    seeded random configurations."""
    names = ARM_JOINTS[arm]
    found = []
    rng = np.random.default_rng(0)
    for first_name, flex_name, last_name in zip(names, names[1:], names[2:], strict=False):
        if not all(n in chain.coordinate_names for n in (first_name, flex_name, last_name)):
            continue
        first, flex, last = (chain.coordinate_index(n) for n in (first_name, flex_name, last_name))
        same = True
        for _ in range(4):
            theta = chain.sample_coordinates(rng)
            mirrored = theta.copy()
            mirrored[first] += np.pi
            mirrored[flex] = -mirrored[flex]
            mirrored[last] += np.pi
            a = chain.transform_tool_to_world(arm, theta)
            b = chain.transform_tool_to_world(arm, mirrored)
            if not np.allclose(a.homogeneous, b.homogeneous, atol=1e-9):
                same = False
                break
        if same:
            found.append((first, flex, last))
    return tuple(found)


@dataclass(frozen=True)
class _ReachBound:
    """A cheap necessary condition for reachability: the wrist centre (pose targets)
    or the tool (position targets) must lie within the arm's length of the shoulder
    pan axis origin, which slides with the torso."""

    shoulder_low_m: FloatArray | None
    shoulder_high_m: FloatArray | None
    torso_index: int | None
    arm_length_m: float
    wrist_offset_in_tool_m: FloatArray | None
    tool_extra_m: float

    @staticmethod
    def build(chain: KinematicChain, arm: Arm) -> _ReachBound:
        if chain.has_base:
            return _ReachBound(None, None, None, np.inf, None, 0.0)
        model = chain.model
        names = ARM_JOINTS[arm]
        ids = [model.getJointId(n) for n in names]
        # sum of fixed offsets from the shoulder pan origin to the wrist flex origin
        length = float(sum(np.linalg.norm(model.jointPlacements[j].translation) for j in ids[1:6]))
        torso = (
            chain.coordinate_names.index(TORSO_JOINT)
            if TORSO_JOINT in chain.coordinate_names
            else None
        )
        base = np.zeros(chain.n_coordinates)
        low_theta, high_theta = base.copy(), base.copy()
        if torso is not None:
            low_theta[torso] = chain.lower_limits[torso]
            high_theta[torso] = chain.upper_limits[torso]
        origins_low = chain.joint_origins_world(low_theta)
        origins_high = chain.joint_origins_world(high_theta)
        pan = names[0]
        # wrist flex origin expressed in the tool frame: constant if the wrist axes meet
        rng = np.random.default_rng(0)
        offsets = []
        for _ in range(5):
            theta = rng.uniform(
                np.where(np.isfinite(chain.lower_limits), chain.lower_limits, -np.pi),
                np.where(np.isfinite(chain.upper_limits), chain.upper_limits, np.pi),
            )
            tool = chain.transform_tool_to_world(arm, theta)
            wrist = chain.joint_origins_world(theta)[names[5]]
            offsets.append(tool.actInv(wrist))
        spread = float(np.max(np.ptp(np.array(offsets), axis=0)))
        wrist_offset = np.array(offsets[0]) if spread < 1e-9 else None
        tool_extra = float(np.linalg.norm(offsets[0])) if wrist_offset is not None else 0.5
        return _ReachBound(
            origins_low[pan], origins_high[pan], torso, length, wrist_offset, tool_extra
        )

    def may_reach(
        self, target: IKTarget, low: FloatArray, high: FloatArray, chain: KinematicChain
    ) -> bool:
        if self.shoulder_low_m is None or self.shoulder_high_m is None:
            return True
        a, b = self.shoulder_low_m, self.shoulder_high_m
        if self.torso_index is not None:
            span = chain.upper_limits[self.torso_index] - chain.lower_limits[self.torso_index]
            t_lo = (low[self.torso_index] - chain.lower_limits[self.torso_index]) / span
            t_hi = (high[self.torso_index] - chain.lower_limits[self.torso_index]) / span
            a, b = a + t_lo * (self.shoulder_high_m - a), a + t_hi * (self.shoulder_high_m - a)
        if target.rotation is not None and self.wrist_offset_in_tool_m is not None:
            point = target.position_m + target.rotation @ self.wrist_offset_in_tool_m
            reach = self.arm_length_m
        else:
            point = target.position_m
            reach = self.arm_length_m + self.tool_extra_m
        seg = b - a
        denom = float(seg @ seg)
        s = 0.0 if denom == 0.0 else float(np.clip((point - a) @ seg / denom, 0.0, 1.0))
        return bool(np.linalg.norm(point - (a + s * seg)) <= reach + 1e-6)


def solve_ik(
    chain: KinematicChain,
    arm: Arm,
    target: IKTarget,
    *,
    seed: int = 0,
    time_budget_s: float = 0.005,
    fixed: Mapping[str, float] | None = None,
    collides: CollisionCheck | None = None,
) -> IKResult:
    """One-shot IK (builds an :class:`IKSolver`; keep a solver to amortise set-up)."""
    solver = IKSolver(chain=chain, arm=arm, seed=seed, time_budget_s=time_budget_s)
    return solver.solve(target, fixed=fixed, collides=collides)
