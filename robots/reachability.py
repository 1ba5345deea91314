"""Reachability: ground truth by IK and the paper's RBF network classifier (section 4.2).

Question: an object at ``(x, y, z)`` [m] in the robot frame (``base_footprint``),
at bearing ``theta = atan2(y, x)`` [rad], with the torso at height ``h`` [m]: can
the left arm, the right arm, or neither reach it? "Reach" means the tool frame
on the object with a horizontal grasp pointing along the bearing (tool x-axis
``(cos theta, sin theta, 0)``, fingers horizontal), within the joint limits.

Labels (as the paper): 0 unreachable, 1 left arm, 2 right arm; when both arms
reach, the arm on the object's side (``y >= 0``: left).

Regenerate the shipped data set and weights with::

    python -m skillcompose.robots.reachability generate --n 16000 --seed 0
    python -m skillcompose.robots.reachability train
    python -m skillcompose.robots.reachability evaluate
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from skillcompose.robots.errors import DatasetError, InvalidConfiguration
from skillcompose.robots.ik import IKSolver, IKTarget
from skillcompose.robots.model import TORSO_JOINT, Arm, FloatArray, RobotModel, load_pr2

DATA_DIR = Path(__file__).parent / "data"
DATASET_PATH = DATA_DIR / "reachability_pr2_v1.npz"
WEIGHTS_PATH = DATA_DIR / "reachability_rbf_v2.npz"
FEATURES = ("x_m", "y_m", "z_m", "bearing_rad", "torso_height_m")
#: Sampling box of the data set in the robot frame: x, y, z [m], torso h [m].
DOMAIN = {"x_m": (0.0, 1.2), "y_m": (-1.0, 1.0), "z_m": (0.3, 1.6), "torso_height_m": (0.0, 0.31)}
HELD_OUT_FRACTION = 0.25
#: Shoulder pan joint origins in the robot frame at torso height 0 [m] (left, right),
#: and the wrist flex origin's distance behind the tool frame along the grasp [m].
SHOULDER_LEFT_M = (-0.05, 0.188, 0.790675)
SHOULDER_RIGHT_M = (-0.05, -0.188, 0.790675)
WRIST_BEHIND_TOOL_M = 0.18
#: Name of the distance the RBF units measure (stored with the weights).
METRIC = "x,y,z-h,bearing,wrist-shoulder distances"
_IK_RESTARTS = 12


def grasp_rotation(bearing_rad: float) -> FloatArray:
    """Tool-to-robot rotation of a horizontal grasp pointing along ``bearing_rad``."""
    c, s = np.cos(bearing_rad), np.sin(bearing_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def features_from_position(position_m: FloatArray, torso_height_m: float) -> FloatArray:
    """The 5 classifier inputs ``(x, y, z, bearing, h)`` of an object position."""
    x, y, z = (float(v) for v in position_m)
    return np.array([x, y, z, np.arctan2(y, x), torso_height_m])


@dataclass
class ReachabilityOracle:
    """Ground truth by IK (deterministic: per-query seeds and a restart budget)."""

    model: RobotModel
    seed: int = 0
    solvers: dict[Arm, IKSolver] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.solvers = {
            arm: IKSolver(chain=self.model.chain(f"{arm}_arm_torso"), arm=arm, seed=self.seed)
            for arm in ("left", "right")
        }

    def arms_reaching(
        self, position_m: FloatArray, torso_height_m: float, query_index: int = 0
    ) -> tuple[bool, bool]:
        """Whether (left, right) reach the object at ``position_m`` (robot frame)."""
        low, high = DOMAIN["torso_height_m"]
        if not low <= torso_height_m <= high:
            raise InvalidConfiguration(f"torso height {torso_height_m} m outside [{low}, {high}]")
        x, y, z = (float(v) for v in position_m)
        target = IKTarget(np.array([x, y, z]), grasp_rotation(np.arctan2(y, x)))
        out = []
        for k, solver in enumerate(self.solvers.values()):
            result = solver.solve(
                target,
                fixed={TORSO_JOINT: torso_height_m},
                time_budget_s=10.0,
                max_restarts=_IK_RESTARTS,
                diagnose=False,
                rng=np.random.default_rng([self.seed, query_index, k]),
            )
            out.append(result.success)
        return out[0], out[1]

    def label(self, position_m: FloatArray, torso_height_m: float, query_index: int = 0) -> int:
        """0 unreachable, 1 left, 2 right (both: the arm on the object's side)."""
        left, right = self.arms_reaching(position_m, torso_height_m, query_index)
        if left and right:
            return 1 if position_m[1] >= 0 else 2
        return 1 if left else 2 if right else 0


def sample_inputs(n: int, seed: int) -> FloatArray:
    """``n`` uniform samples of the domain as feature rows (x, y, z, bearing, h)."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(*DOMAIN["x_m"], n)
    y = rng.uniform(*DOMAIN["y_m"], n)
    z = rng.uniform(*DOMAIN["z_m"], n)
    h = rng.uniform(*DOMAIN["torso_height_m"], n)
    return np.column_stack([x, y, z, np.arctan2(y, x), h])


def _label_rows(args: tuple[FloatArray, int, int]) -> NDArrayInt:
    rows, seed, first_index = args
    oracle = ReachabilityOracle(load_pr2(), seed)
    return np.array(
        [oracle.label(r[:3], float(r[4]), first_index + i) for i, r in enumerate(rows)],
        dtype=np.uint8,
    )


NDArrayInt = np.ndarray


def generate_dataset(
    n: int, seed: int, *, workers: int = 1, rows: slice | None = None
) -> tuple[FloatArray, NDArrayInt]:
    """Inputs and labels of the seeded data set (or its ``rows`` slice).

    The labels do not depend on ``workers``: every query has its own seed.
    """
    inputs = sample_inputs(n, seed)
    indices = np.arange(n)[rows] if rows is not None else np.arange(n)
    chunks = np.array_split(indices, max(1, workers * 8))
    jobs = [(inputs[c], seed, int(c[0])) for c in chunks if len(c)]
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            labels = np.concatenate(list(pool.map(_label_rows, jobs)))
    else:
        labels = np.concatenate([_label_rows(j) for j in jobs])
    return inputs[indices], labels


def save_dataset(path: Path, inputs: FloatArray, labels: NDArrayInt, seed: int) -> None:
    """Write a compressed data set with its generation parameters."""
    np.savez_compressed(
        path, inputs=inputs, labels=labels, seed=np.int64(seed), n=np.int64(len(labels))
    )


def load_dataset(path: Path = DATASET_PATH) -> tuple[FloatArray, NDArrayInt, int]:
    """Inputs, labels and seed of a data set written by :func:`save_dataset`."""
    if not path.is_file():
        raise DatasetError(
            f"{path} not found; regenerate it with "
            "`python -m skillcompose.robots.reachability generate`"
        )
    with np.load(path) as data:
        try:
            return np.asarray(data["inputs"]), np.asarray(data["labels"]), int(data["seed"])
        except KeyError as exc:
            raise DatasetError(f"{path}: missing array {exc}; regenerate the data set") from exc


def split(n: int, seed: int) -> tuple[NDArrayInt, NDArrayInt]:
    """Seeded (train, held-out) index split."""
    order = np.random.default_rng([seed, 1]).permutation(n)
    cut = round(n * (1 - HELD_OUT_FRACTION))
    return order[:cut], order[cut:]


@dataclass
class RBFClassifier:
    """Radial-basis-function network: Gaussian units on k-means centres, linear
    read-out fitted by ridge regression on one-hot labels; 5 inputs, 3 classes.

    The units measure distance in ``(x, y, z - h, bearing, d_left, d_right)``
    (standardised), all computed from the 5 inputs: the torso is a vertical
    prismatic joint, so reachability depends on the object's height relative to
    the torso, ``z - h``; ``d_left`` / ``d_right`` are the distances from each
    shoulder to where the wrist must be for the grasp (the object minus 0.18 m
    along the bearing), the quantity the arm's length bounds.

    ``reach_margin`` biases the decision towards "unreachable": a reaching class
    wins only if its score beats the unreachable score by this margin.
    """

    centres: FloatArray
    width: float
    weights: FloatArray
    mean: FloatArray
    scale: FloatArray
    reach_margin: float = 0.0

    @classmethod
    def fit(
        cls,
        inputs: FloatArray,
        labels: NDArrayInt,
        *,
        n_centres: int = 3000,
        width_factor: float = 1.3,
        ridge: float = 1e-5,
        seed: int = 0,
        kmeans_iterations: int = 10,
    ) -> RBFClassifier:
        """Fit on ``inputs`` (k x 5) and ``labels`` (k,) in {0, 1, 2}."""
        rng = np.random.default_rng(seed)
        metric = _metric_inputs(inputs)
        mean, scale = metric.mean(axis=0), metric.std(axis=0)
        z = (metric - mean) / scale
        centres = z[rng.choice(len(z), n_centres, replace=False)]
        for _ in range(kmeans_iterations):
            nearest = np.argmin(_sq_dist(z, centres), axis=1)
            for k in range(n_centres):
                members = z[nearest == k]
                if len(members):
                    centres[k] = members.mean(axis=0)
        spacing = np.sqrt(np.sort(_sq_dist(centres, centres), axis=1)[:, 1]).mean()
        width = float(width_factor * spacing)
        phi = _design(z, centres, width)
        onehot = np.eye(3)[labels]
        gram = phi.T @ phi + ridge * len(z) * np.eye(phi.shape[1])
        weights = np.linalg.solve(gram, phi.T @ onehot)
        return cls(centres, width, weights, mean, scale)

    def __post_init__(self) -> None:
        # single-query fast path: the Gaussian exponent -|z - c|^2 / (2 w^2) expanded
        # as z @ (c / w^2) - |c|^2 / (2 w^2) - |z|^2 / (2 w^2), centres stored
        # transposed (one contiguous row per input dimension), read-out transposed
        gain = 1.0 / (2.0 * self.width * self.width)
        self._gain = gain
        self._projection = np.ascontiguousarray(2.0 * gain * self.centres.T)
        self._offset = -gain * np.einsum("ij,ij->i", self.centres, self.centres)
        self._readout = np.ascontiguousarray(self.weights[:-1].T)
        self._bias = np.array(self.weights[-1])

    def scores(self, inputs: FloatArray) -> FloatArray:
        """Class scores (k x 3), without ``reach_margin``; in blocks of 512 rows."""
        z_all = (_metric_inputs(np.atleast_2d(inputs)) - self.mean) / self.scale
        out = np.empty((len(z_all), 3))
        for first in range(0, len(z_all), 512):
            z = z_all[first : first + 512]
            exponent = z @ self._projection
            exponent += self._offset
            exponent -= self._gain * np.einsum("ij,ij->i", z, z)[:, None]
            out[first : first + 512] = np.exp(exponent, out=exponent) @ self._readout.T
        return out + self._bias

    def predict(self, inputs: FloatArray) -> NDArrayInt:
        """Labels (k,): 0 unreachable, 1 left, 2 right."""
        inputs = np.asarray(inputs, dtype=np.float64)
        if inputs.ndim == 1 or inputs.shape[0] == 1:
            return np.array([self.predict_one(inputs.reshape(-1))])
        s = self.scores(inputs)
        s[:, 0] += self.reach_margin
        return np.asarray(np.argmax(s, axis=1))

    def predict_one(self, row: FloatArray) -> int:
        """Label of one input row ``(x, y, z, bearing, h)``: 0, 1 or 2."""
        z = (_metric_row(row) - self.mean) / self.scale
        exponent = z @ self._projection
        exponent += self._offset
        exponent -= self._gain * float(z @ z)
        s = self._readout @ np.exp(exponent, out=exponent) + self._bias
        s[0] += self.reach_margin
        return int(np.argmax(s))

    def save(self, path: Path) -> None:
        np.savez_compressed(
            path,
            metric=np.array(METRIC),
            centres=self.centres,
            width=self.width,
            weights=self.weights,
            mean=self.mean,
            scale=self.scale,
            reach_margin=self.reach_margin,
        )

    @classmethod
    def load(cls, path: Path = WEIGHTS_PATH) -> RBFClassifier:
        if not path.is_file():
            raise DatasetError(
                f"{path} not found; retrain with `python -m skillcompose.robots.reachability train`"
            )
        with np.load(path) as d:
            metric = str(d["metric"]) if "metric" in d else "x,y,z-h,bearing"
            if metric != METRIC:
                raise DatasetError(
                    f"{path}: weights for the metric {metric!r}, this version uses "
                    f"{METRIC!r}; retrain with `python -m skillcompose.robots.reachability train`"
                )
            return cls(
                d["centres"],
                float(d["width"]),
                d["weights"],
                d["mean"],
                d["scale"],
                float(d["reach_margin"]),
            )


def _metric_inputs(inputs: FloatArray) -> FloatArray:
    """(x, y, z, bearing, h) rows -> (x, y, z - h, bearing, d_left, d_right) rows [m, rad]."""
    x, y, z, bearing, h = (inputs[:, i] for i in range(5))
    wrist_x = x - WRIST_BEHIND_TOOL_M * np.cos(bearing)
    wrist_y = y - WRIST_BEHIND_TOOL_M * np.sin(bearing)
    height = z - h
    out = [x, y, height, bearing]
    for sx, sy, sz in (SHOULDER_LEFT_M, SHOULDER_RIGHT_M):
        out.append(np.sqrt((wrist_x - sx) ** 2 + (wrist_y - sy) ** 2 + (height - sz) ** 2))
    return np.column_stack(out)


def _metric_row(row: FloatArray) -> FloatArray:
    """:func:`_metric_inputs` for one row, in scalar arithmetic (the fast path)."""
    x, y, z, bearing, h = (float(v) for v in row)
    wrist_x = x - WRIST_BEHIND_TOOL_M * math.cos(bearing)
    wrist_y = y - WRIST_BEHIND_TOOL_M * math.sin(bearing)
    height = z - h
    (lx, ly, lz), (rx, ry, rz) = SHOULDER_LEFT_M, SHOULDER_RIGHT_M
    return np.array(
        [
            x,
            y,
            height,
            bearing,
            math.sqrt((wrist_x - lx) ** 2 + (wrist_y - ly) ** 2 + (height - lz) ** 2),
            math.sqrt((wrist_x - rx) ** 2 + (wrist_y - ry) ** 2 + (height - rz) ** 2),
        ]
    )


def _sq_dist(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.maximum((a * a).sum(1)[:, None] - 2 * a @ b.T + (b * b).sum(1)[None, :], 0.0)


def _design(z: FloatArray, centres: FloatArray, width: float) -> FloatArray:
    phi = np.exp(-_sq_dist(z, centres) / (2 * width * width))
    return np.column_stack([phi, np.ones(len(z))])


@dataclass(frozen=True)
class ClassifierReport:
    """Agreement of the classifier with IK on held-out points."""

    accuracy: float
    false_reachable_rate: float
    n_held_out: int
    class_counts: tuple[int, int, int]


def evaluate(classifier: RBFClassifier, inputs: FloatArray, labels: NDArrayInt) -> ClassifierReport:
    """Accuracy and the fraction of unreachable points called reachable."""
    predicted = classifier.predict(inputs)
    unreachable = labels == 0
    false_reach = float(np.mean(predicted[unreachable] != 0)) if unreachable.any() else 0.0
    counts = np.bincount(labels, minlength=3)
    return ClassifierReport(
        float(np.mean(predicted == labels)),
        false_reach,
        len(labels),
        tuple(int(c) for c in counts),  # type: ignore[arg-type]
    )


def train_from_dataset(
    inputs: FloatArray, labels: NDArrayInt, seed: int, *, max_false_reachable: float = 0.02
) -> RBFClassifier:
    """Fit on the training split and pick ``reach_margin`` on a validation part of it."""
    train, _ = split(len(labels), seed)
    rng = np.random.default_rng([seed, 2])
    order = rng.permutation(train)
    cut = int(0.85 * len(order))
    fit_idx, val_idx = order[:cut], order[cut:]
    model = RBFClassifier.fit(inputs[fit_idx], labels[fit_idx], seed=seed)
    for margin in np.linspace(0.0, 0.5, 26):
        model.reach_margin = float(margin)
        if (
            evaluate(model, inputs[val_idx], labels[val_idx]).false_reachable_rate
            <= max_false_reachable
        ):
            break
    final = RBFClassifier.fit(inputs[train], labels[train], seed=seed)
    final.reach_margin = model.reach_margin
    return final


@dataclass
class ReachabilityModel:
    """Fast reachability queries backed by the shipped RBF classifier."""

    classifier: RBFClassifier

    @classmethod
    def load(cls, path: Path = WEIGHTS_PATH) -> ReachabilityModel:
        return cls(RBFClassifier.load(path))

    def reachable(self, position_m: FloatArray, torso_height_m: float) -> int:
        """Predicted label for an object at ``position_m`` (robot frame) [m]."""
        return int(self.classifier.predict(features_from_position(position_m, torso_height_m))[0])


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m skillcompose.robots.reachability {generate,train,evaluate}``."""
    parser = argparse.ArgumentParser(prog="python -m skillcompose.robots.reachability")
    sub = parser.add_subparsers(dest="command", required=True)
    gen = sub.add_parser("generate", help="label a seeded data set with IK")
    gen.add_argument("--n", type=int, default=16000)
    gen.add_argument("--seed", type=int, default=0)
    gen.add_argument("--workers", type=int, default=2)
    gen.add_argument("--out", type=Path, default=DATASET_PATH)
    tr = sub.add_parser("train", help="fit the RBF network on the data set")
    tr.add_argument("--data", type=Path, default=DATASET_PATH)
    tr.add_argument("--out", type=Path, default=WEIGHTS_PATH)
    ev = sub.add_parser("evaluate", help="held-out accuracy of the shipped weights")
    ev.add_argument("--data", type=Path, default=DATASET_PATH)
    ev.add_argument("--weights", type=Path, default=WEIGHTS_PATH)
    args = parser.parse_args(argv)
    if args.command == "generate":
        start = time.perf_counter()
        inputs, labels = generate_dataset(args.n, args.seed, workers=args.workers)
        save_dataset(args.out, inputs, labels, args.seed)
        counts = np.bincount(labels, minlength=3)
        print(
            f"{args.out.name}: {len(labels)} rows, classes {counts.tolist()}, "
            f"{time.perf_counter() - start:.1f} s"
        )
        return 0
    inputs, labels, seed = load_dataset(args.data)
    _, held_out = split(len(labels), seed)
    if args.command == "train":
        classifier = train_from_dataset(inputs, labels, seed)
        classifier.save(args.out)
    else:
        classifier = RBFClassifier.load(args.weights)
    report = evaluate(classifier, inputs[held_out], labels[held_out])
    print(
        f"held-out: {report.n_held_out} points, classes {list(report.class_counts)}, "
        f"accuracy {report.accuracy:.4f}, unreachable called reachable "
        f"{report.false_reachable_rate:.4f}, margin {classifier.reach_margin:.2f}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
