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


def row_jacobian_error(row, figure, Q, eps: float = 1e-6) -> float:
    """The largest difference between a per-frame row kind's analytic Jacobian and central
    finite differences over the q entries of its columns (1-dof joints: the tangent entry is
    the q entry); ``row.qidx`` lists those q entries in the order of ``row.cols``."""
    from pinrecon.rows import State

    def r(Qx):
        return row.evaluate(State(figure, Qx, np.zeros(0, int), False), False).r

    J = row.evaluate(State(figure, Q, np.zeros(0, int), False), True).J
    err = 0.0
    for k, iq in enumerate(np.asarray(row.qidx).ravel()):
        Qp, Qm = Q.copy(), Q.copy()
        Qp[:, iq] += eps
        Qm[:, iq] -= eps
        err = max(err, float(np.abs(J[:, 0, :, k] - (r(Qp) - r(Qm)) / (2 * eps)).max()))
    return err
