"""Hoffman & Flinchbaugh (1982) "structure from planar motion" propositions.

Frames and conventions
----------------------
Orthographic camera with axes x right, y down, z forward (depth).  A 3D vector
relative to the pivot/hinge ``O`` is ``(u, v, z)``; the camera sees ``(u, v)``
(``uv``, image units: pixels or metres) and loses ``z``.  Translation drops out
because every vector is taken relative to ``O``.

A rod of length ``L`` turning in a plane through ``O`` whose normal is not
perpendicular to the line of sight lies on the plane ``z = g . uv`` (``g`` is
the *depth gradient*, dimensionless).  Its length condition is

    |uv|^2 + (g . uv)^2 = L^2   <=>   uv^T M uv = 1,   M = (I + g g^T) / L^2,

the centred image ellipse of the circle traced by the rod.  ``M`` is recovered
linearly from the image; then ``L = 1 / sqrt(lambda_min(M))``,
``|g|^2 = lambda_max / lambda_min - 1`` along the eigenvector of ``lambda_max``,
and every depth is ``z = g . uv``.  The sign of ``g`` is the reflection about the
image plane that orthographic projection cannot resolve.  The plane normal in
camera axes is ``n = (-g_x, -g_y, 1) / sqrt(1 + |g|^2)`` (oriented away from the
camera, ``n_z > 0``).  The *canonical* member of a reflection pair is the one
whose normal has ``n_x > 0`` (or ``n_x == 0`` and ``n_y >= 0``); ``reflected()``
gives the other.  Derivations, degeneracies and accuracy are in
``docs/planarity.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .conics import conic_eig, hinge_conic, pow2_scale, readonly, rod_conic, sym_row

__all__ = [
    "DEFAULT_RTOL",
    "PlanarSolution",
    "hinge_from_two_views",
    "rod_from_three_views",
]

#: Default relative tolerance for detecting degenerate configurations.  It is
#: applied to dimensionless quantities only (sines of angles between image
#: vectors, relative differences of squared projected lengths, |g|^2, ...), so
#: every test is invariant to the image scale.
DEFAULT_RTOL = 1e-9


# --------------------------------------------------------------------------
# small vectorised helpers (the shared conic algebra lives in conics.py)
# --------------------------------------------------------------------------
def _cross2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """2D cross product ``a_x b_y - a_y b_x`` over the last axis."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _sine(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|sin| of the angle between 2D vectors (0 when either vector is zero)."""
    den = np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.abs(_cross2(a, b)) / den
    return np.where(den > 0, s, 0.0)


def _gradient_from_conic(m: np.ndarray):
    """Depth gradient ``g`` (canonical sign) and ``lam_min`` from a PD conic.

    ``M = (I + g g^T) / L^2`` so ``|g|^2 = (lam_max - lam_min) / lam_min``.
    Returns ``(g, lam_min, lam_max)``; ``g`` is NaN where ``M`` is not PD.
    """
    lam_min, lam_max, gap, e_max = conic_eig(m)
    with np.errstate(invalid="ignore", divide="ignore"):
        gnorm = np.sqrt(gap / lam_min)
    g = gnorm[..., None] * e_max
    g = np.where((lam_min > 0)[..., None], g, np.nan)
    return _canonical_gradient(g), lam_min, lam_max


def _canonical_gradient(g: np.ndarray) -> np.ndarray:
    """Pick the reflection member with normal ``n_x > 0`` (i.e. ``g_x < 0``).

    Ties (``g_x == 0``) are broken by ``n_y >= 0`` (``g_y <= 0``).
    """
    flip = (g[..., 0] > 0) | ((g[..., 0] == 0) & (g[..., 1] > 0))
    return np.where(flip[..., None], -g, g)


