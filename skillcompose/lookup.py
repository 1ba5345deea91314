"""What the model, the engine and the file layer ask of a skill registry: the lookup alone.

:class:`~skillcompose.registry.Registry` loads modules, files and entry points and keeps the
skills; the FSA model (:mod:`skillcompose.fsa`), the engine (:mod:`skillcompose.executor`,
:mod:`skillcompose.nested`) and the file writer (:mod:`skillcompose.fsafile`) only look
skills up, through :class:`SkillLookup`. So they do not know the loader, and anything with
these four members (a registry, a test double, a read-only view) serves them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    from .skill import Skill, SkillSpec

__all__ = ["SkillLookup"]


@runtime_checkable
class SkillLookup(Protocol):
    """Skills by name: their declaration, their implementation on a backend, and which
    backends have one. ``backend`` is the one a lookup without a backend uses."""

    backend: str

    def spec(self, name: str) -> SkillSpec:
        """The declaration of skill ``name``; raises
        :class:`~skillcompose.errors.UnknownSkillError` for a name it does not hold."""
        ...

    def resolve(self, name: str, backend: str | None = None) -> Skill:
        """The implementation of ``name`` on ``backend`` (default :attr:`backend`)."""
        ...

    def backends(self, name: str) -> list[str]:
        """The backends that have an implementation of ``name``."""
        ...
