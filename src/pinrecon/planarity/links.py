"""Link discovery: rigid links and hinges among many tracked points.

The paper's "linking" by-product (Hoffman & Flinchbaugh 1982): a pair of points
whose hinge-relative image vector traces a centred ellipse is a candidate rigid
rod in planar motion, two links sharing a point whose ellipses share one plane
are a hinge.  :func:`discover_links` prunes all ``N (N - 1) / 2`` pairs, then the
hinged triples, with cheap batched algebraic conic fits and Sampson residuals,
and fits only the survivors with :func:`~.groups.fit_planar_group` (for ``N == 3``
every point is tried as the hinge).  The result is a
:class:`~.fit_types.LinkGraph`.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from .conics import conic_eig, quad
from .fit_types import GroupFit, HingedTriple, Link, LinkGraph
from .groups import DEFAULT_MODEL_TOL, as_tracks, estimate_noise_sigma, fit_planar_group

__all__ = ["discover_links"]


def _pair_prune(x: np.ndarray, sigma: float, model_tol: float, factor: float, min_frames: int):
    """Cheap batched test of all pairs: linear conic fit + Sampson residual.

    Returns the pairs (i, j), i < j, worth a full fit, and the number of pairs examined.
    """
    _T, N, _ = x.shape
    ii, jj = np.triu_indices(N, 1)
    U = x[:, jj] - x[:, ii]  # (T, P, 2)
    valid = np.all(np.isfinite(U), axis=2)
    n_valid = valid.sum(axis=0)
    U0 = np.where(valid[..., None], U, 0.0)
    r = np.linalg.norm(U0, axis=2)
    med = np.zeros(len(ii))  # pairs never seen together (a joint never detected) stay 0: pruned
    seen = n_valid > 0
    med[seen] = np.nanmedian(np.where(valid[:, seen], r[:, seen], np.nan), axis=0)
    ok = (n_valid >= min_frames) & (med > 10 * max(sigma, 1e-300))
    scale = np.where(ok, med, 1.0)
    un = U0 / scale[None, :, None]
    rows = (
        np.stack([un[..., 0] ** 2, 2 * un[..., 0] * un[..., 1], un[..., 1] ** 2], axis=2)
        * valid[..., None]
    )
    A = np.einsum("tpi,tpj->pij", rows, rows)
    b = rows.sum(axis=0)
    A += 1e-12 * np.trace(A, axis1=1, axis2=2)[:, None, None] * np.eye(3)
    A[~ok] = np.eye(3)  # pruned pairs (e.g. no frame in common: A = 0) must not stop the solve
    m = np.linalg.solve(A, b[..., None])[..., 0]  # (P, 3)
    lam_min, _, _, _ = conic_eig(m)
    ok &= lam_min > 0
    val = quad(m[None], un) - 1.0
    gx = m[None, :, 0] * un[..., 0] + m[None, :, 1] * un[..., 1]
    gy = m[None, :, 1] * un[..., 0] + m[None, :, 2] * un[..., 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.where(valid, val / (2 * np.hypot(gx, gy)), 0.0) * scale[None]
        rms = np.sqrt(np.sum(d * d, axis=0) / np.maximum(n_valid, 1))
    thr = np.hypot(np.sqrt(2.0) * sigma * 1.5, model_tol * med)
    ok &= rms <= factor * thr
    return [(int(i), int(j)) for i, j, k in zip(ii, jj, ok) if k], len(ii)


def _triple_prune(
    x: np.ndarray,
    triples: list[tuple[int, int, int]],
    sigma: float,
    model_tol: float,
    factor: float,
    min_frames: int,
) -> list[tuple[int, int, int]]:
    """Cheap batched test of hinged triples (i, hinge j, k): shared-conic algebraic fit.

    Fits ``u^T Q u = c_a`` (rod j->i) and ``= c_b`` (rod j->k) over all frames
    (homogeneous least squares, smallest eigenvector of the 5x5 normal matrix)
    and keeps the triples whose Sampson residual is below ``factor`` times the
    threshold, best (lowest residual / threshold) first.
    """
    if not triples:
        return []
    tri = np.array(triples)
    U = np.stack(
        [x[:, tri[:, 0]] - x[:, tri[:, 1]], x[:, tri[:, 2]] - x[:, tri[:, 1]]], axis=2
    )  # (T, K, 2, 2)
    valid = np.all(np.isfinite(U), axis=(2, 3))
    n_valid = valid.sum(axis=0)
    U0 = np.where(valid[..., None, None], U, 0.0)
    r = np.linalg.norm(U0, axis=3)
    with np.errstate(invalid="ignore"):
        med = np.nanmedian(np.where(valid[..., None], r, np.nan), axis=(0, 2))
    scale = np.where(np.isfinite(med) & (med > 0), med, 1.0)
    un = U0 / scale[None, :, None, None]
    T, K = un.shape[:2]
    rows = np.zeros((T, K, 2, 5))
    rows[..., 0] = un[..., 0] ** 2
    rows[..., 1] = 2 * un[..., 0] * un[..., 1]
    rows[..., 2] = un[..., 1] ** 2
    rows[..., 0, 3] = -1.0
    rows[..., 1, 4] = -1.0
    rows *= valid[..., None, None]
    A = np.einsum("tkri,tkrj->kij", rows, rows)
    _, vec = np.linalg.eigh(A)
    w = vec[..., 0]  # (K, 5)
    w = np.where((w[:, 0] + w[:, 2] < 0)[:, None], -w, w)
    q = w[:, :3]
    lam_min, _, _, _ = conic_eig(q)
    ok = (n_valid >= min_frames) & (lam_min > 0) & (w[:, 3] > 0) & (w[:, 4] > 0)
    val = quad(q[None, :, None, :], un) - w[None, :, 3:5]
    gx = q[None, :, None, 0] * un[..., 0] + q[None, :, None, 1] * un[..., 1]
    gy = q[None, :, None, 1] * un[..., 0] + q[None, :, None, 2] * un[..., 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.where(valid[..., None], val / (2 * np.hypot(gx, gy)), 0.0) * scale[None, :, None]
        rms = np.sqrt(np.sum(d * d, axis=(0, 2)) / np.maximum(2 * n_valid, 1))
    thr = np.hypot(np.sqrt(2.0) * sigma * 1.5, model_tol * med)
    ok &= rms <= factor * thr
    order = np.argsort(np.where(ok, rms / thr, np.inf), kind="stable")
    return [triples[k] for k in order if ok[k]]


def discover_links(
    tracks,
    names: Sequence[str] | None = None,
    sigma: float | None = None,
    *,
    model_tol: float = DEFAULT_MODEL_TOL,
    prune_factor: float = 2.0,
    min_frames: int = 4,
    n_hypotheses: int = 32,
    max_triples: int = 300,
    seed: int | None = 0,
) -> LinkGraph:
    """Find rigid links and hinges among tracked points (the paper's linking by-product).

    Parameters
    ----------
    tracks : array_like, shape (T, N, 2)
        Image positions, NaN for missing.
    names : sequence of str, optional
        ``N`` point names used in the results' text.
    sigma : float or None
        Per-coordinate image noise; None estimates it from all tracks
        (:func:`estimate_noise_sigma`), each group then caps it at 2 % of its
        median projected rod length.
    model_tol : float
        Model tolerance passed to :func:`fit_planar_group`.
    prune_factor : float
        A pair is fully fitted only if its cheap batched algebraic conic fit
        has a Sampson residual below ``prune_factor`` times the threshold.
    min_frames : int
        Pairs with fewer frames in common are not considered.
    n_hypotheses : int
        RANSAC hypotheses per group fit.
    max_triples : int
        Upper bound on the number of hinged-triple fits; candidates are fitted
        in order of their cheap algebraic score.  Walking figures are only
        weakly constrained (short arcs), so on real data many pairs and
        triples are consistent and this cap bounds the run time.
    seed : int or None
        Random seed.

    Returns
    -------
    LinkGraph
        For ``N == 3`` every point is tried as the hinge (the paper's ankle /
        knee / hip example) and ``hinge`` is the accepted one with the lowest
        ``rms / threshold``; ``candidates`` holds the three fits.  For all
        ``N``: ``links`` (pairs that pass as rigid rods in planar motion with a
        determined plane) and ``triples`` (pairs of links sharing a point that
        pass as one hinged planar structure).
    """
    x = as_tracks(tracks)
    _T, N, _ = x.shape
    if N < 2:
        raise ValueError(
            f"tracks must have at least 2 points (shape (T, N>=2, 2)); got shape {x.shape}"
        )
    if names is not None:
        names = tuple(str(n) for n in names)
        if len(names) != N:
            raise ValueError(f"names must have one entry per point: expected {N}, got {len(names)}")
    if sigma is None:
        est = estimate_noise_sigma(x)
        sig_prune = est if np.isfinite(est) else 0.0
        sig_fit = None  # each group estimates (and caps) its own noise level
    else:
        sig_prune = sig_fit = float(sigma)
    lab = (lambda idx: tuple(names[i] for i in idx)) if names else (lambda idx: None)
    fit_kw = {
        "model_tol": model_tol,
        "find_spans": False,
        "n_hypotheses": n_hypotheses,
        "seed": seed,
    }

    pairs, n_pairs = _pair_prune(x, sig_prune, model_tol, prune_factor, min_frames)
    links = []
    adj: dict[int, set[int]] = {i: set() for i in range(N)}
    for i, j in pairs:
        f = fit_planar_group(x[:, [i, j]], hinge=0, sigma=sig_fit, **fit_kw)
        if (
            f.planar
            and f.degeneracy in (None, "plane_parallel_to_image")
            and f.n_frames >= min_frames
        ):
            links.append(Link(points=(i, j), names=lab((i, j)), fit=f))
            adj[i].add(j)
            adj[j].add(i)

    candidates: tuple[GroupFit, ...] = ()
    hinge = None
    triples = []
    if N == 3:
        candidates = tuple(fit_planar_group(x, hinge=h, sigma=sig_fit, **fit_kw) for h in range(3))
        ok = [
            h
            for h, f in enumerate(candidates)
            if f.planar
            and f.degeneracy in (None, "plane_parallel_to_image")
            and f.n_frames >= min_frames
        ]
        if ok:
            hinge = min(ok, key=lambda h: candidates[h].score)
            i, k = candidates[hinge].points
            triples.append(
                HingedTriple(
                    points=(i, hinge, k),
                    hinge=hinge,
                    names=lab((i, hinge, k)),
                    fit=candidates[hinge],
                    rigid_triangle=(k in adj[i]),
                )
            )
    else:
        # a triple whose ends are also rigidly linked is a rigid triangle: no hinge to find
        cand = [
            (i, j, k)
            for j in range(N)
            for i, k in itertools.combinations(sorted(adj[j]), 2)
            if k not in adj[i]
        ]
        cand = _triple_prune(x, cand, sig_prune, model_tol, prune_factor, min_frames)[:max_triples]
        for i, j, k in cand:
            f = fit_planar_group(x[:, [i, j, k]], hinge=1, sigma=sig_fit, **fit_kw)
            if (
                f.planar
                and f.degeneracy in (None, "plane_parallel_to_image")
                and f.n_frames >= min_frames
            ):
                triples.append(HingedTriple(points=(i, j, k), hinge=j, names=lab((i, j, k)), fit=f))
    sig_report = sig_prune if sigma is None else float(sigma)
    return LinkGraph(
        n_points=N,
        names=names,
        links=tuple(links),
        triples=tuple(triples),
        hinge=hinge,
        candidates=candidates,
        sigma=sig_report,
        n_pairs=n_pairs,
        n_pairs_fitted=len(pairs),
    )