def _normal_from_gradient(g: np.ndarray) -> np.ndarray:
    """Unit plane normal in camera axes, ``(-g_x, -g_y, 1) / sqrt(1 + |g|^2)``."""
    n = np.concatenate([-g, np.ones(g.shape[:-1] + (1,))], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def _as_uv(uv, name: str, shape: tuple[int, ...], meaning: str) -> np.ndarray:
    try:
        arr = np.asarray(uv, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"{name} must be a numeric array of shape {shape} ({meaning}); {exc}"
        ) from None
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape} ({meaning}); got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(
            f"{name} must be finite; got NaN/inf at indices {np.argwhere(~np.isfinite(arr)).tolist()}"
        )
    return arr


# --------------------------------------------------------------------------
# result type
# --------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class PlanarSolution:
    """Structure recovered by one of the planar-motion propositions.

    Attributes
    ----------
    kind : str
        ``"rod"`` (Proposition 1) or ``"hinge"`` (Proposition 2).
    depths : ndarray
        Depths ``z`` (camera z, forward) of the free end(s) relative to the
        pivot/hinge, same units as the input.  Shape ``(3,)`` for a rod (one per
        view) and ``(2, 2)`` (views x (A, B)) for a hinge.  One member of the
        reflection pair (see :meth:`reflected`).  NaN when undetermined.
    lengths : ndarray
        3D rod length(s): shape ``(1,)`` for a rod, ``(2,)`` = (|OA|, |OB|) for a hinge.
    normal : ndarray, shape (3,)
        Unit plane normal in camera axes with ``n_z >= 0``.
    gradient : ndarray, shape (2,)
        Depth gradient ``g``: every point of the plane has ``z = g . uv``.
    conic : ndarray, shape (2, 2)
        Image ellipse ``uv^T M uv = 1`` of the (first) rod's circle.
    degeneracy : str or None
        ``None`` for a generic configuration, else a short tag (see the
        functions' docstrings).  ``unique`` tells whether the returned solution
        is nevertheless unique up to reflection.
    unique : bool
        True when the solution is unique up to the reflection about the image plane.
    consistent : bool
        False when no real rigid planar interpretation exists.
    """

    kind: str
    depths: np.ndarray
    lengths: np.ndarray
    normal: np.ndarray
    gradient: np.ndarray
    conic: np.ndarray
    degeneracy: str | None
    unique: bool
    consistent: bool

    @property
    def length(self) -> float:
        """First (for a rod: the only) 3D length."""
        return float(self.lengths[0])

    @property
    def tilt_deg(self) -> float:
        """Angle between the motion plane and the image plane, degrees."""
        return float(np.degrees(np.arccos(np.clip(self.normal[2], -1.0, 1.0))))

    def reflected(self) -> PlanarSolution:
        """The other member of the reflection pair (depths negated, ``n -> (-n_x, -n_y, n_z)``)."""
        return replace(
            self,
            depths=readonly(-self.depths),
            normal=readonly(self.normal * np.array([-1.0, -1.0, 1.0])),
            gradient=readonly(-self.gradient),
        )

    def pair(self) -> tuple[PlanarSolution, PlanarSolution]:
        """Both members of the reflection pair, canonical member first."""
        return self, self.reflected()

    def summary(self) -> str:
        """Multi-line human-readable description."""
        what = "rod (Proposition 1)" if self.kind == "rod" else "hinge (Proposition 2)"
        lines = [f"planar {what}"]
        if not self.consistent:
            lines.append("  no real rigid planar interpretation")
        lens = ", ".join(f"{x:.6g}" for x in self.lengths)
        lines.append(f"  lengths: {lens}")
        if np.all(np.isfinite(self.normal)):
            n = self.normal
            lines.append(
                f"  normal (camera x right, y down, z fwd): ({n[0]:+.4f}, {n[1]:+.4f}, {n[2]:+.4f})"
                f"  tilt {self.tilt_deg:.2f} deg"
            )
        else:
            lines.append("  normal: undetermined")
        lines.append(
            "  depths (one member of the reflection pair): "
            + np.array2string(np.asarray(self.depths), precision=5, suppress_small=False)
        )
        lines.append(
            f"  degeneracy: {self.degeneracy or 'none'}; unique up to reflection: {self.unique}"
        )
        return "\n".join(lines)

    def __repr__(self) -> str:
        lens = ", ".join(f"{x:.6g}" for x in self.lengths)
        if np.all(np.isfinite(self.normal)):
            nrm = "(" + ", ".join(f"{x:+.4f}" for x in self.normal) + ")"
        else:
            nrm = "undetermined"
        return (
            f"PlanarSolution(kind={self.kind!r}, lengths=[{lens}], normal={nrm}, "
            f"degeneracy={self.degeneracy!r}, unique={self.unique}, consistent={self.consistent})"
        )

    __str__ = summary


