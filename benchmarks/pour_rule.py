"""The abstract pouring rule against the physics: where the sim and kinematic skills say the
water goes, and where it goes in MuJoCo.

The abstract pour skills decide with a rule (:func:`skillcompose.skills.pour_geometry.\
water_after_motion`) whether a held jug's water stays in, lands in the glass or spills. An
FSA evolved on them pours on the dynamic backend only where the rule agrees with the
physics, so this script measures that agreement on poses the PR2 model can take (the pour
task's ``reach=pr2`` check), each run through the dynamic twins from the task's world:
RecogniseObject, MoveToObject, GraspObject, MoveGripperToParam to the spout position,
RotateGripperToParam to the rotation (from upright, as an FSA that pours does)::

    python benchmarks/pour_rule.py                      # 300 poses of each sample, 2 workers
    python benchmarks/pour_rule.py --poses 20 --out /tmp/pr   # a quick look

Two samples, drawn from ``--seed``:

- **near the glass**: spout within 6 cm of the rim's centre horizontally, 3.5 to 15 cm
  above it; roll, pitch and yaw uniform over the skill's ranges, tilted at least 60°, the
  jug clear of the glass all the way there (as the abstract skills turn it);
- **the rule pours**: the same, kept only where the rule says the water lands in the
  glass: how often it really does is what an FSA evolved on the rule can expect.

For each, the rule's answer beside MuJoCo's (``glass`` when at least 80 % of the particles
end in the glass), and the same for the rule of the earlier pour world (tilt 60° to 120°,
spout within 4 cm of the centre and 0 to 15 cm above the rim, yaw free), kept here as a
baseline. It also measures how far the jug slides in the fingers as it tips
(:data:`~skillcompose.skills.pour_geometry.JUG_SLIP_M`). Writes ``pour_rule.md`` and
``pour_rule.json`` in ``--out`` (default ``docs/results``).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import platform
import sys
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from skillcompose.arguments import output_folder
from skillcompose.files import atomic_write
from skillcompose.skills import pour_geometry as pg
from skillcompose.stats import rate_bounds

ROOT = Path(__file__).resolve().parents[1]
Pose = tuple[pg.Vec3, pg.Vec3]
_UPRIGHT = pg.rpy_matrix((0.0, 0.0, 0.0))


@functools.cache
def _start() -> tuple[pg.Vec3, pg.Vec3, pg.Vec3]:
    """The pour task's world: the jug's spout, the glass's rim, the gripper's home [m]."""
    from skillcompose.registry import import_target

    task = import_target("examples.pour_water")
    return (task.JUG_SPOUT_WORLD, task.GLASS_RIM_WORLD, task.GRIPPER_HOME_WORLD)


def rule(pose: Pose, glass: pg.Vec3) -> str:
    """The abstract skills' answer: ``glass``, ``spilled`` or ``jug`` (stays in)."""
    position, rotation = pose
    water = pg.water_after_motion(position, _UPRIGHT, position, pg.rpy_matrix(rotation), glass)
    return water or "jug"


def earlier_rule(pose: Pose, glass: pg.Vec3) -> str:
    """The earlier pour world's rule: tilt 60° to 120°, the spout (the grasp point) within
    4 cm of the rim's centre horizontally and 0 to 15 cm above it, yaw free."""
    position, rotation = pose
    t = pg.tilt(rotation)
    if t < math.pi / 3:
        return "jug"
    dx, dy, dz = (position[k] - glass[k] for k in range(3))
    inside = dx * dx + dy * dy <= 0.04**2 and 0.0 <= dz <= 0.15
    return "glass" if t <= 2 * math.pi / 3 and inside else "spilled"


