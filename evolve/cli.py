"""``skillcompose evolve``: evolve an FSA for a task from the command line.

::

    skillcompose evolve examples.toy_task --set p_fail=0.1 --generations 200 --out runs/toy
    skillcompose evolve --resume runs/toy            # continue a killed run
    skillcompose evolve examples.toy_task --seed-fsa edited.yaml --out runs/toy2

Wired into ``skillcompose`` by :func:`register_cli`; ``main(argv)`` runs it on its own.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from skillcompose.errors import SkillcomposeError
from skillcompose.task import load_task, parse_settings

from .algorithm import evolve
from .config import PRESETS, EvolutionConfig
from .errors import EvolutionError
from .evaluation import BACKENDS
from .rundir import RunDir

__all__ = ["add_arguments", "handle", "main", "register_cli"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "task", nargs="?",
        help="task module (dotted name or .py path) defining make_task(**settings); "
        "may be left out with --resume",
    )
    p.add_argument("--set", dest="settings", action="append", default=[], metavar="NAME=VALUE",
                   help="a task setting passed to make_task (repeatable), e.g. p_fail=0.2")
    p.add_argument("--generations", type=int, help="generation budget (default 1000)")
    p.add_argument("--population", type=int, help="individuals N (default 300, table 1)")
    p.add_argument("--initial-nodes", type=int, help="initial nodes S (default 50, table 1)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="paper",
                   help="starting settings: paper (table 1, the default), robust (our best "
                   "options: N=600, 3 shared trials, elitism 2, tournament 3, S=12, sigma "
                   "0.1, solutions confirmed on 20 fresh trials) or push (for many "
                   "parameters, e.g. a network's weights: N=300, the task's shared trials, "
                   "every mutated node's parameters perturbed, confirmed on 200 fresh "
                   "trials); the flags below override it")
    p.add_argument("--tournament", type=int, help="tournament size (default 2)")
    p.add_argument("--param-sigma", type=float,
                   help="standard deviation of parameter noise in [0, 1] units (default 0.05)")
    p.add_argument("--seed", type=int, default=0, help="run seed (default 0)")
    p.add_argument("--workers", type=int, default=None,
                   help="evaluation workers (default: all cores for process/ray)")
    p.add_argument("--backend", choices=BACKENDS, default=None,
                   help="where to evaluate: serial, a local process pool, or Ray "
                   "(default: a process pool on all cores, serial on one core or with "
                   "--workers 1)")
    p.add_argument("--out", help="run directory: best FSA, drawing, history, plot, checkpoints")
    p.add_argument("--resume", metavar="DIR", help="continue the run in DIR from its checkpoint")
    p.add_argument("--seed-fsa", metavar="FILE",
                   help="an FSA file placed in the first population (hand-edit, then re-evolve)")
    p.add_argument("--trials", type=int, help="episodes per evaluation (default: the task's)")
    p.add_argument("--elitism", type=int, help="copy the best K unchanged (default 0)")
    p.add_argument("--crn", action="store_true",
                   help="common random numbers: a generation's individuals meet the same worlds")
    p.add_argument("--cache", action="store_true", help="do not re-evaluate unchanged genomes")
    p.add_argument("--cache-refresh", type=int,
                   help="with --cache, fresh trials added each time a genome reappears")
    p.add_argument("--parsimony", action="store_true", help="fewer states wins at equal fitness")
    p.add_argument("--confirm", type=int, dest="confirm_trials",
                   help="fresh trials that must confirm a solution before the run stops")
    p.add_argument("--checkpoint-every", type=int, help="generations between checkpoints (10)")
    p.add_argument("--no-simplify", action="store_true",
                   help="export the best FSA as evolved, without simplification")
    p.add_argument("--simplify-trials", type=int, default=200,
                   help="fresh trials per simplification test (default 200)")
    p.add_argument("--check-trials", type=int, default=200,
                   help="fresh episodes on which the exported FSA is measured at the end "
                   "(default 200; 0: none)")
    p.add_argument("--eval-time-limit", type=float, metavar="SECONDS",
                   help="wall-clock limit of one evaluation; past it, it scores worst and "
                   "counts as a time-out (default 60; 0: no limit)")
    p.add_argument("--worker-max-jobs", type=int, metavar="N",
                   help="replace a worker after N evaluations (default 0: never)")
    p.add_argument("--worker-max-growth-mb", type=float, metavar="MB",
                   help="replace a worker whose memory grew by more than MB (default 1024; "
                   "0: never)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _config(args: argparse.Namespace) -> EvolutionConfig:
    changes: dict[str, Any] = dict(PRESETS[args.preset])
    for opt, name in (
        ("generations", "generations"), ("population", "population"),
        ("initial_nodes", "initial_nodes"), ("trials", "trials"), ("elitism", "elitism"),
        ("tournament", "tournament"), ("param_sigma", "param_sigma"),
        ("confirm_trials", "confirm_trials"),
        ("cache_refresh", "cache_refresh"), ("checkpoint_every", "checkpoint_every"),
        ("worker_max_jobs", "worker_max_jobs"),
        ("worker_max_growth_mb", "worker_max_growth_mb"),
    ):
        v = getattr(args, opt)
        if v is not None:
            changes[name] = v
    if args.eval_time_limit is not None:
        changes["eval_time_limit"] = args.eval_time_limit or None
    if args.crn:
        changes["common_random_numbers"] = True
    if args.cache:
        changes["cache"] = True
    if args.parsimony:
        changes["parsimony"] = True
    return EvolutionConfig(**changes)


def handle(args: argparse.Namespace) -> int:
    try:
        if args.resume:
            info = RunDir(args.resume).load_run_info()
            module = args.task or info.get("task_module")
            if not module:
                raise EvolutionError(
                    f"{args.resume}: the run's task module is unknown; give it: "
                    f"skillcompose evolve TASK --resume {args.resume}"
                )
            task = load_task(module, **dict(info.get("task_settings") or {}))
            cfg = None
            backend = args.backend or info.get("backend") or "serial"
            workers = args.workers if args.workers is not None else info.get("workers")
        else:
            if not args.task:
                raise EvolutionError(
                    "name a task module, e.g. `skillcompose evolve examples.toy_task`, "
                    "or continue a run with --resume DIR"
                )
            task = load_task(args.task, **parse_settings(args.settings))
            cfg = _config(args)
            cores = args.workers or os.cpu_count() or 1
            backend = args.backend or ("process" if cores > 1 else "serial")
            workers = args.workers
        result = evolve(
            task, cfg, seed=args.seed, workers=workers, backend=backend,
            out_dir=None if args.resume else args.out, seed_fsa=args.seed_fsa,
            progress=not args.quiet, resume=args.resume,
            simplify_result=not args.no_simplify, simplify_trials=args.simplify_trials,
            check_trials=args.check_trials,
        )
    except SkillcomposeError as exc:
        print(f"skillcompose evolve: error: {exc}", file=sys.stderr)
        return 2
    state = "solved" if result.solved else "not solved"
    print(
        f"{task.name}: {state}, best fitness {result.best_fitness:g} after "
        f"{result.generations} generations, {result.evaluations} evaluations, "
        f"{result.wall_time:.1f} s; best FSA has {len(result.best_fsa.states)} states "
        f"(evolved: {len(result.evolved_fsa.states)})"
    )
    fresh = result.fresh
    if fresh:
        print(
            f"the exported FSA on {fresh['episodes']} fresh episodes: "
            f"{100 * fresh['success_rate']:.1f} % reach the target, mean fitness "
            f"{fresh['mean_fitness']:g}"
        )
        if fresh["differs"]:
            print(
                f"warning: that differs from the evolved fitness {result.best_fitness:g}: "
                "evolution measured it on its own few episodes; trust the fresh ones "
                "(more trials per evaluation, --preset robust or --confirm N evolve FSAs "
                "that hold)", file=sys.stderr,
            )
    faults = result.faults
    if faults.total:
        print(f"faults: {faults.describe()} in {faults.jobs} evaluations "
              f"({faults.failed} failed entirely); per generation in history.jsonl",
              file=sys.stderr)
        if faults.first_error:
            print(f"first error {faults.first_error}", file=sys.stderr)
    if result.files:
        print("files written:")
        for f in result.files:
            print(f"  {f}")
    if result.nothing_succeeded:
        print(
            f"skillcompose evolve: error: every one of the {faults.jobs} evaluations failed "
            "(see the first error above); fix the task or its skills", file=sys.stderr,
        )
        return 1
    return 0


def register_cli(subparsers: Any) -> None:
    """Add ``evolve`` to the ``skillcompose`` command."""
    p = subparsers.add_parser(
        "evolve", help="evolve an FSA for a task (the paper's algorithm)",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_arguments(p)
    p.set_defaults(func=handle)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="skillcompose")
    register_cli(parser.add_subparsers(dest="command", required=True))
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":
    raise SystemExit(main())
