"""Constant-velocity smoothing rows (DiFranco et al. eq. 3), written on the Lie group.

With ``d_t = q_{t+1} (-) q_t = pin.difference(q_t, q_{t+1})`` (for the free-flyer root
the SE(3) log of ``q_t^-1 q_{t+1}``, a body twist), the row for frame t is

    r_t = W (d_t - d_{t-1}) / dt^2 * sqrt(dt),    t = 1 .. T-2,

a discrete acceleration, zero exactly when the motion has constant (body) velocity, i.e.
when ``q_t`` is the geodesic midpoint of its neighbours. ``W = diag(1 / sigma)`` holds
separate acceleration standard deviations for root translation (m/s^2), root rotation
(rad/s^2) and joints (rad/s^2). The ``sqrt(dt)`` makes the sum approximate
``integral |a / sigma|^2 dt``, so the prior's strength does not change with the frame
rate (super-sampled reconstructions keep the same weights).

Jacobians, with ``J0_t, J1_t`` the derivatives of ``d_t`` w.r.t. the tangents at
``q_t`` and ``q_{t+1}`` (``pin.dDifference``):

    dr_t/dv_{t-1} = -W' J0_{t-1},  dr_t/dv_t = W' (J0_t - J1_{t-1}),  dr_t/dv_{t+1} = W' J1_t

(``W' = W sqrt(dt) / dt^2``). For 1-dof Euclidean joints ``J0 = -1``, ``J1 = 1`` and the
rows are the familiar ``q_{t-1} - 2 q_t + q_{t+1}``: those are returned as a diagonal
block; the root (and any joint whose group is not R^1) as a dense block.
"""

from __future__ import annotations

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

    def __init__(self, figure, n_frames, dt, sigma):
        self.figure = figure
        self.T = int(n_frames)
        m = figure.model
        euclid = np.zeros(figure.nv, dtype=bool)
        for jid in range(1, m.njoints):
            if m.nqs[jid] == 1 and m.nvs[jid] == 1:
                euclid[m.idx_vs[jid]] = True
        self.dense_cols = np.where(~euclid)[0]
        self.diag_cols = np.where(euclid)[0]
        self.diag_q = np.array(
            [m.idx_qs[j] for j in range(1, m.njoints) if m.nqs[j] == 1 and m.nvs[j] == 1], dtype=int
        )
        scale = np.sqrt(dt) / dt**2
        w = scale / np.asarray(sigma, float)
        self.w_dense = w[self.dense_cols]
        self.w_diag = w[self.diag_cols]
        self.frames = np.stack([np.arange(0, self.T - 2), np.arange(1, self.T - 1), np.arange(2, self.T)], 1)

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
