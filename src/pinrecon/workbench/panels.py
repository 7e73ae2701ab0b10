"""Pictures the workbench page shows as images: the camera's view (2D tracks with the
reprojection over them) and the timeline (per-frame reprojection error, keyframes, the
frames waiting for a solve, the current frame). Plain RGB arrays drawn with Pillow."""

from __future__ import annotations

import numpy as np

__all__ = ["image_view", "timeline"]

_LEFT, _RIGHT, _MID = (31, 111, 209), (209, 67, 31), (60, 60, 60)


def _colour(name: str):
    low = name.lower()
    return _LEFT if low.startswith("left") else _RIGHT if low.startswith("right") else _MID


def image_view(tracks_uv, model_uv, names, edges, *, bounds, size=(480, 360), keyed=None):
    """The image plane at one frame: tracked points (green rings), the figure's
    reprojection (coloured skeleton) and the residuals between them (red).

    tracks_uv, model_uv : (M, 2) pixels for ``names`` (NaN where missing).
    edges : pairs of indices into ``names``.
    bounds : (u_min, v_min, u_max, v_max) of the picture, pixels.
    keyed : optional bool (M,) marking keyed points (yellow squares).
    """
    from PIL import Image, ImageDraw

    W, H = size
    img = Image.new("RGB", (W, H), (250, 250, 247))
    d = ImageDraw.Draw(img)
    u0, v0, u1, v1 = bounds
    s = min((W - 20) / max(u1 - u0, 1e-6), (H - 20) / max(v1 - v0, 1e-6))
    ou = (W - s * (u1 - u0)) / 2 - s * u0
    ov = (H - s * (v1 - v0)) / 2 - s * v0

    def xy(p):
        return (float(ou + s * p[0]), float(ov + s * p[1]))

    ok_m = np.all(np.isfinite(model_uv), axis=1)
    ok_t = np.all(np.isfinite(tracks_uv), axis=1)
    for a, b in edges:
        if ok_m[a] and ok_m[b]:
            d.line([xy(model_uv[a]), xy(model_uv[b])], fill=_colour(names[b]), width=3)
    for i in range(len(names)):
        if ok_t[i] and ok_m[i]:
            d.line([xy(tracks_uv[i]), xy(model_uv[i])], fill=(220, 0, 0), width=1)
        if ok_t[i]:
            x, y = xy(tracks_uv[i])
            d.ellipse([x - 4, y - 4, x + 4, y + 4], outline=(0, 150, 60), width=2)
        if keyed is not None and keyed[i] and ok_m[i]:
            x, y = xy(model_uv[i])
            d.rectangle([x - 3, y - 3, x + 3, y + 3], fill=(230, 170, 0))
    d.text((6, 4), "camera view: tracks (green), reprojection (lines), residual (red)", fill=(90, 90, 90))
    return np.asarray(img)


#: the colour of the spans the multi-hypothesis start could not decide (timeline strip)
UNCERTAIN_RGB = (170, 60, 200)


def timeline(error_px, frame, *, keyframes=(), pending=None, uncertain=(), size=(480, 90)):
    """The sequence at a glance: reprojection error per frame (grey curve, its maximum
    written), keyframes (orange ticks), frames waiting for a solve (blue band), spans
    whose limb depth the multi-hypothesis start could not decide (``uncertain``: (first
    frame, frame after the last) pairs, a purple strip along the bottom: look there
    first), the current frame (red line)."""
    from PIL import Image, ImageDraw

    W, H = size
    T = len(error_px)
    img = Image.new("RGB", (W, H), (255, 255, 255))
    d = ImageDraw.Draw(img)

    def x(t):
        return 8 + (W - 16) * t / max(1, T - 1)

    if pending is not None:
        d.rectangle([x(pending[0]), 0, x(pending[1]), H], fill=(214, 230, 250))
    err = np.asarray(error_px, float)
    finite = np.isfinite(err)
    top = float(np.nanmax(err)) if finite.any() else 1.0
    top = top if top > 0 else 1.0
    pts = []
    for t in range(T):
        if finite[t]:
            pts.append((x(t), H - 12 - (H - 30) * err[t] / top))
        elif len(pts) > 1:
            d.line(pts, fill=(110, 110, 110), width=1)
            pts = []
        else:
            pts = []
    if len(pts) > 1:
        d.line(pts, fill=(110, 110, 110), width=1)
    for a, b in uncertain:
        d.rectangle([x(a), H - 20, max(x(a) + 1, x(max(a, b - 1))), H - 14], fill=UNCERTAIN_RGB)
    for f in keyframes:
        d.polygon([(x(f), 12), (x(f) - 5, 2), (x(f) + 5, 2)], fill=(230, 150, 0))
    d.line([(x(frame), 0), (x(frame), H)], fill=(200, 0, 0), width=2)
    legend = "; uncertain depth (purple)" if len(uncertain) else ""
    d.text((8, H - 11), f"reprojection error per frame (max {top:.1f} px); keyframes{legend}; frame {frame}",
           fill=(80, 80, 80))
    return np.asarray(img)
