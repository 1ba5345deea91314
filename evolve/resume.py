"""Continuing a run from its directory, which may come from someone else.

What a run *means* is recorded when it starts (:func:`run_record`): the task (its name, the
module that makes it and the settings), the seed, the evolution settings (the per-evaluation
time limit among them), the seed FSA, the simplification and the fresh-episode check. The
checkpoint holds that record under its checksum; ``run.json`` shows it to people. On ``--resume``:

- the checkpoint is read as data only (JSON, never a pickle) and its checksum checked;
- ``run.json`` must say what the checkpoint says (an edited ``run.json``, say another
  ``p_fail``, is refused, naming what differs);
- the task is imported only by the module name recorded at the start, and never from a
  file inside the run directory (a directory received from someone else could carry one);
- settings given again must equal the recorded ones: only the budgets (generations,
  evaluations, episodes) may grow (extending the run), and how it is evaluated (backend,
  workers, when workers are replaced) and checkpointed may change, as none of them changes
  the result.

:func:`open_resumed` locks the run directory and checks all of this before a resumed run
starts.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from skillcompose.limits import MAX_TRIALS
from skillcompose.origins import inside, module_origins
from skillcompose.task import Task, load_task

from .config import EvolutionConfig
from .errors import CheckpointError, EvolutionError
from .rundir import RunDir

__all__ = [
    "FREE_SETTINGS",
    "MEANING",
    "check_record",
    "differences",
    "load_recorded_task",
    "normalise",
    "open_resumed",
    "run_record",
    "without_free",
]

MEANING = ("task", "task_module", "task_settings", "seed", "seed_fsa", "config", "simplify",
           "simplify_trials", "check_trials")
"""The keys of a run record that make the run what it is."""

FREE_SETTINGS = ("generations", "max_evaluations", "max_episodes", "checkpoint_every",
                 "chunks_per_worker", "worker_max_jobs", "worker_max_growth_mb")
"""Evolution settings a resume may change: the budgets (a longer run is the same run, only
longer) and bookkeeping that does not change the result (checkpoints, chunking, replacing
pool workers and Ray actors). ``eval_time_limit`` is not among them: which evaluations
time out, and so score worst, depends on it."""


def normalise(value: Any) -> Any:
    """``value`` as it reads back from JSON (tuples become lists, numpy scalars numbers)."""
    return json.loads(json.dumps(value, default=str))


def run_record(
    task: Task, seed: int, cfg: EvolutionConfig, seed_fsa: str | None, simplify: bool,
    simplify_trials: int, check_trials: int,
) -> dict[str, Any]:
    """What a run means, as plain JSON data."""
    module = task.ref.module if task.ref else None
    if module is not None and (module.endswith(".py") or "/" in module or "\\" in module):
        module = str(Path(module).resolve())  # a file: found again from any directory
    return normalise({
        "task": task.name,
        "task_module": module,
        "task_settings": dict(task.ref.settings) if task.ref else dict(task.settings),
        "seed": seed,
        "seed_fsa": seed_fsa,
        "config": cfg.to_dict(),
        "simplify": simplify,
        "simplify_trials": simplify_trials,
        "check_trials": check_trials,
    })


def _fail(where: str, key: str, value: Any, expected: str) -> CheckpointError:
    text = json.dumps(value)
    text = text if len(text) <= 60 else text[:57] + "..."
    return CheckpointError(f"{where}: {key} = {text} is not valid; expected {expected}")


def check_record(record: Any, where: str) -> dict[str, Any]:
    """``record`` checked value by value (one-line errors naming the key)."""
    if not isinstance(record, dict):
        raise CheckpointError(f"{where}: the run's record is not a JSON object")
    for key in MEANING:
        if key not in record:
            raise CheckpointError(f"{where}: the run's record has no {key!r}")

    def text(key: str, optional: bool) -> None:
        v = record[key]
        if not (isinstance(v, str) and v and "\0" not in v) and not (optional and v is None):
            raise _fail(where, key, v, "a name" + (" or null" if optional else ""))

    text("task", False)
    text("task_module", True)
    text("seed_fsa", True)
    settings = record["task_settings"]
    if not isinstance(settings, dict) or not all(
        isinstance(v, (str, int, float, bool)) or v is None for v in settings.values()
    ):
        raise _fail(where, "task_settings", settings, "an object of plain values")
    seed = record["seed"]
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise _fail(where, "seed", seed, "a whole number >= 0")
    if not isinstance(record["simplify"], bool):
        raise _fail(where, "simplify", record["simplify"], "true or false")
    for key, low in (("simplify_trials", 1), ("check_trials", 0)):
        v = record[key]
        if isinstance(v, bool) or not isinstance(v, int) or not low <= v <= MAX_TRIALS:
            raise _fail(where, key, v, f"a whole number from {low} to {MAX_TRIALS:,}")
    if not isinstance(record["config"], dict):
        raise _fail(where, "config", record["config"], "an object of evolution settings")
    try:
        EvolutionConfig.from_dict(record["config"])
    except (TypeError, EvolutionError) as exc:
        raise CheckpointError(f"{where}: config: {exc}") from None
    return record


def differences(recorded: Mapping[str, Any], given: Mapping[str, Any]) -> list[str]:
    """``key: given (the run has recorded)`` for each key of ``given`` that differs; for
    two objects, each of their keys that differs (``config.trials 5 (the run has 3)``)."""
    out = []
    for key, value in given.items():
        was = recorded.get(key)
        if normalise(value) == normalise(was):
            continue
        if isinstance(value, Mapping) and isinstance(was, Mapping):
            out += [f"{key}.{inner}" for inner in differences(
                was, {k: value.get(k) for k in sorted(set(value) | set(was), key=str)})]
        else:
            out.append(f"{key} {_short(value)} (the run has {_short(was)})")
    return out


def without_free(record_value: Any) -> Any:
    """A run's ``config`` without the settings a resume may change (:data:`FREE_SETTINGS`):
    what ``run.json`` and the checkpoint must agree on (a run killed between writing the one
    and the other, as it is extended, may hold two budgets)."""
    if not isinstance(record_value, Mapping):
        return record_value
    return {k: v for k, v in record_value.items() if k not in FREE_SETTINGS}


def _short(v: Any) -> str:
    text = json.dumps(normalise(v))
    return text if len(text) <= 50 else text[:47] + "..."


def load_recorded_task(record: Mapping[str, Any], run_dir: str | os.PathLike[str]) -> Task:
    """Import the recorded task module (never one inside ``run_dir``) and make the task
    with the recorded settings."""
    module = record.get("task_module")
    where = Path(run_dir)
    if not module:
        raise CheckpointError(
            f"{where}: the run's task was built in Python, not loaded from a module; resume "
            "it from Python: evolve(task, resume=...)"
        )
    for origin in module_origins(module):
        if inside(origin, where):
            raise CheckpointError(
                f"{where}: the run's task module {module} would be imported from {origin}, "
                "inside the run directory; code that came with a run directory is never run "
                "on resume: move it out and check it first"
            )
    task = load_task(module, **dict(record["task_settings"]))
    if task.name != record["task"]:
        raise CheckpointError(
            f"{where}: module {module} now makes task {task.name!r}, but the run is of task "
            f"{record['task']!r}; resume it with the module that made it"
        )
    return task


def open_resumed(
    path: str | os.PathLike[str], task: Task, cfg: EvolutionConfig | None,
    simplify_result: bool | None, simplify_trials: int | None, check_trials: int | None,
) -> tuple[RunDir, dict[str, Any], dict[str, Any], EvolutionConfig]:
    """The run directory at ``path``, locked, its checkpoint, and the run's record and
    settings, checked against ``run.json`` and what was given (unlocked again if refused)."""
    rundir = RunDir(path)
    rundir.lock()
    try:
        checkpoint = rundir.load_checkpoint()
        record, recorded_cfg = _resumed(task, cfg, rundir, checkpoint, simplify_result,
                                        simplify_trials, check_trials)
    except BaseException:
        rundir.unlock()
        raise
    return rundir, checkpoint, record, recorded_cfg


def _resumed(
    task: Task, cfg: EvolutionConfig | None, rundir: RunDir, checkpoint: Mapping[str, Any],
    simplify_result: bool | None, simplify_trials: int | None, check_trials: int | None,
) -> tuple[dict[str, Any], EvolutionConfig]:
    """The run's record and settings, checked against ``run.json`` and what was given."""
    where = str(rundir.checkpoint)
    record = check_record(checkpoint.get("run"), where)
    info = rundir.load_run_info()
    def meaning(k: str, v: Any) -> Any:
        return without_free(normalise(v)) if k == "config" else normalise(v)

    edited = [k for k in MEANING if meaning(k, info.get(k)) != meaning(k, record[k])]
    if edited:
        found = differences({k: meaning(k, record[k]) for k in edited},
                            {k: meaning(k, info.get(k)) for k in edited})
        raise CheckpointError(
            f"{rundir.run_json} differs from the run's checkpoint in {', '.join(found)}; "
            "a run cannot change its meaning on resume: restore run.json, or start a new run "
            "with the settings you want"
        )
    recorded_cfg = EvolutionConfig.from_dict(record["config"])
    given: dict[str, Any] = {"task": task.name}
    if task.ref is not None:
        given["task_settings"] = dict(task.ref.settings)
    if simplify_result is not None:
        given["simplify"] = simplify_result
    if simplify_trials is not None:
        given["simplify_trials"] = simplify_trials
    if check_trials is not None:
        given["check_trials"] = check_trials
    problems = differences(record, given)
    if cfg is not None:
        mine = recorded_cfg.to_dict()
        problems += differences(mine, {
            k: v for k, v in cfg.to_dict().items() if k not in FREE_SETTINGS})
        recorded_cfg = recorded_cfg.replace(**{k: getattr(cfg, k) for k in FREE_SETTINGS})
    if problems:
        raise CheckpointError(
            f"{rundir.path}: resuming with {'; '.join(problems)} would change the run; leave "
            "them out (a resume may change only the budgets, the backend, the "
            "workers, when workers are replaced and how often it checkpoints)"
        )
    return record, recorded_cfg
