"""Command-line argument types: each argument is checked where argparse parses it.

Every function here is an argparse ``type=``: it returns the converted value or raises
:class:`argparse.ArgumentTypeError`, which argparse prints as one line naming the argument,
what is allowed and what was given, and exits with status 2::

    p.add_argument("--trials", type=whole(1, MAX_TRIALS), default=1)
    p.add_argument("-o", "--output", type=output_file(".png", ".svg"))

Checks that need more than the argument (a backend no loaded skill has) raise
:class:`UsageError` later, which the command line also reports with status 2.

The options every subcommand shares live here too, so that a package adding a subcommand
(``register_cli``) follows the same conventions: :func:`add_output_options` (``-q``/``-v``,
which ``skillcompose`` adds to every subcommand by itself), :func:`add_json_option`,
:func:`verbosity`, :func:`note` and :func:`print_json`.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import json
import math
import os
import re
import sys
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any, TextIO

from .errors import SkillcomposeError, clip
from .files import not_a_file

__all__ = [
    "MAX_SEED",
    "MAX_TRIALS",
    "MAX_WORKERS",
    "UsageError",
    "add_json_option",
    "add_output_options",
    "existing_dir",
    "json_output",
    "module_or_file",
    "note",
    "number",
    "output_dir",
    "output_file",
    "print_json",
    "seed",
    "set_hint",
    "setting",
    "verbosity",
    "whole",
]

from .limits import MAX_SEED, MAX_TRIALS, MAX_WORKERS  # the core's bounds, parsed here

_WHOLE = re.compile(r"[-+]?[0-9]{1,30}")
_REAL = re.compile(r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]{1,4})?")
_NAME = r"[A-Za-z_][A-Za-z0-9_]*"
_DOTTED = re.compile(rf"{_NAME}(?:\.{_NAME})*")


class UsageError(SkillcomposeError, ValueError):
    """A command-line argument is not allowed given what it refers to."""


def _shown(text: str) -> str:
    return repr(clip(text))


def whole(low: int, high: int) -> Callable[[str], int]:
    """A whole number in ``[low, high]``."""

    def parse(text: str) -> int:
        t = text.strip()
        if not _WHOLE.fullmatch(t) or not low <= int(t) <= high:
            raise argparse.ArgumentTypeError(
                f"must be a whole number from {low} to {high}, got {_shown(text)}"
            )
        return int(t)

    parse.__name__ = "whole number"
    return parse


def number(low: float, high: float) -> Callable[[str], float]:
    """A finite number in ``[low, high]`` (no nan, no inf)."""

    def parse(text: str) -> float:
        t = text.strip()
        value = float(t) if _REAL.fullmatch(t) else math.nan
        if not (math.isfinite(value) and low <= value <= high):
            raise argparse.ArgumentTypeError(
                f"must be a finite number from {low:g} to {high:g}, got {_shown(text)}"
            )
        return value

    parse.__name__ = "number"
    return parse


seed = whole(0, MAX_SEED)
"""A run seed: a whole number from 0 to 2**63 - 1."""


def module_or_file(text: str) -> str:
    """A Python module: a dotted name (``examples.pour_water``) or an existing ``.py`` file;
    an FSA file (``.yaml``) is accepted too, for ``--skills``."""
    if _DOTTED.fullmatch(text):
        return text
    if text.endswith((".py", ".yaml", ".yml")) or "/" in text or os.sep in text:
        if not Path(text).is_file():
            kind = not_a_file(text)
            raise argparse.ArgumentTypeError(
                f"{_shown(text)} is {kind}, not a file" if kind else f"no file {_shown(text)}")
        return text
    raise argparse.ArgumentTypeError(
        f"{_shown(text)} is neither a module name (like examples.pour_water) nor a .py file"
    )


def setting(text: str) -> str:
    """A task setting ``NAME=VALUE`` (the value is converted by the task's loader); a value
    that reads as a number must be a finite one."""
    name, eq, value = text.partition("=")
    if not eq or not re.fullmatch(_NAME, name.strip()):
        raise argparse.ArgumentTypeError(
            f"must look like NAME=VALUE (e.g. p_fail=0.3), got {_shown(text)}"
        )
    try:
        number_ = float(value)
    except ValueError:
        return text
    if not math.isfinite(number_):
        raise argparse.ArgumentTypeError(
            f"{name.strip()}: {_shown(value)} is not a finite number; give a number within "
            "about ±1.8e308 (no inf, no nan)"
        )
    return text


def set_hint(args: argparse.Namespace, exc: BaseException) -> str:
    """``"; check --set NAME"`` for the settings given with ``--set`` that were in play
    when the task's own code failed (a :class:`~skillcompose.task.TaskError` carries them),
    else ``""``."""
    involved = getattr(exc, "settings", None) or {}
    given = {item.partition("=")[0].strip() for item in getattr(args, "settings", None) or ()}
    names = [name for name in involved if name in given]
    if not names:
        return ""
    values = "value" if len(names) == 1 else "values"
    return f"; check the {values} given with " + ", ".join(f"--set {n}" for n in names)


def _writable_place(path: Path) -> str | None:
    """Why files cannot be created at ``path`` (a directory to be), or None."""
    probe = path
    while not probe.exists() and probe.parent != probe:
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        return f"{probe} is a file, not a directory"
    if not os.access(probe, os.W_OK | os.X_OK):
        return f"cannot write in {probe} (permission denied)"
    return None


def output_file(*suffixes: str) -> Callable[[str], str]:
    """A file to write, with one of ``suffixes`` (any when none are given), in a place
    where it can be created."""

    def parse(text: str) -> str:
        path = Path(text)
        if not text or text.endswith(("/", os.sep)) or path.is_dir():
            raise argparse.ArgumentTypeError(f"{_shown(text)} is a directory; give a file name")
        if suffixes and path.suffix.lower() not in suffixes:
            raise argparse.ArgumentTypeError(
                f"{_shown(text)}: the file name must end in {' '.join(suffixes)}"
            )
        if path.exists() and not os.access(path, os.W_OK):
            raise argparse.ArgumentTypeError(f"cannot write {text} (permission denied)")
        why = _writable_place(path.parent if str(path.parent) else Path("."))
        if why is not None:
            raise argparse.ArgumentTypeError(f"cannot write {text}: {why}")
        return text

    parse.__name__ = "output file"
    return parse


def output_dir(text: str) -> str:
    """A directory to write into: existing, or one that can be created."""
    path = Path(text)
    if not text:
        raise argparse.ArgumentTypeError("give a directory name")
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{_shown(text)} is a file; give a directory")
    why = _writable_place(path)
    if why is not None:
        raise argparse.ArgumentTypeError(f"cannot write in {text}: {why}")
    return text


def output_folder(text: str) -> Path:
    """:func:`output_dir` as a :class:`~pathlib.Path` (for ``type=`` of an ``--out`` whose
    default is a path)."""
    return Path(output_dir(text))


def existing_dir(text: str) -> str:
    """A directory that exists."""
    if not Path(text).is_dir():
        raise argparse.ArgumentTypeError(f"no directory {_shown(text)}")
    return text


# -- options every subcommand shares -------------------------------------------------------
def add_output_options(p: argparse.ArgumentParser, *, top: bool = False) -> None:
    """``-q/--quiet`` and ``-v/--verbose``: accepted before and after the subcommand, with
    one meaning everywhere. ``-q``: standard output keeps the result, standard error only
    warnings and errors (no progress, no notes). ``-v`` (repeatable): notes on standard
    error about what is loaded and how long the command took. ``top`` is the
    ``skillcompose`` parser itself (the defaults); on a subcommand the options leave a value
    given before it alone unless given again. An option the parser already has is kept."""
    default: Any = 0 if top else argparse.SUPPRESS
    quiet_default: Any = False if top else argparse.SUPPRESS
    known = set(p._option_string_actions)  # a subcommand may have its own -q already
    if not {"-q", "--quiet"} & known:
        p.add_argument("-q", "--quiet", action="store_true", default=quiet_default,
                       help="only the result on standard output; only warnings and errors "
                       "on standard error (no progress)")
    if not {"-v", "--verbose"} & known:
        p.add_argument("-v", "--verbose", action="count", default=default,
                       help="notes on standard error: what is loaded, how long it took")


def add_json_option(p: argparse.ArgumentParser) -> None:
    """``--json``: the result as one JSON document on standard output, nothing else there."""
    p.add_argument("--json", action="store_true",
                   help="print the result as one JSON document on standard output (notes, "
                   "warnings and progress go to standard error)")


def verbosity(args: argparse.Namespace) -> int:
    """-1 with ``-q``, else the number of ``-v`` given (0 by default)."""
    return -1 if getattr(args, "quiet", False) else int(getattr(args, "verbose", 0) or 0)


def note(args: argparse.Namespace, text: str, *, level: int = 0) -> None:
    """Print ``text`` on standard error unless the verbosity is below ``level`` (level 0:
    an ordinary note, hidden by ``-q``; level 1: shown with ``-v``)."""
    if verbosity(args) >= level:
        print(text, file=sys.stderr)


def _plain(value: Any) -> Any:
    """``value`` with only JSON types: NaN and infinities become null, tuples lists,
    paths and other objects their text."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set, frozenset)):
        items = sorted(value, key=str) if isinstance(value, (set, frozenset)) else value
        return [_plain(v) for v in items]
    if hasattr(value, "item") and callable(value.item):  # a numpy scalar
        return _plain(value.item())
    return str(value)


def print_json(document: Mapping[str, Any]) -> None:
    """Write ``document`` as one JSON document (and a newline) on standard output (the one
    the command started with, while :func:`json_output` keeps it)."""
    out = _DOCUMENT_STREAMS[-1] if _DOCUMENT_STREAMS else sys.stdout
    if out is None:  # (Python sets sys.stdout to None when it starts without one)
        raise OSError(errno.EBADF, "standard output is closed: nowhere to write the JSON "
                      "document")
    out.write(json.dumps(_plain(document), indent=2, allow_nan=False) + "\n")
    out.flush()


_DOCUMENT_STREAMS: list[TextIO | None] = []
"""Where :func:`print_json` writes while :func:`json_output` is active (the innermost
last). Like the file descriptors it stands for, this is the process's."""
_KEPT_FDS: list[int] = []
"""The descriptors :func:`json_output` keeps the real standard output on."""


def _drop_kept_fds_in_child() -> None:
    """In a process forked while a document is kept (an evaluation worker): /dev/null over
    the kept standard output, so the child can never write there, nor hold the pipe open."""
    if not _KEPT_FDS:
        return
    null = os.open(os.devnull, os.O_WRONLY)
    for fd in _KEPT_FDS:
        with contextlib.suppress(OSError):
            os.dup2(null, fd)
    os.close(null)


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_drop_kept_fds_in_child)


