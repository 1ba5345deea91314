"""What the viewer shows, read from files and runs: plain data, no web code.

Every reader here tolerates files that are being written (a half-written last line of
``history.jsonl`` is skipped), files that vanish between a listing and a read (the run is
left out) and files that are not what they should be (shown as their problem), so the pages
built on it never fail on a run directory in use. Each reads only regular files inside the
folder served (:mod:`skillcompose.view.folder`), bounded in size.

The runs page asks again every second, so nothing is read twice: ``run.json`` is parsed
again only when its (inode, size, modification time) changed, and ``history.jsonl`` is read
incrementally (:mod:`.history`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from skillcompose.errors import FSAValidationError, Problem, SkillcomposeError, clip, one_line
from skillcompose.fsa import FSA
from skillcompose.fsafile import MAX_FILE_BYTES, load_fsa, loads_fsa
from skillcompose.graph import trap_states
from skillcompose.limits import MAX_SEED
from skillcompose.registry import Registry

from .folder import not_unicode, open_below, read_below, read_fd, resolve_below, unicode_name
from .history import Budget, Cache, History, HistoryReader, number, read_history, stat_key

__all__ = [
    "Budget", "FSAView", "History", "HistoryReader", "RunSummary", "StateRow",
    "describe_value", "find_runs", "mermaid", "pid_alive", "read_fsa", "read_fsa_file",
    "read_history", "read_run", "read_run_info", "run_info_problem",
]

MAX_RUNS = 200  # run directories listed under one folder
MAX_DEPTH = 4  # how deep below the folder run directories are looked for
MAX_RUN_JSON_BYTES = 16 * 1024 * 1024
MAX_REFRESH_READ = 32 * 1024 * 1024  # new history bytes one listing of the runs reads at most
MAX_TEXT = 300  # the longest text of a run.json value a table cell shows
MAX_SETTINGS = 100  # task settings a run.json may hold
MAX_VALUE = 4096  # characters of a run.json text value (a task's name, a setting)
_FRESH_SHOWN = ("success_rate", "lower", "upper", "holds", "deterministic")
"""The keys of a run's fresh check the runs page reads (:func:`fresh_text`)."""
_CONFIG_SHOWN = ("population", "generations", "trials", "elitism")


# ---------------------------------------------------------------------------------------
# runs
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RunSummary:
    """One run directory as the runs page lists it."""

    name: str  # its path relative to the viewed folder
    path: Path
    task: str
    task_module: str
    settings: str  # task settings and the main evolution settings, readable
    seed: int | None
    status: str  # running, finished, interrupted, unreadable
    generations: int  # records in history.jsonl (the last generation's index + 1, usually)
    best: float | None  # the run's result's best fitness; without a result, generation_best
    success: float | None  # share of fresh episodes that succeeded, at the end
    problem: str = ""  # why a file of the run could not be read
    task_settings: str = ""  # the task's settings alone, as name=value, ...
    success_text: str = "–"  # the fresh rate, its bounds and whether it holds, readable
    points: tuple[tuple[int, float], ...] = ()  # the chart's (generation, best)
    reading: bool = False  # the history is still being read (a large one)
    # the index of the last generation evaluated (0: the initial population), the N of
    # `skillcompose evolve`'s "after N generations": run.json's result.generations, else the
    # last history record's generation; None: none evaluated yet
    last_generation: int | None = None
    generation_best: float | None = None  # the last generation's best evaluation (the chart's)
    best_is_result: bool = False  # best is run.json's result.best_fitness


def pid_alive(pid: int) -> bool:
    """Whether process ``pid`` exists (on this machine)."""
    if not 0 < pid < 1 << 31:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except (OSError, OverflowError):
        return False
    return True


