"""Reproduce the paper's pouring experiment (section 4.1, figure 7) and write the results.

Evolves the pour-water task over several seeds twice: with the paper's table 1 settings, and
with our default (``skillcompose evolve`` with no options); then sweeps the failure
probability of the best evolved FSA (and of the hand-written reference) like figure 7. Every
number in the report comes from this run::

    python benchmarks/reproduce_pour_water.py                 # 10 seeds, writes docs/results/
    python benchmarks/reproduce_pour_water.py --seeds 2 --reps 200 --out /tmp/pw  # quick look

Writes, in ``--out`` (default ``docs/results``): ``pour_water.md`` (the report),
``pour_water_best.fsa.yaml`` (the best FSA evolved with our default),
``pour_water_robustness.csv`` / ``.png`` (its sweep) and
``pour_water_reference_robustness.csv`` (the sweep of the hand-written reference).

Each run is serial (one process), so its wall time is that of one core of this machine.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from skillcompose import FSA, save_fsa
from skillcompose.arguments import output_dir
from skillcompose.evolve import EvolutionConfig, evolve
from skillcompose.evolve.config import preset_settings
from skillcompose.robustness import SweepRow, plot_sweep, robustness_sweep, write_csv
from skillcompose.task import Task, load_task

TASK = "examples.pour_water"
REFERENCE = Path(__file__).resolve().parents[1] / "examples" / "pour_water_reference.fsa.yaml"
PAPER_GENERATIONS = 418
PAPER_STATES = 7
PR2_EPISODES = 20
"""Episodes of each run's exported FSA on the kinematic PR2 model (``backend=kinematic``)."""
DYNAMIC_EPISODES = 2
"""Episodes of each run's exported FSA on the PR2 in MuJoCo (``backend=dynamic``; the pour
world is fixed, so they differ only in the seeds of the IK's restarts)."""

PAPER = EvolutionConfig()  # table 1: N=300, p_mut=0.1, p_cross=0.1, p_add=0.2, p_del=0.01, S=50
"""The paper's settings; one episode per evaluation (task default trials=1)."""

OURS = EvolutionConfig(**preset_settings("default", deterministic=False))
"""Our default (``skillcompose evolve examples.pour_water`` with no options; for a noisy task
``skillcompose.evolve.NOISY_DEFAULT``): 4 islands of 150, 3 episodes per evaluation that a
whole generation shares (common random numbers), the two best kept, tournaments of 3,
initial FSAs of 12 nodes, parameter noise on every child's nodes (``p_param`` 0.3), and a run
solved only when its exported FSA holds on fresh episodes (``require_holds``: the one-sided
95 % lower bound of its success rate at the task's 0.99). Chosen on pour water's tuning
seeds 100-119 (docs/evolve.md, "The default for noisy tasks"), none of the seeds run here."""


@dataclass(frozen=True)
class Run:
    seed: int
    solved: bool
    generations: int
    evaluations: int
    wall_time: float
    states_evolved: int
    states_simplified: int
    solved_rate_evolved: float  # fresh runs at p_fail = 0.2 that pour the water
    solved_rate: float  # the same for the simplified FSA
    pr2_rate: float  # episodes on the kinematic PR2 model that pour, simplified FSA
    dynamic_rate: float  # episodes on the PR2 in MuJoCo that pour, simplified FSA
    fsa_evolved: FSA
    fsa: FSA  # simplified

    @property
    def best_variant(self) -> tuple[float, str, FSA]:
        """The evolved or the simplified FSA, whichever pours more often."""
        if self.solved_rate >= self.solved_rate_evolved:
            return self.solved_rate, "simplified", self.fsa
        return self.solved_rate_evolved, "evolved", self.fsa_evolved


def _pour_rate(task: Task, fsa: FSA, episodes: int) -> float:
    """The share of ``episodes`` (seed 10,000) of ``task``'s backend in which ``fsa`` pours."""
    scores = [t.fitness for t in task.each_trial(task.compile(fsa), 10_000, episodes)]
    return sum(f == 0.0 for f in scores) / episodes


