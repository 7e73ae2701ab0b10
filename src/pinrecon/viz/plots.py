"""Static pictures of a reconstruction (DiFranco, Cham & Rehg 2001, figures 7-9).

Every function returns the matplotlib :class:`~matplotlib.figure.Figure` it drew (built
with the object-oriented API on an Agg canvas: headless, not registered with pyplot) and,
when ``out`` is given, also writes it there (PNG unless the suffix says otherwise;
atomic; the folder is created).

Artists carry gids so that tests and users can find the data drawn: joint-angle curves
are Line2D with gid ``"reconstruction"`` / ``"truth"``; stick figures have a Line2D of
keypoints (gid ``"keypoints"``, ``"truth_keypoints"``) and a LineCollection of bones
(``"bones"``, ``"truth_bones"``); the reprojection plot has ``"tracks"``,
``"reprojection"`` and ``"residuals"``; the error plot ``"reprojection_error"`` (all
cameras) and ``"reprojection_error:<camera name>"`` (each camera of a several-camera
result).
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..anatomy import joint_title
from ..errors import InputError, UnknownNameError
from ._common import (
    TITLE_Y,
    as_motion,
    view_up,
    check_frames,
    default_camera,
    draw_contacts,
    draw_floor,
    draw_stick,
    even_frames,
    find_series,
    floor_segment,
    height_ticks,
    joint_series,
    legend_handles,
    new_figure,
    place_grid,
    save_figure,
    second_view_camera,
    skeleton,
    skeleton_points,
    square_limits,
    view_unit,
)

__all__ = [
    "plot_joint_angles",
    "plot_reprojection",
    "plot_stick_strip",
    "plot_reprojection_error",
    "plot_result",
]


def _default_joints(series: dict, count: int = 6) -> list[str]:
    """The ``count`` 1-dof joints that move most (largest range), in figure order."""
    cand = [(n, v) for n, (v, u) in series.items() if u == "deg" and not n.startswith("root_")]
    if not cand:
        cand = [(n, v) for n, (v, u) in series.items() if not n.startswith("root_")]
    ranges = sorted(cand, key=lambda nv: -float(np.ptp(nv[1])) if len(nv[1]) else 0.0)[:count]
    chosen = {n for n, _ in ranges}
    return [n for n in series if n in chosen]


def plot_joint_angles(
    result,
    joints: Sequence[str] | None = None,
    truth=None,
    out: str | os.PathLike | None = None,
    *,
    labels: tuple[str, str] = ("reconstruction", "ground truth"),
    ncols: int | None = None,
):
    """Joint-angle curves over time, one small panel per joint (DiFranco et al. fig. 9).

    Parameters
    ----------
    result : a :class:`pinrecon.Result` (or BvhMotion, or a result NPZ path).
    joints : names of 1-dof joints (revolute in degrees, prismatic in metres); root
        channels ``root_x ... root_rx`` (see :mod:`pinrecon.io.csv_export`) also work.
        Default: the six joints with the largest range of motion.
    truth : ground truth or a second result drawn dashed (Result, BvhMotion or path);
        matched by joint name and drawn against its own time axis.
    out : PNG path to write.
    labels : legend labels of the two curves.
    """
    motion = as_motion(result, labels[0])
    series = joint_series(motion)
    if joints is None:
        joints = _default_joints(series)
    if isinstance(joints, str):
        joints = [joints]
    cols = [find_series(series, j) for j in joints]
    unknown = [j for j, c in zip(joints, cols) if c is None]
    if unknown:
        valid = [n[:-2] if n.endswith("_m") else n for n in series]
        raise UnknownNameError("joint", unknown, valid, field="joints")
    if not cols:
        raise InputError("no joints to plot", field="joints")
    tmotion = tseries = None
    if truth is not None:
        tmotion = as_motion(truth, labels[1])
        tseries = joint_series(tmotion)
        missing = [j for j in joints if find_series(tseries, j) is None]
        if len(missing) == len(joints):
            warnings.warn(
                "the truth shares none of the plotted joints by name; it is not drawn", stacklevel=2
            )
    n = len(cols)
    ncols = ncols or (1 if n == 1 else 2 if n <= 4 else 3)
    nrows = math.ceil(n / ncols)
    fig = new_figure((3.4 * ncols, 2.1 * nrows + 0.4), layout=None)
    axes = np.atleast_1d(fig.subplots(nrows, ncols, sharex=True, squeeze=False)).ravel()
    place_grid(fig, nrows, ncols, left=0.6, bottom=0.45, top=0.3, wgap=0.6, hgap=0.4)
    for k, (name, col) in enumerate(zip(joints, cols)):
        ax = axes[k]
        values, unit = series[col]
        (line,) = ax.plot(motion.times, values, "-", color="#1f77b4", lw=1.4, label=labels[0])
        line.set_gid("reconstruction")
        if tseries is not None:
            tcol = find_series(tseries, name)
            if tcol is not None:
                tv, _ = tseries[tcol]
                (tl,) = ax.plot(tmotion.times, tv, "--", color="black", lw=1.1, label=labels[1])
                tl.set_gid("truth")
        ax.set_title(joint_title(motion.figure, name), fontsize=9, y=TITLE_Y)
        ylabel = "angle (deg)" if unit == "deg" else f"position ({unit})" if unit else "value"
        ax.set_ylabel(ylabel, fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, lw=0.3, alpha=0.6)
        if k >= n - ncols:
            ax.set_xlabel("time (s)", fontsize=8)
    for ax in axes[n:]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7, loc="best")
    if out is not None:
        save_figure(fig, out)
    return fig


def _camera_index(result, camera) -> int:
    """The index in ``result.cameras`` of a camera given by name or index."""
    names = list(getattr(result, "camera_names", None) or [])
    if isinstance(camera, str):
        if camera not in names:
            raise UnknownNameError("camera", [camera], names, field="camera")
        return names.index(camera)
    i = int(camera)
    if not 0 <= i < len(names):
        raise InputError(f"camera index {i} is out of range: the result has {len(names)} cameras", field="camera")
    return i


def _resolve_camera(result, camera):
    """``camera`` itself, or the result's camera with that name or index, or the
    result's (first) camera when None."""
    if camera is None:
        return getattr(result, "camera", None)
    if isinstance(camera, (str, int, np.integer)):
        return result.cameras[_camera_index(result, camera)]
    return camera


