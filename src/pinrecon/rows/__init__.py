"""Row kinds: each returns residuals and Jacobian blocks for the frames it touches."""

from .base import RowBlock, RowKind, State
from .global_prior import GlobalPrior
from .intrinsics import CameraScale
from .keyframes import JointKeyframes
from .limits import JointLimits
from .measurement import Measurement2D
from .points3d import Points3D
from .posture import Posture
from .smoothing import Smoothing, smoothing_sigmas

__all__ = [
    "RowBlock",
    "RowKind",
    "State",
    "Measurement2D",
    "Points3D",
    "JointLimits",
    "Smoothing",
    "smoothing_sigmas",
    "JointKeyframes",
    "Posture",
    "GlobalPrior",
    "CameraScale",
]
