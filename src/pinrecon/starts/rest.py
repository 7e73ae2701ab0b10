"""The rest-pose start: the figure's rest pose placed where the 2D tracks are, then
rigidly fitted (root only) to the measurements and the smoothing prior.

It is also the building block other starts refine: :func:`place_on_tracks` shifts any
trajectory's root so the figure projects onto the tracks.

Pixels become directions through the camera's own model: a perspective camera's
:meth:`~pinrecon.cameras.Perspective.normalized` (K and the lens distortion), an
orthographic camera's scale and centre.

Several cameras: the start of :mod:`.triangulation` (the tracks triangulated, the rest
pose aligned to them, the figure fitted to the points); cameras that share no point fall
back to the first camera's placement with the root fitted to every camera.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..kinematics import quaternion_matrices
from ..problem import ReconstructionProblem, rest_pose
from ..rows import Measurement2D
from ..solver import SolverOptions, solve
from .triangulation import fit_triangulated, normalized_coords

__all__ = ["RigidBody", "fit_root", "place_on_tracks", "rest_start"]


def _as_list(x) -> list:
    return list(x) if isinstance(x, (list, tuple)) else [x]


def _model_normalized(camera, p_world) -> np.ndarray:
    """:func:`~pinrecon.starts.triangulation.normalized_coords` of world points (the
    ideal ray: no distortion)."""
    if hasattr(camera, "scale"):
        return np.asarray(p_world, float) @ camera.R[:2].T
    x_cam = camera.camera_points(p_world)
    return x_cam[..., :2] / x_cam[..., 2:3]


def place_on_tracks(figure, Q, camera, meas: Measurement2D | Sequence[Measurement2D] | None) -> np.ndarray:
    """Translate each observed frame's root so the figure's observed keypoints project
    onto the tracks' centroid (in the image plane, keeping camera depth); frames in
    between get the interpolated shift.

    ``camera`` and ``meas`` may be sequences (one per camera, paired in order): the shift
    then makes the centroids agree in every camera at once (least squares, a few
    linearised steps), which also sets the depth.
    """
    cams = _as_list(camera)
    meas_l = [m for m in _as_list(meas) if m is not None]
    if not figure.floating or not meas_l or all(len(m.frames) == 0 for m in meas_l):
        return Q
    if len(cams) > 1:
        return _place_multiview(figure, Q, cams, meas_l)
    camera, meas = cams[0], meas_l[0]
    Q = Q.copy()
    P = figure.keypoints(Q[meas.frames])[:, meas.keypoints]  # (N, M, 3)
    obs = meas.observed
    shift = np.zeros((len(meas.frames), 3))
    R = camera.R
    ortho = hasattr(camera, "scale")
    for n in range(len(meas.frames)):
        o = obs[n]
        if o.sum() == 0:
            continue
        d = normalized_coords(camera, meas.uv_px[n, o]).mean(0) - _model_normalized(camera, P[n, o]).mean(0)
        if not ortho:
            d = d * max(float(camera.depth(P[n, o]).mean()), 1e-3)
        shift[n] = R.T @ np.r_[d, 0.0]
    ok = obs.any(axis=1)
    if not ok.any():
        return Q
    fr = meas.frames[ok]
    for a in range(3):
        Q[:, a] += np.interp(np.arange(len(Q)), fr, shift[ok, a])
    return Q


def _place_multiview(figure, Q, cams, meas_l, steps: int = 3) -> np.ndarray:
    """:func:`place_on_tracks` for several cameras: per frame, the root shift ``s`` with
    ``sum_c |J_c s - d_c|^2`` least, ``d_c`` the centroid's offset in camera ``c``'s
    normalised image plane times its depth (metres) and ``J_c`` its derivative."""
    Q = Q.copy()
    T = len(Q)
    seen = np.zeros(T, bool)
    for m in meas_l:
        seen[m.frames[m.observed.any(axis=1)]] = True
    if not seen.any():
        return Q
    total = np.zeros((T, 3))
    for _ in range(steps):
        A = np.zeros((T, 3, 3))
        b = np.zeros((T, 3))
        for cam, m in zip(cams, meas_l):
            if not len(m.frames):
                continue
            o = m.observed
            cnt = o.sum(axis=1)
            k = cnt > 0
            if not k.any():
                continue
            P = figure.keypoints(Q[m.frames[k]])[:, m.keypoints]  # (N, M, 3)
            o, c = o[k], cnt[k][:, None]
            xy_obs = np.where(o[..., None], normalized_coords(cam, np.where(o[..., None], m.uv_px[k], 0.0)), 0.0).sum(1) / c
            xy_mod = np.where(o[..., None], _model_normalized(cam, P), 0.0).sum(1) / c
            if hasattr(cam, "scale"):
                J = np.broadcast_to(cam.R[:2], (len(c), 2, 3))
                d = xy_obs - xy_mod
            else:
                z = np.maximum(np.where(o, cam.depth(P), 0.0).sum(1) / c[:, 0], 1e-3)
                J = cam.R[:2][None] - xy_mod[..., None] * cam.R[2]
                d = (xy_obs - xy_mod) * z[:, None]
            fr = m.frames[k]
            np.add.at(A, fr, np.einsum("nki,nkj->nij", J, J))
            np.add.at(b, fr, np.einsum("nki,nk->ni", J, d))
        A[seen] += 1e-9 * np.eye(3)
        step = np.zeros((T, 3))
        step[seen] = np.linalg.solve(A[seen], b[seen][..., None])[..., 0]
        Q[seen, :3] += step[seen]
        total[seen] += step[seen]
    fr = np.where(seen)[0]
    rest = ~seen
    for a in range(3):
        Q[rest, a] += np.interp(np.where(rest)[0], fr, total[seen, a])
    return Q


class RigidBody:
    """``figure`` whose joints stay at one configuration's in every frame while its root moves
    (a root-only fit): :meth:`world_kinematics` forms the body's keypoints and WORLD Jacobian
    once, at the identity root, and moves them by each frame's root (the Jacobian by the root's
    adjoint), instead of running the joints' recursion each time. The same numbers as
    ``figure.world_kinematics`` to rounding; everything else is ``figure``'s.
    :meth:`of` makes one where that holds."""

    def __init__(self, figure, q):
        self.figure = figure
        q = np.array(q, float)
        q[:7] = (0, 0, 0, 0, 0, 0, 1)
        P, Jw = figure.world_kinematics(q[None], True)
        self._P, self._Jw = P[0], Jw[0]

    @classmethod
    def of(cls, figure, Q):
        """A :class:`RigidBody` of ``figure`` for trajectory ``Q`` when its root is a free flyer
        placed at the world's origin and every frame holds the joints below it alike; else
        ``figure`` itself."""
        m = getattr(figure, "model", None)
        Q = np.asarray(Q, float)
        if not getattr(figure, "floating", False) or m is None or m.njoints < 2 or m.parents[1] != 0 \
                or not np.array_equal(m.jointPlacements[1].homogeneous, np.eye(4)) or len(Q) < 2 \
                or not np.array_equal(Q[1:, 7:], np.broadcast_to(Q[0, 7:], Q[1:, 7:].shape)):
            return figure
        return cls(figure, Q[0])

    def __getattr__(self, name):
        return getattr(self.figure, name)

    def world_kinematics(self, Q: np.ndarray, jacobian: bool = True):
        """The figure's :meth:`~pinrecon.figure.Figure.world_kinematics` for ``Q`` (its joints
        the body's): keypoints (T, K, 3) and the WORLD Jacobian (T, 6, nv) or ``None``."""
        Q = np.asarray(Q, float)
        R = quaternion_matrices(*Q[:, 3:7].T).transpose(2, 0, 1)  # (T, 3, 3), as the recursion forms it
        p = Q[:, :3]
        P = np.einsum("tab,kb->tka", R, self._P) + p[:, None]
        if not jacobian:
            return P, None
        ang = np.matmul(R, self._Jw[3:])  # (T, 3, nv): a twist at the origin acted by (R, p)
        Jw = np.empty((len(Q), 6, self._Jw.shape[1]))
        Jw[:, 3:] = ang
        Jw[:, :3] = np.matmul(R, self._Jw[:3]) + np.cross(p[:, :, None], ang, axis=1)
        return P, Jw


