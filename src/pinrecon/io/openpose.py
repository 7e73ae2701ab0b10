"""OpenPose folders as :class:`pinrecon.Tracks` (the parser is :mod:`.openpose_json`).

This module imports :mod:`pinrecon.tracks`, so :mod:`pinrecon.tracks` imports only the parser.
"""

from __future__ import annotations

import os

from ..tracks import Tracks
from .openpose_json import BODY_25, COCO_18, read_openpose

__all__ = ["load_openpose", "read_openpose", "BODY_25", "COCO_18"]


def load_openpose(folder: str | os.PathLike, *, fps: float, person=None, layout=None) -> Tracks:
    """Read an OpenPose JSON folder (files in natural order) as tracks at ``fps``.

    ``person`` picks the subject followed through the frames: None (the most prominent
    person of the first frame with people), an index in that frame, a box
    ``(x1, y1, x2, y2)`` or ``"largest"`` (see :mod:`pinrecon.io.people`); ``layout``
    names the detector layout (default: detected, see :mod:`pinrecon.layouts`).
    :func:`pinrecon.load_tracks` ``(folder, fps=fps)`` reads the same way.
    """
    return Tracks.from_arrays(read_openpose(folder, person=person, layout=layout), fps=fps)
