"""Learned 3D cues: a lifter's per-frame 3D estimate of the tracked points.

A lifter (MediaPipe's world landmarks, MotionBERT, VideoPose3D, MMPose's 3D inferencer, or
pinrecon's own) gives, per frame, 3D positions of named points. Their scale and translation are
unreliable and their axes are the lifter's own, so :class:`Lifted` carries only what the MAP can
use as a prior on the figure's shape: directions between points, per frame, with a confidence.

``frame`` says how the lifter's axes relate to the camera whose image was lifted:

* ``"camera"``: the camera's own axes (x right, y down, z forward, as OpenCV), up to scale and
  translation; the rotation to the camera is the identity.
* ``"unknown"``: some fixed axes of the lifter's (MediaPipe's world landmarks: hips-centred,
  y down, but not aligned with the camera), one rotation for the whole clip, estimated.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError
from .io.lifters import LIFTER_FORMATS, guess_lifter_format, read_lifter_npy, read_mmpose3d

__all__ = ["LIFTED_FRAMES", "LIFTER_FORMATS", "UNUSED_CUES", "Lifted", "load_lifted"]

LIFTED_FRAMES = ("camera", "unknown")

#: points whose 3D a reconstruction does not take as cues, per lifter (:attr:`Lifted.source`):
#: MediaPipe's heels and foot tips, its least accurate world landmarks (the median angle between
#: its ankle-heel direction and the true one is 39-56 degrees on the four cameras of Pose2Sim's
#: real trial, against 6-31 for the limbs and the trunk: bench/README.md, bench_video); their 2D
#: points still place the feet
UNUSED_CUES: dict[str, tuple[str, ...]] = {
    "mediapipe": ("left_heel", "right_heel", "left_foot_index", "right_foot_index"),
}


@dataclass(eq=False)
class Lifted:
    """3D positions of K named points over T frames from a learned lifter.

    Attributes
    ----------
    points : (T, K, 3) positions in the lifter's units and axes, NaN where missing.
    names : K point names (the same vocabulary as :class:`pinrecon.Tracks` names).
    confidence : (T, K) in [0, 1] (the lifter's visibility or certainty), 0 where missing.
    frame : ``"camera"`` or ``"unknown"`` (see the module's docstring).
    source : what produced them (``"mediapipe"``, ``"motionbert"``, a file name ...).
    camera : index of the camera whose image they were lifted from (several-camera solves).
    """

    points: np.ndarray
    names: list[str]
    confidence: np.ndarray | None = None
    frame: str = "unknown"
    source: str | None = None
    camera: int = 0

    def __post_init__(self):
        src = self.source
        try:
            pts = np.array(self.points, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise InputError("must be numeric (T, K, 3)", file=src, field="lifted") from None
        if pts.ndim != 3 or pts.shape[2] != 3:
            raise InputError(f"expected shape (T, K, 3), got {pts.shape}", file=src, field="lifted")
        names = [str(n) for n in self.names]
        if len(names) != pts.shape[1]:
            raise InputError(f"{len(names)} names but {pts.shape[1]} points", file=src, field="lifted names")
        if len(set(names)) != len(names):
            raise InputError("duplicate names", file=src, field="lifted names")
        bad = ~np.all(np.isfinite(pts), axis=2)
        pts[bad] = np.nan
        huge = np.argwhere(np.abs(np.where(bad[..., None], 0.0, pts)) > 1e6)
        if huge.size:
            raise InputError("coordinates beyond +-1e6 are no positions", file=src, field="lifted",
                             frame=int(huge[0, 0]))
        if self.confidence is None:
            conf = np.ones(pts.shape[:2])
        else:
            try:
                conf = np.array(self.confidence, dtype=float)
            except (TypeError, ValueError, OverflowError):
                raise InputError("must be numeric (T, K)", file=src, field="lifted confidence") from None
            if conf.shape != pts.shape[:2]:
                raise InputError(f"expected shape {pts.shape[:2]}, got {conf.shape}", file=src,
                                 field="lifted confidence")
            conf = np.clip(np.where(np.isfinite(conf), conf, 0.0), 0.0, 1.0)
        conf[bad] = 0.0
        if self.frame not in LIFTED_FRAMES:
            raise InputError(f"frame must be one of {LIFTED_FRAMES}, got {self.frame!r}", file=src,
                             field="lifted frame")
        self.points, self.names, self.confidence = pts, names, conf
        self.camera = int(self.camera)

    @property
    def T(self) -> int:
        return self.points.shape[0]

    @property
    def K(self) -> int:
        return self.points.shape[1]

    def select(self, names: Sequence[str]) -> Lifted:
        """The named points only, in that order (names it lacks are missing: NaN, confidence 0)."""
        index = {n: i for i, n in enumerate(self.names)}
        pts = np.full((self.T, len(names), 3), np.nan)
        conf = np.zeros((self.T, len(names)))
        for j, n in enumerate(names):
            if n in index:
                pts[:, j] = self.points[:, index[n]]
                conf[:, j] = self.confidence[:, index[n]]
        return Lifted(pts, list(names), conf, self.frame, self.source, self.camera)

    def cues(self) -> Lifted:
        """The points a reconstruction takes as cues: those :data:`UNUSED_CUES` names for this
        lifter's ``source`` at confidence 0 (their positions kept)."""
        unused = [j for j, n in enumerate(self.names) if n in UNUSED_CUES.get(self.source or "", ())]
        if not unused:
            return self
        conf = self.confidence.copy()
        conf[:, unused] = 0.0
        return Lifted(self.points, self.names, conf, self.frame, self.source, self.camera)

    def frames(self, start: int = 0, stop: int | None = None, step: int = 1) -> Lifted:
        """A frame range, as :meth:`pinrecon.Tracks.frames`."""
        sl = slice(start, stop, step)
        return Lifted(self.points[sl], self.names, self.confidence[sl], self.frame, self.source, self.camera)

    def __repr__(self):
        return f"Lifted({self.T} frames x {self.K} points, frame={self.frame!r}, source={self.source!r})"


def load_lifted(
    path: str | os.PathLike,
    *,
    fmt: str | None = None,
    layout=None,
    names: Sequence[str] | None = None,
    person: int = 0,
    frames: int | None = None,
    frame: str | None = None,
) -> Lifted:
    """Read a lifter's 3D output file as :class:`Lifted` (``docs/formats.md``, section 11).

    ``fmt``: ``"npy"`` (MotionBERT's ``X3D.npy``, VideoPose3D's ``--viz-export``; also
    spelled ``"motionbert"``, ``"videopose3d"``) or ``"mmpose3d"`` (MMPose's 3D inferencer
    JSON); default from the suffix. The joints are in Human3.6M-17 order unless ``layout``
    (a 17-point :mod:`pinrecon.layouts` name) or ``names`` (one per joint) says otherwise;
    an H36M file whose bone lengths cannot be that order is refused. ``person`` picks the
    subject in MMPose files. ``frames``, when given, is the number of frames the lifted
    points must have (the tracks' ``T``). Every problem is an :class:`InputError` naming
    the file, the field and the frame. ``frame`` replaces the format's own axes
    (``"camera"`` for all three) for a file someone has turned into other axes
    (``"unknown"``: e.g. video2bvh's ``3d_pose.npy``, VideoPose3D's output moved to a Z-up world).
    """
    path = Path(path)
    if not path.exists():
        raise InputError("file not found", file=path)
    fmt = guess_lifter_format(path) if fmt is None else str(fmt).lower()
    if fmt in ("npy", "motionbert", "videopose3d"):
        la = read_lifter_npy(path, layout=layout, names=names)
    elif fmt == "mmpose3d":
        la = read_mmpose3d(path, person=person, layout=layout, names=names)
    else:
        raise InputError(f"unknown lifter format {fmt!r}; valid formats are: {', '.join(LIFTER_FORMATS)}",
                         file=path, field="format")
    T = len(la.points)
    if frames is not None and T != frames:
        raise InputError(f"{T} frames of lifted 3D for {frames} frames of tracks", file=path, field="points",
                         frame=min(T, frames))
    try:
        return Lifted(la.points, la.names, la.confidence, la.frame if frame is None else frame, la.source, la.camera)
    except InputError as err:
        raise InputError(err.message, file=path, field=err.field, frame=err.frame) from None
