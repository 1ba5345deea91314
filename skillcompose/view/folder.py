"""Reading only below the folder the viewer serves.

Every file the viewer reads (``run.json``, ``history.jsonl``, ``best.yaml``, FSA files,
live files, a task setting that names a file) goes through :func:`read_below` or
:func:`open_below`: the path, its links followed (``os.path.realpath``), must lead to a
regular file inside the folder, and the file is opened by that resolved path with
``O_NOFOLLOW`` (a link put in its place since is refused, not followed) and ``O_NONBLOCK``
(a pipe is refused at once, never waited on). A link that stays inside the folder is read;
one that leads outside is refused as :class:`OutsideFolder`, whatever it names.

This is the check Starlette's ``StaticFiles`` makes (the real path must lie below the
directory), written out here because the viewer reads files by their own rules (bounded,
incrementally, with errors shown in the page) rather than serving them; the standard library
has no "open beneath" call (Linux's ``openat2(RESOLVE_BENEATH)`` is not exposed).

:func:`walk_below` lists files below the folder without following linked folders, bounded in
depth and in the entries it looks at. Importing this module loads nothing beyond the
standard library.
"""

from __future__ import annotations

import json
import os
import stat
from collections.abc import Callable, Iterator
from pathlib import Path

__all__ = ["MAX_SCAN_ENTRIES", "OutsideFolder", "inside", "not_unicode", "open_below",
           "read_below", "read_fd", "resolve_below", "unicode_name", "walk_below"]

MAX_SCAN_ENTRIES = 50_000
"""The most folder entries one listing looks at (a huge folder is listed in part)."""


class OutsideFolder(OSError):
    """A path that leads (through a link, or by ``..``) outside the folder served."""


def unicode_name(name: str) -> bool:
    """Whether a file name is UTF-8 text (a name that is not decodes with lone surrogates,
    which no page can show: such files are not listed)."""
    try:
        name.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def not_unicode(value: object) -> bool:
    """Whether JSON data read from a file holds text that is not Unicode (a lone surrogate
    escape such as ``"\\ud800"``, which JSON allows and no page can show)."""
    try:
        json.dumps(value, ensure_ascii=False).encode("utf-8")
    except UnicodeEncodeError:
        return True
    except (ValueError, TypeError, RecursionError):
        return False
    return False


def inside(path: Path, root: Path) -> bool:
    """Whether the real path ``path`` is ``root`` or below it (both already resolved)."""
    return path == root or path.is_relative_to(root)


def resolve_below(path: str | os.PathLike[str], root: str | os.PathLike[str]) -> Path:
    """``path`` with every link followed; raises :class:`OutsideFolder` when that is not
    inside ``root`` (links followed too), ``ValueError`` for a path holding a NUL."""
    real_root = Path(os.path.realpath(root))
    real = Path(os.path.realpath(Path(root, path)))  # a relative path is below root
    if not inside(real, real_root):
        raise OutsideFolder(0, "it leads outside the folder served (links followed); the "
                            "viewer reads only files inside it", os.fspath(path))
    return real


def open_below(path: str | os.PathLike[str], root: str | os.PathLike[str]) -> int:
    """A file descriptor of the regular file ``path`` inside ``root`` (see the module's
    docstring); the caller closes it. Raises ``OSError`` (:class:`OutsideFolder`,
    ``FileNotFoundError``, ``skillcompose.files.NotARegularFile``...)."""
    from skillcompose.files import NotARegularFile

    real = resolve_below(path, root)
    fd = os.open(real, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOFOLLOW", 0))
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            what = ("a folder" if stat.S_ISDIR(mode) else "a pipe" if stat.S_ISFIFO(mode)
                    else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
                    else "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
            raise NotARegularFile(0, f"it is {what}, not a regular file", os.fspath(path))
    except BaseException:
        os.close(fd)
        raise
    return fd


def read_fd(fd: int, limit: int, offset: int = 0) -> bytes:
    """At most ``limit`` bytes of ``fd`` from ``offset`` on (fewer at its end)."""
    chunks: list[bytes] = []
    left = limit
    while left > 0:
        chunk = os.pread(fd, min(left, 1 << 20), offset)
        if not chunk:
            break
        chunks.append(chunk)
        left -= len(chunk)
        offset += len(chunk)
    return b"".join(chunks)


def read_below(path: str | os.PathLike[str], root: str | os.PathLike[str],
               limit: int) -> bytes:
    """The bytes of the regular file ``path`` inside ``root``, at most ``limit + 1`` of
    them (more than ``limit`` means the file is larger)."""
    fd = open_below(path, root)
    try:
        return read_fd(fd, limit + 1)
    finally:
        os.close(fd)


def walk_below(root: Path, wanted: Callable[[str], bool], *, max_depth: int,
               max_files: int) -> Iterator[Path]:
    """The files below ``root`` whose name ``wanted`` accepts, folder by folder in name
    order: hidden folders skipped, linked folders not entered, a linked file only when it
    leads to a regular file inside ``root``; at most ``max_depth`` folders deep,
    ``max_files`` files, :data:`MAX_SCAN_ENTRIES` entries looked at."""
    real_root = Path(os.path.realpath(root))
    seen = 0
    found = 0
    stack: list[tuple[Path, int]] = [(root, 0)]
    while stack:
        folder, depth = stack.pop()
        try:
            with os.scandir(folder) as it:
                entries = sorted(it, key=lambda e: e.name)
        except OSError:
            continue
        subfolders = []
        for entry in entries:
            seen += 1
            if seen > MAX_SCAN_ENTRIES:
                return
            if not unicode_name(entry.name):
                continue
            try:
                if entry.is_dir(follow_symlinks=False):
                    if not entry.name.startswith(".") and depth < max_depth:
                        subfolders.append(Path(entry.path))
                    continue
                if not wanted(entry.name):
                    continue
                if entry.is_symlink():
                    real = Path(os.path.realpath(entry.path))
                    if not inside(real, real_root) or not real.is_file():
                        continue
                elif not entry.is_file(follow_symlinks=False):
                    continue
            except OSError:
                continue
            yield Path(entry.path)
            found += 1
            if found >= max_files:
                return
        stack.extend((p, depth + 1) for p in reversed(subfolders))
