"""The contract between row kinds and the solver.

A *row kind* (measurement, 3D points, limits, smoothing, keyframes) is a small object
that knows which frames it touches and, for a trajectory state, returns a
:class:`RowBlock`: whitened residuals ``r`` (cost ``0.5 |r|^2``) and their Jacobian
blocks with respect to the tangent spaces of the frames each row group touches.
The solver only sees RowBlocks, so adding a row kind never touches the solver.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["RowBlock", "RowKind", "State"]


@dataclass
class RowBlock:
    """Residuals and Jacobian blocks of N row groups.

    Attributes
    ----------
    frames : (N, s) int, the s frames row group n touches, in increasing order.
    r : (N, m) whitened residuals.
    J : Jacobian blocks, ``None`` when not requested.
        dense: (N, s, m, c), the derivative of r[n] w.r.t. the tangent entries ``cols``
        of frame ``frames[n, i]``;
        diagonal (``diagonal=True``, m == c): (N, s, m), entry k being d r[n, k] /
        d v[frames[n, i], cols[k]] (all other derivatives are zero).
    cols : (c,) tangent indices the Jacobian blocks cover.
    name : row kind, for the per-kind cost report.
    diagonal : whether J is stored as diagonal blocks (see J).
    cost_value : the row kind's own cost when it is not 0.5 |r|^2 (robust losses).
    """

    frames: np.ndarray
    r: np.ndarray
    J: np.ndarray | None
    cols: np.ndarray
    name: str
    diagonal: bool = False
    cost_value: float | None = None

    @property
    def cost(self) -> float:
        """0.5 |r|^2, or the robust cost when the row kind reweights (``cost_value``)."""
        if self.cost_value is not None:
            return self.cost_value
        return 0.5 * float(np.einsum("nm,nm->", self.r, self.r))


class RowKind:
    """Base class: ``evaluate(state, jacobian)`` returns a :class:`RowBlock`.

    Subclasses set ``name`` and may declare ``kinematic_frames`` (frames at which they
    need keypoint positions/Jacobians), so the state computes forward kinematics once
    for all row kinds.
    """

    name = "rows"
    kinematic_frames: np.ndarray = np.zeros(0, dtype=int)

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:  # pragma: no cover
        raise NotImplementedError


class State:
    """A trajectory ``Q`` (T, nq) with keypoint kinematics cached at the frames rows need.

    ``points[slot[t]]`` (K, 3) and ``jacobians[slot[t]]`` (K, 3, nv) for frames t in
    ``frames``; computed once, shared by every row kind.
    """

    def __init__(self, figure, Q: np.ndarray, frames: np.ndarray, jacobian: bool):
        self.figure = figure
        self.Q = Q
        self.frames = frames
        self.slot = np.full(Q.shape[0], -1, dtype=int)
        self.slot[frames] = np.arange(len(frames))
        if len(frames):
            if jacobian:
                self.points, self.jacobians = figure.keypoint_jacobians(Q[frames])
            else:
                self.points, self.jacobians = figure.keypoints(Q[frames]), None
        else:
            self.points = np.zeros((0, figure.K, 3))
            self.jacobians = np.zeros((0, figure.K, 3, figure.nv)) if jacobian else None
