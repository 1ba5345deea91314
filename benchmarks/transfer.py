"""Transfer: the shipped FSA files on the three backends side by side (sim, kinematic, dynamic).

For each experiment the shipped file runs unchanged on ``sim`` (fresh abstract worlds), and
on ``kinematic`` and ``dynamic`` over the *same* judged worlds (same seeds: the kinematic
run and the physics run of world k start from one blackboard); the report gives the
success of each backend, the dynamic failures by cause, episodes per second and, on
``dynamic``, simulated seconds per wall second::

    python benchmarks/transfer.py                         # writes docs/results/transfer.*
    python benchmarks/transfer.py --push 40 --stacking 20 --out /tmp/transfer

Experiments are entries of :data:`EXPERIMENTS` (task module, file, settings, seeds and how
a run counts as a success); another experiment (pouring water) adds one there.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from skillcompose import Blackboard, Registry, RunResult, compile_fsa, load_fsa
from skillcompose.arguments import output_folder
from skillcompose.executor import trial_rngs
from skillcompose.skills.kinematic_world import REASON_KEY
from skillcompose.task import Task, load_task

ROOT = Path(__file__).resolve().parents[1]
BACKENDS = ("sim", "kinematic", "dynamic")


@dataclass(frozen=True)
class Experiment:
    """One row group of the report: a task, its shipped file and how it is judged.

    Attributes:
        name: the experiment's name in the report.
        task: the task module.
        fsa: the shipped FSA file (relative to the repository).
        settings: the task's settings on every backend (``backend`` added per backend).
        robot_settings: added on ``kinematic`` and ``dynamic`` (e.g. ``judge``: the worlds
            the paper tested on the robot).
        seed: the first world's seed on ``kinematic`` and ``dynamic``; ``sim`` uses
            ``sim_seed``.
        success: whether a run's fitness is a success.
        default_n: worlds per backend.
        target: the share of dynamic successes the issue asks for.
        paper: the paper's real-robot result, in words.
    """

    name: str
    task: str
    fsa: str
    settings: dict[str, Any]
    robot_settings: dict[str, Any]
    seed: int
    sim_seed: int
    success: Callable[[float], bool]
    default_n: int
    target: float
    paper: str
    extra: dict[str, Any] = field(default_factory=dict)


EXPERIMENTS: dict[str, Experiment] = {
    "push": Experiment(
        "moving to push (section 4.2)", "examples.move_to_push",
        "examples/move_to_reach.fsa.yaml", {"network": "layered"}, {"judge": True},
        seed=20_000, sim_seed=10_000, success=lambda f: f == 1.0, default_n=395, target=0.9,
        paper="323/395 = 82 % pushed on the real PR2"),
    "stacking": Experiment(
        "stacking (section 4.3)", "examples.stacking", "docs/results/stacking_best.fsa.yaml",
        {"trials": 1}, {}, seed=30_000, sim_seed=10_000, success=lambda f: f == 0.0,
        default_n=100, target=0.9, paper="20/20 stacked on the real PR2"),
}
"""The experiments; pouring water joins as another entry."""


CAUSES = {
    "unreachable": "no IK solution: for push, the finger tips on the object's face (or a "
                   "straight stroke from there) at every height, with either arm; for "
                   "stacking, the kinematic plan itself, made from the simulated poses",
    "joint_limits": "as unreachable, only outside the joint limits",
    "collision": "every IK solution of a goal or waypoint hits the table (the dynamic push "
                 "aims lower than the kinematic one, and its strokes are also checked "
                 "against the simulated table), or a stacking goal would sink the held "
                 "object into the other as they now stand",
    "blocked": "an arm or the base stopped short of its goal: it struck the table or an "
               "object on the way (joint-space motion between approach or stacking "
               "waypoints)",
    "hit_table": "the robot ended a motion touching the table",
    "toppled": "the pushed object tipped over instead of sliding",
    "not_moved": "the pushed object moved less than 5 cm",
    "missed": "the fingers closed on nothing or on the other object",
    "dropped": "the held object slipped out of the fingers while carried",
    "failure": "the run ended with CheckSuccess's failure: the objects not stacked upright "
               "after the release",
    "timeout": "the step limit ended the run (a skill failing again and again)",
}
"""What each failure cause means, for the report."""


@dataclass
class Measured:
    successes: int = 0
    episodes: int = 0
    wall_s: float = 0.0
    sim_s: float = 0.0
    failures: Counter[str] = field(default_factory=Counter)

    def as_dict(self) -> dict[str, Any]:
        return {"successes": self.successes, "episodes": self.episodes,
                "wall_s": round(self.wall_s, 3), "sim_s": round(self.sim_s, 3),
                "failures": dict(sorted(self.failures.items()))}


def _task(exp: Experiment, backend: str) -> Task:
    settings = {**exp.settings, "backend": backend}
    if backend != "sim":
        settings.update(exp.robot_settings)
    return load_task(exp.task, **settings)


def measure(exp: Experiment, backend: str, n: int, *, progress: bool = False) -> Measured:
    """The shipped file of ``exp`` on ``backend`` over ``n`` worlds."""
    task = _task(exp, backend)
    compiled = compile_fsa(load_fsa(ROOT / exp.fsa), task.registry, backend)
    world = None
    if backend == "dynamic":
        from skillcompose.skills.dynamic_world import world_of

        world = world_of(task.registry)
    seed = exp.sim_seed if backend == "sim" else exp.seed
    out = Measured()
    t0 = time.perf_counter()
    for k, rng in enumerate(trial_rngs(seed, n)):
        bb = task.setup(rng)
        result = compiled.run(bb, rng, trace=True)
        ok = exp.success(task.score(result, bb))
        out.successes += ok
        out.episodes += 1
        if world is not None and world.physics is not None:
            out.sim_s += world.physics.time_s
        if not ok:
            out.failures[cause(result, bb, task.registry, backend)] += 1
        if progress:
            print(f"{exp.name} {backend} {k}: {'ok' if ok else 'no'}", file=sys.stderr,
                  flush=True)
    out.wall_s = time.perf_counter() - t0
    return out


def cause(result: RunResult, bb: Blackboard, registry: Registry, backend: str) -> str:
    """Why a traced run failed: the reason (:data:`REASON_KEY`) when the last step that
    failed gave it, else that step's outcome (``failure`` of CheckSuccess, say), or
    ``timeout`` when the step limit ended the run. The last failing step gave the reason when
    its skill writes one (rewriting the same reason changes nothing a trace can see), or when
    a failing step wrote it last and only that state failed after it (a nested FSA failing
    again and again). A reason noted by a step that went on, or by one the FSA recovered
    from, is not the cause."""
    steps = result.trace or ()
    failed = [i for i, step in enumerate(steps) if step.outcome != "success"]
    if not failed:
        return result.outcome
    last = steps[failed[-1]]
    if bb.get(REASON_KEY):
        if REASON_KEY in registry.resolve(last.skill, backend).spec.writes:
            return str(bb[REASON_KEY])
        written = [i for i, step in enumerate(steps) if REASON_KEY in step.changes]
        if written and steps[written[-1]].outcome != "success" and \
                all(steps[i].state == steps[written[-1]].state for i in failed
                    if i >= written[-1]):
            return str(bb[REASON_KEY])
    return "timeout" if result.outcome == "timeout" else last.outcome


def report(results: dict[str, dict[str, Measured]], sizes: dict[str, int], total_s: float,
           command: str) -> str:
    lines = [
        "# Transfer: the shipped files on sim, kinematic and dynamic",
        "",
        "Written by `benchmarks/transfer.py`; every number below was measured by that run. "
        "Do not edit by hand: rerun the script.",
        "",
        f"Command: `{command}`  ",
        f"Machine: {os.cpu_count()} CPUs (shared), {platform.machine()}, Python "
        f"{platform.python_version()}; one process. Total time: {total_s / 60:.1f} min.",
        "",
        "`sim`: the abstract skills on fresh worlds. `kinematic`: the PR2 model (IK, box "
        "collisions). `dynamic`: the kinematic plans executed by the PR2 in MuJoCo and judged "
        "from the simulated state (docs/robots.md, \"The dynamic backend: push and "
        "stacking\"). Kinematic and dynamic run the same worlds (same seeds).",
        "",
    ]
    for key, per in results.items():
        exp = EXPERIMENTS[key]
        n = sizes[key]
        lines += [f"## {exp.name}", "",
                  f"`{exp.fsa}`, unchanged, on {n} worlds per backend (paper: {exp.paper}).",
                  "",
                  "| backend | success | episodes/s | simulated s per wall s |",
                  "|---|---:|---:|---:|"]
        for backend, m in per.items():
            rate = m.episodes / m.wall_s if m.wall_s > 0 else float("nan")
            speed = f"{m.sim_s / m.wall_s:.1f}" if backend == "dynamic" and m.wall_s else "—"
            lines.append(f"| {backend} | {m.successes}/{m.episodes} = "
                         f"{m.successes / max(m.episodes, 1):.1%} | {rate:.2f} | {speed} |")
        dyn = per.get("dynamic")
        if dyn is not None:
            met = dyn.successes >= exp.target * dyn.episodes
            lines += ["", "Dynamic failures by cause: " + (", ".join(
                f"{k} {v}" for k, v in dyn.failures.most_common()) or "none") + ".", "",
                f"Target: dynamic success at least {exp.target:.0%}: "
                f"**{'met' if met else 'not met'}**.", ""]
            if dyn.failures:
                lines += ["Why, by cause:", "", "| cause | runs | what it means |",
                          "|---|---:|---|"]
                lines += [f"| {k} | {v} | {CAUSES.get(k, '')} |"
                          for k, v in dyn.failures.most_common()]
                lines.append("")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for key, exp in EXPERIMENTS.items():
        p.add_argument(f"--{key}", type=int, default=exp.default_n,
                       help=f"worlds per backend for {key} (default {exp.default_n}; 0 skips)")
    p.add_argument("--out", type=output_folder, default=ROOT / "docs" / "results")
    p.add_argument("--progress", action="store_true", help="a line per episode on stderr")
    p.add_argument("--report-only", action="store_true",
                   help="rewrite transfer.md from the transfer.json in --out; run nothing")
    args = p.parse_args(argv)
    if args.report_only:
        return _rewrite(args.out)
    t0 = time.perf_counter()
    sizes = {key: getattr(args, key) for key in EXPERIMENTS if getattr(args, key) > 0}
    results = {key: {b: measure(EXPERIMENTS[key], b, n, progress=args.progress)
                     for b in BACKENDS} for key, n in sizes.items()}
    total = time.perf_counter() - t0
    command = "python benchmarks/transfer.py " + " ".join(
        f"--{k} {n}" for k, n in sizes.items())
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "transfer.md").write_text(report(results, sizes, total, command),
                                          encoding="utf-8")
    (args.out / "transfer.json").write_text(json.dumps(
        {"command": command, "total_s": round(total, 1),
         **{k: {b: m.as_dict() for b, m in per.items()} for k, per in results.items()}},
        indent=2) + "\n", encoding="utf-8")
    print(f"wrote {args.out / 'transfer.md'} in {total / 60:.1f} min", file=sys.stderr)
    return 0


def _rewrite(out: Path) -> int:
    data = json.loads((out / "transfer.json").read_text(encoding="utf-8"))
    results = {key: {b: Measured(m["successes"], m["episodes"], m["wall_s"], m["sim_s"],
                                 Counter(m["failures"])) for b, m in data[key].items()}
               for key in EXPERIMENTS if key in data}
    sizes = {key: per["dynamic"].episodes for key, per in results.items()}
    command = data.get("command") or "python benchmarks/transfer.py " + " ".join(
        f"--{k} {n}" for k, n in sizes.items())
    (out / "transfer.md").write_text(report(results, sizes, float(data.get("total_s", 0.0)),
                                            command), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
