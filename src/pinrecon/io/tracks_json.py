"""pinrecon's own tracks format, JSON and NPZ (``docs/formats.md``).

JSON: ``{"fps": 120.0, "names": [K names], "points": T x K list of [u, v] or null,
"confidence": optional T x K, "lifted": optional {"names", "points": T x K [x, y, z] or null,
"confidence", "frame", "source", "camera"}}``. NPZ: the same keys, ``points`` (T, K, 2) with
NaN for missing, the lifted block as ``lifted_points``, ``lifted_names`` ... .

Plain data both ways: the readers return :class:`~pinrecon.io.track_arrays.TrackArrays`
and the writer takes arrays; :func:`pinrecon.load_tracks` and :meth:`pinrecon.Tracks.save`
build and validate the ``Tracks`` (this module never imports :mod:`pinrecon.tracks`).
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path

import numpy as np

from ..errors import InputError
from .atomic import atomic_path, atomic_write_text
from .jsonfile import read_json, read_npz
from .track_arrays import LiftedArrays, TrackArrays

__all__ = ["read_tracks_json", "read_tracks_npz", "write_tracks", "tracks_dict", "lifted_dict"]


def _require(data, key, path):
    if key not in data:
        raise InputError("required field is missing", file=path, field=key)
    return data[key]


def read_tracks_json(path: str | os.PathLike) -> TrackArrays:
    """Parse a pinrecon tracks JSON file (``fps`` as written; ``Tracks`` checks it)."""
    path = Path(path)
    data = read_json(path)
    if not isinstance(data, dict):
        raise InputError("expected a JSON object with fps, names, points", file=path)
    fps = _require(data, "fps", path)
    names = _require(data, "names", path)
    rows = _require(data, "points", path)
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise InputError("must be a list of strings", file=path, field="names")
    if not isinstance(rows, list):
        raise InputError("must be a list of frames", file=path, field="points")
    pts = _point_rows(rows, names, 2, path, "points")
    conf = data.get("confidence")
    if conf is not None:
        conf = _value_rows(conf, len(rows), len(names), path, "confidence")
    lifted = _lifted_json(data.get("lifted"), path)
    return TrackArrays(pts, names, fps, conf, str(path), lifted=lifted)


def _point_rows(rows, names: list[str], dim: int, path: Path, field: str) -> np.ndarray:
    """T frames of K points, each ``[c0 .. c{dim-1}]`` or null, as a (T, K, dim) array."""
    if not isinstance(rows, list):
        raise InputError("must be a list of frames", file=path, field=field)
    K = len(names)
    shape = "[u, v]" if dim == 2 else "[x, y, z]"
    pts = np.full((len(rows), K, dim), np.nan)
    for t, row in enumerate(rows):
        if not isinstance(row, list) or len(row) != K:
            n = len(row) if isinstance(row, list) else type(row).__name__
            raise InputError(f"expected {K} points (one per name), got {n}", file=path, field=field, frame=t)
        for k, p in enumerate(row):
            if p is None:
                continue
            if not isinstance(p, list) or len(p) != dim:
                raise InputError(f"point {names[k]!r} must be {shape} or null, got {p!r}", file=path, field=field,
                                 frame=t)
            try:
                pts[t, k] = [np.nan if c is None else float(c) for c in p]
            except (TypeError, ValueError, OverflowError):
                raise InputError(f"point {names[k]!r} is not numeric: {p!r}", file=path, field=field, frame=t) from None
    return pts


def _value_rows(rows, T: int, K: int, path: Path, field: str) -> np.ndarray:
    """T frames of K numbers (null read as NaN) as a (T, K) array."""
    if not isinstance(rows, list) or len(rows) != T:
        raise InputError(f"expected {T} rows to match points", file=path, field=field)
    arr = np.zeros((T, K))
    for t, row in enumerate(rows):
        if not isinstance(row, list) or len(row) != K:
            raise InputError(f"expected {K} values", file=path, field=field, frame=t)
        try:
            arr[t] = [np.nan if c is None else float(c) for c in row]
        except (TypeError, ValueError, OverflowError):
            raise InputError("not numeric", file=path, field=field, frame=t) from None
    return arr


def _lifted_json(block, path: Path) -> LiftedArrays | None:
    """The optional ``lifted`` object: a lifter's 3D cues of the same frames."""
    if block is None:
        return None
    if not isinstance(block, dict):
        raise InputError("must be an object with names, points, frame", file=path, field="lifted")
    names = block.get("names")
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise InputError("must be a list of strings", file=path, field="lifted.names")
    if "points" not in block:
        raise InputError("required field is missing", file=path, field="lifted.points")
    pts = _point_rows(block["points"], names, 3, path, "lifted.points")
    conf = block.get("confidence")
    if conf is not None:
        conf = _value_rows(conf, len(pts), len(names), path, "lifted.confidence")
    frame = block.get("frame", "unknown")
    source = block.get("source")
    if source is not None and not isinstance(source, str):
        raise InputError(f"must be a string or null, got {source!r}", file=path, field="lifted.source")
    camera = block.get("camera", 0)
    if isinstance(camera, bool) or not isinstance(camera, int) or camera < 0:
        raise InputError(f"must be a camera index (integer >= 0), got {camera!r}", file=path, field="lifted.camera")
    return LiftedArrays(pts, names, conf, frame, source, camera)


