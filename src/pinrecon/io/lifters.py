"""Other lifters' 3D output as files, read into plain :class:`~pinrecon.io.track_arrays.LiftedArrays`
(:func:`pinrecon.lifted.load_lifted` validates them into a :class:`pinrecon.lifted.Lifted`).

Two formats (``docs/formats.md``, section 11):

* **MotionBERT / VideoPose3D** ``.npy``: one float array (T, 17, 3), Human3.6M-17 joint
  order (:data:`H36M_17_ORDER`). MotionBERT's ``infer_wild.py`` saves ``X3D.npy``: x right
  and y down as the image (scaled to [-1, 1], or pixels with ``--pixel``), z the depth away
  from the camera in the same scale, pelvis depth 0 in frame 0. VideoPose3D's
  ``run.py --viz-export`` saves the prediction "in camera space": metres, x right, y down,
  z forward, pelvis at the origin. Both are the camera's axes: ``frame="camera"``.
* **MMPose's 3D inferencer** JSON (``MMPoseInferencer(pose3d=...)`` with ``pred_out_dir``
  on a video): ``[{"frame_id": t, "instances": [{"keypoints": [[X, Y, Z] x 17],
  "keypoint_scores": [17], "bbox": ..., "bbox_score": ...}, ...]}, ...]`` (or the instance
  lists of ``{"predictions": [...]}``), the instances in the order of their track ids
  (the inferencer sorts them so; the file does not carry the ids). MMPose turns its lifter's camera-frame output into
  ``X = -x, Y = z, Z = -y`` and shifts Z so that the lowest keypoint is at 0 (a z-up
  display frame, a mirror image of the camera's); the reader turns it back
  (``x = -X, y = -Z, z = Y``), so these too are in the camera's axes.

The joint order is checked (:func:`check_h36m_order`): a file whose joints are not in
Human3.6M-17 order (COCO order, or any other) gives an InputError; name another layout
(``layout=``) or the points themselves (``names=``) for a lifter with another order.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..layouts import H36M_17, get_layout
from .jsonfile import read_json
from .track_arrays import LiftedArrays

__all__ = ["H36M_17_ORDER", "LIFTER_FORMATS", "check_h36m_order", "read_lifter_npy", "read_mmpose3d",
           "guess_lifter_format", "MMPOSE_TO_CAMERA"]

LIFTER_FORMATS = ("npy", "motionbert", "videopose3d", "mmpose3d")

#: the Human3.6M-17 joints as MotionBERT, VideoPose3D and MMPose order them (MMPose's names)
H36M_17_ORDER = ("root", "right_hip", "right_knee", "right_foot", "left_hip", "left_knee", "left_foot", "spine",
                 "thorax", "neck_base", "head", "left_shoulder", "left_elbow", "left_wrist", "right_shoulder",
                 "right_elbow", "right_wrist")

#: camera axes from MMPose's 3D display axes: ``p_cam = MMPOSE_TO_CAMERA @ p_mmpose``
MMPOSE_TO_CAMERA = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

# Human3.6M-17 indices (H36M_17_ORDER)
_PELVIS, _RHIP, _RKNEE, _RANKLE, _LHIP, _LKNEE, _LANKLE, _SPINE, _THORAX = range(9)
_LSHO, _LELB, _LWRI, _RSHO, _RELB, _RWRI = 11, 12, 13, 14, 15, 16
#: left and right bones that must have about the same length
_PAIRS = (((_LHIP, _LKNEE), (_RHIP, _RKNEE), "thigh"), ((_LKNEE, _LANKLE), (_RKNEE, _RANKLE), "shin"),
          ((_LSHO, _LELB), (_RSHO, _RELB), "upper arm"), ((_LELB, _LWRI), (_RELB, _RWRI), "forearm"),
          ((_PELVIS, _LHIP), (_PELVIS, _RHIP), "pelvis to hip"), ((_THORAX, _LSHO), (_THORAX, _RSHO),
                                                                   "thorax to shoulder"))
_SYMMETRY = 1.5  # a left bone at most 1.5 times its right one, and the other way round


def _length(points, a, b):
    """Median over frames of the distance between joints a and b."""
    d = np.linalg.norm(points[:, a] - points[:, b], axis=-1)
    d = d[np.isfinite(d)]
    return float(np.median(d)) if d.size else np.nan


def check_h36m_order(points: np.ndarray, *, file=None, field="keypoints") -> None:
    """An InputError when (T, 17, 3) points cannot be in Human3.6M-17 order: a left bone
    (thigh, shin, upper arm, forearm, pelvis to hip, thorax to shoulder) more than 1.5
    times its right one or less than 1/1.5 of it (medians over frames), the pelvis farther
    from the hips' midpoint than half the pelvis-thorax distance, or the spine point off
    the pelvis-thorax line (the path through it more than 1.5 times the straight one).
    A left/right exchange keeps every length and cannot be told from them."""
    pts = np.asarray(points, float)
    torso = _length(pts, _PELVIS, _THORAX)
    why = []
    for left, right, name in _PAIRS:
        a, b = _length(pts, *left), _length(pts, *right)
        if not (a <= _SYMMETRY * b and b <= _SYMMETRY * a):
            why.append(f"left {name} {a:.3g} but right {name} {b:.3g}")
    mid = np.linalg.norm(pts[:, _PELVIS] - 0.5 * (pts[:, _LHIP] + pts[:, _RHIP]), axis=-1)
    mid = float(np.median(mid[np.isfinite(mid)])) if np.isfinite(mid).any() else np.nan
    if not mid <= 0.5 * torso:
        why.append(f"pelvis {mid:.3g} from the hips' midpoint, pelvis to thorax {torso:.3g}")
    bent = _length(pts, _PELVIS, _SPINE) + _length(pts, _SPINE, _THORAX)
    if not bent <= 1.5 * torso:
        why.append(f"pelvis-spine-thorax {bent:.3g} against pelvis-thorax {torso:.3g}")
    if why:
        raise InputError(
            "the joints are not in Human3.6M-17 order (" + "; ".join(why) + "): name the lifter's "
            "layout (layout=, --lifted-layout) or its points (names=)", file=file, field=field)


def _names(n_points: int, layout, names, file, field) -> tuple[list[str], bool]:
    """The point names of a lifter's file and whether the H36M order is to be checked."""
    if names is not None:
        names = [str(n) for n in names]
        if len(names) != n_points:
            raise InputError(f"{len(names)} names given for {n_points} joints", file=file, field=field)
        return names, False
    lay = get_layout("h36m17" if layout is None else layout)
    if lay.n_points != n_points:
        raise InputError(f"expected {lay.n_points} joints per frame ({lay.title}), got {n_points}", file=file,
                         field=field)
    return list(lay.names), lay.names == H36M_17


