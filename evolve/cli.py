"""``skillcompose evolve``: evolve an FSA for a task from the command line."""

from __future__ import annotations

import argparse
import math
import os
import shlex
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from skillcompose.arguments import add_json_option, json_output, print_json, set_hint
from skillcompose.errors import SkillcomposeError, clip, printable

from .config import (
    DEFAULT_KINDS,
    DEFAULT_PRESET,
    PRESET_NAMES,
    EvolutionConfig,
    default_islands,
    preset_help,
    preset_settings,
)
from .config import EVALUATION_BACKENDS as BACKENDS
from .errors import EvolutionError
from .settings import FLAGGED, Kind, Setting

if TYPE_CHECKING:
    from skillcompose.task import Task

    from .result import EvolutionResult

# The evolution itself (numpy, the runtime, the evaluators) is imported by `handle`, when the
# command runs: `skillcompose --help` imports this module and must stay quick.

__all__ = ["add_arguments", "handle", "main", "register_cli"]

DESCRIPTION = """\
Evolve an FSA for a task with the paper's algorithm, and write what it finds as an FSA file
you can read, edit, run and evolve again.

examples:
  skillcompose evolve examples.toy_task --set p_fail=0.1 --generations 200 --out runs/toy
  skillcompose evolve --resume runs/toy                     continue a killed run
  skillcompose evolve --resume runs/toy --generations 400   extend a run to 400 generations
  skillcompose evolve examples.toy_task --max-evaluations 30000 --out runs/toy3
                                        stop after 30,000 genome evaluations at most
  skillcompose evolve examples.toy_task --seed-fsa edited.yaml --out runs/toy2

A resumed run is the run it would have been without the interruption. It keeps its task,
seed and settings: giving others is refused; only the budgets (--generations,
--max-evaluations, --max-episodes: to extend it), --backend, --workers, --worker-max-jobs,
--worker-max-growth-mb, --checkpoint-every and --quiet may change. A finished run is left
as it is, but for its best.yaml and best_evolved.yaml, written again if they were deleted.
"""

# options whose absence matters on --resume: None until given (a new run's defaults: seed 0,
# preset default, 200 simplification trials, 200 fresh episodes checked)
_UNSET_UNTIL_GIVEN = ("seed", "preset", "simplify_trials", "check_trials")


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``skillcompose evolve``, each checked where it is parsed: the run's,
    written here, then one per evolution setting of the table that has a flag."""
    from skillcompose.arguments import (
        MAX_TRIALS,
        MAX_WORKERS,
        existing_dir,
        module_or_file,
        output_dir,
        seed,
        setting,
        whole,
    )

    p.add_argument(
        "task", nargs="?", type=module_or_file,
        help="task module (dotted name or .py path) defining make_task(**settings); "
        "may be left out with --resume",
    )
    p.add_argument("--set", dest="settings", action="append", default=[], metavar="NAME=VALUE",
                   type=setting,
                   help="a task setting passed to make_task (repeatable), e.g. p_fail=0.2")
    p.add_argument("--preset", choices=PRESET_NAMES, default=DEFAULT_PRESET,
                   help=preset_help().replace("%", "%%"))
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
    p.add_argument("--no-simplify", action="store_true",
                   help="export the best FSA as evolved, without simplification")
    p.add_argument("--simplify-trials", type=whole(1, MAX_TRIALS), default=200,
                   help="fresh trials per simplification test, at least 1 (default 200)")
    p.add_argument("--check-trials", type=whole(0, MAX_TRIALS), default=200,
                   help="fresh episodes on which the exported FSA is measured at the end "
                   "(default 200; 0: none)")
    add_json_option(p)
    group = p.add_argument_group(
        "evolution settings",
        "each overrides the preset's; a default below is EvolutionConfig's (the paper's "
        "table 1 where it gives one), which --preset changes")
    defaults = EvolutionConfig()
    for s in FLAGGED:
        _add_setting(group, s, getattr(defaults, s.name))


def _add_setting(group: Any, s: Setting, default: Any) -> None:
    """The option of setting ``s``: it takes what the config takes, into ``args.<name>``."""
    options: dict[str, Any] = {"dest": s.name,
                               "help": s.option_help(default).replace("%", "%%")}
    if s.kind is Kind.SWITCH:
        options["action"] = "store_true"  # given: on (the default is off, as in the config)
    elif s.kind is Kind.CHOICE:
        options["choices"] = s.choices
    else:
        options["type"] = _option_type(s)
        options["metavar"] = s.metavar
    group.add_argument(s.flag, **options)


def _option_type(s: Setting) -> Callable[[str], Any]:
    """The argparse ``type=`` of a number setting: within the setting's own bounds (and 0,
    when the option's 0 means None)."""
    from skillcompose.arguments import number, whole

    if s.kind is Kind.WHOLE:
        return whole(int(s.low), int(s.high))
    finite = number(-math.inf, math.inf)
    expected = s.expected() + (f", or 0 for {s.none}" if s.flag_zero_is_none else "") + \
        (f" (0: {s.zero})" if s.zero else "")

    def parse(text: str) -> float:
        try:
            value = finite(text)
        except argparse.ArgumentTypeError:
            value = math.nan
        if not (s.accepts(value) or (s.flag_zero_is_none and value == 0)):
            raise argparse.ArgumentTypeError(f"must be {expected}, got {clip(text)!r}")
        return value

    parse.__name__ = "number"
    return parse


