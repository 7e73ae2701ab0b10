"""pinrecon's own 2D-to-3D lifter: learned depth for tracks that carry no 3D cues.

``lift(tracks, camera=None) -> Lifted`` estimates, per frame, the 12 COCO-17 body points
(shoulders, elbows, wrists, hips, knees, ankles) relative to the hips' midpoint, in the
camera's axes (OpenCV: x right, y down, z forward), from a window of 2D frames around it.
It is a temporal convolution (VideoPose3D's shape: kernel 3, dilations 1, 3, 9, 27, a
receptive field of 81 frames at the model's 30 frames per second) whose weights ship in
``models/lifter/lifter.npz`` (trained by ``tools/train_lifter.py``, model card
``models/lifter/README.md``). Inference is NumPy alone.

Its sizes are in metres for a figure whose limb segments (upper arm, forearm, thigh, shank)
average 40 cm: the lifter is scale-free, and :class:`pinrecon.lifted.Lifted` is used as one.
Each point's confidence is ``1 / (1 + (sigma / 0.1 m)^2)`` of the lifter's own predicted
spread ``sigma`` (a Gaussian's standard deviation, per point and frame): an inverse variance
relative to 10 cm, bounded by 1 (rows weigh a point by its confidence).

Call::

    from pinrecon.lifter import lift
    tracks.lifted = lift(tracks, camera)   # camera: a Perspective (or None: unknown)
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ._resources import model_path
from .errors import InputError
from .io.calibration import CalibratedCamera
from .layouts import normalise_point_name
from .lifted import Lifted

__all__ = [
    "BODY",
    "CONFIDENCE_SIGMA_M",
    "DEFAULT_LIFTER",
    "HALF_WINDOW",
    "LIFTERS",
    "LIMB_LENGTH_M",
    "MODEL_FPS",
    "LifterModel",
    "attach_lifter",
    "features",
    "lift",
    "load_lifter",
    "on_rays",
    "resolve_lifter",
]

#: the lifter's points, in its input and output order
BODY = ("left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
        "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle")
#: frames either side of the predicted frame the model sees (at its rate)
HALF_WINDOW = 40
#: the frame rate the model was trained at; faster tracks are read every round(fps / 30) frames
MODEL_FPS = 30.0
#: the output's unit: a figure whose mean limb segment is this long comes out in metres
LIMB_LENGTH_M = 0.40
#: confidence = 1 / (1 + (sigma / CONFIDENCE_SIGMA_M)^2)
CONFIDENCE_SIGMA_M = 0.10
#: ``lifter=`` values besides a weights file: the shipped weights, or none
LIFTERS = ("auto", "none")
#: what ``reconstruct`` does without a ``lifter=``: the shipped weights, joining with the broader
#: pose prior where the default does not know the clip (the prior stage's switch) (measured: bench/README.md, ``bench_lifter.py``)
DEFAULT_LIFTER = "auto"
#: at least this many of :data:`BODY` tracked for the lifter to run by default
MIN_BODY_POINTS = 8
#: per-frame input channels: 12 x (x, y, confidence), centre velocity (2), camera cues (4)
N_FEATURES = 3 * len(BODY) + 2 + 4


def _fill_nearest(values: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Frames (axis 0 of ``values`` (T, ...)) where ``valid`` is False take the nearest valid
    frame's values (all zeros when no frame is valid)."""
    T = len(values)
    idx = np.flatnonzero(valid)
    if idx.size == 0:
        return np.zeros_like(values)
    pos = np.searchsorted(idx, np.arange(T))
    lo, hi = idx[np.clip(pos - 1, 0, idx.size - 1)], idx[np.clip(pos, 0, idx.size - 1)]
    near = np.where(np.abs(np.arange(T) - lo) <= np.abs(hi - np.arange(T)), lo, hi)
    return values[near]


