"""TRC marker files (OpenSim, Pose2Sim, Motion Analysis): 3D points over time, read and written.

The format (tab-separated text), as OpenSim reads it and Pose2Sim writes it::

    PathFileType  4  (X/Y/Z)  <file name>
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
    60        60          100        21          m      60            0                   100
    Frame#  Time  RHip        RKnee ...
                  X1  Y1  Z1  X2  Y2  Z2 ...
    1       0.0   ...

followed by one row per frame (a blank line may come first). A marker missing in a frame
is an empty field or ``NaN``. ``Units`` is ``m``, ``cm`` or ``mm``.

Axes: OpenSim's world is **Y up** (X forward, Z to the right); pinrecon's is Z up.
:func:`load_trc` turns the file's world into pinrecon's by the rotation that takes its up
axis to Z (for Y up, ``(x, y, z) -> (z, x, y)``: a rotation, not a mirror), and
:func:`write_trc` turns it back. ``pinrecon export --trc`` writes the export's grounded world
(:func:`pinrecon.io.bvh_export.ground_frame`: Y up, the floor at height 0; ``--facing=+x``
faces the figure along OpenSim's forward axis).

Names: by default the file's names are kept. ``names="pinrecon"`` renames the points whose
meaning is the same in every skeleton Pose2Sim and OpenPose write (``RShoulder`` ->
``right_shoulder``, ``LBigToe`` -> ``left_big_toe``, ``Nose`` -> ``nose``, ...;
:data:`POSE2SIM_NAMES`), so that the markers meet :meth:`pinrecon.Figure.human`'s keypoints.
``Neck``, ``Head`` and ``Hip`` keep their names: Pose2Sim's ``Neck`` is the top of the neck
in its HALPE_26 and BODY_25B skeletons but the shoulders' midpoint in BODY_25, and no file
says which. :func:`write_trc` with ``names="pose2sim"`` writes the same table the other way.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..tracks import Markers
from .atomic import atomic_write_text
from .jsonfile import read_text

__all__ = ["POSE2SIM_AMBIGUOUS", "POSE2SIM_NAMES", "load_trc", "write_trc", "z_up_rotation"]

#: Pose2Sim's and OpenPose's names of the points whose meaning every skeleton shares ->
#: pinrecon's names (:mod:`pinrecon.layouts`).
POSE2SIM_NAMES = {
    "Nose": "nose", "REye": "right_eye", "LEye": "left_eye", "REar": "right_ear", "LEar": "left_ear",
    "RShoulder": "right_shoulder", "LShoulder": "left_shoulder", "RElbow": "right_elbow", "LElbow": "left_elbow",
    "RWrist": "right_wrist", "LWrist": "left_wrist", "RHip": "right_hip", "LHip": "left_hip",
    "RKnee": "right_knee", "LKnee": "left_knee", "RAnkle": "right_ankle", "LAnkle": "left_ankle",
    "RBigToe": "right_big_toe", "LBigToe": "left_big_toe", "RSmallToe": "right_small_toe",
    "LSmallToe": "left_small_toe", "RHeel": "right_heel", "LHeel": "left_heel",
}
#: Pose2Sim's names whose point depends on the skeleton, which the file does not name: ``Neck``
#: is the top of the neck (pinrecon's ``upper_neck``) in HALPE_26 and BODY_25B but the
#: shoulders' midpoint (``neck``) in BODY_25; ``Head`` and ``Hip`` likewise
POSE2SIM_AMBIGUOUS = ("Neck", "Head", "Hip")
_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
_AXES = {"x": 0, "y": 1, "z": 2}


#: the farthest marker accepted, metres (a larger or infinite coordinate is a broken file)
MAX_MARKER_M = 1e6


def z_up_rotation(up: str) -> np.ndarray:
    """The rotation (3, 3) taking a world whose ``up`` axis is up to pinrecon's Z-up world: a
    cyclic permutation of the axes (determinant +1)."""
    if up not in _AXES:
        raise InputError(f"must be 'x', 'y' or 'z', got {up!r}", field="up")
    shift = 2 - _AXES[up]  # world axis i = file axis (i - shift) mod 3
    return np.roll(np.eye(3), shift, axis=0)


def load_trc(path: str | os.PathLike, *, up: str = "y", names: str = "file") -> Markers:
    """The markers of a TRC file, in metres, in pinrecon's Z-up world (see the module doc).

    up : the file's up axis (``"y"``: OpenSim's and Pose2Sim's convention).
    names : ``"file"`` (as written) or ``"pinrecon"`` (:data:`POSE2SIM_NAMES` renamed).

    Raises :class:`~pinrecon.errors.InputError` naming the file, the header field or the
    frame of anything it cannot read."""
    path = Path(path)
    if names not in ("file", "pinrecon"):
        raise InputError(f"must be 'file' or 'pinrecon', got {names!r}", field="names")
    R = z_up_rotation(up)
    rows = read_text(path, errors="replace").splitlines()
    if len(rows) < 5 or not rows[0].startswith("PathFileType"):
        raise InputError("not a TRC file: the first line does not start with PathFileType", file=path,
                         field="PathFileType")
    keys, values = rows[1].split("\t"), rows[2].split("\t")
    header = {k.strip(): v.strip() for k, v in zip(keys, values)}
    rate = _header_number(header, "DataRate", path)
    n_frames = int(_header_number(header, "NumFrames", path))
    n_markers = int(_header_number(header, "NumMarkers", path))
    unit = header.get("Units", "")
    if unit not in _UNITS:
        raise InputError(f"unknown unit {unit!r}: expected one of {', '.join(_UNITS)}", file=path, field="Units")
    cells = rows[3].split("\t")
    if len(cells) < 2 or cells[0].strip() != "Frame#":
        raise InputError("the fourth line should name the columns, starting with Frame# and Time", file=path,
                         field="Frame#")
    marker_names = [c.strip() for c in cells[2:] if c.strip()]
    if len(marker_names) != n_markers:
        raise InputError(f"NumMarkers says {n_markers}, the names line has {len(marker_names)}", file=path,
                         field="NumMarkers")
    if len(set(marker_names)) != len(marker_names):
        dup = next(n for n in marker_names if marker_names.count(n) > 1)
        raise InputError(f"marker {dup!r} is named twice", file=path, field="names")
    data = [(i, r) for i, r in enumerate(rows[5:], start=6) if r.strip()]  # (line number, row)
    if len(data) != n_frames:
        raise InputError(f"NumFrames says {n_frames}, the file has {len(data)} rows of data", file=path,
                         field="NumFrames")
    X = np.full((n_frames, n_markers, 3), np.nan)
    for t, (line, row) in enumerate(data):
        fields = row.split("\t")[2 : 2 + 3 * n_markers]
        try:
            vals = [float(f) if f.strip() else math.nan for f in fields]
        except ValueError:
            k = next(k for k, f in enumerate(fields) if f.strip() and not _is_number(f))
            raise InputError(f"not a number: {fields[k].strip()!r} (line {line}, marker {marker_names[k // 3]!r})",
                             file=path, field="coordinates", frame=t) from None
        X[t].flat[: len(vals)] = vals
        big = [k for k, v in enumerate(vals) if not abs(v) <= MAX_MARKER_M / _UNITS[unit] and not math.isnan(v)]
        if big:
            raise InputError(f"{fields[big[0]].strip()!r} is not a position (line {line}, marker "
                             f"{marker_names[big[0] // 3]!r})", file=path, field="coordinates", frame=t)
    X = (X * _UNITS[unit]) @ R.T
    if names == "pinrecon":
        marker_names = [POSE2SIM_NAMES.get(n, n) for n in marker_names]
        if len(set(marker_names)) != len(marker_names):
            raise InputError("renamed, two markers would share a name; give names='file'", file=path, field="names")
    return Markers(X, marker_names, rate, str(path))


def write_trc(path: str | os.PathLike, markers: Markers, *, up: str = "y", names: str = "file",
              precision: int = 6) -> Path:
    """Write ``markers`` (metres, pinrecon's Z-up world) as a TRC file in metres whose up axis
    is ``up`` (``"y"``: OpenSim's; the inverse of :func:`load_trc`'s rotation, so that
    ``load_trc(write_trc(p, m))`` gives ``m`` back). ``names="pose2sim"`` writes pinrecon's
    names of :data:`POSE2SIM_NAMES` as Pose2Sim's (``right_shoulder`` -> ``RShoulder``), so
    that Pose2Sim's OpenSim models find their markers; ``"file"`` keeps ``markers.names``.
    Missing points are written as empty fields; ``precision`` decimals of a metre. The file
    appears whole or not at all. Returns the path."""
    if names not in ("file", "pose2sim"):
        raise InputError(f"must be 'file' or 'pose2sim', got {names!r}", field="names")
    R = z_up_rotation(up)
    path = Path(path)
    out = list(markers.names)
    if names == "pose2sim":
        back = {v: k for k, v in POSE2SIM_NAMES.items()}
        out = [back.get(n, n) for n in out]
    bad = next((n for n in out if not n or any(c in n for c in "\t\r\n")), None)
    if bad is not None:
        raise InputError(f"a marker name must be non-empty text without tabs or line breaks: {bad!r}", file=path,
                         field="names")
    X = markers.points @ R  # the inverse rotation: p_file = R^T p
    T, K = markers.points.shape[:2]
    lines = [
        f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
        f"{markers.fps:g}\t{markers.fps:g}\t{T}\t{K}\tm\t{markers.fps:g}\t1\t{T}",
        "Frame#\tTime\t" + "\t".join(f"{n}\t\t" for n in out),
        "\t\t" + "\t".join(f"X{k + 1}\tY{k + 1}\tZ{k + 1}" for k in range(K)),
        "",
    ]
    for t in range(T):
        vals = ["" if not np.isfinite(v) else f"{v:.{precision}f}" for v in X[t].ravel()]
        lines.append(f"{t + 1}\t{t / markers.fps:.{max(precision, 6)}f}\t" + "\t".join(vals))
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, "\n".join(lines) + "\n")
    return path


def _header_number(header: dict, key: str, path: Path) -> float:
    try:
        v = float(header[key])
    except KeyError:
        raise InputError(f"the header has no {key}", file=path, field=key) from None
    except ValueError:
        raise InputError(f"not a number: {header[key]!r}", file=path, field=key) from None
    if not (math.isfinite(v) and v > 0):
        raise InputError(f"must be above 0, got {header[key]!r}", file=path, field=key)
    return v


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True
