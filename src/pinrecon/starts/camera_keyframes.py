"""Cameras from 3D keyframes: where point keyframes (3D positions in a world of the
user's) and the tracks at the keyed frames put a camera.

* :func:`camera_from_keyframes`: rotation, position and focal length (a direct linear
  transform refined on the reprojection error), 6 points or more;
* :func:`camera_pose_from_keyframes`: rotation and position at a known focal length
  (perspective-n-point), 4 points or more; what places the auto camera when the
  keyframes cannot fix its focal length (:func:`keyframe_focal_interval`: their
  reprojection cost profiled over the focal length, the pose re-fitted at each);
* :func:`orthographic_from_keyframes`: an orthographic camera;
* :func:`camera_scale_from_keyframes`: a given camera's focal length (or scale) only,
  in closed form (the start of a calibrated solve).

:mod:`pinrecon.starts.camera_auto` uses them for the auto camera.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..cameras import Orthographic, Perspective

__all__ = [
    "PROFILE_THRESHOLD",
    "camera_from_keyframes",
    "camera_pose_from_keyframes",
    "camera_scale_from_keyframes",
    "keyframe_correspondences",
    "keyframe_focal_interval",
    "orthographic_from_keyframes",
]

#: a cost rise (nats) that rules a focal length out: chi-square(1) / 2 at 95 %
PROFILE_THRESHOLD = 1.92


def keyframe_correspondences(tracks, keyframes) -> tuple[np.ndarray, np.ndarray]:
    """World points (N, 3) of the point keyframes and the tracks' pixels (N, 2) of the
    same points at the same frames (keyframe frames index the tracks), observed ones only."""
    X, uv = [], []
    names = {n: i for i, n in enumerate(tracks.names)}
    for k in keyframes or ():
        if k.points is None or not (0 <= k.frame < tracks.T):
            continue
        for name, p in k.points.items():
            j = names.get(name)
            if j is None:
                continue
            u = tracks.points[k.frame, j]
            if np.all(np.isfinite(u)) and np.all(np.isfinite(p)):
                X.append(np.asarray(p, float))
                uv.append(u)
    return np.reshape(X, (-1, 3)), np.reshape(uv, (-1, 2))


def camera_scale_from_keyframes(camera, tracks, keyframes, min_points: int = 6):
    """``camera`` with its focal length (perspective; fx and fy together, the principal
    point fixed) or scale (orthographic) set to the least-squares value that projects
    the point keyframes onto the tracks at the keyed frames; ``camera`` itself when
    fewer than ``min_points`` correspondences exist or the camera has lens distortion.

    Perspective: ``u - c = f (x/z)`` with ``x/z`` from the camera's pose, so
    ``f = sum (u - c).(x/z) / sum |x/z|^2``; orthographic: ``u - c = s (R X)[:2]``
    with ``c`` fitted too (the image of the world origin)."""
    X, uv = keyframe_correspondences(tracks, keyframes)
    if len(X) < min_points:
        return camera
    if isinstance(camera, Orthographic):
        a = X @ camera.R[:2].T  # (N, 2) metres in the image plane
        am, um = a.mean(0), uv.mean(0)
        den = float(((a - am) ** 2).sum())
        if den <= 1e-12:
            return camera
        s = float(((uv - um) * (a - am)).sum()) / den
        if not s > 0:
            return camera
        return dataclasses.replace(camera, scale=s, center=um - s * am)
    if isinstance(camera, Perspective) and not camera.has_distortion:
        x = camera.camera_points(X)
        ok = x[:, 2] > 1e-6
        if ok.sum() < min_points:
            return camera
        xy = x[ok, :2] / x[ok, 2:3]
        d = uv[ok] - camera.K[:2, 2]
        den = float((xy * xy).sum())
        f = float((d * xy).sum()) / den if den > 1e-12 else 0.0
        if not f > 0:
            return camera
        K = np.array(camera.K, float)
        K[:2, :2] *= f / K[0, 0]
        return dataclasses.replace(camera, K=K)
    return camera




def _rodrigues(r) -> np.ndarray:
    th = float(np.linalg.norm(r))
    if th < 1e-12:
        return np.eye(3)
    k = np.asarray(r, float) / th
    Kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(th) * Kx + (1.0 - np.cos(th)) * Kx @ Kx


def _log_rotation(R) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_rotvec()


def _reprojection(X, uv, c, pose, f) -> np.ndarray:
    """Pixel residuals of world points ``X`` against ``uv`` through a pinhole camera with
    principal point ``c``, focal length ``f`` and ``pose`` = (rotation vector, translation)."""
    xc = X @ _rodrigues(pose[:3]).T + pose[3:6]
    z = np.where(np.abs(xc[:, 2]) > 1e-9, xc[:, 2], 1e-9)
    return (f * xc[:, :2] / z[:, None] + c - uv).ravel()


def camera_from_keyframes(X, uv, image_size, f0: float) -> Perspective | None:
    """A perspective camera (principal point at the image centre, square pixels) whose
    rotation, position and focal length best project world points ``X`` (N, 3) onto
    pixels ``uv`` (N, 2): a direct linear transform in coordinates normalised by ``f0``
    (RQ-decomposed into K R), then Gauss-Newton on the reprojection error over the
    rotation, translation and log focal length. ``None`` when the points are too few
    (fewer than 6) or degenerate (coplanar, or behind the camera)."""
    from scipy.linalg import rq
    from scipy.optimize import least_squares

    X, uv = np.asarray(X, float), np.asarray(uv, float)
    if len(X) < 6 or np.linalg.matrix_rank(X - X.mean(0), tol=1e-3) < 3:
        return None
    c = np.array([image_size[0] / 2.0, image_size[1] / 2.0])
    xy = (uv - c) / f0
    mX = X.mean(0)
    sX = float(np.sqrt(((X - mX) ** 2).sum(1).mean())) or 1.0
    Xn = (X - mX) / sX
    A = np.zeros((2 * len(X), 12))
    Xh = np.c_[Xn, np.ones(len(X))]
    A[0::2, 0:4], A[0::2, 8:12] = Xh, -xy[:, :1] * Xh
    A[1::2, 4:8], A[1::2, 8:12] = Xh, -xy[:, 1:2] * Xh
    P = np.linalg.svd(A)[2][-1].reshape(3, 4)
    M = P[:, :3]
    if np.linalg.det(M) < 0:
        P, M = -P, -M
    Kr, R = rq(M)
    D = np.diag(np.sign(np.diag(Kr)))  # positive diagonal of K: R' = D R, K' = K D
    Kr, R = Kr @ D, D @ R
    if np.linalg.det(R) < 0:
        return None
    scale = Kr[2, 2]
    f_rel = 0.5 * (Kr[0, 0] + Kr[1, 1]) / scale
    t_n = np.linalg.solve(Kr, P[:, 3])  # translation in normalised world units
    t = t_n * sX - R @ mX
    f = f0 * f_rel
    if not (np.isfinite(f) and f > 0):
        return None
    x_cam = X @ R.T + t
    if np.mean(x_cam[:, 2] > 0) < 0.5:
        return None

    p0 = np.r_[_log_rotation(R), t, np.log(f)]
    sol = least_squares(lambda p: _reprojection(X, uv, c, p[:6], np.exp(p[6])), p0, method="lm", max_nfev=200)
    R, t, f = _rodrigues(sol.x[:3]), sol.x[3:6], float(np.exp(sol.x[6]))
    K = np.array([[f, 0.0, c[0]], [0.0, f, c[1]], [0.0, 0.0, 1.0]])
    return Perspective(K, R, t)


def camera_pose_from_keyframes(X, uv, image_size, f: float, *, rotations=()) -> Perspective | None:
    """A perspective camera of focal length ``f`` (principal point at the image centre,
    square pixels) whose rotation and position best project world points ``X`` (N, 3)
    onto pixels ``uv`` (N, 2): the perspective-n-point problem with known intrinsics.
    Started from the affine fit (:func:`orthographic_from_keyframes`: its rotation, and
    the distance ``f / s`` its scale ``s`` implies) and from any of ``rotations`` (e.g. a
    direct linear transform's), then Gauss-Newton on the reprojection error; the lowest
    with every point in front. ``None`` for fewer than 4 points, points in one plane, or
    no solution in front of the camera.

    This places the auto camera when the point keyframes cannot fix the focal length too:
    :func:`camera_from_keyframes` then runs along the focal length's valley (from one
    keyframe of the bundled walk, on ``bench/bench_real.py``'s detector tracks, it put the
    camera 13-84 m from the truth)."""
    from scipy.optimize import least_squares

    X, uv = np.asarray(X, float), np.asarray(uv, float)
    aff = orthographic_from_keyframes(X, uv)
    if aff is None:
        return None
    c = np.array([image_size[0] / 2.0, image_size[1] / 2.0])
    mX = X.mean(0)
    depth = f / aff.scale
    best = None
    for R0 in (aff.R, *rotations):
        t0 = np.r_[(uv.mean(0) - c) / f * depth, depth] - R0 @ mX
        sol = least_squares(lambda p: _reprojection(X, uv, c, p, f), np.r_[_log_rotation(R0), t0], method="lm",
                            max_nfev=400)
        R, t = _rodrigues(sol.x[:3]), sol.x[3:6]
        rss = float(sol.fun @ sol.fun)
        if np.all((X @ R.T + t)[:, 2] > 0) and (best is None or rss < best[0]):
            best = (rss, R, t)
    if best is None:
        return None
    K = np.array([[f, 0.0, c[0]], [0.0, f, c[1]], [0.0, 0.0, 1.0]])
    return Perspective(K, best[1], best[2])


def keyframe_focal_interval(X, uv, camera, *, steps: Sequence[float] = (0.05, 0.1, 0.2, 0.35, 0.5, 0.7),
                            threshold: float = PROFILE_THRESHOLD) -> tuple[tuple, tuple]:
    """How far point keyframes fix a perspective camera's focal length when they also
    place it (:func:`camera_from_keyframes`): the profile of their reprojection cost over
    the focal length, rotation and position re-fitted at each value (log steps ``steps``
    out from ``camera``'s on both sides), in units of the fit's own residual variance
    (``RSS / (2 N - 7)`` over the N points: the keyframes' noise seen through the camera).
    The focal length and the camera's distance trade off; few keyframes, or keyframes
    whose points span little depth, leave a long valley. Returns ``((low, high),
    (bounded_low, bounded_high))``: the focal lengths whose cost rises by less than
    ``threshold`` nats (chi-square(1) / 2 at 95 %), a side unbounded when even its last
    step stays within it."""
    from scipy.optimize import least_squares

    X, uv = np.asarray(X, float), np.asarray(uv, float)
    c = np.asarray(camera.K[:2, 2], float)
    f_fit = float(camera.K[0, 0])

    def fit(f, p0):
        sol = least_squares(lambda p: _reprojection(X, uv, c, p, f), p0, method="lm", max_nfev=400)
        return sol.x, float(sol.fun @ sol.fun)

    p_fit, rss0 = fit(f_fit, np.r_[_log_rotation(camera.R), camera.t])
    var = max(rss0 / max(2 * len(X) - 7, 1), 1e-12)
    ends, bounded = [], []
    for sign in (-1.0, 1.0):
        p, d0, c0, out = p_fit, 0.0, 0.0, False
        for d in sorted(steps):
            p, rss = fit(f_fit * float(np.exp(sign * d)), p)
            cost = (rss - rss0) / (2.0 * var)
            if cost > threshold:  # the crossing, linear in log f between the last two steps
                d0, out = d0 + (threshold - c0) / (cost - c0) * (d - d0), True
                break
            d0, c0 = d, cost
        ends.append(f_fit * float(np.exp(sign * d0)))
        bounded.append(out)
    return (ends[0], ends[1]), (bounded[0], bounded[1])


def orthographic_from_keyframes(X, uv) -> Orthographic | None:
    """The orthographic camera ``u = s (R X)[:2] + c`` best projecting world points ``X``
    (N, 3) onto pixels ``uv`` (N, 2): the affine map ``u = A X + b`` by linear least
    squares, then ``A`` replaced by the nearest ``s R[:2]`` (orthonormal rows, ``s`` the
    mean singular value) and ``c`` refitted. ``None`` for fewer than 4 points or
    degenerate ones."""
    X, uv = np.asarray(X, float), np.asarray(uv, float)
    if len(X) < 4 or np.linalg.matrix_rank(X - X.mean(0), tol=1e-3) < 3:
        return None
    Xh = np.c_[X, np.ones(len(X))]
    Ab = np.linalg.lstsq(Xh, uv, rcond=None)[0].T  # (2, 4)
    U, S, Vt = np.linalg.svd(Ab[:, :3], full_matrices=False)
    s = float(S.mean())
    if not s > 0:
        return None
    R2 = U @ Vt  # (2, 3) orthonormal rows
    R = np.vstack([R2, np.cross(R2[0], R2[1])])
    c = (uv - s * X @ R2.T).mean(0)
    return Orthographic(R, s, c)
