"""Publish a running FSA's state, so that ``skillcompose view`` shows it as it runs.

A program that drives a real or simulated robot runs its FSA tick-wise (``CompiledFSA.start``)
and hands each tick to a :class:`LivePublisher`, which writes a small JSON file atomically
(never a torn file) whenever the active state changes, and at most every ``interval``
seconds otherwise::

    run = compiled.start(bb, rng, trace=True)
    with LivePublisher("live/robot.live.json", compiled.fsa) as live:
        while run.tick() == RUNNING:
            live.publish(run, bb)
            time.sleep(0.05)
        live.publish(run, bb)

``skillcompose view live/`` lists every ``*.live.json`` below the folder on its Live page
and lights the active state of each. The file holds the FSA itself (its YAML), so the viewer
needs neither the program's skills nor its task. Importing this module loads no web code.
"""

from __future__ import annotations

import itertools
import json
import os
import time
from collections.abc import Collection
from pathlib import Path
from types import TracebackType
from typing import Any

from skillcompose import Blackboard
from skillcompose.executor import FSARun
from skillcompose.files import atomic_write
from skillcompose.fsa import FSA
from skillcompose.fsafile import MAX_FILE_BYTES, dumps_fsa

from .episode import short
from .folder import not_unicode, open_below, read_fd

__all__ = ["LIVE_FORMAT", "LIVE_SUFFIX", "LivePublisher", "live_problem", "read_live"]

LIVE_FORMAT = "skillcompose live state"
LIVE_SUFFIX = ".live.json"
MAX_LIVE_BYTES = 4 * 1024 * 1024


class LivePublisher:
    """Writes the state of one running FSA to ``path`` (a ``*.live.json`` file).

    ``keys`` limits the blackboard keys published (default: all, each shown as a short
    text); ``interval`` [s] is the longest time between two writes while a state runs.
    """

    def __init__(self, path: str | os.PathLike[str], fsa: FSA, *,
                 keys: Collection[str] | None = None, interval: float = 0.5) -> None:
        self.path = Path(path)
        if not self.path.name.endswith(LIVE_SUFFIX):
            raise ValueError(f"live file {self.path}: its name must end in {LIVE_SUFFIX}, "
                             "so that the viewer finds it")
        self.fsa = fsa
        self.keys = None if keys is None else frozenset(keys)
        self.interval = interval
        self._fsa_text = dumps_fsa(fsa)
        self._started = time.time()
        self._last: tuple[str, int, bool] | None = None
        self._written = 0.0
        self.path.parent.mkdir(parents=True, exist_ok=True)

    def publish(self, run: FSARun, bb: Blackboard | None = None) -> bool:
        """Write the run's state if it changed or ``interval`` passed; True if written."""
        trace = run.trace or ()
        now = time.time()
        key = (run.state, len(trace), run.done)
        if key == self._last and now - self._written < self.interval:
            return False
        last = trace[-1] if trace else None
        record: dict[str, Any] = {
            "format": LIVE_FORMAT,
            "name": self.fsa.name,
            "pid": os.getpid(),
            "started": self._started,
            "time": now,
            "state": None if run.done else run.state,
            "steps": len(trace),
            "done": run.done,
            "outcome": run.result.outcome if run.done else None,
            "last": None if last is None else {
                "state": last.state, "skill": last.skill, "outcome": last.outcome,
                "target": last.target},
            "blackboard": {} if bb is None else {
                k: short(v) for k, v in sorted(bb.to_dict().items())
                if self.keys is None or k in self.keys},
            "fsa": self._fsa_text,
        }
        atomic_write(self.path, (json.dumps(record) + "\n").encode())
        self._last = key
        self._written = now
        return True

    def close(self) -> None:
        """Nothing to release: the file stays, showing how the run ended."""

    def __enter__(self) -> LivePublisher:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


_PROBLEM = " problem"  # (a key no publisher writes) why read_live's record cannot be shown
_CACHE: dict[str, tuple[tuple[int, int, int, int], dict[str, Any] | None]] = {}
_CACHE_SIZE = 1000


