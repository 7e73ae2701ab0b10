"""BVH: read any BVH file as a pinrecon figure and its motion (configurations), and
write motion back as BVH.

The file format itself (parsing, writing text) is :mod:`pinrecon.io.bvh_format`; the
figure built from a skeleton is described in :mod:`pinrecon.figure_bvh` (and
``docs/formats.md``, "BVH figures"); figures that did not come from a BVH file are
converted by :func:`pinrecon.io.bvh_urdf.urdf_figure_to_bvh`. This module joins them:
it imports the domain type :class:`pinrecon.Figure`; figure.py never imports it.

Motion: root position and rotation channels become the free-flyer pose ``q[:7]``; every
other channel is one joint value (radians, or metres for position channels), so the
conversion is exact both ways.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..figure import Figure
from ..rotations import continuous_euler, euler_to_matrix, matrix_to_euler, matrix_to_quat_xyzw, quat_xyzw_to_matrix
from .bvh_format import BvhClip, BvhJoint, read_bvh, static_joints, write_bvh_text
from .bvh_urdf import urdf_figure_to_bvh

__all__ = [
    "BvhJoint",
    "BvhClip",
    "BvhMotion",
    "read_bvh",
    "figure_from_bvh",
    "motion_from_bvh",
    "load_bvh",
    "static_joints",
    "write_bvh",
    "euler_to_matrix",
    "matrix_to_euler",
]


def figure_from_bvh(clip: BvhClip, length_scale: float = 1.0, *, lock: Iterable[str] | str = ()) -> Figure:
    """Build a :class:`pinrecon.Figure` from a parsed BVH skeleton
    (:meth:`pinrecon.Figure.from_bvh_clip`; construction in :mod:`pinrecon.figure_bvh`).

    Parameters
    ----------
    clip : parsed BVH (:func:`read_bvh`).
    length_scale : metres per file unit (CMU files: 0.056444).
    lock : BVH joint names whose channels are welded at zero (fixed joints), or
        ``"static"`` for every joint :func:`static_joints` finds.
    """
    return Figure.from_bvh_clip(clip, length_scale, lock=lock)


def motion_from_bvh(figure, clip: BvhClip) -> np.ndarray:
    """The clip's motion as configurations (frames, nq) of ``figure`` (built from ``clip``).

    Keypoint positions of the result reproduce the BVH joint positions exactly (up to
    floating point). Locked joints must be zero in every frame.
    """
    meta = figure.meta.get("bvh")
    if meta is None or meta["names"] != clip.names:
        raise InputError("figure was not built from this BVH skeleton", file=clip.path, field="figure")
    scale = meta["length_scale"]
    lock = set(meta["lock"])
    F = clip.n_frames
    Q = np.tile(figure.neutral(), (F, 1))
    cols = clip.channel_columns()
    root = clip.joints[0]
    block = clip.values[:, cols[0]]
    pos = np.tile(np.asarray(root.offset, float), (F, 1))
    rot_axes, rot_idx = "", []
    for k, ch in enumerate(root.channels):
        if ch.endswith("position"):
            pos[:, "XYZ".index(ch[0])] += block[:, k]
        else:
            rot_axes += ch[0]
            rot_idx.append(k)
    R = euler_to_matrix(rot_axes, block[:, rot_idx]) if rot_axes else np.broadcast_to(np.eye(3), (F, 3, 3))
    Q[:, :3] = pos * scale
    Q[:, 3:7] = matrix_to_quat_xyzw(R)
    for j, c in zip(clip.joints[1:], cols[1:]):
        block = clip.values[:, c]
        if j.name in lock:
            bad = np.where(np.any(np.abs(block) > 1e-9, axis=1))[0]
            if bad.size:
                raise InputError(
                    f"joint {j.name!r} is locked but its channels are non-zero",
                    file=clip.path,
                    field=j.name,
                    frame=int(bad[0]),
                )
            continue
        for k, ch in enumerate(j.channels):
            qs, _ = figure.joint_slices(f"{j.name}_{ch}")
            Q[:, qs.start] = np.radians(block[:, k]) if ch.endswith("rotation") else block[:, k] * scale
    return Q


@dataclass
class BvhMotion:
    """A BVH file loaded as a figure and its motion: ``q`` (frames, nq) at ``fps``."""

    figure: object
    q: np.ndarray
    fps: float
    clip: BvhClip

    @property
    def times(self) -> np.ndarray:
        return np.arange(self.q.shape[0]) / self.fps

    def keypoints(self) -> np.ndarray:
        return self.figure.keypoints(self.q)


def load_bvh(
    path: str | os.PathLike,
    length_scale: float = 1.0,
    *,
    lock: Iterable[str] | str = (),
    skip_frames: int = 0,
) -> BvhMotion:
    """Read a BVH file into a figure and its motion.

    Parameters
    ----------
    length_scale : metres per file unit (CMU: 0.056444).
    lock : joints to weld (must be zero in every frame), or ``"static"`` to lock every
        joint that :func:`static_joints` finds.
    skip_frames : frames to drop at the start (1 for the CMU T-pose frame of cgspeed files).
    """
    clip = read_bvh(path)
    if isinstance(lock, str):
        if lock != "static":
            raise InputError(f"lock must be a list of joint names or 'static', got {lock!r}", field="lock")
        lock = static_joints(clip)
    if skip_frames:
        clip = BvhClip(clip.joints, clip.frame_time, clip.values[skip_frames:], clip.path)
    figure = figure_from_bvh(clip, length_scale, lock=lock)
    return BvhMotion(figure, motion_from_bvh(figure, clip), clip.fps, clip)


# ---------------------------------------------------------------------------- writing
def write_bvh(path: str | os.PathLike, figure, q: np.ndarray, fps: float) -> None:
    """Write motion ``q`` (frames, nq) of ``figure`` as BVH, atomically.

    A figure built from a BVH writes back with its original joint names, channel orders,
    offsets and end sites, in its own length unit. Other figures are converted by
    :func:`pinrecon.io.bvh_urdf.urdf_figure_to_bvh`. Values are written with 9 decimals
    so positions survive the round trip to well below 1e-6 m.
    """
    q = np.asarray(q, float)
    if q.ndim != 2 or q.shape[1] != figure.nq:
        raise InputError(f"expected q of shape (frames, {figure.nq}), got {q.shape}", file=path, field="q")
    if not (fps > 0):
        raise InputError(f"must be positive, got {fps}", file=path, field="fps")
    bad = np.where(~np.all(np.isfinite(q), axis=1))[0]
    if bad.size:
        raise InputError("NaN or infinite configuration value", file=path, field="q", frame=int(bad[0]))
    if "bvh" in figure.meta:
        joints, values, unit = _bvh_skeleton_and_values(figure, q)
    else:
        joints, values, unit = urdf_figure_to_bvh(figure, q)
    write_bvh_text(path, joints, values, unit, fps)


def _bvh_skeleton_and_values(figure, q):
    """Joints (offsets in metres) and channel values (file units/degrees) for a BVH figure."""
    meta = figure.meta["bvh"]
    unit = meta["length_scale"]
    lock = set(meta["lock"])
    joints = [
        BvhJoint(n, p, np.asarray(o), tuple(c), [np.asarray(e) for e in es])
        for n, p, o, c, es in zip(meta["names"], meta["parents"], meta["offsets"], meta["channels"], meta["end_sites"])
    ]
    F = q.shape[0]
    cols = []
    root = joints[0]
    R = np.array([quat_xyzw_to_matrix(x) for x in q[:, 3:7]])
    pos = q[:, :3] / unit - root.offset / unit
    rot_axes = "".join(c[0] for c in root.channels if c.endswith("rotation"))
    if rot_axes and len(rot_axes) != 3:
        raise InputError("root rotation channels must be three distinct axes to export", field="channels")
    if rot_axes:
        eul = continuous_euler(matrix_to_euler(rot_axes, R))  # no 360-degree jumps when turning
    else:
        eul = np.zeros((F, 0))
    ri = 0
    block = np.zeros((F, len(root.channels)))
    for k, ch in enumerate(root.channels):
        if ch.endswith("position"):
            block[:, k] = pos[:, "XYZ".index(ch[0])]
        else:
            block[:, k] = eul[:, ri]
            ri += 1
    cols.append(block)
    for j in joints[1:]:
        block = np.zeros((F, len(j.channels)))
        if j.name not in lock:
            for k, ch in enumerate(j.channels):
                qs, _ = figure.joint_slices(f"{j.name}_{ch}")
                v = q[:, qs.start]
                block[:, k] = np.degrees(v) if ch.endswith("rotation") else v / unit
        cols.append(block)
    return joints, np.concatenate(cols, axis=1), unit