def fit_root(figure, Q, meas, smoothing, options: SolverOptions | None = None) -> np.ndarray:
    """``Q`` with only the root's tangent entries fitted to the measurements (one
    :class:`Measurement2D` or a sequence of them, one per camera) and the smoothing prior
    (a short solve). Where the joints are alike in every frame, their kinematics are formed
    once (:class:`RigidBody`)."""
    active = np.zeros(figure.nv, bool)
    active[figure.root_v] = True
    rows = [m for m in _as_list(meas) if m is not None]
    problem = ReconstructionProblem(RigidBody.of(figure, Q), Q.shape[0], rows + [smoothing])
    res = solve(problem, Q, options or SolverOptions(max_iterations=30, ftol=1e-5), active=active)
    return res.x


def rest_start(problem: ReconstructionProblem) -> np.ndarray:
    """The rest pose in every frame, placed on the tracks and rigidly fitted (root only).
    Under perspective the figure is first put at the depth where its size matches the
    tracks' spread (in undistorted normalised coordinates). With several cameras: the
    triangulation start (module docstring)."""
    figure, camera, meas = problem.figure, problem.camera, problem.measurement
    q_rest = rest_pose(figure)
    Q = np.tile(q_rest, (problem.n_frames, 1))
    if meas is None:
        return Q
    if len(problem.views) > 1:
        Q_mv = fit_triangulated(problem)
        if Q_mv is not None:
            return Q_mv
    if not figure.floating:
        return Q
    if not hasattr(camera, "scale"):
        P = figure.keypoints(q_rest)[meas.keypoints]
        span_model = np.ptp(P, axis=0).max()
        xy = camera.normalized(meas.uv_px[meas.observed.any(1)])
        ext = np.ptp(xy, axis=1) if xy.size else np.zeros(0)  # NaN in frames with a point missing
        span = np.nanmax(ext) if np.isfinite(ext).any() else np.nan  # no All-NaN warning when none is whole
        z = span_model / span if np.isfinite(span) and span > 1e-9 else 1.0
        centre_cam = np.array([0.0, 0.0, z])
        Q[:, :3] = (camera.R.T @ (centre_cam - camera.t))[None, :] - (P.mean(0) - q_rest[:3])
    Q = place_on_tracks(figure, Q, problem.cameras or camera, problem.measurements or meas)
    return fit_root(figure, Q, problem.measurements or meas, problem.smoothing)
