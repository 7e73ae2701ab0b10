"""COCO keypoint JSON: a dataset file (``images`` + ``annotations`` + ``categories``) or a
results list (``[{"image_id", "keypoints", "score"}, ...]``), read as tracks.

Frames are the images in increasing ``image_id`` order (or, for a dataset file, the
order of ``images``). One person per frame: the annotation with the highest ``score``
(results) or largest ``area`` (dataset). Visibility ``v = 0`` means missing; for
results the third value is a confidence.

:func:`read_coco` returns plain :class:`~pinrecon.io.track_arrays.TrackArrays` (no frame
rate); :func:`pinrecon.load_tracks` ``(path, fps=...)`` makes the ``Tracks``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from .jsonfile import read_json
from .track_arrays import TrackArrays

__all__ = ["read_coco", "is_coco_json", "COCO_17"]

COCO_17 = [
    "nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder",
    "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hip",
    "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
]


def is_coco_json(path: str | os.PathLike) -> bool:
    """A COCO file is a JSON list, or an object with a top-level 'annotations' key.

    The whole file is parsed: real COCO files list thousands of ``images`` before
    ``annotations``, so a look at the first bytes is not enough.
    """
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return False
    return isinstance(data, list) or (isinstance(data, dict) and "annotations" in data)


def read_coco(path: str | os.PathLike) -> TrackArrays:
    """Parse a COCO dataset file or results list (see the module docstring); ``fps`` is None."""
    path = Path(path)
    data = read_json(path)
    names = COCO_17
    if isinstance(data, list):
        anns, results = data, True
        image_ids = sorted({a.get("image_id") for a in anns if isinstance(a, dict)}, key=lambda x: (str(type(x)), x))
    elif isinstance(data, dict) and "annotations" in data:
        anns, results = data["annotations"], False
        cats = data.get("categories") or []
        for c in cats:
            if isinstance(c, dict) and c.get("keypoints"):
                names = [str(n) for n in c["keypoints"]]
                break
        images = data.get("images")
        if images:
            image_ids = [im.get("id") for im in images]
        else:
            image_ids = sorted({a.get("image_id") for a in anns})
    else:
        raise InputError("expected a COCO dataset object or a results list", file=path)
    K = len(names)
    frame_of = {iid: t for t, iid in enumerate(image_ids)}
    T = len(image_ids)
    pts = np.full((T, K, 2), np.nan)
    conf = np.zeros((T, K))
    best = np.full(T, -np.inf)
    for i, a in enumerate(anns):
        fld = f"annotations[{i}]" if not results else f"[{i}]"
        if not isinstance(a, dict) or "image_id" not in a or "keypoints" not in a:
            raise InputError("needs 'image_id' and 'keypoints'", file=path, field=fld)
        t = frame_of.get(a["image_id"])
        if t is None:
            raise InputError(f"image_id {a['image_id']!r} is not in 'images'", file=path, field=fld)
        kp = a["keypoints"]
        if not isinstance(kp, list) or len(kp) != 3 * K:
            raise InputError(f"expected {3 * K} numbers (x, y, v for {K} points)", file=path, field=f"{fld}.keypoints", frame=t)
        try:
            arr = np.asarray(kp, dtype=float).reshape(K, 3)
        except (TypeError, ValueError):
            raise InputError("non-numeric keypoints", file=path, field=f"{fld}.keypoints", frame=t) from None
        rank = float(a.get("score", 0.0)) if results else float(a.get("area", 0.0))
        if rank <= best[t]:
            continue
        best[t] = rank
        vis = arr[:, 2]
        c = np.clip(vis, 0.0, 1.0) if results else (vis > 0).astype(float)
        p = arr[:, :2].copy()
        p[vis <= 0] = np.nan
        pts[t], conf[t] = p, c
    return TrackArrays(pts, names, None, conf, str(path))
