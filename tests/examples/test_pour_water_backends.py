"""The pour-water task's ``backend`` setting: sim (default), kinematic and dynamic, and what
``p_fail`` means on each."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from examples import kinematic_pour
from examples import pour_water as ex
from skillcompose import load_fsa
from skillcompose.cli import main
from skillcompose.task import TaskError, load_task

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = ROOT / "examples" / "pour_water_reference.fsa.yaml"


def test_sim_is_the_default_and_keeps_its_settings() -> None:
    task = load_task("examples.pour_water")
    assert task.backend == "sim"
    assert dict(task.settings) == {"p_fail": 0.2, "trials": 1, "step_limit": 20, "reach": "pr2"}


def test_p_fail_is_the_sim_backends_and_refused_elsewhere() -> None:
    with pytest.raises(TaskError, match="backend='warp' must be one of sim, kinematic, dynamic"):
        ex.make_task(backend="warp")
    for backend in ("kinematic", "dynamic"):
        with pytest.raises(TaskError, match=f"p_fail=0.2 is the sim backend's.*{backend}"):
            ex.make_task(backend=backend, p_fail=0.2)


@pytest.mark.kinematics
def test_kinematic_backend_is_what_kinematic_pour_runs() -> None:
    task = load_task("examples.pour_water", backend="kinematic")
    assert task.backend == "kinematic"
    assert dict(task.settings) == {"backend": "kinematic", "p_fail": 0.0, "trials": 1,
                                   "step_limit": 20}
    assert task.ref is not None and task.ref.build().settings == task.settings
    old = kinematic_pour.make_task()
    assert old.name == "kinematic_pour" and old.backend == "kinematic"
    assert old.skills == task.skills
    assert task.evaluate(task.compile(load_fsa(REFERENCE)), 0, 2) == 0.0


@pytest.mark.physics
@pytest.mark.kinematics
@pytest.mark.slow
def test_the_reference_runs_from_the_command_line_on_dynamic(
        capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("mujoco")
    code = main(["run", str(REFERENCE), "--task", "examples.pour_water", "--set",
                 "backend=dynamic", "--seed", "5", "--json", "-q"])
    assert code == 0
    document = json.loads(capsys.readouterr().out)
    assert document["backend"] == "dynamic"
    assert document["outcomes"] == {"success": 1}
