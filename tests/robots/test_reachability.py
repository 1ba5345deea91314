from __future__ import annotations

import numpy as np
import pytest

from robots.model import RobotModel
from robots.reachability import (
    ClassifierReport,
    RBFClassifier,
    ReachabilityModel,
    ReachabilityOracle,
    evaluate,
    generate_dataset,
    load_dataset,
    split,
)

pytestmark = pytest.mark.kinematics


def test_shipped_rows_regenerate_identically() -> None:
    inputs, labels, seed = load_dataset()
    rows = slice(0, 60)
    new_inputs, new_labels = generate_dataset(len(labels), seed, rows=rows)
    np.testing.assert_array_equal(new_inputs, inputs[rows])
    np.testing.assert_array_equal(new_labels, labels[rows])


def _held_out_report() -> ClassifierReport:
    inputs, labels, seed = load_dataset()
    _, held_out = split(len(labels), seed)
    return evaluate(RBFClassifier.load(), inputs[held_out], labels[held_out])


def test_classifier_on_the_held_out_set() -> None:
    report = _held_out_report()
    assert report.n_held_out >= 5000
    assert min(report.class_counts) > 500
    # measured: 97.51 % agreement, 1.71 % false "reachable" (guards against regressions)
    assert report.accuracy >= 0.97, report
    assert report.false_reachable_rate <= 0.02, report


@pytest.mark.xfail(strict=True, reason="target 98 % not met yet: 97.5 % measured (see docs)")
def test_classifier_meets_the_98_percent_target() -> None:
    assert _held_out_report().accuracy >= 0.98


def test_oracle_labels_make_sense(pr2: RobotModel) -> None:
    oracle = ReachabilityOracle(pr2)
    assert oracle.label(np.array([0.6, 0.25, 0.8]), 0.1) == 1
    assert oracle.label(np.array([0.6, -0.25, 0.8]), 0.1) == 2
    assert oracle.label(np.array([1.5, 0.0, 0.8]), 0.1) == 0
    model = ReachabilityModel.load()
    assert model.reachable(np.array([0.6, 0.25, 0.8]), 0.1) == 1
    assert model.reachable(np.array([1.5, 0.0, 0.8]), 0.1) == 0
