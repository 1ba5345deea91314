"""Reproduce the paper's moving-to-push experiment (section 4.2, figures 9 and 10).

Evolves the move-to-push task (``examples.move_to_push``) over several seeds for both
MoveBase network topologies (the paper's 38-weight count, a layered 5-3-5 network, and the
authors' 112-weight fully recurrent network) with ``--preset push``; checks every exported
FSA on fresh abstract worlds; then runs the best evolved FSA file, unchanged, on the
kinematic backend (the PR2 model judges each push by IK) over the paper's 395 placements,
and measures evaluation speed. Every number in the report comes from this run::

    python benchmarks/reproduce_move_to_push.py                  # writes docs/results/
    python benchmarks/reproduce_move_to_push.py --seeds 1 --placements 40 --out /tmp/push

Writes, in ``--out`` (default ``docs/results``): ``move_to_push.md`` (the report),
``move_to_push_placements.png`` (figure 10: object positions in the robot frame, pushed or
not), ``move_to_push_robot.png`` (the PR2 at an evolved base pose beside the table) and
``move_to_push_best.fsa.yaml``; with ``--ship`` also ``examples/move_to_reach.fsa.yaml``
(the best file, with its provenance in ``meta``, for the stacking experiment).
"""

from __future__ import annotations

import argparse
import cProfile
import os
import platform
import pstats
import statistics
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from skillcompose import FSA, compile_fsa, load_fsa, save_fsa
from skillcompose.arguments import output_dir
from skillcompose.evolve import PRESETS, EvolutionConfig, evolve
from skillcompose.executor import trial_rngs
from skillcompose.task import Task, load_task

ROOT = Path(__file__).resolve().parents[1]
TASK = "examples.move_to_push"
SHIPPED = ROOT / "examples" / "move_to_reach.fsa.yaml"
PAPER_GENERATIONS = 1633
BUDGET = 300 * 408
"""Genome evaluations of a quarter of the paper's generations at its population."""
PAPER_REAL_ROBOT = (323, 395)
PRESET = "push"
CHECK_SEED = 10_000
PLACEMENT_SEED = 20_000


@dataclass(frozen=True)
class Run:
    topology: str
    seed: int
    solved: bool
    generations: int
    genome_evaluations: int
    episodes: int
    wall_time: float
    states_evolved: int
    states_simplified: int
    success_evolved: float
    success: float
    fsa_evolved: FSA
    fsa: FSA

    @property
    def best_variant(self) -> tuple[float, str, FSA]:
        if self.success >= self.success_evolved:
            return self.success, "simplified", self.fsa
        return self.success_evolved, "evolved", self.fsa_evolved


def success_rate(task: Task, fsa: FSA, worlds: int, seed: int) -> float:
    """Mean fitness (pushed or not) of ``fsa`` on ``worlds`` fresh worlds."""
    return task.evaluate(compile_fsa(fsa, task.registry, task.backend), seed, worlds)


def run_topology(
    topology: str, seeds: Sequence[int], cfg: EvolutionConfig, workers: int, check: int,
    out_dir: Path | None,
) -> list[Run]:
    task = load_task(TASK, network=topology)
    runs = []
    for seed in seeds:
        run_dir = out_dir / f"{topology}-{seed}" if out_dir is not None else None
        r = evolve(task, cfg, seed=seed, workers=workers,
                   backend="process" if workers > 1 else "serial", out_dir=run_dir)
        genome_evals = cfg.population * (r.generations + 1)  # generation 0 included
        run = Run(
            topology=topology, seed=seed, solved=r.solved, generations=r.generations,
            genome_evaluations=genome_evals, episodes=r.evaluations, wall_time=r.wall_time,
            states_evolved=len(r.evolved_fsa.states), states_simplified=len(r.best_fsa.states),
            success_evolved=success_rate(task, r.evolved_fsa, check, CHECK_SEED),
            success=success_rate(task, r.best_fsa, check, CHECK_SEED),
            fsa_evolved=r.evolved_fsa, fsa=r.best_fsa,
        )
        runs.append(run)
        print(f"{topology} seed {seed}: solved={r.solved} generations={r.generations} "
              f"genome evaluations={genome_evals} wall={r.wall_time:.1f}s states "
              f"{run.states_evolved}->{run.states_simplified} success on {check} fresh "
              f"worlds: evolved {run.success_evolved:.3f}, simplified {run.success:.3f}",
              file=sys.stderr, flush=True)
    return runs


