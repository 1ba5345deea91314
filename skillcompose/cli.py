"""The ``skillcompose`` command line (also ``python -m skillcompose``).

Subcommands of the runtime: ``run``, ``validate``, ``show``, ``skills``. Other packages add
theirs (``evolve``, ``robustness``, ``robot``) through a ``register_cli(subparsers)``
function in the modules listed in :data:`SUBCOMMAND_MODULES`.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import traceback
from collections.abc import Sequence
from typing import Any, NoReturn

import numpy as np

from .arguments import MAX_TRIALS, UsageError, module_or_file, output_file, seed, setting, whole
from .blackboard import DELETED
from .errors import SkillcomposeError, clip
from .executor import compile_fsa, error_summary, summarize
from .fsafile import load_fsa
from .progress import progress_bar
from .registry import Registry
from .task import Task, load_task, parse_settings, trials

__all__ = ["SUBCOMMAND_MODULES", "build_parser", "check_backend", "main"]

DRAWING_SUFFIXES = (".dot", ".gv", ".mmd", ".mermaid", ".svg", ".png", ".pdf")


class _Parser(argparse.ArgumentParser):
    """Usage errors in one line: which argument, what is allowed, what was given."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

SUBCOMMAND_MODULES = (
    "evolve.cli",
    "skillcompose.robustness",
    "robots.cli",
)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="skillcompose",
        description="Compose robot skills into finite state automata, run and evolve them.",
        epilog="Exit status: 0 done, 1 failed (an output that cannot be written, an "
        "unexpected error), 2 usage error (an argument not allowed, an invalid FSA file, a "
        "task or skills module that does not load), 130 interrupted.",
    )
    parser.add_argument("--traceback", action="store_true",
                        help="show the traceback of an unexpected error")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    def skills_args(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--skills", action="append", default=[], metavar="MODULE", type=module_or_file,
            help="a module (dotted name or .py file) or FSA file whose skills to load; "
            "repeatable",
        )
        p.add_argument(
            "--task", metavar="TASK", type=module_or_file,
            help="a task module (make_task): its skills and, for run, its world per trial",
        )
        p.add_argument(
            "--set", action="append", default=[], metavar="NAME=VALUE", dest="settings",
            type=setting, help="a task setting, e.g. --set p_fail=0.3; repeatable",
        )
        p.add_argument("--backend", help="which implementation of each skill to run (one "
                       "that a loaded skill has; `skills` lists them)")

    p = sub.add_parser("run", help="run an FSA file and report its outcomes")
    p.add_argument("file", help="the FSA file (YAML)")
    skills_args(p)
    p.add_argument("--seed", type=seed, default=0, help="run seed (default 0)")
    p.add_argument("--trials", type=whole(1, MAX_TRIALS), default=1,
                   help=f"number of runs, 1 to {MAX_TRIALS} (default 1)")
    p.add_argument("--trace", action="store_true",
                   help="print each step of the first run, and a traceback on error")
    p.add_argument("--propagate", action="store_true",
                   help="let a skill's exception stop the command with its traceback")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("validate", help="check an FSA file (against skills when given)")
    p.add_argument("file")
    skills_args(p)
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("show", help="draw an FSA file (DOT, Mermaid, SVG, PNG)")
    p.add_argument("file")
    p.add_argument("-o", "--output", type=output_file(*DRAWING_SUFFIXES),
                   help="output file: .dot .mmd .svg .png .pdf (default: DOT on standard "
                   "output)")
    p.add_argument("--mermaid", action="store_true", help="print Mermaid instead of DOT")
    p.add_argument("--no-params", action="store_true", help="leave parameters out")
    p.set_defaults(func=cmd_show)

    p = sub.add_parser("skills", help="list skills: parameters, ranges, outcomes, keys")
    skills_args(p)
    p.set_defaults(func=cmd_skills)

    for name in SUBCOMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name is not None and name.startswith(exc.name):
                continue  # that part of skillcompose is not installed
            raise
        register = getattr(module, "register_cli", None)
        if callable(register):
            register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run a subcommand; return its exit status (see the parser's epilog).

    Errors are printed as one line (an invalid FSA file lists its problems), never as a
    traceback unless ``--traceback``, or ``run --trace`` / ``--propagate``, asks for one.
    """
    parser = build_parser()
    args = parser.parse_args(argv)  # a usage error: one line and SystemExit(2)
    func = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 2
    loud = any(getattr(args, flag, False) for flag in ("traceback", "trace", "propagate"))
    prog = f"skillcompose {args.command}"
    try:
        return int(func(args))
    except SkillcomposeError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader went away (`... | head`): stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141
    except OSError as exc:  # an output that cannot be written, a disk that is full
        if loud:
            raise
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"{prog}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 1
    except Exception as exc:
        if loud:
            raise
        print(f"{prog}: error: unexpected {type(exc).__name__}: {exc} (rerun with "
              "`skillcompose --traceback ...` to see where)", file=sys.stderr)
        return 1


# ---------------------------------------------------------------------------------------
def _load(args: argparse.Namespace) -> tuple[Registry, Task | None]:
    task: Task | None = None
    if getattr(args, "task", None):
        task = load_task(args.task, **parse_settings(args.settings))
        registry = task.registry
    else:
        if args.settings:
            raise UsageError("--set needs --task: settings belong to a task")
        registry = Registry()
    if args.backend:
        registry.backend = args.backend
    elif task is not None and task.backend:
        registry.backend = task.backend
    for target in args.skills:
        registry.load_module(target)
    registry.load_entry_points()
    if args.backend and len(registry):
        check_backend(registry, args.backend)
    return registry, task


def check_backend(registry: Registry, backend: str) -> None:
    """Raise :class:`UsageError` unless some skill of ``registry`` has ``backend``."""
    known = sorted({b for name in registry.names() for b in registry.backends(name)})
    if backend not in known:
        raise UsageError(
            f"--backend {backend!r}: no loaded skill has this backend; the loaded skills "
            f"have {', '.join(known) or 'none'}"
        )


def cmd_run(args: argparse.Namespace) -> int:
    fsa = load_fsa(args.file)
    registry, task = _load(args)
    if not len(registry):
        raise SkillcomposeError(
            f"{args.file}: no skills loaded; give --skills MODULE or --task TASK"
        )
    try:  # with a task, the task's step limit (as in evolution); else the file's
        compiled = task.compile(fsa, args.backend) if task is not None else \
            compile_fsa(fsa, registry, args.backend)
    except SkillcomposeError as exc:
        raise SkillcomposeError(str(exc)) from None
    if task is not None and fsa.step_limit != task.step_limit:
        print(f"{args.file}: step limit {task.step_limit} from task {task.name} (the file's "
              f"{fsa.step_limit} applies when it runs without --task)", file=sys.stderr)
    results = []
    fitness: list[float] = []
    bar = progress_bar(args.trials, "run")  # on a terminal, once it takes a while
    options: dict[str, Any] = {"trace_first": args.trace, "propagate": args.propagate}
    loop = task.each_trial(compiled, args.seed, args.trials, **options) if task is not None \
        else trials(compiled, args.seed, args.trials, **options)
    for trial in loop:
        bar.update(1)
        result = trial.result
        results.append(result)
        if task is not None:
            fitness.append(trial.fitness)
        if result.trace is not None:
            _print_trace(result)
        if result.error is not None and args.trace and trial.number == 0:
            print(f"state {result.last_state} raised:", file=sys.stderr)
            traceback.print_exception(result.error, file=sys.stderr)
    bar.close()
    s = summarize(results)
    print(f"{args.file}: {s['trials']} run(s), seed {args.seed}, backend {compiled.backend}")
    width = max(len(o) for o in s["outcomes"])
    for outcome, count in s["outcomes"].items():
        print(f"  {outcome:<{width}}  {count:>7}  {100.0 * count / s['trials']:6.2f}%")
    print(f"  mean steps {s['mean_steps']:.2f}")
    if task is not None:
        arr = np.asarray(fitness)
        print(f"  fitness mean {arr.mean():.4g}  std {arr.std():.4g}  "
              f"({'lower' if task.minimize else 'higher'} is better)")
    errors = [(k, r) for k, r in enumerate(results) if r.error is not None]
    if errors and not args.trace:
        k, first = errors[0]
        assert first.error is not None
        print(
            f"  {len(errors)} run(s) ended in error; the first (run {k}) in state "
            f"{first.last_state}: {error_summary(first.error)}\n"
            "  rerun with --trace for the whole traceback",
            file=sys.stderr,
        )
    if len(errors) == len(results):
        print(f"skillcompose run: error: every run of {args.file} ended in error",
              file=sys.stderr)
        return 1
    return 0


def _short(v: Any) -> str:
    return "∅" if v is DELETED else clip(repr(v), 60)


def _print_trace(result: Any) -> None:
    for ev in result.trace:
        print(f"{ev.step:>4}  {ev.state} ({ev.skill}) -> {ev.outcome} -> {ev.target}")
        for key, (old, new) in ev.changes.items():
            print(f"        {key}: {_short(old)} => {_short(new)}")
    print(f"ended: {result.outcome} after {result.steps} step(s)")


def cmd_validate(args: argparse.Namespace) -> int:
    fsa = load_fsa(args.file)
    if args.skills or args.task:
        registry, _ = _load(args)
        fsa.validate(registry)
        checked = f"against {len(registry)} skills"
    else:
        checked = "structure only (give --skills or --task to check skills and parameters)"
    from .graph import trap_states

    unreachable = fsa.unreachable()
    traps = trap_states(fsa)
    print(f"{args.file}: valid, {len(fsa.states)} states, start {fsa.start}; {checked}")
    if unreachable:
        print(f"  warning: unreachable from {fsa.start}: {', '.join(unreachable)} "
              "(they never run; delete them or route an outcome to them)")
    if traps:
        print(f"  warning: no terminal outcome can be reached from {', '.join(traps)}: a run "
              "that enters them ends in timeout; route an outcome to a state that ends")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    from .draw import render, to_dot, to_mermaid

    fsa = load_fsa(args.file)
    if args.output:
        out = render(fsa, args.output, params=not args.no_params)
        print(f"wrote {out}")
    elif args.mermaid:
        sys.stdout.write(to_mermaid(fsa))
    else:
        sys.stdout.write(to_dot(fsa, params=not args.no_params))
    return 0


def cmd_skills(args: argparse.Namespace) -> int:
    registry, _ = _load(args)
    if not len(registry):
        raise SkillcomposeError("no skills loaded; give --skills MODULE or --task TASK")
    for name in sorted(registry.names()):
        spec = registry.spec(name)
        backends = ", ".join(registry.backends(name))
        print(f"{name}  [{backends}]")
        print(f"  outcomes: {', '.join(spec.outcomes)}")
        for p in spec.params:
            print(f"  param {p.name}: {p.describe_range()} (default {p.default!r}"
                  f"{', log scale' if p.scale == 'log' else ''})")
        if spec.reads:
            print(f"  reads:  {', '.join(sorted(spec.reads))}")
        if spec.writes:
            print(f"  writes: {', '.join(sorted(spec.writes))}")
        if spec.doc:
            print("  " + spec.doc.splitlines()[0])
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
