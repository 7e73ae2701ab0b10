"""A posture prior: every 1-dof joint pulled towards a reference pose.

``r = (q_joint - q_ref) / sigma`` per frame, a diagonal block; ``sigma`` one number or one
per configuration entry (``(nq,)``, read at the joints' q indices). The generic human's
reference and ``sigma`` are its pose prior learned from motion capture (the joints' mean and
standard deviation, :func:`posture_row`); other figures get the rest pose
and one weak ``sigma``. With a large ``sigma``
(default 1 rad) it barely moves well-observed joints (the bias on a joint is about
``(q - q_ref) / (sigma^2 H_data)``), but it gives the directions the data cannot see
(the twist of a limb whose keypoints are collinear, redundant rotations of zero-length
BVH joints) a definite value, which keeps the normal equations well conditioned. This
plays the role of DiFranco et al.'s stabilising term ``kI``, in joint space.
"""

from __future__ import annotations

import functools
import json

import numpy as np

from .._resources import model_path
from .base import RowBlock, RowKind, State

__all__ = ["Posture", "pose_prior", "posture_row", "rest_pose"]


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
        sig = np.asarray(sigma, float)
        self.inv_sigma = 1.0 / (sig[self.qidx] if sig.ndim else np.full(len(self.qidx), float(sig)))
        self.frames = np.arange(n_frames)

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        r = (state.Q[:, self.qidx] - self.q_ref) * self.inv_sigma
        J = None
        if jacobian:
            J = np.broadcast_to(self.inv_sigma, (len(self.frames), 1, len(self.cols)))
        return RowBlock(self.frames[:, None], r, J, self.cols, self.name, diagonal=True)


def pose_prior(figure, rest: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(q_ref (nq,), sigma (nq,)): the generic human's joint means and standard deviations
    over motion capture (``models/priors/human_pose.json``, made by
    ``tools/fit_pose_prior.py``); entries the file does not name keep ``rest`` and 1 rad."""
    table = _pose_prior_table()
    m = figure.model
    ref, sigma = np.array(rest, float), np.ones(figure.nq)
    for jid in range(1, m.njoints):
        if m.names[jid] in table and m.nqs[jid] == 1:
            ref[m.idx_qs[jid]], sigma[m.idx_qs[jid]] = table[m.names[jid]]
    return ref, sigma


@functools.lru_cache(maxsize=1)
def _pose_prior_table() -> dict:
    path = model_path("priors", "human_pose.json")
    return {k: (float(v[0]), float(v[1])) for k, v in json.loads(path.read_text())["joints"].items()}


def posture_row(figure, n_frames: int, weights, active=None) -> Posture | None:
    """The posture prior of ``figure`` (``weights`` a :class:`pinrecon.problem.Weights`): the
    generic human's pose prior learned from motion capture (``weights.pose_prior``,
    :func:`pose_prior`), else the rest pose with ``weights.sigma_posture`` (``None``: no row)."""
    if weights.pose_prior is not None and figure.meta.get("generic") == "human":
        ref, sigma = pose_prior(figure, rest_pose(figure))
        return Posture(figure, n_frames, ref, sigma * weights.pose_prior, active)
    if weights.sigma_posture is None:
        return None
    return Posture(figure, n_frames, rest_pose(figure), weights.sigma_posture, active)


def rest_pose(figure, margin=0.05):
    """The neutral configuration clamped inside the joint limits (with a margin)."""
    return figure.clamp(figure.neutral(), margin=margin)
