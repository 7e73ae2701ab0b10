"""OpenPose output: a folder of per-frame JSON files (``*_keypoints.json``), or one file.

Each file holds ``{"people": [{"pose_keypoints_2d": [x0, y0, c0, x1, y1, c1, ...]}]}``.
Pose2Sim and Sports2D write the same files for other detectors (RTMPose Halpe-26 ...).

* Frames are the files in natural order (``frame_2`` before ``frame_10``).
* The layout follows from the number of points per person: BODY_25 and BODY_25B
  (both 25) are told apart by their geometry (:mod:`pinrecon.layouts.detect`), or
  named with ``layout=``; 18 is COCO-18, 26 Halpe-26, 17 COCO-17 ... Point names are
  pinrecon's (:mod:`pinrecon.layouts`). A point with confidence 0 is missing.
* Several people: one subject is followed through the frames
  (:mod:`pinrecon.io.people`); ``person`` picks it.
* A file that cannot be read, or a person entry that is not a list of triples, or has
  another number of points than the rest of the sequence, is a missing frame (or a
  dropped detection), counted in one warning; the load fails only when nothing is left.

:func:`read_openpose` returns plain :class:`~pinrecon.io.track_arrays.TrackArrays` (no
frame rate); :func:`pinrecon.load_tracks` and :func:`pinrecon.io.openpose.load_openpose`
make the ``Tracks``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..layouts import BODY_25 as _BODY_25_NAMES
from ..layouts import COCO_18 as _COCO_18_NAMES
from .detections import Detections, to_track_arrays
from .jsonfile import read_json
from .people import Detection, natural_key
from .track_arrays import TrackArrays

__all__ = ["read_openpose", "openpose_files", "parse_triples", "BODY_25", "COCO_18"]

BODY_25 = list(_BODY_25_NAMES)
COCO_18 = list(_COCO_18_NAMES)


def parse_triples(flat, *, file, field, frame) -> Detection:
    """A detection from a flat ``[x, y, c, ...]`` list; an InputError when it is not one."""
    if not isinstance(flat, list) or len(flat) % 3:
        raise InputError("must be a flat list of x, y, c triples", file=file, field=field, frame=frame)
    if not flat:
        raise InputError("empty: a person without points", file=file, field=field, frame=frame)
    if not all(v is None or (type(v) in (int, float)) for v in flat):
        raise InputError("non-numeric values", file=file, field=field, frame=frame)
    try:
        arr = np.array([np.nan if v is None else v for v in flat], dtype=float).reshape(-1, 3)
    except OverflowError:
        raise InputError("numbers out of range", file=file, field=field, frame=frame) from None
    return Detection.from_values(arr[:, :2], arr[:, 2])


def openpose_files(path: Path) -> list[Path]:
    """The frame files of an OpenPose folder (or the one file), in natural order."""
    if path.is_file():
        return [path]
    files = list(path.glob("*_keypoints.json")) or list(path.glob("*.json"))
    files = [f for f in files if f.is_file()]
    if not files:
        raise InputError("no OpenPose *_keypoints.json files in this folder", file=path)
    return sorted(files, key=lambda f: natural_key(f.name))


def read_openpose(path: str | os.PathLike, *, person=None, layout=None) -> TrackArrays:
    """Parse an OpenPose JSON folder (or one file); ``fps`` is None.

    ``person``: None (the most prominent person of the first frame with people), an
    index in that frame, a box ``(x1, y1, x2, y2)``, or ``"largest"`` (each frame's most
    prominent, not followed). ``layout``: a :mod:`pinrecon.layouts` name, else detected.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("file not found", file=path)
    det = Detections(str(path), "openpose")
    for t, f in enumerate(openpose_files(path)):
        try:
            data = read_json(f, frame=t)
            people = data.get("people") if isinstance(data, dict) else None
            if not isinstance(people, list):
                raise InputError("no 'people' list", file=f, field="people", frame=t)
        except InputError as exc:
            det.broken.append(exc)
            det.add_frame()
            continue
        dets = []
        for i, p in enumerate(people):
            try:
                flat = p.get("pose_keypoints_2d") if isinstance(p, dict) else None
                dets.append(parse_triples(flat, file=f, field=f"people[{i}].pose_keypoints_2d", frame=t))
            except InputError as exc:
                det.dropped.append(exc)
        det.add_frame(dets)
    return to_track_arrays(det, person=person, layout=layout)