@contextlib.contextmanager
def json_output(active: bool = True, for_good: bool = False) -> Iterator[None]:
    """Keep standard output for the one JSON document of ``--json`` while the block runs.

    Everything else written there goes to standard error: ``print`` in a task or a skill
    (``sys.stdout`` is standard error meanwhile) and, when standard output is file
    descriptor 1, what C code, child processes and forked workers write to that
    descriptor (it is pointed at standard error; the document goes to a copy of the real
    one). :func:`print_json` writes the document there. ``active=False`` changes nothing.
    ``for_good``: the process ends after the block (the command line's own run), so
    standard output is not given back: what runs after (``atexit`` handlers, threads still
    going) writes to standard error, never after the document.
    """
    if not active:
        yield
        return
    real = sys.stdout
    with contextlib.suppress(AttributeError, OSError, ValueError):
        real.flush()
    kept = _keep_fd_1() if _fileno(real) == 1 else None
    copy: TextIO | None = None
    if kept is not None:  # the document goes to the real standard output, kept aside
        copy = open(kept, "w", closefd=False,  # noqa: SIM115 - closed in the finally below
                    encoding=getattr(real, "encoding", None) or "utf-8",
                    errors=getattr(real, "errors", None) or "strict")
        _KEPT_FDS.append(kept)
    _DOCUMENT_STREAMS.append(copy if copy is not None else real)
    sys.stdout = sys.stderr
    try:
        yield
    finally:
        _DOCUMENT_STREAMS.pop()
        with contextlib.suppress(AttributeError, OSError, ValueError):
            sys.stderr.flush()
        if not (for_good and kept is not None):
            sys.stdout = real
        if kept is not None and copy is not None:
            _KEPT_FDS.remove(kept)
            with contextlib.suppress(OSError, ValueError):  # a reader gone away
                copy.close()
            if not for_good:
                os.dup2(kept, 1)
            os.close(kept)


def _keep_fd_1() -> int | None:
    """A copy of file descriptor 1, which then points at standard error (or, without one,
    at /dev/null); None when descriptor 1 is closed (then nothing changes)."""
    try:
        kept = os.dup(1)
    except OSError:
        return None
    try:
        os.dup2(2, 1)
    except OSError:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.close(null)
    return kept


def _fileno(stream: Any) -> int | None:
    try:
        return int(stream.fileno())
    except (AttributeError, OSError, ValueError):  # a StringIO, a test's capture, closed
        return None

