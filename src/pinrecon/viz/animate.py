"""Animation of a reconstruction: the camera view and a second view side by side."""

from __future__ import annotations

import math
import os
import shutil
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_path
from ._common import (
    MissingDependencyError,
    as_motion,
    view_up,
    check_frames,
    default_camera,
    draw_contacts,
    draw_floor,
    draw_stick,
    floor_segment,
    height_ticks,
    legend_handles,
    new_figure,
    require_matplotlib,
    second_view_camera,
    skeleton,
    skeleton_points,
    square_limits,
    view_unit,
)

__all__ = ["animate"]

_MAX_GIF_FPS = 50.0  # browsers slow down GIF frames shorter than 20 ms


def animate(
    result,
    out_path: str | os.PathLike,
    camera=None,
    second_view=None,
    fps: float | None = None,
    frames: Sequence[int] | None = None,
    *,
    truth=None,
    max_frames: int = 150,
    dpi: float = 80,
    size_in: tuple[float, float] = (8.0, 4.2),
    up=None,
) -> Path:
    """Write an animation of the stick figure: camera view (left) and second view (right).

    Parameters
    ----------
    result : Result (or BvhMotion, or result NPZ path).
    out_path : ``.gif`` (matplotlib's PillowWriter) or ``.mp4`` (needs ffmpeg on PATH).
        Written atomically; the folder is created.
    camera, second_view, up : as in :func:`pinrecon.viz.plot_stick_strip`.
    fps : playback rate; default real time for the rendered frames (GIF capped at 50).
    frames : frame indices to render (default all); subsampled evenly to at most
        ``max_frames`` so files stay small (~1-2 MB GIF).
    truth : ground truth drawn in grey (nearest frame in time).
    dpi, size_in : picture size (default 640 x 336 pixels).

    Returns the path written. Bones follow the figure's kinematic tree
    (:attr:`pinrecon.Figure.parents_of_keypoints`, joined through joint origins where it
    leaves keypoints unconnected). The views keep fixed limits, so the figure travels.
    The reconstruction is drawn over the truth; a legend names the colours (left blue,
    right red); the second view's vertical axis reads heights, positive up. A result with
    a floor and contacts (``reconstruct(..., floor=...)``) also shows the floor's line and
    squares on the foot points in contact.
    """
    require_matplotlib()
    from matplotlib import animation as mpl_animation

    out_path = Path(out_path)
    suffix = out_path.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise InputError(
            f"animations are written as .gif or .mp4, got {out_path.name!r}", field="out_path"
        )
    if suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise MissingDependencyError(
            "writing MP4 needs ffmpeg on PATH (e.g. apt-get install ffmpeg, conda install ffmpeg); "
            "write a .gif instead, which needs only matplotlib"
        )
    motion = as_motion(result)
    T = len(motion.times)
    idx = np.arange(T) if frames is None else check_frames(frames, T)
    if max_frames < 1:
        raise InputError(f"must be at least 1, got {max_frames}", field="max_frames")
    step = max(1, math.ceil(len(idx) / max_frames))
    idx = idx[::step]
    if fps is None:
        fps = motion.fps / step if motion.fps > 0 else 10.0
    fps = float(fps)
    if not (fps > 0 and math.isfinite(fps)):
        raise InputError(f"must be a positive number, got {fps}", field="fps")
    if suffix == ".gif":
        fps = min(fps, _MAX_GIF_FPS)

    cam = camera if camera is not None else getattr(result, "camera", None)
    cam = cam or default_camera()
    feet = motion.feet
    up_w = view_up(cam, feet) if up is None else np.asarray(up, float) / np.linalg.norm(up)
    cam2 = second_view_camera(cam, second_view, up_w)
    sk = skeleton(motion.figure)
    P = skeleton_points(motion, sk, idx)
    TP = tsk = None
    if truth is not None:
        tmotion = as_motion(truth, "ground truth")
        tsk = skeleton(tmotion.figure)
        TP = skeleton_points(tmotion, tsk, [tmotion.frame_at(motion.times[f]) for f in idx])

    fidx = motion.figure.keypoint_index(feet.names) if feet is not None else None
    fig = new_figure(size_in, dpi=dpi)
    axes = fig.subplots(1, 2)
    artists = []
    for ax, view, title in zip(axes, (cam, cam2), ("camera view", "second view")):
        uv = view.project(P)
        tuv = view.project(TP) if TP is not None else None
        allp = (uv if tuv is None else np.concatenate([uv, tuv], axis=1)).reshape(-1, 2)
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        square_limits(ax, 0.5 * (lo + hi), 0.53 * float(np.max(hi - lo)) + 1e-9)
        unit = view_unit(view)
        if view is cam2 and unit == "m":
            title = f"{title}, {height_ticks(ax, feet.floor if feet else None, up_w)}"
        ax.set_title(f"{title} ({unit})", fontsize=9)
        ax.tick_params(labelsize=6)
        ax.grid(True, lw=0.3, alpha=0.5)
        t_art = f_art = c_art = None
        if tuv is not None:
            t_art = draw_stick(ax, tuv[0], tsk, truth=True, prefix="truth_")
        if feet is not None:
            centre = motion.keypoints3d[idx].reshape(-1, 3).mean(axis=0)
            f_art = draw_floor(ax, floor_segment(view, feet.floor, centre, 0.6 * _extent_m(motion, idx) + 1.0))
            c_art = draw_contacts(ax, np.zeros((0, 2)))
        artists.append((view, uv, tuv, draw_stick(ax, uv[0], sk), t_art, c_art))
    stamp = fig.suptitle(f"frame {idx[-1]}   t = {motion.times[idx[-1]]:.2f} s", fontsize=9)
    fig.legend(handles=legend_handles(TP is not None, feet is not None, feet is not None), loc="outside lower center",
               ncols=6, fontsize=7, frameon=False)
    fig.canvas.draw()  # lay out once, then freeze: no jitter, faster frames
    fig.set_layout_engine("none")

    def update(k):
        for view, uv, tuv, (pts, bones), t_art, c_art in artists:
            pts.set_data(uv[k, : sk.K, 0], uv[k, : sk.K, 1])
            bones.set_segments([uv[k, [a, b]] for a, b in sk.edges])
            if t_art is not None:
                t_art[0].set_data(tuv[k, : tsk.K, 0], tuv[k, : tsk.K, 1])
                t_art[1].set_segments([tuv[k, [a, b]] for a, b in tsk.edges])
            if c_art is not None:
                on = view.project(motion.keypoints3d[idx[k], fidx[feet.contact[idx[k]]]]).reshape(-1, 2)
                c_art.set_data(on[:, 0], on[:, 1])
        stamp.set_text(f"frame {idx[k]}   t = {motion.times[idx[k]]:.2f} s")

    animated = [stamp]
    for _, _, _, arts, t_art, c_art in artists:
        animated += list(arts) + (list(t_art) if t_art is not None else []) + ([c_art] if c_art is not None else [])
    animated.sort(key=lambda a: a.get_zorder())  # blitting draws in this order: the truth under the reconstruction
    with atomic_path(out_path) as tmp:
        if suffix == ".gif":
            _write_gif(tmp, _blit_frames(fig, animated, update, len(idx)), fps)
        else:
            writer = mpl_animation.FFMpegWriter(
                fps=fps, codec="h264", extra_args=["-pix_fmt", "yuv420p"]
            )
            with writer.saving(fig, str(tmp), dpi):
                for k in range(len(idx)):
                    update(k)
                    writer.grab_frame()
    return out_path


