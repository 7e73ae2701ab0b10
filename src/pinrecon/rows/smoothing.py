"""Constant-velocity smoothing rows (DiFranco et al. eq. 3), written on the Lie group.

With ``d_t = q_{t+1} (-) q_t`` (Pinocchio's ``difference``) the row for frame t is

    r_t = W (d_t - d_{t-1}) / dt^2 * sqrt(dt),    t = 1 .. T-2,

a discrete acceleration, zero exactly when the motion has constant velocity on the
group, i.e. when ``q_t`` is the geodesic midpoint of its neighbours. ``W = diag(1/sigma)``
holds separate acceleration standard deviations for root translation (m/s^2), root
rotation (rad/s^2) and joints (rad/s^2). The ``sqrt(dt)`` makes the sum approximate
``integral |a / sigma|^2 dt``, so the prior's strength does not change with the frame
rate (super-sampled reconstructions keep the same weights).

Jacobians, with ``J0_t, J1_t`` the derivatives of ``d_t`` w.r.t. the tangents at
``q_t`` and ``q_{t+1}`` (``dDifference``):

    dr_t/dv_{t-1} = -W' J0_{t-1},  dr_t/dv_t = W' (J0_t - J1_{t-1}),  dr_t/dv_{t+1} = W' J1_t

(``W' = W sqrt(dt) / dt^2``). For 1-dof Euclidean joints ``J0 = -1``, ``J1 = 1`` and the
rows are the familiar ``q_{t-1} - 2 q_t + q_{t+1}`` (a diagonal block).

**The root** has two choices of group (``root_group``):

* ``"R3xSO3"`` (default): the root's world translation and its orientation are smoothed
  separately, translation as a vector in world axes (``dp/dv = [R, 0]`` for the free
  flyer's local twist) and orientation on SO(3) with ``pin.liegroups.SO3``. A walking
  pelvis turns back and forth while it travels in a straight line; this prior calls that
  smooth.
* ``"SE3"``: the free flyer's own group, ``d_t`` the SE(3) log (a body twist). Constant
  velocity then means a constant screw, which ties the pelvis's yaw oscillation to a
  curved path. Under an orthographic camera, where the root's depth is seen only
  through keyframes and this prior, that coupling lets the depth drift (measured in
  ``bench/bench_engine.py``'s root-group comparison).
"""

from __future__ import annotations

import copy

import numpy as np
import pinocchio as pin

from .base import RowBlock, RowKind, State

__all__ = ["Smoothing", "smoothing_sigmas"]


def smoothing_sigmas(figure, root_translation=5.0, root_rotation=10.0, joints=10.0) -> np.ndarray:
    """Per-tangent-index acceleration standard deviations (root trans, root rot, joints)."""
    sig = np.full(figure.nv, float(joints))
    if figure.floating:
        sig[0:3] = float(root_translation)
        sig[3:6] = float(root_rotation)
    return sig


def _triples(T: int) -> np.ndarray:
    """(T - 2, 3) the frames (t - 1, t, t + 1) of the second differences, t = 1 .. T - 2."""
    return np.stack([np.arange(0, T - 2), np.arange(1, T - 1), np.arange(2, T)], 1)


