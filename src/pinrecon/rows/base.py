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

import copy
import weakref
from dataclasses import dataclass

import numpy as np

from ..kinematics import keypoint_jacobians_from_world, point_jacobian_factors, rows_of

__all__ = ["NoRows", "RowBlock", "RowKind", "State", "crop_aligned", "crop_every_frame", "supported_columns"]


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
    group_cost : (N,) each row group's ``0.5 |r|^2`` when ``r`` leaves out residuals
        without a derivative (the lifted-pose rows' part along the bone), else ``None``.
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
    group_cost: np.ndarray | None = None

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

    def crop(self, lo: int, hi: int) -> RowKind | None:
        """These rows on frames ``lo .. hi - 1`` alone, as a problem of ``hi - lo`` frames
        (frames shifted to start at 0; a row group touching a frame outside is dropped), or
        ``None`` when the kind cannot be cropped
        (:meth:`pinrecon.problem.ReconstructionProblem.cropped`)."""
        return None


def crop_aligned(row, lo: int, hi: int, aligned=()):
    """A copy of ``row`` (one row group per entry of its (N,) ``frames``) with the groups
    whose frame lies in ``lo .. hi - 1``: ``frames`` shifted by ``-lo`` and the attributes
    named in ``aligned`` (arrays whose first axis follows ``frames``) selected alike."""
    keep = (row.frames >= lo) & (row.frames < hi)
    if not keep.any():
        return NoRows(row.name)
    new = copy.copy(row)
    for name in aligned:
        setattr(new, name, getattr(row, name)[keep])
    new.frames = row.frames[keep] - lo
    new.kinematic_frames = new.frames
    return new


class NoRows(RowKind):
    """A row kind cropped to frames where it has no row (:meth:`RowKind.crop`)."""

    def __init__(self, name: str):
        self.name = name

    def evaluate(self, state: State, jacobian: bool = True) -> list:
        return []

    def crop(self, lo: int, hi: int) -> NoRows:
        return self


def crop_every_frame(row, lo: int, hi: int):
    """A copy of ``row`` (one row group per frame, ``frames = arange(T)``, evaluated on the
    whole trajectory) over ``hi - lo`` frames."""
    new = copy.copy(row)
    new.frames = np.arange(int(hi) - int(lo))
    return new


class State:
    """A trajectory ``Q`` (T, nq) with keypoint kinematics cached at the frames rows need.

    ``points[slot[t]]`` (K, 3) and ``jacobians[slot[t]]`` (K, 3, nv) for frames t in
    ``frames``; computed once, shared by every row kind.

    With global unknowns: ``g`` (n_g,) their current values. With ``proportions`` (a
    :class:`pinrecon.proportions.Proportions`) the figure's log-scale factors are
    ``g[proportion_cols]`` (default ``0 .. n-1``): ``points`` and ``jacobians`` are those of
    the figure scaled by them, and ``dpoints_dglobals[slot[t]]`` (K, 3, n) holds
    d p_world / d g[proportion_cols] (``None`` without proportions or Jacobians), kept
    as its factors (``factor_derivatives``) and formed on demand.
    """

    def __init__(self, figure, Q: np.ndarray, frames: np.ndarray, jacobian: bool, g=None, proportions=None,
                 proportion_cols=None):
        self.figure = figure
        self.Q = Q
        self.frames = frames
        self.g = None if g is None else np.asarray(g, float)
        self.proportions = proportions
        self.factor_derivatives = None
        self.proportion_cols = np.zeros(0, dtype=int)
        self.slot = np.full(Q.shape[0], -1, dtype=int)
        self.slot[frames] = np.arange(len(frames))
        # the keypoints' Jacobians are formed from the WORLD joint Jacobian (T_k, 6, nv)
        # only when a row asks for them (``jacobians``); ``point_jacobians`` projects first
        self.world_jacobians = None
        self._jacobians = None
        if proportions is not None:
            if self.g is None:
                raise ValueError("State: proportions need the global vector g")
            cols = np.arange(proportions.n) if proportion_cols is None else np.asarray(proportion_cols, dtype=int)
            self.proportion_cols = cols
            log_factors = self.g[cols]
            if jacobian:
                self.points, self.world_jacobians, self.factor_derivatives = proportions.world_kinematics(
                    log_factors, Q[frames], full=False)
            else:
                self.points = proportions.keypoints(log_factors, Q[frames])
        elif len(frames):
            self.points, self.world_jacobians = figure.world_kinematics(Q[frames], jacobian)
        else:
            self.points = np.zeros((0, figure.K, 3))
            self.world_jacobians = np.zeros((0, 6, figure.nv)) if jacobian else None

    @property
    def dpoints_dglobals(self) -> np.ndarray | None:
        """(T_k, K, 3, n) d p_world / d g[proportion_cols] (``None`` without proportions or
        Jacobians); rows should prefer :meth:`global_point_jacobians`, which projects first."""
        return None if self.factor_derivatives is None else self.factor_derivatives.full()

    @property
    def jacobians(self) -> np.ndarray | None:
        """(T_k, K, 3, nv) keypoint Jacobians d p_world / d v (``None`` without Jacobians)."""
        if self._jacobians is None and self.world_jacobians is not None:
            self._jacobians = keypoint_jacobians_from_world(
                self.points, self.world_jacobians, self.figure.keypoint_support)
        return self._jacobians

    def point_jacobians(self, slots, keypoints, A=None, weights=None, cols=None) -> np.ndarray:
        """(N, M, r, c): ``weights[n, m] A[n, m] d p_k / d v[cols]`` for keypoints
        ``keypoints`` (M,) at the state's frames ``slots`` (N,) (indices into ``points``),
        with ``A`` an (r, 3) matrix, per-point (N, M, r, 3) matrices, or the identity
        (``None``); ``cols`` tangent entries (default all nv).

        The same numbers as ``A @ jacobians[slots][:, keypoints][..., cols]``, computed as
        one small product per frame with the WORLD joint Jacobian
        (:func:`pinrecon.kinematics.point_jacobian_factors`), without the (T_k, K, 3, nv)
        intermediate."""
        P = rows_of(self.points, slots)[:, keypoints]
        G = point_jacobian_factors(P, A)  # (N, M, r, 6)
        if weights is not None:
            G = G * np.asarray(weights, float)[..., None, None]
        N, M, r = G.shape[:3]
        Jw = rows_of(self.world_jacobians, slots)
        support = self.figure.keypoint_support[keypoints]
        if cols is not None:
            Jw, support = Jw[:, :, cols], support[:, cols]
        J = np.matmul(G.reshape(N, M * r, 6), Jw).reshape(N, M, r, Jw.shape[-1])
        J *= support[None, :, None, :]
        return J

    def global_point_jacobians(self, slots, keypoints, A=None, out=None) -> np.ndarray:
        """(N, M, r, n): ``A d p_k / d g[proportion_cols]`` for keypoints ``keypoints`` at
        the state's frames ``slots``, with ``A`` an (r, 3) matrix, per-point (N, M, r, 3)
        matrices or the identity (``None``); written into ``out`` when given. A constant
        ``A`` is applied before the derivatives are formed
        (:meth:`pinrecon.proportions.FactorDerivatives.projected`)."""
        return self.factor_derivatives.projected(slots, keypoints, np.eye(3) if A is None else A, out=out)

    @property
    def has_global_points(self) -> bool:
        """Whether the keypoints depend on global unknowns (proportions) here."""
        return self.factor_derivatives is not None and len(self.proportion_cols) > 0


_COLUMNS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def supported_columns(figure, keypoints) -> np.ndarray:
    """The tangent entries that move some of ``keypoints`` (:meth:`Figure.support_mask
    <pinrecon.figure.Figure.support_mask>`, the same test as the problem's observable
    mask): the only columns of their Jacobians that are not zero (a rotation whose axis
    passes through every point it carries moves none of them). Cached per figure."""
    key = np.asarray(keypoints, dtype=int).tobytes()
    per_figure = _COLUMNS.setdefault(figure, {})
    if key not in per_figure:
        names = [figure.keypoint_names[k] for k in np.asarray(keypoints, dtype=int)]
        per_figure[key] = np.flatnonzero(figure.support_mask(names))
    return per_figure[key]