def _lock_table() -> dict[tuple[int, int, int], list[int]] | None:
    """The processes holding a lock on each file (device major, minor, inode), as the
    system lists them in /proc/locks (Linux), or None where it does not."""
    try:
        with open("/proc/locks", encoding="ascii", errors="replace") as f:
            text = f.read(1 << 22)
    except OSError:
        return None
    table: dict[tuple[int, int, int], list[int]] = {}
    for line in text.splitlines():
        parts = line.split()  # "1: POSIX  ADVISORY  WRITE 4242 fe:00:6029412 0 EOF"
        if len(parts) < 6 or parts[1] == "->":  # "->": a process waiting for the lock
            continue
        try:
            major, minor, inode = parts[5].split(":")
            table.setdefault((int(major, 16), int(minor, 16), int(inode)), []).append(
                int(parts[4]))
        except ValueError:
            continue
    return table


def _lock_holder(run_dir: Path, root: Path,
                 table: dict[tuple[int, int, int], list[int]] | None) -> int | None:
    """The process evolving in ``run_dir``: the one holding the lock on ``.lock`` (an
    evolve holds it while it runs, and writes its process id there). The lock is read from
    the system's list (``table``), without opening the file (closing any descriptor of a
    file drops the POSIX locks its process holds on it, so an evolve running in this process
    would lose its own) and without trying the lock (trying it, even shared, could make an
    ``evolve --resume`` starting at that moment fail). Where the system lists no locks,
    the process whose id is written there, if it lives (which an id reused by another
    process can fake)."""
    lock = run_dir / ".lock"
    if table is not None:
        try:
            st = lock.stat()
        except OSError:
            return None
        holders = table.get((os.major(st.st_dev), os.minor(st.st_dev), st.st_ino), [])
        return holders[0] if holders else None
    try:
        pid = int(read_below(lock, root, 32)[:32].decode("ascii", "replace").strip())
    except (OSError, ValueError):
        return None
    return pid if pid > 0 and pid_alive(pid) else None


def _settings_text(info: Mapping[str, Any]) -> str:
    parts = [f"{k}={v}" for k, v in dict(info.get("task_settings") or {}).items()]
    config = info.get("config")
    if isinstance(config, Mapping):
        for key in _CONFIG_SHOWN:
            if config.get(key) is not None:
                parts.append(f"{key}={config[key]}")
    if info.get("backend"):
        workers = info.get("workers")
        parts.append(f"backend={info['backend']}" + (f"×{workers}" if workers else ""))
    return clip(", ".join(parts), MAX_TEXT)


_SCALAR = (str, int, float, bool, type(None))
_FIELDS: dict[str, tuple[type, ...]] = {
    "task": (str,), "task_module": (str,), "task_settings": (dict, type(None)),
    "seed": (int, type(None)), "config": (dict, type(None)), "backend": (str, type(None)),
    "workers": (int, type(None)), "result": (dict, type(None)),
}


def run_info_problem(info: Mapping[str, Any]) -> str:
    """Why the fields of a ``run.json`` the runs page shows cannot be used ("" when they
    can): each must have its type (``task_settings`` an object of plain values, ...)."""
    for key, types in _FIELDS.items():
        if key in info and (not isinstance(info[key], types) or (isinstance(info[key], bool)
                            and bool not in types)):
            return f"run.json: {key} is {_kind(info[key])}, not {_expected(types)}"
    settings = info.get("task_settings") or {}
    if len(settings) > MAX_SETTINGS:
        return f"run.json: task_settings has {len(settings)} entries (at most {MAX_SETTINGS})"
    for key, value in settings.items():
        if not isinstance(value, _SCALAR):
            return (f"run.json: task setting {clip(one_line(str(key)), 40)} is "
                    f"{_kind(value)}, not a plain value")
        if len(str(key)) > MAX_VALUE or (isinstance(value, str) and len(value) > MAX_VALUE):
            return (f"run.json: task setting {clip(one_line(str(key)), 40)} is longer than "
                    f"{MAX_VALUE} characters")
    for key in ("task", "task_module", "backend"):
        if isinstance(info.get(key), str) and len(info[key]) > MAX_VALUE:
            return f"run.json: {key} is longer than {MAX_VALUE} characters"
    seed = info.get("seed")
    if isinstance(seed, int) and not 0 <= seed <= MAX_SEED:
        return f"run.json: seed is outside 0..{MAX_SEED}"
    result = info.get("result") or {}
    for key, types in (("best_fitness", (int, float, type(None))),
                       ("fresh", (dict, type(None))), ("generations", (int, type(None)))):
        if key in result and (not isinstance(result[key], types) or (
                isinstance(result[key], bool) and key == "generations")):
            return f"run.json: result.{key} is {_kind(result[key])}, not {_expected(types)}"
    return ""


