"""Centred image conics and the small exact-arithmetic helpers the planarity fits share.

A centred conic ``u^T M u`` with ``M = [[p, q], [q, r]]`` is stored as the
vector ``m = (p, q, r)`` (last axis; every function broadcasts over leading
axes).  The image of a rod turning in a plane through the pivot is the ellipse
``u^T M u = 1`` with ``M = (I + g g^T) / L^2`` (see
:mod:`pinrecon.planarity.propositions` and ``docs/planarity.md``).  This module
holds the closed forms used both by the propositions and by the robust group
fits: evaluating a conic, its stable eigen-analysis, the linear rows of the
chord conditions, the batched minimal conics of a rod (three views) and of a
hinge (two views), plus the power-of-two data scale and read-only arrays that
keep results exact and immutable.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "conic_eig",
    "hinge_conic",
    "pow2_scale",
    "quad",
    "readonly",
    "rod_conic",
    "sym_row",
]


def sym_row(d: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Row of the linear condition ``d^T M s = 0`` for ``M = [[p, q], [q, r]]``.

    Returns ``(d_x s_x, d_x s_y + d_y s_x, d_y s_y)`` so that the row dotted
    with ``(p, q, r)`` equals ``d^T M s``.
    """
    return np.stack(
        [
            d[..., 0] * s[..., 0],
            d[..., 0] * s[..., 1] + d[..., 1] * s[..., 0],
            d[..., 1] * s[..., 1],
        ],
        axis=-1,
    )


def quad(m: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``u^T M u`` for ``m = (p, q, r)`` (broadcast over leading axes)."""
    return (
        m[..., 0] * u[..., 0] ** 2
        + 2 * m[..., 1] * u[..., 0] * u[..., 1]
        + m[..., 2] * u[..., 1] ** 2
    )


def conic_eig(m: np.ndarray):
    """Stable closed-form eigen-analysis of ``M = [[p, q], [q, r]]``.

    Returns ``(lam_min, lam_max, gap, e_max)`` with ``gap = lam_max - lam_min``
    computed without cancellation (``2 hypot((p - r)/2, q)``) and ``e_max`` the
    unit eigenvector of ``lam_max`` (angle ``atan2(2q, p - r) / 2``).
    """
    p, q, r = m[..., 0], m[..., 1], m[..., 2]
    half = 0.5 * (p + r)
    rad = np.hypot(0.5 * (p - r), q)
    lam_max = half + rad
    # lam_min = det / lam_max avoids cancellation when lam_min << lam_max.
    with np.errstate(invalid="ignore", divide="ignore"):
        lam_min = np.where(
            lam_max > 0, (p * r - q * q) / np.where(lam_max > 0, lam_max, 1.0), half - rad
        )
    ang = 0.5 * np.arctan2(2 * q, p - r)
    e_max = np.stack([np.cos(ang), np.sin(ang)], axis=-1)
    return lam_min, lam_max, 2 * rad, e_max


def pow2_scale(x: float) -> float:
    """Power of two close to ``x`` (> 0): dividing by it is exact in floating point.

    Normalising the data by an arbitrary scale would round every input once,
    which for nearly equal views (small rotations) is amplified by the
    problem's conditioning (~1/eps^2 for views eps rad apart).
    """
    return float(np.ldexp(1.0, int(np.frexp(x)[1])))


def readonly(a) -> np.ndarray:
    """A float copy of ``a`` that cannot be written to (results are immutable)."""
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


# --------------------------------------------------------------------------
# batched minimal solvers (Propositions 1 and 2, also the RANSAC hypotheses)
# --------------------------------------------------------------------------
def rod_conic(u: np.ndarray) -> np.ndarray:
    """Conic ``m = (p, q, r)`` with ``u_i^T M u_i = 1`` through three views.

    ``u`` has shape ``(..., 3, 2)``.  Uses the difference form
    ``(u_j - u_1)^T M (u_j + u_1) = 0`` (j = 2, 3), whose rows are exactly
    ``r_j - r_1`` of the direct system ``r_i . m = 1`` but are formed from
    differences of the data, then normalises with the mean of ``u_i^T M u_i``.
    Not normalised-positive: a non-PD result means "no interpretation".
    NaN when the two difference rows are parallel (collinear views).
    """
    d = u[..., 1:, :] - u[..., :1, :]
    s = u[..., 1:, :] + u[..., :1, :]
    rows = sym_row(d, s)  # (..., 2, 3)
    m = np.cross(rows[..., 0, :], rows[..., 1, :])
    c = quad(m[..., None, :], u).mean(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return m / c[..., None]


def hinge_conic(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Shape matrix ``Q ~ I + g g^T`` (up to positive scale) from two views of a hinge.

    ``a``, ``b``: shape ``(..., 2, 2)`` = (views, image axes) of the rods OA, OB.
    Conditions ``(a2 - a1)^T Q (a2 + a1) = 0`` and the same for ``b``.  The
    sign is chosen so that ``trace(Q) > 0``; the result is scaled so that
    ``lambda_min(Q) = 1`` when ``Q`` is PD.
    """
    ra = sym_row(a[..., 1, :] - a[..., 0, :], a[..., 1, :] + a[..., 0, :])
    rb = sym_row(b[..., 1, :] - b[..., 0, :], b[..., 1, :] + b[..., 0, :])
    q = np.cross(ra, rb)
    tr = q[..., 0] + q[..., 2]
    q = np.where((tr < 0)[..., None], -q, q)
    lam_min, _, _, _ = conic_eig(q)
    with np.errstate(invalid="ignore", divide="ignore"):
        return q / np.where(lam_min > 0, lam_min, np.abs(tr) / 2 + (tr == 0))[..., None]
