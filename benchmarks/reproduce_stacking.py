"""Reproduce the paper's stacking experiment (section 4.3, figures 11-13).

Evolves the stacking task (``examples.stacking``, MoveToReach being the evolved
``examples/move_to_reach.fsa.yaml`` used as a nested skill) over several seeds with one
preset; records generations, genome evaluations, wall time and FSA size before and after
simplification (and whether MoveToReach appears more than once); sweeps the failure
probability of the best file with ``skillcompose robustness`` (figure 12); runs that file,
unchanged, on the kinematic backend (the PR2 model) over fresh scenes; and draws the PR2 at
the end of a successful kinematic run (figure 13). Every number in the report comes from
this run::

    python benchmarks/reproduce_stacking.py                       # writes docs/results/
    python benchmarks/reproduce_stacking.py --seeds 1 --reps 300 --scenes 10 --out /tmp/st

Writes, in ``--out`` (default ``docs/results``): ``stacking.md`` (the report),
``stacking_best.fsa.yaml``, ``stacking_robustness.csv`` / ``.png`` (figure 12),
``stacking_robot.png`` (figure 13) and ``stacking_fitness.png`` (best fitness per
generation of every seed).
"""

from __future__ import annotations

import argparse
import ast
import csv
import os
import platform
import statistics
import sys
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from matplotlib.figure import Figure

from skillcompose import FSA, compile_fsa, load_fsa, save_fsa
from skillcompose.arguments import output_folder
from skillcompose.cli import main as skillcompose_main
from skillcompose.evolve import PRESETS, EvolutionConfig, evolve
from skillcompose.executor import trial_rngs
from skillcompose.task import load_task

ROOT = Path(__file__).resolve().parents[1]
TASK = "examples.stacking"
PAPER_GENERATIONS = 603
TARGET_GENERATIONS = 151  # a quarter of 603
TARGET_POPULATION = 300
TARGET_EVALUATIONS = TARGET_GENERATIONS * TARGET_POPULATION
TARGET_MINUTES = 15.0
TARGET_FITNESS = 0.5
TARGET_P_FAIL = 0.3
TARGET_SCENES = 0.95
CHECK_SEED = 10_000
REFERENCE = ROOT / "examples" / "stacking_reference.fsa.yaml"
TASK_FILE = ROOT / "examples" / "stacking.py"
SCENE_SEED = 30_000
STACKING_SETTINGS = {"population": 300, "trials": 10, "confirm_trials": 1000,
                     "confirm_rate": 0.92}
"""Changes to the preset: the target's population; ten shared worlds per evaluation; a
solution confirmed when at least 92 % of 1000 fresh worlds are stacked (the hand-written
reference FSA stacks about 93 % at p_fail 0.3, and at 1000 worlds an FSA stacking 88 %
passes about never)."""


@dataclass(frozen=True)
class Run:
    seed: int
    solved: bool
    generations: int
    genome_evaluations: int
    episodes: int
    wall_time: float
    states_evolved: int
    states_simplified: int
    reach_evolved: int
    reach_simplified: int
    fitness_check: float
    stacked_check: float
    fsa: FSA
    history: list[float]


def _count(fsa: FSA, skill: str) -> int:
    return sum(1 for st in fsa.states.values() if st.skill == skill)


def run_seeds(seeds: Sequence[int], cfg: EvolutionConfig, workers: int, check: int
              ) -> list[Run]:
    task = load_task(TASK)
    runs = []
    for seed in seeds:
        r = evolve(task, cfg, seed=seed, workers=workers,
                   backend="process" if workers > 1 else "serial")
        check_fitness, stacked = sim_check(r.best_fsa, check)
        run = Run(
            seed=seed, solved=r.solved, generations=r.generations,
            genome_evaluations=cfg.population * (r.generations + 1), episodes=r.evaluations,
            wall_time=r.wall_time, states_evolved=len(r.evolved_fsa.states),
            states_simplified=len(r.best_fsa.states),
            reach_evolved=_count(r.evolved_fsa, "MoveToReach"),
            reach_simplified=_count(r.best_fsa, "MoveToReach"),
            fitness_check=check_fitness, stacked_check=stacked, fsa=r.best_fsa,
            history=[h.best for h in r.history],
        )
        runs.append(run)
        print(f"seed {seed}: solved={r.solved} generations={r.generations} "
              f"wall={r.wall_time:.0f}s states {run.states_evolved}->{run.states_simplified} "
              f"on {check} fresh worlds: fitness {check_fitness:.3f}, stacked "
              f"{100 * stacked:.1f} %", file=sys.stderr,
              flush=True)
    return runs


