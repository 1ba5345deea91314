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
    """The options of ``skillcompose evolve``, each checked where it is parsed."""
    from skillcompose.arguments import (
        MAX_TRIALS,
        MAX_WORKERS,
        existing_dir,
        module_or_file,
        number,
        output_dir,
        seed,
        setting,
        whole,
    )

    big = 10**7  # generations, individuals, trials: bounded, far beyond any real run
    p.add_argument(
        "task", nargs="?", type=module_or_file,
        help="task module (dotted name or .py path) defining make_task(**settings); "
        "may be left out with --resume",
    )
    p.add_argument("--set", dest="settings", action="append", default=[], metavar="NAME=VALUE",
                   type=setting,
                   help="a task setting passed to make_task (repeatable), e.g. p_fail=0.2")
    p.add_argument("--generations", type=whole(0, big), help="generation budget (default 1000)")
    p.add_argument("--population", type=whole(2, 10**6),
                   help="individuals N (default 300, table 1)")
    p.add_argument("--initial-nodes", type=whole(1, 10_000),
                   help="initial nodes S (default 50, table 1)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="paper",
                   help="starting settings: paper (table 1, the default) or robust (our best "
                   "options: N=600, 3 shared trials, elitism 2, tournament 3, S=12, sigma "
                   "0.1, solutions confirmed on 20 fresh trials); the flags below override it")
    p.add_argument("--tournament", type=whole(1, 10**6), help="tournament size (default 2)")
    p.add_argument("--param-sigma", type=number(0.0, 1.0),
                   help="standard deviation of parameter noise in [0, 1] units, from 0 to 1 "
                   "(default 0.05)")
    p.add_argument("--seed", type=seed, default=0, help="run seed (default 0)")
    p.add_argument("--workers", type=whole(1, MAX_WORKERS), default=None,
                   help="evaluation workers, at least 1 (default: all cores for process/ray)")
    p.add_argument("--backend", choices=BACKENDS, default=None,
                   help="where to evaluate: serial, a local process pool, or Ray "
                   "(default: a process pool on all cores, serial on one core or with "
                   "--workers 1)")
    p.add_argument("--out", type=output_dir,
                   help="run directory: best FSA, drawing, history, plot, checkpoints")
    p.add_argument("--resume", metavar="DIR", type=existing_dir,
                   help="continue the run in DIR from its checkpoint")
    p.add_argument("--seed-fsa", metavar="FILE",
                   help="an FSA file placed in the first population (hand-edit, then re-evolve)")
    p.add_argument("--trials", type=whole(1, MAX_TRIALS),
                   help=f"episodes per evaluation, 1 to {MAX_TRIALS} (default: the task's)")
    p.add_argument("--elitism", type=whole(0, 10**6), help="copy the best K unchanged (default 0)")
    p.add_argument("--crn", action="store_true",
                   help="common random numbers: a generation's individuals meet the same worlds")
    p.add_argument("--cache", action="store_true", help="do not re-evaluate unchanged genomes")
    p.add_argument("--cache-refresh", type=whole(0, MAX_TRIALS),
                   help="with --cache, fresh trials added each time a genome reappears")
    p.add_argument("--parsimony", action="store_true", help="fewer states wins at equal fitness")
    p.add_argument("--confirm", type=whole(0, MAX_TRIALS), dest="confirm_trials",
                   help="fresh trials that must confirm a solution before the run stops")
    p.add_argument("--checkpoint-every", type=whole(1, big),
                   help="generations between checkpoints (10)")
    p.add_argument("--no-simplify", action="store_true",
                   help="export the best FSA as evolved, without simplification")
    p.add_argument("--simplify-trials", type=whole(1, MAX_TRIALS), default=200,
                   help="fresh trials per simplification test, at least 1 (default 200)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _config(args: argparse.Namespace) -> EvolutionConfig:
    changes: dict[str, Any] = dict(PRESETS[args.preset])
    for opt, name in (
        ("generations", "generations"), ("population", "population"),
        ("initial_nodes", "initial_nodes"), ("trials", "trials"), ("elitism", "elitism"),
        ("tournament", "tournament"), ("param_sigma", "param_sigma"),
        ("confirm_trials", "confirm_trials"),
        ("cache_refresh", "cache_refresh"), ("checkpoint_every", "checkpoint_every"),
    ):
        v = getattr(args, opt)
        if v is not None:
            changes[name] = v
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
    if result.files:
        print("files written:")
        for f in result.files:
            print(f"  {f}")
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
