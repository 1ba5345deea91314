"""The kinematic pour-water example runs (small settings)."""

from __future__ import annotations

import pytest

from examples import kinematic_pour
from skillcompose import compile_fsa, load_fsa
from skillcompose.task import TaskError

pytestmark = pytest.mark.kinematics


def test_reference_runs_through_the_example(capsys: pytest.CaptureFixture[str]) -> None:
    assert kinematic_pour.main(["--runs", "3", "--seed", "1"]) == 0
    assert "solved 3/3" in capsys.readouterr().out


def test_task_scores_the_reference_on_the_kinematic_backend() -> None:
    task = kinematic_pour.make_task(trials=2)
    assert task.backend == "kinematic"
    compiled = compile_fsa(load_fsa(kinematic_pour.REFERENCE_FSA), task.registry, task.backend)
    assert compiled.backend == "kinematic"
    result = task.evaluate(compiled, 0, 2)
    assert result == 0.0
    with pytest.raises(TaskError, match="trials"):
        kinematic_pour.make_task(trials=0)
