"""The run directory: what an evolution writes as it goes, and its checkpoints.

Files (all written atomically, so a killed run leaves no torn file but ``history.jsonl``,
which a resume rewrites from the checkpoint; a file keeps its mode when rewritten, a new one
gets the umask's):

- ``best.yaml``      the best FSA so far, editable, in the runtime's file format; its
                     fitness and lineage are under ``meta:``. At the end: the simplified FSA.
- ``best_evolved.yaml`` the best FSA as evolved, before simplification (at the end).
- ``best.dot`` / ``best.png`` its drawing (Graphviz text; PNG at checkpoints and the end,
                     none for an FSA of more than :data:`MAX_DRAWN_STATES` states).
- ``history.jsonl``  one JSON line per generation: best / mean / median fitness, best
                     size, evaluations, evaluations/s, wall time.
- ``fitness.png``    the fitness plot.
- ``run.json``       the task, seed, backend and settings of the run, for people to read.
- ``checkpoint.json`` everything needed to continue (:data:`CHECKPOINT_VERSION`): plain data
                     that cannot run code, with a SHA-256 checksum of its content.
- ``.lock``          locked (``lockf``) by the one process evolving in the directory.
- ``.written.json``  the SHA-256 of what the run last wrote to ``best.yaml`` and
                     ``best_evolved.yaml``: a file that differs was edited by a person, and
                     is kept (renamed ``best.edited.yaml``, ``best.edited-2.yaml``, ...)
                     before the run writes its own.

A new run (``--out``) refuses a directory that holds a run's files without a checkpoint
(``run.json``, ``history.jsonl``, ``best.yaml``, ``best_evolved.yaml`` and the drawings):
another run's, or a person's, which it would overwrite.

A checkpoint is one header line, a JSON object
``{"format": "skillcompose evolve checkpoint", "version": 2, "sha256": HEX, "bytes": N}``,
followed by N bytes: the run's state as compact JSON (floats exactly, ``Infinity`` for the
worst fitness). Any change to those bytes, a single bit included, fails the checksum.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import stat
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import IO, Any

from skillcompose import FSA, dumps_fsa
from skillcompose.draw import render, to_dot
from skillcompose.files import (
    TEMPORARY_MARK,
    atomic_write,
    not_a_file,
    read_limited,
    temporary_beside,
)
from skillcompose.registry import Registry

from .errors import CheckpointError

try:
    import fcntl
except ImportError:  # pragma: no cover - platforms without flock: no lock
    fcntl = None  # type: ignore[assignment]

__all__ = ["CHECKPOINT_FORMAT", "CHECKPOINT_VERSION", "MAX_DRAWN_STATES", "RunDir",
           "draw_fsa", "plot_history"]

MAX_CHECKPOINT_BYTES = 2 << 30
"""The largest checkpoint read (a run's state, its cache included, is far smaller)."""
MAX_RUN_JSON_BYTES = 16 << 20
"""The largest ``run.json`` read."""
MAX_DRAWN_STATES = 100
"""The most states of an FSA the run draws in ``best.png``: a picture of more is too
large to read and slow to draw (matplotlib, on a busy two-core machine: 2.3 s for 92 states,
4.9 s for 170, 10.6 s for 318, at every checkpoint); ``best.dot`` and ``skillcompose show``
still draw any FSA."""

CHECKPOINT_FORMAT = "skillcompose evolve checkpoint"
CHECKPOINT_VERSION = 2  # 1 was a pickle, which is never loaded (it could run code)
_HEADER_MAX = 1024


def _atomic_write(path: Path, data: bytes) -> None:
    atomic_write(path, data, sync=True)


def _read(path: Path, limit: int, fix: str) -> bytes:
    """A run file's bytes, or one line saying why not: missing, not a regular file (a pipe
    would wait for ever, a device never end), larger than ``limit``."""
    try:
        too_large = os.stat(path).st_size > limit  # said without reading gigabytes
        data = b"" if too_large else read_limited(path, limit)
    except OSError as exc:
        raise CheckpointError(f"{path} cannot be read: {exc.strerror or exc}; {fix}") from None
    if too_large or len(data) > limit:
        raise CheckpointError(f"{path} is larger than {limit >> 20} MiB, more than any run "
                              f"writes there; {fix}")
    return data


class RunDir:
    """Writes one run's files under ``path``; one process at a time (:meth:`lock`)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.best_yaml = self.path / "best.yaml"
        self.best_evolved_yaml = self.path / "best_evolved.yaml"
        self.best_dot = self.path / "best.dot"
        self.best_png = self.path / "best.png"
        self.history = self.path / "history.jsonl"
        self.fitness_png = self.path / "fitness.png"
        self.run_json = self.path / "run.json"
        self.checkpoint = self.path / "checkpoint.json"
        self.old_checkpoint = self.path / "checkpoint.pkl"
        self.lock_file = self.path / ".lock"
        self.written_json = self.path / ".written.json"
        self._lock: IO[str] | None = None
        self._written: dict[str, list[str]] | None = None
        self.kept: list[tuple[Path, Path]] = []  # edited files kept: (file, kept as)

    # -- one process at a time -------------------------------------------------------------
    def lock(self) -> None:
        """Hold the directory's lock until :meth:`unlock` (or this process ends); then remove
        the temporary files a killed run may have left. Raises :class:`CheckpointError` when
        another process holds it."""
        if self._lock is not None:
            return
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:  # under a file, on a read-only file system, not allowed
            raise CheckpointError(
                f"{self.path}: the run's folder cannot be made ({exc.strerror or exc}); give "
                "a folder you can write in"
            ) from None
        # never through a link (a directory from elsewhere could point .lock at a file of
        # yours, which writing the process id would destroy), never waiting on a pipe
        flags = os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | \
            getattr(os, "O_NONBLOCK", 0)
        what = "is not a file"
        try:
            fd = os.open(self.lock_file, flags, 0o666)
        except OSError as exc:
            fd = -1
            what = "is a link" if os.path.islink(self.lock_file) else \
                f"cannot be opened: {exc.strerror}"
        kind = None if fd < 0 or stat.S_ISREG(os.fstat(fd).st_mode) else \
            not_a_file(self.lock_file) or "not a file"
        if fd < 0 or kind is not None:
            if fd >= 0:
                os.close(fd)
            raise CheckpointError(
                f"{self.lock_file} {f'is {kind}' if kind else what}, where evolve keeps its "
                "lock file; remove it, then run again"
            )
        f = open(fd, "a+", encoding="utf-8")  # noqa: SIM115 - held open on purpose
        if fcntl is not None:
            try:
                # a POSIX record lock: held by this process only, not by the processes it
                # forks (pool workers), so it ends with this process, however it ends
                fcntl.lockf(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                f.seek(0)
                holder = f.read().strip() or "unknown"
                f.close()
                raise CheckpointError(
                    f"{self.path} is in use by another evolve (process {holder}); wait for it "
                    "to end, or choose another --out directory"
                ) from None
        f.seek(0)
        f.truncate()
        f.write(f"{os.getpid()}\n")
        f.flush()
        self._lock = f
        self.remove_temporary()
        for p in (self.best_yaml, self.best_evolved_yaml, self.best_dot, self.best_png,
                  self.history, self.fitness_png, self.run_json, self.checkpoint,
                  self.written_json):
            kind = not_a_file(p)
            if kind is not None:
                self.unlock()
                raise CheckpointError(
                    f"{p} is {kind}, where the run keeps a file; remove or rename it, then "
                    "run again"
                )

    def unlock(self) -> None:
        if self._lock is not None:
            self._lock.close()  # closing the file releases the lock
            self._lock = None

    def remove_temporary(self) -> list[Path]:
        """Remove the temporary files (``.NAME.tmp-*``) a killed writer left behind."""
        gone = []
        for p in self.path.glob(f".*{TEMPORARY_MARK}*"):
            with contextlib.suppress(OSError):
                p.unlink()
                gone.append(p)
        return gone

    # -- files -----------------------------------------------------------------------------
    def create(self, run_info: Mapping[str, Any]) -> None:
        """Start a new run here (locked), refusing a directory that holds a run: one with
        its checkpoint, or a run's files without one (another run's, or a person's, which
        the new run would overwrite); nothing is written then."""
        for locked in (False, True):  # looked at before taking the lock too: nothing made
            if locked:
                self.lock()
            for cp in (self.checkpoint, self.old_checkpoint):
                if cp.exists():
                    raise CheckpointError(
                        f"{self.path} holds a run already ({cp.name}); continue it with "
                        f"--resume {self.path}, or choose another --out directory"
                    )
            held = [p.name for p in (self.run_json, self.history, self.best_yaml,
                                     self.best_evolved_yaml, self.best_dot, self.best_png,
                                     self.fitness_png) if os.path.lexists(p)]
            if held and not self._killed_as_it_started(held):
                raise CheckpointError(
                    f"{self.path} holds {', '.join(held)} but no checkpoint: another run's "
                    "files or yours, which a new run would overwrite; choose another --out "
                    "directory, or move them away"
                )
        self.write_run_info(run_info)
        _atomic_write(self.history, b"")

    def _killed_as_it_started(self, held: list[str]) -> bool:
        """Whether the run files here are only those of a run killed before its first
        checkpoint (``run.json`` as evolve writes it, an empty history): nothing anyone
        would lose, and a new run may take the directory."""
        if not set(held) <= {self.run_json.name, self.history.name}:
            return False
        try:
            if self.history.name in held and read_limited(self.history, 0):
                return False
            info = json.loads(read_limited(self.run_json, MAX_RUN_JSON_BYTES))
        except (OSError, ValueError, RecursionError):
            return False
        return isinstance(info, dict) and {"task", "seed", "config"} <= set(info) and \
            "result" not in info

    def write_run_info(self, run_info: Mapping[str, Any]) -> None:
        _atomic_write(self.run_json, (json.dumps(run_info, indent=2) + "\n").encode())

    def update_run_info(self, changes: Mapping[str, Any]) -> None:
        """Add or replace top-level entries of ``run.json`` (the result, at the end)."""
        info = self.load_run_info()
        info.update(changes)
        _atomic_write(self.run_json, (json.dumps(info, indent=2, default=str) + "\n").encode())

    def append_history(self, record: Mapping[str, Any]) -> None:
        with self.history.open("a", encoding="utf-8") as f:
            f.write(json.dumps(record) + "\n")

    def rewrite_history(self, records: Sequence[Mapping[str, Any]]) -> None:
        text = "".join(json.dumps(r) + "\n" for r in records)
        _atomic_write(self.history, text.encode())

    def write_best(
        self, fsa: FSA, registry: Registry, header: str, path: Path | None = None
    ) -> None:
        self.write_editable(path or self.best_yaml,
                            dumps_fsa(fsa, registry, header=header).encode("utf-8"))
        _atomic_write(self.best_dot, to_dot(fsa).encode())

    # -- files a person may edit -----------------------------------------------------------
    def _written_map(self) -> dict[str, list[str]]:
        """Per file name, the SHA-256 of what this run last wrote there (the one before it
        too: a run killed between recording and writing leaves either on disk)."""
        if self._written is None:
            self._written = {}
            try:
                data = json.loads(read_limited(self.written_json, 1 << 20).decode("utf-8"))
            except (OSError, ValueError, RecursionError):
                data = {}
            if isinstance(data, dict):
                self._written = {str(k): [h for h in v if isinstance(h, str)]
                                 for k, v in data.items() if isinstance(v, list)}
        return self._written

    def keep_edits(self, path: Path) -> Path | None:
        """If ``path`` holds what this run did not write there (a person edited it), rename
        it to a free ``NAME.edited[-K].yaml`` beside it, say so on standard error and
        return where it went; else None."""
        try:
            if not path.is_file():  # absent, or not a file: writing says what is wrong
                return None
            digest = hashlib.sha256(read_limited(path, 16 << 20)).hexdigest()
        except OSError:
            return None
        recorded = self._written_map().get(path.name)
        if digest in (recorded or []):
            return None
        stem = path.name.removesuffix(".yaml")
        for k in range(1, 10_000):
            aside = path.with_name(f"{stem}.edited{'' if k == 1 else f'-{k}'}.yaml")
            try:
                os.link(path, aside)  # never over an existing file
            except FileExistsError:
                continue
            except OSError:  # no hard links here: rename, having checked the name is free
                if os.path.lexists(aside):
                    continue
                os.rename(path, aside)
            else:
                os.unlink(path)
            self.kept.append((path, aside))
            why = "was edited since this run wrote it" if recorded else (
                f"may have been edited: the run's record of what it wrote there "
                f"({self.written_json.name}) is missing or unreadable")
            print(f"{path} {why}: kept as {aside.name}, and the run writes its own "
                  f"{path.name}", file=sys.stderr)
            return aside
        raise CheckpointError(f"{path} was edited, and no free name is left beside it to "
                              "keep it under; move the .edited files away")

    def write_editable(self, path: Path, data: bytes) -> None:
        """Write ``data`` to ``path`` (atomically, keeping its mode), having kept a person's
        edits of it (:meth:`keep_edits`)."""
        self.keep_edits(path)
        written = self._written_map()
        written[path.name] = [*written.get(path.name, [])[-1:],
                              hashlib.sha256(data).hexdigest()]
        _atomic_write(self.written_json, (json.dumps(written, indent=1) + "\n").encode())
        atomic_write(path, data)

    # -- checkpoints -----------------------------------------------------------------------
    def save_checkpoint(self, state: Mapping[str, Any]) -> None:
        """Write ``state`` (plain JSON data) as a versioned, checksummed checkpoint."""
        payload = json.dumps(state, separators=(",", ":"), allow_nan=True).encode()
        header = json.dumps({
            "format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION,
            "sha256": hashlib.sha256(payload).hexdigest(), "bytes": len(payload),
        }, separators=(",", ":")).encode()
        _atomic_write(self.checkpoint, header + b"\n" + payload)

    def load_checkpoint(self) -> dict[str, Any]:
        """The state of the last checkpoint, checked: never code, only data. Raises
        :class:`CheckpointError` (one line) when it is missing, damaged or of another
        version."""
        cp = self.checkpoint
        if not cp.exists():
            if self.old_checkpoint.exists():
                raise CheckpointError(
                    f"{self.old_checkpoint} is a checkpoint of an older evolve, a pickle, "
                    "which is never loaded (loading it could run any code); start the run "
                    "afresh"
                )
            raise CheckpointError(
                f"{self.path} has no checkpoint.json to resume from; a run writes one as it "
                "starts and every checkpoint_every generations (start it with --out DIR)"
            )
        data = _read(cp, MAX_CHECKPOINT_BYTES, "restore it from a copy or start afresh")
        return self.parse_checkpoint(data)

    def parse_checkpoint(self, data: bytes) -> dict[str, Any]:
        """The state in a checkpoint's bytes, checked (see :meth:`load_checkpoint`)."""
        cp = self.checkpoint
        damaged = f"{cp} is damaged"
        first, newline, payload = data.partition(b"\n")
        try:
            if not newline or len(first) > _HEADER_MAX:
                raise ValueError
            header = json.loads(first)
            if not isinstance(header, dict) or header.get("format") != CHECKPOINT_FORMAT:
                raise ValueError
        except (ValueError, RecursionError):
            raise CheckpointError(
                f"{damaged}: its first line is not the header of an evolve checkpoint; "
                "restore it from a copy or start afresh"
            ) from None
        if header.get("version") != CHECKPOINT_VERSION:
            raise CheckpointError(
                f"{cp} is a checkpoint of version {header.get('version')!r}; this evolve "
                f"reads version {CHECKPOINT_VERSION}: continue it with the evolve that wrote "
                "it, or start afresh"
            )
        if header.get("bytes") != len(payload) or \
                header.get("sha256") != hashlib.sha256(payload).hexdigest():
            raise CheckpointError(
                f"{damaged}: its content does not match its checksum (the file was changed "
                "or corrupted); restore it from a copy or start afresh"
            )
        try:
            state = json.loads(payload)
        except (ValueError, RecursionError):
            raise CheckpointError(f"{damaged}: its content is not JSON") from None
        if not isinstance(state, dict):
            raise CheckpointError(f"{damaged}: its content is not a JSON object")
        return state

    def load_run_info(self) -> dict[str, Any]:
        data = _read(self.run_json, MAX_RUN_JSON_BYTES, "restore it from a copy")
        try:
            info = json.loads(data.decode("utf-8"))
        except (ValueError, RecursionError) as exc:
            raise CheckpointError(f"{self.run_json} is not valid JSON: {exc}") from None
        if not isinstance(info, dict):
            raise CheckpointError(f"{self.run_json} is not a JSON object")
        return info

    def plots(self, history: Sequence[Mapping[str, Any]], fsa: FSA | None) -> None:
        """Draw the fitness plot and the best FSA (``best.png``); an FSA of more than
        :data:`MAX_DRAWN_STATES` states is not drawn, and a picture of an earlier best is
        removed, so that ``best.png`` never shows another FSA than ``best.yaml``."""
        if history:
            plot_history(history, self.fitness_png)
        if fsa is None:
            return
        if len(fsa.states) > MAX_DRAWN_STATES:
            with contextlib.suppress(FileNotFoundError):
                self.best_png.unlink()
            return
        draw_fsa(fsa, self.best_png)


