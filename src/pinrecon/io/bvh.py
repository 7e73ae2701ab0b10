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
from .motion import check_motion

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
    "bvh_unit",
    "transform_motion",
    "BVH_UNITS",
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
#: BVH length units by name (metres per file unit)
BVH_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}


def bvh_unit(unit) -> float | None:
    """Metres per file unit of ``unit``: ``"m"``, ``"cm"``, ``"mm"``, a positive number, or
    ``None`` (the figure's own unit)."""
    if unit is None:
        return None
    if isinstance(unit, str):
        if unit not in BVH_UNITS:
            raise InputError(f"unknown unit {unit!r}; use one of {sorted(BVH_UNITS)} or metres per unit",
                             field="unit")
        return BVH_UNITS[unit]
    u = float(unit)
    if not (u > 0 and np.isfinite(u)):
        raise InputError(f"must be a positive number of metres per unit, got {unit!r}", field="unit")
    return u


def transform_motion(figure, q: np.ndarray, R_new_world: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """Motion ``q`` of a free-flyer figure moved rigidly into a new world:
    ``p_new = R_new_world p_world + t_new`` for every point of the figure (the root's pose
    is premultiplied; joint values do not change)."""
    if not figure.floating:
        raise InputError("only a figure with a free-flyer root can be moved in the world", field="figure")
    q = np.array(q, float)
    R = np.asarray(R_new_world, float)
    q[:, :3] = q[:, :3] @ R.T + np.asarray(t_new, float)
    q[:, 3:7] = matrix_to_quat_xyzw(R @ quat_xyzw_to_matrix(q[:, 3:7]))
    return q


def write_bvh(path: str | os.PathLike, figure, q: np.ndarray, fps: float, *, unit=None, world=None) -> None:
    """Write motion ``q`` (frames, nq) of ``figure`` as BVH, atomically.

    A figure built from a BVH writes back with its original joint names, channel orders,
    offsets and end sites, in its own length unit. Other figures are converted by
    :func:`pinrecon.io.bvh_urdf.urdf_figure_to_bvh`. Values are written with 9 decimals
    so positions survive the round trip to well below 1e-6 m.

    Options (defaults keep the motion as it is):

    unit : the file's length unit, ``"m"``, ``"cm"``, ``"mm"`` or metres per unit (default:
        the figure's own, metres for URDF figures).
    world : ``(R, t)``, a rotation (3, 3) and translation (3,) metres moving the whole
        motion rigidly (``p -> R p + t``) before writing, e.g. from
        :func:`pinrecon.io.bvh_export.ground_frame` (floor at height zero, Y up, facing +Z).
        A fixed-base figure takes it in its ROOT channels.
    """
    q = np.asarray(q, float)
    if q.ndim != 2 or q.shape[1] != figure.nq:
        raise InputError(f"expected q of shape (frames, {figure.nq}), got {q.shape}", file=path, field="q")
    if not (fps > 0):
        raise InputError(f"must be positive, got {fps}", file=path, field="fps")
    check_motion(figure, q, fps, file=path)
    u = bvh_unit(unit)
    R = t = None
    if world is not None:
        R, t = np.asarray(world[0], float), np.asarray(world[1], float)
        if R.shape != (3, 3) or t.shape != (3,) or not np.allclose(R @ R.T, np.eye(3), atol=1e-9):
            raise InputError("world must be (R, t): a rotation matrix (3, 3) and a translation (3,)", field="world")
        if figure.floating:
            q = transform_motion(figure, q, R, t)
    if "bvh" in figure.meta:
        joints, values, unit_m = _bvh_skeleton_and_values(figure, q)
        if u is not None and u != unit_m:
            values = _rescale_positions(joints, values, unit_m / u)
            unit_m = u
    else:
        joints, values, unit_m = urdf_figure_to_bvh(figure, q, 1.0 if u is None else u)
    if world is not None and not figure.floating:
        values = np.array(values, float)
        values[:, 0:3] = t / unit_m  # the ROOT's channels: Xposition Yposition Zposition Zrotation Yrotation Xrotation
        values[:, 3:6] = matrix_to_euler("ZYX", R[None])[0]
    write_bvh_text(path, joints, values, unit_m, fps)


def _rescale_positions(joints, values, factor: float) -> np.ndarray:
    """Channel values with every position channel multiplied by ``factor``."""
    values = np.array(values, float)
    c = 0
    for j in joints:
        for ch in j.channels:
            if ch.endswith("position"):
                values[:, c] *= factor
            c += 1
    return values


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
