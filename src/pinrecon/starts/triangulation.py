"""The several-camera start: triangulate the tracks, align the rest pose to the points,
fit the figure to them.

1. **Triangulate** (:func:`triangulate`): every tracked point seen by two or more
   cameras in a frame, by linear least squares on its undistorted rays; a point whose
   reprojection misses a camera's observation by more than ``max(10 px, 5 sigma_px)``
   is dropped (a mislabelled detection).
2. **Align** (:func:`aligned_rest`): the rest pose rigidly moved onto the triangulated
   points frame by frame (:func:`rigid_transform`, frames with three or more points),
   geodesically interpolated in between and held outside.
3. **Fit** (:func:`triangulation_start`): the figure fitted to the triangulated points
   as 3D point rows (``sigma_markers_m``, default 2 cm) with the problem's limits,
   smoothing and posture prior, in a short batch solve (as
   :func:`pinrecon.reconstruct_markers` does for motion capture). Points one camera
   alone sees are not triangulated: smoothing carries the figure through them, on the
   right side of the single view's depth ambiguity, and the batch solve that follows
   uses them.

The rest start (:func:`pinrecon.starts.rest.rest_start`) calls this when a problem has
several cameras, and falls back to the first camera's placement when nothing
triangulates (cameras that share no point).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ..errors import InputError
from ..problem import ReconstructionProblem, make_marker_problem, rest_pose
from ..solver import SolverOptions, solve
from ..tracks import Markers

__all__ = [
    "aligned_rest",
    "normalized_coords",
    "rigid_transform",
    "triangulate",
    "triangulated_tracks",
    "triangulation_start",
]


def normalized_coords(camera, uv_px) -> np.ndarray:
    """Undistorted normalised image coordinates ``x_cam[:2] / z`` (perspective: K and the
    lens distortion inverted, :meth:`~pinrecon.cameras.Perspective.normalized`) or metres
    in the image plane (orthographic: ``(uv - c) / s``) of pixels ``uv_px`` (..., 2)."""
    if hasattr(camera, "scale"):
        return (np.asarray(uv_px, float) - np.asarray(camera.center, float)) / camera.scale
    return camera.normalized(uv_px)


def triangulate(cameras: Sequence, uv_px: Sequence[np.ndarray]) -> np.ndarray:
    """World points from their pixels in several cameras (linear least squares).

    ``uv_px[c]`` (..., 2) are camera ``c``'s pixels of the same points, NaN where the
    camera does not see a point. Each view gives two linear equations in the world point
    ``X``: perspective ``(x R_3 - R_1) X = t_1 - x t_3`` (and the same for ``y``) with
    ``(x, y)`` the undistorted normalised coordinates; orthographic
    ``R_12 X = (uv - c) / s``. Returns (..., 3), NaN where fewer than two cameras see the
    point or the rays are near parallel.
    """
    shape = np.shape(uv_px[0])[:-1]
    A = np.zeros(shape + (3, 3))
    b = np.zeros(shape + (3,))
    n = np.zeros(shape, int)
    for cam, uv in zip(cameras, uv_px):
        uv = np.asarray(uv, float)
        ok = np.all(np.isfinite(uv), axis=-1)
        xy = normalized_coords(cam, np.where(ok[..., None], uv, 0.0))
        if hasattr(cam, "scale"):
            rows = np.broadcast_to(cam.R[:2], shape + (2, 3))
            rhs = xy
        else:
            rows = xy[..., :, None] * cam.R[2] - cam.R[:2]  # (..., 2, 3)
            rhs = cam.t[:2] - xy * cam.t[2]
        rows = np.where(ok[..., None, None], rows, 0.0)
        rhs = np.where(ok[..., None], rhs, 0.0)
        A += np.einsum("...ki,...kj->...ij", rows, rows)
        b += np.einsum("...ki,...k->...i", rows, rhs)
        n += ok
    X = np.full(shape + (3,), np.nan)
    w = np.linalg.eigvalsh(A) if A.size else np.zeros(shape + (3,))
    good = (n >= 2) & (w[..., 0] > 1e-6 * np.maximum(w[..., -1], 1e-300))
    if good.any():
        X[good] = np.linalg.solve(A[good], b[good][..., None])[..., 0]
    return X


def rigid_transform(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation ``R`` and translation ``t`` minimising ``sum |R a + t - b|^2`` over the
    rows of ``A`` and ``B`` (n, 3) (Kabsch)."""
    ca, cb = A.mean(0), B.mean(0)
    U, _, Vt = np.linalg.svd((A - ca).T @ (B - cb))
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    return R, cb - R @ ca


