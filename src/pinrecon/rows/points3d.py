"""3D point rows: the paper's "noise channel" only (3D keyframes and motion-capture markers).

For frame t and keypoint k observed at world position ``X`` (metres):
``r = sqrt(w) (p_k(q_t) - X) / sigma_m``, Jacobian ``sqrt(w) / sigma_m * J_k(q_t)``.
Missing markers (NaN) contribute zero rows. With the figure's proportions as global
unknowns (in the state), ``d r / d theta = sqrt(w) / sigma_m * d p_k / d theta``.
"""

from __future__ import annotations

import numpy as np

from .base import RowBlock, RowKind, State, crop_aligned, supported_columns

__all__ = ["Points3D"]


class Points3D(RowKind):
    """Rows pulling keypoints to observed 3D positions.

    Parameters
    ----------
    frames : (N,) reconstruction frames.
    keypoints : (M,) figure keypoint indices.
    p_world : (N, M, 3) observed positions in metres, NaN where missing.
    sigma_m : (N,) or scalar standard deviation in metres.
    name : cost-report label (``"keyframe_points"`` or ``"markers"``).
    """

    def __init__(self, frames, keypoints, p_world, sigma_m, name="points3d", weights=None):
        self.name = name
        self.frames = np.asarray(frames, dtype=int)
        self.kinematic_frames = self.frames
        self.keypoints = np.asarray(keypoints, dtype=int)
        p = np.asarray(p_world, float)
        observed = np.all(np.isfinite(p), axis=-1)
        if weights is not None:
            observed &= np.asarray(weights) > 0
        sigma = np.broadcast_to(np.asarray(sigma_m, float), self.frames.shape)
        w = observed / sigma[:, None]
        if weights is not None:
            w = w * np.sqrt(np.asarray(weights, float))
        self.sqrt_w = w
        self.p_filled = np.where(observed[..., None], p, 0.0)
        self.observed = observed

    def crop(self, lo: int, hi: int) -> Points3D:
        return crop_aligned(self, lo, hi, ("sqrt_w", "p_filled", "observed"))

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        slots = state.slot[self.frames]
        P = state.points[slots][:, self.keypoints]
        N, M = len(self.frames), len(self.keypoints)
        r = ((P - self.p_filled) * self.sqrt_w[..., None]).reshape(N, 3 * M)
        J = Jg = gcols = None
        if jacobian:
            cols = supported_columns(state.figure, self.keypoints)  # structurally non-zero columns only
            J = state.point_jacobians(slots, self.keypoints, None, self.sqrt_w, cols).reshape(N, 1, 3 * M, -1)
            if state.has_global_points:
                dP = state.global_point_jacobians(slots, self.keypoints) * self.sqrt_w[..., None, None]
                Jg, gcols = dP.reshape(N, 3 * M, -1), state.proportion_cols
        cols = cols if jacobian else np.arange(state.figure.nv)
        return RowBlock(self.frames[:, None], r, J, cols, self.name, Jg=Jg, gcols=gcols)
