"""Foot-contact rows: a foot keypoint in contact stays still, on the floor.

The floor is the plane ``n . p = d`` (``n`` the unit up normal in world axes, ``d``
metres); the height of a point is ``h(p) = n . p - d``. A foot keypoint ``k`` (ankle,
heel, toe ...) sits at its own height ``c_k`` above the floor when its part of the foot
rests on it (an ankle about 8 cm, a toe tip about 2 cm). The floor is fixed within a
solve (it is re-estimated between solves, :mod:`pinrecon.contact`).

**No sliding** (:class:`ContactVelocity`), for a keypoint in contact at frames t and t + 1
(weight ``w``, standard deviation ``sigma_v`` in m/s, frame rate ``fps``, ``B`` the (3, 2)
orthonormal basis of the floor's plane)::

    r = sqrt(w) B^T (p_k(q_{t+1}) - p_k(q_t)) fps / sigma_v               (2 rows)
    dr/dv_t = -sqrt(w) fps / sigma_v B^T J_k(q_t),  dr/dv_{t+1} = sqrt(w) fps / sigma_v B^T J_k(q_{t+1})

(``J_k`` the keypoint's world Jacobian, :meth:`pinrecon.Figure.keypoint_jacobians`).
Only the horizontal velocity is held at zero: a planted foot rolls (the heel rises, the
toes come down), which moves its keypoints up and down while they do not slide; the
height row below holds them on the floor. With ``normal=None``, ``B`` is the identity
(3 rows, all of the velocity). One row group per frame pair (t, t + 1): the rows of
keypoints not in contact at both frames are zero.

**Height on the floor** (:class:`ContactHeight`), for a keypoint in contact at frame t::

    r = sqrt(w) (n . p_k(q_t) - d - c_k) / sigma_h,     dr/dv_t = sqrt(w) / sigma_h n^T J_k(q_t)

With the figure's proportions as global unknowns (in the state) both kinds also return
``d r / d theta`` through ``d p_k / d theta`` exactly as the 3D point rows do.
"""

from __future__ import annotations

import numpy as np

from .base import RowBlock, RowKind, State

__all__ = ["ContactHeight", "ContactVelocity"]


def _unit(normal) -> np.ndarray:
    n = np.asarray(normal, float).reshape(3)
    norm = np.linalg.norm(n)
    if not (norm > 0 and np.isfinite(norm)):
        raise ValueError(f"the floor normal must be a non-zero finite 3-vector, got {normal!r}")
    return n / norm


def _plane_basis(n) -> np.ndarray:
    """(3, 2) orthonormal basis of the plane perpendicular to unit ``n``."""
    a = np.eye(3)[int(np.argmin(np.abs(n)))]
    u1 = np.cross(n, a)
    u1 /= np.linalg.norm(u1)
    return np.stack([u1, np.cross(n, u1)], axis=1)