def _kind(value: Any) -> str:
    return {dict: "an object", list: "a list", str: "a text", bool: "true or false",
            type(None): "null"}.get(type(value), "a number")


def _expected(types: tuple[type, ...]) -> str:
    names = {dict: "an object", str: "a text", int: "a whole number", float: "a number"}
    return " or ".join(dict.fromkeys(names[t] for t in types if t in names))


_RUN_INFOS = Cache(2 * MAX_RUNS)


def read_run_info(run_dir: Path, root: Path | None = None) -> tuple[dict[str, Any], str]:
    """The object in ``run_dir``'s ``run.json`` (inside ``root``; default: ``run_dir``),
    and why it cannot be used ("" when it can; then ``{}``): not JSON, not an object, or a
    field of the wrong type (:func:`run_info_problem`). Raises :class:`FileNotFoundError`
    when there is none. Parsed again only when the file changed."""
    path = run_dir / "run.json"
    try:
        fd = open_below(path, run_dir if root is None else root)
    except FileNotFoundError:
        raise
    except OSError as exc:
        return {}, f"run.json cannot be read: {exc.strerror or exc}"
    try:
        key = stat_key(os.fstat(fd))
        cached = _RUN_INFOS.recall(str(path))
        if cached is not None and cached[0] == key:
            return cached[1]
        data = read_fd(fd, MAX_RUN_JSON_BYTES + 1)
    except OSError as exc:
        return {}, f"run.json cannot be read: {exc.strerror or exc}"
    finally:
        os.close(fd)
    answer: tuple[dict[str, Any], str]
    if len(data) > MAX_RUN_JSON_BYTES:
        answer = {}, f"run.json cannot be read: larger than {MAX_RUN_JSON_BYTES >> 20} MiB"
    else:
        try:
            loaded = json.loads(data.decode("utf-8"))  # (not UTF-8: a ValueError too)
        except (ValueError, RecursionError):
            loaded = None
        if not isinstance(loaded, dict):
            answer = {}, "run.json is not a JSON object (being written, or damaged)"
        elif not_unicode(loaded):
            answer = {}, "run.json holds text that is not Unicode (a lone \\u surrogate)"
        else:
            problem = run_info_problem(loaded)
            answer = ({}, problem) if problem else (_kept(loaded), "")
    _RUN_INFOS.remember(str(path), (key, answer))
    return answer


def _kept(info: dict[str, Any]) -> dict[str, Any]:
    """What the viewer uses of a ``run.json`` (checked by :func:`run_info_problem`): kept
    between reads, so only these few values."""
    kept = {k: info[k] for k in _FIELDS if k in info and k not in ("config", "result")}
    if isinstance(info.get("config"), dict):
        kept["config"] = {k: info["config"][k] for k in _CONFIG_SHOWN
                          if k in info["config"] and isinstance(info["config"][k], _SCALAR)}
    result = info.get("result")
    if isinstance(result, dict):
        fresh = result.get("fresh")
        kept["result"] = {"best_fitness": result.get("best_fitness"),
                          "generations": result.get("generations")} | (
            {"fresh": {k: fresh[k] for k in _FRESH_SHOWN
                       if k in fresh and isinstance(fresh[k], _SCALAR)}}
            if isinstance(fresh, dict) else {})
    return kept


