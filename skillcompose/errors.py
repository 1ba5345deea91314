"""One exception family for everything skillcompose reports to a user.

Every error raised at a boundary (a skill definition, an FSA file, the registry, the
blackboard, the command line) derives from :class:`SkillcomposeError`. Messages name the
thing at fault (file, line, state, key, skill), the bad value, what was expected and the fix.
"""

from __future__ import annotations

import unicodedata
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

__all__ = [
    "BlackboardAccessError",
    "BlackboardKeyError",
    "BlackboardTypeError",
    "FSAFileError",
    "FSAValidationError",
    "ParamError",
    "Problem",
    "RegistryError",
    "SkillDefinitionError",
    "SkillProtocolError",
    "SkillcomposeError",
    "UndeclaredOutcomeError",
    "UnknownSkillError",
    "control_characters",
    "exception_text",
    "one_line",
    "printable",
]


MAX_SHOWN_PROBLEMS = 20
"""An error message lists at most this many problems, then counts the rest."""


def clip(text: str, n: int = 40) -> str:
    """``text`` cut to ``n`` characters (ending ``...``) when longer: a value in a message."""
    return text if len(text) <= n else text[:n - 3] + "..."


_CONTROL_CATEGORIES = frozenset({"Cc", "Cf", "Cs", "Zl", "Zp"})
_ESCAPES = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def control_characters(text: str) -> list[str]:
    """The characters of ``text`` that a terminal would act on rather than show: C0/C1
    controls and DEL (``Cc``), invisible format characters such as bidirectional overrides
    (``Cf``), lone surrogates, and line/paragraph separators."""
    return [c for c in text if unicodedata.category(c) in _CONTROL_CATEGORIES]


def one_line(text: str) -> str:
    """``text`` with every line break and control character written as an escape (``\\n``,
    ``\\x1b``, ``\\u202e``), so that it prints as one line and cannot move the cursor,
    clear the screen or reorder what follows. Other characters, backslashes too, are kept."""
    if not control_characters(text):
        return text
    out = []
    for c in text:
        if unicodedata.category(c) not in _CONTROL_CATEGORIES:
            out.append(c)
        elif c in _ESCAPES:
            out.append(_ESCAPES[c])
        else:
            code = ord(c)
            out.append(f"\\x{code:02x}" if code < 0x100 else
                       f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}")
    return "".join(out)


def printable(exc: BaseException) -> str:
    """The message of ``exc`` for one error line: :func:`one_line` of it, except that an
    error whose message lists problems one per line (``listing``) keeps those line breaks
    (each line is made printable on its own)."""
    text = str(exc)
    if getattr(exc, "listing", False):
        return "\n".join(one_line(line) for line in text.split("\n"))
    return one_line(text)


def exception_text(exc: BaseException) -> str:
    """``Type: message`` of an exception, as part of a message: the class's own name (not
    its module's, which for a file loaded by path is an internal one), and for
    ``SystemExit`` that the code exited the process instead of returning."""
    name = type(exc).__name__
    if isinstance(exc, SystemExit):
        return (f"{name}: {exc.code!r} (sys.exit() was called; return, or raise an "
                "exception, instead of exiting)")
    text = str(exc)
    return f"{name}: {text}" if text else name


class SkillcomposeError(Exception):
    """Base class of every error skillcompose raises on purpose."""

    listing: ClassVar[bool] = False
    """True when the message is a list of problems, one per line: :func:`printable` keeps
    its line breaks, and whoever builds it writes each problem with :func:`one_line`."""


class SkillDefinitionError(SkillcomposeError, TypeError):
    """A function or class given to ``@skill`` cannot be a skill (bad signature, no outcomes)."""


class ParamError(SkillcomposeError, ValueError):
    """A parameter value is missing, of the wrong type, or outside its declared range."""


class RegistryError(SkillcomposeError):
    """A skill cannot be added to, or found in, a registry."""


class UnknownSkillError(RegistryError, KeyError):
    """A skill name (or a backend of it) is not in the registry."""

    def __str__(self) -> str:  # KeyError quotes its message; we want it plain
        return str(self.args[0]) if self.args else ""


class BlackboardAccessError(SkillcomposeError, PermissionError):
    """A skill read or wrote a blackboard key it did not declare."""


class BlackboardKeyError(SkillcomposeError, KeyError):
    """A blackboard key was read before anything wrote it."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class BlackboardTypeError(SkillcomposeError, TypeError):
    """A value written to a typed blackboard key has the wrong type."""


class UndeclaredOutcomeError(SkillcomposeError, ValueError):
    """A skill returned an outcome it did not declare."""


class SkillProtocolError(SkillcomposeError, RuntimeError):
    """A long-running skill broke the start / tick / cancel protocol, or a run was misused
    (for example a generator skill yielded something other than ``"running"``)."""


@dataclass(frozen=True)
class Problem:
    """One thing wrong with an FSA: where it is, what is wrong and how to fix it."""

    message: str
    state: str | None = None
    key: str | None = None
    fix: str | None = None
    line: int | None = None  # 1-based, when the FSA came from a file
    column: int | None = None  # 1-based

    def render(self, path: str | Path | None = None) -> str:
        """``path:line:column: state S: message; fix``, each part there when known, on one
        line whatever the names hold (see :func:`one_line`)."""
        where = "" if path is None else f"{one_line(str(path))}{self._position()}: "
        state = "" if self.state is None else f"state {one_line(self.state)}: "
        return f"{where}{state}{one_line(self.message)}" + (
            f"; {one_line(self.fix)}" if self.fix else "")

    def _position(self) -> str:
        if self.line is None:
            return ""
        return f":{self.line}" if self.column is None else f":{self.line}:{self.column}"


class FSAValidationError(SkillcomposeError, ValueError):
    """An FSA is inconsistent with itself or with the registry it is compiled against.

    ``problems`` holds every problem found, not only the first.
    """

    listing = True  # several problems: one per line

    def __init__(self, problems: Iterable[Problem], path: str | Path | None = None) -> None:
        self.problems = tuple(problems)
        self.path = path
        n = len(self.problems)
        lines = [p.render(path) for p in self.problems[:MAX_SHOWN_PROBLEMS]]
        if n == 1:
            head = lines[0]
        else:
            shown = f"; the first {len(lines)}" if n > len(lines) else ""
            head = f"invalid FSA ({n} problems{shown}):\n  " + "\n  ".join(lines)
            if n > len(lines):
                head += f"\n  ... and {n - len(lines)} more (fix these first)"
        super().__init__(head)


class FSAFileError(FSAValidationError):
    """An FSA file cannot be read: not YAML, a wrong key, a wrong value type."""