@dataclass(frozen=True)
class Placement:
    object_robot: tuple[float, float]  # x, y [m] in the robot's starting frame
    pushed: bool
    reason: str  # why not, from the kinematic skills
    classifier_says: bool | None  # classifier's verdict at the pose MoveBase reached


def kinematic_placements(fsa: FSA, topology: str, n: int) -> list[Placement]:
    """The file, unchanged, on the kinematic backend over ``n`` judged worlds."""
    from skillcompose.skills.move_to_push import ARM_CODES, classifier_label, object_in_robot_frame

    task = load_task(TASK, network=topology, backend="kinematic", judge=True)
    compiled = compile_fsa(fsa, task.registry, "kinematic")
    out = []
    for rng in trial_rngs(PLACEMENT_SEED, n):
        bb = task.setup(rng)
        start = bb["base_pose_world"]
        obj = bb["object_position_world"]
        x, y, _ = object_in_robot_frame(start, obj)
        result = compiled.run(bb, rng)
        pushed = task.score(result, bb) == 1.0
        says: bool | None = None
        if bb.get("arm_in_use") in ARM_CODES:
            label = classifier_label(bb["base_pose_world"], bb["torso_height_m"], obj)
            says = label == ARM_CODES[bb["arm_in_use"]]
        reason = "" if pushed else str(bb.get("last_failure_reason") or result.outcome)
        out.append(Placement((x, y), pushed, reason, says))
    return out


def plot_placements(placements: Sequence[Placement], path: Path, title: str) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.5, 6))
    ax = fig.add_subplot()
    ok = np.array([p.object_robot for p in placements if p.pushed]).reshape(-1, 2)
    bad = np.array([p.object_robot for p in placements if not p.pushed]).reshape(-1, 2)
    ax.scatter(-ok[:, 1], ok[:, 0], marker="x", color="tab:green", label=f"pushed ({len(ok)})")
    ax.scatter(-bad[:, 1], bad[:, 0], marker="x", color="tab:red",
               label=f"not pushed ({len(bad)})")
    ax.add_patch(_circle(0.33))
    ax.set_xlabel("-y [m] (robot's right)")
    ax.set_ylabel("x [m] (robot's front)")
    ax.set_aspect("equal")
    ax.set_xlim(-1.6, 1.6)
    ax.set_ylim(-0.2, 1.6)
    ax.legend(loc="lower right")
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _circle(radius: float):  # type: ignore[no-untyped-def]
    from matplotlib.patches import Circle

    return Circle((0.0, 0.0), radius, fill=False, color="tab:red", linewidth=2)


def render_robot(fsa: FSA, topology: str, path: Path) -> str:
    """The PR2 at the base pose the FSA's MoveBase chooses in a judged world, with the arm
    configuration IK found for the push; returns a caption."""
    from skillcompose.robots.collision import Scene
    from skillcompose.robots.model import ARMS, RobotPose, load_pr2
    from skillcompose.robots.render import render_configuration
    from skillcompose.skills.kinematic_world import read_state

    task = load_task(TASK, network=topology, backend="kinematic", judge=True)
    compiled = compile_fsa(fsa, task.registry, "kinematic")
    for rng in trial_rngs(PLACEMENT_SEED + 1, 50):
        bb = task.setup(rng)
        obj = bb["object_position_world"]
        result = compiled.run(bb, rng)
        if task.score(result, bb) != 1.0:
            continue
        state = read_state(bb)
        pose = RobotPose(state.base_pose_world, state.torso_height_m,
                         {a: state.q_arm_rad[a] for a in ARMS})
        render_configuration(load_pr2(), pose, path, scene=Scene((bb["table_world"],)),
                             targets_m=[np.array(obj)],
                             title=f"PR2 after MoveBase and Push ({state.arm_in_use} arm)")
        x, y, yaw = state.base_pose_world
        return (f"base ({x:.2f} m, {y:.2f} m, {yaw:.2f} rad), torso "
                f"{state.torso_height_m:.3f} m, {state.arm_in_use} arm; the red cross is where "
                "the object stood")
    return "no successful run among 50 judged worlds"


