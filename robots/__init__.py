"""PR2 kinematics for skillcompose skills: model, IK, collisions, reachability, rendering.

Units: metres [m] and radians [rad]; frames are named in every function name.
"""

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