def read_run(run_dir: Path, root: Path, budget: Budget | None = None,
             locks: dict[tuple[int, int, int], list[int]] | bool | None = True
             ) -> RunSummary | None:
    """The summary of one run directory, or None when it vanished. ``locks``: the system's
    lock table (True: read it here)."""
    try:
        name = str(run_dir.relative_to(root)) if run_dir != root else run_dir.name
    except ValueError:
        name = str(run_dir)
    try:
        info, problem = read_run_info(run_dir, root)
    except FileNotFoundError:
        if not run_dir.exists():
            return None
        info, problem = {}, "run.json is missing"
    history = read_history(run_dir / "history.jsonl", root, budget)
    result = info.get("result") if isinstance(info.get("result"), dict) else None
    if problem:
        status = "unreadable"
    elif result is not None:
        status = "finished"
    elif _lock_holder(run_dir, root, _lock_table() if locks is True else
                      locks if isinstance(locks, dict) else None) is not None:
        status = "running"
    else:
        status = "interrupted"
    if history.problem and not problem:
        problem = history.problem
    best = number(result.get("best_fitness")) if result else None
    best_is_result = best is not None
    if best is None:
        best = history.best
    last = result.get("generations") if result else None
    if not isinstance(last, int) or isinstance(last, bool):
        last = history.last_generation
    success = None
    success_text = "–"
    if result and isinstance(result.get("fresh"), dict):
        success = number(result["fresh"].get("success_rate"))
        success_text = fresh_text(result["fresh"])
    seed = info.get("seed")
    return RunSummary(
        name=name, path=run_dir, task=clip(str(info.get("task", "?")), MAX_TEXT),
        task_module=str(info.get("task_module", "")), settings=_settings_text(info),
        seed=seed if isinstance(seed, int) and not isinstance(seed, bool) else None,
        status=status,
        task_settings=", ".join(f"{k}={v}" for k, v in
                                dict(info.get("task_settings") or {}).items()),
        generations=history.generations, best=best, success=success,
        problem=clip(problem, MAX_TEXT), success_text=success_text, points=history.points,
        reading=not history.complete, last_generation=last, generation_best=history.best,
        best_is_result=best_is_result,
    )


def fresh_text(fresh: dict[str, Any]) -> str:
    """A run's fresh check in a table cell: ``99.8% (99.5–100.0) holds``; an older run's
    (no bounds) as its rate alone."""
    rate = number(fresh.get("success_rate"))
    if rate is None:
        return "–"
    if fresh.get("deterministic") is True:  # one episode is every episode: no bounds
        return "reaches the target" if rate >= 1.0 else "does not reach the target"
    text = f"{100 * rate:.1f}%"
    lower, upper = number(fresh.get("lower")), number(fresh.get("upper"))
    if lower is not None and upper is not None:
        text += f" ({100 * lower:.1f}–{100 * upper:.1f})"
    holds = fresh.get("holds")
    if holds is True:
        text += " holds"
    elif holds is False:
        text += " does not hold"
    return text


def find_runs(root: Path, budget: Budget | None = None) -> list[RunSummary]:
    """Every run directory (one with ``run.json``) at or below ``root``, by name; at most
    :data:`MAX_RUNS`, :data:`MAX_DEPTH` folders deep, hidden and linked folders skipped.
    The histories read take at most ``budget`` new bytes (default
    :data:`MAX_REFRESH_READ`); a run whose history is not read to its end yet says so
    (``reading``). A run whose files cannot be used is listed with its problem."""
    found: list[Path] = []
    budget = Budget(MAX_REFRESH_READ) if budget is None else budget

    def walk(folder: Path, depth: int) -> None:
        if len(found) >= MAX_RUNS:
            return
        if (folder / "run.json").is_file():
            found.append(folder)
            return
        if depth >= MAX_DEPTH:
            return
        try:
            with os.scandir(folder) as it:
                children = sorted(Path(e.path) for e in it
                                  if e.is_dir(follow_symlinks=False) and unicode_name(e.name)
                                  and not e.name.startswith("."))
        except OSError:
            return
        for child in children:
            walk(child, depth + 1)

    walk(root, 0)
    runs = []
    locks = _lock_table()
    for path in found:
        try:
            summary = read_run(path, root, budget, locks)
        except OSError:
            continue
        except Exception as exc:  # one run's files never cost the others their rows
            summary = _broken_run(path, root, f"unexpected {type(exc).__name__}: {exc}")
        if summary is not None:
            runs.append(summary)
    return runs


def _broken_run(path: Path, root: Path, problem: str) -> RunSummary:
    try:
        name = str(path.relative_to(root))
    except ValueError:
        name = str(path)
    return RunSummary(name=name, path=path, task="?", task_module="", settings="",
                      seed=None, status="unreadable", generations=0, best=None,
                      success=None, problem=clip(one_line(problem), MAX_TEXT))


