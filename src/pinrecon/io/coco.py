"""COCO-style keypoint JSON: a dataset file, a results list, AlphaPose results, boxes.

* **Dataset** (``images`` + ``annotations`` + ``categories``): frames are the images in
  natural order of their ``file_name`` (else of their ``id``). The point names are the
  category's ``keypoints`` (a registered layout when they match one: COCO-17,
  CrowdPose-14, H36M-17 ...), else the layout with that many points (COCO-17 when the
  count matches none). ``v = 0`` is missing. By default each image keeps its largest
  annotation (``area``): a dataset is a collection of images; ``person=`` follows one
  person instead.
* **Results** (``[{"image_id", "keypoints", "score"}, ...]``, as COCO evaluation,
  mmdetection/mmpose ``--dump`` and **AlphaPose** ``alphapose-results.json`` write
  them): frames are the distinct image ids in natural order (``"2.jpg"`` before
  ``"10.jpg"``, numbers as numbers); when every id is a file name with one frame
  number (AlphaPose ``"17.jpg"``), frames without a detection are kept as missing
  frames so that time stays right. The third value of each point is a confidence;
  one subject is followed through the frames (:mod:`pinrecon.io.people`). Only
  ``category_id`` 1 (person) is read when the file has several categories. The layout
  follows from the number of points (17 COCO-17 or H36M-17 by geometry, 26 Halpe-26,
  136 Halpe-136 ...).
* **Boxes only** (results with ``bbox`` ``[x, y, w, h]`` and no ``keypoints``): the
  ``box`` layout, two points ``box_top_left`` and ``box_bottom_right``.

Unreadable annotations are dropped and counted in one warning; the load fails only
when nothing is left. :func:`read_coco` returns plain
:class:`~pinrecon.io.track_arrays.TrackArrays` (no frame rate).
"""

from __future__ import annotations

import os
import re
from collections import Counter
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..layouts import COCO_17 as _COCO_17_NAMES
from ..layouts import layouts_with
from .detections import Detections, to_track_arrays
from .jsonfile import read_json
from .people import Detection, natural_key
from .track_arrays import TrackArrays

__all__ = ["read_coco", "is_coco_json", "coco_kind", "COCO_17"]

COCO_17 = list(_COCO_17_NAMES)


def coco_kind(data) -> str | None:
    """``"dataset"``, ``"results"`` or None for parsed JSON."""
    if isinstance(data, dict) and "annotations" in data:
        return "dataset"
    if isinstance(data, list) and not (data and isinstance(data[0], dict) and ("instances" in data[0] or "keypoint_scores" in data[0])):
        return "results"
    return None


def is_coco_json(path: str | os.PathLike) -> bool:
    """A COCO file is a JSON list (results) or an object with a top-level 'annotations'
    key (dataset). The whole file is parsed: real COCO files list thousands of
    ``images`` before ``annotations``."""
    try:
        data = read_json(path)
    except InputError:
        return False
    return coco_kind(data) is not None


def _hashable_id(value) -> bool:
    return isinstance(value, (int, str)) and not isinstance(value, bool)


def _numbers(kp, n: int, *, file, field, frame) -> np.ndarray:
    if not isinstance(kp, list) or len(kp) != 3 * n:
        raise InputError(f"expected {3 * n} numbers (x, y, v for {n} points)", file=file, field=field, frame=frame)
    if not all(type(v) in (int, float) for v in kp):
        raise InputError("non-numeric keypoints", file=file, field=field, frame=frame)
    try:
        return np.array(kp, dtype=float).reshape(n, 3)
    except OverflowError:
        raise InputError("numbers out of range", file=file, field=field, frame=frame) from None


def _point_count(anns, names) -> int:
    """Points per person: the category's names, else the most common count that a
    registered layout has, else 17 (COCO)."""
    if names:
        return len(names)
    counts = Counter(
        len(a["keypoints"]) // 3
        for a in anns
        if isinstance(a, dict) and isinstance(a.get("keypoints"), list) and len(a["keypoints"]) % 3 == 0
    )
    for n, _ in counts.most_common():
        if layouts_with(n):
            return n
    return 17


def _category_names(data) -> list[str] | None:
    cats = data.get("categories")
    if isinstance(cats, list):
        for c in cats:
            kp = c.get("keypoints") if isinstance(c, dict) else None
            if isinstance(kp, list) and kp and all(isinstance(n, str) for n in kp):
                return list(kp)
    return None


def _box(value) -> np.ndarray | None:
    """COCO ``[x, y, w, h]`` as ``(x1, y1, x2, y2)``, None if not 4 finite numbers."""
    if isinstance(value, list) and len(value) == 1 and isinstance(value[0], list):
        value = value[0]
    if not isinstance(value, list) or len(value) != 4 or not all(type(v) in (int, float) for v in value):
        return None
    try:
        x, y, w, h = (float(v) for v in value)
    except OverflowError:
        return None
    b = np.array([x, y, x + w, y + h])
    return b if np.all(np.isfinite(b)) and w > 0 and h > 0 else None


