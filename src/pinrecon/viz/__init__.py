"""Pictures and animations of reconstructions (the optional ``viz`` extra: matplotlib).

``import pinrecon.viz`` works without matplotlib; the functions raise
:class:`MissingDependencyError` (a :class:`pinrecon.PinreconError` and an
``ImportError``) naming the ``viz`` extra when it is missing.

* :func:`plot_joint_angles` - joint angles over time, truth dashed (DiFranco et al. fig. 9).
* :func:`plot_reprojection` - 2D tracks with the reconstruction reprojected over them.
* :func:`plot_stick_strip` - stick figures over frames from the camera and a second view
  (figs. 7 and 8).
* :func:`plot_reprojection_error` - reprojection error per frame.
* :func:`animate` - GIF/MP4 of the two views side by side.
* :func:`plot_result` - all of the above for a result file (``pinrecon plot``).
"""

from ._common import MissingDependencyError, Skeleton, skeleton
from .animate import animate
from .plots import (
    plot_joint_angles,
    plot_reprojection,
    plot_reprojection_error,
    plot_result,
    plot_stick_strip,
)

__all__ = [
    "plot_joint_angles",
    "plot_reprojection",
    "plot_stick_strip",
    "plot_reprojection_error",
    "plot_result",
    "animate",
    "skeleton",
    "Skeleton",
    "MissingDependencyError",
]
