"""One exception family for everything skillcompose reports to a user.

Every error raised at a boundary (a skill definition, an FSA file, the registry, the
blackboard, the command line) derives from :class:`SkillcomposeError`. Messages name the
thing at fault (file, line, state, key, skill), the bad value, what was expected and the fix.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

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
]


MAX_SHOWN_PROBLEMS = 20
"""An error message lists at most this many problems, then counts the rest."""


def clip(text: str, n: int = 40) -> str:
    """``text`` cut to ``n`` characters (ending ``...``) when longer: a value in a message."""
    return text if len(text) <= n else text[:n - 3] + "..."


class SkillcomposeError(Exception):
    """Base class of every error skillcompose raises on purpose."""


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
        """``path:line:column: state S: message; fix``, each part there when known."""
        where = "" if path is None else f"{path}{self._position()}: "
        state = "" if self.state is None else f"state {self.state}: "
        return f"{where}{state}{self.message}" + (f"; {self.fix}" if self.fix else "")

    def _position(self) -> str:
        if self.line is None:
            return ""
        return f":{self.line}" if self.column is None else f":{self.line}:{self.column}"


class FSAValidationError(SkillcomposeError, ValueError):
    """An FSA is inconsistent with itself or with the registry it is compiled against.

    ``problems`` holds every problem found, not only the first.
    """

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
