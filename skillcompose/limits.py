"""The bounds every entry point shares: the Python API, the files and the command line check
values against these, so that a value one of them takes the others take too. The command
line's parsers (:mod:`skillcompose.arguments`) import them from here; the core never imports
the command line."""

from __future__ import annotations

__all__ = ["MAX_SEED", "MAX_TRIALS", "MAX_WORKERS"]

MAX_SEED = 2**63 - 1
"""The largest seed (a non-negative 64-bit whole number)."""
MAX_TRIALS = 1_000_000
"""The most runs one command makes of an FSA per point (``--trials``, ``--reps``)."""
MAX_WORKERS = 1024
"""The most worker processes or actors a run starts."""
