"""``skillcompose robustness``: the sweep of :mod:`skillcompose.robustness` from the command
line (``skillcompose robustness FILE --task T --p-fail 0:1:21 --reps 5000 -o fig.png``)."""

from __future__ import annotations

import argparse
import os
import shlex
import sys
from pathlib import Path
from typing import Any

from .arguments import (
    MAX_TRIALS,
    MAX_WORKERS,
    module_or_file,
    note,
    output_file,
    seed,
    setting,
    whole,
)
from .errors import one_line
from .fsa import ERROR, MAX_STEP_LIMIT
from .robustness import (
    MAX_SWEEP_POINTS,
    RobustnessError,
    format_table,
    parse_values,
    plot_sweep,
    robustness_sweep,
    write_csv,
)

__all__ = ["cmd_robustness", "register_cli"]


def register_cli(subparsers: Any) -> None:
    """Add ``skillcompose robustness`` to the command line."""
    p = subparsers.add_parser(
        "robustness",
        help="run an FSA file under a sweep of a task's failure probability (figure 7)",
        description="Run FILE --reps times at each value of the task setting --setting "
        "(p_fail by default), in parallel, and write the table (CSV) and the plot of mean "
        "fitness with standard-deviation bars.",
    )
    p.add_argument("file", help="the FSA file (YAML)")
    p.add_argument("--task", required=True, metavar="TASK", type=module_or_file,
                   help="the task module (dotted name or .py file) with make_task(**settings)")
    p.add_argument("--p-fail", dest="values", default="0:1:21", metavar="SWEEP",
                   type=_sweep_arg, help="values: START:STOP:COUNT or a comma list, at most "
                   f"{MAX_SWEEP_POINTS} finite values (default 0:1:21)")
    p.add_argument("--setting", default="p_fail", type=_setting_name,
                   help="the task setting the values go to (default p_fail)")
    p.add_argument("--reps", type=whole(1, MAX_TRIALS), default=5000,
                   help=f"runs per value, 1 to {MAX_TRIALS} (default 5000)")
    p.add_argument("-o", "--output", metavar="FIG", type=output_file(".png", ".svg", ".pdf"),
                   help="the plot: .png, .svg or .pdf (default: no plot)")
    p.add_argument("--csv", metavar="CSV", type=output_file(".csv"),
                   help="the table (default: the plot's name with .csv, when -o is given)")
    p.add_argument("--seed", type=seed, default=0, help="seed of the repetitions (default 0)")
    p.add_argument("--workers", type=whole(1, MAX_WORKERS), default=os.cpu_count() or 1,
                   help="processes (default: the number of CPUs); results do not depend on it")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", type=setting,
                   dest="settings", help="another task setting, kept fixed; repeatable")
    p.add_argument("--skills", action="append", default=[], metavar="MODULE",
                   type=module_or_file, help="a module (dotted name or .py file) or FSA file "
                   "whose skills to add to the task's (a nested FSA, say); repeatable")
    p.add_argument("--backend", help="which implementation of each skill to run")
    p.add_argument("--step-limit", type=whole(1, MAX_STEP_LIMIT),
                   help="steps after which a run ends in timeout (default: the task's)")
    p.set_defaults(func=cmd_robustness)


def _sweep_arg(text: str) -> list[float]:
    try:
        return parse_values(text)
    except RobustnessError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _setting_name(text: str) -> str:
    if not text.isidentifier():
        raise argparse.ArgumentTypeError(f"must be a setting name like p_fail, got {text!r}")
    return text


def cmd_robustness(args: argparse.Namespace) -> int:
    from .registry import check_backend
    from .task import load_task, parse_settings

    settings = parse_settings(args.settings)
    if args.backend:
        check_backend(load_task(args.task, **settings).registry, args.backend)
    if args.setting in settings:
        raise RobustnessError(
            f"--set {args.setting}=... conflicts with the sweep of {args.setting}; drop it"
        )
    rows = robustness_sweep(
        args.file, args.task, args.values, reps=args.reps, seed=args.seed, workers=args.workers,
        setting=args.setting, settings=settings, backend=args.backend,
        step_limit=args.step_limit, progress=not getattr(args, "quiet", False),
        skills=args.skills,
    )
    print(format_table(rows))
    csv_path = args.csv or (str(Path(args.output).with_suffix(".csv")) if args.output else None)
    if csv_path:
        write_csv(rows, csv_path)
        note(args, f"table: {csv_path}")
    if args.output:
        plot_sweep(rows, args.output, title=f"{Path(args.file).name} on {args.task}")
        note(args, f"plot: {args.output}")
    if all(r.outcomes.get(ERROR, 0) == r.reps for r in rows):  # as `run` does
        sets = "".join(f" --set {shlex.quote(str(s))}" for s in args.settings or [])
        print(f"skillcompose robustness: error: every run of {one_line(str(args.file))} "
              "ended in error (a skill raised or exited); see the first with: skillcompose "
              f"run {shlex.quote(str(args.file))} --task {shlex.quote(str(args.task))}{sets}",
              file=sys.stderr)
        return 1
    return 0
