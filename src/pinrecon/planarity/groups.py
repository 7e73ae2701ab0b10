"""Robust planarity test of point groups over a sequence (:func:`fit_planar_group`).

A *group* is a hinge (or pivot) point plus one or two other points tracked in
``T`` frames.  Hypothesis: every other point is joined to the hinge by a rigid
rod and all rods turn in one plane through the hinge, fixed relative to the
hinge for the whole sequence (Hoffman & Flinchbaugh's "pairwise-rigid
structure in planar motion").  Frames, units and sign conventions are those of
:mod:`pinrecon.planarity.propositions`: orthographic camera, x right, y down,
z forward; vectors relative to the hinge (translation drops out); depths
``z = g . uv``; one global member of the reflection pair.  This module checks
the input, estimates the image noise and runs the fit; the model and its
refinement are in :mod:`.fit_core`, the hypotheses in :mod:`.hypotheses`, the
planar spans in :mod:`.spans` and the result type in :mod:`.fit_types`.
"""

from __future__ import annotations

import numpy as np

from .fit_core import core_fit, make_fit
from .fit_types import GroupFit
from .propositions import DEFAULT_RTOL
from .spans import planar_spans

__all__ = [
    "DEFAULT_MODEL_TOL",
    "SIGMA_CAP_FRACTION",
    "as_tracks",
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


# --------------------------------------------------------------------------
# input handling and noise
# --------------------------------------------------------------------------
def as_tracks(tracks, name: str = "tracks", n_points: tuple[int, ...] | None = None) -> np.ndarray:
    """``tracks`` as a float array of shape (T, N, 2), or a ``ValueError`` naming ``name``.

    NaN marks a missing point; inf is refused.  ``n_points`` restricts ``N``.
    """
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
    x = as_tracks(tracks)
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
    x = as_tracks(tracks, n_points=(2, 3))
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
        return make_fit(core, T, hinge, points, sig)
    core = core_fit(U, frames, sig, n_hyp=n_hypotheses, rng=rng, **kw)
    if core["status"] in ("planar", "minimal") or not find_spans:
        return make_fit(core, T, hinge, points, sig)
    spans, span_fits = planar_spans(U, valid, sig, window, rng, n_hypotheses, kw, hinge, points)
    return make_fit(core, T, hinge, points, sig, spans=spans, span_fits=span_fits)
