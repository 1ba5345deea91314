"""The replay command on the dynamic backend: frames of the simulation at sub-steps."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import pytest

from examples import pour_water as task_module

EXAMPLES = Path(task_module.__file__).parent

pytestmark = [pytest.mark.kinematics, pytest.mark.physics]


@pytest.mark.slow  # one pour in MuJoCo (about 23 simulated seconds) and six pictures
def test_a_dynamic_replay_draws_the_simulation_every_few_seconds(tmp_path: Path) -> None:
    from skillcompose.skills.replay import replay

    every = 5.0
    result = replay(EXAMPLES / "pour_water_reference.fsa.yaml", "examples.pour_water",
                    tmp_path, seed=0, settings={"backend": "dynamic"}, every_s=every)
    assert result.outcome == "success" and result.steps == 6
    # a frame at t = 0 and one every 5 s of the run: the pour takes 20 to 30 simulated s
    assert 5 <= len(result.frames) <= 7
    assert [f.name for f in result.frames] == [f"frame_{k:03d}.png"
                                               for k in range(len(result.frames))]
    assert all(f.stat().st_size > 10_000 for f in result.frames)
    assert result.strip.is_file() and result.gif.is_file()


def test_a_recorded_object_is_drawn_by_its_heading() -> None:
    import numpy as np

    from skillcompose.robots.physics import PoseRecorder
    from skillcompose.robots.physics_model import ObjectSpec, SceneSpec
    from skillcompose.skills.replay import _recorded_scene

    scene_spec = SceneSpec(objects=(ObjectSpec("box", "box", (0.03, 0.02, 0.06), 0.3),))
    world = SimpleNamespace(physics=SimpleNamespace(physics=SimpleNamespace(scene=scene_spec)))

    recorder = PoseRecorder()
    recorder.objects, recorder.bodies = ("box",), ("box", "particle_0")
    half = math.pi / 6  # a quarter turn about z by half angles: yaw = pi / 3
    recorder.positions = [np.array([[0.5, 0.1, 0.8], [0.4, 0.0, 0.9]])]
    recorder.quaternions = [np.array([[math.cos(half), 0, 0, math.sin(half)], [1, 0, 0, 0]])]
    scene, particles = _recorded_scene(world, recorder, 0)
    box = next(b for b in scene.boxes if b.name == "box")
    assert box.yaw_rad == pytest.approx(math.pi / 3)
    assert box.half_extents_m == (0.03, 0.02, 0.06) and box.center_m == (0.5, 0.1, 0.8)
    assert len(particles) == 1 and list(particles[0]) == [0.4, 0.0, 0.9]