def _undetermined(
    kind: str, depth_shape, n_len: int, degeneracy: str, consistent: bool
) -> PlanarSolution:
    nan2 = np.full(2, np.nan)
    return PlanarSolution(
        kind=kind,
        depths=readonly(np.full(depth_shape, np.nan)),
        lengths=readonly(np.full(n_len, np.nan)),
        normal=readonly(np.full(3, np.nan)),
        gradient=readonly(nan2),
        conic=readonly(np.full((2, 2), np.nan)),
        degeneracy=degeneracy,
        unique=False,
        consistent=consistent,
    )


def _mat(m: np.ndarray) -> np.ndarray:
    return np.array([[m[0], m[1]], [m[1], m[2]]])


# --------------------------------------------------------------------------
# Proposition 1
# --------------------------------------------------------------------------
def rod_from_three_views(uv, *, rtol: float = DEFAULT_RTOL) -> PlanarSolution:
    """Proposition 1: depths of a rigid rod turning in a plane, from three views.

    Parameters
    ----------
    uv : array_like, shape (3, 2)
        Image vector from the pivot ``O`` to the free end in each view
        (``uv[i] = (u_i, v_i)``, camera x right / y down, any image unit).
    rtol : float
        Relative tolerance for the degeneracy tests (dimensionless quantities).

    Returns
    -------
    PlanarSolution
        ``depths`` shape (3,) (``z_i = g . uv_i``), ``lengths`` shape (1,)
        (``L = 1 / sqrt(lambda_min(M))``), unit ``normal``; the other member of
        the reflection pair is ``result.reflected()``.

    Notes
    -----
    The three conditions ``uv_i^T M uv_i = 1`` fix the image ellipse
    ``M = (I + g g^T) / L^2``; the linear system has determinant
    ``2 k3 k4 k5`` (pairwise 2D cross products), so it is singular exactly for
    collinear projections.  Degeneracy tags:

    ``"collinear_views_1_2"`` / ``"_1_3"`` / ``"_2_3"`` / ``"collinear_views_all"``
        Two (or all) projections are parallel/antiparallel (k5, k4 or k3 = 0):
        a one-parameter family of solutions, depths/length/normal are NaN.
        ``consistent`` is False if two collinear projections have different
        lengths (only possible with all three collinear, i.e. the plane
        containing the line of sight).
    ``"no_planar_interpretation"``
        ``M`` is not positive definite: no real rigid planar rod fits.  NaN.
    ``"plane_parallel_to_image"``
        ``M`` is proportional to ``I`` (|g|^2 <= rtol): depths are 0, the
        reflection pair collapses, the normal is (0, 0, 1) and its azimuth is
        meaningless.
    ``"equal_projected_lengths_2_3"``
        ``r2 == r3`` (the paper's k1 = k2, where its root-selection argument
        b = 0 fails).  The solution is still unique up to reflection and is
        returned (``unique`` is True).
    """
    u = _as_uv(uv, "uv", (3, 2), "three views x (u, v) of the free end relative to the pivot")
    scale = float(np.max(np.linalg.norm(u, axis=1)))
    if scale == 0.0:
        return _undetermined("rod", (3,), 1, "collinear_views_all", True)
    scale = pow2_scale(scale)
    un = u / scale
    r2 = np.sum(un**2, axis=1)

    # Collinearity: sines for the pairs (1,2)=k5, (1,3)=k4, (2,3)=k3.
    pairs = ((0, 1), (0, 2), (1, 2))
    sines = np.array([_sine(un[i], un[j]) for i, j in pairs])
    coll = sines <= rtol
    if np.any(coll):
        if np.all(coll):
            return _undetermined("rod", (3,), 1, "collinear_views_all", True)
        k = int(np.argmax(coll))
        i, j = pairs[k]
        # Two centred-ellipse points on one line through O are antipodal: equal lengths.
        same = abs(r2[i] - r2[j]) <= max(1e3 * rtol, 1e-12) * max(r2[i], r2[j])
        return _undetermined("rod", (3,), 1, f"collinear_views_{i + 1}_{j + 1}", bool(same))

    m = rod_conic(un)
    g, lam_min, lam_max = _gradient_from_conic(m)
    if not (np.isfinite(lam_min) and lam_min > rtol * abs(lam_max)):
        return _undetermined("rod", (3,), 1, "no_planar_interpretation", False)

    length = scale / np.sqrt(lam_min)
    g2 = float(g @ g)
    if g2 <= rtol:
        g = np.zeros(2)
        tag, depths = "plane_parallel_to_image", np.zeros(3)
    else:
        depths = u @ g
        tag = None
        if abs(r2[1] - r2[2]) <= rtol * max(r2[1], r2[2]):
            tag = "equal_projected_lengths_2_3"
    return PlanarSolution(
        kind="rod",
        depths=readonly(depths),
        lengths=readonly([length]),
        normal=readonly(_normal_from_gradient(g)),
        gradient=readonly(g),
        conic=readonly(_mat(m) / scale**2),
        degeneracy=tag,
        unique=True,
        consistent=True,
    )