def sample(rng: np.random.Generator, n: int, pours_only: bool) -> list[Pose]:
    """``n`` poses near the glass that the PR2 model takes (see the module docstring)."""
    from skillcompose.skills.pour_robot import pr2_can_pour

    start = _start()
    glass = start[1]
    poses: list[Pose] = []
    while len(poses) < n:
        r, a = 0.06 * math.sqrt(rng.random()), rng.uniform(-math.pi, math.pi)
        position = (glass[0] + r * math.cos(a), glass[1] + r * math.sin(a),
                    glass[2] + rng.uniform(0.035, 0.15))
        rotation = tuple(float(v) for v in rng.uniform(-math.pi, math.pi, 3))
        pose: Pose = (position, rotation)  # type: ignore[assignment]
        if pg.tilt(rotation) < math.pi / 3 or pg.held_jug_turns_into_glass(
                position, _UPRIGHT, pg.rpy_matrix(rotation), glass):
            continue  # the abstract skills would not turn the jug into the glass
        if pours_only and rule(pose, glass) != "glass":
            continue
        if pr2_can_pour(start, position, pose[1]):
            poses.append(pose)
    return poses


def physics(pose: Pose) -> dict[str, Any]:
    """Run the dynamic twins to ``pose`` and say where the water went and where the jug sits
    in the fingers."""
    from skillcompose.skills import pour_robot, pour_water_dynamic

    position, rotation = pose
    registry, world = pour_robot._dynamic()
    bb = pour_robot._start_board(_start())
    pour_water_dynamic.start_episode(world, bb)  # type: ignore[arg-type]
    took = pour_robot._take_pose(registry, "dynamic", bb, position, rotation)
    sim = world.current(bb, "pour_rule")  # type: ignore[attr-defined]
    jug = sim.object_transform("jug")
    r = np.array(pg.rpy_matrix(rotation))
    centre = np.array(position) - r[:, 2] * pg.JUG_GRASP_ABOVE_CENTRE_M
    slip = r.T @ (jug.translation - centre)
    glass = sim.object_transform("glass")
    return {"position": position, "rotation": rotation, "took": took,
            "reason": bb.get("last_failure_reason"),
            "water": bb["water"], "in_glass": sim.particles_in("glass"),
            "in_jug": sim.particles_in("jug"),
            "glass_upright": bool(glass.rotation[2, 2] > 0.9),
            "slip_along_axis_m": float(slip[2]), "tilt_rad": pg.tilt(rotation)}


def cause(row: dict[str, Any]) -> str:
    """Why MuJoCo did not pour where the rule said it would."""
    if not row.get("glass_upright", True):
        return "the arm knocked the glass over"
    if row["water"] == "jug":
        return "the water stayed in the jug"
    if row["in_glass"] > 0:
        return "part of the water missed the glass (fewer than 80 % in it)"
    return "all of the water missed the glass"


def confusion(rows: list[dict[str, Any]], judge: str) -> dict[str, Any]:
    """How the ``judge`` rule's answers meet MuJoCo's on ``rows``."""
    table: Counter[str] = Counter()
    for row in rows:
        table[f"{row[judge]} / {'glass' if row['water'] == 'glass' else 'not'}"] += 1
    said = table["glass / glass"] + table["glass / not"]
    poured = table["glass / glass"] + table["jug / glass"] + table["spilled / glass"]
    return {"table": dict(table), "said_glass": said, "right_when_said": table["glass / glass"],
            "poured": poured}


def _share(k: int, n: int) -> str:
    if n == 0:
        return "-"
    low, high = rate_bounds(k, n, 0.025)
    return f"{k} / {n} = {100 * k / n:.1f} % [{100 * low:.1f}, {100 * high:.1f}]"


