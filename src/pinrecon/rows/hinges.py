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
analytic: ``dw = Jlog3(R) omega`` (``pin.Jlog3``, ``omega`` the body-frame angular
velocity), ``omega = R_2^T R_1^T e_0 dt_0 + R_2^T e_1 dt_1 + e_2 dt_2``.
"""

from __future__ import annotations

import re

import numpy as np
import pinocchio as pin

from .base import RowBlock, RowKind, State

__all__ = ["Hinges", "hinge_row"]

_AXES = {"X": np.array([1.0, 0.0, 0.0]), "Y": np.array([0.0, 1.0, 0.0]), "Z": np.array([0.0, 0.0, 1.0])}


def _rot(e, t):
    """(N, 3, 3) rotations by angles ``t`` (N,) about the unit axis ``e``."""
    K = np.array([[0.0, -e[2], e[1]], [e[2], 0.0, -e[0]], [-e[1], e[0], 0.0]])
    s, c = np.sin(t)[:, None, None], np.cos(t)[:, None, None]
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


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
            ids = [j for j in range(1, m.njoints) if re.fullmatch(re.escape(joint) + r"_[XYZ]rotation", m.names[j])]
            if len(ids) != 3 or (active is not None and not all(active[m.idx_vs[j]] for j in ids)):
                continue
            a = np.asarray(a, float) / np.linalg.norm(a)
            u = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
            u /= np.linalg.norm(u)
            bases.append(np.stack([u, np.cross(a, u)]))  # (2, 3)
            qidx.append([m.idx_qs[j] for j in ids])
            cols.append([m.idx_vs[j] for j in ids])
            axes.append([_AXES[m.names[j][-9]] for j in ids])
            labels.append(joint)
        self.qidx = np.array(qidx, int).reshape(-1, 3)
        self.cols = np.array(cols, int).ravel()
        self.axes = axes
        self.bases = np.array(bases, float).reshape(-1, 2, 3)
        self.joints = labels
        self.sigma = float(sigma)
        self.frames = np.arange(n_frames)

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        Q = state.Q
        N, H = len(self.frames), len(self.joints)
        r = np.zeros((N, 2 * H))
        J = np.zeros((N, 1, 2 * H, 3 * H)) if jacobian else None
        for h in range(H):
            e0, e1, e2 = self.axes[h]
            t = Q[:, self.qidx[h]]
            R1, R2 = _rot(e1, t[:, 1]), _rot(e2, t[:, 2])
            R = _rot(e0, t[:, 0]) @ R1 @ R2
            for n in range(N):
                w = pin.log3(R[n])
                r[n, 2 * h : 2 * h + 2] = self.bases[h] @ w / self.sigma
                if jacobian:
                    W = np.stack([R2[n].T @ R1[n].T @ e0, R2[n].T @ e1, e2], axis=1)  # (3, 3) body velocity
                    J[n, 0, 2 * h : 2 * h + 2, 3 * h : 3 * h + 3] = self.bases[h] @ pin.Jlog3(R[n]) @ W / self.sigma
        return RowBlock(self.frames[:, None], r, J, self.cols, self.name)


def hinge_row(figure, n_frames: int, active=None, sigma: float = 0.01) -> Hinges | None:
    """The :class:`Hinges` row of a figure whose metadata names hinges (``meta["hinges"]``,
    set by ``Figure.with_limits`` from a CMU ASF skeleton), else None."""
    hinges = (figure.meta or {}).get("hinges")
    if not hinges:
        return None
    row = Hinges(figure, n_frames, hinges, sigma, active)
    return row if row.joints else None
