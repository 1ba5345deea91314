"""Skill libraries: task-level skills, one module per task and backend.

- :mod:`skills.pour_water`: the six skills of the paper's pouring experiment (section 4.1)
  on the abstract ``"sim"`` backend.

Each module defines ``register(registry)``; load one with
``registry.load_module("skills.pour_water")``. Skills of different backends share names
(``MoveToObject``), so their modules are exported whole rather than their skills one by one.
"""

from __future__ import annotations

from . import pour_water

__all__ = ["pour_water"]
