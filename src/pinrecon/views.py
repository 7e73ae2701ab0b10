"""Which tracks each camera saw and the time grid they share: the views of a problem
(:func:`pinrecon.problem.make_problem` pairs tracks with cameras and puts them on one grid of
reconstruction frames)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .errors import InputError
from .io.calibration import CalibratedCamera
from .tracks import Tracks

__all__ = ["camera_views", "upsample_factor", "view_grid"]


def upsample_factor(fps_obs: float, fps_out: float | None) -> int:
    """Reconstruction frames per observed frame (``fps_out`` an integer multiple of ``fps_obs``)."""
    if fps_out is None:
        return 1
    ratio = float(fps_out) / float(fps_obs)
    factor = round(ratio)
    if factor < 1 or abs(ratio - factor) > 1e-6 * ratio:
        raise InputError(
            f"fps_out {fps_out:g} must be an integer multiple of the tracks' {fps_obs:g} fps", field="fps_out"
        )
    return factor


def camera_views(tracks, camera) -> list[tuple[str, Tracks, object]]:
    """Pair tracks with cameras: ``(name, tracks, camera)`` per camera, in order.

    ``tracks`` and ``camera`` are one :class:`Tracks` and one camera, or two sequences of
    the same length paired in order. A camera may be a
    :class:`~pinrecon.io.calibration.CalibratedCamera` (from
    :func:`~pinrecon.io.calibration.load_cameras`), whose name is kept; other cameras are
    named ``camera1``, ``camera2``, ...
    """
    many = isinstance(tracks, (list, tuple)) or isinstance(camera, (list, tuple))
    tl = list(tracks) if isinstance(tracks, (list, tuple)) else [tracks]
    cl = list(camera) if isinstance(camera, (list, tuple)) else [camera]
    if len(tl) != len(cl):
        raise InputError(
            f"{len(tl)} tracks but {len(cl)} cameras: give one camera per tracks, paired in order", field="camera"
        )
    if not tl:
        raise InputError("no tracks given", field="tracks")
    out, seen = [], set()
    for i, (trk, cam) in enumerate(zip(tl, cl)):
        where = f"[{i}]" if many else ""
        name = f"camera{i + 1}"
        if isinstance(cam, CalibratedCamera):
            name, cam = cam.name, cam.camera
        if not isinstance(trk, Tracks):
            raise InputError(f"tracks must be a pinrecon.Tracks, got {type(trk).__name__}", field=f"tracks{where}")
        if not (hasattr(cam, "project") and hasattr(cam, "project_with_jacobian")):
            raise InputError(
                f"camera must be a pinrecon camera (Orthographic, Perspective) or a CalibratedCamera, "
                f"got {type(cam).__name__}",
                field=f"camera{where}",
            )
        if name in seen:
            name = f"{name}#{i + 1}"
        seen.add(name)
        out.append((name, trk, cam))
    return out


def view_grid(tracks: Sequence[Tracks], names: Sequence[str], *, fps_out=None, factor=None) -> tuple[list[int], int, float]:
    """The reconstruction's time grid for several cameras' tracks: ``(factors, T, fps)``.

    Frame ``i`` of camera ``c``'s tracks is reconstruction frame ``i * factors[c]``: every
    camera's tracks start at the same instant (the first frame). The grid runs at
    ``fps_out`` (or ``factor`` times the first camera's rate), by default the highest
    camera rate, which every camera's rate must divide. The cameras must end together:
    each one's last frame within one of its own frame periods of the grid's end (with one
    rate: the same number of frames). Anything else is one clear error.
    """
    tracks = list(tracks)
    for t, name in zip(tracks, names):
        if t.T < 1:
            who = "tracks" if len(tracks) == 1 else f"tracks of camera {name!r}"
            raise InputError(f"{who} have no frames", file=t.source, field="points")
    if len(tracks) == 1:
        t = tracks[0]
        f = upsample_factor(t.fps, fps_out) if factor is None else int(factor)
        return [f], (t.T - 1) * f + 1, t.fps * f
    if factor is not None:
        fps = tracks[0].fps * int(factor)
    else:
        fps = float(fps_out) if fps_out is not None else max(t.fps for t in tracks)
    factors = []
    for t, name in zip(tracks, names):
        ratio = fps / t.fps
        f = round(ratio)
        if f < 1 or abs(ratio - f) > 1e-6 * ratio:
            rates = ", ".join(f"{n!r} {u.fps:g} fps" for n, u in zip(names, tracks))
            hint = ""
            if all(float(u.fps).is_integer() for u in tracks):
                hint = f" (e.g. fps_out={math.lcm(*[int(u.fps) for u in tracks])})"
            raise InputError(
                f"the cameras run at different rates ({rates}) and {t.fps:g} fps does not divide the "
                f"reconstruction's {fps:g} fps: pass fps_out, a common multiple of every camera's rate{hint}",
                file=t.source,
                field="fps_out" if fps_out is not None else "fps",
            )
        factors.append(f)
    spans = [(t.T - 1) * f for t, f in zip(tracks, factors)]
    T = max(spans) + 1
    for t, f, span, name in zip(tracks, factors, spans, names):
        if (T - 1) - span >= f:
            longest = int(np.argmax(spans))
            raise InputError(
                f"camera {name!r} has {t.T} frames at {t.fps:g} fps ({(t.T - 1) / t.fps:.3f} s) but camera "
                f"{names[longest]!r} has {tracks[longest].T} frames at {tracks[longest].fps:g} fps "
                f"({(tracks[longest].T - 1) / tracks[longest].fps:.3f} s): the cameras' tracks must start at the "
                f"same instant and end together; cut them to the same span with Tracks.frames(start, stop)",
                file=t.source,
                field="points",
            )
    return factors, T, fps


# ----------------------------------------------------------------------------- builders
