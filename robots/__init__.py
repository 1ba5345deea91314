"""PR2 kinematics for skillcompose skills: model, IK, collisions, reachability, rendering.

Units: metres [m] and radians [rad]; frames are named in every function name.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from robots.errors import (
        ChainNotFound,
        DatasetError,
        FrameNotFound,
        InvalidConfiguration,
        RobotDataNotFound,
        RobotModelError,
    )
    from robots.ik import IKResult, IKSolver, IKStatus, IKTarget, solve_ik
    from robots.model import (
        ARM_JOINTS,
        ARMS,
        CHAIN_LAYOUT,
        TOOL_FRAMES,
        Arm,
        KinematicChain,
        RobotModel,
        RobotPose,
        find_pr2_urdf,
        load_pr2,
    )

# Each public name and the module that defines it: the package imports that module when the
# name is first used, so that importing the package (the command line's --help does) stays
# cheap.
_HOMES = {
    "ARMS": "robots.model",
    "ARM_JOINTS": "robots.model",
    "Arm": "robots.model",
    "CHAIN_LAYOUT": "robots.model",
    "ChainNotFound": "robots.errors",
    "DatasetError": "robots.errors",
    "FrameNotFound": "robots.errors",
    "IKResult": "robots.ik",
    "IKSolver": "robots.ik",
    "IKStatus": "robots.ik",
    "IKTarget": "robots.ik",
    "InvalidConfiguration": "robots.errors",
    "KinematicChain": "robots.model",
    "RobotDataNotFound": "robots.errors",
    "RobotModel": "robots.model",
    "RobotModelError": "robots.errors",
    "RobotPose": "robots.model",
    "TOOL_FRAMES": "robots.model",
    "find_pr2_urdf": "robots.model",
    "load_pr2": "robots.model",
    "solve_ik": "robots.ik",
}

__all__ = [
    "ARMS",
    "ARM_JOINTS",
    "CHAIN_LAYOUT",
    "TOOL_FRAMES",
    "Arm",
    "ChainNotFound",
    "DatasetError",
    "FrameNotFound",
    "IKResult",
    "IKSolver",
    "IKStatus",
    "IKTarget",
    "InvalidConfiguration",
    "KinematicChain",
    "RobotDataNotFound",
    "RobotModel",
    "RobotModelError",
    "RobotPose",
    "find_pr2_urdf",
    "load_pr2",
    "solve_ik",
]


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(home, __name__), name)
    globals()[name] = value  # later uses skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
