"""Transfer of the pour-water FSAs: the same files on the sim, kinematic and dynamic backends.

Runs the hand-written reference (``examples/pour_water_reference.fsa.yaml``), the evolved
FSA (``docs/results/pour_water_best.fsa.yaml``) and, when it exists, the one evolved against
the physics (``docs/results/pour_water_physics.fsa.yaml``, ``--evolve-physics SEED``) on
``examples.pour_water`` with ``backend=sim`` (the paper's ``p_fail`` 0.2), ``kinematic``
and ``dynamic`` (the PR2 in MuJoCo, water as particles), the same seeds on each, and writes
what poured, why the rest did not, and how fast::

    nice -n 10 python benchmarks/transfer_pour.py              # 100 runs per FSA and backend
    python benchmarks/transfer_pour.py --evolve-physics 0      # evolve the reach=physics FSA too
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
import time
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from skillcompose import load_fsa
from skillcompose.files import atomic_write
from skillcompose.skills.dynamic_world import world_of
from skillcompose.task import load_task

ROOT = Path(__file__).resolve().parents[1]
FSAS = {
    "reference": ROOT / "examples" / "pour_water_reference.fsa.yaml",
    "evolved": ROOT / "docs" / "results" / "pour_water_best.fsa.yaml",
    "evolved, reach=physics": ROOT / "docs" / "results" / "pour_water_physics.fsa.yaml",
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
    from skillcompose.evolve import EvolutionConfig, evolve
    from skillcompose.evolve.config import preset_settings

    task = load_task(TASK, reach="physics")
    cfg = EvolutionConfig(**{**preset_settings("default", task.deterministic),
                             "generations": generations})
    result = evolve(task, cfg, seed=seed, workers=1, backend="serial")
    save_fsa(result.best_fsa, FSAS["evolved, reach=physics"], header=(
        "The best pour-water FSA evolved with reach=physics (the abstract skills pour only "
        "where the PR2 in MuJoCo does) by benchmarks/transfer_pour.py --evolve-physics "
        f"{seed}. Edit and rerun it freely."))
    return {"seed": seed, "solved": result.solved, "generations": result.generations,
            "episodes": result.evaluations, "wall_s": result.wall_time,
            "fresh": result.fresh}


def _rate(per_s: float) -> str:
    return f"{per_s:,.0f}" if per_s >= 10 else f"{per_s:.2f}"


def report(rows: dict[str, list[dict[str, Any]]], runs: int, seed: int,
           evolved_physics: dict[str, Any] | None = None) -> str:
    lines = [
        "# Pour water: the same FSAs on three backends",
        "",
        f"Written by `benchmarks/transfer_pour.py --runs {runs} --seed {seed}`: each FSA "
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
              "`benchmarks/reproduce_pour_water.py` (its world: the task's default "
              "`reach=pr2`, the abstract skills pour only from a pose the PR2 model can take); "
              "`evolved, reach=physics` is docs/results/pour_water_physics.fsa.yaml, evolved "
              "by this script with the default preset on `reach=physics` (the abstract skills "
              "pour only from a pose from which the PR2 in MuJoCo pours)."]
    if evolved_physics is not None:
        e = evolved_physics
        fresh = e["fresh"] or {}
        lines += ["", f"This run evolved it (`--evolve-physics {e['seed']}`): "
                  f"{'solved' if e['solved'] else 'not solved'} after {e['generations']} "
                  f"generations, {e['episodes']:,} episodes, {e['wall_s']:.0f} s; its exported "
                  f"FSA on fresh abstract episodes: {100 * fresh.get('success_rate', 0):.1f} % "
                  f"of {fresh.get('episodes', 0)}."]
    lines += ["", "## Runs that did not pour, by cause", ""]
    for name, per_backend in rows.items():
        for row in per_backend:
            if not row["causes"]:
                continue
            lines.append(f"- **{name}, {row['backend']}**: " + "; ".join(
                f"{cause}: {count}" for cause, count in row["causes"].items()))
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
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results")
    parser.add_argument("--evolve-physics", type=int, default=None, metavar="SEED",
                        help="first evolve the reach=physics FSA with this seed (writes "
                             "docs/results/pour_water_physics.fsa.yaml; tens of minutes)")
    parser.add_argument("--generations", type=int, default=1000,
                        help="generation budget of --evolve-physics")
    args = parser.parse_args(argv)
    if args.runs < 1:
        parser.error("--runs must be at least 1")
    evolved_physics = None
    if args.evolve_physics is not None:
        evolved_physics = evolve_physics(args.evolve_physics, args.generations)
        print(f"evolved with reach=physics: {evolved_physics}", flush=True)
    rows: dict[str, list[dict[str, Any]]] = {}
    for name, path in FSAS.items():
        if not path.is_file():
            print(f"{name}: {path.relative_to(ROOT)} does not exist (--evolve-physics SEED "
                  "writes it); not measured", flush=True)
            continue
        for backend in args.backends:
            row = measure(path, backend, args.runs, args.seed)
            rows.setdefault(name, []).append(row)
            print(f"{name:9s} {backend:9s} poured {row['poured']}/{row['runs']} "
                  f"{row['episodes_per_s']:.1f} episodes/s {row['causes'] or ''}", flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write(args.out / "transfer_pour.md",
                 report(rows, args.runs, args.seed, evolved_physics).encode())
    atomic_write(args.out / "transfer_pour.json", (json.dumps(
        {"runs": args.runs, "seed": args.seed, "task": TASK, "fsas": {
            k: str(v.relative_to(ROOT)) for k, v in FSAS.items() if k in rows},
         "evolved_physics": evolved_physics, "results": rows},
        indent=2) + "\n").encode())
    print(f"wrote {args.out / 'transfer_pour.md'} and .json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
