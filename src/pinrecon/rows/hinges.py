"""Hinge rows: a BVH joint whose three rotation channels stand for a one-DOF bone.

A BVH file gives every joint three rotation channels, but a knee or an elbow turns about
one axis: in a CMU skeleton (ASF) the tibia and the radius have one degree of freedom, a
rotation about the tilted axis ``C e_x`` of the bone's ``axis`` frame, and the BVH release's
three channels compose exactly that rotation (``pinrecon.io.asf``; the bundled clips'
knees and elbows lie on their ASF axis to 0.0 degrees). Limits alone, carried onto the
channels as a box (``Figure.with_limits``), leave such a joint three degrees of freedom
(the elbow's box spans 190, 78 and 130 degrees): a forearm can then be mirrored in depth
without turning the upper arm, and under an orthographic camera nothing else tells the
mirror from the truth (bench/README.md, the lab run).

The row holds the joint's rotation on its axis ``a``: with ``R = R_0(t_0) R_1(t_1) R_2(t_2)``
the channels' rotations in their order and ``w = log(R)`` its rotation vector,

    r = B^T w / sigma,      B = [u, v] an orthonormal basis of the plane normal to ``a``,

two rows per hinge and frame, zero exactly when ``R`` turns about ``a``. The Jacobian is
analytic: ``dw = Jlog3(R) omega`` (Pinocchio's ``Jlog3``, written vectorised over the
frames; ``omega`` the body-frame angular velocity),
``omega = R_2^T R_1^T e_0 dt_0 + R_2^T e_1 dt_1 + e_2 dt_2``.
"""

from __future__ import annotations

import re

import numpy as np
from scipy.spatial.transform import Rotation

from ..rotations import euler_to_matrix
from .base import RowBlock, RowKind, State, crop_every_frame

__all__ = ["Hinges", "channel_joints", "hinge_row"]

_AXES = {"X": np.array([1.0, 0.0, 0.0]), "Y": np.array([0.0, 1.0, 0.0]), "Z": np.array([0.0, 0.0, 1.0])}


def channel_joints(model, joint: str, active=None) -> tuple[str, list[int], list[int]] | None:
    """A BVH joint's three rotation channels in ``model`` (joints ``<joint>_<X|Y|Z>rotation``,
    in the model's order): ``(letters, q indices, v indices)``; None when it has not three,
    or when a channel is outside ``active``."""
    ids = [j for j in range(1, model.njoints) if re.fullmatch(re.escape(joint) + r"_[XYZ]rotation", model.names[j])]
    if len(ids) != 3 or (active is not None and not all(active[model.idx_vs[j]] for j in ids)):
        return None
    return "".join(model.names[j][-9] for j in ids), [model.idx_qs[j] for j in ids], [model.idx_vs[j] for j in ids]


def _jlog3(w):
    """(..., 3, 3) the derivative of ``log(R exp(d))`` at ``d = 0`` for ``R = exp(w)``
    (``pin.Jlog3``, vectorised): ``I + [w]/2 + (1/t^2 - (1 + cos t) / (2 t sin t)) [w]^2``."""
    t = np.linalg.norm(w, axis=-1)
    K = np.zeros(w.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    K -= np.swapaxes(K, -1, -2)
    small = t < 1e-4
    ts = np.where(small, 1.0, t)
    c = np.where(small, 1.0 / 12.0 + t**2 / 720.0, 1.0 / ts**2 - (1.0 + np.cos(ts)) / (2.0 * ts * np.sin(ts)))
    return np.eye(3) + 0.5 * K + c[..., None, None] * (K @ K)


class Hinges(RowKind):
    """Rows holding BVH joints on their hinge axes.

    figure : a BVH figure; hinges : ``{joint: axis (3,)}`` (the joint's channels are the
    figure's joints ``<joint>_<X|Y|Z>rotation``, in the model's order); sigma : radians
    (the rotation's allowed angle off the axis, about). A hinge with a channel outside
    ``active`` is left out."""

    name = "hinges"

    def __init__(self, figure, n_frames, hinges, sigma=0.01, active=None):
        m = figure.model
        qidx, cols, axes, bases, labels = [], [], [], [], []
        for joint, a in hinges.items():
            ch = channel_joints(m, joint, active)
            if ch is None:
                continue
            a = np.asarray(a, float) / np.linalg.norm(a)
            u = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
            u /= np.linalg.norm(u)
            bases.append(np.stack([u, np.cross(a, u)]))  # (2, 3)
            axes.append(ch[0])  # the channels' letters, in order
            qidx.append(ch[1])
            cols.append(ch[2])
            labels.append(joint)
        self.qidx = np.array(qidx, int).reshape(-1, 3)
        self.cols = np.array(cols, int).ravel()
        self.axes = axes
        self.bases = np.array(bases, float).reshape(-1, 2, 3)
        self.joints = labels
        self.sigma = float(sigma)
        self.frames = np.arange(n_frames)

    def crop(self, lo: int, hi: int) -> Hinges:
        return crop_every_frame(self, lo, hi)

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        Q = state.Q
        N, H = len(self.frames), len(self.joints)
        r = np.zeros((N, 2 * H))
        J = np.zeros((N, 1, 2 * H, 3 * H)) if jacobian else None
        for h, seq in enumerate(self.axes):
            deg = np.degrees(Q[:, self.qidx[h]])
            w = Rotation.from_matrix(euler_to_matrix(seq, deg)).as_rotvec()  # (N, 3) log(R_0 R_1 R_2)
            r[:, 2 * h : 2 * h + 2] = w @ self.bases[h].T / self.sigma
            if jacobian:
                R1, R2 = euler_to_matrix(seq[1], deg[:, 1:2]), euler_to_matrix(seq[2], deg[:, 2:3])
                e0, e1, e2 = (_AXES[c] for c in seq)
                W = np.stack([np.swapaxes(R1 @ R2, 1, 2) @ e0, np.swapaxes(R2, 1, 2) @ e1,
                              np.broadcast_to(e2, (N, 3))], axis=2)  # (N, 3, 3) body velocity per channel
                J[:, 0, 2 * h : 2 * h + 2, 3 * h : 3 * h + 3] = self.bases[h] @ _jlog3(w) @ W / self.sigma
        return RowBlock(self.frames[:, None], r, J, self.cols, self.name)


def hinge_row(figure, n_frames: int, active=None, sigma: float = 0.01) -> Hinges | None:
    """The :class:`Hinges` row of a figure whose metadata names hinges (``meta["hinges"]``,
    set by ``Figure.with_limits`` from a CMU ASF skeleton), else None."""
    hinges = (figure.meta or {}).get("hinges")
    if not hinges:
        return None
    row = Hinges(figure, n_frames, hinges, sigma, active)
    return row if row.joints else None
