"""OpenPose output folders read as :class:`pinrecon.Tracks`.

The parser and the point layouts live in :mod:`pinrecon.io.openpose_json` (plain data,
re-exported here); this module only adds :func:`load_openpose`, which makes the
``Tracks`` with :meth:`pinrecon.Tracks.from_arrays` like :func:`pinrecon.load_tracks`.
It imports :mod:`pinrecon.tracks`; ``tracks`` imports only the parser.
"""

from __future__ import annotations

import os

from ..tracks import Tracks
from .openpose_json import BODY_25, COCO_18, read_openpose

__all__ = ["load_openpose", "read_openpose", "BODY_25", "COCO_18"]


def load_openpose(folder: str | os.PathLike, *, fps: float, person: int = 0) -> Tracks:
    """Read an OpenPose JSON folder (files sorted by name) as tracks at ``fps``.

    ``person`` selects which detected person of each frame to keep (OpenPose's order).
    :func:`pinrecon.load_tracks` ``(folder, fps=fps)`` reads person 0 the same way.
    """
    return Tracks.from_arrays(read_openpose(folder, person=person), fps=fps)
