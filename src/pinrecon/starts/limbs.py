"""Limb chains, camera rays and the trunk's reflection: the geometry the
multi-hypothesis start (:mod:`.hypotheses`) enumerates over.

* :func:`limb_chains` - the figure's limbs among the tracked keypoints, in pieces of at
  most two segments (hip-knee-ankle, shoulder-elbow-wrist, then knee-ankle-toe ...).
* :func:`camera_rays`, :func:`sphere_ray`, :func:`ray_point_at_depth` - the two points
  of a camera ray at a segment's length from its start: the depth reflection, exact
  under perspective.
* :func:`clean_tracks` - the tracks on the reconstruction grid with isolated spikes
  (outliers, swapped labels) removed, gaps filled and noise smoothed.
* :func:`trunk_keypoints`, :func:`torso_flip` - the trunk's own reflection (a nearly
  planar quadrilateral of hips and shoulders has two poses with one image).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "LENGTH_RATIO_BOUNDS",
    "Chain",
    "camera_rays",
    "clean_tracks",
    "image_lengths",
    "kept_lengths",
    "length_ratios",
    "limb_chains",
    "limb_segments",
    "measured_lengths",
    "ray_point_at_depth",
    "sphere_ray",
    "torso_flip",
    "trunk_keypoints",
]


# ----------------------------------------------------------------------------- chains
@dataclass(frozen=True, eq=False)
class Chain:
    """A piece of a limb: a start keypoint (held where the base puts it) and up to two
    segments below it whose reflections are enumerated.

    names : (start, end of segment 1[, end of segment 2]) keypoint names.
    kp : their keypoint indices.
    lengths_m : (S,) the figure's segment lengths.
    v_mask : (nv,) tangent entries that move the chain's ends but not its start.
    """

    names: tuple[str, ...]
    kp: np.ndarray
    lengths_m: np.ndarray
    v_mask: np.ndarray

    @property
    def label(self) -> str:
        return "-".join(self.names)

    @property
    def n_segments(self) -> int:
        return len(self.names) - 1

    @property
    def n_states(self) -> int:
        return 2 ** self.n_segments


def _limb_paths(figure, names):
    """Maximal unbranched keypoint paths of the figure's limb triples among ``names``."""
    from ..planarity.calibrate import kinematic_triples

    nxt: dict[tuple[str, str], str] = {}
    segs_after: set[tuple[str, str]] = set()
    for (a, j, c), limb in kinematic_triples(figure, names):
        if limb:
            nxt[(a, j)] = c
            segs_after.add((j, c))
    paths = []
    for (a, j) in nxt:
        if (a, j) in segs_after:
            continue
        path = [a, j]
        while (path[-2], path[-1]) in nxt:
            path.append(nxt[(path[-2], path[-1])])
        paths.append(path)
    return paths


def limb_chains(figure, names, *, min_fraction: float = 0.25) -> list[list[Chain]]:
    """The limb chains of ``figure`` among the tracked keypoint ``names``, in passes.

    Every maximal unbranched path of limb triples (hip-knee-ankle-toe ...) is cut into
    pieces of at most two segments; segments shorter than ``min_fraction`` of the longest
    limb segment (toe ends, hand ends) are left out. Pass 0 holds the first piece of every
    path (rooted at a branching point: hip, shoulder), pass 1 the second pieces (rooted
    where pass 0 left off), and so on.
    """
    from ..planarity.calibrate import model_lengths

    paths = _limb_paths(figure, names)
    if not paths:
        return []
    all_segs = [(p[i], p[i + 1]) for p in paths for i in range(len(p) - 1)]
    L_all, _ = model_lengths(figure, all_segs)
    L_of = dict(zip(all_segs, L_all))
    longest = float(L_all.max())
    passes: list[list[Chain]] = []
    for p in paths:
        keep = [p[0]]
        for i in range(len(p) - 1):
            if L_of[(p[i], p[i + 1])] < min_fraction * longest:
                break
            keep.append(p[i + 1])
        pieces = [keep[i : i + 3] for i in range(0, len(keep) - 1, 2)]
        for k, piece in enumerate(pieces):
            if len(piece) < 2:
                continue
            start_mask = figure.support_mask([piece[0]])
            mask = figure.support_mask(piece[1:]) & ~start_mask
            chain = Chain(
                tuple(piece),
                figure.keypoint_index(piece),
                np.array([L_of[(piece[i], piece[i + 1])] for i in range(len(piece) - 1)]),
                mask,
            )
            while len(passes) <= k:
                passes.append([])
            passes[k].append(chain)
    return passes


