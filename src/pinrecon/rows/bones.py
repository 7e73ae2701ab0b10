"""Bone rows: a BVH joint held to its ASF bone's own degrees of freedom and limits.

A CMU skeleton (ASF) gives each bone a frame ``C`` (its ``axis``), the rotations it may
make (``dof``: a foot ``rx rz``, a clavicle ``ry rz``, a femur or humerus ``rx ry rz``) and
their limits (degrees), with the bone's rotation ``C M C^-1``, ``M = Rz(rz) Ry(ry)
Rx(rx)`` over its DOFs. The BVH release writes the same rotation as three channels
(``pinrecon.io.asf``). ``Figure.with_limits(asf)`` carries the limits onto the channels as
the box containing their image, which is loose for a three-DOF bone: the humerus's box in
its own angles becomes one in the channels that also holds arms the ASF rules out. Here
every frame's channel rotation ``R`` is turned back into the bone's angles, ``M = C^T R C``
decomposed as ``Rz(a) Ry(b) Rx(c)`` (``a = atan2(M10, M00)``, ``b = -asin(M20)``, ``c =
atan2(M21, M22)``), and each angle gets a row:

* an angle the bone does not have (the foot's ``ry``): ``r = angle / sigma_lock``, held at 0;
* an angle it has, with limits ``[lo, hi]``: ``r = (min(0, angle - lo + m) + max(0, angle -
  hi - m)) / sigma_limit``, ``m`` a margin, zero inside (the barrier of
  :mod:`pinrecon.rows.limits` in the bone's own angles).

One-DOF bones (knees, elbows) are :mod:`pinrecon.rows.hinges`. The captured clips keep the
missing DOFs at 0 exactly, but leave the ASF's limits by a few degrees in places (the
bundled run's humerus 5 degrees past its ``rz`` limit, its femur 13 degrees past ``rx``):
the limits are soft (``sigma_limit`` 0.1 rad, a margin of 5 degrees), and they are what tells
an arm reflected in depth from the truth under an orthographic camera (bench/README.md, the
lab run). The Jacobian is analytic: ``dR/dt_0 = K_0 R``, ``dR/dt_1 = R_0 R_1 K_1 R_2``,
``dR/dt_2 = R K_2`` (``K`` the channel axis's cross-product matrix), ``dM = C^T dR C``, and
the angles' derivatives from ``dM``.
"""

from __future__ import annotations

import numpy as np

from ..rotations import euler_to_matrix
from .base import RowBlock, RowKind, State, crop_every_frame
from .hinges import channel_joints, hinge_row

__all__ = ["Bones", "bone_angles", "bone_row", "skeleton_rows"]

_K = {
    "X": np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),
    "Y": np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]),
    "Z": np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]),
}
_DOFS = ("rz", "ry", "rx")  # the order of the decomposition M = Rz Ry Rx


def bone_angles(M: np.ndarray, dM: np.ndarray | None = None):
    """``(a, b, c)`` with ``M = Rz(a) Ry(b) Rx(c)`` (radians, ``(..., 3)``), and with ``dM``
    (``(..., k, 3, 3)``, ``k`` directions) their derivatives ``(..., 3, k)``."""
    m00, m10, m20, m21, m22 = M[..., 0, 0], M[..., 1, 0], M[..., 2, 0], M[..., 2, 1], M[..., 2, 2]
    s = np.clip(-m20, -1.0, 1.0)
    ang = np.stack([np.arctan2(m10, m00), np.arcsin(s), np.arctan2(m21, m22)], axis=-1)
    if dM is None:
        return ang
    n1 = np.maximum(m00**2 + m10**2, 1e-12)[..., None]
    n2 = np.maximum(m21**2 + m22**2, 1e-12)[..., None]
    cb = np.sqrt(np.maximum(1.0 - s**2, 1e-12))[..., None]
    da = (m00[..., None] * dM[..., 1, 0] - m10[..., None] * dM[..., 0, 0]) / n1
    db = -dM[..., 2, 0] / cb
    dc = (m22[..., None] * dM[..., 2, 1] - m21[..., None] * dM[..., 2, 2]) / n2
    return ang, np.stack([da, db, dc], axis=-2)


