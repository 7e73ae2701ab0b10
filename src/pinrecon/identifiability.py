"""Which fitted segment lengths the data determine, and which only the priors chose.

A calibrated solve (``calibrate="lengths"``) fits one log factor per segment group. Some
of them the data cannot see: 12 body points do not tell the trunk's length from the
spine's bend that reaches the same shoulders, nor the neck's from the head's when only
the nose is tracked; and one camera without a 3D keyframe sees no length by itself (a
longer limb leaning out of the image projects as a shorter one in it), nor the figure's
overall size (a larger figure further away looks the same). The solve still returns a
value for each: the one the priors (pose prior, joint limits, the factors' own log-normal
prior) prefer. This module says which.

**How.** :func:`pinrecon.solver.globals_information` gives what the *data rows* alone
(2D measurements, 3D markers, keyframes) say about the globals with the motion profiled
out: ``S_d``, the Schur complement of their ``J^T J``. Added to the factors' own prior
(``P``, diagonal) it is the posterior a solve would have without the pose prior, limits
and smoothing; a factor whose posterior standard deviation stays above half of its
prior's (``threshold``: the data less than quadrupled its precision) is *not fixed by
the data*. The figure's overall size (all factors scaled together, direction ``u``) is
judged by the data's information along ``u`` alone (``u^T S_d u`` against the prior's),
so groups the data miss (a neck and head placed by the nose only) do not hide a size
that the rest fixes; each group is judged given the overall size (both covariances
conditioned on ``u^T theta``), so a clip that fixes the proportions but not the size
says exactly that. It is a local (Laplace) statement at the solution: a small change of a flagged
factor is taken up by the poses at no cost in the data. It cannot see one-sided bounds,
and one view's 2D tracks alone give nothing else: a segment can always be longer and
lean out of the image, its child kept on its ray, so every length is only bounded from
below. Where a segment lies in the image plane the local curvature would call its length
fixed (the Balancing trial's standing leg: ratios 0.11-0.14); with one view and no 3D
data every group is therefore reported not fixed, whatever the ratios.

The synthetic subject of ``tests/test_reconstruct.py`` (known factors, 12 COCO points as
1 cm markers): the limbs' and the pelvis's ratios are 0.03-0.11 and their factors come
within 0.01 of the truth; the trunk's, shoulders', neck's and head's are 0.61-0.92, and
the trunk and shoulders came out 10 and 8 % from the truth.
"""

from __future__ import annotations

import numpy as np

from .rows.global_prior import GlobalPrior
from .solver import globals_information

__all__ = ["DATA_ROWS", "UNDETERMINED_RATIO", "is_data_row", "proportions_identifiability"]

#: Row kinds that are data (their names' prefixes): the 2D measurements of every view, 3D
#: markers and keyframes. Everything else (pose prior, limits, smoothing, bones, the feet's
#: rows, priors on globals) is a prior.
DATA_ROWS = ("measurement", "markers", "keyframe", "points3d")

#: A factor is not fixed by the data when its posterior standard deviation from the data
#: and its own prior stays above this fraction of the prior's alone.
UNDETERMINED_RATIO = 0.5


def is_data_row(block) -> bool:
    """Whether a row block is data (:data:`DATA_ROWS`)."""
    return block.name.startswith(DATA_ROWS)


def _prior_precision(problem, n_g: int) -> np.ndarray:
    """The diagonal precision the problem's :class:`GlobalPrior` rows put on each global."""
    prec = np.zeros(n_g)
    for row in problem.rows:
        if isinstance(row, GlobalPrior):
            np.add.at(prec, row.cols, row.inv_sigma**2)
    return prec


def _inverse(H: np.ndarray) -> np.ndarray:
    """``H^-1`` of a symmetric positive semi-definite matrix, a direction with no
    information getting a huge (not infinite) variance."""
    lam, V = np.linalg.eigh(0.5 * (H + H.T))
    lam = np.maximum(lam, 1e-12 * max(float(np.abs(lam).max()), 1e-300))
    return (V / lam) @ V.T


def _conditioned(cov: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``cov`` given ``u^T theta`` (a Gaussian's covariance conditioned on one direction)."""
    cu = cov @ u
    return cov - np.outer(cu, cu) / float(u @ cu)


def proportions_identifiability(problem, Q, g, *, threshold: float = UNDETERMINED_RATIO) -> dict | None:
    """Which of ``problem``'s segment groups the data determine at the solution ``(Q, g)``.

    Returns ``None`` without proportions, else plain data (JSON-ready):

    ``ratios``: per group, its posterior standard deviation from the data and its own
        prior over the prior's alone, given the overall size (1: the data say nothing;
        0.71: only its sum with another group, e.g. neck and head; near 0: well fixed);
    ``size_ratio``: the same for the overall size: all factors scaled together, the
        other directions held (1: a uniformly larger or smaller figure costs nothing in
        the data, as under one camera without a 3D keyframe);
    ``undetermined``: the groups over ``threshold`` (every group with one view and no 3D
        data, see above); ``size_determined``;
    ``threshold``; ``data_rows``: the row kinds read as data; ``views``: the cameras;
    ``one_view``: whether the one-view rule above decided (one camera's 2D rows only).
    """
    props = getattr(problem, "proportions", None)
    if props is None or g is None or not np.size(g):
        return None
    g = np.asarray(g, float).reshape(-1)
    k = props.n
    S = globals_information(problem, Q, g, problem.active, rows=is_data_row)
    prec = _prior_precision(problem, len(g))
    floor = 1e-12 * max(float(prec.max()), 1.0)
    cov = _inverse(S + np.diag(np.maximum(prec, floor)))[:k, :k]
    prior = np.diag(1.0 / np.maximum(prec[:k], floor))
    u = np.ones(k) / np.sqrt(k)
    # the overall size: what the data say of all factors scaled together, the rest held
    size_info = float(u @ S[:k, :k] @ u) / float(u @ np.diag(prec[:k]) @ u)
    size_ratio = float(1.0 / np.sqrt(1.0 + max(size_info, 0.0)))
    if k > 1:
        post_c, prior_c = _conditioned(cov, u), _conditioned(prior, u)
        ratios = np.sqrt(np.clip(np.diag(post_c), 0.0, None) / np.diag(prior_c))
    else:
        ratios = np.array([size_ratio])
    names = list(props.names)
    data = sorted({b.name for b in problem.rows if is_data_row(b)})
    views = len(getattr(problem, "views", None) or [])
    # one view's 2D rows alone bound every length from below only (a longer segment leans
    # out of the image, its child kept on its ray): where a segment lies in the image
    # plane the local curvature sees a length it cannot fix, so it is not asked
    one_view = views <= 1 and set(data) <= {"measurement"}
    undetermined = names if one_view else [n for n, r in zip(names, ratios) if r > threshold]
    return {
        "ratios": {n: round(float(r), 4) for n, r in zip(names, ratios)},
        "size_ratio": round(size_ratio, 4),
        "undetermined": list(undetermined),
        "size_determined": bool(size_ratio <= threshold) and not one_view,
        "threshold": float(threshold),
        "data_rows": data,
        "views": views,
        "one_view": bool(one_view),
    }
