"""Exports of a saved result: :func:`export_result` for the ``pinrecon export`` command.

It reads the result through :mod:`pinrecon.result` (never the pipeline) and writes with
:func:`pinrecon.io.bvh.write_bvh` and :func:`pinrecon.io.csv_export.write_csv`.
:func:`urdf_figure_to_bvh` (:mod:`pinrecon.io.bvh_urdf`) and :func:`continuous_euler`
(:mod:`pinrecon.rotations`) are re-exported here, where they used to live.

**Landing well** (``ground=True``, the default): a reconstruction's world is the camera's
(a tilted floor, the figure anywhere). :func:`ground_frame` moves the motion rigidly so
that the floor (the result's own, :mod:`pinrecon.contact`, else estimated under the
figure's lowest foot points) is at height zero with its normal along the target's up
axis (``up="y"``, BVH's convention, or ``"z"``), the root's position on the first frame
is over the origin, and the figure faces ``facing`` on the first frame (default ``+z``
when Y is up, which Blender's default BVH import turns to -Y, facing its front view;
``-y`` when Z is up). The facing direction is ``(left - right) x up`` averaged over the
figure's left/right keypoint pairs (``left_hip``/``right_hip``, ``LeftFoot``/``RightFoot``,
``LHip``/``RHip`` ...).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from ..contact import Floor, FootContact, estimate_floor, foot_keypoints, sole_offset
from ..errors import InputError
from ..result import load_result
from ..rotations import continuous_euler
from ..tracks import Markers
from .bvh import bvh_unit, transform_motion, write_bvh
from .bvh_urdf import urdf_figure_to_bvh
from .csv_export import write_csv
from .trc import write_trc, z_up_rotation

__all__ = ["export_result", "ground_frame", "facing_direction", "result_floor", "urdf_figure_to_bvh",
           "continuous_euler"]

_AXES = {"x": 0, "y": 1, "z": 2}
_PAIRS = ((re.compile(r"left"), "right"), (re.compile(r"Left"), "Right"), (re.compile(r"LEFT"), "RIGHT"),
          (re.compile(r"^L(?=[A-Z])"), "R"), (re.compile(r"^l_"), "r_"), (re.compile(r"_l$"), "_r"))


def _axis(spec: str, field: str) -> np.ndarray:
    m = re.fullmatch(r"([+-]?)([xyz])", str(spec).strip().lower())
    if not m:
        raise InputError(f"expected an axis such as 'y', '+z' or '-x', got {spec!r}", field=field)
    v = np.zeros(3)
    v[_AXES[m.group(2)]] = -1.0 if m.group(1) == "-" else 1.0
    return v


def result_floor(result) -> Floor:
    """The floor of a result: the one its reconstruction used (``extras``), else one
    estimated under its foot keypoints (all keypoints when it has none)."""
    feet = FootContact.from_extras(result.extras or {})
    if feet is not None:
        return feet.floor
    fig = result.figure
    feet = foot_keypoints(fig)
    names = feet or list(fig.keypoint_names)
    P = result.keypoints3d
    upper = result.q[:, :3] if fig.floating else P
    fl = estimate_floor(P[:, fig.keypoint_index(names)], p_upper=upper, fps=result.fps)
    return Floor(fl.normal, fl.offset_m - (sole_offset(feet) if feet else 0.0))


def facing_direction(names, p_world, up) -> np.ndarray | None:
    """The direction a figure faces (unit, perpendicular to ``up``): ``(left - right) x up``
    averaged over its left/right keypoint pairs at one frame (``p_world`` (K, 3)); ``None``
    when it has no such pair."""
    index = {n: i for i, n in enumerate(names)}
    acc = np.zeros(3)
    for n, i in index.items():
        for pat, rep in _PAIRS:
            if pat.search(n):
                j = index.get(pat.sub(rep, n, count=1))
                if j is not None:
                    acc += p_world[i] - p_world[j]
                break
    up = np.asarray(up, float)
    f = np.cross(acc, up)
    f -= (f @ up) * up
    n = np.linalg.norm(f)
    return f / n if n > 1e-9 else None


def _rotation_between(a, b) -> np.ndarray:
    """The smallest rotation taking unit vector ``a`` to unit vector ``b``."""
    v = np.cross(a, b)
    c = float(a @ b)
    if c < -1 + 1e-12:  # opposite: half a turn about any perpendicular axis
        p = np.eye(3)[int(np.argmin(np.abs(a)))]
        p = np.cross(a, p)
        p /= np.linalg.norm(p)
        return 2.0 * np.outer(p, p) - np.eye(3)
    V = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + V + V @ V / (1.0 + c)


def ground_frame(result, *, up: str = "y", facing: str | None = None, floor: Floor | None = None):
    """``(R, t)`` moving a result's world to the export's: ``p -> R p + t`` puts the floor
    at height zero with its normal along ``up``, the root's first position over the
    origin, and the figure facing ``facing`` on the first frame (see the module doc).
    ``floor`` overrides :func:`result_floor`; ``facing=""`` keeps the heading."""
    up_v = _axis(up, "up")
    if up_v.min() < 0:
        raise InputError(f"the up axis must be positive ('x', 'y' or 'z'), got {up!r}", field="up")
    fl = floor if floor is not None else result_floor(result)
    R = _rotation_between(fl.n, up_v)
    fig, P = result.figure, np.asarray(result.keypoints3d, float)
    if facing is None:
        facing = "+z" if up_v[1] == 1 else "-y"
    if facing:
        target = _axis(facing, "facing")
        if abs(target @ up_v) > 0.5:
            raise InputError(f"the facing axis {facing!r} must be horizontal, not along up {up!r}", field="facing")
        f = facing_direction(list(fig.keypoint_names), P[0] @ R.T, up_v)
        if f is not None:
            ang = np.arctan2(np.cross(f, target) @ up_v, f @ target)
            K = np.array([[0, -up_v[2], up_v[1]], [up_v[2], 0, -up_v[0]], [-up_v[1], up_v[0], 0]])
            R = (np.eye(3) + np.sin(ang) * K + (1 - np.cos(ang)) * K @ K) @ R
    start = result.q[0, :3] if fig.floating else P[0].mean(axis=0)
    s = R @ start
    t = -(s - (s @ up_v) * up_v)  # the root's start over the origin
    t = t - fl.offset_m * up_v  # R p . up = n . p, so the floor goes to height zero
    return R, t


def export_result(
    npz_path: str | os.PathLike,
    bvh: str | os.PathLike | None = None,
    csv: str | os.PathLike | None = None,
    *,
    ground: bool = True,
    up: str = "y",
    units: str | float | None = "m",
    facing: str | None = None,
    trc: str | os.PathLike | None = None,
    trc_names: str = "file",
) -> list[Path]:
    """Export a result NPZ as BVH, CSV and/or TRC (the ``pinrecon export`` command).

    Parameters
    ----------
    npz_path : a result written by :meth:`pinrecon.Result.save`.
    bvh : BVH output path (:func:`pinrecon.io.bvh.write_bvh`; BVH figures keep their own
        skeleton, URDF figures are converted by :func:`urdf_figure_to_bvh`).
    csv : CSV output path (:func:`pinrecon.io.csv_export.write_csv`; root position in
        metres in the export's world).
    ground : move the motion so that it lands well (:func:`ground_frame`): floor at height
        zero, ``up`` axis up, the root's start over the origin, facing ``facing``. False:
        the reconstruction's world as it is.
    up : ``"y"`` (default, BVH's convention) or ``"z"``.
    units : BVH length unit, ``"m"`` (default), ``"cm"``, ``"mm"``, metres per unit, or
        ``None`` (the figure's own: CMU figures in CMU units, URDF figures in metres).
    facing : the axis the figure faces on the first frame (default ``"+z"`` with Y up,
        ``"-y"`` with Z up); ``""`` keeps the heading.
    trc : TRC output path (:func:`pinrecon.io.trc.write_trc`): the 3D keypoints (one per
        distinct position), in metres, in the same world with ``up`` the file's up axis
        (OpenSim's Y by default; ``facing="+x"`` faces OpenSim's forward axis).
    trc_names : ``"file"`` (the figure's keypoint names) or ``"pose2sim"`` (Pose2Sim's
        names where they mean the same point, :data:`pinrecon.io.trc.POSE2SIM_NAMES`).

    Returns the paths written. Output folders are created.
    """
    if bvh is None and csv is None and trc is None:
        raise InputError("nothing to do: give a BVH, CSV and/or TRC output path", field="bvh/csv/trc")
    bvh_unit(units)
    result = load_result(npz_path)
    if result.figure is None:
        raise InputError(
            "the result has no embedded figure; cannot export", file=npz_path, field="figure_urdf"
        )
    world = ground_frame(result, up=up, facing=facing) if ground else None
    written = []
    if bvh is not None:
        bvh = Path(bvh)
        write_bvh(bvh, result.figure, result.q, result.fps, unit=units, world=world)
        written.append(bvh)
    if csv is not None:
        csv = Path(csv)
        q = result.q
        if world is not None and result.figure.floating:
            q = transform_motion(result.figure, q, *world)
        write_csv(csv, result, q)
        written.append(csv)
    if trc is not None:
        names = result.figure.distinct_keypoint_names
        P = np.asarray(result.keypoints3d, float)[:, result.figure.keypoint_index(names)]
        if world is not None:
            P = P @ world[0].T + world[1]
        # these coordinates go into the file as they are (the export's world, or the reconstruction's as BVH and
        # CSV keep it); write_trc turns pinrecon's Z-up points to ``up``, so hand it them turned the other way
        P = P @ z_up_rotation(up).T
        written.append(write_trc(trc, Markers(P, names, result.fps), up=up, names=trc_names))
    return written