class Bones(RowKind):
    """Rows holding BVH joints to their ASF bones' DOFs and limits.

    figure : a BVH figure; bones : ``{joint: {"axis": C (3x3), "dof": [...], "limits":
    [[lo, hi], ...] degrees, one per DOF}}`` (``pinrecon.io.asf.bvh_bones_from_asf``);
    sigma_lock, sigma_limit : radians; margin_deg : degrees added to each limit. A bone
    with a channel outside ``active`` is left out."""

    name = "bones"

    def __init__(self, figure, n_frames, bones, sigma_lock=0.01, sigma_limit=0.1, margin_deg=5.0, active=None):
        m = figure.model
        self.joints, self.axes, qidx, cols, Cs, lo, hi, inv = [], [], [], [], [], [], [], []
        for joint, spec in bones.items():
            ch = channel_joints(m, joint, active)
            if ch is None:
                continue
            lims = dict(zip(spec["dof"], spec.get("limits") or [None] * len(spec["dof"])))
            b_lo, b_hi, b_inv = np.full(3, -np.inf), np.full(3, np.inf), np.zeros(3)
            for i, d in enumerate(_DOFS):
                if d not in lims:  # a DOF the bone does not have: held at zero
                    b_lo[i], b_hi[i], b_inv[i] = 0.0, 0.0, 1.0 / sigma_lock
                elif lims[d] is not None:
                    b_lo[i] = np.radians(lims[d][0] - margin_deg)
                    b_hi[i] = np.radians(lims[d][1] + margin_deg)
                    b_inv[i] = 1.0 / sigma_limit
            self.joints.append(joint)
            self.axes.append(ch[0])
            qidx.append(ch[1])
            cols.append(ch[2])
            Cs.append(np.asarray(spec["axis"], float).reshape(3, 3))
            lo.append(b_lo), hi.append(b_hi), inv.append(b_inv)
        self.qidx = np.array(qidx, int).reshape(-1, 3)
        self.cols = np.array(cols, int).ravel()
        self.C = np.array(Cs, float).reshape(-1, 3, 3)
        self.lower, self.upper = np.array(lo).reshape(-1, 3), np.array(hi).reshape(-1, 3)
        self.inv_sigma = np.array(inv).reshape(-1, 3)
        self.frames = np.arange(n_frames)

    def angles(self, Q: np.ndarray) -> np.ndarray:
        """``(T, bones, 3)`` the bones' own angles ``(rz, ry, rx)`` in radians."""
        return np.stack([self._angles(Q, h)[0] for h in range(len(self.joints))], axis=1)

    def _angles(self, Q, h, jacobian=False):
        seq, C = self.axes[h], self.C[h]
        deg = np.degrees(Q[:, self.qidx[h]])
        R0, R1, R2 = (euler_to_matrix(seq[k], deg[:, k : k + 1]) for k in range(3))
        R = R0 @ R1 @ R2
        M = C.T @ R @ C
        if not jacobian:
            return bone_angles(M), None
        dR = np.stack([_K[seq[0]] @ R, R0 @ R1 @ _K[seq[1]] @ R2, R @ _K[seq[2]]], axis=1)  # (N, 3, 3, 3)
        return bone_angles(M, C.T @ dR @ C)

    def crop(self, lo: int, hi: int) -> Bones:
        return crop_every_frame(self, lo, hi)

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        Q = state.Q
        N, H = len(self.frames), len(self.joints)
        r = np.zeros((N, 3 * H))
        J = np.zeros((N, 1, 3 * H, 3 * H)) if jacobian else None
        for h in range(H):
            ang, dang = self._angles(Q, h, jacobian)
            below, above = ang < self.lower[h], ang > self.upper[h]
            viol = np.where(below, ang - self.lower[h], 0.0) + np.where(above, ang - self.upper[h], 0.0)
            r[:, 3 * h : 3 * h + 3] = viol * self.inv_sigma[h]
            if jacobian:
                on = (below | above) * self.inv_sigma[h]  # (N, 3)
                J[:, 0, 3 * h : 3 * h + 3, 3 * h : 3 * h + 3] = dang * on[..., None]
        return RowBlock(self.frames[:, None], r, J, self.cols, self.name)


def bone_row(figure, n_frames: int, active=None) -> Bones | None:
    """The :class:`Bones` row of a figure whose metadata names ASF bones (``meta["bones"]``,
    set by ``Figure.with_limits`` from a CMU ASF skeleton), else None."""
    bones = (figure.meta or {}).get("bones")
    if not bones:
        return None
    row = Bones(figure, n_frames, bones, active=active)
    return row if row.joints else None


def skeleton_rows(figure, n_frames: int, active=None) -> list:
    """The rows a BVH figure's ASF skeleton adds (``Figure.with_limits(asf)``): its hinges
    (:mod:`pinrecon.rows.hinges`) and its other bones (:class:`Bones`); none for others."""
    return [r for r in (hinge_row(figure, n_frames, active), bone_row(figure, n_frames, active)) if r is not None]
