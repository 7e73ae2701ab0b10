"""The contract between row kinds and the solver.

A *row kind* (measurement, 3D points, limits, smoothing, keyframes) is a small object
that knows which frames it touches and, for a trajectory state, returns a
:class:`RowBlock`: whitened residuals ``r`` (cost ``0.5 |r|^2``) and their Jacobian
blocks with respect to the tangent spaces of the frames each row group touches.
The solver only sees RowBlocks, so adding a row kind never touches the solver.

**Global unknowns.** Besides the per-frame tangents a problem may have a small vector
``g`` of time-invariant unknowns (segment log-scale factors, camera log-focal length).
A row kind that depends on some of them returns their Jacobian columns in
``RowBlock.Jg`` (dense, one (m, c_g) matrix per row group) with ``RowBlock.gcols`` the
indices into ``g`` they cover; row kinds that do not depend on globals leave both
``None``. A row group may touch no frame at all (``frames`` of shape (N, 0), e.g. a
prior on ``g``). The :class:`State` carries ``g`` and, when the figure's proportions are
unknowns, the keypoints of the figure scaled by them with their derivatives
``dpoints_dglobals`` (see :mod:`pinrecon.proportions`).
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
    Jg : (N, m, c_g) derivative of r[n] w.r.t. the global unknowns ``g[gcols]``, or
        ``None`` (no dependence on globals, or not requested).
    gcols : (c_g,) indices into the global vector ``g`` that ``Jg`` covers.
    """

    frames: np.ndarray
    r: np.ndarray
    J: np.ndarray | None
    cols: np.ndarray
    name: str
    diagonal: bool = False
    cost_value: float | None = None
    Jg: np.ndarray | None = None
    gcols: np.ndarray | None = None

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

    With global unknowns: ``g`` (n_g,) their current values. With ``proportions`` (a
    :class:`pinrecon.proportions.Proportions`) the figure's log-scale factors are
    ``g[proportion_cols]`` (default ``0 .. n-1``): ``points`` and ``jacobians`` are those of
    the figure scaled by them, and ``dpoints_dglobals[slot[t]]`` (K, 3, n) holds
    d p_world / d g[proportion_cols] (``None`` without proportions or Jacobians).
    """

    def __init__(self, figure, Q: np.ndarray, frames: np.ndarray, jacobian: bool, g=None, proportions=None,
                 proportion_cols=None):
        self.figure = figure
        self.Q = Q
        self.frames = frames
        self.g = None if g is None else np.asarray(g, float)
        self.proportions = proportions
        self.dpoints_dglobals = None
        self.proportion_cols = np.zeros(0, dtype=int)
        self.slot = np.full(Q.shape[0], -1, dtype=int)
        self.slot[frames] = np.arange(len(frames))
        if proportions is not None:
            if self.g is None:
                raise ValueError("State: proportions need the global vector g")
            cols = np.arange(proportions.n) if proportion_cols is None else np.asarray(proportion_cols, dtype=int)
            self.proportion_cols = cols
            log_factors = self.g[cols]
            if jacobian:
                self.points, self.jacobians, self.dpoints_dglobals = proportions.kinematics(log_factors, Q[frames])
            else:
                self.points, self.jacobians = proportions.keypoints(log_factors, Q[frames]), None
        elif len(frames):
            if jacobian:
                self.points, self.jacobians = figure.keypoint_jacobians(Q[frames])
            else:
                self.points, self.jacobians = figure.keypoints(Q[frames]), None
        else:
            self.points = np.zeros((0, figure.K, 3))
            self.jacobians = np.zeros((0, figure.K, 3, figure.nv)) if jacobian else None