def triangulated_tracks(problem: ReconstructionProblem, max_error_px: float | None = None) -> np.ndarray:
    """(T, K, 3) the figure's keypoints triangulated from every camera's tracks on the
    problem's time grid; NaN where fewer than two cameras see a point, or where its
    reprojection misses an observation by more than ``max_error_px`` (default
    ``max(10, 5 sigma_px)``)."""
    T, K = problem.n_frames, len(problem.figure.keypoint_names)
    uv = []
    for m in problem.measurements:
        g = np.full((T, K, 2), np.nan)
        g[m.frames[:, None], m.keypoints[None, :]] = np.where(m.observed[..., None], m.uv_px, np.nan)
        uv.append(g)
    X = triangulate(problem.cameras, uv)
    limit = max(10.0, 5.0 * problem.weights.sigma_px) if max_error_px is None else float(max_error_px)
    ok = np.all(np.isfinite(X), axis=-1)
    bad = np.zeros_like(ok)
    for cam, g in zip(problem.cameras, uv):
        seen = ok & np.all(np.isfinite(g), axis=-1)
        err = np.linalg.norm(cam.project(np.where(ok[..., None], X, 0.0)) - np.where(seen[..., None], g, 0.0), axis=-1)
        bad |= seen & ~(err <= limit)
    X[bad] = np.nan
    return X


def aligned_rest(problem: ReconstructionProblem, X: np.ndarray) -> np.ndarray | None:
    """The rest pose rigidly aligned to the triangulated points ``X`` (T, K, 3) frame by
    frame, geodesically interpolated between aligned frames (held outside); None when no
    frame has three non-collinear points. A fixed-root figure stays at rest."""
    import pinocchio as pin

    figure = problem.figure
    q_rest = rest_pose(figure)
    T = problem.n_frames
    if not figure.floating:
        return np.tile(q_rest, (T, 1))
    ok = np.all(np.isfinite(X), axis=-1)
    P_rest = figure.keypoints(q_rest)
    M_root = pin.XYZQUATToSE3(q_rest[:7])
    poses = {}
    for t in np.where(ok.sum(axis=1) >= 3)[0]:
        A, B = P_rest[ok[t]], X[t, ok[t]]
        if np.linalg.matrix_rank(A - A.mean(0), tol=1e-3) < 2:
            continue
        R, p = rigid_transform(A, B)
        q = q_rest.copy()
        q[:7] = pin.SE3ToXYZQUAT(pin.SE3(R, p) * M_root)
        poses[int(t)] = q
    if not poses:
        return None
    frames = sorted(poses)
    Q = np.empty((T, figure.nq))
    for t in range(T):
        if t <= frames[0]:
            Q[t] = poses[frames[0]]
        elif t >= frames[-1]:
            Q[t] = poses[frames[-1]]
        else:
            k = int(np.searchsorted(frames, t, side="right"))
            a, b = frames[k - 1], frames[k]
            Q[t] = poses[a] if a == t else figure.interpolate(poses[a], poses[b], (t - a) / (b - a))
    return Q


def fit_triangulated(problem: ReconstructionProblem, sigma_m: float = 0.02, options: SolverOptions | None = None):
    """The figure fitted to the triangulated tracks (module docstring), or None when
    nothing triangulates."""
    X = triangulated_tracks(problem)
    Q0 = aligned_rest(problem, X)
    if Q0 is None:
        return None
    figure = problem.figure
    seen = np.all(np.isfinite(X), axis=-1).any(axis=0)
    names = [n for n, s in zip(figure.keypoint_names, seen) if s]
    idx = figure.keypoint_index(names)
    markers = Markers(X[:, idx], names, problem.fps)
    weights = replace(problem.weights, sigma_markers_m=sigma_m)
    mp = make_marker_problem(figure, markers, weights=weights)
    res = solve(mp, figure.clamp(Q0, margin=1e-3), options or SolverOptions(max_iterations=30, ftol=1e-4),
                active=problem.active)
    return figure.normalize(res.x)


def triangulation_start(problem: ReconstructionProblem) -> np.ndarray:
    """The several-camera start (module docstring): ``start(problem) -> Q0``."""
    if len(problem.views) < 2:
        raise InputError("the triangulation start needs two or more cameras", field="init")
    Q = fit_triangulated(problem)
    if Q is None:
        raise InputError(
            "no frame has three points seen by two or more cameras: nothing to triangulate", field="init"
        )
    return Q