def _hold_hint(cfg: EvolutionConfig, task: Task) -> str:
    """What would make a run go on until its exported FSA holds."""
    if (cfg.trials or task.trials) < 3:
        return ("run without --preset paper (every other preset goes on until the exported "
                "FSA holds), or give more --trials per evaluation")
    return "run without --preset paper: every other preset goes on until the exported FSA holds"


def _config(args: argparse.Namespace, kind: tuple[bool, bool] = (False, False)
            ) -> EvolutionConfig:
    """The settings of the command line for a task of ``kind``, ``(deterministic,
    vectors)`` as :func:`~skillcompose.evolve.config.preset_settings` takes them."""
    given = _given_settings(args)
    return EvolutionConfig(**{**_preset(args.preset, kind, given), **given})


def _preset(name: str | None, kind: tuple[bool, bool], given: dict[str, Any]
            ) -> dict[str, Any]:
    """The settings of preset ``name`` (None: the default) for a task of ``kind``
    (:func:`_config`), beside the settings ``given`` on the command line: the default's
    islands follow a population given without them (config.py)."""
    settings = dict(preset_settings(name or DEFAULT_PRESET, *kind))
    if (name or DEFAULT_PRESET) == DEFAULT_PRESET and "islands" not in given and \
            "population" in given and settings.get("islands", 1) > 1:
        settings["islands"] = default_islands(int(given["population"]), settings["islands"])
    return settings