class ContactVelocity(RowKind):
    """Zero-velocity rows of foot keypoints in contact between neighbouring frames.

    Parameters
    ----------
    keypoints : (M,) figure keypoint indices (the foot points).
    contact : (T, M) bool, keypoint m in contact at frame t; a row triple exists for
        (t, m) when m is in contact at t and t + 1.
    fps : reconstruction frame rate (velocities are ``(p_{t+1} - p_t) fps``, m/s).
    sigma_mps : standard deviation of a planted point's speed, m/s.
    weights : optional (T, M) weights (default 1), e.g. ``1 / factor`` on a super-sampled grid.
    normal : the floor's up normal: only the velocity parallel to the floor has rows
        (default ``None``: the whole velocity).
    """

    name = "contact_velocity"

    def __init__(self, keypoints, contact, fps, sigma_mps=0.01, weights=None, normal=None):
        self.keypoints = np.asarray(keypoints, dtype=int)
        c = np.asarray(contact, bool)
        if c.ndim != 2 or c.shape[1] != len(self.keypoints):
            raise ValueError(f"contact must be (T, {len(self.keypoints)}) bool, got shape {c.shape}")
        both = c[:-1] & c[1:]
        w = np.ones(both.shape) if weights is None else np.asarray(weights, float)[:-1]
        frames = np.where(both.any(axis=1))[0]
        self.frames = np.stack([frames, frames + 1], axis=1) if len(frames) else np.zeros((0, 2), int)
        self.kinematic_frames = np.unique(self.frames)
        self.sqrt_w = np.sqrt(np.where(both[frames], w[frames], 0.0)) * float(fps) / float(sigma_mps)  # (N, M)
        self.basis = np.eye(3) if normal is None else _plane_basis(_unit(normal))  # (3, d)

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        N, M, B = self.frames.shape[0], len(self.keypoints), self.basis
        d = B.shape[1]
        s0, s1 = state.slot[self.frames[:, 0]], state.slot[self.frames[:, 1]]
        P0 = state.points[s0][:, self.keypoints]
        P1 = state.points[s1][:, self.keypoints]
        r = (((P1 - P0) @ B) * self.sqrt_w[..., None]).reshape(N, d * M)
        J = Jg = gcols = None
        if jacobian:
            w = self.sqrt_w[..., None, None]
            Bt = B.T
            J0 = -np.matmul(Bt, state.jacobians[s0][:, self.keypoints]) * w  # (N, M, d, nv)
            J1 = np.matmul(Bt, state.jacobians[s1][:, self.keypoints]) * w
            nv = state.figure.nv  # explicit: with no contact frame (N = 0) -1 cannot be inferred
            J = np.stack([J0.reshape(N, d * M, nv), J1.reshape(N, d * M, nv)], axis=1)
            if state.has_global_points:
                dP = state.global_point_jacobians(s1, self.keypoints, Bt) - state.global_point_jacobians(s0, self.keypoints, Bt)
                Jg, gcols = (dP * w).reshape(N, d * M, dP.shape[-1]), state.proportion_cols
        return RowBlock(self.frames, r, J, np.arange(state.figure.nv), self.name, Jg=Jg, gcols=gcols)


class ContactHeight(RowKind):
    """Rows holding foot keypoints in contact at their height above the floor.

    Parameters
    ----------
    keypoints : (M,) figure keypoint indices.
    contact : (T, M) bool.
    normal, offset_m : the floor ``n . p = d`` (``normal`` is normalised).
    height_m : (M,) or (T, M) height ``c_k`` of each keypoint above the floor in contact.
    sigma_m : standard deviation of that height, metres.
    weights : optional (T, M) weights (default 1).
    """

    name = "contact_height"

    def __init__(self, keypoints, contact, normal, offset_m, height_m, sigma_m=0.005, weights=None):
        self.keypoints = np.asarray(keypoints, dtype=int)
        c = np.asarray(contact, bool)
        if c.ndim != 2 or c.shape[1] != len(self.keypoints):
            raise ValueError(f"contact must be (T, {len(self.keypoints)}) bool, got shape {c.shape}")
        self.normal = _unit(normal)
        self.offset = float(offset_m)
        self.frames = np.where(c.any(axis=1))[0]
        self.kinematic_frames = self.frames
        w = np.ones(c.shape) if weights is None else np.asarray(weights, float)
        self.sqrt_w = np.sqrt(np.where(c[self.frames], w[self.frames], 0.0)) / float(sigma_m)
        h = np.broadcast_to(np.asarray(height_m, float), c.shape)
        self.target = h[self.frames] + self.offset  # (N, M): n . p at contact

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        slots = state.slot[self.frames]
        P = state.points[slots][:, self.keypoints]  # (N, M, 3)
        r = (P @ self.normal - self.target) * self.sqrt_w
        J = Jg = gcols = None
        if jacobian:
            N, M = r.shape
            Jk = np.einsum("a,nmav->nmv", self.normal, state.jacobians[slots][:, self.keypoints])
            J = (Jk * self.sqrt_w[..., None]).reshape(N, 1, M, Jk.shape[-1])
            if state.has_global_points:
                dP = state.global_point_jacobians(slots, self.keypoints, self.normal[None])[:, :, 0]
                Jg, gcols = dP * self.sqrt_w[..., None], state.proportion_cols
        return RowBlock(self.frames[:, None], r, J, np.arange(state.figure.nv), self.name, Jg=Jg, gcols=gcols)