def speed(topology: str, fsa: FSA, episodes: int) -> tuple[float, list[str]]:
    """Episodes per second of one core, and the top of a profile of those episodes."""
    task = load_task(TASK, network=topology)
    compiled = compile_fsa(fsa, task.registry, "sim")
    rngs = list(trial_rngs(1, episodes))

    def work() -> None:
        for rng in rngs:
            bb = task.setup(rng)
            task.score(compiled.run(bb, rng), bb)

    t0 = time.perf_counter()
    work()
    rate = episodes / (time.perf_counter() - t0)
    prof = cProfile.Profile()
    prof.enable()
    work()
    prof.disable()
    stats = pstats.Stats(prof)
    total = max(stats.total_tt, 1e-12)  # type: ignore[attr-defined]
    rows = []
    table = stats.stats  # type: ignore[attr-defined]
    groups = {
        "world setup (examples.move_to_push)": ("move_to_push.py", "random_world"),
        "network (skillcompose.skills.network)": ("network.py", "__call__"),
        "reachability classifier": ("reachability.py", "predict_one"),
    }
    for label, (file, func) in groups.items():
        cum = max((v[3] for k, v in table.items() if k[0].endswith(file) and k[2] == func),
                  default=0.0)
        rows.append(f"| {label} | {100 * cum / total:.0f} % |")
    return rate, rows


def _stats(values: Sequence[float], fmt: str) -> str:
    return (f"{format(statistics.median(values), fmt)} "
            f"({format(min(values), fmt)}–{format(max(values), fmt)})")


def _runs_table(runs: Sequence[Run]) -> list[str]:
    out = [
        "| topology | seed | solved | generations | genome evaluations | episodes | wall time "
        "[s] | states evolved → simplified | success on fresh worlds, evolved | simplified |",
        "|---|---:|:---:|---:|---:|---:|---:|:---:|---:|---:|",
    ]
    for r in runs:
        out.append(
            f"| {r.topology} | {r.seed} | {'yes' if r.solved else 'no'} | {r.generations} | "
            f"{r.genome_evaluations} | {r.episodes} | {r.wall_time:.1f} | {r.states_evolved} → "
            f"{r.states_simplified} | {r.success_evolved:.3f} | {r.success:.3f} |"
        )
    return out


