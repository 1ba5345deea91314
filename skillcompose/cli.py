"""The ``skillcompose`` command line (also ``python -m skillcompose``).

Subcommands of the runtime: ``run``, ``validate``, ``show``, ``skills``. The other parts add
theirs (``evolve``, ``robustness``, ``robot``, ``view``), and any installed package may add
more, through a ``register_cli(subparsers)`` function in a module named by an entry point of
the group ``skillcompose.commands`` (:func:`subcommand_modules`).

Every subcommand, those added by other packages too, follows the conventions of
:mod:`skillcompose.arguments` (``-q``/``-v``, which :func:`build_parser` adds to each, and
``--json``). This module and each subcommand module must import
quickly: heavy packages (Pinocchio, CasADi, matplotlib, Ray) are imported by the command that
needs them, not by ``register_cli``, so that ``skillcompose --help`` and ``skillcompose
validate`` answer at once.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
import time
import traceback
import warnings
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING, Any, NoReturn, TextIO

from . import __version__
from .arguments import (
    MAX_TRIALS,
    UsageError,
    add_json_option,
    add_output_options,
    json_output,
    module_or_file,
    note,
    output_file,
    print_json,
    seed,
    set_hint,
    setting,
    whole,
)
from .errors import FSAValidationError, SkillcomposeError, one_line, printable

if TYPE_CHECKING:
    from .registry import Registry
    from .task import Task

__all__ = ["COMMANDS_GROUP", "SUBCOMMAND_MODULES", "build_parser", "main", "subcommand_modules"]

DRAWING_SUFFIXES = (".dot", ".gv", ".mmd", ".mermaid", ".svg", ".png", ".pdf")
MERMAID_SUFFIXES = (".mmd", ".mermaid")


class _Parser(argparse.ArgumentParser):
    """Usage errors in one line: which argument, what is allowed, what was given."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see {self.prog} --help)\n")

SUBCOMMAND_MODULES = (
    "skillcompose.evolve.cli",
    "skillcompose.robustness_cli",
    "skillcompose.robots.cli",
    "skillcompose.view.cli",
)
"""This package's subcommand modules, as its ``skillcompose.commands`` entry points name them
(used as they are when the package runs from a checkout without being installed)."""

COMMANDS_GROUP = "skillcompose.commands"
"""The entry-point group of subcommand modules: each offers ``register_cli(subparsers)``;
another installed package adds its own commands by naming a module here."""


