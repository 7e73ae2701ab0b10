"""2D joint tracks and 3D keyframes: the observations pinrecon reconstructs from.

Validation lives here: every problem is reported with the file, the field and the frame.

This is the one place that builds :class:`Tracks` from files: the format readers in
:mod:`pinrecon.io` (``tracks_json``, ``coco``, ``openpose_json``, ``mmpose``) return
plain :class:`~pinrecon.io.track_arrays.TrackArrays` and never import this module;
:func:`load_tracks` calls them and :meth:`Tracks.from_arrays` validates and issues the
readers' notes (broken frames, people followed, layout chosen) as one
:class:`TracksWarning` each.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError, UnknownNameError
from .io.coco import coco_kind, read_coco
from .io.mmpose import is_mmpose, read_mmpose
from .io.openpose_json import read_openpose
from .io.people import MAX_COORD
from .io.track_arrays import LiftedArrays, TrackArrays, TracksWarning
from .io.tracks_json import read_tracks_json, read_tracks_npz, write_tracks
from .lifted import Lifted

__all__ = [
    "Tracks",
    "TracksWarning",
    "Markers",
    "Keyframe",
    "Keyframes",
    "load_tracks",
    "guess_tracks_format",
    "load_keyframes",
    "keyframes_from_points",
    "TRACKS_FORMATS",
]

TRACKS_FORMATS = ("json", "npz", "openpose", "coco", "alphapose", "mmpose")
FPS_RANGE = (1e-3, 1e6)  # a frame rate outside it makes the time step under- or overflow
KEYFRAME_MAX_VALUE = 1e4  # metres or radians: a larger keyframe value is an error, not a pose
KEYFRAME_SIGMA_RANGE = (1e-9, 1e6)  # outside it the keyframe's weight under- or overflows
KEYFRAME_MAX_FRAME = 1e9


def _finite(x) -> bool:
    """A finite real number (huge Python ints, which no float holds, are not)."""
    try:
        return math.isfinite(x)
    except (OverflowError, TypeError):
        return False


@dataclass(eq=False)
class Tracks:
    """2D positions of K named points over T frames.

    Attributes
    ----------
    points : (T, K, 2) image positions in pixels, NaN where missing.
    names : K point names (matched against the figure's keypoint names).
    fps : frames per second.
    confidence : optional (T, K) weights in [0, 1] (detector scores); NaN counts as 0.
    source : file the tracks came from, for error messages.
    layout : the detector layout the points were read as (:mod:`pinrecon.layouts`), if any.
    lifted : optional learned 3D cues of the same frames (:class:`pinrecon.lifted.Lifted`).
    """

    points: np.ndarray
    names: list[str]
    fps: float
    confidence: np.ndarray | None = None
    source: str | None = None
    layout: str | None = None
    lifted: Lifted | None = None

    def __post_init__(self):
        src = self.source
        if np.asarray(self.points).dtype.kind == "c" or (
            self.confidence is not None and np.asarray(self.confidence).dtype.kind == "c"
        ):
            raise InputError("must be real numbers, not complex", file=src, field="points")
        try:
            pts = np.array(self.points, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise InputError("must be numeric (T, K, 2)", file=src, field="points") from None
        if pts.ndim != 3 or pts.shape[2] != 2:
            raise InputError(f"expected shape (T, K, 2), got {pts.shape}", file=src, field="points")
        names = [str(n) for n in self.names]
        if len(names) != pts.shape[1]:
            raise InputError(
                f"{len(names)} names but points have {pts.shape[1]} columns", file=src, field="names"
            )
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise InputError(f"duplicate names {dup}", file=src, field="names")
        if (
            isinstance(self.fps, bool)
            or not isinstance(self.fps, (int, float, np.floating, np.integer))
            or not _finite(self.fps)
            or self.fps <= 0
        ):
            raise InputError(f"must be a positive number, got {self.fps!r}", file=src, field="fps")
        if not FPS_RANGE[0] <= self.fps <= FPS_RANGE[1]:
            raise InputError(
                f"must be between {FPS_RANGE[0]:g} and {FPS_RANGE[1]:g} frames per second, got {self.fps!r}",
                file=src,
                field="fps",
            )
        # a point is missing if either coordinate is NaN/inf: make both NaN
        bad = ~np.all(np.isfinite(pts), axis=2)
        pts[bad] = np.nan
        huge = np.argwhere(np.abs(np.where(bad[..., None], 0.0, pts)) > MAX_COORD)
        if huge.size:
            raise InputError(
                f"coordinates beyond +-{MAX_COORD:g} px are no image positions", file=src, field="points",
                frame=int(huge[0, 0]),
            )
        conf = None
        if self.confidence is not None:
            try:
                conf = np.array(self.confidence, dtype=float)
            except (TypeError, ValueError, OverflowError):
                raise InputError("must be numeric (T, K)", file=src, field="confidence") from None
            if conf.shape != pts.shape[:2]:
                raise InputError(
                    f"expected shape {pts.shape[:2]} to match points, got {conf.shape}",
                    file=src,
                    field="confidence",
                )
            conf = np.where(np.isfinite(conf), conf, 0.0)
            neg = np.argwhere(conf < 0)
            if neg.size:
                raise InputError("confidence must be >= 0", file=src, field="confidence", frame=int(neg[0, 0]))
        if self.lifted is not None:
            if not isinstance(self.lifted, Lifted):
                raise InputError("must be a pinrecon.lifted.Lifted", file=src, field="lifted")
            if self.lifted.T != pts.shape[0]:
                raise InputError(
                    f"{self.lifted.T} frames of lifted 3D for {pts.shape[0]} frames of tracks",
                    file=self.lifted.source or src, field="lifted",
                )
        self.points, self.names, self.fps, self.confidence = pts, names, float(self.fps), conf

    @classmethod
    def from_arrays(cls, arrays: TrackArrays, *, fps: float | None = None) -> Tracks:
        """Validated tracks from a format reader's plain arrays; ``fps`` (when given)
        replaces the file's frame rate (OpenPose and COCO store none). The reader's
        notes are issued as :class:`TracksWarning` (one warning each)."""
        tracks = cls(
            arrays.points, arrays.names, arrays.fps if fps is None else fps, arrays.confidence, arrays.source,
            arrays.layout, _lifted_from_arrays(arrays),
        )
        for note in arrays.notes:
            warnings.warn(note, TracksWarning, stacklevel=3)
        return tracks

    @property
    def T(self) -> int:
        return self.points.shape[0]

    @property
    def K(self) -> int:
        return self.points.shape[1]

    @property
    def times(self) -> np.ndarray:
        return np.arange(self.T) / self.fps

    @property
    def observed(self) -> np.ndarray:
        """(T, K) bool: the point is present (and has non-zero confidence)."""
        ok = np.all(np.isfinite(self.points), axis=2)
        if self.confidence is not None:
            ok &= self.confidence > 0
        return ok

    def weights(self) -> np.ndarray:
        """(T, K) per-point weights: confidence (or 1), 0 where missing."""
        w = np.ones(self.points.shape[:2]) if self.confidence is None else self.confidence.copy()
        w[~self.observed] = 0.0
        return w

    def select(self, names: Sequence[str]) -> Tracks:
        """Tracks of the named points only, in that order."""
        index = {n: i for i, n in enumerate(self.names)}
        unknown = [n for n in names if n not in index]
        if unknown:
            raise UnknownNameError("track", unknown, self.names, file=self.source, field="names")
        idx = [index[n] for n in names]
        conf = None if self.confidence is None else self.confidence[:, idx]
        lifted = None if self.lifted is None else self.lifted.select(names)
        return Tracks(self.points[:, idx], list(names), self.fps, conf, self.source, self.layout, lifted)

    def frames(self, start: int = 0, stop: int | None = None, step: int = 1) -> Tracks:
        """A frame range (``step`` > 1 subsamples and divides fps)."""
        sl = slice(start, stop, step)
        conf = None if self.confidence is None else self.confidence[sl]
        lifted = None if self.lifted is None else self.lifted.frames(start, stop, step)
        return Tracks(self.points[sl], self.names, self.fps / step, conf, self.source, self.layout, lifted)

    def __repr__(self):
        miss = 1.0 - self.observed.mean() if self.T and self.K else 0.0
        return f"Tracks({self.T} frames x {self.K} points at {self.fps:g} fps, {100 * miss:.1f}% missing)"

    # ---- files
    def save(self, path: str | os.PathLike) -> None:
        """Write JSON (``.json``) or NPZ (``.npz``) atomically; see ``docs/formats.md``."""
        # validate again (attributes may have been replaced since construction): a file that
        # load_tracks would reject is never written
        t = Tracks(self.points, self.names, self.fps, self.confidence, str(path), lifted=self.lifted)
        lifted = None
        if t.lifted is not None:
            lf = Lifted(t.lifted.points, t.lifted.names, t.lifted.confidence, t.lifted.frame, t.lifted.source,
                        t.lifted.camera)
            lifted = LiftedArrays(lf.points, lf.names, lf.confidence, lf.frame, lf.source, lf.camera)
        write_tracks(path, t.points, t.names, t.fps, t.confidence, lifted)


def _lifted_from_arrays(arrays: TrackArrays) -> Lifted | None:
    """The tracks file's lifted block as a validated :class:`Lifted` (errors name the file)."""
    la = arrays.lifted
    if la is None:
        return None
    try:
        lifted = Lifted(la.points, la.names, la.confidence, la.frame, la.source, la.camera)
    except InputError as err:
        raise InputError(err.message, file=arrays.source, field=err.field, frame=err.frame) from None
    if lifted.T != len(arrays.points):
        raise InputError(f"{lifted.T} frames of lifted 3D for {len(arrays.points)} frames of tracks",
                         file=arrays.source, field="lifted")
    return lifted


def guess_tracks_format(path: str | os.PathLike) -> str:
    """The tracks format of ``path``: a folder is ``openpose``; ``.npz`` is ``npz``; a
    JSON file is ``openpose`` (one frame: ``people``), ``coco`` (``annotations`` or a
    results list), ``mmpose`` (``instance_info``, ``predictions`` or a list of frames
    with ``instances``) or ``json`` (pinrecon's own, also for unreadable files, whose
    reader reports the problem)."""
    path = Path(path)
    if path.is_dir():
        return "openpose"
    if path.suffix.lower() == ".npz":
        return "npz"
    from .io.jsonfile import read_json

    try:
        data = read_json(path)
    except InputError:
        return "json"
    if isinstance(data, dict) and "people" in data and "points" not in data:
        return "openpose"
    if is_mmpose(data):
        return "mmpose"
    if coco_kind(data) is not None:
        return "coco"
    return "json"


def load_tracks(
    path: str | os.PathLike,
    *,
    fps: float | None = None,
    fmt: str | None = None,
    person=None,
    layout=None,
) -> Tracks:
    """Read tracks from pinrecon JSON/NPZ, an OpenPose folder (or file), a COCO
    dataset or results file (AlphaPose results too) or MMPose / RTMPose JSON.

    ``fmt`` is one of ``TRACKS_FORMATS``; by default it is guessed
    (:func:`guess_tracks_format`). ``fps`` is required for detector output, which
    stores no frame rate. For detector output, ``person`` picks the subject followed
    through the frames (an index in the first frame with people, a box ``(x1, y1,
    x2, y2)``, or ``"largest"``; see :mod:`pinrecon.io.people`) and ``layout`` names
    the detector's point layout (default: detected; see :mod:`pinrecon.layouts`).
    Broken frames are read as missing, with one warning that counts them.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("file not found", file=path)
    if fmt is None:
        fmt = guess_tracks_format(path)
    if fmt == "json":
        return Tracks.from_arrays(read_tracks_json(path))
    if fmt == "npz":
        return Tracks.from_arrays(read_tracks_npz(path))
    readers = {"openpose": read_openpose, "coco": read_coco, "alphapose": read_coco, "mmpose": read_mmpose}
    if fmt in readers:
        if fps is None:
            raise InputError(f"{fmt} files store no frame rate: pass fps (--fps)", file=path, field="fps")
        return Tracks.from_arrays(readers[fmt](path, person=person, layout=layout), fps=fps)
    raise InputError(
        f"unknown tracks format {fmt!r}; valid formats are: {', '.join(TRACKS_FORMATS)}", file=path, field="format"
    )


# ------------------------------------------------------------------------------ keyframes
@dataclass(eq=False)
class Keyframe:
    """A full or partial 3D key pose at one frame of the tracks.

    Exactly one of ``points`` (keypoint -> world position, metres) and ``joints``
    (joint name -> value: radians for revolute joints, metres for prismatic; for the
    free-flyer root a 7-vector ``x y z qx qy qz qw`` or a 3-vector translation) is set.
    ``sigma`` is the standard deviation of every given value (metres for positions and
    translations, radians for angles).
    """

    frame: int
    sigma: float
    points: dict[str, np.ndarray] | None = None
    joints: dict[str, np.ndarray] | None = None

    @property
    def kind(self) -> str:
        return "points" if self.points is not None else "joints"


@dataclass(eq=False)
class Keyframes:
    """An ordered list of keyframes, as read from a keyframes JSON file."""

    keyframes: list[Keyframe] = field(default_factory=list)
    source: str | None = None

    def __iter__(self):
        return iter(self.keyframes)

    def __len__(self):
        return len(self.keyframes)

    def __getitem__(self, i):
        return self.keyframes[i]

    @classmethod
    def from_dict(cls, data, source=None) -> Keyframes:
        if not isinstance(data, Mapping) or "keyframes" not in data:
            raise InputError("expected an object with a 'keyframes' list", file=source, field="keyframes")
        items = data["keyframes"]
        if not isinstance(items, list):
            raise InputError("must be a list", file=source, field="keyframes")
        out = []
        for i, item in enumerate(items):
            fld = f"keyframes[{i}]"
            if not isinstance(item, Mapping):
                raise InputError("must be an object", file=source, field=fld)
            frame = item.get("frame")
            if (
                isinstance(frame, bool)
                or not isinstance(frame, (int, float))
                or not _finite(frame)
                or int(frame) != frame
            ):
                raise InputError(f"'frame' must be an integer, got {frame!r}", file=source, field=fld)
            if abs(frame) > KEYFRAME_MAX_FRAME:
                raise InputError(f"'frame' {frame!r} is beyond any clip (at most {KEYFRAME_MAX_FRAME:g})",
                                 file=source, field=fld)
            frame = int(frame)
            sigma = item.get("sigma", 0.01)
            if isinstance(sigma, bool) or not isinstance(sigma, (int, float)) or not (sigma > 0) or not _finite(sigma):
                raise InputError(f"'sigma' must be a positive number, got {sigma!r}", file=source, field=fld, frame=frame)
            if not KEYFRAME_SIGMA_RANGE[0] <= sigma <= KEYFRAME_SIGMA_RANGE[1]:
                raise InputError(f"'sigma' must be in [{KEYFRAME_SIGMA_RANGE[0]:g}, {KEYFRAME_SIGMA_RANGE[1]:g}], "
                                 f"got {sigma!r}", file=source, field=fld, frame=frame)
            has_p, has_j = "points" in item, "joints" in item
            if has_p == has_j:
                raise InputError("needs exactly one of 'points' or 'joints'", file=source, field=fld, frame=frame)
            key = "points" if has_p else "joints"
            values = item[key]
            if not isinstance(values, Mapping) or not values:
                raise InputError(f"'{key}' must be a non-empty object", file=source, field=f"{fld}.{key}", frame=frame)
            parsed = {}
            for name, val in values.items():
                f2 = f"{fld}.{key}.{name}"
                try:
                    arr = np.asarray(val, dtype=float)
                except (TypeError, ValueError, OverflowError):
                    raise InputError(f"not numeric: {val!r}", file=source, field=f2, frame=frame) from None
                if key == "points" and arr.shape != (3,):
                    raise InputError(f"expected [x, y, z], got shape {arr.shape}", file=source, field=f2, frame=frame)
                if key == "joints" and arr.ndim > 1:
                    raise InputError(f"expected a number or a list, got shape {arr.shape}", file=source, field=f2, frame=frame)
                if not np.all(np.isfinite(arr)):
                    raise InputError("NaN or infinite value", file=source, field=f2, frame=frame)
                if np.any(np.abs(arr) > KEYFRAME_MAX_VALUE):
                    raise InputError(f"a value beyond +-{KEYFRAME_MAX_VALUE:g} (metres or radians)", file=source,
                                     field=f2, frame=frame)
                parsed[str(name)] = arr
            out.append(Keyframe(frame, float(sigma), **{key: parsed}))
        return cls(out, source)

    def to_dict(self) -> dict:
        items = []
        for k in self.keyframes:
            d = {"frame": _plain(k.frame), "sigma": _plain(k.sigma)}
            vals = k.points if k.points is not None else k.joints
            d[k.kind] = {n: (np.asarray(v, float).tolist() if np.ndim(v) else float(v)) for n, v in vals.items()}
            items.append(d)
        return {"keyframes": items}

    def save(self, path: str | os.PathLike) -> None:
        import json

        from .io.atomic import atomic_write_text

        atomic_write_text(path, json.dumps(self.to_dict(), indent=1))

    def validate(self, figure, n_frames: int) -> None:
        """Check what a keyframes file is checked for when read (integer frames, positive
        ``sigma``, finite ``[x, y, z]`` points: keyframes built in Python skip the reader),
        that frames are inside ``[0, n_frames)`` and that every name exists in ``figure``."""
        Keyframes.from_dict(self.to_dict(), source=self.source)
        for i, k in enumerate(self.keyframes):
            fld = f"keyframes[{i}]"
            if not 0 <= k.frame < n_frames:
                raise InputError(
                    f"frame {k.frame} is outside the sequence (0..{n_frames - 1})",
                    file=self.source,
                    field=fld,
                    frame=k.frame,
                )
            if k.points is not None:
                figure.keypoint_index(list(k.points), file=self.source, field=f"{fld}.points")
            else:
                for name, val in k.joints.items():
                    jid = figure.joint_id(name, file=self.source, field=f"{fld}.joints", frame=k.frame)
                    nq = figure.model.nqs[jid]
                    sizes = (3, 7) if (figure.floating and jid == 1) else (nq,)
                    size = int(np.size(val))
                    if size not in sizes:
                        raise InputError(
                            f"joint {name!r} takes {' or '.join(map(str, sizes))} value(s), got {size}",
                            file=self.source,
                            field=f"{fld}.joints.{name}",
                            frame=k.frame,
                        )


def _plain(value):
    """A NumPy scalar as the Python number it holds (JSON's and the reader's types)."""
    return value.item() if isinstance(value, np.generic) else value


def load_keyframes(path: str | os.PathLike) -> Keyframes:
    """Read a keyframes JSON file (``docs/formats.md``)."""

    from .io.jsonfile import read_json

    return Keyframes.from_dict(read_json(path), source=str(path))


def keyframes_from_points(frames: Iterable[int], points: np.ndarray, names: Sequence[str], sigma: float) -> Keyframes:
    """Point keyframes from a (T, K, 3) array at the given frames (NaN points are left out)."""
    out = []
    for f in frames:
        d = {n: points[f, k] for k, n in enumerate(names) if np.all(np.isfinite(points[f, k]))}
        out.append(Keyframe(int(f), float(sigma), points=d))
    return Keyframes(out)


@dataclass(eq=False)
class Markers:
    """3D positions of K named points over T frames (motion-capture markers), metres.

    ``points`` (T, K, 3) with NaN for dropped markers/frames.
    """

    points: np.ndarray
    names: list[str]
    fps: float
    source: str | None = None

    def __post_init__(self):
        pts = np.array(self.points, dtype=float)
        if pts.ndim != 3 or pts.shape[2] != 3:
            raise InputError(f"expected shape (T, K, 3), got {pts.shape}", file=self.source, field="points")
        if len(self.names) != pts.shape[1]:
            raise InputError(f"{len(self.names)} names for {pts.shape[1]} markers", file=self.source, field="names")
        if not (isinstance(self.fps, (int, float, np.floating, np.integer)) and self.fps > 0):
            raise InputError(f"must be a positive number, got {self.fps!r}", file=self.source, field="fps")
        pts[~np.all(np.isfinite(pts), axis=2)] = np.nan
        self.points, self.names, self.fps = pts, [str(n) for n in self.names], float(self.fps)

    @property
    def T(self) -> int:
        return self.points.shape[0]

    @property
    def observed(self) -> np.ndarray:
        return np.all(np.isfinite(self.points), axis=2)
