"""Replay one kinematic or dynamic run as pictures: the PR2, the table and the objects.

::

    python -m skillcompose.skills.replay examples/stacking_reference.fsa.yaml --task
    examples.stacking \\
        --set backend=kinematic --seed 3 --out replay/

writes ``replay/step_00.png`` (the world before the first step), one ``step_NN.png`` after
each step of the run (titled with the state, its skill and the outcome), ``strip.png`` (all
frames side by side) and ``replay.gif``. The world and the run are the ones
``skillcompose run FILE --task ... --trace --seed N`` prints: the first trial of seed N.
The run is advanced one step at a time by the tick-wise executor (``CompiledFSA.start``), so
the frames show the blackboard exactly as each step left it.

On the dynamic backend (``--set backend=dynamic``) the pictures are of the simulation
itself, every ``--every`` seconds of simulated time (default 0.25 s): the robot as its
servos moved it and the objects as physics moved them (tipped objects drawn by their
heading; water particles as red crosses), each titled with the simulated time and the state
running then, so a push or a topple is visible between two steps. ``replay.gif`` plays them
at four times real time; ``strip.png`` shows at most 16 of them, evenly spaced.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from skillcompose import RUNNING, Blackboard, load_fsa, load_task
from skillcompose.executor import compile_fsa, trial_rngs
from skillcompose.robots.collision import Box, Scene
from skillcompose.robots.model import TUCKED_ARM_RAD, RobotModel, RobotPose, load_pr2
from skillcompose.robots.render import render_configuration, scene_camera
from skillcompose.skills.kinematic_world import DEFAULT_OBJECT_HALF_EXTENTS_M, scene_world
from skillcompose.task import parse_settings

__all__ = ["Replay", "main", "replay", "robot_pose", "world_scene"]


@dataclass(frozen=True)
class Replay:
    """What :func:`replay` wrote and how the run ended."""

    outcome: str
    steps: int
    frames: tuple[Path, ...]
    strip: Path
    gif: Path


def robot_pose(bb: Blackboard) -> RobotPose:
    """The PR2's configuration on a blackboard (the kinematic skills' keys; tucked arms and
    the origin when absent)."""
    base = bb.get("base_pose_world") or (0.0, 0.0, 0.0)
    arms = {arm: tuple(float(v) for v in bb.get(f"q_{arm}_arm_rad") or TUCKED_ARM_RAD[arm])
            for arm in ("left", "right")}
    return RobotPose((float(base[0]), float(base[1]), float(base[2])),
                     float(bb.get("torso_height_m", 0.0)), arms)  # type: ignore[arg-type]


def world_scene(bb: Blackboard) -> Scene:
    """The table, obstacles and every object on a blackboard, as boxes."""
    boxes = list(scene_world(bb).boxes)
    sizes: Mapping[str, Sequence[float]] = bb.get("object_half_extents_m") or {}
    positions: Mapping[str, Sequence[float]] = bb.get("object_positions_world") or {}
    for name, p in positions.items():
        half = tuple(float(v) for v in sizes.get(name, DEFAULT_OBJECT_HALF_EXTENTS_M))
        boxes.append(Box((float(p[0]), float(p[1]), float(p[2])), half, 0.0,  # type: ignore[arg-type]
                         str(name)))
    single = bb.get("object_position_world")
    if single is not None:
        boxes.append(Box(tuple(float(v) for v in single), (0.03, 0.03, 0.10), 0.0,  # type: ignore[arg-type]
                         "object"))
    return Scene(tuple(boxes))


def replay(
    fsa_path: str | Path, task_target: str, out_dir: str | Path, *, seed: int = 0,
    settings: Mapping[str, Any] | None = None, every_s: float = 0.25,
) -> Replay:
    """Run ``fsa_path`` once on ``task_target`` (first trial of ``seed``) and draw each step
    (on the dynamic backend: every ``every_s`` of simulated time) into ``out_dir``; see the
    module's docstring."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    task = load_task(task_target, **dict(settings or {}))
    compiled = compile_fsa(load_fsa(fsa_path), task.registry, task.backend)
    rng = next(iter(trial_rngs(seed, 1)))
    if task.backend == "dynamic":
        return _replay_dynamic(task, compiled, rng, out, every_s)
    bb = task.setup(rng)
    model = load_pr2()
    # the run first, then the pictures, all from one camera that shows every step
    steps = [(robot_pose(bb), world_scene(bb), "start", out / "step_00.png")]
    run = compiled.start(bb, rng, trace=True)
    for last in _steps(run):
        steps.append((robot_pose(bb), world_scene(bb), _title(last),
                      out / f"step_{last.step:02d}.png"))
    camera = scene_camera(model, [pose for pose, *_ in steps], steps[0][1])
    frames = [render_configuration(model, pose, path, scene=scene, title=title, camera=camera)
              for pose, scene, title, path in steps]
    result = run.result
    return Replay(result.outcome, result.steps, tuple(frames), _strip(frames, out / "strip.png"),
                  _gif(frames, out / "replay.gif"))