# ----------------------------------------------------------------------------- geometry
def camera_rays(camera, uv_px):
    """World rays through pixels ``uv_px`` (..., 2): origins and unit directions (..., 3).
    Orthographic: origins on the camera's depth-0 plane, directions the optical axis;
    perspective: the camera centre and the undistorted pixel's direction."""
    uv = np.asarray(uv_px, float)
    R = np.asarray(camera.R, float)
    if hasattr(camera, "scale"):
        o = camera.backproject(uv, 0.0)
        d = np.broadcast_to(R[2], o.shape).copy()
        return o, d
    xy = camera.normalized(uv)
    d_cam = np.concatenate([xy, np.ones(xy.shape[:-1] + (1,))], axis=-1)
    d = d_cam @ R
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    o = np.broadcast_to(-R.T @ camera.t, d.shape).copy()
    return o, d


def sphere_ray(p, o, d, L):
    """The two points (near, far) of the ray ``o + lambda d`` (``d`` unit) at distance
    ``L`` from ``p`` (all (..., 3); ``L`` broadcast). Where the ray misses the sphere both
    are the ray's point closest to ``p``. Returns (near, far, discriminant)."""
    w = p - o
    b = np.einsum("...i,...i->...", w, d)
    disc = b * b - (np.einsum("...i,...i->...", w, w) - np.asarray(L, float) ** 2)
    s = np.sqrt(np.maximum(disc, 0.0))
    near = o + (b - s)[..., None] * d
    far = o + (b + s)[..., None] * d
    return near, far, disc


def limb_segments(figure, names) -> list[tuple[int, int]]:
    """The figure's limb segments among the tracked keypoint ``names``: ``(a, b)`` keypoint
    indices of each consecutive pair of every :func:`limb_chains` chain."""
    return [(c.kp[i], c.kp[i + 1]) for chains in limb_chains(figure, names) for c in chains
            for i in range(len(c.kp) - 1)]


def ray_point_at_depth(camera, uv, z):
    """The world point on the ray through ``uv`` (..., 2) at camera depth ``z`` (...)."""
    if hasattr(camera, "scale"):
        return camera.backproject(uv, z)
    x = camera.normalized(uv)
    x_cam = np.concatenate([x * z[..., None], z[..., None]], axis=-1)
    return (x_cam - camera.t) @ camera.R