def _lifted_npz(data: dict, path: Path) -> LiftedArrays | None:
    """The optional ``lifted_*`` arrays of a tracks NPZ."""
    if "lifted_points" not in data:
        return None
    if "lifted_names" not in data:
        raise InputError("required with lifted_points", file=path, field="lifted_names")
    names = [str(n) for n in np.atleast_1d(data["lifted_names"])]
    frame = str(data["lifted_frame"]) if "lifted_frame" in data else "unknown"
    source = str(data["lifted_source"]) if "lifted_source" in data else None
    camera = data.get("lifted_camera", np.int64(0))
    if camera.shape != () or camera.dtype.kind not in "iu" or int(camera) < 0:
        raise InputError("must be a camera index (integer >= 0)", file=path, field="lifted_camera")
    return LiftedArrays(data["lifted_points"], names, data.get("lifted_confidence"), frame, source, int(camera))


def read_tracks_npz(path: str | os.PathLike) -> TrackArrays:
    """Parse a pinrecon tracks NPZ file."""
    path = Path(path)
    if not zipfile.is_zipfile(path):
        raise InputError("not an NPZ file (an NPZ is a zip archive of .npy arrays)", file=path)
    data = read_npz(path)
    for key in ("fps", "names", "points"):
        _require(data, key, path)
    fps = data["fps"]
    if fps.shape != () or fps.dtype.kind not in "iuf":
        raise InputError(f"must be a number, got {fps.dtype} array of shape {fps.shape}", file=path, field="fps")
    names = [str(n) for n in np.atleast_1d(data["names"])]
    return TrackArrays(data["points"], names, float(fps), data.get("confidence"), str(path),
                       lifted=_lifted_npz(data, path))


def _plain_points(points: np.ndarray) -> list:
    """(T, K, d) array as T lists of K lists (a point with a non-finite coordinate as null)."""
    return [[None if not np.all(np.isfinite(p)) else [float(c) for c in p] for p in row] for row in points]


def lifted_dict(lifted: LiftedArrays) -> dict:
    """The JSON object of a lifter's 3D cues (missing points as null)."""
    out = {"names": list(lifted.names), "points": _plain_points(lifted.points), "frame": lifted.frame,
           "source": lifted.source, "camera": int(lifted.camera)}
    if lifted.confidence is not None:
        out["confidence"] = np.asarray(lifted.confidence, dtype=float).tolist()
    return out


def tracks_dict(
    points: np.ndarray, names: list[str], fps: float, confidence: np.ndarray | None,
    lifted: LiftedArrays | None = None,
) -> dict:
    """The JSON object of tracks (missing points as null)."""
    out = {"fps": fps, "names": list(names), "points": _plain_points(points)}
    if confidence is not None:
        out["confidence"] = confidence.tolist()
    if lifted is not None:
        out["lifted"] = lifted_dict(lifted)
    return out


def write_tracks(
    path: str | os.PathLike, points: np.ndarray, names: list[str], fps: float, confidence: np.ndarray | None,
    lifted: LiftedArrays | None = None,
) -> None:
    """Write tracks as NPZ (``.npz`` suffix) or JSON (otherwise), atomically, with a
    lifter's 3D cues (``lifted``) when given.

    The arrays are written as given: :meth:`pinrecon.Tracks.save` validates them first.
    """
    path = Path(path)
    if path.suffix.lower() == ".npz":
        arrays = {"fps": np.float64(fps), "names": np.array(names), "points": points}
        if confidence is not None:
            arrays["confidence"] = confidence
        if lifted is not None:
            arrays.update(lifted_points=np.asarray(lifted.points, dtype=float), lifted_names=np.array(lifted.names),
                          lifted_frame=np.array(lifted.frame), lifted_camera=np.int64(lifted.camera))
            if lifted.confidence is not None:
                arrays["lifted_confidence"] = np.asarray(lifted.confidence, dtype=float)
            if lifted.source is not None:
                arrays["lifted_source"] = np.array(lifted.source)
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)
    else:
        atomic_write_text(path, json.dumps(tracks_dict(points, names, fps, confidence, lifted)))
