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

import json
import os
import time
from collections.abc import Collection
from pathlib import Path
from types import TracebackType
from typing import Any

from skillcompose import Blackboard
from skillcompose.executor import FSARun
from skillcompose.files import atomic_write, read_limited
from skillcompose.fsa import FSA
from skillcompose.fsafile import dumps_fsa

from .episode import short

__all__ = ["LIVE_FORMAT", "LIVE_SUFFIX", "LivePublisher", "read_live"]

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


def read_live(path: Path) -> dict[str, Any] | None:
    """A live file's record, or None when it is missing, being replaced or not one."""
    try:
        record = json.loads(read_limited(path, MAX_LIVE_BYTES)[:MAX_LIVE_BYTES])
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(record, dict) or record.get("format") != LIVE_FORMAT:
        return None
    return record
