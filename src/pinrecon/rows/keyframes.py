"""Joint-space keyframe rows (DiFranco et al. eq. 4), full or partial, root pose included.

For a keyframe f at frame t with standard deviation sigma, over the tangent entries it
sets (unset parameters have infinite variance: no row):

    r = (f (-) q_t)[set] / sigma = pin.difference(f, q_t)[set] / sigma,
    dr/dv_t = pin.dDifference(f, q_t, ARG1)[set, set] / sigma.

Joint values are radians (metres for prismatic joints). The free-flyer root takes a
7-vector ``x y z qx qy qz qw`` (its 6 rows are the SE(3) log, translation in metres and
rotation in radians) or a 3-vector translation; for the latter
``r = (t(q_t) - t_f) / sigma`` with ``dt/dv = [R(q_t), 0]`` (a local twist moves the
root by ``R v``).
"""

from __future__ import annotations

import copy

import numpy as np
import pinocchio as pin

from .base import NoRows, RowBlock, RowKind, State

__all__ = ["JointKeyframes"]


class JointKeyframes(RowKind):
    """Rows for a list of joint-space keyframes.

    Parameters
    ----------
    figure : the figure.
    items : list of ``(frame, sigma, {joint name: value})`` with names already validated.
    """

    name = "keyframe_joints"

    def __init__(self, figure, items):
        self.figure = figure
        m = figure.model
        self.items = []
        cols_all: set[int] = set()
        for frame, sigma, values in items:
            f = pin.neutral(m)
            set_cols, trans_only = [], None
            for name, val in values.items():
                jid = figure.joint_id(name)
                iq, nq, iv, nv = m.idx_qs[jid], m.nqs[jid], m.idx_vs[jid], m.nvs[jid]
                val = np.atleast_1d(np.asarray(val, float))
                if figure.floating and jid == 1 and val.size == 3:
                    trans_only = val.copy()
                    set_cols += [0, 1, 2]
                    continue
                if figure.floating and jid == 1:
                    val = val.copy()
                    val[3:7] /= np.linalg.norm(val[3:7])
                f[iq : iq + nq] = val
                set_cols += list(range(iv, iv + nv))
            self.items.append((int(frame), 1.0 / float(sigma), f, np.array(sorted(set_cols)), trans_only))
            cols_all.update(set_cols)
        self.cols = np.array(sorted(cols_all), dtype=int)
        self.frames = np.array([it[0] for it in self.items], dtype=int)
        # items that set only 1-dof Euclidean joints: difference q - f, derivative 1 (no Pinocchio call)
        q_of_v = {m.idx_vs[j]: m.idx_qs[j] for j in range(1, m.njoints) if m.nqs[j] == 1 and m.nvs[j] == 1}
        pos = self._pos = {col: k for k, col in enumerate(self.cols)}
        self._euclid = [
            (np.array([q_of_v[c] for c in sc]), np.array([pos[c] for c in sc]))
            if trans is None and all(c in q_of_v for c in sc) else None
            for (_, _, _, sc, trans) in self.items
        ]

    def crop(self, lo: int, hi: int) -> JointKeyframes:
        new = copy.copy(self)
        keep = [i for i, it in enumerate(self.items) if lo <= it[0] < hi]
        if not keep:
            return NoRows(self.name)
        new.items = [(self.items[i][0] - lo,) + tuple(self.items[i][1:]) for i in keep]
        new._euclid = [self._euclid[i] for i in keep]
        new.frames = np.array([it[0] for it in new.items], dtype=int)
        return new

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        m = self.figure.model
        N, c = len(self.items), len(self.cols)
        if all(e is not None for e in self._euclid):  # 1-dof Euclidean joints only: a diagonal block
            r = np.zeros((N, c))
            Jd = np.zeros((N, 1, c)) if jacobian else None
            for n, ((frame, inv_sigma, f, _, _), (qi, idx)) in enumerate(zip(self.items, self._euclid)):
                r[n, idx] = (state.Q[frame, qi] - f[qi]) * inv_sigma
                if jacobian:
                    Jd[n, 0, idx] = inv_sigma
            return RowBlock(self.frames[:, None], r, Jd, self.cols, self.name, diagonal=True)
        r = np.zeros((N, c))
        J = np.zeros((N, 1, c, c)) if jacobian else None
        pos = self._pos
        for n, (frame, inv_sigma, f, set_cols, trans_only) in enumerate(self.items):
            q = state.Q[frame]
            fast = self._euclid[n]
            if fast is not None:
                qi, idx = fast
                r[n, idx] = (q[qi] - f[qi]) * inv_sigma
                if jacobian:
                    J[n, 0, idx, idx] = inv_sigma
                continue
            d = pin.difference(m, f, q)
            idx = [pos[k] for k in set_cols]
            r[n, idx] = d[set_cols] * inv_sigma
            if jacobian:
                Jd = pin.dDifference(m, f, q, pin.ARG1)
                J[n, 0][np.ix_(idx, idx)] = Jd[np.ix_(set_cols, set_cols)] * inv_sigma
            if trans_only is not None:
                k3 = [pos[k] for k in (0, 1, 2)]
                r[n, k3] = (q[0:3] - trans_only) * inv_sigma
                if jacobian:
                    R = pin.Quaternion(q[3:7]).normalized().matrix()
                    J[n, 0][np.ix_(k3, k3)] = R * inv_sigma
                    # the translation rows do not depend on the rotation tangent (at v = 0)
        return RowBlock(self.frames[:, None], r, J, self.cols, self.name)
