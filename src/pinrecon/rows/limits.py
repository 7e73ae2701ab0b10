"""Joint-limit barrier rows (DiFranco et al. eq. 2), lower and upper limits.

For every frame and every limited 1-dof joint with value ``q`` and limits ``[lo, hi]``:
``r = (min(0, q - lo) + max(0, q - hi)) / sigma``: zero inside the limits, a quadratic
restoring cost outside (continuous with continuous first derivative). The Jacobian is
``1 / sigma`` where the limit is violated, else 0 (a diagonal block).
"""

from __future__ import annotations

import numpy as np

from .base import RowBlock, RowKind, State, crop_every_frame

__all__ = ["JointLimits"]


class JointLimits(RowKind):
    """Barrier rows for all frames ``0..T-1``.

    Parameters
    ----------
    figure : gives ``lower_v``, ``upper_v``, ``limited_v`` and the q index of each v.
    n_frames : T.
    sigma : radians (metres for prismatic joints); small = stiff barrier.
    """

    name = "limits"

    def __init__(self, figure, n_frames, sigma=0.01):
        m = figure.model
        cols, qidx = [], []
        for jid in range(1, m.njoints):
            if m.nvs[jid] == 1 and m.nqs[jid] == 1 and figure.limited_v[m.idx_vs[jid]]:
                cols.append(m.idx_vs[jid])
                qidx.append(m.idx_qs[jid])
        self.cols = np.array(cols, dtype=int)
        self.qidx = np.array(qidx, dtype=int)
        self.lower = figure.lower_v[self.cols]
        self.upper = figure.upper_v[self.cols]
        self.frames = np.arange(n_frames)
        self.inv_sigma = 1.0 / float(sigma)

    def crop(self, lo: int, hi: int) -> JointLimits:
        return crop_every_frame(self, lo, hi)

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        q = state.Q[:, self.qidx]
        below = np.minimum(0.0, q - self.lower)
        above = np.maximum(0.0, q - self.upper)
        r = (below + above) * self.inv_sigma
        J = None
        if jacobian:
            J = (((below < 0) | (above > 0)) * self.inv_sigma)[:, None, :]
        return RowBlock(self.frames[:, None], r, J, self.cols, self.name, diagonal=True)