# --------------------------------------------------------------------------
# Proposition 2
# --------------------------------------------------------------------------
def hinge_from_two_views(uv, *, rtol: float = DEFAULT_RTOL) -> PlanarSolution:
    """Proposition 2: depths of two rods hinged at ``O`` moving in one plane, from two views.

    Parameters
    ----------
    uv : array_like, shape (2, 3, 2)
        Absolute image positions: views x (O, A, B) x (u, v).  ``O`` is the
        hinge; the rods are ``a_i = A_i - O_i`` and ``b_i = B_i - O_i``.
    rtol : float
        Relative tolerance for the degeneracy tests (dimensionless quantities).

    Returns
    -------
    PlanarSolution
        ``depths`` shape (2, 2) = views x (A, B), relative to ``O``;
        ``lengths`` = (|OA|, |OB|); unit ``normal``.

    Notes
    -----
    Both rods trace concentric circles in one plane, so their image ellipses
    share ``Q = I + g g^T`` up to scale: ``a1^T Q a1 = a2^T Q a2`` and
    ``b1^T Q b1 = b2^T Q b2`` fix ``Q`` up to scale (written with differences,
    ``(a2 - a1)^T Q (a2 + a1) = 0``).  With rods at in-plane angles alpha_i,
    beta_i the two rows are dependent exactly when
    ``sin(alpha1 - alpha2) sin(beta1 - beta2) sin(alpha1 + alpha2 - beta1 - beta2) = 0``.
    Degeneracy tags:

    ``"collinear_views_A"`` / ``"collinear_views_B"``
        a2 is parallel to a1 in the image (a2 = +-a1 for a rigid rod: it did not
        move or turned by 180 deg), so that rod gives no constraint.  NaN.
    ``"parallel_chords"`` / ``"perpendicular_chords"``
        The two rods' motion bisectors are parallel (3D chords A1A2 and B1B2
        parallel) or perpendicular (image chords conjugate): both conditions
        coincide, one-parameter family.  NaN.
    ``"no_planar_interpretation"``
        ``Q`` is not positive definite.  NaN.
    ``"plane_parallel_to_image"``
        ``Q`` proportional to ``I``: depths 0, normal (0, 0, 1).
    ``"straight_hinge_view_1"``
        a1 parallel to b1 (k5 = 0): the paper's two triple products
        ``[a1 b1 a2] = [a1 b1 b2] = 0`` lose rank, but the conic formulation
        does not; the unique solution is returned (``unique`` True).
    ``"equal_foreshortening_view_1"``
        ``|z_a1| / |OA| == |z_b1| / |OB|``: both rods equally inclined to the
        image plane in view 1.  This is where the paper-style elimination's
        linear coefficient ``k1 k6 k7 - k2 k3 k4`` vanishes (the analogue of its
        equal-length case r2 = r3 of Proposition 1, where |z2| = |z3|).
        Unique, returned (``unique`` True).
    """
    x = _as_uv(uv, "uv", (2, 3, 2), "two views x (O, A, B) x (u, v), absolute image positions")
    a = x[:, 1] - x[:, 0]
    b = x[:, 2] - x[:, 0]
    scale = float(max(np.max(np.linalg.norm(a, axis=1)), np.max(np.linalg.norm(b, axis=1))))
    if scale == 0.0:
        return _undetermined("hinge", (2, 2), 2, "collinear_views_A", True)
    scale = pow2_scale(scale)
    an, bn = a / scale, b / scale
    ra2, rb2 = np.sum(an**2, axis=1), np.sum(bn**2, axis=1)

    for name, w, r2 in (("A", an, ra2), ("B", bn, rb2)):
        if _sine(w[0], w[1]) <= rtol:
            same = abs(r2[0] - r2[1]) <= max(1e3 * rtol, 1e-12) * max(r2[0], r2[1], 1e-300)
            return _undetermined("hinge", (2, 2), 2, f"collinear_views_{name}", bool(same))

    da, sa = an[1] - an[0], an[1] + an[0]
    db, sb = bn[1] - bn[0], bn[1] + bn[0]
    row_a, row_b = sym_row(da, sa), sym_row(db, sb)
    cr = np.cross(row_a, row_b)
    if np.linalg.norm(cr) <= rtol * np.linalg.norm(row_a) * np.linalg.norm(row_b):
        tag = "parallel_chords" if _sine(da, db) <= np.sqrt(rtol) else "perpendicular_chords"
        return _undetermined("hinge", (2, 2), 2, tag, True)

    q = hinge_conic(an[None], bn[None])[0]
    g, lam_min, lam_max = _gradient_from_conic(q)
    if not (np.isfinite(lam_min) and lam_min > rtol * abs(lam_max)):
        return _undetermined("hinge", (2, 2), 2, "no_planar_interpretation", False)

    g2 = float(g @ g)
    tag = None
    if g2 <= rtol:
        g = np.zeros(2)
        tag = "plane_parallel_to_image"
    # 3D lengths: |w|^2 + (g.w)^2, averaged over the two views.
    la = scale * np.sqrt(np.mean(ra2 + (an @ g) ** 2))
    lb = scale * np.sqrt(np.mean(rb2 + (bn @ g) ** 2))
    depths = np.stack([a @ g, b @ g], axis=1)
    if tag is None:
        if _sine(an[0], bn[0]) <= rtol:
            tag = "straight_hinge_view_1"
        elif abs(abs(depths[0, 0]) / la - abs(depths[0, 1]) / lb) <= rtol:
            # Equal foreshortening of OA and OB in view 1: the paper-style
            # quadratic's linear coefficient k1 k6 k7 - k2 k3 k4 vanishes here.
            tag = "equal_foreshortening_view_1"
    conic = np.array([[1.0 + g[0] ** 2, g[0] * g[1]], [g[0] * g[1], 1.0 + g[1] ** 2]]) / la**2
    return PlanarSolution(
        kind="hinge",
        depths=readonly(depths),
        lengths=readonly([la, lb]),
        normal=readonly(_normal_from_gradient(g)),
        gradient=readonly(g),
        conic=readonly(conic),
        degeneracy=tag,
        unique=True,
        consistent=True,
    )
