"""Skill libraries: task-level skills, one module per task and backend.

- :mod:`skillcompose.skills.pour_water`: the six skills of the paper's pouring experiment (section
  4.1)
  on the abstract ``"sim"`` backend.
- :mod:`skillcompose.skills.kinematic`: their twins and more skills on the ``"kinematic"`` backend,
  which
  move a PR2 (IK, joint limits, table collisions); :mod:`skillcompose.skills.kinematic_world` holds
  the
  robot's blackboard keys and frames.

Each module defines ``register(registry)``; load one with
``registry.load_module("skillcompose.skills.pour_water")``. Skills of different backends share names
(``MoveToObject``), so their modules are exported whole rather than their skills one by one.
"""

from __future__ import annotations

from . import pour_water

__all__ = ["kinematic", "kinematic_world", "pour_water"]


def __getattr__(name: str) -> object:
    # the kinematic modules need Pinocchio: import them on first use only
    if name in ("kinematic", "kinematic_world"):
        import importlib

        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
