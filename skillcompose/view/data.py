"""What the viewer shows, read from files and runs: plain data, no web code.

Every reader here tolerates files that are being written (a half-written last line of
``history.jsonl`` is skipped), files that vanish between a listing and a read (the run is
left out) and files that are not what they should be (shown as their problem), so the pages
built on it never fail on a run directory in use.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from skillcompose.errors import FSAValidationError, Problem, SkillcomposeError
from skillcompose.files import read_limited
from skillcompose.fsa import FSA
from skillcompose.fsafile import MAX_FILE_BYTES, load_fsa
from skillcompose.graph import trap_states
from skillcompose.registry import Registry

__all__ = [
    "FSAView", "RunSummary", "StateRow", "describe_value", "find_runs", "mermaid", "pid_alive",
    "read_fsa", "read_history", "read_run", "read_run_info",
]

MAX_RUNS = 200  # run directories listed under one folder
MAX_DEPTH = 4  # how deep below the folder run directories are looked for
MAX_HISTORY_BYTES = 64 * 1024 * 1024
MAX_RUN_JSON_BYTES = 16 * 1024 * 1024


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
    generations: int
    best: float | None
    success: float | None  # share of fresh episodes that succeeded, at the end
    problem: str = ""  # why a file of the run could not be read
    task_settings: str = ""  # the task's settings alone, as name=value, ...
    success_text: str = "–"  # the fresh rate, its bounds and whether it holds, readable


def read_history(path: Path) -> list[dict[str, Any]]:
    """The generations of ``history.jsonl`` that are complete JSON objects, in order (a line
    being written, or a damaged one, is skipped); [] when the file is missing."""
    try:
        data = read_limited(path, MAX_HISTORY_BYTES)[:MAX_HISTORY_BYTES]
    except OSError:
        return []
    records = []
    for line in data.split(b"\n"):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except (ValueError, RecursionError):
            continue
        if isinstance(rec, dict) and isinstance(rec.get("generation"), int):
            records.append(rec)
    return records


def pid_alive(pid: int) -> bool:
    """Whether process ``pid`` exists (on this machine)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OSError:
        return False
    return True


def _lockers(path: Path) -> list[int] | None:
    """The processes holding a lock on ``path``, as the system lists them in /proc/locks
    (Linux), or None where it does not."""
    try:
        st = path.stat()
        with open("/proc/locks", encoding="ascii", errors="replace") as f:
            text = f.read()
    except OSError:
        return None
    want = (os.major(st.st_dev), os.minor(st.st_dev), st.st_ino)
    pids = []
    for line in text.splitlines():
        parts = line.split()  # "1: POSIX  ADVISORY  WRITE 4242 fe:00:6029412 0 EOF"
        if len(parts) < 6 or parts[1] == "->":  # "->": a process waiting for the lock
            continue
        try:
            major, minor, inode = parts[5].split(":")
            if (int(major, 16), int(minor, 16), int(inode)) == want:
                pids.append(int(parts[4]))
        except ValueError:
            continue
    return pids


def _lock_holder(run_dir: Path) -> int | None:
    """The process evolving in ``run_dir``: the one holding the lock on ``.lock`` (an
    evolve holds it while it runs, and writes its process id there). The lock is read from
    the system's list, without opening the file (closing any descriptor of a file drops
    the POSIX locks its process holds on it, so an evolve running in this process would
    lose its own) and without trying the lock (trying it, even shared, could make an
    ``evolve --resume`` starting at that moment fail). Where the system lists no locks,
    the process whose id is written there, if it lives (which an id reused by another
    process can fake)."""
    lock = run_dir / ".lock"
    holders = _lockers(lock)
    if holders is not None:
        return holders[0] if holders else None
    try:
        pid = int(lock.read_text(encoding="utf-8", errors="replace")[:32].strip())
    except (OSError, ValueError):
        return None
    return pid if pid > 0 and pid_alive(pid) else None


def _settings_text(info: Mapping[str, Any]) -> str:
    parts = [f"{k}={v}" for k, v in dict(info.get("task_settings") or {}).items()]
    config = info.get("config")
    if isinstance(config, Mapping):
        for key in ("population", "generations", "trials", "elitism"):
            if config.get(key) is not None:
                parts.append(f"{key}={config[key]}")
    if info.get("backend"):
        workers = info.get("workers")
        parts.append(f"backend={info['backend']}" + (f"×{workers}" if workers else ""))
    return ", ".join(parts)


def _number(value: Any) -> float | None:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
        else None


def read_run_info(run_dir: Path) -> tuple[dict[str, Any], str]:
    """The object in ``run_dir``'s ``run.json``, and why it cannot be used ("" when it
    can; then ``{}``). Raises :class:`FileNotFoundError` when there is none."""
    try:
        data = read_limited(run_dir / "run.json", MAX_RUN_JSON_BYTES)
    except FileNotFoundError:
        raise
    except OSError as exc:
        return {}, f"run.json cannot be read: {exc.strerror}"
    if len(data) > MAX_RUN_JSON_BYTES:
        return {}, f"run.json cannot be read: larger than {MAX_RUN_JSON_BYTES >> 20} MiB"
    try:
        loaded = json.loads(data.decode("utf-8"))  # (not UTF-8: a ValueError too)
    except (ValueError, RecursionError):
        loaded = None
    if not isinstance(loaded, dict):
        return {}, "run.json is not a JSON object (being written, or damaged)"
    return loaded, ""


