"""MMPose / RTMPose JSON output.

Three shapes, all with instances ``{"keypoints": [[x, y], ...], "keypoint_scores":
[s, ...], "bbox": [[x1, y1, x2, y2]], "bbox_score": s}``:

* ``MMPoseInferencer(..., pred_out_dir=...)`` on a video: ``[{"frame_id": 0,
  "instances": [...]}, ...]``; on an image: the list of instances;
* ``demo/topdown_demo_with_mmdet.py --save-predictions``: ``{"meta_info": {...},
  "instance_info": [{"frame_id": 1, "instances": [...]}, ...]}`` (or the instances of
  one image);
* the inferencer's result dictionary dumped as is: ``{"predictions": [[instances of
  image 0], [instances of image 1], ...]}``.

Frames are the ``frame_id`` values in numeric order, gaps kept as missing frames. The
layout comes from ``meta_info`` (``dataset_name`` or ``keypoint_id2name``) when the file
has it, else from the number of points (geometry decides between layouts with the
same count, see :mod:`pinrecon.layouts`). One subject is followed through the frames
(:mod:`pinrecon.io.people`); unreadable frames and instances are missing frames and
dropped detections, counted in one warning.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..layouts import get_layout
from .detections import Detections, to_track_arrays
from .jsonfile import read_json
from .people import Detection
from .track_arrays import TrackArrays

__all__ = ["read_mmpose", "is_mmpose", "parse_instance"]


def is_mmpose(data) -> bool:
    """Parsed JSON in one of MMPose's shapes (see the module docstring)."""
    if isinstance(data, dict):
        return "instance_info" in data or ("predictions" in data and isinstance(data["predictions"], list))
    if isinstance(data, list) and data and isinstance(data[0], dict):
        return "instances" in data[0] or "keypoint_scores" in data[0]
    return False


def _is_number(v) -> bool:
    return type(v) in (int, float)


def parse_instance(inst, *, file, field, frame) -> Detection:
    """One MMPose instance as a detection; an InputError when it is not one."""
    if not isinstance(inst, dict) or not isinstance(inst.get("keypoints"), list) or not inst["keypoints"]:
        raise InputError("needs a non-empty 'keypoints' list", file=file, field=field, frame=frame)
    kp = inst["keypoints"]
    if not all(isinstance(p, list) and len(p) in (2, 3) and all(_is_number(v) for v in p) for p in kp):
        raise InputError("'keypoints' must be a list of [x, y] pairs", file=file, field=f"{field}.keypoints", frame=frame)
    scores = inst.get("keypoint_scores")
    if scores is None:
        scores = [1.0] * len(kp)
    if isinstance(scores, list) and len(scores) == 1 and isinstance(scores[0], list):
        scores = scores[0]
    if not isinstance(scores, list) or len(scores) != len(kp) or not all(_is_number(v) for v in scores):
        raise InputError(
            f"'keypoint_scores' must be {len(kp)} numbers, one per keypoint",
            file=file, field=f"{field}.keypoint_scores", frame=frame,
        )
    try:
        xy = np.array([p[:2] for p in kp], dtype=float)
        conf = np.array(scores, dtype=float)
    except OverflowError:
        raise InputError("numbers out of range", file=file, field=field, frame=frame) from None
    bbox = inst.get("bbox")
    if isinstance(bbox, list) and len(bbox) == 1 and isinstance(bbox[0], list):
        bbox = bbox[0]
    box = None
    if isinstance(bbox, list) and len(bbox) == 4 and all(_is_number(v) for v in bbox):
        try:
            box = np.array(bbox, dtype=float)
        except OverflowError:
            box = None
        if box is not None and not (box[2] > box[0] and box[3] > box[1]):
            box = None
    score = inst.get("bbox_score")
    if isinstance(score, list) and len(score) == 1:
        score = score[0]
    return Detection.from_values(xy, conf, bbox=box, score=score if _is_number(score) else None)


def _names(meta) -> list[str] | None:
    if not isinstance(meta, dict):
        return None
    id2name = meta.get("keypoint_id2name")
    if isinstance(id2name, dict) and id2name:
        try:
            items = sorted((int(k), v) for k, v in id2name.items())
        except (TypeError, ValueError):
            return None
        if [k for k, _ in items] == list(range(len(items))) and all(isinstance(v, str) for _, v in items):
            return [v for _, v in items]
    return None


def _frames(data) -> tuple[list, dict | None]:
    """[(frame_id, instances, field)] and the meta information of a parsed file."""
    meta = None
    if isinstance(data, dict):
        meta = data.get("meta_info")
        if "instance_info" in data:
            data = data["instance_info"]
        else:
            preds = data["predictions"]
            return [(t, p, f"predictions[{t}]") for t, p in enumerate(preds)], meta
        if not isinstance(data, list):
            return [(0, None, "instance_info")], meta
    if data and all(isinstance(d, dict) and "frame_id" not in d and "instances" not in d for d in data):
        return [(0, data, "instances")], meta
    out = []
    for i, d in enumerate(data):
        fid = d.get("frame_id") if isinstance(d, dict) else None
        out.append((fid, d.get("instances") if isinstance(d, dict) else None, f"[{i}]"))
    return out, meta


def read_mmpose(path: str | os.PathLike, *, person=None, layout=None) -> TrackArrays:
    """Parse an MMPose / RTMPose JSON file (see the module docstring); ``fps`` is None.
    ``person`` and ``layout`` as in :func:`pinrecon.io.openpose_json.read_openpose`."""
    path = Path(path)
    data = read_json(path)
    if not is_mmpose(data):
        raise InputError("not MMPose output (no 'instance_info', 'predictions' or frame list)", file=path)
    items, meta = _frames(data)
    det = Detections(str(path), "mmpose")
    det.names = _names(meta)
    if layout is None and isinstance(meta, dict) and isinstance(meta.get("dataset_name"), str):
        try:
            layout = get_layout(meta["dataset_name"]).name
            det.names = None
        except InputError:
            pass
    ids = [fid for fid, _, _ in items if type(fid) is int and abs(fid) < 10**7]
    lo = min(ids, default=0)
    hi = max(ids, default=-1)
    if hi - lo + 1 > 10 * len(items) + 1000:
        raise InputError(f"frame_id values span {lo}..{hi}: too sparse to be frames of one video", file=path)
    for _ in range(hi - lo + 1):
        det.add_frame()
    for fid, instances, fld in items:
        if type(fid) is not int or not lo <= fid <= hi:
            det.broken.append(InputError(f"frame_id must be an integer, got {fid!r}", file=path, field=f"{fld}.frame_id"))
            continue
        t = fid - lo
        if not isinstance(instances, list):
            det.broken.append(InputError("'instances' must be a list", file=path, field=f"{fld}.instances", frame=t))
            continue
        for i, inst in enumerate(instances):
            try:
                det.frames[t].append(parse_instance(inst, file=path, field=f"{fld}.instances[{i}]" if fld != "instances" else f"[{i}]", frame=t))
            except InputError as exc:
                det.dropped.append(exc)
    if not det.frames:
        first = (det.broken + det.dropped)[:1]
        raise first[0] if first else InputError("no frame", file=path)
    return to_track_arrays(det, person=person, layout=layout)
