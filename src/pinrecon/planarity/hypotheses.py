"""Closed-form hypotheses for the robust group fit (the RANSAC stage).

Every hypothesis is a centred image conic ``Q = I + g g^T`` (scaled so that
``lambda_min(Q) = 1``, stored as ``(p, q, r)``) plus the rod lengths ``L_k``
(``u^T Q u = L_k^2`` for each rod ``k``), on hinge-relative vectors normalised
by a power-of-two scale.  Candidates come from an algebraic least-squares fit
over all frames (:func:`linear_fit`) and from the propositions on random minimal
frame subsets (:func:`minimal_hypotheses`: Proposition 1 on frame triples for a
rod, Proposition 2 on frame pairs for a hinge); :func:`sampson` scores them by
the first-order distance of every observation to the hypothesis ellipses, and
:func:`params_from_hypothesis` turns the winner into the start ``(phi, tau,
L...)`` of the variable-projection refinement in :mod:`.fit_core`.
"""

from __future__ import annotations

import numpy as np

from .conics import conic_eig, hinge_conic, quad, rod_conic

__all__ = ["linear_fit", "minimal_hypotheses", "params_from_hypothesis", "sampson"]


def linear_fit(un: np.ndarray):
    """Algebraic fit ``u^T Q u = c_k`` over all frames (homogeneous LS).

    ``un``: (n, R, 2) normalised rod vectors.  Returns ``(Q (p,q,r) with
    lambda_min = 1, lengths (R,))`` or ``None`` if not PD / not positive.
    """
    n, R, _ = un.shape
    x, y = un[..., 0], un[..., 1]
    A = np.zeros((n, R, 3 + R))
    A[..., 0], A[..., 1], A[..., 2] = x * x, 2 * x * y, y * y
    A[:, np.arange(R), 3 + np.arange(R)] = -1.0
    A = A.reshape(n * R, 3 + R)
    if A.shape[0] < 3 + R - 1:
        return None
    if A.shape[0] >= A.shape[1]:
        _, _, vt = np.linalg.svd(A, full_matrices=False)
    else:
        _, _, vt = np.linalg.svd(A, full_matrices=True)
    w = vt[-1]
    if w[0] + w[2] < 0:
        w = -w
    return _normalise_hypothesis(w[:3], w[3:])


def _normalise_hypothesis(q: np.ndarray, c: np.ndarray):
    lam_min, _, _, _ = conic_eig(q)
    if not (lam_min > 0 and np.all(c > 0)):
        return None
    return q / lam_min, np.sqrt(c / lam_min)


def minimal_hypotheses(un: np.ndarray, n_hyp: int, rng: np.random.Generator):
    """RANSAC hypotheses from the propositions on random frame subsets.

    Rod (R = 1): Proposition 1 on frame triples.  Hinge (R = 2): Proposition 2
    on frame pairs.  Returns arrays ``Q (K, 3)`` (lambda_min = 1) and ``L (K, R)``.
    """
    n, R, _ = un.shape
    k_need = 3 if R == 1 else 2
    if n < k_need or n_hyp <= 0:
        return np.zeros((0, 3)), np.zeros((0, R))
    idx = np.argpartition(rng.random((n_hyp, n)), k_need - 1, axis=1)[:, :k_need]  # distinct frames
    if R == 1:
        m = rod_conic(un[idx, 0])  # (K, 3)
        lam_min, _, _, _ = conic_eig(m)
        ok = np.isfinite(lam_min) & (lam_min > 0)
        Q = m[ok] / lam_min[ok, None]
        L = 1.0 / np.sqrt(lam_min[ok])[:, None]
    else:
        a, b = un[idx, 0], un[idx, 1]  # (K, 2, 2)
        Q = hinge_conic(a, b)
        lam_min, _, _, _ = conic_eig(Q)
        ok = np.all(np.isfinite(Q), axis=1) & (np.abs(lam_min - 1.0) < 1e-6)
        Q, a, b = Q[ok], a[ok], b[ok]
        L = np.sqrt(np.stack([quad(Q[:, None], a).mean(1), quad(Q[:, None], b).mean(1)], axis=1))
    return Q, L


def sampson(un: np.ndarray, Q: np.ndarray, L: np.ndarray) -> np.ndarray:
    """First-order distance of each point to the hypothesis ellipses.

    ``un`` (n, R, 2); ``Q`` (K, 3); ``L`` (K, R).  Returns (K, n, R):
    ``(u^T Q u - L^2) / (2 |Q u|)``.
    """
    Qb = Q[:, None, None, :]
    val = quad(Qb, un[None]) - L[:, None, :] ** 2
    gx = Qb[..., 0] * un[None, ..., 0] + Qb[..., 1] * un[None, ..., 1]
    gy = Qb[..., 1] * un[None, ..., 0] + Qb[..., 2] * un[None, ..., 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        return val / (2 * np.hypot(gx, gy))


def params_from_hypothesis(Q: np.ndarray, L: np.ndarray) -> np.ndarray:
    """(phi, tau, L...) from ``Q = I + g g^T`` (lambda_min = 1) and lengths."""
    _, lam_max, _, e_max = conic_eig(Q)
    gnorm = np.sqrt(max(lam_max - 1.0, 0.0))
    g = gnorm * e_max
    tau = np.arctan(gnorm)
    phi = np.arctan2(-g[1], -g[0]) if gnorm > 0 else 0.0
    return np.concatenate([[phi, tau], L])
