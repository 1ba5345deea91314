"""Writing files atomically with the mode a person expects.

A file is written beside its destination and renamed over it, so a reader (or a run killed
half-way) never sees half a file. ``tempfile.mkstemp`` creates files readable by their owner
only (0600); the renamed file would keep that mode. Here it gets the mode of the file it
replaces, or, for a new file, what ``open()`` would have given it: 0666 less the umask.
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["TEMPORARY_MARK", "NotARegularFile", "atomic_write", "file_mode", "not_a_file",
           "read_limited", "temporary_beside", "umask"]

TEMPORARY_MARK = ".tmp-"
"""Temporary files are named ``.NAME.tmp-XXXXXXXX[SUFFIX]`` beside ``NAME``: a run killed
while writing leaves at most such files, which the next writer may remove."""


def umask() -> int:
    """The process's umask (read without changing it where the platform allows)."""
    with contextlib.suppress(OSError, ValueError), open("/proc/self/status", encoding="ascii") as f:
        for line in f:
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    mask = os.umask(0o022)  # no other way to read it: set and restore at once
    os.umask(mask)
    return mask


def file_mode(path: str | os.PathLike[str]) -> int:
    """The permission bits a rewrite of ``path`` should have: those of the existing file,
    else 0666 less the umask."""
    try:
        return os.stat(path).st_mode & 0o7777
    except OSError:
        return 0o666 & ~umask()


@contextlib.contextmanager
def temporary_beside(
    path: str | os.PathLike[str], suffix: str = ""
) -> Iterator[Path]:
    """A temporary path in ``path``'s directory, renamed onto ``path`` with the mode of
    :func:`file_mode` when the block ends without an exception, removed otherwise."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}{TEMPORARY_MARK}", suffix=suffix, dir=p.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, file_mode(p))
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write(path: str | os.PathLike[str], data: bytes, *, sync: bool = False) -> None:
    """Write ``data`` to ``path`` atomically (see the module's docstring); ``sync`` also
    flushes it to the disk before the rename."""
    with temporary_beside(path) as tmp, open(tmp, "wb") as f:
        f.write(data)
        if sync:
            f.flush()
            os.fsync(f.fileno())


class NotARegularFile(OSError):
    """A path that is a pipe, a device, a socket or a folder where a file was expected:
    reading it could wait for ever or never end."""


def read_limited(path: str | os.PathLike[str], limit: int) -> bytes:
    """The bytes of the regular file ``path``, at most ``limit + 1`` of them (more than
    ``limit`` means the file is larger): never blocks on a pipe (opened without waiting for
    a writer, and refused with :class:`NotARegularFile`, as are devices and folders), never
    reads a file whole however large it is. Other failures raise :class:`OSError`."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise NotARegularFile(0, f"it is {_kind(mode)}, not a regular file", str(path))
        chunks: list[bytes] = []
        left = limit + 1
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
        return b"".join(chunks)
    finally:
        os.close(fd)


def _kind(mode: int) -> str:
    return ("a folder" if stat.S_ISDIR(mode) else "a pipe" if stat.S_ISFIFO(mode)
            else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
            else "a socket" if stat.S_ISSOCK(mode) else "not a regular file")


def not_a_file(path: str | os.PathLike[str]) -> str | None:
    """What ``path`` is when it is there but is not a regular file (links followed): "a
    folder", "a pipe", "a device", "a socket", "a broken link"; None when it is a regular
    file or is not there."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return "a broken link" if os.path.islink(path) else None
    except OSError:
        return None
    return None if stat.S_ISREG(mode) else _kind(mode)