def _finite(points: np.ndarray, names, file, field) -> None:
    bad = np.argwhere(~np.isfinite(points))
    if bad.size:
        t, k = int(bad[0, 0]), int(bad[0, 1])
        raise InputError(f"NaN or infinite coordinate of {names[k]!r}", file=file, field=field, frame=t)


def read_lifter_npy(path: str | os.PathLike, *, layout=None, names=None, source: str | None = None) -> LiftedArrays:
    """A MotionBERT / VideoPose3D ``.npy`` (T, 17, 3) (a leading axis of 1 is dropped), in
    the camera's axes. ``layout`` (default ``"h36m17"``) or ``names`` give the joint order."""
    path = Path(path)
    try:
        arr = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise InputError(f"not a NumPy .npy array ({exc})", file=path) from None
    if isinstance(arr, np.lib.npyio.NpzFile):
        with arr:
            keys = list(arr.files)
            if len(keys) != 1:
                raise InputError(f"an .npz with one array expected, got {keys}", file=path)
            arr = arr[keys[0]]
    if arr.dtype.kind not in "iuf":
        raise InputError(f"must be a numeric array, got dtype {arr.dtype}", file=path, field="points")
    while arr.ndim > 3 and arr.shape[0] == 1:
        arr = arr[0]
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise InputError(f"expected shape (T, joints, 3), got {arr.shape}", file=path, field="points")
    pts = arr.astype(float)
    point_names, check = _names(pts.shape[1], layout, names, path, "points")
    _finite(pts, point_names, path, "points")
    if check:
        check_h36m_order(pts, file=path, field="points")
    return LiftedArrays(pts, point_names, None, "camera", source or str(path), 0)


def _instances(data, path) -> list[tuple[int, object, str]]:
    """[(frame index, instances, field)] of MMPose's frame list or ``predictions``."""
    if isinstance(data, dict) and isinstance(data.get("predictions"), list):
        return [(t, p, f"predictions[{t}]") for t, p in enumerate(data["predictions"])]
    if isinstance(data, dict) and isinstance(data.get("instance_info"), list):
        data = data["instance_info"]
    if not isinstance(data, list) or not all(isinstance(d, dict) and "instances" in d for d in data):
        raise InputError("not MMPose 3D output (a list of {frame_id, instances}, or {predictions: [...]})",
                         file=path)
    ids = [d.get("frame_id", i) for i, d in enumerate(data)]
    if not all(type(i) is int for i in ids):
        raise InputError("frame_id must be integers", file=path, field="frame_id")
    lo = min(ids, default=0)
    if sorted(ids) != list(range(lo, lo + len(ids))):
        raise InputError(f"frame_id must run {lo}, {lo + 1} ... without gaps or repeats", file=path,
                         field="frame_id")
    return [(i - lo, d["instances"], f"[{n}].instances") for n, (i, d) in enumerate(zip(ids, data))]


