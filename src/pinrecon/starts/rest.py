"""The rest-pose start: the figure's rest pose placed where the 2D tracks are, then
rigidly fitted (root only) to the measurements and the smoothing prior.

It is also the building block other starts refine: :func:`place_on_tracks` shifts any
trajectory's root so the figure projects onto the tracks.
"""

from __future__ import annotations

import numpy as np

from ..problem import ReconstructionProblem, rest_pose
from ..rows import Measurement2D
from ..solver import SolverOptions, solve

__all__ = ["rest_start", "place_on_tracks", "fit_root"]


def place_on_tracks(figure, Q, camera, meas: Measurement2D | None) -> np.ndarray:
    """Translate each observed frame's root so the figure's observed keypoints project
    onto the tracks' centroid (in the image plane, keeping camera depth); frames in
    between get the interpolated shift."""
    if not figure.floating or meas is None or len(meas.frames) == 0:
        return Q
    Q = Q.copy()
    P = figure.keypoints(Q[meas.frames])[:, meas.keypoints]  # (N, M, 3)
    obs = meas.observed
    shift = np.zeros((len(meas.frames), 3))
    R = camera.R
    for n in range(len(meas.frames)):
        o = obs[n]
        if o.sum() == 0:
            continue
        uv_model = camera.project(P[n, o]).mean(0)
        uv_obs = meas.uv_px[n, o].mean(0)
        if hasattr(camera, "scale"):
            d_cam = np.r_[(uv_obs - uv_model) / camera.scale, 0.0]
        else:
            z = max(float(camera.depth(P[n, o]).mean()), 1e-3)
            d_cam = np.r_[(uv_obs - uv_model) * z / np.array([camera.K[0, 0], camera.K[1, 1]]), 0.0]
        shift[n] = R.T @ d_cam
    ok = obs.any(axis=1)
    if not ok.any():
        return Q
    fr = meas.frames[ok]
    for a in range(3):
        Q[:, a] += np.interp(np.arange(len(Q)), fr, shift[ok, a])
    return Q


def fit_root(figure, Q, meas: Measurement2D, smoothing, options: SolverOptions | None = None) -> np.ndarray:
    """``Q`` with only the root's tangent entries fitted to the measurements and the
    smoothing prior (a short solve)."""
    active = np.zeros(figure.nv, bool)
    active[figure.root_v] = True
    problem = ReconstructionProblem(figure, Q.shape[0], [meas, smoothing])
    res = solve(problem, Q, options or SolverOptions(max_iterations=30, ftol=1e-5), active=active)
    return res.x


def rest_start(problem: ReconstructionProblem) -> np.ndarray:
    """The rest pose in every frame, placed on the tracks and rigidly fitted (root only).
    Under perspective the figure is first put at the depth where its size matches the
    tracks' spread."""
    figure, camera, meas = problem.figure, problem.camera, problem.measurement
    q_rest = rest_pose(figure)
    Q = np.tile(q_rest, (problem.n_frames, 1))
    if meas is None or not figure.floating:
        return Q
    if not hasattr(camera, "scale"):
        P = figure.keypoints(q_rest)[meas.keypoints]
        span_model = np.ptp(P, axis=0).max()
        uv = meas.uv_px[meas.observed.any(1)]
        span_px = np.nanmax(np.ptp(uv, axis=1)) if uv.size else 1.0
        f = float(np.mean([camera.K[0, 0], camera.K[1, 1]]))
        z = f * span_model / max(span_px, 1e-6)
        centre_cam = np.array([0.0, 0.0, z])
        Q[:, :3] = (camera.R.T @ (centre_cam - camera.t))[None, :] - (P.mean(0) - q_rest[:3])
    Q = place_on_tracks(figure, Q, camera, meas)
    return fit_root(figure, Q, meas, problem.smoothing)