def _summary(name: str, runs: Sequence[Run]) -> str:
    return (
        f"| {name} | {sum(r.solved for r in runs)}/{len(runs)} | "
        f"{_stats([r.generations for r in runs], '.0f')} | "
        f"{_stats([r.genome_evaluations for r in runs], '.0f')} | "
        f"{_stats([r.wall_time for r in runs], '.0f')} | "
        f"{_stats([r.states_evolved for r in runs], '.0f')} → "
        f"{_stats([r.states_simplified for r in runs], '.0f')} | "
        f"{_stats([r.success for r in runs], '.3f')} |"
    )


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=5, help="seeds 0..N-1 per topology (5)")
    p.add_argument("--topologies", default="layered,recurrent")
    p.add_argument("--generations", type=int, default=816,
                   help="generation budget of each run (default 816: at the preset's 150 "
                   "individuals, the 122,400 genome evaluations of 408 generations of 300)")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   help="evaluation processes per run (default: all cores)")
    p.add_argument("--check", type=int, default=1000,
                   help="fresh abstract worlds to check each exported FSA (default 1000)")
    p.add_argument("--placements", type=int, default=395,
                   help="judged worlds on the kinematic backend (default 395, the paper's)")
    p.add_argument("--runs-dir", default=None, help="keep each run's directory here")
    p.add_argument("--ship", action="store_true",
                   help="also write the best file to examples/move_to_reach.fsa.yaml")
    p.add_argument("--out", type=output_dir, default=str(ROOT / "docs" / "results"),
                   help="output folder (default docs/results)")
    p.add_argument("--picture-only", action="store_true",
                   help="only redraw move_to_push_robot.png from the move_to_push_best.fsa.yaml "
                   "already in --out (the same world as the report's caption); nothing is "
                   "evolved")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.picture_only:
        best_path = out / "move_to_push_best.fsa.yaml"
        written = load_fsa(best_path)
        topology = written.meta["provenance"]["settings"]["network"]
        caption = render_robot(written, topology, out / "move_to_push_robot.png")
        print(f"wrote {out / 'move_to_push_robot.png'}: {caption}")
        return 0
    # as docs/results/move_to_push.md was measured: solved on the evaluation (and its
    # confirmation), before presets required the exported FSA to hold (docs/results/solved.md)
    cfg = EvolutionConfig(**{**PRESETS[PRESET], "require_holds": False,
                             "generations": args.generations})
    seeds = list(range(args.seeds))
    topologies = [t for t in args.topologies.split(",") if t]
    runs_dir = Path(args.runs_dir) if args.runs_dir else None
    runs = {t: run_topology(t, seeds, cfg, args.workers, args.check, runs_dir)
            for t in topologies}
    every = [r for rs in runs.values() for r in rs]
    best = max(every, key=lambda r: (r.best_variant[0], -r.generations, -r.seed))
    _, variant, best_fsa = best.best_variant
    task = load_task(TASK, network=best.topology)
    meta = {
        **dict(best_fsa.meta),
        "provenance": {
            "script": "benchmarks/reproduce_move_to_push.py",
            "task": TASK, "settings": {"network": best.topology},
            "preset": PRESET, "seed": best.seed, "generations": best.generations,
            "variant": variant,
            "success_on_fresh_worlds": round(best.best_variant[0], 4),
            "fresh_worlds": args.check,
        },
    }
    best_fsa = FSA(best_fsa.states, best_fsa.start, best_fsa.terminals, best_fsa.step_limit,
                   "move_to_reach", meta)
    header = ("The best move-to-push FSA of benchmarks/reproduce_move_to_push.py "
              f"({best.topology} network, seed {best.seed}, {variant}). Run it with: "
              f"skillcompose run FILE --task {TASK} --set network={best.topology}")
    best_path = out / "move_to_push_best.fsa.yaml"
    save_fsa(best_fsa, best_path, task.registry, header=header)
    if args.ship:
        save_fsa(best_fsa, SHIPPED, task.registry, header=header)
    shipped = load_fsa(best_path)  # the file as written, unchanged, from here on
    placements = kinematic_placements(shipped, best.topology, args.placements)
    pushed = sum(p.pushed for p in placements)
    judged = [p for p in placements if p.classifier_says is not None]
    agree = sum(p.classifier_says == p.pushed for p in judged)
    reasons: dict[str, int] = {}
    for pl in placements:
        if not pl.pushed:
            reasons[pl.reason] = reasons.get(pl.reason, 0) + 1
    plot_placements(placements, out / "move_to_push_placements.png",
                    f"{best_path.name} on the PR2 model: {pushed}/{len(placements)} pushed")
    caption = render_robot(shipped, best.topology, out / "move_to_push_robot.png")
    speeds = {t: speed(t, best_fsa if t == best.topology else
                       max(rs, key=lambda r: r.success).fsa, 3000)
              for t, rs in runs.items()}
    pool = {t: statistics.median(r.episodes / r.wall_time for r in rs)
            for t, rs in runs.items()}
    total = time.perf_counter() - t0
    lines = [
        "# Moving to push (paper section 4.2): reproduction",
        "",
        "Written by `benchmarks/reproduce_move_to_push.py`; every number below was measured by "
        "that run. Do not edit by hand: rerun the script.",
        "",
        f"Command: `python benchmarks/reproduce_move_to_push.py --seeds {args.seeds} "
        f"--topologies {args.topologies} --generations {args.generations} --check "
        f"{args.check} --placements {args.placements} --workers {args.workers}`  ",
        f"Machine: {os.cpu_count()} CPUs, {platform.machine()}, Python "
        f"{platform.python_version()}, NumPy {np.__version__}; evaluations on {args.workers} "
        f"worker process(es). Total time of the script: {total / 60:.1f} min. The machine is "
        "shared, so wall times move with its load.",
        "",
        "Task `examples.move_to_push` (its docstring states every decision where the paper is "
        "vague): a 5 m × 5 m room, one table, one object near the table side the robot faces; "
        "RecogniseObject, MoveBase (a network: its weights are the state's vector parameter) "
        "and Push (terminating; judged by the reachability classifier). Fitness 1 when the "
        "object is pushed, else 0; 20 worlds per evaluation, shared by a generation; an FSA "
        "counts as solved at mean 0.95 and must hold it on 200 fresh worlds "
        f"(`--preset {PRESET}`: {_config(cfg)}).",
        "",
        "## Evolution",
        "",
        "The paper says MoveBase is a \"fully recurrent\" network and needs \"38 parameters\": "
        "38 is exactly a layered 5-3-5 network with biases (`layered`); the authors' fully "
        "recurrent network with 5 inputs, 3 hidden and 5 outputs has 112 weights "
        "(`recurrent`). Both were evolved. Median (min–max) over the seeds; a run that did "
        "not solve counts with its whole budget:",
        "",
        "| topology | solved | generations | genome evaluations | wall time [s] | states "
        "evolved → simplified | success on fresh worlds |",
        "|---|:---:|---:|---:|---:|:---:|---:|",
        f"| paper | 1/1 | {PAPER_GENERATIONS} | — | — | 4 (figure 9: two MoveBase) | — |",
        *[_summary(t, rs) for t, rs in runs.items()],
        "",
        "Targets of the issue, as measured:",
        "",
        *[
            f"- {t}: every seed solves: **{'yes' if all(r.solved for r in rs) else 'no'}** "
            f"({sum(r.solved for r in rs)}/{len(rs)}); median genome evaluations at most "
            f"{BUDGET:,} (a quarter of the paper's {PAPER_GENERATIONS} generations at its "
            f"population of 300) at a population of {cfg.population}: **"
            f"{'yes' if statistics.median(r.genome_evaluations for r in rs) <= BUDGET else 'no'}"
            f"** (median {statistics.median(r.genome_evaluations for r in rs):,.0f}, "
            f"{statistics.median(r.generations for r in rs):.0f} generations); every run "
            "under 15 "
            f"minutes: **{'yes' if max(r.wall_time for r in rs) <= 900 else 'no'}** (max "
            f"{max(r.wall_time for r in rs):.0f} s)."
            for t, rs in runs.items()
        ],
        "",
        "Success on fresh worlds: each exported FSA (simplified, and as evolved) on "
        f"{args.check} worlds it never met during evolution.",
        "",
        *_runs_table(every),
        "",
        "## The evolved file on the PR2 model",
        "",
        "The best file (`move_to_push_best.fsa.yaml`"
        + (", shipped as `examples/move_to_reach.fsa.yaml`" if args.ship else
           "; `examples/move_to_reach.fsa.yaml`, the shipped file, is written only with "
           "`--ship`")
        + f": {best.topology} network, seed {best.seed}, "
        f"{variant}, {len(best_fsa.states)} states, success {best.best_variant[0]:.3f} on "
        f"fresh abstract worlds) ran unchanged with `--set backend=kinematic` on "
        f"{len(placements)} placements drawn as the paper tested on the robot (object at most "
        "1.5 m away and not behind the robot). Push then succeeds only when IK finds a "
        "configuration of the chosen arm, within its joint limits and clear of the table, "
        "that puts the gripper on the object and then 5 cm further.",
        "",
        f"- pushed: **{pushed}/{len(placements)} = {pushed / len(placements):.1%}** (the "
        f"paper's real robot: {PAPER_REAL_ROBOT[0]}/{PAPER_REAL_ROBOT[1]} = "
        f"{PAPER_REAL_ROBOT[0] / PAPER_REAL_ROBOT[1]:.1%}; target ≥ 95 %: "
        f"**{'yes' if pushed >= 0.95 * len(placements) else 'no'}**);",
        "- failures by reason: " + (", ".join(f"{k} {v}" for k, v in sorted(reasons.items()))
                                    or "none") + ";",
        f"- the classifier agrees with IK on {agree}/{len(judged)} placements where MoveBase "
        "moved the robot (its verdict at the reached pose against the kinematic push).",
        "",
        "Figure 10 (object positions in the robot's starting frame; the circle is the base):",
        "",
        "![placements](move_to_push_placements.png)",
        "",
        f"The PR2 at an evolved base pose ({caption}):",
        "",
        "![robot](move_to_push_robot.png)",
        "",
        "## Evaluation speed",
        "",
        "| topology | episodes/s, one core (this script) | episodes/s during the runs "
        f"({args.workers} workers, median) |",
        "|---|---:|---:|",
        *[f"| {t} | {speeds[t][0]:.0f} | {pool[t]:.0f} |" for t in runs],
        "",
        "Where an episode's time goes (cProfile, cumulative share of 3000 episodes of the "
        "best FSA; the rest is the runtime's stepping, the blackboard and the fitness):",
        "",
        *[
            line for t in runs
            for line in (f"{t}:", "", "| part | share |", "|---|---:|", *speeds[t][1], "")
        ],
    ]
    (out / "move_to_push.md").write_text("\n".join(lines), encoding="utf-8")
    print(f"wrote {out / 'move_to_push.md'} in {total / 60:.1f} min", file=sys.stderr)
    return 0


def _config(cfg: EvolutionConfig) -> str:
    default = EvolutionConfig()
    changed = {k: v for k, v in cfg.to_dict().items() if v != getattr(default, k)}
    return ", ".join(f"`{k}={v}`" for k, v in changed.items())


if __name__ == "__main__":
    raise SystemExit(main())