class Smoothing(RowKind):
    """Second-difference rows on frames (t-1, t, t+1) for t = 1..T-2.

    Parameters
    ----------
    figure : the figure (for its Lie group).
    n_frames : T (>= 3, else the kind has no rows).
    dt : seconds between reconstruction frames.
    sigma : (nv,) acceleration standard deviations (see :func:`smoothing_sigmas`).
    """

    name = "smoothing"

    def __init__(self, figure, n_frames, dt, sigma, root_group="R3xSO3"):
        if root_group not in ("R3xSO3", "SE3"):
            raise ValueError(f"root_group must be 'R3xSO3' or 'SE3', got {root_group!r}")
        self.figure = figure
        self.T = int(n_frames)
        m = figure.model
        euclid = np.zeros(figure.nv, dtype=bool)
        for jid in range(1, m.njoints):
            if m.nqs[jid] == 1 and m.nvs[jid] == 1:
                euclid[m.idx_vs[jid]] = True
        self.split_root = figure.floating and root_group == "R3xSO3"
        if self.split_root:
            euclid[0:6] = True  # handled by the root block below, not by the generic one
            self.w_root = (np.sqrt(dt) / dt**2) / np.asarray(sigma, float)[0:6]
        self.dense_cols = np.where(~euclid)[0]
        self.diag_cols = np.array([c for c in np.where(euclid)[0] if not (self.split_root and c < 6)], dtype=int)
        self.diag_q = np.array(
            [m.idx_qs[j] for j in range(1, m.njoints) if m.nqs[j] == 1 and m.nvs[j] == 1], dtype=int
        )
        scale = np.sqrt(dt) / dt**2
        w = scale / np.asarray(sigma, float)
        self.w_dense = w[self.dense_cols]
        self.w_diag = w[self.diag_cols]
        self.frames = _triples(self.T)

    def crop(self, lo: int, hi: int) -> Smoothing:
        new = copy.copy(self)
        new.T = int(hi) - int(lo)
        new.frames = _triples(new.T)
        return new

    def evaluate(self, state: State, jacobian: bool = True) -> list[RowBlock]:
        Q = state.Q
        if self.T < 3:
            return []
        blocks = []
        # Euclidean 1-dof joints: plain second differences.
        qd = Q[:, self.diag_q]
        r = (qd[:-2] - 2.0 * qd[1:-1] + qd[2:]) * self.w_diag
        J = None
        if jacobian:
            J = np.broadcast_to(
                np.array([1.0, -2.0, 1.0])[None, :, None] * self.w_diag, (self.T - 2, 3, len(self.diag_cols))
            )
        blocks.append(RowBlock(self.frames, r, J, self.diag_cols, self.name, diagonal=True))
        if self.split_root:
            blocks.append(self._root_block(Q, jacobian))
        if len(self.dense_cols):
            model, c = self.figure.model, self.dense_cols
            D = np.empty((self.T - 1, len(c)))
            J0 = np.empty((self.T - 1, len(c), len(c))) if jacobian else None
            J1 = np.empty_like(J0) if jacobian else None
            for t in range(self.T - 1):
                D[t] = pin.difference(model, Q[t], Q[t + 1])[c]
                if jacobian:
                    J0[t] = pin.dDifference(model, Q[t], Q[t + 1], pin.ARG0)[np.ix_(c, c)]
                    J1[t] = pin.dDifference(model, Q[t], Q[t + 1], pin.ARG1)[np.ix_(c, c)]
            r = (D[1:] - D[:-1]) * self.w_dense
            Jd = None
            if jacobian:
                w = self.w_dense[None, :, None]
                Jd = np.stack([-J0[:-1] * w, (J0[1:] - J1[:-1]) * w, J1[1:] * w], axis=1)
            blocks.append(RowBlock(self.frames, r, Jd, c, self.name))
        return blocks

    def _root_block(self, Q, jacobian):
        """R^3 x SO(3) rows for the free-flyer root: world translation and SO(3) log.

        The SO(3) difference and its Jacobians are evaluated for all frames at once; they
        equal ``pin.liegroups.SO3().difference`` / ``dDifference`` (tested):
        ``d = log(R_a^T R_b)``, ``dd/dw_b = Jlog(d)``, ``dd/dw_a = -Jlog(d) (R_a^T R_b)^T``.
        """
        T = self.T
        p = Q[:, 0:3]
        r_trans = p[:-2] - 2.0 * p[1:-1] + p[2:]
        quat = Q[:, 3:7] / np.linalg.norm(Q[:, 3:7], axis=1, keepdims=True)
        rel = _quat_mul(quat[:-1] * [-1.0, -1.0, -1.0, 1.0], quat[1:])  # R_a^T R_b
        D = _quat_log(rel)  # (T-1, 3)
        r = np.concatenate([r_trans, D[1:] - D[:-1]], axis=1) * self.w_root
        J = None
        if jacobian:
            J1 = _jlog3(D)
            J0 = -J1 @ np.swapaxes(_quat_matrix(rel), 1, 2)
            J = np.zeros((T - 2, 3, 6, 6))
            R = _quat_matrix(quat)  # (T, 3, 3)
            for i, c in enumerate((1.0, -2.0, 1.0)):
                J[:, i, 0:3, 0:3] = c * R[i : T - 2 + i]  # dp/dv_local = R
            J[:, 0, 3:6, 3:6] = -J0[:-1]
            J[:, 1, 3:6, 3:6] = J0[1:] - J1[:-1]
            J[:, 2, 3:6, 3:6] = J1[1:]
            J *= self.w_root[None, None, :, None]
        return RowBlock(self.frames, r, J, np.arange(6), self.name)


def _quat_mul(a, b):
    """Hamilton products of (..., 4) quaternions stored (x, y, z, w)."""
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def _quat_log(q):
    """Rotation vectors (..., 3) of unit quaternions (x, y, z, w), angles in [0, pi]
    (``Rotation.as_rotvec``'s convention and small-angle series)."""
    q = np.where(q[..., 3:4] < 0.0, -q, q)
    v = q[..., :3]
    angle = 2.0 * np.arctan2(np.linalg.norm(v, axis=-1), q[..., 3])
    small = angle <= 1e-3
    a2 = angle * angle
    scale = np.where(small, 2.0 + a2 / 12.0 + 7.0 * a2 * a2 / 2880.0,
                     angle / np.sin(np.where(small, 1.0, angle) / 2.0))
    return scale[..., None] * v


def _quat_matrix(q):
    """Rotation matrices (..., 3, 3) of unit quaternions (x, y, z, w)."""
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def _skew(w):
    S = np.zeros(w.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2], S[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    S[..., 1, 0], S[..., 2, 0], S[..., 2, 1] = w[..., 2], -w[..., 1], w[..., 0]
    return S


def _jlog3(w):
    """Jacobian of log3 at exp(w) (the inverse right Jacobian of SO(3)), for (..., 3)."""
    th = np.linalg.norm(w, axis=-1)
    S = _skew(w)
    small = th < 1e-4
    ths = np.where(small, 1.0, th)
    coef = np.where(small, 1.0 / 12.0 + th**2 / 720.0, 1.0 / ths**2 - (1.0 + np.cos(ths)) / (2.0 * ths * np.sin(ths)))
    return np.eye(3) + 0.5 * S + coef[..., None, None] * (S @ S)