# ---------------------------------------------------------------------------------------
# FSA files
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StateRow:
    """One state as the FSA page lists it."""

    name: str
    skill: str
    params: tuple[str, ...]  # "x = 0.6 m (float in [0.2, 1])"
    transitions: tuple[str, ...]  # "success → Grasp"
    flags: tuple[str, ...]  # start, unreachable, trap


@dataclass(frozen=True)
class FSAView:
    """An FSA file read for the FSA page: its text, and the FSA or its problems."""

    path: Path
    text: str
    fsa: FSA | None
    problems: tuple[Problem, ...] = ()
    rows: tuple[StateRow, ...] = ()
    unreachable: tuple[str, ...] = ()
    traps: tuple[str, ...] = ()
    checked_against: str = ""  # the skills it was checked against ("": its structure only)
    error_lines: tuple[int, ...] = field(default=())


def describe_value(value: Any, registry: Registry | None, skill: str, param: str) -> str:
    """``value`` with the unit and range the skill declares for ``param``, when known."""
    shown = ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value) \
        if isinstance(value, (list, tuple)) else \
        (f"{value:g}" if isinstance(value, float) else str(value))
    if isinstance(value, (list, tuple)):
        shown = f"[{shown}]"
    if registry is None or skill not in registry:
        return f"{param} = {shown}"
    try:
        spec = registry.spec(skill).param(param)
    except (KeyError, SkillcomposeError):
        return f"{param} = {shown}"
    unit = f" {spec.unit}" if spec.unit else ""
    allowed = spec.describe_range()
    if unit and allowed.endswith(unit):
        allowed = allowed[: -len(unit)]
    return f"{param} = {shown}{unit} ({allowed})"


def read_fsa(path: Path, registry: Registry | None = None, what: str = "",
             root: Path | None = None) -> FSAView:
    """Read the FSA file at ``path`` (inside ``root``; default: its folder) for display;
    problems (with their lines) instead of an exception. With a registry the FSA is also
    checked against its skills. The file is read once: the text shown is the text parsed."""
    try:
        data = read_below(path, path.parent if root is None else root, MAX_FILE_BYTES)
    except OSError as exc:
        msg = "file not found" if isinstance(exc, FileNotFoundError) else \
            f"cannot read the file: {exc.strerror or exc}"
        return FSAView(path, "", None, (Problem(msg, fix="check the path"),))
    text = data[:MAX_FILE_BYTES].decode("utf-8", "replace")
    try:
        if len(data) > MAX_FILE_BYTES or text.encode("utf-8") != data:
            # too large, or not UTF-8: the reader's own words for it, from the same bytes
            load_fsa(resolve_below(path, path.parent if root is None else root))
        fsa = loads_fsa(text, str(path))  # the reader's checks: size, YAML, keys, values
    except FSAValidationError as exc:
        return _with_problems(path, text, None, exc.problems)
    checked = ""  # the structure only: the skills and their parameters are not known
    if registry is not None:
        try:
            fsa.validate(registry)
        except FSAValidationError as exc:
            return _with_problems(path, text, fsa, exc.problems)
        checked = f"{what or 'the task'}'s {len(registry)} skills"
    unreachable = tuple(fsa.unreachable())
    traps = tuple(trap_states(fsa))
    return FSAView(path, text, fsa, (), _rows(fsa, registry, unreachable, traps),
                   unreachable, traps, checked)


def read_fsa_file(path: Path, root: Path) -> FSA:
    """The FSA in the file ``path`` inside ``root``, read once and bounded; raises
    :class:`skillcompose.errors.FSAFileError` (one line per problem) as ``load_fsa`` does,
    and for a file outside ``root``."""
    view = read_fsa(path, root=root)
    if view.fsa is None or view.problems:
        from skillcompose.errors import FSAFileError

        raise FSAFileError(view.problems, str(path))
    return view.fsa


