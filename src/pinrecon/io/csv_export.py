"""CSV export of a motion: one row per frame, joint angles in degrees.

Columns (header row, in this order):

* ``time`` : seconds.
* Free-flyer figures: ``root_x, root_y, root_z`` the root position in metres (axes: the
  world the motion is given in; ``pinrecon export`` by default writes it in a grounded
  world, :func:`pinrecon.io.bvh_export.ground_frame`: **Y up** (``--up z``: Z up), the floor
  at height 0, x = z = 0 at the root's first position, the figure facing +Z on the first
  frame (-Y with Z up); right-handed), then
  ``root_rz, root_ry, root_rx`` the root orientation as intrinsic ZYX Euler angles in
  degrees (``R = Rz(rz) Ry(ry) Rx(rx)``, BVH's root convention).
* One column per 1-dof joint, in the figure's joint order, named as the joint:
  revolute joints in **degrees**; prismatic joints in **metres**, with the column name
  suffixed ``_m`` (``slider_m``); unbounded revolute joints (``continuous``, stored as
  cos/sin) in degrees.
* Other multi-dof joints: spherical joints as ``<joint>_rz, <joint>_ry, <joint>_rx``
  (ZYX degrees), nested free flyers as ``<joint>_x ... <joint>_rx``, anything else as
  its raw configuration entries ``<joint>_q0, <joint>_q1, ...``.

All Euler angles and unbounded joints are made continuous over time (no 360 degree
jumps), so values may leave [-180, 180]. Numbers are written with full round-trip
precision unless ``precision`` is given.
"""

from __future__ import annotations

import csv
import io
import math
import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..figure import Figure
from ..rotations import continuous_euler, matrix_to_euler, quat_xyzw_to_matrix
from .atomic import atomic_write_text
from .motion import check_motion

__all__ = ["write_csv", "motion_table", "motion_columns"]


def _zyx_columns(prefix: str, quat_xyzw: np.ndarray, pos: np.ndarray | None):
    R = quat_xyzw_to_matrix(quat_xyzw)
    eul = continuous_euler(matrix_to_euler("ZYX", R))
    names, cols = [], []
    if pos is not None:
        names += [f"{prefix}_x", f"{prefix}_y", f"{prefix}_z"]
        cols += [pos[:, 0], pos[:, 1], pos[:, 2]]
    names += [f"{prefix}_rz", f"{prefix}_ry", f"{prefix}_rx"]
    cols += [eul[:, 0], eul[:, 1], eul[:, 2]]
    return names, cols


def _is_prismatic(model, jid: int) -> bool:
    short = model.joints[jid].shortname()
    return "Prismatic" in short or short in ("JointModelPX", "JointModelPY", "JointModelPZ")


def motion_table(figure, q: np.ndarray, times: np.ndarray) -> tuple[list[str], np.ndarray]:
    """The CSV columns and values (frames, columns) of motion ``q`` (see the module doc)."""
    names, _, table = motion_columns(figure, q, times)
    return names, table


def motion_columns(figure, q: np.ndarray, times: np.ndarray) -> tuple[list[str], list[str], np.ndarray]:
    """Column names, their units (``"s"``, ``"m"``, ``"deg"``, or ``""`` for raw
    configuration entries) and values (frames, columns) of motion ``q``: the CSV columns
    of :func:`motion_table` with units, also what :mod:`pinrecon.viz` plots."""
    q = figure.check_q(q)
    if q.ndim == 1:
        q = q[None]
    times = np.asarray(times, float)
    if times.shape != (q.shape[0],):
        raise InputError(f"expected {q.shape[0]} times, got shape {times.shape}", field="times")
    if not np.all(np.isfinite(q)):
        f = int(np.where(~np.all(np.isfinite(q), axis=1))[0][0])
        raise InputError("NaN or infinite configuration", field="q", frame=f)
    model = figure.model
    names, units, cols = ["time"], ["s"], [times]
    for jid in range(1, model.njoints):
        jname = model.names[jid]
        iq, nq, nv = model.idx_qs[jid], model.nqs[jid], model.nvs[jid]
        short = model.joints[jid].shortname()
        block = q[:, iq : iq + nq]
        if jid == 1 and figure.floating:
            n, c = _zyx_columns("root", block[:, 3:7], block[:, :3])
            u = ["m"] * 3 + ["deg"] * 3
        elif nq == 1 and nv == 1:
            if _is_prismatic(model, jid):
                n, c, u = [f"{jname}_m"], [block[:, 0]], ["m"]
            else:
                n, c, u = [jname], [np.degrees(block[:, 0])], ["deg"]
        elif nq == 2 and nv == 1:  # unbounded revolute: (cos, sin)
            angle = np.unwrap(np.arctan2(block[:, 1], block[:, 0]))
            n, c, u = [jname], [np.degrees(angle)], ["deg"]
        elif "Spherical" in short and nq == 4:
            n, c = _zyx_columns(jname, block, None)
            u = ["deg"] * 3
        elif "FreeFlyer" in short:
            n, c = _zyx_columns(jname, block[:, 3:7], block[:, :3])
            u = ["m"] * 3 + ["deg"] * 3
        else:
            n, c, u = [f"{jname}_q{k}" for k in range(nq)], list(block.T), [""] * nq
        names += n
        units += u
        cols += c
    return names, units, np.stack(cols, axis=1)


def write_csv(
    path: str | os.PathLike,
    result_or_figure,
    q: np.ndarray | None = None,
    *,
    times: np.ndarray | None = None,
    fps: float | None = None,
    precision: int | None = None,
) -> list[str]:
    """Write a motion as CSV (one header row, one row per frame), atomically.

    Parameters
    ----------
    path : output file (its folder is created).
    result_or_figure : a :class:`pinrecon.Result` (its figure, ``q`` and ``times`` are
        used), or a :class:`pinrecon.Figure` with ``q``.
    q : (frames, nq) configurations, with a figure.
    times, fps : frame times in seconds, or a frame rate (times = frame / fps); with a
        figure one of them is required.
    precision : decimals to write; default: full round-trip precision.

    Returns the column names. See the module docstring for the columns and units.
    """
    if isinstance(result_or_figure, Figure):
        figure = result_or_figure
        if q is None:
            raise InputError("give q (frames, nq) with a figure", field="q")
        q = figure.check_q(q)
        n = 1 if q.ndim == 1 else q.shape[0]
        if times is None:
            if fps is None or not (fps > 0 and math.isfinite(fps)):
                raise InputError("give times or a positive fps with a figure", field="fps")
            times = np.arange(n) / float(fps)
    else:
        res = result_or_figure
        if not hasattr(res, "figure") or not hasattr(res, "q"):
            raise InputError(
                f"expected a Result or a Figure, got {type(res).__name__}", field="result_or_figure"
            )
        figure = res.figure
        q = res.q if q is None else q
        times = res.times if times is None else times
        fps = res.fps if fps is None else fps
    check_motion(figure, np.atleast_2d(q), 1.0 if fps is None else fps, file=path)
    times = np.asarray(times, float)
    if not np.all(np.isfinite(times)):
        raise InputError("must be finite", file=path, field="times")
    names, table = motion_table(figure, q, times)

    if precision is None:
        fmt = repr
    else:
        p = int(precision)
        fmt = lambda x: f"{x:.{p}f}"  # noqa: E731

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(names)
    for row in table:
        w.writerow([fmt(float(x)) for x in row])
    atomic_write_text(Path(path), buf.getvalue())
    return names