def _given_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The evolution settings given on the command line (not their defaults)."""
    changes: dict[str, Any] = {}
    for s in FLAGGED:
        v = getattr(args, s.name)
        if s.kind is Kind.SWITCH:
            if v:
                changes[s.name] = True
        elif v is not None:
            changes[s.name] = None if s.flag_zero_is_none and v == 0 else v
    return changes


def _resume_conflicts(args: argparse.Namespace, record: dict[str, Any]) -> list[str]:
    """The options given with --resume that would change the run, each with the run's
    value."""
    from skillcompose.task import parse_settings

    from .resume import FREE_SETTINGS, normalise

    cfg = record["config"]
    given = _given_settings(args)
    problems: list[str] = []

    def differs(option: str, value: Any, recorded: Any, sep: str = " ") -> None:
        if normalise(value) != normalise(recorded):
            problems.append(f"{option}{sep}{value} (the run has {recorded})")

    if args.task:
        differs("TASK", args.task, record["task_module"])
    if args.settings:
        for k, v in parse_settings(args.settings).items():
            differs(f"--set {k}", v, record["task_settings"].get(k, "no such setting"), "=")
    if args.seed is not None:
        differs("--seed", args.seed, record["seed"])
    if args.seed_fsa is not None:
        differs("--seed-fsa", args.seed_fsa, record["seed_fsa"])
    if args.preset is not None:  # default: any of what it resolves to (the task is not
        # imported before the run's options are found to agree)
        choices = [_preset(args.preset, kind, given) for kind in DEFAULT_KINDS]
        found: list[list[str]] = []  # the problems of each choice
        for settings in choices:
            before = len(problems)
            for name, value in settings.items():
                if name not in given:  # a setting given beside it is checked below
                    differs(f"--preset {args.preset}: {name} =", value, cfg.get(name))
            found.append(problems[before:])
            del problems[before:]
        problems.extend(min(found, key=lambda p: len(list(p))))
    if args.no_simplify and record["simplify"]:
        problems.append("--no-simplify (the run simplifies its result)")
    if args.simplify_trials is not None:
        differs("--simplify-trials", args.simplify_trials, record["simplify_trials"])
    if args.check_trials is not None:
        differs("--check-trials", args.check_trials, record["check_trials"])
    if args.out is not None and Path(args.out).resolve() != Path(args.resume).resolve():
        problems.append(f"--out {args.out} (the run's directory is {args.resume})")
    flags = {s.name: s.flag for s in FLAGGED}
    for name, value in given.items():
        if name in FREE_SETTINGS:
            continue
        if name == "eval_time_limit":  # None is `--eval-time-limit 0`: no limit
            if normalise(value) != normalise(cfg.get(name)):
                problems.append(f"--eval-time-limit {args.eval_time_limit:g} (the run has "
                                f"{_limit_text(cfg.get(name))})")
            continue
        differs(flags[name], value, cfg.get(name))
    return problems


def _limit_text(limit: Any) -> str:
    return "no limit" if limit is None else f"{limit:g} s" if isinstance(limit, (int, float)) \
        else str(limit)


def _resume(args: argparse.Namespace) -> tuple[Any, dict[str, Any]]:
    """The recorded task of the run in ``--resume DIR`` and the recorded settings, after
    refusing anything given that would change the run."""
    from .resume import check_record, load_recorded_task
    from .rundir import RunDir

    rundir = RunDir(args.resume)
    checkpoint = rundir.load_checkpoint()
    record = check_record(checkpoint.get("run"), str(rundir.checkpoint))
    problems = _resume_conflicts(args, record)
    if problems:
        raise EvolutionError(
            f"--resume {args.resume}: {'; '.join(problems)} would change the run; leave them "
            "out (a resume may change only --generations, --max-evaluations, --max-episodes, "
            "--backend, --workers, "
            "--worker-max-jobs, --worker-max-growth-mb, --checkpoint-every and --quiet)"
        )
    return load_recorded_task(record, args.resume), record


def handle(args: argparse.Namespace) -> int:
    from .algorithm import evolve
    from .rundir import RunDir

    try:
        task, cfg, options = _run_arguments(args)
        result = evolve(task, cfg, **options)
    except SkillcomposeError as exc:
        print(f"skillcompose evolve: error: {printable(exc)}{set_hint(args, exc)}",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C: say how to go on, when there is a run to go on with
        where = args.resume or args.out
        if where is not None and RunDir(where).checkpoint.is_file():
            print(f"interrupted; continue the run with: skillcompose evolve --resume "
                  f"{shlex.quote(str(where))}", file=sys.stderr)
            return 130
        raise
    if getattr(args, "json", False):
        print_json(summary_document(result, task.name))
        _warn(result, cfg, task)
        return 1 if result.nothing_succeeded else 0
    return _summary(args, result, cfg, task)


def _run_arguments(args: argparse.Namespace) -> tuple[Task, EvolutionConfig, dict[str, Any]]:
    """The task, the settings and :func:`evolve`'s other arguments: a resumed run's from its
    directory (with what a resume may change), a new run's from the options."""
    from skillcompose.task import load_task, parse_settings

    from .resume import FREE_SETTINGS
    from .rundir import RunDir

    if args.resume:
        task, record = _resume(args)
        cfg = EvolutionConfig.from_dict(record["config"]).replace(**{
            k: v for k, v in _given_settings(args).items() if k in FREE_SETTINGS})
        info = RunDir(args.resume).load_run_info()
        backend = args.backend or info.get("backend")
        if backend not in BACKENDS:
            backend = "serial"
        workers = args.workers if args.workers is not None else info.get("workers")
        if isinstance(workers, bool) or not isinstance(workers, int) or \
                not 1 <= workers <= (os.cpu_count() or 1):
            workers = None  # run.json is data from elsewhere: all cores at most
        seed, simplify_result, simplify_trials, check_trials = None, None, None, None
    else:
        if not args.task:
            raise EvolutionError(
                "name a task module, e.g. `skillcompose evolve examples.toy_task`, "
                "or continue a run with --resume DIR"
            )
        task = load_task(args.task, **parse_settings(args.settings))
        from .plan import takes_vectors

        cfg = _config(args, (task.deterministic, takes_vectors(task)))
        cores = args.workers or os.cpu_count() or 1
        backend = args.backend or ("process" if cores > 1 else "serial")
        workers = args.workers
        seed = 0 if args.seed is None else args.seed
        simplify_result = not args.no_simplify
        simplify_trials = 200 if args.simplify_trials is None else args.simplify_trials
        check_trials = 200 if args.check_trials is None else args.check_trials
    return task, cfg, {
        "seed": seed, "workers": workers, "backend": backend,
        "out_dir": None if args.resume else args.out,
        "seed_fsa": None if args.resume else args.seed_fsa,
        "progress": not getattr(args, "quiet", False), "resume": args.resume,
        "simplify_result": simplify_result, "simplify_trials": simplify_trials,
        "check_trials": check_trials,
    }


