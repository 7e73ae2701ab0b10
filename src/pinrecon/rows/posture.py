"""A weak posture prior: every 1-dof joint pulled towards a reference pose (the rest pose).

``r = (q_joint - q_ref) / sigma`` per frame, a diagonal block. With a large ``sigma``
(default 1 rad) it barely moves well-observed joints (the bias on a joint is about
``(q - q_ref) / (sigma^2 H_data)``), but it gives the directions the data cannot see
(the twist of a limb whose keypoints are collinear, redundant rotations of zero-length
BVH joints) a definite value, which keeps the normal equations well conditioned. This
plays the role of DiFranco et al.'s stabilising term ``kI``, in joint space.
"""

from __future__ import annotations

import numpy as np

from .base import RowBlock, RowKind, State

__all__ = ["Posture"]


class Posture(RowKind):
    name = "posture"

    def __init__(self, figure, n_frames, q_ref, sigma=1.0, active=None):
        m = figure.model
        cols, qidx = [], []
        for jid in range(1, m.njoints):
            if m.nqs[jid] == 1 and m.nvs[jid] == 1:
                iv = m.idx_vs[jid]
                if active is None or active[iv]:
                    cols.append(iv)
                    qidx.append(m.idx_qs[jid])
        self.cols = np.array(cols, dtype=int)
        self.qidx = np.array(qidx, dtype=int)
        self.q_ref = np.asarray(q_ref, float)[self.qidx]
        self.inv_sigma = 1.0 / float(sigma)
        self.frames = np.arange(n_frames)

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        r = (state.Q[:, self.qidx] - self.q_ref) * self.inv_sigma
        J = None
        if jacobian:
            J = np.broadcast_to(np.full(len(self.cols), self.inv_sigma), (len(self.frames), 1, len(self.cols)))
        return RowBlock(self.frames[:, None], r, J, self.cols, self.name, diagonal=True)