def run_config(
    name: str, cfg: EvolutionConfig, seeds: Sequence[int], check_reps: int
) -> list[Run]:
    task = load_task(TASK, p_fail=0.2)
    pr2 = load_task(TASK, backend="kinematic")
    dynamic = load_task(TASK, backend="dynamic")
    runs = []
    for seed in seeds:
        r = evolve(task, cfg, seed=seed, workers=1, backend="serial")
        (row,) = robustness_sweep(r.best_fsa, TASK, [0.2], reps=check_reps, seed=10_000)
        (row_evolved,) = robustness_sweep(r.evolved_fsa, TASK, [0.2], reps=check_reps,
                                          seed=10_000)
        pr2_rate = _pour_rate(pr2, r.best_fsa, PR2_EPISODES)
        dynamic_rate = _pour_rate(dynamic, r.best_fsa, DYNAMIC_EPISODES)
        runs.append(Run(
            seed=seed, solved=r.solved, generations=r.generations, evaluations=r.evaluations,
            wall_time=r.wall_time, states_evolved=len(r.evolved_fsa.states),
            states_simplified=len(r.best_fsa.states),
            solved_rate_evolved=row_evolved.solved_rate, solved_rate=row.solved_rate,
            pr2_rate=pr2_rate, dynamic_rate=dynamic_rate, fsa_evolved=r.evolved_fsa,
            fsa=r.best_fsa,
        ))
        print(f"{name} seed {seed}: solved={r.solved} generations={r.generations} "
              f"episodes={r.evaluations} wall={r.wall_time:.1f}s states "
              f"{len(r.evolved_fsa.states)}->{len(r.best_fsa.states)} "
              f"solved at p_fail 0.2: evolved {row_evolved.solved_rate:.3f}, simplified "
              f"{row.solved_rate:.3f}, PR2 model {pr2_rate:.2f}, MuJoCo {dynamic_rate:.2f}",
              file=sys.stderr, flush=True)
    return runs


def _stats(values: Sequence[float], fmt: str) -> str:
    return (f"{format(statistics.median(values), fmt)} "
            f"({format(min(values), fmt)}–{format(max(values), fmt)})")


def _config_line(cfg: EvolutionConfig) -> str:
    default = EvolutionConfig()
    changed = {k: v for k, v in cfg.to_dict().items() if v != getattr(default, k)}
    return ", ".join(f"`{k}={v}`" for k, v in changed.items()) or "table 1 defaults"


def _runs_table(runs: Sequence[Run]) -> list[str]:
    out = [
        "| seed | solved | generations | episodes | wall time [s] | states evolved → "
        "simplified | solved rate at p_fail 0.2, evolved | simplified | PR2 model | MuJoCo |",
        "|---:|:---:|---:|---:|---:|:---:|---:|---:|---:|---:|",
    ]
    for r in runs:
        out.append(
            f"| {r.seed} | {'yes' if r.solved else 'no'} | {r.generations} | "
            f"{r.evaluations} | {r.wall_time:.1f} | {r.states_evolved} → "
            f"{r.states_simplified} | {r.solved_rate_evolved:.3f} | {r.solved_rate:.3f} | "
            f"{r.pr2_rate:.2f} | {r.dynamic_rate:.2f} |"
        )
    return out


def _summary(name: str, runs: Sequence[Run]) -> str:
    return (
        f"| {name} | {sum(r.solved for r in runs)}/{len(runs)} | "
        f"{_stats([r.generations for r in runs], '.0f')} | "
        f"{_stats([r.evaluations for r in runs], '.0f')} | "
        f"{_stats([r.wall_time for r in runs], '.1f')} | "
        f"{_stats([r.states_evolved for r in runs], '.0f')} | "
        f"{_stats([r.states_simplified for r in runs], '.0f')} | "
        f"{_stats([r.solved_rate_evolved for r in runs], '.3f')} | "
        f"{_stats([r.solved_rate for r in runs], '.3f')} | "
        f"{sum(r.pr2_rate == 1.0 for r in runs)}/{len(runs)} | "
        f"{sum(r.dynamic_rate == 1.0 for r in runs)}/{len(runs)} |"
    )


def _sweep_table(rows: Sequence[SweepRow]) -> list[str]:
    out = ["| p_fail | mean fitness | std | solved rate | timeout rate |",
           "|---:|---:|---:|---:|---:|"]
    for r in rows:
        out.append(f"| {r.value:.2f} | {r.mean:.4g} | {r.std:.4g} | {r.solved_rate:.4f} | "
                   f"{r.timeout_rate:.4f} |")
    return out