def figure12(best: Path, out: Path, reps: int, workers: int) -> list[dict[str, float]]:
    """``skillcompose robustness`` over 30 failure probabilities; the rows it wrote."""
    csv_path = out / "stacking_robustness.csv"
    code = skillcompose_main([
        "robustness", str(best), "--task", TASK, "--p-fail", "0:1:30", "--reps", str(reps),
        "-o", str(out / "stacking_robustness.png"), "--csv", str(csv_path),
        "--workers", str(workers),
    ])
    if code != 0:
        raise SystemExit(f"skillcompose robustness failed with exit code {code}")
    with csv_path.open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    key = next(iter(rows[0]))
    return [{"p_fail": float(r[key]), "mean": float(r["mean"]), "std": float(r["std"]),
             "stacked": float(r["solved_rate"])} for r in rows]


def kinematic_scenes(fsa: FSA, n: int, picture: Path | None, *, picture_only: bool = False
                     ) -> tuple[int, Counter[str], str]:
    """Runs ``fsa`` on ``n`` kinematic scenes: stacked count, outcomes, and the caption of
    the picture (when ``picture`` is given) of the PR2 at the end of the first successful
    run; with ``picture_only``, stops once the picture is drawn."""
    from skillcompose.robots.model import load_pr2
    from skillcompose.robots.render import render_configuration
    from skillcompose.skills.replay import robot_pose, world_scene

    task = load_task(TASK, backend="kinematic", trials=1)
    compiled = compile_fsa(fsa, task.registry, "kinematic")
    stacked = 0
    outcomes: Counter[str] = Counter()
    caption = "no successful run"
    for k, rng in enumerate(trial_rngs(SCENE_SEED, n)):
        bb = task.setup(rng)
        near = bb["start_near"]
        result = compiled.run(bb, rng)
        ok = task.score(result, bb) == 0.0
        stacked += ok
        outcomes[f"{result.outcome} ({'near' if near else 'far'} start)"] += 1
        if ok and picture is not None and caption == "no successful run":
            render_configuration(load_pr2(), robot_pose(bb), picture, scene=world_scene(bb),
                                 title="PR2 at the end of a stacking run")
            caption = (f"scene {k} ({'near' if near else 'far'} start), {result.steps} steps")
            if picture_only:
                break
        print(f"scene {k}: {result.outcome}", file=sys.stderr, flush=True)
    return stacked, outcomes, caption


def sim_check(fsa: FSA, n: int) -> tuple[float, float]:
    """Mean fitness and share stacked of ``fsa`` on the ``n`` fresh worlds every evolved FSA
    is checked on."""
    task = load_task(TASK)
    scores = [f for _, f in task.run_trials(compile_fsa(fsa, task.registry, "sim"),
                                            CHECK_SEED, n)]
    return statistics.fmean(scores), sum(f == 0.0 for f in scores) / len(scores)


def decisions() -> list[str]:
    """The task's decisions where section 4.3 is vague, from its module docstring."""
    doc = ast.get_docstring(ast.parse(TASK_FILE.read_text(encoding="utf-8"))) or ""
    start = doc.index("Decisions where")
    body = doc[start:].split("\n", 1)[1].strip()
    return [line.strip() if not line.startswith("  ") else "  " + line.strip()
            for line in body.splitlines()]