def _summary(args: argparse.Namespace, result: EvolutionResult, cfg: EvolutionConfig,
             task: Task) -> int:
    """Say what the run found, on standard output (its warnings on standard error); the
    exit status."""
    from .holds import describe_fresh

    state = "solved" if result.solved else "not solved"
    if result.unchanged:
        ended = result.stopped_by if result.stopped_by in ("evaluations", "episodes") \
            else "generations"
        limit = result.budgets.get(ended, {}).get("limit") or result.budget
        why = "solved" if result.solved else f"not solved in its budget of {limit} {ended}"
        restored = ", ".join(p.name for p in result.files)
        print(
            f"{args.resume}: the run finished in generation {result.generations} ({why}); "
            + (f"wrote again {restored}, which had been deleted; nothing else was changed."
               if restored else "nothing was changed.")
            + (" A solved run is not extended; to search on from its FSA, start a new run: "
               f"skillcompose evolve {shlex.quote(task.ref.module if task.ref else 'TASK')} "
               + "".join(f"--set {shlex.quote(f'{k}={v}')} " for k, v in task.settings.items())
               + f"--seed-fsa {shlex.quote(str(Path(args.resume) / 'best.yaml'))} --out "
               "NEW_FOLDER" if result.solved else "")
            + ("" if result.solved else
               f" Extend it with: skillcompose evolve --resume {args.resume} "
               f"--{'generations' if ended == 'generations' else 'max-' + ended} "
               f"{2 * max(limit, 1)}")
        )
        return 0
    best = f"{result.best_fitness:g}"
    if math.isinf(result.best_fitness) and task.error_fitness is None and result.faults.total:
        best += (" (an episode of it raised, ran past the time limit or was lost, scored as "
                 "the task's error_fitness, by default the worst)")
    print(
        f"{task.name}: {state}, best fitness {best} after "
        f"{result.generations} generations, {result.episodes} episodes, "
        f"{result.wall_time:.1f} s; best FSA has {len(result.best_fsa.states)} states "
        f"(evolved: {len(result.evolved_fsa.states)})"
    )
    if any(result.budgets.get(b, {}).get("limit") is not None
           for b in ("evaluations", "episodes")):
        print(budget_line(result))
    fresh = result.fresh
    if fresh:
        print(f"the exported FSA: {describe_fresh(fresh)}; mean fitness "
              f"{fresh['mean_fitness']:g}")
    if result.solved and result.solved_by == "evaluation":
        print("solved by the paper's criterion (one evaluation reached the target), not by "
              "the fresh episodes above; without --preset paper a run goes on until its "
              "exported FSA holds")
    _warn(result, cfg, task, summary=True)
    if result.files:
        print("files written:")
        for f in result.files:
            print(f"  {f}")
        from .rundir import MAX_DRAWN_STATES  # here: `--help` loads no heavy package

        if result.out_dir is not None and len(result.best_fsa.states) > MAX_DRAWN_STATES:
            best = shlex.quote(str(result.out_dir / "best.yaml"))
            print(f"  (no best.png: {len(result.best_fsa.states)} states are more than "
                  f"{MAX_DRAWN_STATES} to draw legibly; best.dot holds the graph, or: "
                  f"skillcompose show {best} -o best.svg)")
        print(f"run it: {result.run_command}")
    return 1 if result.nothing_succeeded else 0