def subcommand_modules() -> list[str]:
    """The modules that add subcommands: every ``skillcompose.commands`` entry point (this
    package's and other installed packages'), by name; this package's own when it is not
    installed (a checkout run as ``python -m skillcompose``)."""
    from importlib import metadata

    found = sorted((ep.name, ep.value) for ep in metadata.entry_points(group=COMMANDS_GROUP))
    modules = [value.split(":", 1)[0] for _, value in found]
    return list(dict.fromkeys(modules)) or list(SUBCOMMAND_MODULES)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="skillcompose",
        description="Compose robot skills into finite state automata, run and evolve them.",
        epilog="-q/-v may be given before or after the subcommand. --json (run, validate, "
        "skills, evolve): one JSON document on standard output, nothing else (what tasks "
        "and skills print goes to standard error). "
        "Exit status: 0 done, 1 failed (an output that cannot be written, an "
        "unexpected error, every run of `run` or `robustness` ended in error), 2 usage "
        "error (an argument not allowed, an invalid FSA file, a task or skills module that "
        "does not load or whose make_task, register() or world setup fails), 130 interrupted.",
    )
    parser.add_argument("--version", action="version", version=f"skillcompose {__version__}")
    parser.add_argument("--traceback", action="store_true",
                        help="show the traceback of an unexpected error")
    add_output_options(parser, top=True)
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
    add_json_option(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("validate", help="check an FSA file (against skills when given)")
    p.add_argument("file")
    skills_args(p)
    add_json_option(p)
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("show", help="draw an FSA file (DOT, Mermaid, SVG, PNG)")
    p.add_argument("file")
    p.add_argument("-o", "--output", type=output_file(*DRAWING_SUFFIXES),
                   help="output file: .dot .mmd .svg .png .pdf, its suffix picks the format "
                   "(default: DOT on standard output); never the FSA file itself")
    p.add_argument("--mermaid", action="store_true",
                   help="Mermaid instead of DOT: on standard output, or with -o a .mmd file")
    p.add_argument("--no-params", action="store_true", help="leave parameters out")
    p.set_defaults(func=cmd_show)

    p = sub.add_parser("skills", help="list skills: parameters, ranges, outcomes, keys")
    skills_args(p)
    add_json_option(p)
    p.set_defaults(func=cmd_skills)

    for name in subcommand_modules():
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name is not None and name.startswith(exc.name):
                continue  # that part of skillcompose is not installed
            raise
        register = getattr(module, "register_cli", None)
        if callable(register):
            register(sub)
    for command in sub.choices.values():  # every subcommand, those of other packages too
        add_output_options(command)
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
    started = time.perf_counter()
    try:
        # --json: standard output holds the document only; what tasks and skills print
        # goes to standard error
        # (run as the program, argv from the command line: the process ends after it)
        with json_output(bool(getattr(args, "json", False)), for_good=argv is None), \
                _one_line_warnings(prog):
            status = int(func(args))
        note(args, f"{prog}: exit status {status} after {time.perf_counter() - started:.2f} s",
             level=1)
        return status
    except SkillcomposeError as exc:
        print(f"{prog}: error: {printable(exc)}{set_hint(args, exc)}", file=sys.stderr)
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
        print(f"{prog}: error: {one_line(f'{where}{exc.strerror or exc}')}", file=sys.stderr)
        return 1
    except Exception as exc:
        if loud:
            raise
        print(f"{prog}: error: unexpected {type(exc).__name__}: {printable(exc)} (rerun with "
              "`skillcompose --traceback ...` to see where)", file=sys.stderr)
        return 1


@contextlib.contextmanager
def _one_line_warnings(prog: str) -> Iterator[None]:
    """Warnings shown while a command runs (a numpy RuntimeWarning in a task's code, say)
    come as one line on standard error naming where they were raised, not as Python's two
    lines quoting the source; ``-W`` and ``PYTHONWARNINGS`` still choose which are shown."""

    def show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
             file: TextIO | None = None, line: str | None = None) -> None:
        print(f"{prog}: warning: {category.__name__}: {one_line(str(message))} "
              f"({filename}:{lineno})", file=file or sys.stderr)

    old = warnings.showwarning
    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = old


# ---------------------------------------------------------------------------------------
def _load(args: argparse.Namespace) -> tuple[Registry, Task | None]:
    from .registry import Registry, check_backend
    from .task import load_task, parse_settings

    started = time.perf_counter()
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
    registry.load_modules(args.skills)
    registry.load_entry_points()
    if args.backend and len(registry):
        check_backend(registry, args.backend)  # one line, status 2, as any registry error
    note(args, f"skillcompose {args.command}: loaded {len(registry)} skills"
         + (f" and task {task.name}" if task is not None else "")
         + f" in {time.perf_counter() - started:.2f} s", level=1)
    return registry, task


