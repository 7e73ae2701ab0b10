"""pinrecon's own tracks format, JSON and NPZ (``docs/formats.md``).

JSON: ``{"fps": 120.0, "names": [K names], "points": T x K list of [u, v] or null,
"confidence": optional T x K}``. NPZ: the same keys, ``points`` (T, K, 2) with NaN for
missing.

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
from .jsonfile import read_json
from .track_arrays import TrackArrays

__all__ = ["read_tracks_json", "read_tracks_npz", "write_tracks", "tracks_dict"]


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
    K = len(names)
    pts = np.full((len(rows), K, 2), np.nan)
    for t, row in enumerate(rows):
        if not isinstance(row, list) or len(row) != K:
            n = len(row) if isinstance(row, list) else type(row).__name__
            raise InputError(f"expected {K} points (one per name), got {n}", file=path, field="points", frame=t)
        for k, p in enumerate(row):
            if p is None:
                continue
            if not isinstance(p, list) or len(p) != 2:
                raise InputError(
                    f"point {names[k]!r} must be [u, v] or null, got {p!r}", file=path, field="points", frame=t
                )
            try:
                pts[t, k] = [np.nan if c is None else float(c) for c in p]
            except (TypeError, ValueError, OverflowError):
                raise InputError(f"point {names[k]!r} is not numeric: {p!r}", file=path, field="points", frame=t) from None
    conf = data.get("confidence")
    if conf is not None:
        if not isinstance(conf, list) or len(conf) != len(rows):
            raise InputError(f"expected {len(rows)} rows to match points", file=path, field="confidence")
        arr = np.zeros((len(rows), K))
        for t, row in enumerate(conf):
            if not isinstance(row, list) or len(row) != K:
                raise InputError(f"expected {K} values", file=path, field="confidence", frame=t)
            try:
                arr[t] = [np.nan if c is None else float(c) for c in row]
            except (TypeError, ValueError, OverflowError):
                raise InputError("not numeric", file=path, field="confidence", frame=t) from None
        conf = arr
    return TrackArrays(pts, names, fps, conf, str(path))


def read_tracks_npz(path: str | os.PathLike) -> TrackArrays:
    """Parse a pinrecon tracks NPZ file."""
    path = Path(path)
    if not zipfile.is_zipfile(path):
        raise InputError("not an NPZ file (an NPZ is a zip archive of .npy arrays)", file=path)
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except Exception as exc:  # noqa: BLE001 - a damaged archive fails in zipfile, zlib or numpy's .npy header parser
        raise InputError(f"not a readable NPZ file ({type(exc).__name__}: {exc})", file=path) from None
    for key in ("fps", "names", "points"):
        _require(data, key, path)
    fps = data["fps"]
    if fps.shape != () or fps.dtype.kind not in "iuf":
        raise InputError(f"must be a number, got {fps.dtype} array of shape {fps.shape}", file=path, field="fps")
    names = [str(n) for n in np.atleast_1d(data["names"])]
    return TrackArrays(data["points"], names, float(fps), data.get("confidence"), str(path))


def tracks_dict(points: np.ndarray, names: list[str], fps: float, confidence: np.ndarray | None) -> dict:
    """The JSON object of tracks (missing points as null)."""
    pts = [
        [None if not np.all(np.isfinite(p)) else [float(p[0]), float(p[1])] for p in row]
        for row in points
    ]
    out = {"fps": fps, "names": list(names), "points": pts}
    if confidence is not None:
        out["confidence"] = confidence.tolist()
    return out


def write_tracks(
    path: str | os.PathLike, points: np.ndarray, names: list[str], fps: float, confidence: np.ndarray | None
) -> None:
    """Write tracks as NPZ (``.npz`` suffix) or JSON (otherwise), atomically.

    The arrays are written as given: :meth:`pinrecon.Tracks.save` validates them first.
    """
    path = Path(path)
    if path.suffix.lower() == ".npz":
        arrays = {"fps": np.float64(fps), "names": np.array(names), "points": points}
        if confidence is not None:
            arrays["confidence"] = confidence
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)
    else:
        atomic_write_text(path, json.dumps(tracks_dict(points, names, fps, confidence)))