def _warn(result: EvolutionResult, cfg: EvolutionConfig,
          task: Task, summary: bool = False) -> None:
    """The warnings and faults of a run, on standard error (``summary``: the summary on
    standard output has said how the exported FSA holds)."""
    if result.unchanged:
        return
    fresh = result.fresh
    if result.solved and fresh.get("holds") is False and not summary:
        print(
            f"warning: the run is solved on evolution's own episodes, but the exported FSA "
            f"does not hold on fresh ones; {_hold_hint(cfg, task)}",
            file=sys.stderr,
        )
    faults = result.faults
    if faults.total:
        print(f"faults: {faults.describe()} in {faults.jobs} evaluations "
              f"({faults.failed} failed entirely); per generation in history.jsonl",
              file=sys.stderr)
        if faults.first_error:
            print(f"first error {faults.first_error}", file=sys.stderr)
    if result.nothing_succeeded:
        print(
            f"skillcompose evolve: error: every one of the {faults.jobs} evaluations failed "
            "(see the first error above); fix the task or its skills", file=sys.stderr,
        )


def budget_line(result: EvolutionResult) -> str:
    """What ended the run and what it used of each budget, in one line."""
    parts = []
    for name in ("generations", "evaluations", "episodes"):
        use = result.budgets.get(name, {})
        limit = use.get("limit")
        parts.append(f"{use.get('used', 0):,} {name}" +
                     ("" if limit is None else f" of {limit:,}"))
    ended = "solved" if result.stopped_by == "solved" else \
        f"ended by its {result.stopped_by} budget" if result.stopped_by else "ended"
    return f"{ended}: used {', '.join(parts)}"


def summary_document(result: EvolutionResult, task_name: str) -> dict[str, Any]:
    """What ``skillcompose evolve --json`` prints: the run's summary (keys documented in the
    README)."""
    faults = result.faults
    return {
        "command": "evolve", "task": task_name, "seed": result.seed,
        "solved": result.solved, "solved_by": result.solved_by, "unchanged": result.unchanged,
        "best_fitness": result.best_fitness, "generations": result.generations,
        "budget": result.budget, "evaluations": result.evaluations,
        "genome_evaluations": result.genome_evaluations, "episodes": result.episodes,
        "stopped_by": result.stopped_by or None, "budgets": result.budgets,
        "wall_time_s": result.wall_time, "states": len(result.best_fsa.states),
        "evolved_states": len(result.evolved_fsa.states),
        "fresh": dict(result.fresh) or None,
        "faults": {"jobs": faults.jobs, "failed": faults.failed, "total": faults.total,
                   "first_error": faults.first_error or None},
        "out_dir": str(result.out_dir) if result.out_dir is not None else None,
        "files": [str(f) for f in result.files], "run_command": result.run_command or None,
    }


def register_cli(subparsers: Any) -> None:
    """Add ``evolve`` to the ``skillcompose`` command."""
    p = subparsers.add_parser(
        "evolve", help="evolve an FSA for a task (the paper's algorithm)",
        description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_arguments(p)
    # None: not given, so that --resume can tell a given value from a default one
    p.set_defaults(func=handle, **dict.fromkeys(_UNSET_UNTIL_GIVEN))


def build_parser() -> argparse.ArgumentParser:
    from skillcompose.arguments import add_output_options

    parser = argparse.ArgumentParser(prog="skillcompose")
    add_output_options(parser, top=True)
    sub = parser.add_subparsers(dest="command", required=True)
    register_cli(sub)
    for command in sub.choices.values():
        add_output_options(command)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    with json_output(bool(getattr(args, "json", False)), for_good=argv is None):
        return int(args.func(args))


if __name__ == "__main__":
    raise SystemExit(main())
