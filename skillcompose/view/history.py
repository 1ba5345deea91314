"""``history.jsonl`` read incrementally, with bounded memory.

An evolution appends one JSON line per generation; the runs page asks for every run's
history every second. :class:`HistoryReader` keeps, per file, where its last read stopped
and reads on from there only when the file changed (its inode, size or modification time),
at most :data:`MAX_HISTORY_READ` new bytes per read (a 100 MB history is read over several
refreshes, each a bounded piece of work, in the refresh's worker thread), and keeps a bounded
summary instead of the records: the record count, the last record's generation and best
fitness, and at most :data:`MAX_POINTS` (generation, best) points for the chart, thinned
evenly as the file grows (the last point always kept). A file replaced or rewritten
(another inode, shorter, or its bytes before the position changed) is read again from its
start. A line longer than :data:`MAX_LINE_BYTES` is skipped as damaged; a line still being
written is read once it is whole.

Written here: no library reads a growing JSON Lines file on from an offset (the standard
library's ``json`` parses each line; ``os.pread`` reads from the offset), and the least
recently used cache of summaries is a few lines over ``OrderedDict`` (``functools.lru_cache``
caches calls, not entries that are updated in place).
"""

from __future__ import annotations

import json
import math
import os
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .folder import open_below, read_fd

__all__ = ["HISTORIES", "MAX_HISTORY_READ", "MAX_LINE_BYTES", "MAX_POINTS", "MAX_WHOLE",
           "Budget", "Cache", "History", "HistoryReader", "number", "read_history", "stat_key"]

MAX_HISTORY_READ = 8 * 1024 * 1024  # new bytes of one history one read takes at most
MAX_LINE_BYTES = 1024 * 1024  # a longer line of a history is skipped as damaged
MAX_POINTS = 2000  # points of one history kept for the chart
MAX_CACHED = 400  # files whose summary is kept between reads


def stat_key(st: os.stat_result) -> tuple[int, int, int, int]:
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns


MAX_WHOLE = 2**53  # a whole number the page can hold exactly (larger ones are refused)


def number(value: Any) -> float | None:
    """``value`` as a finite float, or None (not a number, a bool, infinite, too large)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        out = float(value)
    except OverflowError:
        return None
    return out if math.isfinite(out) else None


class Cache(OrderedDict[Any, Any]):
    """A dict that forgets its least recently used entries beyond ``size``."""

    def __init__(self, size: int) -> None:
        super().__init__()
        self.size = size
        self.lock = threading.Lock()

    def remember(self, key: Any, value: Any) -> None:
        with self.lock:
            self[key] = value
            self.move_to_end(key)
            while len(self) > self.size:
                self.popitem(last=False)

    def recall(self, key: Any) -> Any:
        with self.lock:
            value = self.get(key)
            if value is not None:
                self.move_to_end(key)
            return value


# ---------------------------------------------------------------------------------------
# histories
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class History:
    """What the pages show of one ``history.jsonl``: how many complete generations it holds,
    the last one's best fitness, and (generation, best) points for the chart (all of them up
    to :data:`MAX_POINTS`, else evenly thinned, the last one always kept)."""

    generations: int = 0  # complete records read (lines, not the last one's index)
    best: float | None = None
    points: tuple[tuple[int, float], ...] = ()
    complete: bool = True  # False: part of the file is still to be read
    problem: str = ""  # why the file cannot be read ("" when it can, or is missing)
    last_generation: int | None = None  # the last record's ``generation`` (0: the first)


class Budget:
    """How many more bytes the reads of one listing may take."""

    def __init__(self, left: int) -> None:
        self.left = left


class _HistoryState:
    """One history file's reading position and the summary of what was read."""

    def __init__(self, ident: tuple[int, int]) -> None:
        self.ident = ident
        self.offset = 0  # bytes consumed: up to the end of the last complete line
        self.guard = b""  # the bytes just before offset, to notice a file rewritten
        self.seen: tuple[int, int, int, int] | None = None  # the stat read up to its end
        self.skipping = False  # inside a line longer than MAX_LINE_BYTES
        self.generations = 0
        self.last_generation: int | None = None
        self.best: float | None = None
        self.points: list[tuple[int, float]] = []
        self.candidates = 0  # points offered so far (kept: every stride-th)
        self.stride = 1
        self.last: tuple[int, float] | None = None
        self.snapshot = History()
        self.lock = threading.Lock()

    def take(self, line: bytes) -> None:
        if not line.strip() or len(line) > MAX_LINE_BYTES:
            return
        try:
            rec = json.loads(line)
        except (ValueError, RecursionError):
            return
        if not isinstance(rec, dict):
            return
        gen = rec.get("generation")
        if not isinstance(gen, int) or isinstance(gen, bool) or abs(gen) > MAX_WHOLE:
            return
        self.generations += 1
        self.last_generation = gen
        best = number(rec.get("best"))
        self.best = best
        if best is None:
            return
        point = (gen, best)
        self.last = point
        if self.candidates % self.stride == 0:
            self.points.append(point)
            if len(self.points) > MAX_POINTS:
                del self.points[1::2]
                self.stride *= 2
        self.candidates += 1

    def summary(self, complete: bool) -> History:
        points = tuple(self.points)
        if self.last is not None and (not points or points[-1] != self.last):
            points += (self.last,)
        return History(self.generations, self.best, points, complete,
                       last_generation=self.last_generation)