def cmd_run(args: argparse.Namespace) -> int:
    import numpy as np

    from .errors import exception_text
    from .executor import compile_fsa, error_summary, summarize
    from .fsafile import load_fsa
    from .progress import progress_bar
    from .task import skill_fault, trials

    fsa = load_fsa(args.file)
    registry, task = _load(args)
    if not len(registry):
        raise SkillcomposeError(
            f"{one_line(str(args.file))}: no skills loaded; give --skills MODULE or --task TASK"
        )
    # with a task, the task's step limit (as in evolution); else the file's
    compiled = task.compile(fsa, args.backend) if task is not None else \
        compile_fsa(fsa, registry, args.backend)
    if task is not None and fsa.step_limit != task.step_limit:
        note(args, f"{one_line(str(args.file))}: step limit {task.step_limit} from task "
             f"{task.name} (the file's {fsa.step_limit} applies when it runs without --task)")
    results = []
    fitness: list[float] = []
    # on a terminal, once it takes a while; never with -q
    bar = progress_bar(args.trials, "run", disable=getattr(args, "quiet", False))
    # A skill that exits (sys.exit(), GeneratorExit...) ends its run in error, as one that
    # raises does, unless --propagate; the task's own setup or fitness failing stops the
    # command (a TaskError naming it), and so does a Ctrl-C.
    options: dict[str, Any] = {"trace_first": args.trace, "propagate": args.propagate,
                               "catch": None if args.propagate else skill_fault}
    loop = task.guarded().each_trial(compiled, args.seed, args.trials, **options) \
        if task is not None else trials(compiled, args.seed, args.trials, **options)
    as_json = getattr(args, "json", False)
    trace_out = sys.stderr if as_json else sys.stdout  # --json: stdout holds the document
    try:
        for trial in loop:
            bar.update(1)
            result = trial.result
            results.append(result)
            fitness.append(trial.fitness)  # nan without a task
            if result.trace is not None:
                _print_trace(result, trace_out)
            if result.error is not None and args.trace and trial.number == 0:
                print(f"state {result.last_state} raised:", file=sys.stderr)
                traceback.print_exception(result.error, file=sys.stderr)
    except (Exception, KeyboardInterrupt):
        raise
    except BaseException as stop:  # --propagate, and a skill exited: its traceback, status 1
        raise RuntimeError(f"a skill stopped the run: {exception_text(stop)}") from stop
    bar.close()
    s = summarize(results)
    errors = [(k, r.last_state, r.error) for k, r in enumerate(results) if r.error is not None]
    arr = np.asarray(fitness)
    with np.errstate(invalid="ignore", over="ignore"):  # a run in error scores inf, say
        mean, std = float(arr.mean()), float(arr.std())
    if as_json:
        first = None
        if errors:
            k, state, exc = errors[0]
            first = {"run": k, "state": state, "error": exception_text(exc)}
        print_json({
            "command": "run", "file": args.file, "seed": args.seed, "trials": s["trials"],
            "backend": compiled.backend, "task": task.name if task is not None else None,
            "step_limit": compiled.step_limit, "outcomes": s["outcomes"],
            "mean_steps": s["mean_steps"],
            "fitness": None if task is None else {
                "mean": mean, "std": std,
                "minimize": task.minimize},
            "errors": {"count": len(errors), "first": first},
        })
    else:
        print(f"{one_line(str(args.file))}: {s['trials']} run(s), seed {args.seed}, backend "
              f"{compiled.backend}")
        width = max(len(o) for o in s["outcomes"])
        for outcome, count in s["outcomes"].items():
            print(f"  {outcome:<{width}}  {count:>7}  {100.0 * count / s['trials']:6.2f}%")
        print(f"  mean steps {s['mean_steps']:.2f}")
        if task is not None:
            print(f"  fitness mean {mean:.4g}  std {std:.4g}  "
                  f"({'lower' if task.minimize else 'higher'} is better)")
    if errors and not args.trace:
        k, state, exc = errors[0]
        print(
            f"  {len(errors)} run(s) ended in error; the first (run {k}) in state "
            f"{state}: {error_summary(exc)}\n"
            "  rerun with --trace for the whole traceback",
            file=sys.stderr,
        )
    if len(errors) == len(results):
        print(f"skillcompose run: error: every run of {one_line(str(args.file))} ended in error",
              file=sys.stderr)
        return 1
    return 0


def _print_trace(result: Any, out: Any) -> None:
    from .display import trace_lines

    for line in trace_lines(result):
        print(line, file=out)


def _invalid_document(file: str, exc: FSAValidationError) -> dict[str, Any]:
    """``validate --json`` of a file that is not valid: its problems, with their lines."""
    return {"command": "validate", "file": file, "valid": False, "states": None,
            "start": None, "skills_checked": None, "unreachable": [], "traps": [],
            "problems": [{"line": p.line, "column": p.column, "state": p.state, "key": p.key,
                          "message": p.message, "fix": p.fix} for p in exc.problems]}