def read_mmpose3d(path: str | os.PathLike, *, person: int = 0, layout=None, names=None,
                  source: str | None = None) -> LiftedArrays:
    """MMPose's 3D inferencer JSON (see the module docstring), turned back to the camera's
    axes. One person is followed: ``person`` (default 0) indexes the instances of each
    frame (MMPose writes them in track order), or, when the instances carry a ``track_id``
    (scripts that add it), the track of that instance in the first frame with anyone is
    followed. Frames without the person are missing (NaN, confidence 0)."""
    path = Path(path)
    items = _instances(read_json(path), path)
    T = len(items)
    if T == 0:
        raise InputError("no frames", file=path)
    pts = cnf = point_names = check = None
    track = None
    for t, instances, fld in sorted(items, key=lambda x: x[0]):
        if not isinstance(instances, list):
            raise InputError("must be a list of instances", file=path, field=fld, frame=t)
        if not instances:
            continue
        if track is None:  # the first frame with people fixes whom to follow
            if not 0 <= person < len(instances):
                raise InputError(f"person {person} asked, the first frame with people has {len(instances)}",
                                 file=path, field=fld, frame=t)
            track = instances[person].get("track_id") if isinstance(instances[person], dict) else None
            pick = person
        else:
            ids = [i.get("track_id") if isinstance(i, dict) else None for i in instances]
            pick = ids.index(track) if track is not None and track in ids else (
                person if track is None and person < len(instances) else None)
            if pick is None:
                continue
        inst, ifld = instances[pick], f"{fld}[{pick}]"
        kp = inst.get("keypoints") if isinstance(inst, dict) else None
        if isinstance(kp, list) and len(kp) == 1 and isinstance(kp[0], list) and kp[0] and isinstance(kp[0][0], list):
            kp = kp[0]  # one instance's (1, K, 3)
        try:
            xyz = np.array(kp, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise InputError("must be a list of [X, Y, Z] numbers", file=path, field=f"{ifld}.keypoints",
                             frame=t) from None
        if xyz.ndim != 2 or xyz.shape[1] != 3:
            raise InputError(f"expected [X, Y, Z] per keypoint, got shape {xyz.shape}", file=path,
                             field=f"{ifld}.keypoints", frame=t)
        if pts is None:
            point_names, check = _names(xyz.shape[0], layout, names, path, f"{ifld}.keypoints")
            pts = np.full((T, len(point_names), 3), np.nan)
            cnf = np.zeros((T, len(point_names)))
        if xyz.shape[0] != len(point_names):
            raise InputError(f"expected {len(point_names)} keypoints, got {xyz.shape[0]}", file=path,
                             field=f"{ifld}.keypoints", frame=t)
        _finite(xyz[None], point_names, path, f"{ifld}.keypoints")
        scores = inst.get("keypoint_scores", [1.0] * len(point_names))
        if isinstance(scores, list) and len(scores) == 1 and isinstance(scores[0], list):
            scores = scores[0]
        try:
            sc = np.array(scores, dtype=float)
        except (TypeError, ValueError, OverflowError):
            sc = None
        if sc is None or sc.shape != (len(point_names),):
            raise InputError(f"must be {len(point_names)} numbers, one per keypoint", file=path,
                             field=f"{ifld}.keypoint_scores", frame=t)
        pts[t] = xyz @ MMPOSE_TO_CAMERA.T
        cnf[t] = sc
    if pts is None:
        raise InputError("no person in any frame", file=path)
    if check:
        check_h36m_order(pts, file=path, field="keypoints")
    return LiftedArrays(pts, point_names, cnf, "camera", source or str(path), 0)


def guess_lifter_format(path: str | os.PathLike) -> str:
    """``npy`` for ``.npy`` / ``.npz`` files, ``mmpose3d`` for JSON."""
    suffix = Path(path).suffix.lower()
    if suffix in (".npy", ".npz"):
        return "npy"
    if suffix == ".json":
        return "mmpose3d"
    raise InputError(f"cannot tell the lifter's format from the suffix {suffix!r}: pass the format "
                     f"({', '.join(LIFTER_FORMATS)})", file=path, field="format")