def report(result: dict[str, Any]) -> str:
    lines = [
        "# The abstract pouring rule against the physics",
        "",
        f"Written by `benchmarks/pour_rule.py {result['command']}`, seed {result['seed']}, "
        f"{result['workers']} workers on a shared {os.cpu_count()}-core machine "
        f"({platform.machine()}, Python {platform.python_version()}), "
        f"{result['wall_s']:.0f} s. Each pose (one the PR2 model takes) is run through the "
        "dynamic twins from the pour task's world: grasp, move the spout there, rotate from "
        "upright. MuJoCo's answer is `glass` when at least 80 % of the particles end in the "
        "glass. `rule` is the abstract skills' rule now "
        "(`skillcompose.skills.pour_geometry.water_after_motion`), `earlier rule` the one of "
        "the earlier pour world (tilt 60°-120°, spout within 4 cm of the centre and "
        "0-15 cm above the rim). Shares with 95 % Clopper-Pearson intervals.",
        "",
        "| sample | poses | judge | said glass | MuJoCo poured of those | MuJoCo poured, "
        "judge said not |",
        "|---|---|---|---|---|---|",
    ]
    for name, block in result["samples"].items():
        n = len(block["rows"])
        for judge in ("rule", "earlier_rule"):
            c = block[judge]
            missed = c["poured"] - c["right_when_said"]
            lines.append(f"| {name} | {n} | {judge.replace('_', ' ')} | {c['said_glass']} | "
                         f"{_share(c['right_when_said'], c['said_glass'])} | "
                         f"{missed} of {c['poured']} poured |")
    lines += ["", "## Where the rule and MuJoCo differ", ""]
    for name, block in result["samples"].items():
        table = block["rule"]["table"]
        cells = ", ".join(f"{k}: {v}" for k, v in sorted(table.items()))
        lines.append(f"- **{name}** (rule / MuJoCo): {cells}")
    lines += ["", "Where the rule said `glass` and MuJoCo did not pour, by cause (both "
              "samples):", ""]
    causes = Counter(cause(row) for block in result["samples"].values()
                     for row in block["rows"]
                     if row["rule"] == "glass" and row["water"] != "glass")
    lines += [f"- {k}: {v}" for k, v in causes.most_common()] or ["- none"]
    lines += ["", "## How far the jug slides in the fingers", "",
              "The jug's centre along its own axis, from where the tool frame holds it, after "
              "the rotation (all poses of both samples), by tilt:", "",
              "| tilt | poses | mean [cm] | std [cm] |", "|---|---|---|---|"]
    for band in result["slip"]:
        lines.append(f"| {band['from_deg']}°-{band['from_deg'] + 15}° | {band['n']} | "
                     f"{100 * band['mean_m']:.2f} | {100 * band['std_m']:.2f} |")
    lines += ["", f"The rule takes {100 * pg.JUG_SLIP_M:.1f} cm (`JUG_SLIP_M`).", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=300, help="poses per sample")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=output_folder, default=ROOT / "docs" / "results")
    args = parser.parse_args(argv)
    if args.poses < 1 or args.workers < 1:
        parser.error("--poses and --workers: expected at least 1")
    rng = np.random.default_rng(args.seed)
    glass = _start()[1]
    start = time.perf_counter()
    samples: dict[str, Any] = {}
    with ProcessPoolExecutor(args.workers) as pool:
        for name, only in (("near the glass", False), ("the rule pours", True)):
            poses = sample(rng, args.poses, only)
            rows = list(pool.map(physics, poses, chunksize=4))
            for row, pose in zip(rows, poses, strict=True):
                row["rule"] = rule(pose, glass)
                row["earlier_rule"] = earlier_rule(pose, glass)
            samples[name] = {"rows": rows, "rule": confusion(rows, "rule"),
                             "earlier_rule": confusion(rows, "earlier_rule")}
            print(f"{name}: {len(rows)} poses, {time.perf_counter() - start:.0f} s",
                  file=sys.stderr)
    every = [row for block in samples.values() for row in block["rows"]]
    slip = []
    for low in range(60, 180, 15):
        values = [r["slip_along_axis_m"] for r in every
                  if low <= math.degrees(r["tilt_rad"]) < low + 15]
        if values:
            slip.append({"from_deg": low, "n": len(values), "mean_m": float(np.mean(values)),
                         "std_m": float(np.std(values))})
    result = {"command": " ".join(argv if argv is not None else sys.argv[1:]),
              "seed": args.seed, "workers": args.workers, "poses": args.poses,
              "wall_s": time.perf_counter() - start, "samples": samples, "slip": slip}
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write(args.out / "pour_rule.json", (json.dumps(result, indent=1) + "\n").encode())
    atomic_write(args.out / "pour_rule.md", report(result).encode())
    print(report(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