class HistoryReader:
    """Reads ``history.jsonl`` files incrementally (see the module's docstring);
    ``bytes_read`` counts every byte it has read, for the tests."""

    def __init__(self, max_read: int = MAX_HISTORY_READ) -> None:
        self.max_read = max(max_read, MAX_LINE_BYTES)
        self.bytes_read = 0
        self._states = Cache(MAX_CACHED)

    def read(self, path: Path, root: Path | None = None,
             budget: Budget | None = None) -> History:
        root = path.parent if root is None else root
        try:
            fd = open_below(path, root)
        except FileNotFoundError:
            return History()
        except OSError as exc:
            return History(problem=f"history.jsonl cannot be read: {exc.strerror or exc}")
        try:
            return self._read(fd, path, budget)
        finally:
            os.close(fd)

    def _read(self, fd: int, path: Path, budget: Budget | None) -> History:
        st = os.fstat(fd)
        key = str(path)
        state = self._states.recall(key)
        if state is None or state.ident != (st.st_dev, st.st_ino):
            state = _HistoryState((st.st_dev, st.st_ino))
            self._states.remember(key, state)
        if not state.lock.acquire(blocking=False):  # another thread is reading it now
            return state.snapshot
        try:
            if stat_key(st) == state.seen:
                return state.snapshot
            if st.st_size < state.offset or (state.guard and self._pread(
                    fd, len(state.guard), state.offset - len(state.guard)) != state.guard):
                fresh = _HistoryState(state.ident)  # rewritten: read it again from the start
                fresh.lock = state.lock
                state = fresh
                self._states.remember(key, state)
            if budget is not None and budget.left <= 0:  # this listing has read enough
                state.snapshot = state.summary(False)
                return state.snapshot
            start = state.offset
            data = self._pread(fd, min(self.max_read, st.st_size - start), start)
            if budget is not None:
                budget.left -= len(data)
            cut = data.rfind(b"\n")
            if cut >= 0:
                lines = data[:cut].split(b"\n")
                if state.skipping:  # the end of a line too long to be a generation
                    lines = lines[1:]
                    state.skipping = False
                for line in lines:
                    state.take(line)
                state.offset += cut + 1
                state.guard = data[max(0, cut + 1 - 64):cut + 1]
            elif len(data) >= MAX_LINE_BYTES:  # inside a line too long to be a generation
                state.skipping = True
                state.offset += len(data)
                state.guard = data[-64:]
            # a line still being written stays unread; it is read again once the file grows
            complete = start + len(data) >= st.st_size
            if complete:
                state.seen = stat_key(st)
            state.snapshot = state.summary(complete)
            return state.snapshot
        finally:
            state.lock.release()

    def _pread(self, fd: int, n: int, offset: int) -> bytes:
        data = read_fd(fd, n, offset) if n > 0 else b""
        self.bytes_read += len(data)
        return data


HISTORIES = HistoryReader()
"""The viewer's one history reader, shared by every page and refresh."""


def read_history(path: Path, root: Path | None = None, budget: Budget | None = None
                 ) -> History:
    """The summary of ``history.jsonl`` at ``path`` (inside ``root``; default: its folder),
    read on from where the last read of it stopped: only complete JSON objects with an
    integer ``generation`` count (a line being written, or a damaged one, is skipped); an
    empty summary when the file is missing."""
    return HISTORIES.read(path, root, budget)