def camera_file_stem(name: str) -> str:
    """A camera name made safe for a file name."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", str(name)).strip("._") or "camera"


def plot_stick_strip(
    result,
    frames: Sequence[int] | None = None,
    camera=None,
    second_view=None,
    truth=None,
    out: str | os.PathLike | None = None,
    *,
    up=None,
):
    """The 3D stick figure over a strip of frames, from the camera (row 1) and from a
    second viewpoint (row 2) (DiFranco et al. figs. 7 and 8).

    Parameters
    ----------
    result : Result (or BvhMotion, or result NPZ path).
    frames : frame indices of ``result`` (default: 6 evenly spaced).
    camera : the viewing camera (default ``result.camera``, else a front view along -Z).
        Row 1 is in the camera's image coordinates (pixels, y down): the keypoints drawn
        are exactly ``camera.project(keypoints3d[f])``.
    second_view : a camera, or an angle in degrees to turn the camera about the world up
        axis (default 90). Drawn orthographically in metres.
    truth : ground truth (Result, BvhMotion or path) drawn in grey under the
        reconstruction, at the frame nearest in time.
    up : world up axis for the turn (default: the coordinate axis nearest the camera's up).

    A legend names the colours (left blue, right red). Row 2's vertical axis is labelled
    with heights (above the floor when the result has one), positive up. A result with a
    floor and contacts (``reconstruct(..., floor=...)``) also gets the floor's line (gid
    ``"floor"``) and squares on the foot points in contact (gid ``"contacts"``).
    """
    motion = as_motion(result)
    T = len(motion.times)
    frames = even_frames(T, 6) if frames is None else check_frames(frames, T)
    cam = _resolve_camera(result, camera) or default_camera()
    feet = motion.feet
    up_w = view_up(cam, feet) if up is None else np.asarray(up, float) / np.linalg.norm(up)
    cam2 = second_view_camera(cam, second_view, up_w)
    sk = skeleton(motion.figure)
    P = skeleton_points(motion, sk, frames)
    tmotion = tsk = TP = None
    if truth is not None:
        tmotion = as_motion(truth, "ground truth")
        tsk = skeleton(tmotion.figure)
        tframes = [tmotion.frame_at(motion.times[f]) for f in frames]
        TP = skeleton_points(tmotion, tsk, tframes)
    n = len(frames)
    fig = new_figure((1.9 * n + 0.6, 4.8), layout=None)
    axes = np.atleast_2d(fig.subplots(2, n, squeeze=False))
    place_grid(fig, 2, n, left=0.65, right=0.1, bottom=0.6, top=0.3, wgap=0.4, hgap=0.35)
    for row, view in enumerate((cam, cam2)):
        uv = view.project(P)
        tuv = view.project(TP) if TP is not None else None
        allpts = uv if tuv is None else np.concatenate([uv, tuv], axis=1)
        lo, hi = allpts.min(axis=1), allpts.max(axis=1)
        half = 0.55 * float(np.max(hi - lo)) + 1e-9
        unit = view_unit(view)
        for k, f in enumerate(frames):
            ax = axes[row, k]
            if tuv is not None:
                draw_stick(ax, tuv[k], tsk, truth=True, label="ground truth", prefix="truth_")
            draw_stick(ax, uv[k], sk, label="reconstruction")
            if feet is not None:
                fidx = motion.figure.keypoint_index(feet.names)
                centre = motion.keypoints3d[f].mean(axis=0)
                draw_floor(ax, floor_segment(view, feet.floor, centre, 1.0))
                on = feet.contact[f]
                draw_contacts(ax, view.project(motion.keypoints3d[f, fidx[on]]))
            square_limits(ax, 0.5 * (lo[k] + hi[k]), half)
            ax.tick_params(labelsize=6)
            if row == 0:
                ax.set_title(f"frame {f}, t = {motion.times[f]:.2f} s", fontsize=8, y=TITLE_Y)
            if k == 0:
                what = "camera view" if row == 0 else "second view"
                if row == 1 and unit == "m":
                    what = f"second view, {height_ticks(ax, feet.floor if feet else None, up_w)}"
                ax.set_ylabel(f"{what} ({unit})", fontsize=8)
            elif row == 1 and unit == "m":
                height_ticks(ax, feet.floor if feet else None, up_w)
    fig.legend(handles=legend_handles(truth is not None, feet is not None, feet is not None), loc="lower center",
               ncols=6, fontsize=7, frameon=False)
    if out is not None:
        save_figure(fig, out)
    return fig


def plot_reprojection(
    result,
    tracks,
    frames: Sequence[int] | None = None,
    out: str | os.PathLike | None = None,
    *,
    camera=None,
):
    """The 2D tracks with the reconstruction's reprojection drawn over them.

    Parameters
    ----------
    result : Result (or result NPZ path) with a camera (or pass ``camera``).
    tracks : :class:`pinrecon.Tracks` or a path :func:`pinrecon.load_tracks` reads.
    frames : track frame indices (default: 4 evenly spaced); the reconstruction frame at
        the same time is used.
    camera : overrides ``result.camera``: a camera, or the name or index of one of the
        result's cameras (``result.camera_names``); ``tracks`` are then that camera's.

    Tracked points are crosses joined by the figure's keypoint bones
    (:attr:`pinrecon.Figure.parents_of_keypoints`); the reprojection is the full stick
    figure (gid ``"reprojection"`` holds ``camera.project`` of the keypoints); thin lines
    join each tracked point to its reprojection. Image y points down.
    """
    from ..result import load_result
    from ..tracks import Tracks, load_tracks

    if isinstance(result, (str, os.PathLike)) and Path(result).suffix.lower() != ".bvh":
        result = load_result(result)
    motion = as_motion(result)
    cam = _resolve_camera(result, camera)
    who = ""
    if isinstance(camera, (str, int, np.integer)) and len(getattr(result, "cameras", ())) > 1:
        who = f"{result.camera_names[_camera_index(result, camera)]}: "
    if cam is None:
        raise InputError("the result has no camera; pass camera=...", field="camera")
    if not isinstance(tracks, Tracks):
        tracks = load_tracks(tracks)
    frames = even_frames(tracks.T, 4) if frames is None else check_frames(frames, tracks.T)
    fig_kp = motion.figure.keypoint_names
    shared = [n for n in tracks.names if n in set(fig_kp)]
    if not shared:
        raise UnknownNameError("track", tracks.names, fig_kp, field="tracks.names")
    kp_idx = motion.figure.keypoint_index(shared)
    tr_idx = [tracks.names.index(n) for n in shared]
    sk = skeleton(motion.figure)
    pos_in_tracks = {int(k): i for i, k in enumerate(kp_idx)}
    track_edges = [
        (pos_in_tracks[a], pos_in_tracks[b])
        for a, b in sk.keypoint_edges
        if a in pos_in_tracks and b in pos_in_tracks
    ]
    rframes = [motion.frame_at(tracks.times[f]) for f in frames]
    P = skeleton_points(motion, sk, rframes)
    n = len(frames)
    fig = new_figure((3.0 * n + 0.4, 3.6), layout=None)
    axes = np.atleast_1d(fig.subplots(1, n, squeeze=False)).ravel()
    place_grid(fig, 1, n, left=0.6, right=0.1, bottom=0.45, top=0.3, wgap=0.45)
    for k, f in enumerate(frames):
        ax = axes[k]
        uv = cam.project(P[k])
        obs = tracks.points[f, tr_idx]
        ok = np.all(np.isfinite(obs), axis=1)
        segs = [obs[[a, b]] for a, b in track_edges if ok[a] and ok[b]]
        from matplotlib.collections import LineCollection

        tb = LineCollection(segs, colors="#2ca02c", linewidths=1.0, linestyles="--", zorder=2)
        tb.set_gid("track_bones")
        ax.add_collection(tb)
        (tl,) = ax.plot(
            obs[:, 0], obs[:, 1], "x", color="#2ca02c", ms=5, mew=1.3, zorder=5, label="2D tracks"
        )
        tl.set_gid("tracks")
        pts, _ = draw_stick(ax, uv, sk, label="reprojection")
        pts.set_gid("reprojection")
        res = [np.stack([obs[i], uv[kp_idx[i]]]) for i in range(len(shared)) if ok[i]]
        rl = LineCollection(res, colors="#ff7f0e", linewidths=0.8, zorder=4)
        rl.set_gid("residuals")
        ax.add_collection(rl)
        err = np.linalg.norm(obs[ok] - uv[kp_idx[ok]], axis=1)
        err_txt = f", {err.mean():.1f} px" if err.size else ""
        ax.set_title(f"{who}frame {f} (t = {tracks.times[f]:.2f} s){err_txt}", fontsize=8, y=TITLE_Y)
        allp = np.concatenate([uv, obs[ok]])
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        square_limits(ax, 0.5 * (lo + hi), 0.55 * float(np.max(hi - lo)) + 1e-9)
        ax.tick_params(labelsize=6)
        ax.set_xlabel("u (px)", fontsize=8)
        if k == 0:
            ax.set_ylabel("v (px, down)", fontsize=8)
            ax.legend(fontsize=6, loc="lower left")
    if out is not None:
        save_figure(fig, out)
    return fig


def plot_reprojection_error(result, out: str | os.PathLike | None = None):
    """Mean reprojection error per frame (pixels) of a Result, observed frames only; with
    several cameras, one thin line per camera under the mean over all of them."""
    err = np.asarray(result.reprojection_error_px, float)
    fig = new_figure((6.0, 2.4), layout=None)
    ax = fig.subplots()
    place_grid(fig, 1, 1, left=0.6, right=0.1, bottom=0.45, top=0.3)
    per = getattr(result, "reprojection_error_px_per_camera", None)
    names = list(getattr(result, "camera_names", None) or [])
    several = per is not None and len(names) > 1 and np.shape(per) == (len(names), len(err))
    (line,) = ax.plot(result.times, err, "-", color="#1f77b4", lw=1.4 if several else 1.0,
                      label="all cameras" if several else None)
    line.set_gid("reprojection_error")
    if several:
        for name, e in zip(names, np.asarray(per, float)):
            ok = np.isfinite(e)
            (lc,) = ax.plot(result.times[ok], e[ok], "-", lw=0.7, alpha=0.8, label=f"{name}")
            lc.set_gid(f"reprojection_error:{name}")
        ax.legend(fontsize=6, loc="upper right")
    ax.set_xlabel("time (s)", fontsize=8)
    ax.set_ylabel("reprojection error (px)", fontsize=8)
    finite = err[np.isfinite(err)]
    if finite.size:
        ax.set_title(f"mean {finite.mean():.2f} px, max {finite.max():.2f} px", fontsize=9, y=TITLE_Y)
    ax.grid(True, lw=0.3, alpha=0.6)
    if out is not None:
        save_figure(fig, out)
    return fig


def plot_result(
    result_path_or_result,
    out_dir: str | os.PathLike,
    truth=None,
    tracks=None,
    *,
    animation: bool = True,
    truth_length_scale: float | None = None,
    truth_skip_frames: int = 0,
    joints=None,
    tracks_fps: float | None = None,
) -> list[Path]:
    """Write the standard pictures of a result (the ``pinrecon plot`` command).

    Files in ``out_dir`` (created): ``joint_angles.png``, ``stick_strip.png``,
    ``reprojection.png`` (with ``tracks`` and a camera; with a list of tracks, one per
    camera of a several-camera result, ``reprojection_<camera name>.png`` each),
    ``reprojection_error.png``
    (when the result has finite errors) and ``animation.gif`` (unless
    ``animation=False``).

    Parameters
    ----------
    result_path_or_result : a result NPZ path or a :class:`pinrecon.Result`.
    truth : ground truth: a result NPZ, a BVH file, a Result or a BvhMotion. A BVH file
        is read with ``truth_length_scale`` (metres per file unit), by default the
        length scale of the result's figure when that came from a BVH, else 1.0; and
        ``truth_skip_frames`` frames are dropped at its start (1 for CMU's T-pose).
    tracks : the 2D tracks (path or :class:`pinrecon.Tracks`), or a list of them paired in
        order with ``result.cameras``.
    joints : joints for ``joint_angles.png`` (default: the six that move most).
    tracks_fps : frame rate of tracks files that carry none (an OpenPose folder, COCO JSON).

    Returns the list of files written. Every input is read before anything is drawn, and
    when a picture fails the files this call wrote are removed again: a failed call
    leaves no half set of pictures behind. Where the process may use a second CPU
    (:func:`pinrecon.processes.forkable`; ``PINRECON_BESIDE=0`` says no), a forked child
    draws some of the pictures meanwhile: the same files.
    """
    from ..result import load_result
    from ..tracks import Tracks, load_tracks

    result = result_path_or_result
    if isinstance(result, (str, os.PathLike)):
        result = load_result(result)
    if isinstance(tracks, (list, tuple)):
        tracks = [t if isinstance(t, Tracks) else load_tracks(t, fps=tracks_fps) for t in tracks]
    elif tracks is not None and not isinstance(tracks, Tracks):
        tracks = load_tracks(tracks, fps=tracks_fps)
    out_dir = Path(out_dir)
    tmotion = None
    if truth is not None:
        scale = truth_length_scale
        meta = getattr(result.figure, "meta", {}) or {}
        if scale is None and "bvh" in meta:
            scale = float(meta["bvh"]["length_scale"])
        tmotion = as_motion(
            truth, "ground truth", length_scale=scale, skip_frames=truth_skip_frames
        )
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    try:
        _draw_all(result, out_dir, tmotion, tracks, joints, animation, written)
    except BaseException:
        for f in written:
            Path(f).unlink(missing_ok=True)
        raise
    return written


def _draw_all(result, out_dir: Path, tmotion, tracks, joints, animation: bool, written: list) -> None:
    """The pictures of :func:`plot_result`; each path is appended to ``written`` once saved
    (in the order that docstring lists them). Where a child may be forked beside this process
    (:class:`pinrecon.processes.Beside`) it draws the stick strip and the error plot (with an
    animation: the animation) while this process draws the rest; the child's pictures come
    back as bytes and are written here, with the others (staged with them under an
    :meth:`~pinrecon.io.atomic.Outputs.commit`). Without a child all are drawn here."""
    from ..io.atomic import atomic_write_bytes
    from ..processes import Beside

    # each draws its pictures into a folder, appending their paths to a list as it saves them
    def angles(folder, into):
        into.append(save_figure(plot_joint_angles(result, joints, tmotion), folder / "joint_angles.png"))

    def strip(folder, into):
        into.append(save_figure(plot_stick_strip(result, truth=tmotion), folder / "stick_strip.png"))

    def reprojection(folder, into):
        if isinstance(tracks, (list, tuple)):
            _per_camera_reprojection(result, tracks, folder, into)
        elif tracks is not None and getattr(result, "camera", None) is None:
            warnings.warn("the result has no camera: reprojection.png is not drawn", stacklevel=3)
        elif tracks is not None:
            into.append(save_figure(plot_reprojection(result, tracks), folder / "reprojection.png"))

    def error(folder, into):
        if np.any(np.isfinite(np.asarray(getattr(result, "reprojection_error_px", np.zeros(0)), float))):
            into.append(save_figure(plot_reprojection_error(result), folder / "reprojection_error.png"))

    def animation_gif(folder, into):
        from .animate import animate

        into.append(animate(result, folder / "animation.gif", truth=tmotion))

    order = [angles, strip, reprojection, error] + ([animation_gif] if animation else [])
    there = [animation_gif] if animation else [strip, error]
    beside = Beside(_rendered, there)
    if not beside.forked:  # no child: every picture drawn here, straight into the folder
        there = []
    done = {}
    try:
        for draw in (d for d in order if d not in there):
            mark = len(written)
            draw(out_dir, written)
            done[draw] = written[mark:]
    except BaseException:
        beside.wait()  # its pictures were never written here: nothing of it to remove
        raise
    for draw, files in zip(there, beside.result() if there else ()):
        done[draw] = []
        for name, data in files:
            done[draw].append(atomic_write_bytes(out_dir / name, data))
            written.append(done[draw][-1])
    written[:] = [f for d in order for f in done[d]]


def _rendered(draws) -> list[list[tuple[str, bytes]]]:
    """Each of ``draws`` (``draw(folder, into)``: pictures drawn into a folder, their paths
    appended to ``into``) drawn in a temporary folder, not staged (a forked child's staging is
    never published): per draw, its files' names and bytes."""
    import tempfile

    from ..io.atomic import unstaged

    out = []
    with unstaged(), tempfile.TemporaryDirectory(prefix="pinrecon-plots-") as tmp:
        for draw in draws:
            files: list[Path] = []
            draw(Path(tmp), files)
            out.append([(Path(p).name, Path(p).read_bytes()) for p in files])
    return out


def _per_camera_reprojection(result, tracks: Sequence, out_dir: Path, written: list | None = None) -> list[Path]:
    """``reprojection_<name>.png`` for each of the result's cameras and its tracks."""
    cams = list(getattr(result, "cameras", None) or [])
    if len(tracks) != len(cams):
        raise InputError(
            f"{len(tracks)} tracks for a result with {len(cams)} cameras "
            f"({', '.join(getattr(result, 'camera_names', []))}): give one tracks per camera, in order",
            field="tracks",
        )
    written = [] if written is None else written
    stems = set()
    for i, (name, trk) in enumerate(zip(result.camera_names, tracks)):
        stem = camera_file_stem(name)
        stem = stem if stem not in stems else f"{stem}_{i + 1}"
        stems.add(stem)
        fig = plot_reprojection(result, trk, camera=i)
        written.append(save_figure(fig, out_dir / f"reprojection_{stem}.png"))
    return written
