"""The planar rigid model of a point group, its refinement and the fit on one frame set.

Model: plane normal ``n = (cos(phi) sin(tau), sin(phi) sin(tau), cos(tau))``
(``tau`` is the tilt from the image plane), rod ``k`` of length ``L_k`` at
in-plane angle ``theta_{t,k}`` in frame ``t``.  In image axes rotated by
``-phi`` its image is ``L_k (cos(tau) cos(theta), sin(theta))`` and its depth is
``-L_k sin(tau) cos(theta)``.  The fit minimises the squared image distances
between these model points and the observed hinge-relative vectors over
``(phi, tau, L_k)`` and all ``theta_{t,k}``; the angles are eliminated exactly
(variable projection: each one is the nearest point of the rod's image
ellipse), so the outer problem has ``2 + R`` parameters.  :func:`core_fit` runs
the hypotheses of :mod:`.hypotheses`, refines the best one, derives standard
errors from the reduced Jacobian and gives the chi-square verdict on one set of
frames; :func:`make_fit` turns that verdict into a :class:`~.fit_types.GroupFit`
over the whole sequence (canonical member of the reflection pair).
"""

from __future__ import annotations

import numpy as np

# chi2.ppf(q, k) = chdtri(k, 1 - q), without importing scipy.stats (0.9 s)
from scipy.special import chdtri

from .conics import pow2_scale, readonly
from .fit_types import GroupFit
from .hypotheses import linear_fit, minimal_hypotheses, params_from_hypothesis, sampson

__all__ = ["core_fit", "make_fit"]

_CHI2_QUANTILE = 0.999


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
    # imported here: scipy.optimize takes 0.07 s to import, and most runs fit no planar group
    from scipy.optimize import least_squares

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
def core_fit(
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
    scale = pow2_scale(float(np.sqrt(np.mean(np.sum(u * u, axis=-1)))) or 1.0)
    un = u / scale
    sig_rel = np.sqrt(2.0) * sigma / scale  # noise of a hinge-relative vector
    med_len = float(np.median(np.linalg.norm(un, axis=-1)))
    cut = 3.0 * np.hypot(sig_rel, model_tol * med_len)

    # hypotheses: linear all-frames fit + minimal solutions on random subsets
    hyps_Q, hyps_L = [], []
    lin = linear_fit(un)
    if lin is not None:
        hyps_Q.append(lin[0])
        hyps_L.append(lin[1])
    Qm, Lm = minimal_hypotheses(un, n_hyp, rng)
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
    d = sampson(un, Q, L)
    cost = np.nansum(np.minimum(np.nan_to_num(d, nan=np.inf) ** 2, cut**2), axis=(1, 2))
    best = int(np.argmin(cost))
    # local optimisation: refit linearly on the inliers of the best hypothesis
    inl = np.all(np.abs(d[best]) <= cut, axis=1)
    if np.count_nonzero(inl) >= n_min + 1 and np.count_nonzero(inl) < n:
        lo = linear_fit(un[inl])
        if lo is not None:
            dlo = sampson(un, lo[0][None], lo[1][None])
            clo = np.nansum(np.minimum(np.nan_to_num(dlo, nan=np.inf) ** 2, cut**2))
            if clo < cost[best]:
                Q, L, best = lo[0][None], lo[1][None], 0
    x0 = params_from_hypothesis(Q[best], L[best])
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
                (np.sqrt(2.0) * sigma) ** 2 * chdtri(dof, 1.0 - _CHI2_QUANTILE) / n_pts
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
    """Boolean copy of ``a`` that cannot be written to."""
    a = np.array(a, dtype=bool)
    a.setflags(write=False)
    return a


def make_fit(
    core: dict, T: int, hinge: int, points: tuple[int, ...], sigma: float, spans=(), span_fits=()
) -> GroupFit:
    """The :class:`GroupFit` of a :func:`core_fit` result over all ``T`` frames.

    ``core`` is the dict returned by :func:`core_fit` (or a minimal one with
    ``frames``, ``status`` and ``reason``); ``hinge`` and ``points`` index the
    group's points; ``spans`` / ``span_fits`` come from :func:`~.spans.planar_spans`.
    Frames outside ``core["frames"]`` get NaN depths and residuals.
    """
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
        depths=readonly(depths),
        lengths=readonly(lengths),
        normal=readonly(normal),
        gradient=readonly(gradient),
        rms=rms,
        threshold=thr,
        sigma=sigma,
        planar=planar,
        reason=core["reason"],
        degeneracy=degeneracy,
        spans=tuple(spans),
        frame_rms=readonly(frame_rms),
        used=_frozen_bool(used),
        length_std=readonly(length_std),
        normal_std_deg=nstd,
        span_fits=tuple(span_fits),
    )
