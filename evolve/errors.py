"""Errors of evolution runs, in skillcompose's one exception family."""

from __future__ import annotations

from skillcompose.errors import SkillcomposeError

__all__ = ["CheckpointError", "EvolutionConfigError", "EvolutionError", "SeedFSAError"]


class EvolutionError(SkillcomposeError):
    """An evolution run cannot start or continue."""


class EvolutionConfigError(EvolutionError, ValueError):
    """An :class:`~skillcompose.evolve.config.EvolutionConfig` value is out of range."""


class SeedFSAError(EvolutionError, ValueError):
    """A seed FSA (``--seed-fsa FILE``) cannot become a genome of this task."""

    listing = True  # its problems, one per line


class CheckpointError(EvolutionError):
    """A run directory has no usable checkpoint, or it belongs to another run."""
