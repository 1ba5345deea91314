"""Tick-wise running, by its historical name: the activation protocol and the engine's run.

The protocol lives in :mod:`skillcompose.activation` and the engine in
:mod:`skillcompose.executor`; this module gathers the names a tick-wise caller needs.
"""

from .activation import RUNNING, Activation, Starter
from .executor import FSARun, run_ticking

__all__ = ["RUNNING", "Activation", "FSARun", "Starter", "run_ticking"]