def _fill_batch(values: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """:func:`_fill_nearest` over the leading batch axes of ``values`` (..., T[, D])."""
    bad = ~np.all(valid, axis=-1)
    if not np.any(bad):
        return values
    if valid.ndim == 1:
        return _fill_nearest(values, valid)
    out = values.copy()
    for i in zip(*np.nonzero(bad)):
        out[i] = _fill_nearest(values[i], valid[i])
    return out


def features(xy: np.ndarray, conf: np.ndarray, *, stride: int = 1, known=False) -> np.ndarray:
    """Per-frame input channels (..., T, N_FEATURES) of the lifter, for training and inference.

    ``xy`` (..., T, 12, 2) image points of :data:`BODY` (NaN where missing), in normalised
    camera coordinates (``x_cam / z``) where ``known`` (the camera's intrinsics are known; a
    bool, or one per leading index), else in any image unit (pixels); ``conf`` (..., T, 12)
    in [0, 1] (0 where missing); ``stride`` the frames between two of the model's steps. Each
    frame is centred on its points' confidence-weighted mean and divided by the person's size
    (the median, over the model's window, of the points' RMS distance to that centre); the
    centre's velocity per model step in sizes follows, and, where ``known``, the centre's
    ray, the log of the size and a flag.
    """
    xy = np.asarray(xy, float)
    T, K = xy.shape[-3:-1]
    d = max(int(stride), 1)
    w = np.where(np.all(np.isfinite(xy), axis=-1), np.clip(np.nan_to_num(np.asarray(conf, float)), 0.0, 1.0), 0.0)
    x0 = np.where(w[..., None] > 0, np.nan_to_num(xy), 0.0)
    sw = w.sum(-1)
    valid = sw > 0
    c = (w[..., None] * x0).sum(-2) / np.maximum(sw, 1e-12)[..., None]
    c = _fill_batch(c, valid)
    r = np.sqrt((w * ((x0 - c[..., None, :]) ** 2).sum(-1)).sum(-1) / np.maximum(sw, 1e-12))
    ok = valid & (r > 0)
    r = np.where(np.any(ok, axis=-1, keepdims=True), _fill_batch(r, ok), 1.0)
    h = HALF_WINDOW * d
    pad = [(0, 0)] * (r.ndim - 1) + [(h, h)]
    win = np.lib.stride_tricks.sliding_window_view(np.pad(r, pad, mode="edge"), 2 * h + 1, axis=-1)[..., ::d]
    s = np.median(win, axis=-1)
    rel = (x0 - c[..., None, :]) / s[..., None, None] * (w[..., None] > 0)
    prev = c[..., np.maximum(np.arange(T) - d, 0), :]
    out = np.zeros(xy.shape[:-3] + (T, N_FEATURES))
    out[..., : 3 * K] = np.concatenate([rel, w[..., None]], axis=-1).reshape(xy.shape[:-3] + (T, 3 * K))
    out[..., 3 * K: 3 * K + 2] = (c - prev) / s[..., None]
    kn = np.broadcast_to(np.asarray(known, bool), xy.shape[:-3])[..., None]
    out[..., 3 * K + 2: 3 * K + 4] = np.where(kn[..., None], c, 0.0)
    out[..., 3 * K + 4] = np.where(kn, np.log(s), 0.0)
    out[..., 3 * K + 5] = np.where(kn, 1.0, 0.0)
    return out


@dataclass(eq=False)
class LifterModel:
    """The lifter's weights (BatchNorm folded in) and what the training tool recorded."""

    layers: dict
    meta: dict
    path: str | None = None

    def predict(self, X: np.ndarray, stride: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Network outputs for per-frame features ``X`` (T, N_FEATURES) (:func:`features`):
        root-relative points (T, 12, 3) in limb lengths and log spreads (T, 12). Edges are
        padded by repeating the first and last frame's features."""
        L = self.layers
        d = max(int(stride), 1)
        X = np.asarray(X, np.float64)
        T = len(X)
        h = np.concatenate([np.repeat(X[:1], HALF_WINDOW * d, 0), X, np.repeat(X[-1:], HALF_WINDOW * d, 0)])

        def conv(x, W, b, dil):
            n = len(x) - 2 * dil
            return x[:n] @ W[0] + x[dil: dil + n] @ W[1] + x[2 * dil:] @ W[2] + b

        h = np.maximum(conv(h, L["in_W"], L["in_b"], d), 0.0)
        for k, dil in enumerate((3, 9, 27)):
            dil *= d
            res = h[dil:-dil]
            y = np.maximum(conv(h, L[f"b{k}_W1"], L[f"b{k}_b1"], dil), 0.0)
            y = np.maximum(y @ L[f"b{k}_W2"] + L[f"b{k}_b2"], 0.0)
            h = res + y
        out = h @ L["out_W"] + L["out_b"]
        assert len(out) == T
        n = len(BODY)
        return out[:, : 3 * n].reshape(T, n, 3), out[:, 3 * n:]


def load_lifter(path: str | Path | None = None) -> LifterModel:
    """The lifter's weights from ``path`` (default: the shipped ``models/lifter/lifter.npz``)."""
    return _load(str(path) if path is not None else str(model_path("lifter", "lifter.npz")))


@lru_cache(maxsize=4)
def _load(path: str) -> LifterModel:
    import json

    try:
        with np.load(path, allow_pickle=False) as z:
            layers = {k: np.asarray(z[k], np.float64) for k in z.files if not k.startswith(("meta", "fixture_"))}
            meta = json.loads(str(z["meta"])) if "meta" in z.files else {}
    except (OSError, ValueError, KeyError) as exc:
        raise InputError(f"cannot read lifter weights ({exc})", file=path) from None
    need = ["in_W", "in_b", "out_W", "out_b"] + [f"b{k}_{p}" for k in range(3) for p in ("W1", "b1", "W2", "b2")]
    missing = [k for k in need if k not in layers]
    if missing:
        raise InputError(f"lifter weights lack {missing}", file=path, field="lifter")
    if layers["in_W"].ndim != 3 or layers["in_W"].shape[:2] != (3, N_FEATURES):
        raise InputError(f"lifter weights take {layers['in_W'].shape[1:2]} features in kernels of shape "
                         f"{layers['in_W'].shape}, this pinrecon makes (3, {N_FEATURES}, channels)",
                         file=path, field="in_W")
    H = layers["in_W"].shape[2]
    shapes = {"in_b": (H,), "out_W": (H, 4 * len(BODY)), "out_b": (4 * len(BODY),)}
    for k in range(3):
        shapes.update({f"b{k}_W1": (3, H, H), f"b{k}_b1": (H,), f"b{k}_W2": (H, H), f"b{k}_b2": (H,)})
    for key, shape in shapes.items():
        if layers[key].shape != shape:
            raise InputError(f"lifter weights {key} have shape {layers[key].shape}, expected {shape} ({H} channels, "
                             f"{len(BODY)} points x (x, y, z, log spread) out)", file=path, field=key)
    return LifterModel(layers, meta, path)


def _bare(camera):
    """The camera itself of a calibration file's :class:`~pinrecon.io.calibration.CalibratedCamera`
    (as ``load_cameras`` and ``pinrecon reconstruct --camera FILE`` give it), else ``camera``."""
    return camera.camera if isinstance(camera, CalibratedCamera) else camera


def _camera_ray(camera, uv: np.ndarray) -> np.ndarray | None:
    """Normalised camera coordinates of pixels ``uv`` when ``camera`` is a perspective one."""
    camera = _bare(camera)
    if camera is None or not hasattr(camera, "normalized"):
        return None
    return camera.normalized(uv)


def lift(tracks, camera=None, *, model: LifterModel | None = None) -> Lifted:
    """The lifter's 3D estimate of ``tracks``' body points, as :class:`pinrecon.lifted.Lifted`
    with frame ``"camera"`` (the axes of ``camera``, or of whatever camera took the tracks).

    ``tracks``: :class:`pinrecon.Tracks` whose names (any layout the human keypoint maps know)
    include at least some of the 12 COCO-17 body points; missing points (NaN, confidence 0)
    are allowed. ``camera``: a :class:`pinrecon.cameras.Perspective` (its intrinsics make the
    lifter's perspective cues exact; a calibration file's ``CalibratedCamera`` is its camera),
    or ``None``. Returns the 12 points relative to the hips'
    midpoint, metres for a figure whose limb segments average 40 cm, and per-point confidence.
    """
    model = model or load_lifter()
    names = [normalise_point_name(n) for n in tracks.names]
    index = {n: i for i, n in enumerate(names)}
    have = [n for n in BODY if n in index]
    if len(have) < 4:
        raise InputError(f"the lifter needs the COCO-17 body points {list(BODY)}; the tracks have {have}",
                         file=tracks.source, field="names")
    T = tracks.T if hasattr(tracks, "T") else len(tracks.points)
    uv = np.full((T, len(BODY), 2), np.nan)
    conf = np.zeros((T, len(BODY)))
    tconf = tracks.confidence if getattr(tracks, "confidence", None) is not None else np.ones(tracks.points.shape[:2])
    for j, n in enumerate(BODY):
        if n in index:
            uv[:, j] = tracks.points[:, index[n]]
            conf[:, j] = tconf[:, index[n]]
    conf = np.where(np.all(np.isfinite(uv), axis=2), np.nan_to_num(conf), 0.0)
    xy = _camera_ray(camera, uv)
    stride = max(1, round(float(tracks.fps) / MODEL_FPS)) if getattr(tracks, "fps", None) else 1
    X = features(xy if xy is not None else uv, conf, stride=stride, known=xy is not None)
    P, log_sigma = model.predict(X, stride)
    P = P - P[:, [BODY.index("left_hip"), BODY.index("right_hip")]].mean(1, keepdims=True)
    sigma_m = np.exp(log_sigma) * LIMB_LENGTH_M
    return Lifted(P * LIMB_LENGTH_M, list(BODY), 1.0 / (1.0 + (sigma_m / CONFIDENCE_SIGMA_M) ** 2), "camera",
                  f"pinrecon lifter ({Path(model.path).name if model.path else 'weights'})", 0)


def on_rays(lifted: Lifted, tracks, camera) -> Lifted:
    """``lifted`` (``frame="camera"``, :func:`lift`'s output) with each point moved onto its
    detection's ray at the lifter's depth: the image decides where the points are across the
    view, the lifter only how far each is in depth.

    Per frame, the points' camera coordinates become ``(x_j Z_j, y_j Z_j, Z_j)`` with ``(x_j,
    y_j)`` the detection's normalised coordinates (``camera.normalized``; an orthographic
    camera: ``(uv - center) / scale`` at one depth) and ``Z_j = Z_0 + z_j``, ``z_j`` the
    lifter's depth relative to its hips and ``Z_0`` the distance that makes the detections'
    spread across the view (about their confidence-weighted mean) the lifter's in its own
    units (least squares). Points the tracks miss keep the lifter's position; a point's
    confidence is the smaller of the lifter's and the detection's. Unit-free as the lifter.
    """
    camera = _bare(camera)
    names = [normalise_point_name(n) for n in tracks.names]
    index = {n: i for i, n in enumerate(names)}
    K = len(lifted.names)
    uv = np.full((lifted.T, K, 2), np.nan)
    det = np.zeros((lifted.T, K))
    tconf = tracks.confidence if getattr(tracks, "confidence", None) is not None else np.ones(tracks.points.shape[:2])
    for j, n in enumerate(lifted.names):
        if n in index:
            uv[:, j] = tracks.points[:, index[n]]
            det[:, j] = tconf[:, index[n]]
    seen = np.all(np.isfinite(uv), axis=-1) & (det > 0) & (lifted.confidence > 0)
    if hasattr(camera, "normalized"):
        xy = camera.normalized(np.where(seen[..., None], uv, 0.0))
        perspective = True
    else:
        xy = (np.where(seen[..., None], uv, 0.0) - np.asarray(camera.center, float)) / float(camera.scale)
        perspective = False
    P = lifted.points
    w = np.where(seen, det, 0.0)
    sw = np.maximum(w.sum(1, keepdims=True), 1e-12)
    xy_c = xy - (w[..., None] * xy).sum(1, keepdims=True) / sw[..., None]
    XY = np.nan_to_num(P[..., :2])
    XY_c = XY - (w[..., None] * XY).sum(1, keepdims=True) / sw[..., None]
    num = (w * (xy_c * XY_c).sum(-1)).sum(1)
    den = (w * (xy_c ** 2).sum(-1)).sum(1)
    Z0 = np.where(den > 1e-12, num / np.maximum(den, 1e-12), np.nan)  # lifter units per normalised unit
    ok = seen & (np.isfinite(Z0) & (Z0 > 0))[:, None]
    z = np.nan_to_num(P[..., 2])
    Z = Z0[:, None] + (z if perspective else 0.0)
    out = P.copy()
    out[..., 0] = np.where(ok, xy[..., 0] * Z, P[..., 0])
    out[..., 1] = np.where(ok, xy[..., 1] * Z, P[..., 1])
    out[..., 2] = np.where(ok, Z if perspective else z, P[..., 2])
    conf = np.where(ok, np.minimum(lifted.confidence, np.clip(det, 0.0, 1.0)), lifted.confidence)
    return Lifted(out, list(lifted.names), conf, lifted.frame, lifted.source, lifted.camera)


def resolve_lifter(lifter):
    """``lifter`` as :func:`attach_lifter` takes it, a weights file read now (an InputError
    naming the file and the layer when it is not a lifter's): ``"auto"``, ``"none"`` or a
    :class:`LifterModel`."""
    if lifter is None or lifter is False:
        return "none"
    if isinstance(lifter, LifterModel):
        return lifter
    text = str(lifter).strip()
    if text.lower() in LIFTERS:
        return text.lower()
    return load_lifter(text)


def attach_lifter(figure, tracks, camera, lifter="auto", *, intrinsics: bool = True):
    """``tracks`` with pinrecon's lifter's 3D cues attached (``Tracks.lifted``, for the
    lifted-pose rows of :mod:`pinrecon.rows.lifted`) where it applies, else ``tracks`` as given.

    ``lifter``: ``"auto"`` (the shipped weights), ``"none"`` (``None``, ``False``: off), a
    weights file, or a :class:`LifterModel`. It applies to one camera's tracks (a
    :class:`pinrecon.Tracks`, or a list of one) that carry no 3D cues of their own
    (``lifted`` is ``None``) and hold at least :data:`MIN_BODY_POINTS` of the 12 COCO-17 body
    points (any layout :mod:`pinrecon.layouts` names them in), and with ``"auto"`` only for
    the generic human (``Figure.human()``, ``meta["generic"] == "human"``); several cameras
    see depth and are left alone. ``camera``: the view's camera (``Perspective`` or
    ``Orthographic``, or a calibration file's ``CalibratedCamera``); ``intrinsics=False`` when
    it is a guess (the auto camera): the lifter then reads pixels, and the camera only places
    the points on their rays (:func:`on_rays`).
    """
    if lifter is None or lifter is False or isinstance(lifter, str) and lifter.strip().lower() == "none":
        return tracks
    several = isinstance(tracks, (list, tuple))
    if several and len(tracks) != 1:
        return tracks
    one = tracks[0] if several else tracks
    cam = _bare(camera[0] if isinstance(camera, (list, tuple)) else camera)
    if getattr(one, "lifted", None) is not None or not hasattr(cam, "R"):
        return tracks
    auto = isinstance(lifter, str) and lifter.strip().lower() == "auto"
    if auto and (getattr(figure, "meta", None) or {}).get("generic") != "human":
        return tracks
    names = [normalise_point_name(n) for n in one.names]
    seen = one.observed.any(axis=0) if hasattr(one, "observed") else np.ones(len(names), bool)
    have = {n for n, s in zip(names, seen) if s} & set(BODY)
    if len(have) < MIN_BODY_POINTS:
        if auto:
            return tracks
        raise InputError(f"the lifter needs at least {MIN_BODY_POINTS} of the COCO-17 body points {list(BODY)}; "
                         f"the tracks have {sorted(have)}", file=one.source, field="names")
    model = lifter if isinstance(lifter, LifterModel) else load_lifter(None if auto else lifter)
    lifted = on_rays(lift(one, cam if intrinsics else None, model=model), one, cam)
    own = {n: t for n, t in zip(names, one.names)}
    keep = [j for j, n in enumerate(lifted.names) if n in own]
    lifted = Lifted(lifted.points[:, keep], [own[lifted.names[j]] for j in keep], lifted.confidence[:, keep],
                    lifted.frame, lifted.source, lifted.camera)
    from dataclasses import replace

    out = replace(one, lifted=lifted)
    return [out] if several else out