def draw_fsa(fsa: FSA, path: str | os.PathLike[str]) -> None:
    """A picture of an FSA (Graphviz when installed, else matplotlib): see
    :func:`skillcompose.draw.render`."""
    with temporary_beside(path, suffix=Path(path).suffix) as tmp:  # never half a picture
        render(fsa, tmp)


def plot_history(history: Sequence[Mapping[str, Any]], path: str | os.PathLike[str]) -> None:
    """Best, mean and median fitness per generation (matplotlib's object API: no pyplot
    state, no backend switch)."""
    _save_fig(_history_figure(history), Path(path))


def history_svg(history: Sequence[Mapping[str, Any]]) -> str:
    """The picture of :func:`plot_history` as SVG text (for a notebook)."""
    import io

    buffer = io.StringIO()
    _history_figure(history).savefig(buffer, format="svg")
    return buffer.getvalue()


def _history_figure(history: Sequence[Mapping[str, Any]]) -> Any:
    from matplotlib.figure import Figure

    gens = [r["generation"] for r in history]
    fig = Figure(figsize=(7, 4))
    ax = fig.add_subplot()
    for key in ("best", "median", "mean"):
        ax.plot(gens, [r[key] for r in history], label=key)
    ax.set_xlabel("generation")
    ax.set_ylabel("fitness")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def _save_fig(fig: Any, path: Path) -> None:
    with temporary_beside(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=90)