def _dataset(path: Path, data: dict) -> tuple[Detections, bool]:
    det = Detections(str(path), "coco")
    names = _category_names(data)
    det.names = names
    anns = data["annotations"]
    if not isinstance(anns, list):
        raise InputError("must be a list", file=path, field="annotations")
    images = data.get("images")
    if isinstance(images, list) and images:
        ims = [im for im in images if isinstance(im, dict) and _hashable_id(im.get("id"))]
        if all(isinstance(im.get("file_name"), str) for im in ims):
            ims.sort(key=lambda im: natural_key(im["file_name"]))
        else:
            ims.sort(key=lambda im: natural_key(im["id"]))
        ids = list(dict.fromkeys(im["id"] for im in ims))
    else:
        ids = sorted(
            {a.get("image_id") for a in anns if isinstance(a, dict) and _hashable_id(a.get("image_id"))},
            key=natural_key,
        )
    frame_of = {iid: t for t, iid in enumerate(ids)}
    for _ in ids:
        det.add_frame()
    n = _point_count(anns, names)
    for i, a in enumerate(anns):
        fld = f"annotations[{i}]"
        try:
            if not isinstance(a, dict) or "image_id" not in a or "keypoints" not in a:
                raise InputError("needs 'image_id' and 'keypoints'", file=path, field=fld)
            t = frame_of.get(a["image_id"]) if _hashable_id(a["image_id"]) else None
            if t is None:
                raise InputError(f"image_id {a['image_id']!r} is not in 'images'", file=path, field=fld)
            arr = _numbers(a["keypoints"], n, file=path, field=f"{fld}.keypoints", frame=t)
        except InputError as exc:
            det.dropped.append(exc)
            continue
        area = a.get("area")
        det.frames[t].append(
            Detection.from_values(arr[:, :2], (arr[:, 2] > 0).astype(float), bbox=_box(a.get("bbox")), score=area)
        )
    return det, False


_FRAME_NAME = re.compile(r"^(\D*)(\d+)(\D*)$")


def _result_frames(ids: list) -> list:
    """The frames of a results file: its distinct ids in natural order, with the gaps
    filled (as ``None``) when every id is a file name with one frame number."""
    ids = sorted(set(ids), key=natural_key)
    if ids and all(isinstance(i, str) for i in ids):
        m = [_FRAME_NAME.match(i) for i in ids]
        if all(m) and len({(x.group(1), x.group(3)) for x in m}) == 1:
            num = {int(x.group(2)): i for x, i in zip(m, ids)}
            lo, hi = min(num), max(num)
            if hi - lo + 1 <= 10 * len(ids) + 1000:
                return [num.get(k) for k in range(lo, hi + 1)]
    return ids


def _results(path: Path, data: list) -> tuple[Detections, bool]:
    det = Detections(str(path), "coco")
    entries = [(i, a) for i, a in enumerate(data) if isinstance(a, dict)]
    if any(a.get("category_id") == 1 for _, a in entries):
        entries = [(i, a) for i, a in entries if a.get("category_id", 1) == 1]
    box_only = bool(entries) and not any("keypoints" in a for _, a in entries)
    kept = {i for i, _ in entries}
    ids = [a.get("image_id") for _, a in entries if _hashable_id(a.get("image_id"))]
    frames = _result_frames(ids)
    frame_of = {iid: t for t, iid in enumerate(frames) if iid is not None}
    for _ in frames:
        det.add_frame()
    n = 2 if box_only else _point_count([a for _, a in entries], None)
    for i, a in enumerate(data):
        fld = f"[{i}]"
        try:
            if not isinstance(a, dict):
                raise InputError("must be an object", file=path, field=fld)
            if i not in kept:
                continue
            if "image_id" not in a or ("bbox" if box_only else "keypoints") not in a:
                raise InputError(f"needs 'image_id' and '{'bbox' if box_only else 'keypoints'}'", file=path, field=fld)
            t = frame_of.get(a["image_id"]) if _hashable_id(a["image_id"]) else None
            if t is None:
                raise InputError(f"image_id must be a number or a string, got {a['image_id']!r}", file=path, field=fld)
            score = a.get("score")
            if box_only:
                b = _box(a["bbox"])
                if b is None:
                    raise InputError("bbox must be [x, y, w, h] with w, h > 0", file=path, field=f"{fld}.bbox", frame=t)
                s = float(score) if type(score) is float or (type(score) is int and abs(score) < 2**53) else 1.0
                d = Detection.from_values(b.reshape(2, 2), [s, s], bbox=b, score=score)
            else:
                arr = _numbers(a["keypoints"], n, file=path, field=f"{fld}.keypoints", frame=t)
                d = Detection.from_values(arr[:, :2], arr[:, 2], bbox=_box(a.get("box", a.get("bbox"))), score=score)
        except InputError as exc:
            det.dropped.append(exc)
            continue
        det.frames[t].append(d)
    return det, box_only


def read_coco(path: str | os.PathLike, *, person=None, layout=None) -> TrackArrays:
    """Parse a COCO dataset file, a results list (COCO, AlphaPose) or a boxes-only
    results list (see the module docstring); ``fps`` is None. ``person`` and
    ``layout`` as in :func:`pinrecon.io.openpose_json.read_openpose` (a dataset file
    keeps each image's largest annotation unless ``person`` is given)."""
    path = Path(path)
    data = read_json(path)
    kind = coco_kind(data)
    if kind == "dataset":
        det, box_only = _dataset(path, data)
        if person is None:
            person = "largest"
    elif kind == "results":
        det, box_only = _results(path, data)
    else:
        raise InputError("expected a COCO dataset object or a results list", file=path)
    if not det.frames:
        raise InputError("no image and no annotation", file=path)
    return to_track_arrays(det, person=person, layout=layout, box_only=box_only)