def _with_problems(path: Path, text: str, fsa: FSA | None,
                   problems: Sequence[Problem]) -> FSAView:
    lines = tuple(sorted({p.line for p in problems if p.line is not None}))
    rows = _rows(fsa, None, (), ()) if fsa is not None else ()
    return FSAView(path, text, fsa, tuple(problems), rows, error_lines=lines)


def _rows(fsa: FSA, registry: Registry | None, unreachable: Sequence[str],
          traps: Sequence[str]) -> tuple[StateRow, ...]:
    rows = []
    for name, st in fsa.states.items():
        flags = []
        if name == fsa.start:
            flags.append("start")
        if name in unreachable:
            flags.append("unreachable")
        if name in traps:
            flags.append("trap")
        rows.append(StateRow(
            name, st.skill,
            tuple(describe_value(v, registry, st.skill, p) for p, v in st.params.items()),
            tuple(f"{o} → {t}" for o, t in st.transitions.items()), tuple(flags)))
    return tuple(rows)


_MERMAID_SAFE = frozenset(" _.,:-+=()[]/*")


def _esc(text: str) -> str:
    """``text`` for a quoted Mermaid label: letters, digits and a few signs as they are,
    every other character as Mermaid's entity code ``#<decimal>;`` (so that no name can
    end the label, start a directive such as ``%%{init}%%``, or reach the page as HTML;
    Mermaid turns the code into an HTML character reference, shown as the character)."""
    return "".join(c if (c.isalnum() and c.isprintable()) or c in _MERMAID_SAFE
                   else f"#{ord(c)};" for c in text)


def mermaid(fsa: FSA, *, active: str | None = None, params: Mapping[str, Sequence[str]] |
            None = None, unreachable: Sequence[str] = (), traps: Sequence[str] = (),
            ended: str | None = None) -> str:
    """The FSA as a Mermaid flowchart: one node per state (``s<k>``, labelled with the state,
    its skill and ``params[state]``), one per terminal outcome (``t<k>``), one edge per
    (state, target) labelled with its outcomes. Classes: ``start``, ``unreachable``,
    ``trap``, ``terminal``, ``active`` (the state ``active``, or the terminal ``ended``)."""
    ids = {s: f"s{k}" for k, s in enumerate(fsa.states)}
    tids = {t: f"t{k}" for k, t in enumerate(fsa.terminals)}
    lines = ["flowchart TD"]
    for name, st in fsa.states.items():
        label = f"<b>{_esc(name)}</b><br/>{_esc(st.skill)}"
        for p in (params or {}).get(name, ()):
            label += f"<br/><small>{_esc(p)}</small>"
        lines.append(f'  {ids[name]}["{label}"]')
    for t, tid in tids.items():
        lines.append(f'  {tid}(["{_esc(t)}"])')
    for name, st in fsa.states.items():
        grouped: dict[str, list[str]] = {}
        for outcome, target in st.transitions.items():
            grouped.setdefault(target, []).append(outcome)
        for target, outs in grouped.items():
            dest = tids.get(target) or ids.get(target)
            if dest is not None:
                lines.append(f'  {ids[name]} -->|"{_esc(", ".join(outs))}"| {dest}')
    lines += [
        "  classDef start stroke:#2563eb,stroke-width:4px",
        "  classDef unreachable fill:#e5e7eb,stroke:#9ca3af,stroke-dasharray:4 3,color:#6b7280",
        "  classDef trap fill:#fee2e2,stroke:#dc2626,stroke-width:2px",
        "  classDef terminal fill:#ecfdf5,stroke:#059669",
        "  classDef active fill:#fde047,stroke:#ca8a04,stroke-width:4px",
        f"  class {ids[fsa.start]} start",
    ]
    if tids:
        lines.append(f"  class {','.join(tids.values())} terminal")
    for cls, names in (("unreachable", unreachable), ("trap", traps)):
        chosen = [ids[n] for n in names if n in ids]
        if chosen:
            lines.append(f"  class {','.join(chosen)} {cls}")
    if active in ids:
        lines.append(f"  class {ids[active]} active")
    elif ended in tids:
        lines.append(f"  class {tids[ended]} active")
    return "\n".join(lines) + "\n"