def _steps(run: Any) -> Iterator[Any]:
    """Tick ``run`` to its end, giving the trace's last step after each tick."""
    status = RUNNING
    while status == RUNNING:
        status = run.tick()
        if not run.trace:
            return
        yield run.trace[-1]


def _title(step: Any) -> str:
    return f"step {step.step}: {step.state} ({step.skill}) -> {step.outcome}"


def _replay_dynamic(task: Any, compiled: Any, rng: Any, out: Path, every_s: float) -> Replay:
    """The run on the dynamic backend, drawn from the simulation's own recording."""
    from skillcompose.robots.physics import PoseRecorder
    from skillcompose.skills.dynamic_world import world_of

    world = world_of(task.registry)
    if world is None:
        raise ValueError(f"task {task.name}: its registry has no dynamic skills bound to a "
                         "world; give a task that supports backend=dynamic")
    recorder = PoseRecorder(every_s=every_s)
    world.recorder = recorder
    try:
        bb = task.setup(rng)
        run = compiled.start(bb, rng, trace=True)
        steps: list[tuple[float, str]] = []  # (simulated time at its end, title)
        for last in _steps(run):
            ended = world.physics.time_s if world.physics is not None else 0.0
            steps.append((ended, _title(last)))
    finally:
        world.recorder = None
    model = load_pr2()
    scenes = [_recorded_scene(world, recorder, k) for k in range(len(recorder.times_s))]
    camera = scene_camera(model, list(recorder.robot[:: max(1, len(recorder.robot) // 8)]),
                          scenes[0][0])
    frames = []
    for k, (scene, particles) in enumerate(scenes):
        t = recorder.times_s[k]
        title = next((title for ended, title in steps if t <= ended + 1e-9), "after the run")
        frames.append(_frame(model, recorder.robot[k], out / f"frame_{k:03d}.png", scene,
                             particles, f"t = {t:.2f} s   {title}", camera))
    result = run.result
    shown = frames[:: max(1, -(-len(frames) // 16))]
    return Replay(result.outcome, result.steps, tuple(frames), _strip(shown, out / "strip.png"),
                  _gif(frames, out / "replay.gif", duration_ms=max(20, round(every_s * 250))))


def _frame(model: RobotModel, pose: RobotPose, path: Path, scene: Scene, particles: Any,
           title: str, camera: Any) -> Path:
    return render_configuration(model, pose, path, scene=scene, title=title, camera=camera,
                                targets_m=list(particles))


def _recorded_scene(world: Any, recorder: Any, k: int) -> tuple[Scene, Any]:
    """Sample ``k`` of the recording as boxes (the table, each object by its heading) and the
    water particles' positions."""
    import math

    import numpy as np

    spec = world.physics.physics.scene
    boxes = [] if spec.table is None else [spec.table]
    positions, quaternions = recorder.positions[k], recorder.quaternions[k]
    for row, name in enumerate(recorder.objects):
        obj = spec.object(name)
        size = obj.size_m
        half = (size[0], size[0], size[1]) if obj.shape == "cylinder" else \
            (size[0],) * 3 if obj.shape == "sphere" else tuple(size)
        w, x, y, z = (float(v) for v in quaternions[row])
        yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        p = positions[row]
        boxes.append(Box((float(p[0]), float(p[1]), float(p[2])), half, yaw, name))
    particles = [np.asarray(positions[row]) for row, body in enumerate(recorder.bodies)
                 if body.startswith("particle_")]
    return Scene(tuple(boxes)), particles


def _strip(frames: Sequence[Path], path: Path) -> Path:
    """All frames in a grid of up to four columns."""
    from matplotlib.image import imread

    cols = min(4, len(frames))
    rows = (len(frames) + cols - 1) // cols
    fig = Figure(figsize=(4 * cols, 3.5 * rows))
    for k, frame in enumerate(frames):
        ax = fig.add_subplot(rows, cols, k + 1)
        ax.imshow(imread(frame))
        ax.set_axis_off()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return path


def _gif(frames: Sequence[Path], path: Path, duration_ms: int = 900) -> Path:
    from PIL import Image

    images = [Image.open(f).convert("P", palette=Image.Palette.ADAPTIVE) for f in frames]
    images[0].save(path, save_all=True, append_images=images[1:], duration=duration_ms,
                   loop=0)
    return path


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m skillcompose.skills.replay",
                                description=__doc__.split("\n")[0])
    p.add_argument("fsa", help="the FSA file to run")
    p.add_argument("--task", required=True, help="task module, e.g. examples.stacking")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="task setting, e.g. backend=kinematic (repeatable)")
    p.add_argument("--seed", type=int, default=0, help="the run's seed (default 0)")
    p.add_argument("--out", type=Path, required=True, help="directory for the frames")
    p.add_argument("--every", type=float, default=0.25, metavar="SECONDS",
                   help="dynamic backend: simulated seconds between frames (default 0.25)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    result = replay(args.fsa, args.task, args.out, seed=args.seed,
                    settings=parse_settings(args.set), every_s=args.every)
    print(f"{result.outcome} after {result.steps} steps; wrote {len(result.frames)} frames, "
          f"{result.strip} and {result.gif}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
