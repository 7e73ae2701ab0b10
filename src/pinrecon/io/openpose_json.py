"""OpenPose output folders: one ``*_keypoints.json`` per frame.

Each file holds ``{"people": [{"pose_keypoints_2d": [x0, y0, c0, x1, y1, c1, ...]}]}``.
BODY_25 (25 points) and COCO-18 (18 points) layouts are recognised; point names follow
pinrecon's COCO-17 names where the point is a COCO point (``nose``, ``left_eye`` ...)
and snake_case names otherwise (``neck``, ``mid_hip``, ``left_big_toe`` ...). A point
with confidence 0 is missing; a frame without people is all missing.

:func:`read_openpose` returns plain :class:`~pinrecon.io.track_arrays.TrackArrays` (no
frame rate); :func:`pinrecon.load_tracks` and :func:`pinrecon.io.openpose.load_openpose`
make the ``Tracks``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from .jsonfile import read_json
from .track_arrays import TrackArrays

__all__ = ["read_openpose", "BODY_25", "COCO_18"]

BODY_25 = [
    "nose", "neck", "right_shoulder", "right_elbow", "right_wrist", "left_shoulder",
    "left_elbow", "left_wrist", "mid_hip", "right_hip", "right_knee", "right_ankle",
    "left_hip", "left_knee", "left_ankle", "right_eye", "left_eye", "right_ear", "left_ear",
    "left_big_toe", "left_small_toe", "left_heel", "right_big_toe", "right_small_toe", "right_heel",
]
COCO_18 = [
    "nose", "neck", "right_shoulder", "right_elbow", "right_wrist", "left_shoulder",
    "left_elbow", "left_wrist", "right_hip", "right_knee", "right_ankle", "left_hip",
    "left_knee", "left_ankle", "right_eye", "left_eye", "right_ear", "left_ear",
]
_LAYOUTS = {25: BODY_25, 18: COCO_18}


def read_openpose(folder: str | os.PathLike, *, person: int = 0) -> TrackArrays:
    """Parse an OpenPose JSON folder (files sorted by name); ``fps`` is None.

    ``person`` selects which detected person of each frame to keep (OpenPose's order).
    """
    folder = Path(folder)
    files = sorted(folder.glob("*_keypoints.json")) or sorted(folder.glob("*.json"))
    if not files:
        raise InputError("no OpenPose *_keypoints.json files in this folder", file=folder)
    rows, confs, layout = [], [], None
    for t, f in enumerate(files):
        data = read_json(f, frame=t)
        people = data.get("people") if isinstance(data, dict) else None
        if people is None:
            raise InputError("no 'people' list", file=f, field="people", frame=t)
        if len(people) <= person:
            rows.append(None)
            confs.append(None)
            continue
        flat = people[person].get("pose_keypoints_2d")
        if not isinstance(flat, list) or len(flat) % 3:
            raise InputError("must be a flat list of x, y, c triples", file=f, field="pose_keypoints_2d", frame=t)
        n = len(flat) // 3
        if n not in _LAYOUTS:
            raise InputError(
                f"{n} points: only BODY_25 (25) and COCO-18 (18) layouts are known",
                file=f,
                field="pose_keypoints_2d",
                frame=t,
            )
        if layout is None:
            layout = n
        elif layout != n:
            raise InputError(f"{n} points but earlier frames had {layout}", file=f, field="pose_keypoints_2d", frame=t)
        try:
            arr = np.asarray(flat, dtype=float).reshape(n, 3)
        except (TypeError, ValueError):
            raise InputError("non-numeric values", file=f, field="pose_keypoints_2d", frame=t) from None
        rows.append(arr[:, :2])
        confs.append(arr[:, 2])
    if layout is None:
        raise InputError(f"no frame has person {person}", file=folder, field="people")
    names = _LAYOUTS[layout]
    T, K = len(files), len(names)
    pts = np.full((T, K, 2), np.nan)
    conf = np.zeros((T, K))
    for t, (r, c) in enumerate(zip(rows, confs)):
        if r is not None:
            pts[t], conf[t] = r, c
    pts[conf <= 0] = np.nan
    return TrackArrays(pts, names, None, conf, str(folder))