def read_live(path: Path, root: Path | None = None) -> dict[str, Any] | None:
    """A live file's record, or None when it is missing, being replaced, not one, or not a
    regular file inside ``root`` (default: its folder). Parsed again only when the file
    changed (its inode, size or modification time), and kept as the page shows it
    (:func:`_kept`): what many live files cost is bounded."""
    try:
        fd = open_below(path, path.parent if root is None else root)
    except (OSError, ValueError):
        return None
    try:
        st = os.fstat(fd)
        key = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
        cached = _CACHE.get(str(path))
        if cached is not None and cached[0] == key:
            return cached[1]
        data = read_fd(fd, MAX_LIVE_BYTES + 1)
    except OSError:
        return None
    finally:
        os.close(fd)
    record: dict[str, Any] | None
    try:
        loaded = json.loads(data) if len(data) <= MAX_LIVE_BYTES else None
    except (ValueError, RecursionError):
        loaded = None
    record = loaded if isinstance(loaded, dict) and loaded.get("format") == LIVE_FORMAT \
        else None
    if record is not None and not_unicode(record):
        record = {"format": LIVE_FORMAT, _PROBLEM: "it holds text that is not Unicode (a "
                  "lone \\u surrogate)"}
    elif record is not None:
        record = _kept(record)
    if len(_CACHE) >= _CACHE_SIZE:
        _CACHE.clear()
    _CACHE[str(path)] = (key, record)
    return record


MAX_SHOWN_KEYS = 500  # blackboard keys of a live file the page keeps
MAX_SHOWN_TEXT = 200  # characters of a blackboard key or value kept (a publisher writes 80)


def _kept(record: dict[str, Any]) -> dict[str, Any]:
    """What the page uses of a live file's record, bounded: the fields a publisher writes,
    names cut to 4096 characters, the FSA's text to what its reader would still read, the
    blackboard to :data:`MAX_SHOWN_KEYS` keys of :data:`MAX_SHOWN_TEXT` characters."""
    kept = {k: v for k, v in record.items() if k in _LIVE_FIELDS or (k in (
        "format", "started", "time") and not isinstance(v, (dict, list, str)))}
    for key in ("name", "state", "outcome"):
        if isinstance(kept.get(key), str):
            kept[key] = kept[key][:4096]
    if isinstance(kept.get("fsa"), str):
        kept["fsa"] = kept["fsa"][:MAX_FILE_BYTES + 1]  # longer: the reader's "too large"
    if isinstance(kept.get("blackboard"), dict):
        kept["blackboard"] = {_cut(k): _cut(v) for k, v in itertools.islice(
            kept["blackboard"].items(), MAX_SHOWN_KEYS)}
    if isinstance(kept.get("last"), dict):
        kept["last"] = {k: _cut(kept["last"].get(k)) for k in (
            "state", "skill", "outcome", "target") if k in kept["last"]}
    kept["format"] = LIVE_FORMAT
    return kept


def _cut(value: Any) -> Any:
    if value is None or isinstance(value, (bool, int, float)):
        return value
    text = value if isinstance(value, str) else str(value)
    return text if len(text) <= MAX_SHOWN_TEXT else text[:MAX_SHOWN_TEXT - 3] + "..."


_LIVE_FIELDS: dict[str, tuple[type, ...]] = {
    "name": (str, type(None)), "pid": (int, type(None)), "state": (str, type(None)),
    "steps": (int,), "done": (bool,), "outcome": (str, type(None)),
    "blackboard": (dict, type(None)), "fsa": (str,), "last": (dict, type(None)),
}


def live_problem(record: dict[str, Any]) -> str | None:
    """Why a live file's record cannot be shown (None: it can): a field the page shows is
    missing or of another type than :class:`LivePublisher` writes."""
    if isinstance(record.get(_PROBLEM), str):
        return str(record[_PROBLEM])
    for key, types in _LIVE_FIELDS.items():
        if key not in record and type(None) in types:
            continue
        value = record.get(key)
        if key not in record or not isinstance(value, types) or (
                isinstance(value, bool) and bool not in types):
            what = "missing" if key not in record else f"of type {type(value).__name__}"
            return (f"its {key} is {what}; expected "
                    f"{' or '.join(t.__name__ for t in types if t is not type(None))}")
    return None
