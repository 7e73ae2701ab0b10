"""The dense reference of row blocks: J and r written out entry by entry from the
:class:`pinrecon.rows.RowBlock` definition (frames, columns, diagonal blocks, global
columns), independently of the banded assembly. Tests compare the assembled normal
equations, the Schur solve and the rows' Jacobians against it."""

from __future__ import annotations

import numpy as np


def dense_jacobian(blocks, T: int, nv: int, n_g: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Dense J (rows x (T nv + n_g)) and r of ``blocks``: block by block, each block's
    row groups in order, each group's residuals in order (``r.ravel()``)."""
    Js, rs = [], []
    for b in blocks:
        N, m = b.r.shape
        for n in range(N):
            J = np.zeros((m, T * nv + n_g))
            for i in range(b.frames.shape[1]):
                t = b.frames[n, i]
                for ci, c in enumerate(b.cols):
                    if b.diagonal:
                        J[ci, t * nv + c] += b.J[n, i, ci]
                    else:
                        J[:, t * nv + c] += b.J[n, i, :, ci]
            if n_g and b.Jg is not None:
                for gi, c in enumerate(b.gcols):
                    J[:, T * nv + c] += b.Jg[n, :, gi]
            Js.append(J)
            rs.append(b.r[n])
    if not Js:
        return np.zeros((0, T * nv + n_g)), np.zeros(0)
    return np.vstack(Js), np.concatenate(rs)
