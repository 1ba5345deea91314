"""PR2 kinematics for skillcompose skills: model, IK, collisions, reachability, rendering.

Units: metres [m] and radians [rad]; frames are named in every function name.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .errors import ChainNotFound as ChainNotFound
    from .errors import DatasetError as DatasetError
    from .errors import FrameNotFound as FrameNotFound
    from .errors import InvalidConfiguration as InvalidConfiguration
    from .errors import RobotDataNotFound as RobotDataNotFound
    from .errors import RobotModelError as RobotModelError
    from .ik import IKResult as IKResult
    from .ik import IKSolver as IKSolver
    from .ik import IKStatus as IKStatus
    from .ik import IKTarget as IKTarget
    from .ik import solve_ik as solve_ik
    from .model import ARM_JOINTS as ARM_JOINTS
    from .model import ARMS as ARMS
    from .model import CHAIN_LAYOUT as CHAIN_LAYOUT
    from .model import TOOL_FRAMES as TOOL_FRAMES
    from .model import Arm as Arm
    from .model import KinematicChain as KinematicChain
    from .model import RobotModel as RobotModel
    from .model import RobotPose as RobotPose
    from .model import find_pr2_urdf as find_pr2_urdf
    from .model import load_pr2 as load_pr2
else:
    import lazy_loader

    # Each public name is imported with its module when it is first used, so that importing
    # the package stays cheap (Pinocchio loads with skillcompose.robots.model). The table repeats
    # the
    # imports above, which only the type checker runs; a test keeps the two equal.
    _EXPORTS = {
        "errors": ("ChainNotFound DatasetError FrameNotFound InvalidConfiguration "
                   "RobotDataNotFound RobotModelError"),
        "ik": "IKResult IKSolver IKStatus IKTarget solve_ik",
        "model": ("ARMS ARM_JOINTS CHAIN_LAYOUT TOOL_FRAMES Arm KinematicChain RobotModel "
                  "RobotPose find_pr2_urdf load_pr2"),
    }
    __getattr__, __dir__, __all__ = lazy_loader.attach(
        __name__, submod_attrs={module: names.split() for module, names in _EXPORTS.items()}
    )