def _below(rows: Sequence[SweepRow], limit: float) -> float:
    return min(r.solved_rate for r in rows if r.value < limit)


def report(
    paper: Sequence[Run], ours: Sequence[Run], best: Run, sweep: Sequence[SweepRow],
    ref_sweep: Sequence[SweepRow], args: argparse.Namespace, total_wall: float,
) -> str:
    _, variant, best_fsa = best.best_variant
    med_paper = statistics.median(r.generations for r in paper)
    med_ours = statistics.median(r.generations for r in ours)
    quarter = PAPER_GENERATIONS / 4
    lines = [
        "# Pouring water (paper section 4.1): reproduction",
        "",
        "Written by `benchmarks/reproduce_pour_water.py`; every number below was measured by "
        "that run. Do not edit by hand: rerun the script.",
        "",
        f"Command: `python benchmarks/reproduce_pour_water.py --seeds {args.seeds} "
        f"--reps {args.reps} --check-reps {args.check_reps} --generations {args.generations}`"
        f"  ",
        f"Machine: {os.cpu_count()} CPUs, {platform.machine()}, Python "
        f"{platform.python_version()}, NumPy {np.__version__}; each evolution ran serially on "
        f"one core. Total time of the script: {total_wall / 60:.1f} min.",
        "",
        "Task: `examples.pour_water` with `p_fail=0.2` (the paper's failure probability), "
        "step limit 20, fitness equation (1), one episode per evaluation unless said. A run "
        "of table 1 *solves* when the best individual of a generation has fitness 0 (the "
        "water is in the glass in every episode of its evaluation, here one); a run of ours "
        "when, besides, its exported FSA holds on fresh episodes (the one-sided 95 % lower "
        "bound of its success rate reaches the task's 0.99). The *solved rate* checks the "
        "exported "
        f"FSA afterwards on {args.check_reps} fresh episodes at p_fail 0.2, as evolved and "
        "after `skillcompose.evolve.simplify`; *PR2 model* runs the simplified FSA, unchanged, "
        f"on {PR2_EPISODES} episodes of the kinematic backend (IK, joint limits, the table, "
        f"the glass) and gives the share that pours; *MuJoCo* on {DYNAMIC_EPISODES} episodes "
        "of the dynamic backend (the PR2 in MuJoCo, the water as particles; "
        "docs/robots.md).",
        "",
        "World: the paper's fixed table of section 4.1. The abstract pouring rule is the one "
        "measured against MuJoCo (`benchmarks/pour_rule.py`, docs/results/pour_rule.md): "
        "the water leaves when the jug tips past level, over the lowest point of its mouth, "
        "and lands in the glass when that point stays within 2 cm of the rim's centre, the "
        "jug turned along the shortest turn and never into the glass. With the task's "
        "default `reach=pr2`, the abstract skills pour only from a pose the PR2's arm can "
        "take without touching the glass (`skillcompose.skills.pour_robot`). The paper's "
        "abstract world has no such check (`--set reach=free`); "
        "`benchmarks/transfer_pour.py` runs the shipped FSAs on all three backends.",
        "",
        "## Evolution",
        "",
        f"- Paper (table 1): {_config_line(PAPER)} — N=300, p_mut=0.1, p_cross=0.1, "
        "p_add=0.2, p_del=0.01, S=50.",
        "- Ours, the default (`skillcompose evolve examples.pour_water` with no options): "
        f"{_config_line(OURS)}.",
        "",
        "Median (min–max) over the seeds:",
        "",
        "| settings | solved | generations to solve | episodes to solve | wall time [s] | "
        "states evolved | states simplified | solved rate at p_fail 0.2, evolved | "
        "simplified | runs whose FSA pours on the PR2 model in every episode | "
        "... in MuJoCo |",
        "|---|:---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        f"| paper's result | 1/1 | {PAPER_GENERATIONS} | — | — | {PAPER_STATES} | — | — | — "
        "| — | — |",
        _summary("table 1 (ours, measured)", paper),
        _summary("our default", ours),
        "",
        "Targets of the issue, as measured:",
        "",
        "- every seed solves with our default: "
        f"**{'yes' if all(r.solved for r in ours) else 'no'}**"
        f" ({sum(r.solved for r in ours)}/{len(ours)}; with table 1: "
        f"{sum(r.solved for r in paper)}/{len(paper)});",
        f"- median generations at most a quarter of the paper's ({quarter:.1f}): "
        f"**{'yes' if med_ours <= quarter else 'no'}** (median {med_ours:.0f}; table 1 here: "
        f"{med_paper:.0f}; a run that did not solve counts with its whole budget of "
        f"{args.generations} generations);",
        f"- under a minute of wall time: **"
        f"{'yes' if max(r.wall_time for r in ours) < 60 else 'no'}** (our default: median "
        f"{statistics.median(r.wall_time for r in ours):.1f} s, max "
        f"{max(r.wall_time for r in ours):.1f} s).",
        "",
        "Per seed, table 1 settings:",
        "",
        *_runs_table(paper),
        "",
        "Per seed, our default:",
        "",
        *_runs_table(ours),
        "",
        "## Robustness of the best FSA (figure 7)",
        "",
        f"The best FSA evolved with our default (seed {best.seed}, {variant}, "
        f"{len(best_fsa.states)} states; the highest solved rate at p_fail 0.2 of all runs "
        "and both variants) is `pour_water_best.fsa.yaml`. It was run "
        f"{args.reps} times at each failure probability from 0 to 1 "
        "(`skillcompose robustness`), as in figure 7: ",
        "",
        "![robustness](pour_water_robustness.png)",
        "",
        "The paper: *\"with failure probabilities less than 0.5 the FSA correctly solves the "
        "task almost all of the time\"*. Measured: the lowest solved rate below p_fail 0.5 is "
        f"**{_below(sweep, 0.5):.4f}** for the best evolved FSA and "
        f"**{_below(ref_sweep, 0.5):.4f}** for the hand-written reference "
        "(`examples/pour_water_reference.fsa.yaml`).",
        "",
        "Best evolved FSA:",
        "",
        *_sweep_table(sweep),
        "",
        "Hand-written reference:",
        "",
        *_sweep_table(ref_sweep),
        "",
    ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=10, help="seeds 0..N-1 (default 10)")
    p.add_argument("--generations", type=int, default=2000,
                   help="generation budget of each run (default 2000)")
    p.add_argument("--reps", type=int, default=5000,
                   help="runs per failure probability in the sweep (default 5000, the paper's)")
    p.add_argument("--check-reps", type=int, default=1000,
                   help="fresh runs to check each evolved FSA at p_fail 0.2 (default 1000)")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   help="processes for the sweeps (evolution runs stay serial)")
    p.add_argument("--out", type=output_dir,
                   default=str(Path(__file__).resolve().parents[1] / "docs" / "results"),
                   help="output folder (default docs/results)")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    seeds = list(range(args.seeds))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    paper = run_config("table 1", PAPER.replace(generations=args.generations), seeds,
                       args.check_reps)
    ours = run_config("ours", OURS.replace(generations=args.generations), seeds,
                      args.check_reps)
    best = max(ours, key=lambda r: (r.best_variant[0], -len(r.best_variant[2].states),
                                     -r.seed))
    _, variant, best_fsa = best.best_variant
    task = load_task(TASK)
    save_fsa(best_fsa, out / "pour_water_best.fsa.yaml", task.registry,
             header="The best pour-water FSA of benchmarks/reproduce_pour_water.py "
             f"(our default, seed {best.seed}, {variant}). Edit and rerun it freely.")
    grid = [round(x, 2) for x in np.linspace(0, 1, 21)]
    sweep = robustness_sweep(best_fsa, TASK, grid, reps=args.reps, seed=0,
                             workers=args.workers)
    write_csv(sweep, out / "pour_water_robustness.csv")
    plot_sweep(sweep, out / "pour_water_robustness.png",
               title=f"best evolved FSA (seed {best.seed}), {args.reps} runs per point")
    ref_sweep = robustness_sweep(REFERENCE, TASK, grid, reps=args.reps, seed=0,
                                 workers=args.workers)
    write_csv(ref_sweep, out / "pour_water_reference_robustness.csv")
    text = report(paper, ours, best, sweep, ref_sweep, args, time.perf_counter() - t0)
    (out / "pour_water.md").write_text(text, encoding="utf-8")
    print(f"wrote {out / 'pour_water.md'}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
