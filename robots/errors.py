"""Exceptions raised by :mod:`robots`.

One family: every error derives from :class:`RobotModelError`, itself a
``skillcompose.errors.SkillcomposeError``, so the CLI reports them like any other.
"""

from __future__ import annotations

from collections.abc import Iterable

from skillcompose.errors import SkillcomposeError


class RobotModelError(SkillcomposeError):
    """Base class of every error raised by :mod:`robots`."""


class RobotDataNotFound(RobotModelError):
    """The robot description (URDF) could not be found in the installed packages."""

    def __init__(self, package: str, detail: str) -> None:
        self.package = package
        self.detail = detail
        super().__init__(
            f"cannot find the robot description in package {package!r}: {detail}. "
            f"Fix: install it with `pip install {package}`."
        )


class FrameNotFound(RobotModelError):
    """A frame name is not in the model; the message lists the valid frames."""

    def __init__(self, name: str, valid: Iterable[str]) -> None:
        self.name = name
        self.valid = tuple(valid)
        shown = ", ".join(self.valid[:40])
        more = f" (and {len(self.valid) - 40} more)" if len(self.valid) > 40 else ""
        super().__init__(f"frame {name!r} not found; valid frames: {shown}{more}")


class ChainNotFound(RobotModelError):
    """A kinematic chain name is unknown; the message lists the valid chains."""

    def __init__(self, name: str, valid: Iterable[str]) -> None:
        self.name = name
        self.valid = tuple(valid)
        super().__init__(f"chain {name!r} not found; valid chains: {', '.join(self.valid)}")


class InvalidConfiguration(RobotModelError):
    """A configuration or target has the wrong shape, a non-finite value or a bad key."""


class DatasetError(RobotModelError):
    """A shipped or cached data file is missing, corrupt or does not match its spec."""