def _extent_m(motion, idx) -> float:
    """The largest distance the keypoints spread over the rendered frames, metres."""
    P = motion.keypoints3d[idx].reshape(-1, 3)
    return float(np.max(P.max(axis=0) - P.min(axis=0)))


def _blit_frames(fig, animated, update, n):
    """Yield RGBA frames (H, W, 4): the static parts (axes, ticks, titles) are drawn once
    and the moving artists are drawn over a copy of that background (about ten times
    faster than redrawing the whole figure)."""
    canvas = fig.canvas
    for a in animated:
        a.set_animated(True)
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)
    for k in range(n):
        update(k)
        canvas.restore_region(background)
        for a in animated:
            fig.draw_artist(a)
        yield np.asarray(canvas.buffer_rgba()).copy()


def _write_gif(path, frames, fps: float) -> None:
    """Encode RGBA frames as a looping GIF with Pillow (what matplotlib's PillowWriter does)."""
    from PIL import Image

    images = [Image.fromarray(f, "RGBA") for f in frames]
    # GIF delays are whole centiseconds: spread the rounding so the clip plays in real time
    ends_cs = np.round(np.arange(1, len(images) + 1) * 100.0 / fps).astype(int)
    durations_ms = (np.diff(ends_cs, prepend=0) * 10).tolist()
    images[0].save(
        path,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=durations_ms if len(images) > 1 else durations_ms[0],
        loop=0,
    )
