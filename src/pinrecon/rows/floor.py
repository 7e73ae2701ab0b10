"""Soft non-penetration of the floor by every foot keypoint at every frame.

The floor is the plane ``n . p = d`` (unit up normal ``n``); a foot keypoint ``k`` may
not go lower than its clearance ``c_k`` above it (the height at which its part of the
foot rests on the floor). For frame t, with ``e = n . p_k(q_t) - d - c_k``::

    r = sqrt(w) min(0, e) / sigma,      dr/dv_t = sqrt(w) / sigma n^T J_k(q_t) where e < 0, else 0,

a one-sided barrier like the joint limits' (:mod:`pinrecon.rows.limits`): zero above the
floor, quadratic below it, continuous with a continuous first derivative. The floor is
fixed within a solve. With the figure's proportions as global unknowns the rows also
return ``d r / d theta = sqrt(w) / sigma n^T d p_k / d theta`` where ``e < 0``.
"""

from __future__ import annotations

import numpy as np

from .base import RowBlock, RowKind, State

__all__ = ["FloorPenetration"]


class FloorPenetration(RowKind):
    """Barrier rows keeping foot keypoints above the floor, on every frame given.

    Parameters
    ----------
    keypoints : (M,) figure keypoint indices.
    frames : (N,) frames (usually all, ``0 .. T-1``).
    normal, offset_m : the floor ``n . p = d`` (``normal`` is normalised).
    clearance_m : (M,) lowest allowed height of each keypoint above the floor.
    sigma_m : standard deviation, metres (small = stiff).
    weights : optional (N,) per-frame weights (default 1).
    """

    name = "floor"

    def __init__(self, keypoints, frames, normal, offset_m, clearance_m, sigma_m=0.002, weights=None):
        self.keypoints = np.asarray(keypoints, dtype=int)
        self.frames = np.asarray(frames, dtype=int)
        self.kinematic_frames = self.frames
        n = np.asarray(normal, float).reshape(3)
        norm = np.linalg.norm(n)
        if not (norm > 0 and np.isfinite(norm)):
            raise ValueError(f"the floor normal must be a non-zero finite 3-vector, got {normal!r}")
        self.normal = n / norm
        self.lowest = float(offset_m) + np.broadcast_to(np.asarray(clearance_m, float), self.keypoints.shape)
        w = np.ones(len(self.frames)) if weights is None else np.asarray(weights, float)
        self.sqrt_w = np.sqrt(w) / float(sigma_m)  # (N,)

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        slots = state.slot[self.frames]
        P = state.points[slots][:, self.keypoints]
        e = P @ self.normal - self.lowest  # (N, M)
        below = e < 0
        r = np.where(below, e, 0.0) * self.sqrt_w[:, None]
        J = Jg = gcols = None
        if jacobian:
            N, M = r.shape
            scale = (below * self.sqrt_w[:, None])[..., None]
            Jk = np.einsum("a,nmav->nmv", self.normal, state.jacobians[slots][:, self.keypoints]) * scale
            J = Jk.reshape(N, 1, M, Jk.shape[-1])
            if state.has_global_points:
                dP = state.global_point_jacobians(slots, self.keypoints, self.normal[None])[:, :, 0]
                Jg, gcols = dP * scale, state.proportion_cols
        return RowBlock(self.frames[:, None], r, J, np.arange(state.figure.nv), self.name, Jg=Jg, gcols=gcols)