def read_run(run_dir: Path, root: Path) -> RunSummary | None:
    """The summary of one run directory, or None when it vanished."""
    try:
        name = str(run_dir.relative_to(root)) if run_dir != root else run_dir.name
    except ValueError:
        name = str(run_dir)
    try:
        info, problem = read_run_info(run_dir)
    except FileNotFoundError:
        if not run_dir.exists():
            return None
        info, problem = {}, "run.json is missing"
    history = read_history(run_dir / "history.jsonl")
    result = info.get("result") if isinstance(info.get("result"), dict) else None
    if problem:
        status = "unreadable"
    elif result is not None:
        status = "finished"
    elif _lock_holder(run_dir) is not None:
        status = "running"
    else:
        status = "interrupted"
    best = _number(result.get("best_fitness")) if result else None
    if best is None and history:
        best = _number(history[-1].get("best"))
    success = None
    success_text = "–"
    if result and isinstance(result.get("fresh"), dict):
        success = _number(result["fresh"].get("success_rate"))
        success_text = fresh_text(result["fresh"])
    seed = info.get("seed")
    return RunSummary(
        name=name, path=run_dir, task=str(info.get("task", "?")),
        task_module=str(info.get("task_module", "")), settings=_settings_text(info),
        seed=seed if isinstance(seed, int) else None, status=status,
        task_settings=", ".join(f"{k}={v}" for k, v in
                                dict(info.get("task_settings") or {}).items()),
        generations=len(history), best=best, success=success, problem=problem,
        success_text=success_text,
    )


def fresh_text(fresh: dict[str, Any]) -> str:
    """A run's fresh check in a table cell: ``99.8% (99.5–100.0) holds``; an older run's
    (no bounds) as its rate alone."""
    rate = _number(fresh.get("success_rate"))
    if rate is None:
        return "–"
    text = f"{100 * rate:.1f}%"
    lower, upper = _number(fresh.get("lower")), _number(fresh.get("upper"))
    if lower is not None and upper is not None:
        text += f" ({100 * lower:.1f}–{100 * upper:.1f})"
    holds = fresh.get("holds")
    if holds is True:
        text += " holds"
    elif holds is False:
        text += " does not hold"
    return text


def find_runs(root: Path) -> list[RunSummary]:
    """Every run directory (one with ``run.json``) at or below ``root``, by name; at most
    :data:`MAX_RUNS`, :data:`MAX_DEPTH` folders deep, hidden folders skipped."""
    found: list[Path] = []

    def walk(folder: Path, depth: int) -> None:
        if len(found) >= MAX_RUNS:
            return
        if (folder / "run.json").is_file():
            found.append(folder)
            return
        if depth >= MAX_DEPTH:
            return
        try:
            children = sorted(p for p in folder.iterdir() if p.is_dir()
                              and not p.name.startswith(".") and not p.is_symlink())
        except OSError:
            return
        for child in children:
            walk(child, depth + 1)

    walk(root, 0)
    runs = []
    for path in found:
        with contextlib.suppress(OSError):
            summary = read_run(path, root)
            if summary is not None:
                runs.append(summary)
    return runs


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
    checked_against: str = ""  # what the FSA was validated against
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


def read_fsa(path: Path, registry: Registry | None = None, what: str = "") -> FSAView:
    """Read the FSA file at ``path`` for display; problems (with their lines) instead of an
    exception. With a registry the FSA is also checked against its skills."""
    try:
        text = read_limited(path, MAX_FILE_BYTES)[:MAX_FILE_BYTES].decode("utf-8", "replace")
    except OSError as exc:
        msg = "file not found" if isinstance(exc, FileNotFoundError) else \
            f"cannot read the file: {exc.strerror or exc}"
        return FSAView(path, "", None, (Problem(msg, fix="check the path"),))
    try:
        fsa = load_fsa(path)  # the reader's own checks: size, UTF-8, YAML, keys, values
    except FSAValidationError as exc:
        return _with_problems(path, text, None, exc.problems)
    checked = "structure only (give --task to check skills and parameters)"
    if registry is not None:
        try:
            fsa.validate(registry)
        except FSAValidationError as exc:
            return _with_problems(path, text, fsa, exc.problems)
        checked = f"checked against {what or 'the task'}'s {len(registry)} skills"
    unreachable = tuple(fsa.unreachable())
    traps = tuple(trap_states(fsa))
    return FSAView(path, text, fsa, (), _rows(fsa, registry, unreachable, traps),
                   unreachable, traps, checked)


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


def _esc(text: str) -> str:
    return (text.replace("&", "#amp;").replace('"', "#quot;").replace("<", "#lt;")
            .replace(">", "#gt;"))


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