def cmd_validate(args: argparse.Namespace) -> int:
    try:
        return _validate(args)
    except FSAValidationError as exc:
        if getattr(args, "json", False):  # the document goes to standard output, here where
            print_json(_invalid_document(args.file, exc))  # --json keeps it for its document
        raise


def _validate(args: argparse.Namespace) -> int:
    from .fsafile import load_fsa

    fsa = load_fsa(args.file)
    skills_checked: int | None = None
    if args.skills or args.task:
        registry, _ = _load(args)
        fsa.validate(registry)
        skills_checked = len(registry)
        checked = f"against {len(registry)} skills"
    else:
        checked = "structure only (give --skills or --task to check skills and parameters)"
    unreachable = fsa.unreachable()
    traps = fsa.trap_states()  # networkx-free: validate stays quick
    if getattr(args, "json", False):
        print_json({"command": "validate", "file": args.file, "valid": True,
                    "states": len(fsa.states), "start": fsa.start,
                    "skills_checked": skills_checked, "unreachable": list(unreachable),
                    "traps": list(traps), "problems": []})
        return 0
    print(f"{one_line(str(args.file))}: valid, {len(fsa.states)} states, start {fsa.start}; "
          f"{checked}")
    if unreachable:
        print(f"  warning: unreachable from {fsa.start}: {', '.join(unreachable)} "
              "(they never run; delete them or route an outcome to them)")
    if traps:
        print(f"  warning: no terminal outcome can be reached from {', '.join(traps)}: a run "
              "that enters them ends in timeout; route an outcome to a state that ends")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    from .draw import render, to_dot, to_mermaid
    from .fsafile import load_fsa

    suffix = os.path.splitext(args.output or "")[1].lower()
    if args.mermaid and args.output and suffix not in MERMAID_SUFFIXES:
        raise UsageError(
            f"--mermaid writes Mermaid, but -o {args.output} asks for "
            f"{suffix.lstrip('.').upper()} (with -o the file's suffix picks the format); name "
            "a .mmd file, or leave out --mermaid"
        )
    fsa = load_fsa(args.file)
    if args.output:
        out = render(fsa, args.output, params=not args.no_params)
        note(args, f"wrote {one_line(str(out))}")
    elif args.mermaid:
        sys.stdout.write(to_mermaid(fsa))
    else:
        sys.stdout.write(to_dot(fsa, params=not args.no_params))
    return 0


def cmd_skills(args: argparse.Namespace) -> int:
    registry, _ = _load(args)
    if not len(registry):
        raise SkillcomposeError("no skills loaded; give --skills MODULE or --task TASK")
    docs = [_skill_document(registry, name) for name in sorted(registry.names())]
    if getattr(args, "json", False):
        print_json({"command": "skills", "skills": docs})
        return 0
    for d in docs:
        print(f"{d['name']}  [{', '.join(d['backends'])}]")
        print(f"  outcomes: {', '.join(d['outcomes'])}")
        for p in d["params"]:
            print(f"  param {p['name']}: {p['range']} (default {p['default']!r}"
                  f"{', log scale' if p['scale'] == 'log' else ''})")
        if d["reads"]:
            print(f"  reads:  {', '.join(d['reads'])}")
        if d["writes"]:
            print(f"  writes: {', '.join(d['writes'])}")
        if d["doc"]:
            print("  " + d["doc"])
    return 0


def _skill_document(registry: Registry, name: str) -> dict[str, Any]:
    spec = registry.spec(name)
    return {
        "name": name, "backends": list(registry.backends(name)),
        "outcomes": list(spec.outcomes),
        "params": [{"name": p.name, "range": p.describe_range(), "default": p.default,
                    "scale": p.scale} for p in spec.params],
        "reads": sorted(spec.reads), "writes": sorted(spec.writes),
        "doc": spec.doc.splitlines()[0] if spec.doc else "",
    }


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
