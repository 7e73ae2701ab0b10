"""What the 2D-tracks format readers return: plain arrays, not :class:`pinrecon.Tracks`.

The readers (:mod:`pinrecon.io.tracks_json`, :mod:`pinrecon.io.coco`,
:mod:`pinrecon.io.openpose_json`) parse a file into a :class:`TrackArrays`;
:mod:`pinrecon.tracks` is the one place that turns it into a validated ``Tracks``
(:func:`pinrecon.load_tracks`). So the readers never import ``pinrecon.tracks``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["TrackArrays", "TracksWarning", "LiftedArrays"]


class TracksWarning(UserWarning):
    """Something about the input tracks the user should know (broken frames read as
    missing, people followed across frames, a layout chosen by default ...)."""


class LiftedArrays(NamedTuple):
    """The fields of :class:`pinrecon.lifted.Lifted`, in its order, as read from a file.

    ``points`` (T, K, 3), NaN where missing; ``names`` K point names; ``confidence``
    (T, K) or None; ``frame`` ``"camera"`` or ``"unknown"``; ``source`` the lifter (or the
    file) they came from; ``camera`` the index of the camera whose image was lifted.
    """

    points: np.ndarray
    names: list[str]
    confidence: np.ndarray | None
    frame: str
    source: str | None
    camera: int = 0


class TrackArrays(NamedTuple):
    """The fields of :class:`pinrecon.Tracks`, in its order, as read from a file.

    ``points`` (T, K, 2) pixels, NaN where missing; ``names`` K point names; ``fps`` as
    stored in the file (None for formats that store no frame rate: OpenPose, COCO);
    ``confidence`` (T, K) or None; ``source`` the file or folder read; ``layout`` the
    detector layout the points were read as (:mod:`pinrecon.layouts`), if any;
    ``notes`` what the user should be told (issued as :class:`TracksWarning` when the
    ``Tracks`` is built); ``lifted`` a lifter's 3D cues stored beside the tracks
    (:class:`LiftedArrays`), if any.
    """

    points: np.ndarray
    names: list[str]
    fps: object
    confidence: np.ndarray | None
    source: str
    layout: str | None = None
    notes: tuple[str, ...] = ()
    lifted: LiftedArrays | None = None