def clean_tracks(problem, Q_base, camera=None) -> np.ndarray:
    """(T, K, 2) image positions of every keypoint on the reconstruction grid: the tracks,
    with isolated spikes removed (running median of 5 observations: outliers, swapped
    labels), gaps interpolated and noise smoothed (moving average over about 1/20 s);
    keypoints nobody tracks take ``Q_base``'s projection (through ``camera``, by default the
    problem's)."""
    fig, meas = problem.figure, problem.measurement
    T = len(Q_base)
    uv = (problem.camera if camera is None else camera).project(fig.keypoints(Q_base))
    if meas is None or not len(meas.frames):
        return uv
    t_all = np.arange(T)
    w = max(1, int(round((problem.fps or 30.0) / 20.0)))
    w += 1 - w % 2
    kern = np.ones(w) / w
    for m, k in enumerate(meas.keypoints):
        ok = meas.observed[:, m]
        if ok.sum() < 5:
            continue
        t_obs, x = meas.frames[ok], meas.uv_px[ok, m]
        pad = np.concatenate([x[:1], x[:1], x, x[-1:], x[-1:]])
        med = np.median(np.stack([pad[i : i + len(x)] for i in range(5)]), axis=0)
        for c in range(2):
            y = np.interp(t_all, t_obs, med[:, c])
            if w > 1:
                y = np.convolve(np.pad(y, w // 2, mode="edge"), kern, mode="valid")
            uv[:, k, c] = y
    return uv


def measured_lengths(problem, Q, pairs, percentile: float = 95.0, g=None) -> np.ndarray:
    """(P,) the 3D lengths of keypoint pairs (P, 2) measured from the tracks: each frame,
    the second point's image position (cleaned tracks, :func:`clean_tracks`) is put on its
    ray at the first point's depth in ``Q`` (the figure and camera at the globals ``g``,
    by default ``problem.g0``); a segment that swings through the image plane shows its full
    length there, so the ``percentile`` of those distances is its length (an underestimate
    for a segment that never crosses). NaN for a pair whose points are not both tracked in at
    least a tenth of the frames."""
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    meas = problem.measurement
    cam = problem.camera if g is None else problem.cameras_at(g)[0]
    uv = clean_tracks(problem, Q, cam)
    z = cam.depth(problem.keypoints(Q, g))
    seen = np.zeros(problem.figure.K)
    if meas is not None and len(meas.frames):
        seen[np.asarray(meas.keypoints)] = meas.observed.mean(axis=0)
    out = np.full(len(pairs), np.nan)
    for i, pair in enumerate(pairs):
        if seen[pair].min() >= 0.1:
            out[i] = float(np.percentile(image_lengths(cam, uv, z, pair)[:, 0], percentile))
    return out


#: :func:`length_ratios` beyond these bounds says the figure's lengths are not the subject's (the
#: human fitted to Pose2Sim's subject from one camera: 0.88-1.05 over its limb segments; a figure
#: calibrated on the CMU walk, reused on it: 0.87-1.03; the CMU walk's skeleton on Pose2Sim's
#: subject: upper arms, thighs and shanks 0.69-0.81, feet 1.18). Lower by more: a segment that
#: never swings through the image plane is measured short
LENGTH_RATIO_BOUNDS = (0.8, 1.15)


def length_ratios(problem, Q, g=None) -> dict[str, float]:
    """``{"left_hip-left_knee": ratio, ...}``: each limb segment of the figure, as the tracks
    measure it at the solution ``Q`` (:func:`measured_lengths` with the globals ``g``: the
    fitted camera), over its length on the figure: about 1 where the figure's proportions are
    the subject's (a uniform size is taken up by the depth). Empty but for one camera and a
    figure whose lengths the solve keeps (no proportions among its unknowns)."""
    if len(problem.views) != 1 or getattr(problem, "proportions", None) is not None or problem.measurement is None:
        return {}
    fig = problem.figure
    pairs = limb_segments(fig, list(problem.tracks.names))
    if not pairs:
        return {}
    P = problem.keypoints(Q, g)
    own = np.array([np.median(np.linalg.norm(P[:, b] - P[:, a], axis=-1)) for a, b in pairs])
    seen = measured_lengths(problem, Q, pairs, g=g)
    kn = fig.keypoint_names
    return {f"{kn[a]}-{kn[b]}": float(m / o) for (a, b), m, o in zip(pairs, seen, own) if np.isfinite(m) and o > 0}


def kept_lengths(problem, Q, g=None) -> dict:
    """``{"lengths_kept": {segment: ratio}}`` of :func:`length_ratios` for a result's
    ``calibration`` where the figure's lengths were kept and measured, else ``{}``."""
    ratios = length_ratios(problem, Q, g)
    return {"lengths_kept": {k: round(v, 3) for k, v in ratios.items()}} if ratios else {}


def image_lengths(camera, uv, z, path) -> np.ndarray:
    """(T, S) the lengths of the S segments of the keypoint path ``path`` (S + 1,) in
    every frame, each segment's end put on its ray at its start's depth: image positions
    ``uv`` (T, K, 2), camera depths ``z`` (T, K). Where a segment crosses the image plane
    this is its true length; elsewhere its projection, shorter."""
    path = np.asarray(path, dtype=int)
    pts = ray_point_at_depth(camera, uv[:, path], z[:, path])
    ends = ray_point_at_depth(camera, uv[:, path[1:]], z[:, path[:-1]])  # ends at their start's depth
    return np.linalg.norm(ends - pts[:, :-1], axis=-1)


def trunk_keypoints(figure, names, passes) -> list[str]:
    """Tracked keypoints that are not the moving end of any limb chain (hips, shoulders,
    face ...): the trunk whose own reflection :func:`torso_flip` tries."""
    ends = {n for chains in passes for c in chains for n in c.names[1:]}
    return [n for n in names if n not in ends]


def torso_flip(figure, Q, camera, trunk) -> np.ndarray:
    """``Q`` with the whole figure turned, frame by frame, by the rotation (about the
    trunk's centroid) that best maps the trunk keypoints onto their depth reflection
    about that centroid (each point moved along its own ray: the projection does not
    change). For a nearly planar trunk (hips and shoulders) this is the other member of
    its reflection pair (the Necker reversal); limbs keep their joint angles."""
    import pinocchio as pin

    from .keyframes import kabsch

    idx = figure.keypoint_index(trunk)
    P = figure.keypoints(Q)[:, idx]  # (T, n, 3)
    z = camera.depth(P)
    zc = z.mean(axis=1, keepdims=True)
    uv = camera.project(P)
    Pm = ray_point_at_depth(camera, uv, 2.0 * zc - z)
    out = Q.copy()
    for t in range(len(Q)):
        R, tr = kabsch(P[t], Pm[t])
        M = pin.SE3(R, tr) * pin.XYZQUATToSE3(Q[t, :7])
        out[t, :7] = pin.SE3ToXYZQUAT(M)
    return out
