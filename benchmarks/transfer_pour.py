"""Transfer of the pour-water FSAs: the same files on the sim, kinematic and dynamic backends.

Runs the hand-written reference (``examples/pour_water_reference.fsa.yaml``), the evolved
FSA (``docs/results/pour_water_best.fsa.yaml``) and, when it exists, the one evolved against
the physics (``docs/results/pour_water_physics.fsa.yaml``, ``--evolve-physics SEED``) on
``examples.pour_water`` with ``backend=sim`` (the paper's ``p_fail`` 0.2), ``kinematic``
and ``dynamic`` (the PR2 in MuJoCo, water as particles), the same seeds on each, and writes
what poured, why the rest did not, and how fast::

    nice -n 10 python benchmarks/transfer_pour.py              # 100 runs per FSA and backend
    python benchmarks/transfer_pour.py --evolve-physics 0      # evolve the reach=physics FSA too
    python benchmarks/transfer_pour.py --finetune-dynamic 1    # and fine-tune on dynamic
    python benchmarks/transfer_pour.py --runs 5 --out /tmp/tp  # a quick look

A run *pours* when its fitness is 0 (equation (1): CheckSuccess's ``success`` with the water
in the glass; on ``dynamic``, at least 80 % of the particles in the simulated glass). A run
that does not is counted by its cause: the outcome, ``last_failure_reason`` (the skill's
reason, kinematic or physical), and where the water ended (``water``; on ``dynamic`` the
particles in the glass). Writes ``transfer_pour.md`` and ``transfer_pour.json`` in ``--out``
(default ``docs/results``). Serial, one process: wall times are one core's of this machine.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from skillcompose import load_fsa
from skillcompose.arguments import output_folder
from skillcompose.files import atomic_write
from skillcompose.skills.dynamic_world import world_of
from skillcompose.task import load_task

ROOT = Path(__file__).resolve().parents[1]
FSAS = {
    "reference": ROOT / "examples" / "pour_water_reference.fsa.yaml",
    "evolved": ROOT / "docs" / "results" / "pour_water_best.fsa.yaml",
    "evolved, reach=physics": ROOT / "docs" / "results" / "pour_water_physics.fsa.yaml",
    "evolved, fine-tuned on dynamic": ROOT / "docs" / "results" / "pour_water_finetuned.fsa.yaml",
}
"""The FSAs measured: the hand-written one, the best of ``reproduce_pour_water.py`` (evolved
with the task's default ``reach=pr2``), and one evolved with ``reach=physics`` by this script
(``--evolve-physics SEED``; measured when its file exists)."""
BACKENDS = ("sim", "kinematic", "dynamic")
TASK = "examples.pour_water"


def measure(fsa: Path, backend: str, runs: int, seed: int) -> dict[str, Any]:
    """``runs`` episodes of ``fsa`` on ``backend`` from ``seed``: poured, causes, speed."""
    task = load_task(TASK, backend=backend)
    compiled = task.compile(load_fsa(fsa))
    world = world_of(task.registry)
    poured = 0
    outcomes: Counter[str] = Counter()
    causes: Counter[str] = Counter()
    in_glass: Counter[int] = Counter()
    simulated_s = 0.0
    start, cpu = time.perf_counter(), time.process_time()
    for trial in task.each_trial(compiled, seed, runs):
        bb = trial.blackboard
        outcomes[trial.result.outcome] += 1
        physics = world.physics if world is not None else None
        if physics is not None:
            simulated_s += physics.time_s
            in_glass[physics.particles_in("glass")] += 1
        if trial.fitness == 0.0:
            poured += 1
            continue
        reason = None if bb is None else bb.get("last_failure_reason")
        water = None if bb is None else bb.get("water")
        causes[f"{trial.result.outcome}, last reason {reason or '-'}, water {water}"] += 1
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    row: dict[str, Any] = {
        "backend": backend, "runs": runs, "poured": poured, "outcomes": dict(outcomes),
        "causes": dict(causes.most_common()), "wall_s": wall, "cpu_s": cpu,
        "episodes_per_s": runs / wall,
    }
    if world is not None:
        row.update(simulated_s=simulated_s, sim_per_wall=simulated_s / wall,
                   sim_per_cpu=simulated_s / cpu,
                   particles_in_glass={str(k): v for k, v in sorted(in_glass.items())})
    return row


def evolve_physics(seed: int, generations: int) -> dict[str, Any]:
    """Evolve pour water with ``reach=physics`` (the default preset, serially: the physics
    checks are cached per process) and write its best FSA where :data:`FSAS` looks."""
    from skillcompose import save_fsa
    from skillcompose.evolve import EvolutionConfig, evolve, task_preset

    task = load_task(TASK, reach="physics")
    cfg = EvolutionConfig(**{**task_preset("default", task), "generations": generations})
    result = evolve(task, cfg, seed=seed, workers=1, backend="serial")
    save_fsa(result.best_fsa, FSAS["evolved, reach=physics"], header=(
        "The best pour-water FSA evolved with reach=physics (the abstract skills pour only "
        "where the PR2 in MuJoCo does) by benchmarks/transfer_pour.py --evolve-physics "
        f"{seed}. Edit and rerun it freely."))
    return {"seed": seed, "solved": result.solved, "generations": result.generations,
            "episodes": result.evaluations, "wall_s": result.wall_time,
            "fresh": result.fresh}


def finetune_dynamic(seed: int, episodes: int) -> dict[str, Any]:
    """Fine-tune the reproduction's evolved FSA on the dynamic backend (``--seed-fsa``):
    parameters only (every child's perturbed, noise 0.1 of each range), a population of 8,
    one episode per evaluation, the two best kept, within ``episodes``; its best FSA is
    written where :data:`FSAS` looks. The pour world is fixed, so an episode judges the FSA
    itself; the run stops at the first evaluation that pours (fitness 0)."""
    from skillcompose import save_fsa
    from skillcompose.evolve import EvolutionConfig, evolve

    task = load_task(TASK, backend="dynamic")
    cfg = EvolutionConfig(population=8, trials=1, common_random_numbers=True, elitism=2,
                          tournament=3, initial_nodes=12, param_sigma=0.1, p_param=1.0,
                          p_cross=0.0, p_add=0.0, p_del=0.0, max_episodes=episodes,
                          generations=10**6)
    result = evolve(task, cfg, seed=seed, workers=2, backend="process",
                    seed_fsa=FSAS["evolved"], simplify_result=False, check_trials=0)
    save_fsa(result.best_fsa, FSAS["evolved, fine-tuned on dynamic"], header=(
        "The reproduction's evolved pour-water FSA fine-tuned on the dynamic backend (the "
        f"PR2 in MuJoCo) by benchmarks/transfer_pour.py --finetune-dynamic {seed}. Edit and "
        "rerun it freely."))
    return {"seed": seed, "solved": result.solved, "generations": result.generations,
            "episodes": result.evaluations, "wall_s": result.wall_time,
            "best_fitness": result.best_fitness,
            "history": [[r.generation, r.best, r.mean] for r in result.history]}


def _rate(per_s: float) -> str:
    return f"{per_s:,.0f}" if per_s >= 10 else f"{per_s:.2f}"


def report(rows: dict[str, list[dict[str, Any]]], runs: int, seed: int,
           evolved_physics: dict[str, Any] | None = None,
           finetuned: dict[str, Any] | None = None, command: str = "") -> str:
    lines = [
        "# Pour water: the same FSAs on three backends",
        "",
        f"Written by `benchmarks/transfer_pour.py {command}`: each FSA "
        f"{runs} times per backend with the same seeds, on `{TASK}` with `backend=sim` "
        "(p_fail 0.2, the paper's), `kinematic` and `dynamic` (the PR2 in MuJoCo; "
        "see docs/robots.md, \"The dynamic backend: pouring water\"). A run pours when its "
        "fitness is 0: CheckSuccess's `success` with the water in the glass (on `dynamic`, "
        ">= 80 % of the particles in the simulated glass). Serial, one core of a shared "
        f"{os.cpu_count()}-core machine ({platform.machine()}, Python "
        f"{platform.python_version()}); `sim s / wall s` is simulated time per wall-clock "
        "second, `sim s / cpu s` per second of this process's CPU time, which other load "
        "disturbs less.",
        "",
        "| FSA | backend | poured | outcomes | episodes / s | sim s / wall s | "
        "sim s / cpu s |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, per_backend in rows.items():
        for row in per_backend:
            speed = (f"{row['sim_per_wall']:.1f} | {row['sim_per_cpu']:.1f}"
                     if "sim_per_wall" in row else "- | -")
            outcomes = ", ".join(f"{k} {v}" for k, v in sorted(row["outcomes"].items()))
            lines.append(f"| {name} | {row['backend']} | {row['poured']} / {row['runs']} | "
                         f"{outcomes} | {_rate(row['episodes_per_s'])} | {speed} |")
    lines += ["", "The FSAs: `reference` is examples/pour_water_reference.fsa.yaml, written by "
              "hand; `evolved` is docs/results/pour_water_best.fsa.yaml, the best of "
              "`benchmarks/reproduce_pour_water.py` (its world: the abstract pouring rule "
              "measured against MuJoCo by `benchmarks/pour_rule.py`, and the task's default "
              "`reach=pr2`: the abstract skills pour only from a pose the PR2 model can take)"
              + ("; `evolved, reach=physics` is docs/results/pour_water_physics.fsa.yaml, "
                 "evolved by this script with the default preset on `reach=physics` (the "
                 "abstract skills pour only from a pose from which the PR2 in MuJoCo pours)"
                 if "evolved, reach=physics" in rows else "") + "."]
    if evolved_physics is not None:
        e = evolved_physics
        fresh = e["fresh"] or {}
        lines += ["", f"It was evolved by `--evolve-physics {e['seed']}`: "
                  f"{'solved' if e['solved'] else 'not solved'} after {e['generations']} "
                  f"generations, {e['episodes']:,} episodes, {e['wall_s']:.0f} s; its exported "
                  f"FSA on fresh abstract episodes: {100 * fresh.get('success_rate', 0):.1f} % "
                  f"of {fresh.get('episodes', 0)}."]
    if finetuned is not None:
        f = finetuned
        lines += ["", "`evolved, fine-tuned on dynamic` is docs/results/pour_water_finetuned"
                  ".fsa.yaml: `evolved` fine-tuned on the dynamic backend (`--seed-fsa`; "
                  f"`--finetune-dynamic {f['seed']}`): parameters only, a population of 8, one "
                  "episode per evaluation on the fixed pour world, every child's parameters "
                  f"perturbed (noise 0.1). It ran {f['generations']} generations, "
                  f"{f['episodes']} episodes, {f['wall_s']:.0f} s on 2 workers, and "
                  f"{'reached fitness 0 (poured)' if f['solved'] else 'did not pour'}; best "
                  "per generation: " + ", ".join(f"{b:.4g}" for _, b, _ in f["history"])
                  + "."]
    lines += ["", "## Runs that did not pour, by cause", ""]
    causes = [f"- **{name}, {row['backend']}**: " + "; ".join(
        f"{cause}: {count}" for cause, count in row["causes"].items())
        for name, per_backend in rows.items() for row in per_backend if row["causes"]]
    lines += causes or ["- none: every run of every FSA poured"]
    lines += ["", "## Particles in the glass at the end (dynamic)", ""]
    for name, per_backend in rows.items():
        for row in per_backend:
            if "particles_in_glass" in row:
                lines.append(f"- **{name}**: " + ", ".join(
                    f"{k} particles: {v} runs" for k, v in row["particles_in_glass"].items()))
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100, help="episodes per FSA and backend")
    parser.add_argument("--seed", type=int, default=0, help="seed of the episodes")
    parser.add_argument("--backends", nargs="+", choices=BACKENDS, default=list(BACKENDS))
    parser.add_argument("--out", type=output_folder, default=ROOT / "docs" / "results")
    parser.add_argument("--evolve-physics", type=int, default=None, metavar="SEED",
                        help="first evolve the reach=physics FSA with this seed (writes "
                             "docs/results/pour_water_physics.fsa.yaml; tens of minutes)")
    parser.add_argument("--generations", type=int, default=1000,
                        help="generation budget of --evolve-physics")
    parser.add_argument("--finetune-dynamic", type=int, default=None, metavar="SEED",
                        help="first fine-tune the evolved FSA on the dynamic backend with this "
                             "seed (writes docs/results/pour_water_finetuned.fsa.yaml)")
    parser.add_argument("--finetune-episodes", type=int, default=240,
                        help="episode budget of --finetune-dynamic")
    args = parser.parse_args(argv)
    if args.runs < 1:
        parser.error("--runs must be at least 1")
    # what an earlier run evolved is kept with its file, when this run does not redo it
    earlier = json.loads((args.out / "transfer_pour.json").read_text(encoding="utf-8")) \
        if (args.out / "transfer_pour.json").is_file() else {}
    # (only while the file it wrote is there to measure)
    evolved_physics = earlier.get("evolved_physics") \
        if FSAS["evolved, reach=physics"].is_file() else None
    if args.evolve_physics is not None:
        evolved_physics = evolve_physics(args.evolve_physics, args.generations)
        print(f"evolved with reach=physics: {evolved_physics}", flush=True)
    finetuned = earlier.get("finetuned") \
        if FSAS["evolved, fine-tuned on dynamic"].is_file() else None
    if args.finetune_dynamic is not None:
        finetuned = finetune_dynamic(args.finetune_dynamic, args.finetune_episodes)
        print(f"fine-tuned on dynamic: {finetuned}", flush=True)
    rows: dict[str, list[dict[str, Any]]] = {}
    for name, path in FSAS.items():
        if not path.is_file():
            print(f"{name}: {path.relative_to(ROOT)} does not exist (--evolve-physics SEED "
                  "or --finetune-dynamic SEED writes it); not measured", flush=True)
            continue
        for backend in args.backends:
            row = measure(path, backend, args.runs, args.seed)
            rows.setdefault(name, []).append(row)
            print(f"{name:9s} {backend:9s} poured {row['poured']}/{row['runs']} "
                  f"{row['episodes_per_s']:.1f} episodes/s {row['causes'] or ''}", flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write(args.out / "transfer_pour.md",
                 report(rows, args.runs, args.seed, evolved_physics, finetuned,
                        " ".join(sys.argv[1:] if argv is None else argv)).encode())
    atomic_write(args.out / "transfer_pour.json", (json.dumps(
        {"runs": args.runs, "seed": args.seed, "task": TASK, "fsas": {
            k: str(v.relative_to(ROOT)) for k, v in FSAS.items() if k in rows},
         "evolved_physics": evolved_physics, "finetuned": finetuned, "results": rows},
        indent=2) + "\n").encode())
    print(f"wrote {args.out / 'transfer_pour.md'} and .json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
