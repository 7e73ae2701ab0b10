"""Robust planarity test of point groups over a sequence, and link discovery.

A *group* is a hinge (or pivot) point plus one or two other points tracked in
``T`` frames.  Hypothesis: every other point is joined to the hinge by a rigid
rod and all rods turn in one plane through the hinge, fixed relative to the
hinge for the whole sequence (Hoffman & Flinchbaugh's "pairwise-rigid
structure in planar motion").  Frames, units and sign conventions are those of
:mod:`pinrecon.planarity.propositions`: orthographic camera, x right, y down,
z forward; vectors relative to the hinge (translation drops out); depths
``z = g . uv``; one global member of the reflection pair.

Model
-----
Plane normal ``n = (cos(phi) sin(tau), sin(phi) sin(tau), cos(tau))`` (``tau``
is the tilt from the image plane), rod ``k`` of length ``L_k`` at in-plane
angle ``theta_{t,k}`` in frame ``t``.  In image axes rotated by ``-phi`` its
image is ``L_k (cos(tau) cos(theta), sin(theta))`` and its depth is
``-L_k sin(tau) cos(theta)``.  The fit minimises the squared image distances
between these model points and the observed hinge-relative vectors over
``(phi, tau, L_k)`` and all ``theta_{t,k}``; the angles are eliminated exactly
(variable projection: each one is the nearest point of the rod's image
ellipse), so the outer problem has ``2 + R`` parameters.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import chi2

from .propositions import (
    DEFAULT_RTOL,
    _conic_eig,
    _hinge_conic,
    _pow2_scale,
    _quad,
    _readonly,
    _rod_conic,
)

__all__ = [
    "DEFAULT_MODEL_TOL",
    "GroupFit",
    "HingedTriple",
    "Link",
    "LinkGraph",
    "discover_links",
    "estimate_noise_sigma",
    "fit_planar_group",
]

#: Default model tolerance: RMS deviation from an exact rigid planar model that
#: is still accepted, as a fraction of the RMS rod length.  Real limbs are only
#: approximately planar (hip ab/adduction, axial rotation, marker motion): on
#: the CMU 02_01 walk the correct knee hinge leaves 1.2 % (side view) to 3.0 %
#: (60 deg from side-on) of the length, the wrong hinges (hip-ankle "rod")
#: 3.3-6 %.  Set 0 to test against image noise only (exact synthetic data).
DEFAULT_MODEL_TOL = 0.035

#: ``sigma=None`` estimates are capped at this fraction of the median projected
#: rod length (temporal differences overestimate the noise of fast or sparsely
#: sampled motion; without a cap any group would pass).
SIGMA_CAP_FRACTION = 0.02

_CHI2_QUANTILE = 0.999


# --------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class GroupFit:
    """Result of :func:`fit_planar_group`.

    Attributes
    ----------
    hinge : int
        Index (into the group's points) of the hinge / pivot.
    points : tuple of int
        Indices of the other points, in order; they index the columns of
        ``depths`` and the entries of ``lengths``.
    depths : ndarray, shape (T, R)
        Depth (camera z, forward) of each other point relative to the hinge,
        from the fitted model, one global member of the reflection pair; NaN in
        skipped frames (any needed point missing).
    lengths : ndarray, shape (R,)
        3D rod lengths (input units).
    normal : ndarray, shape (3,)
        Unit plane normal in camera axes, ``n_z >= 0``.
    gradient : ndarray, shape (2,)
        Depth gradient ``g`` (``z = g . uv`` relative to the hinge).
    rms : float
        RMS 2D residual of the hinge-relative image vectors (input units).
    threshold : float
        Largest ``rms`` accepted as planar (noise + model tolerance).
    sigma : float
        Per-coordinate image noise used (given or estimated), input units.
    planar : bool
        Verdict: the group is a pairwise-rigid structure in planar motion over
        all used frames, with a determined plane.
    reason : str
        Short explanation of the verdict.
    degeneracy : str or None
        ``None``, ``"no_planar_interpretation"``, ``"insufficient_motion"``
        (plane/lengths not determined by the data), ``"plane_parallel_to_image"``,
        or ``"too_few_frames"``.
    spans : tuple of (int, int)
        Frame ranges ``[start, stop)`` where planarity holds (the whole used
        range when ``planar``; sliding-window spans otherwise).
    span_fits : tuple of GroupFit
        Separate fits of the spans when the whole sequence is not planar.
    frame_rms : ndarray, shape (T,)
        Per-frame RMS residual (NaN in skipped frames).
    used : ndarray of bool, shape (T,)
        Frames used by the fit.
    length_std : ndarray, shape (R,)
        Standard errors of ``lengths`` (a-posteriori residual variance).
    normal_std_deg : float
        Standard error of the normal direction, degrees.
    """

    hinge: int
    points: tuple[int, ...]
    depths: np.ndarray
    lengths: np.ndarray
    normal: np.ndarray
    gradient: np.ndarray
    rms: float
    threshold: float
    sigma: float
    planar: bool
    reason: str
    degeneracy: str | None
    spans: tuple[tuple[int, int], ...]
    frame_rms: np.ndarray
    used: np.ndarray
    length_std: np.ndarray
    normal_std_deg: float
    span_fits: tuple[GroupFit, ...] = field(default=())

    @property
    def n_frames(self) -> int:
        """Number of frames used."""
        return int(np.count_nonzero(self.used))

    @property
    def tilt_deg(self) -> float:
        """Angle between the motion plane and the image plane, degrees."""
        return float(np.degrees(np.arccos(np.clip(self.normal[2], -1.0, 1.0))))

    @property
    def score(self) -> float:
        """``rms / threshold`` (<= 1 means the residual test passes)."""
        return float(self.rms / self.threshold) if self.threshold > 0 else float("inf")

    def reflected(self) -> GroupFit:
        """The other member of the reflection pair (all depths negated)."""
        return replace(
            self,
            depths=_readonly(-self.depths),
            normal=_readonly(self.normal * np.array([-1.0, -1.0, 1.0])),
            gradient=_readonly(-self.gradient),
            span_fits=tuple(f.reflected() for f in self.span_fits),
        )

    def pair(self) -> tuple[GroupFit, GroupFit]:
        """Both members of the reflection pair."""
        return self, self.reflected()

    def summary(self, names: list[str] | tuple[str, ...] | None = None) -> str:
        """Multi-line human-readable description (``names`` label the group's points)."""
        lab = (lambda i: names[i]) if names is not None else (lambda i: f"p{i}")
        head = "PLANAR" if self.planar else "not planar"
        lines = [f"group hinge={lab(self.hinge)}: {head} ({self.reason})"]
        for k, p in enumerate(self.points):
            lines.append(
                f"  |{lab(self.hinge)}-{lab(p)}| = {self.lengths[k]:.6g} +- {self.length_std[k]:.2g}"
            )
        if np.all(np.isfinite(self.normal)):
            n = self.normal
            lines.append(
                f"  normal (camera x right, y down, z fwd): ({n[0]:+.4f}, {n[1]:+.4f}, {n[2]:+.4f})"
                f"  tilt {self.tilt_deg:.2f} deg +- {self.normal_std_deg:.2g}"
            )
        lines.append(
            f"  residual RMS {self.rms:.4g} (threshold {self.threshold:.4g}, sigma {self.sigma:.3g}), "
            f"{self.n_frames} frames"
        )
        if self.degeneracy:
            lines.append(f"  degeneracy: {self.degeneracy}")
        if self.spans:
            lines.append("  spans: " + ", ".join(f"[{a}, {b})" for a, b in self.spans))
        return "\n".join(lines)

    def __repr__(self) -> str:
        lens = ", ".join(f"{x:.5g}" for x in self.lengths)
        nrm = (
            ("(" + ", ".join(f"{x:+.3f}" for x in self.normal) + ")")
            if np.all(np.isfinite(self.normal))
            else "undetermined"
        )
        return (
            f"GroupFit(hinge={self.hinge}, points={self.points}, planar={self.planar}, lengths=[{lens}], "
            f"normal={nrm}, rms={self.rms:.4g}, threshold={self.threshold:.4g}, "
            f"degeneracy={self.degeneracy!r}, frames={self.n_frames}, spans={list(self.spans)})"
        )

    __str__ = summary


@dataclass(frozen=True, eq=False)
class Link:
    """A rigid rod in planar motion between two points."""

    points: tuple[int, int]
    names: tuple[str, str] | None
    fit: GroupFit

    @property
    def length(self) -> float:
        return float(self.fit.lengths[0])

    @property
    def normal(self) -> np.ndarray:
        return self.fit.normal

    @property
    def rms(self) -> float:
        return self.fit.rms

    def __repr__(self) -> str:
        who = (
            f"{self.names[0]}--{self.names[1]}"
            if self.names
            else f"{self.points[0]}--{self.points[1]}"
        )
        return f"Link({who}, length={self.length:.5g}, rms={self.rms:.3g}, tilt={self.fit.tilt_deg:.1f} deg)"


@dataclass(frozen=True, eq=False)
class HingedTriple:
    """Two rods hinged at ``hinge`` moving in one plane; ``points`` = (end, hinge, end)."""

    points: tuple[int, int, int]
    hinge: int
    names: tuple[str, str, str] | None
    fit: GroupFit
    rigid_triangle: bool = False

    @property
    def lengths(self) -> np.ndarray:
        return self.fit.lengths

    @property
    def normal(self) -> np.ndarray:
        return self.fit.normal

    @property
    def rms(self) -> float:
        return self.fit.rms

    def __repr__(self) -> str:
        lab = self.names or tuple(str(p) for p in self.points)
        tri = ", rigid triangle" if self.rigid_triangle else ""
        return (
            f"HingedTriple({lab[0]}-[{lab[1]}]-{lab[2]}, lengths=({self.lengths[0]:.5g}, "
            f"{self.lengths[1]:.5g}), rms={self.rms:.3g}, tilt={self.fit.tilt_deg:.1f} deg{tri})"
        )


@dataclass(frozen=True, eq=False)
class LinkGraph:
    """Result of :func:`discover_links`.

    Attributes
    ----------
    n_points : int
    names : tuple of str or None
    links : tuple of Link
        Pairs consistent with a rigid rod in planar motion (determined plane).
    triples : tuple of HingedTriple
        Hinged triples (both rods rigid, one common plane).
    hinge : int or None
        For ``n_points == 3``: the point accepted as the hinge (None if no
        hypothesis passed).  For larger sets: None (see ``triples``).
    candidates : tuple of GroupFit
        For ``n_points == 3``: the fits with point 0, 1, 2 as the hinge.
    sigma : float
        Noise level used (input units).
    n_pairs : int
        Pairs examined; ``n_pairs_fitted`` of them survived the cheap prune.
    n_pairs_fitted : int
    """

    n_points: int
    names: tuple[str, ...] | None
    links: tuple[Link, ...]
    triples: tuple[HingedTriple, ...]
    hinge: int | None
    candidates: tuple[GroupFit, ...]
    sigma: float
    n_pairs: int
    n_pairs_fitted: int

    def _chosen(self) -> GroupFit | None:
        return self.candidates[self.hinge] if (self.hinge is not None and self.candidates) else None

    @property
    def depths(self) -> np.ndarray | None:
        """For a triple with an accepted hinge: depths (T, 2) of the other points."""
        f = self._chosen()
        return None if f is None else f.depths

    @property
    def lengths(self) -> np.ndarray | None:
        """For a triple with an accepted hinge: the two rod lengths."""
        f = self._chosen()
        return None if f is None else f.lengths

    @property
    def normal(self) -> np.ndarray | None:
        """For a triple with an accepted hinge: the plane normal."""
        f = self._chosen()
        return None if f is None else f.normal

    @property
    def degeneracy(self) -> str | None:
        """For a triple: None if a hinge was found, else ``"no_hinge_found"``."""
        if self.n_points != 3:
            return None
        return None if self.hinge is not None else "no_hinge_found"

    def _lab(self, i: int) -> str:
        return self.names[i] if self.names else f"p{i}"

    def summary(self) -> str:
        """Multi-line human-readable description."""
        lines = [
            (
                f"LinkGraph: {self.n_points} points, {len(self.links)} links, {len(self.triples)} hinged triples "
                f"(sigma {self.sigma:.3g}; {self.n_pairs_fitted}/{self.n_pairs} pairs fitted after pruning)"
            )
        ]
        if self.candidates:
            for h, f in enumerate(self.candidates):
                mark = "  <- hinge" if h == self.hinge else ""
                lines.append(
                    f"  hinge {self._lab(h)}: {'planar' if f.planar else 'rejected'}, rms {f.rms:.4g} "
                    f"/ threshold {f.threshold:.4g}{mark}"
                )
        for ln in self.links:
            i, j = ln.points
            lines.append(
                f"  link {self._lab(i)} -- {self._lab(j)}: length {ln.length:.5g}, rms {ln.rms:.3g}, "
                f"tilt {ln.fit.tilt_deg:.1f} deg"
            )
        for tr in self.triples:
            i, h, k = tr.points
            lines.append(
                f"  hinge {self._lab(h)} joins {self._lab(i)} ({tr.lengths[0]:.5g}) and {self._lab(k)} "
                f"({tr.lengths[1]:.5g}), rms {tr.rms:.3g}, tilt {tr.fit.tilt_deg:.1f} deg"
                + (" [rigid triangle]" if tr.rigid_triangle else "")
            )
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (
            f"LinkGraph(n_points={self.n_points}, links={[ln.points for ln in self.links]}, "
            f"triples={[t.points for t in self.triples]}, hinge={self.hinge})"
        )

    __str__ = summary


# --------------------------------------------------------------------------
# input handling and noise
# --------------------------------------------------------------------------
def _as_tracks(tracks, name: str = "tracks", n_points: tuple[int, ...] | None = None) -> np.ndarray:
    try:
        x = np.asarray(tracks, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array of shape (T, N, 2); {exc}") from None
    if x.ndim != 3 or x.shape[2] != 2:
        raise ValueError(
            f"{name} must have shape (T, N, 2) (frames x points x (u, v)); got shape {x.shape}"
        )
    if n_points is not None and x.shape[1] not in n_points:
        want = " or ".join(str(n) for n in n_points)
        raise ValueError(
            f"{name} must have shape (T, {want}, 2) for this function; got shape {x.shape}"
        )
    if np.any(np.isinf(x)):
        raise ValueError(f"{name} must not contain inf (use NaN for missing points)")
    return x


def estimate_noise_sigma(tracks) -> float:
    """Per-coordinate image noise from the tracks' high-frequency content.

    For white noise of standard deviation ``sigma`` the second temporal
    difference ``x[t+1] - 2 x[t] + x[t-1]`` has standard deviation
    ``sqrt(6) sigma``; the estimate is ``1.4826 * median(|diff2|) / sqrt(6)``
    pooled over points and axes.  It assumes motion sampled densely in time
    (true acceleration * dt^2 small against the noise) and is an upper bound
    otherwise.  Returns NaN when fewer than 8 second differences exist.

    Parameters
    ----------
    tracks : array_like, shape (T, N, 2)
        Image positions, NaN for missing.
    """
    x = _as_tracks(tracks)
    if x.shape[0] < 3:
        return float("nan")
    d2 = x[2:] - 2 * x[1:-1] + x[:-2]
    d2 = np.abs(d2[np.isfinite(d2)])
    if d2.size < 8:
        return float("nan")
    return float(1.4826 * np.median(d2) / np.sqrt(6.0))


def _resolve_sigma(sigma, tracks_group: np.ndarray, median_len: float) -> float:
    if sigma is not None:
        s = float(sigma)
        if not (np.isfinite(s) and s >= 0):
            raise ValueError(
                f"sigma must be a finite number >= 0 (image units) or None; got {sigma!r}"
            )
        return s
    est = estimate_noise_sigma(tracks_group)
    cap = SIGMA_CAP_FRACTION * median_len
    if not np.isfinite(est):
        return cap
    return float(np.clip(est, 1e-12 * median_len, cap))


# --------------------------------------------------------------------------
# conic hypotheses
# --------------------------------------------------------------------------
def _linear_fit(un: np.ndarray):
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
    lam_min, _, _, _ = _conic_eig(q)
    if not (lam_min > 0 and np.all(c > 0)):
        return None
    return q / lam_min, np.sqrt(c / lam_min)


def _minimal_hypotheses(un: np.ndarray, n_hyp: int, rng: np.random.Generator):
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
        m = _rod_conic(un[idx, 0])  # (K, 3)
        lam_min, _, _, _ = _conic_eig(m)
        ok = np.isfinite(lam_min) & (lam_min > 0)
        Q = m[ok] / lam_min[ok, None]
        L = 1.0 / np.sqrt(lam_min[ok])[:, None]
    else:
        a, b = un[idx, 0], un[idx, 1]  # (K, 2, 2)
        Q = _hinge_conic(a, b)
        lam_min, _, _, _ = _conic_eig(Q)
        ok = np.all(np.isfinite(Q), axis=1) & (np.abs(lam_min - 1.0) < 1e-6)
        Q, a, b = Q[ok], a[ok], b[ok]
        L = np.sqrt(np.stack([_quad(Q[:, None], a).mean(1), _quad(Q[:, None], b).mean(1)], axis=1))
    return Q, L


def _sampson(un: np.ndarray, Q: np.ndarray, L: np.ndarray) -> np.ndarray:
    """First-order distance of each point to the hypothesis ellipses.

    ``un`` (n, R, 2); ``Q`` (K, 3); ``L`` (K, R).  Returns (K, n, R):
    ``(u^T Q u - L^2) / (2 |Q u|)``.
    """
    Qb = Q[:, None, None, :]
    val = _quad(Qb, un[None]) - L[:, None, :] ** 2
    gx = Qb[..., 0] * un[None, ..., 0] + Qb[..., 1] * un[None, ..., 1]
    gy = Qb[..., 1] * un[None, ..., 0] + Qb[..., 2] * un[None, ..., 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        return val / (2 * np.hypot(gx, gy))


def _params_from_hypothesis(Q: np.ndarray, L: np.ndarray) -> np.ndarray:
    """(phi, tau, L...) from ``Q = I + g g^T`` (lambda_min = 1) and lengths."""
    _, lam_max, _, e_max = _conic_eig(Q)
    gnorm = np.sqrt(max(lam_max - 1.0, 0.0))
    g = gnorm * e_max
    tau = np.arctan(gnorm)
    phi = np.arctan2(-g[1], -g[0]) if gnorm > 0 else 0.0
    return np.concatenate([[phi, tau], L])


# --------------------------------------------------------------------------
# variable-projection refinement
# --------------------------------------------------------------------------
class _Model:
    """Residuals of the planar rigid model with the in-plane angles eliminated."""

    def __init__(self, un: np.ndarray):
        n, R, _ = un.shape
        self.R = R
        self.obs = un.reshape(n * R, 2)
        self.rod = np.tile(np.arange(R), n)
        self._key = None

    def _solve(self, x: np.ndarray):
        key = x.tobytes()
        if key == self._key:
            return self._cache
        phi, tau = x[0], x[1]
        L = x[2:][self.rod]
        c, s = np.cos(phi), np.sin(phi)
        q = np.stack(
            [c * self.obs[:, 0] + s * self.obs[:, 1], -s * self.obs[:, 0] + c * self.obs[:, 1]],
            axis=1,
        )
        ct, st = np.cos(tau), np.sin(tau)
        theta = np.arctan2(q[:, 1] * abs(ct), q[:, 0] * (1.0 if ct >= 0 else -1.0))
        for _ in range(12):
            cth, sth = np.cos(theta), np.sin(theta)
            px, py = L * ct * cth, L * sth
            tx, ty = -L * ct * sth, L * cth
            ex, ey = px - q[:, 0], py - q[:, 1]
            f1 = ex * tx + ey * ty
            t2 = tx * tx + ty * ty
            f2 = t2 - (ex * px + ey * py)
            den = np.where(f2 > 0.1 * t2, f2, t2)
            with np.errstate(invalid="ignore", divide="ignore"):
                step = np.where(den > 0, -f1 / den, 0.0)
            theta = theta + np.clip(step, -0.5, 0.5)
            if np.max(np.abs(step)) < 1e-14:
                break
        cth, sth = np.cos(theta), np.sin(theta)
        p = np.stack([L * ct * cth, L * sth], axis=1)
        self._key, self._cache = key, (q, theta, p, ct, st)
        return self._cache

    def residuals(self, x: np.ndarray) -> np.ndarray:
        q, _, p, _, _ = self._solve(x)
        return (p - q).ravel()

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        q, theta, _p, ct, st = self._solve(x)
        L = x[2:][self.rod]
        m = self.obs.shape[0]
        J = np.zeros((m, 2, 2 + self.R))
        J[:, 0, 0], J[:, 1, 0] = -q[:, 1], q[:, 0]  # d/dphi of p - Rot(-phi) obs
        J[:, 0, 1] = -L * st * np.cos(theta)  # d/dtau
        J[np.arange(m), 0, 2 + self.rod] = ct * np.cos(theta)
        J[np.arange(m), 1, 2 + self.rod] = np.sin(theta)
        # project out the tangent (the eliminated angle): Kaufman's VarPro Jacobian
        t = np.stack([-L * ct * np.sin(theta), L * np.cos(theta)], axis=1)
        t2 = np.sum(t * t, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            tn = np.where(t2[:, None] > 0, t / np.sqrt(t2)[:, None], 0.0)
        J = J - tn[:, :, None] * np.einsum("mi,mij->mj", tn, J)[:, None, :]
        return J.reshape(2 * m, 2 + self.R)

    def depths_and_points(self, x: np.ndarray):
        """Model image points (original axes) and the depth gradient of the plane."""
        _, _theta, p, ct, st = self._solve(x)
        phi = x[0]
        c, s = np.cos(phi), np.sin(phi)
        uv = np.stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1]], axis=1)
        n = np.array([np.cos(phi) * st, np.sin(phi) * st, ct])
        if n[2] < 0:
            n = -n
        return uv, n


def _refine(un: np.ndarray, x0: np.ndarray, loss: str, f_scale: float):
    model = _Model(un)
    res = least_squares(
        model.residuals,
        x0,
        jac=model.jacobian,
        method="trf",
        loss=loss,
        f_scale=f_scale,
        x_scale="jac",
        max_nfev=200,
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
    )
    return model, res.x


def _parameter_variances(J: np.ndarray, s2: float) -> np.ndarray:
    """Diagonal of ``s2 (J^T J)^-1``; ``inf`` for parameters in a (near) null space.

    ``J`` is the reduced (variable-projection) Jacobian, i.e. the Schur
    complement of the eliminated in-plane angles.  Columns are scaled to unit
    norm first; eigenvalues below ``1e-10`` of the largest count as null
    directions, and every parameter with a component above ``1e-3`` in one of
    them is undetermined.
    """
    JtJ = J.T @ J
    d = np.sqrt(np.diag(JtJ))
    p = JtJ.shape[0]
    var = np.full(p, np.inf)
    ok_col = d > 0
    if not np.any(ok_col):
        return var
    dd = d[ok_col]
    N = JtJ[np.ix_(ok_col, ok_col)] / np.outer(dd, dd)
    w, V = np.linalg.eigh(N)
    null = w <= 1e-10 * w[-1]
    inv = (V[:, ~null] / w[~null]) @ V[:, ~null].T
    v = s2 * np.diag(inv) / dd**2
    if np.any(null):
        v = np.where(np.any(np.abs(V[:, null]) > 1e-3, axis=1), np.inf, v)
    var[ok_col] = v
    return var


# --------------------------------------------------------------------------
# core fit on a set of frames
# --------------------------------------------------------------------------
def _core_fit(
    U: np.ndarray,
    frames: np.ndarray,
    sigma: float,
    model_tol: float,
    n_hyp: int,
    rng: np.random.Generator,
    loss: str,
    max_normal_std_deg: float,
    max_length_rel_std: float,
    rtol: float,
) -> dict:
    """Fit the planar rigid model to ``U[frames]`` (hinge-relative vectors, (T, R, 2))."""
    u = U[frames]
    n, R, _ = u.shape
    n_min = 3 if R == 1 else 2
    out = {"frames": frames, "n": n, "R": R}
    if n < n_min:
        out.update(status="too_few_frames", reason=f"too few frames ({n} < {n_min})")
        return out
    scale = _pow2_scale(float(np.sqrt(np.mean(np.sum(u * u, axis=-1)))) or 1.0)
    un = u / scale
    sig_rel = np.sqrt(2.0) * sigma / scale  # noise of a hinge-relative vector
    med_len = float(np.median(np.linalg.norm(un, axis=-1)))
    cut = 3.0 * np.hypot(sig_rel, model_tol * med_len)

    # hypotheses: linear all-frames fit + minimal solutions on random subsets
    hyps_Q, hyps_L = [], []
    lin = _linear_fit(un)
    if lin is not None:
        hyps_Q.append(lin[0])
        hyps_L.append(lin[1])
    Qm, Lm = _minimal_hypotheses(un, n_hyp, rng)
    if len(Qm):
        hyps_Q.extend(Qm)
        hyps_L.extend(Lm)
    if not hyps_Q:
        out.update(
            status="no_planar_interpretation",
            reason="no real rigid planar interpretation (image conic not an ellipse)",
        )
        return out
    Q, L = np.array(hyps_Q), np.array(hyps_L)
    d = _sampson(un, Q, L)
    cost = np.nansum(np.minimum(np.nan_to_num(d, nan=np.inf) ** 2, cut**2), axis=(1, 2))
    best = int(np.argmin(cost))
    # local optimisation: refit linearly on the inliers of the best hypothesis
    inl = np.all(np.abs(d[best]) <= cut, axis=1)
    if np.count_nonzero(inl) >= n_min + 1 and np.count_nonzero(inl) < n:
        lo = _linear_fit(un[inl])
        if lo is not None:
            dlo = _sampson(un, lo[0][None], lo[1][None])
            clo = np.nansum(np.minimum(np.nan_to_num(dlo, nan=np.inf) ** 2, cut**2))
            if clo < cost[best]:
                Q, L, best = lo[0][None], lo[1][None], 0
    x0 = _params_from_hypothesis(Q[best], L[best])
    model, x = _refine(un, x0, loss, f_scale=max(cut / 3.0, 1e-12))
    r = model.residuals(x).reshape(n, R, 2)
    d2 = np.sum(r * r, axis=-1)  # (n, R)
    ssr = float(np.sum(d2))
    n_pts = n * R
    dof = n_pts - R - 2
    lengths = np.abs(x[2:]) * scale
    uv_fit, normal = model.depths_and_points(x)
    g = -normal[:2] / normal[2] if normal[2] > 0 else np.full(2, np.nan)
    depths = (
        (uv_fit @ g).reshape(n, R) * scale if np.all(np.isfinite(g)) else np.full((n, R), np.nan)
    )
    rms = float(np.sqrt(ssr / n_pts)) * scale
    frame_rms = np.sqrt(np.mean(d2, axis=1)) * scale
    # uncertainty from the reduced (VarPro) Jacobian
    s2 = ssr / dof if dof > 0 else 0.0
    var = _parameter_variances(model.jacobian(x), s2)
    length_std = np.sqrt(var[2:]) * scale
    tau = x[1]
    # the azimuth phi does not matter when the plane is parallel to the image (sin(tau) = 0)
    var_phi_term = np.sin(tau) ** 2 * var[0] if abs(np.sin(tau)) > 1e-8 else 0.0
    normal_std_deg = float(np.degrees(np.sqrt(var[1] + var_phi_term)))
    mean_len = float(np.sqrt(np.mean(x[2:] ** 2))) * scale
    if dof > 0:
        thr = float(
            np.sqrt(
                (np.sqrt(2.0) * sigma) ** 2 * chi2.ppf(_CHI2_QUANTILE, dof) / n_pts
                + (model_tol * mean_len) ** 2
            )
        )
    else:
        thr = float("nan")
    out.update(
        rms=rms,
        threshold=thr,
        lengths=lengths,
        normal=normal,
        gradient=g,
        depths=depths,
        frame_rms=frame_rms,
        length_std=length_std,
        normal_std_deg=normal_std_deg,
        dof=dof,
    )
    tilt_deg = float(np.degrees(np.arccos(np.clip(abs(normal[2]), 0, 1))))
    parallel = tilt_deg <= max(2.0 * normal_std_deg, float(np.degrees(np.sqrt(rtol))))
    if dof <= 0:
        out.update(
            status="minimal",
            reason="exactly determined (no redundant frame): planarity not testable",
        )
    elif not rms <= thr:
        out.update(
            status="rejected",
            reason=f"residual RMS {rms:.3g} > threshold {thr:.3g}: not a rigid planar group",
        )
    elif (normal_std_deg > max_normal_std_deg and not parallel) or np.any(
        length_std > max_length_rel_std * lengths
    ):
        out.update(
            status="insufficient_motion",
            reason=f"motion does not determine the plane (normal +-{normal_std_deg:.2g} deg, "
            f"length rel. std {np.max(length_std / lengths):.2g})",
        )
    else:
        out.update(status="planar", reason=f"residual RMS {rms:.3g} <= threshold {thr:.3g}")
    if out["status"] in ("planar", "minimal") and parallel:
        out["parallel"] = True
    return out


def _frozen_bool(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=bool)
    a.setflags(write=False)
    return a


def _make_fit(
    core: dict, T: int, hinge: int, points: tuple[int, ...], sigma: float, spans=(), span_fits=()
) -> GroupFit:
    R = len(points)
    used = np.zeros(T, dtype=bool)
    used[core["frames"]] = True
    depths = np.full((T, R), np.nan)
    frame_rms = np.full(T, np.nan)
    status = core["status"]
    if "rms" in core:
        depths[core["frames"]] = core["depths"]
        frame_rms[core["frames"]] = core["frame_rms"]
        lengths, normal, gradient = core["lengths"], core["normal"], core["gradient"]
        rms, thr = core["rms"], core["threshold"]
        length_std, nstd = core["length_std"], core["normal_std_deg"]
    else:
        lengths, normal, gradient = np.full(R, np.nan), np.full(3, np.nan), np.full(2, np.nan)
        rms, thr, length_std, nstd = float("nan"), float("nan"), np.full(R, np.nan), float("nan")
    planar = status in ("planar", "minimal")
    degeneracy = None
    if status in ("no_planar_interpretation", "insufficient_motion", "too_few_frames"):
        degeneracy = status
    elif planar and core.get("parallel"):
        degeneracy = "plane_parallel_to_image"
        depths[core["frames"]] = 0.0
        gradient = np.zeros(2)
        normal = np.array([0.0, 0.0, 1.0])
    # canonical member of the reflection pair: normal n_x > 0 (tie: n_y >= 0)
    if np.all(np.isfinite(normal)) and (normal[0] < 0 or (normal[0] == 0 and normal[1] < 0)):
        depths, normal, gradient = -depths, normal * np.array([-1.0, -1.0, 1.0]), -gradient
    if planar and not spans:
        fr = core["frames"]
        spans = ((int(fr[0]), int(fr[-1]) + 1),)
    return GroupFit(
        hinge=hinge,
        points=points,
        depths=_readonly(depths),
        lengths=_readonly(lengths),
        normal=_readonly(normal),
        gradient=_readonly(gradient),
        rms=rms,
        threshold=thr,
        sigma=sigma,
        planar=planar,
        reason=core["reason"],
        degeneracy=degeneracy,
        spans=tuple(spans),
        frame_rms=_readonly(frame_rms),
        used=_frozen_bool(used),
        length_std=_readonly(length_std),
        normal_std_deg=nstd,
        span_fits=tuple(span_fits),
    )


# --------------------------------------------------------------------------
# public: group fit
# --------------------------------------------------------------------------
def fit_planar_group(
    tracks,
    hinge: int = 0,
    sigma: float | None = None,
    *,
    model_tol: float = DEFAULT_MODEL_TOL,
    find_spans: bool = True,
    window: int | None = None,
    n_hypotheses: int = 200,
    loss: str = "linear",
    max_normal_std_deg: float = 5.0,
    max_length_rel_std: float = 0.05,
    rtol: float = DEFAULT_RTOL,
    seed: int | None = 0,
) -> GroupFit:
    """Test a 2- or 3-point group for pairwise-rigid planar motion over a sequence.

    Parameters
    ----------
    tracks : array_like, shape (T, 2 or 3, 2)
        Image positions (u right, v down; any unit), NaN for missing.  A frame
        in which any point of the group is missing is skipped.
    hinge : int
        Index of the hinge (for two points: the pivot; the result does not
        depend on which end is chosen except for the sign of ``depths``).
    sigma : float or None
        Per-coordinate image noise of each point (input units).  None:
        :func:`estimate_noise_sigma` on the tracks, clipped to
        ``SIGMA_CAP_FRACTION`` (2 %) of the median projected rod length.
    model_tol : float
        Accepted RMS model deviation as a fraction of the RMS rod length
        (default :data:`DEFAULT_MODEL_TOL`); 0 tests against noise only.
    find_spans : bool
        When the whole sequence is not planar, search sliding windows for the
        frame ranges where it is (``spans`` / ``span_fits``).
    window : int or None
        Window length for the span search (default ``max(8, T // 10)``).
    n_hypotheses : int
        Number of minimal-sample (RANSAC) hypotheses: Proposition 1 on frame
        triples (rod) or Proposition 2 on frame pairs (hinge).
    loss : str
        ``scipy.optimize.least_squares`` loss of the refinement ("linear" is the
        maximum-likelihood fit for Gaussian noise; "soft_l1"/"huber" down-weight
        outlier frames, scaled by the noise+model tolerance).
    max_normal_std_deg, max_length_rel_std : float
        Above these standard errors the plane is "insufficient_motion" (not
        determined by the data) and the verdict is negative.
    rtol : float
        Relative tolerance for exact-degeneracy tests.
    seed : int or None
        Seed of the random frame subsets.

    Returns
    -------
    GroupFit
        Verdict ``planar`` with ``reason``; ``depths`` (T, R), ``lengths`` (R,),
        unit ``normal``, ``rms`` and ``threshold`` (input units), ``spans``.

    Notes
    -----
    Verdict: with ``n`` used points (frames x rods) and ``dof = n - R - 2``
    the residual sum of squares of an exact model with Gaussian noise is
    ``2 sigma^2 chi2(dof)`` (hinge-relative vectors carry twice the variance),
    so the group is accepted when
    ``rms^2 <= 2 sigma^2 chi2_0.999(dof) / n + (model_tol * L_rms)^2`` and the
    normal and lengths are determined (standard errors from the reduced
    Jacobian).  All depths come from one fitted plane, hence one global member
    of the reflection pair.
    """
    x = _as_tracks(tracks, n_points=(2, 3))
    T, N, _ = x.shape
    if not isinstance(hinge, (int, np.integer)) or not 0 <= int(hinge) < N:
        raise ValueError(
            f"hinge must be an integer index in [0, {N}) for tracks of shape {x.shape}; got {hinge!r}"
        )
    if model_tol < 0:
        raise ValueError(f"model_tol must be >= 0; got {model_tol}")
    hinge = int(hinge)
    points = tuple(i for i in range(N) if i != hinge)
    U = x[:, list(points)] - x[:, [hinge]]
    valid = np.all(np.isfinite(U), axis=(1, 2))
    frames = np.flatnonzero(valid)
    lens = np.linalg.norm(U[valid], axis=-1)
    med_len = float(np.median(lens)) if lens.size else 0.0
    sig = _resolve_sigma(sigma, x, med_len if med_len > 0 else 1.0)
    rng = np.random.default_rng(seed)
    kw = {
        "model_tol": model_tol,
        "loss": loss,
        "max_normal_std_deg": max_normal_std_deg,
        "max_length_rel_std": max_length_rel_std,
        "rtol": rtol,
    }
    if med_len == 0.0:
        core = {
            "frames": frames,
            "status": "too_few_frames",
            "reason": "no frame with all points present and distinct from the hinge",
        }
        return _make_fit(core, T, hinge, points, sig)
    core = _core_fit(U, frames, sig, n_hyp=n_hypotheses, rng=rng, **kw)
    if core["status"] in ("planar", "minimal") or not find_spans:
        return _make_fit(core, T, hinge, points, sig)
    spans, span_fits = _find_spans(U, valid, sig, window, rng, n_hypotheses, kw, hinge, points)
    return _make_fit(core, T, hinge, points, sig, spans=spans, span_fits=span_fits)


def _find_spans(U, valid, sigma, window, rng, n_hyp, kw, hinge, points):
    T, R, _ = U.shape
    n_min = (3 if R == 1 else 2) + 2
    W = int(window) if window is not None else max(8, T // 10)
    W = max(W, n_min)
    if W > T:
        return (), ()
    stride = max(1, W // 2)
    starts = list(range(0, T - W + 1, stride))
    if starts[-1] != T - W:
        starts.append(T - W)

    def fit(a, b):
        fr = np.flatnonzero(valid[a:b]) + a
        if fr.size < n_min:
            return None
        c = _core_fit(U, fr, sigma, n_hyp=min(n_hyp, 64), rng=rng, **kw)
        # windows too short to determine the plane still count if their residual passes
        return c if c["status"] in ("planar", "insufficient_motion") else None

    spans = []
    cur = None  # (start, stop, core)
    for a in starts:
        c = fit(a, a + W)
        if c is None:
            continue
        if cur is not None and a <= cur[1]:
            merged = fit(cur[0], a + W)
            if merged is not None:
                cur = (cur[0], a + W, merged)
                continue
            spans.append(cur)
        elif cur is not None:
            spans.append(cur)
        cur = (a, a + W, c)
    if cur is not None:
        spans.append(cur)
    spans = [sp for sp in spans if sp[2]["status"] == "planar"]
    out_spans = tuple((int(s[2]["frames"][0]), int(s[2]["frames"][-1]) + 1) for s in spans)
    out_fits = tuple(_make_fit(s[2], T, hinge, points, sigma) for s in spans)
    return out_spans, out_fits


# --------------------------------------------------------------------------
# public: link discovery
# --------------------------------------------------------------------------
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
    with np.errstate(invalid="ignore"):
        med = np.nanmedian(np.where(valid, r, np.nan), axis=0)
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
    m = np.linalg.solve(A, b[..., None])[..., 0]  # (P, 3)
    lam_min, _, _, _ = _conic_eig(m)
    ok &= lam_min > 0
    val = _quad(m[None], un) - 1.0
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
    lam_min, _, _, _ = _conic_eig(q)
    ok = (n_valid >= min_frames) & (lam_min > 0) & (w[:, 3] > 0) & (w[:, 4] > 0)
    val = _quad(q[None, :, None, :], un) - w[None, :, 3:5]
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
    x = _as_tracks(tracks)
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