def plot_histories(runs: Sequence[Run], path: Path) -> None:
    fig = Figure(figsize=(7, 4))
    ax = fig.add_subplot()
    for r in runs:
        ax.plot(r.history, label=f"seed {r.seed}")
    ax.set_yscale("symlog", linthresh=0.1)
    ax.set_xlabel("generation")
    ax.set_ylabel("best fitness (equation 2, minimised)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _met(ok: bool) -> str:
    return "**met**" if ok else "**not met**"


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--preset", default="robust", choices=sorted(PRESETS))
    p.add_argument("--population", type=int, default=STACKING_SETTINGS["population"])
    p.add_argument("--trials", type=int, default=STACKING_SETTINGS["trials"],
                   help="worlds per evaluation")
    p.add_argument("--confirm", type=int, default=STACKING_SETTINGS["confirm_trials"],
                   help="fresh worlds that confirm a solution")
    p.add_argument("--confirm-rate", type=float, default=STACKING_SETTINGS["confirm_rate"],
                   help="share of those that must be stacked")
    p.add_argument("--generations", type=int, default=400, help="budget per run")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--check", type=int, default=1000, help="fresh worlds per evolved FSA")
    p.add_argument("--reps", type=int, default=3000, help="runs per p_fail in figure 12")
    p.add_argument("--scenes", type=int, default=100, help="kinematic scenes")
    p.add_argument("--out", type=output_folder, default=ROOT / "docs" / "results")
    p.add_argument("--picture-only", action="store_true",
                   help="only redraw stacking_robot.png from the stacking_best.fsa.yaml already "
                   "in --out (the same scene the report's caption names); nothing is evolved")
    args = p.parse_args(argv)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    if args.picture_only:
        _, _, caption = kinematic_scenes(load_fsa(out / "stacking_best.fsa.yaml"), args.scenes,
                                         out / "stacking_robot.png", picture_only=True)
        print(f"wrote {out / 'stacking_robot.png'}: {caption}")
        return 0
    t0 = time.perf_counter()
    cfg = EvolutionConfig(**{
        **PRESETS[args.preset], "require_holds": False,  # as docs/results/stacking.md was
        # measured: solved on the evaluation, before presets asked the FSA to hold
        "generations": args.generations, "population": args.population,
        "trials": args.trials, "confirm_trials": args.confirm, "confirm_rate": args.confirm_rate,
    })
    runs = run_seeds(range(args.seeds), cfg, args.workers, args.check)
    best_run = min(runs, key=lambda r: (not r.solved, r.fitness_check, r.states_simplified))
    best_file = out / "stacking_best.fsa.yaml"
    save_fsa(best_run.fsa, best_file, load_task(TASK).registry, header=(
        f"The best stacking FSA of benchmarks/reproduce_stacking.py (seed {best_run.seed}, "
        f"simplified). Run it with: skillcompose run FILE --task {TASK}"))
    plot_histories(runs, out / "stacking_fitness.png")
    sweep = figure12(best_file, out, args.reps, args.workers)
    stacked, outcomes, caption = kinematic_scenes(best_run.fsa, args.scenes,
                                                  out / "stacking_robot.png")
    reference = load_fsa(REFERENCE)
    ref_fitness, ref_stacked = sim_check(reference, args.check)
    ref_scenes, _, _ = kinematic_scenes(reference, args.scenes, None)
    total = time.perf_counter() - t0

    solved = [r for r in runs if r.solved]
    gens = [r.generations for r in runs]
    median_gens = statistics.median(gens)
    evals = [r.genome_evaluations for r in runs]
    walls = [r.wall_time / 60 for r in runs]
    ok_gens = len(solved) == len(runs) and (
        (cfg.population <= TARGET_POPULATION and median_gens <= TARGET_GENERATIONS)
        or statistics.median(evals) <= TARGET_EVALUATIONS)
    ok_wall = max(walls) <= TARGET_MINUTES
    low = [row for row in sweep if row["p_fail"] <= TARGET_P_FAIL + 1e-9]
    ok_sweep = all(row["mean"] <= TARGET_FITNESS for row in low)
    ok_scenes = stacked >= TARGET_SCENES * args.scenes

    lines = [
        "# Stacking (paper §4.3): measured",
        "",
        f"Written by `benchmarks/reproduce_stacking.py` on {platform.machine()} with "
        f"{os.cpu_count()} CPUs, {args.workers} worker(s), in {total / 60:.1f} minutes. "
        f"Task `{TASK}` (step limit 15, p_fail 0.3; decisions in the task's docstring), "
        "MoveToReach = `examples/move_to_reach.fsa.yaml` as a nested FSA.",
        "",
        f"Preset `{args.preset}` with population {cfg.population}, {cfg.trials} shared worlds "
        f"per evaluation, a solution confirmed when at least {100 * cfg.confirm_rate:.0f} % of "
        f"{cfg.confirm_trials} fresh worlds are stacked; budget {cfg.generations} "
        "generations.",
        "",
        "## Decisions",
        "",
        "Where section 4.3 is vague, the task decides (from `examples/stacking.py`'s "
        "docstring, which the skills and the task keep to):",
        "",
        *decisions(),
        "",
        "## Evolution",
        "",
        "| seed | solved | generations | genome evaluations | wall [min] | states evolved → "
        "simplified | MoveToReach states evolved → simplified | on "
        f"{args.check} fresh worlds: fitness | stacked |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in runs:
        lines.append(
            f"| {r.seed} | {r.solved} | {r.generations} | {r.genome_evaluations:,} | "
            f"{r.wall_time / 60:.1f} | {r.states_evolved} → {r.states_simplified} | "
            f"{r.reach_evolved} → {r.reach_simplified} | {r.fitness_check:.3f} | "
            f"{100 * r.stacked_check:.1f} % |")
    lines += [
        "",
        f"Solved {len(solved)} of {len(runs)}; median generations {median_gens} (paper: "
        f"{PAPER_GENERATIONS}), median genome evaluations {statistics.median(evals):,.0f}, "
        f"longest run {max(walls):.1f} min.",
        "",
        f"- Target: every seed solves in a median of at most {TARGET_GENERATIONS} generations "
        f"at a population of at most {TARGET_POPULATION} (else at most "
        f"{TARGET_EVALUATIONS:,} genome evaluations): {_met(ok_gens)}.",
        f"- Target: at most {TARGET_MINUTES:.0f} minutes a run: {_met(ok_wall)}.",
        "",
        f"The hand-written `examples/stacking_reference.fsa.yaml` on the same {args.check} "
        f"fresh worlds: fitness {ref_fitness:.3f}, stacked {100 * ref_stacked:.1f} %; on the "
        f"PR2 model, {ref_scenes} of {args.scenes} scenes stacked. Its misses, like the "
        "evolved files', are mostly worlds where the evolved MoveToReach does not bring the "
        "object into reach.",
        "",
        "![best fitness per generation](stacking_fitness.png)",
        "",
        f"The best file (seed {best_run.seed}): `stacking_best.fsa.yaml`.",
        "",
        "## Figure 12: robustness",
        "",
        f"`skillcompose robustness stacking_best.fsa.yaml --task {TASK} --p-fail 0:1:30 "
        f"--reps {args.reps}`: mean ± std of equation (2) at 30 failure probabilities.",
        "",
        "| p_fail | mean | std | stacked |",
        "| --- | --- | --- | --- |",
    ]
    lines += [f"| {r['p_fail']:.3f} | {r['mean']:.3f} | {r['std']:.3f} | "
              f"{100 * r['stacked']:.1f} % |" for r in sweep]
    worst_low = max(row["mean"] for row in low)
    lines += [
        "",
        f"- Target: mean fitness ≤ {TARGET_FITNESS} for every p_fail ≤ {TARGET_P_FAIL} "
        f"(worst there: {worst_low:.3f}): {_met(ok_sweep)}.",
        "",
        "![figure 12](stacking_robustness.png)",
        "",
        "## The same file on the PR2 model",
        "",
        f"`stacking_best.fsa.yaml`, unchanged, with `--set backend=kinematic` (IK, box "
        f"collisions; p_fail 0) on {args.scenes} fresh scenes: **{stacked} of {args.scenes} "
        "stacked** (paper: 20 of 20 on the real robot).",
        "",
        "| outcome | runs |",
        "| --- | --- |",
    ]
    lines += [f"| {k} | {v} |" for k, v in sorted(outcomes.items())]
    lines += [
        "",
        f"- Target: at least {TARGET_SCENES * args.scenes:.0f} of {args.scenes} stacked: "
        f"{_met(ok_scenes)}.",
        "",
        f"![the PR2 at the end of a stacking run](stacking_robot.png) ({caption})",
        "",
        "Replay any kinematic run step by step: `python -m skillcompose.skills.replay "
        "docs/results/stacking_best.fsa.yaml --task examples.stacking --set "
        "backend=kinematic --seed N --out DIR`.",
        "",
    ]
    (out / "stacking.md").write_text("\n".join(lines), encoding="utf-8")
    print(f"wrote {out / 'stacking.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
