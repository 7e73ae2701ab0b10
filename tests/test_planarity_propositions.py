"""Tests for the Hoffman-Flinchbaugh propositions (pinrecon.planarity.propositions).

Ground truth is built here from random 3D geometry (a plane through the pivot,
an orthonormal in-plane basis, rods at known in-plane angles) and projected
orthographically (camera x right, y down, z forward: drop z).  Nothing is
derived from the code under test.
"""

from __future__ import annotations

import numpy as np
import pytest

from pinrecon.planarity import PlanarSolution, hinge_from_two_views, rod_from_three_views

RNG_SEED = 20240601


# ----------------------------------------------------------------------------
# independent ground-truth geometry
# ----------------------------------------------------------------------------
def plane_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal in-plane basis (e1, e2) for a unit normal."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(normal, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(normal, e1)


def random_normal(rng, tilt_min_deg=5.0, tilt_max_deg=85.0) -> np.ndarray:
    tilt = np.radians(rng.uniform(tilt_min_deg, tilt_max_deg))
    azim = rng.uniform(-np.pi, np.pi)
    return np.array([np.sin(tilt) * np.cos(azim), np.sin(tilt) * np.sin(azim), np.cos(tilt)])


def rod_points(length, normal, angles) -> np.ndarray:
    """3D rod tips (K, 3) relative to the pivot at in-plane angles."""
    e1, e2 = plane_basis(normal)
    angles = np.asarray(angles, dtype=float)
    return length * (np.cos(angles)[:, None] * e1 + np.sin(angles)[:, None] * e2)


def angles_well_separated(rng, k, min_sep_deg=5.0):
    """k in-plane angles whose directions (mod 180 deg) are pairwise >= min_sep apart."""
    while True:
        th = rng.uniform(-np.pi, np.pi, k)
        diff = np.abs((th[:, None] - th[None, :] + np.pi / 2) % np.pi - np.pi / 2)
        if diff[np.triu_indices(k, 1)].min() > np.radians(min_sep_deg):
            return th


def depth_error_up_to_reflection(depths, truth, scale):
    d = np.asarray(depths)
    return min(np.max(np.abs(d - truth)), np.max(np.abs(-d - truth))) / scale


def normal_angle(n1, n2):
    """Angle between two plane normals (planes, so sign-free), radians."""
    return float(np.arccos(np.clip(abs(np.dot(n1, n2)), -1.0, 1.0)))


def true_normal_matching(sol: PlanarSolution, normal, depths_truth):
    """The truth's normal for the reflection member that the solution picked."""
    d = np.asarray(sol.depths)
    if np.max(np.abs(d - depths_truth)) <= np.max(np.abs(-d - depths_truth)):
        return normal
    return normal * np.array([1.0, 1.0, -1.0])


# ----------------------------------------------------------------------------
# Proposition 1
# ----------------------------------------------------------------------------
def test_rod_random_exact_recovers_depths_length_and_normal():
    rng = np.random.default_rng(RNG_SEED)
    worst_depth = worst_len = worst_norm = 0.0
    for _ in range(3000):
        length = 10 ** rng.uniform(-2, 3)
        normal = random_normal(rng)
        P = rod_points(length, normal, angles_well_separated(rng, 3))
        sol = rod_from_three_views(P[:, :2])
        assert sol.degeneracy is None and sol.unique and sol.consistent
        worst_depth = max(worst_depth, depth_error_up_to_reflection(sol.depths, P[:, 2], length))
        worst_len = max(worst_len, abs(sol.length - length) / length)
        # the normal must be the plane's, oriented consistently with the chosen member
        n_true = true_normal_matching(sol, normal, P[:, 2])
        n_true = n_true if n_true[2] > 0 else -n_true
        worst_norm = max(worst_norm, float(np.linalg.norm(sol.normal - n_true)))
    assert worst_depth < 1e-9
    assert worst_len < 1e-9
    assert worst_norm < 1e-9


def test_rod_reflection_pair_and_scale_invariance():
    rng = np.random.default_rng(1)
    normal = random_normal(rng, 20, 70)
    P = rod_points(2.5, normal, [0.1, 1.0, 2.2])
    sol = rod_from_three_views(P[:, :2])
    a, b = sol.pair()
    assert a is sol
    np.testing.assert_allclose(b.depths, -a.depths)
    np.testing.assert_allclose(b.normal, a.normal * [-1, -1, 1])
    # both members satisfy rigidity and planarity
    for member in (a, b):
        X = np.column_stack([P[:, :2], member.depths])
        np.testing.assert_allclose(np.linalg.norm(X, axis=1), 2.5, rtol=1e-12)
        np.testing.assert_allclose(X @ member.normal, 0, atol=1e-12)
    for s in (1e-4, 3.7, 512.0, 1e5):
        sol_s = rod_from_three_views(P[:, :2] * s)
        np.testing.assert_allclose(sol_s.depths, sol.depths * s, rtol=1e-11, atol=1e-13 * s)
        np.testing.assert_allclose(sol_s.normal, sol.normal, atol=1e-12)
        assert sol_s.length == pytest.approx(2.5 * s, rel=1e-12)


@pytest.mark.parametrize("eps_rad", [1e-2, 1e-3])
def test_rod_small_rotations(eps_rad):
    """Views eps apart: the input rounding alone limits accuracy to ~1e-16/eps^2."""
    rng = np.random.default_rng(7)
    errs = []
    for _ in range(300):
        normal = random_normal(rng, 10, 80)
        t0 = rng.uniform(-np.pi, np.pi)
        P = rod_points(1.0, normal, t0 + eps_rad * np.arange(3))
        sol = rod_from_three_views(P[:, :2])
        assert sol.degeneracy is None
        errs.append(depth_error_up_to_reflection(sol.depths, P[:, 2], 1.0))
    errs = np.array(errs)
    # measured at 1e-3 rad: median 3e-11, worst 5e-10 (intrinsic limit ~1e-10 .. 1e-9)
    assert errs.max() < 1e-9 * (1e-3 / eps_rad) ** 2
    assert np.median(errs) < 1e-10 * (1e-3 / eps_rad) ** 2


@pytest.mark.parametrize(
    "offsets, tag",
    [
        ((0.0, np.pi, 1.3), "collinear_views_1_2"),  # u2 = -u1
        ((0.0, 0.0, 1.3), "collinear_views_1_2"),  # identical views
        ((0.0, 1.3, np.pi), "collinear_views_1_3"),
        ((0.0, 1.3, 1.3 + np.pi), "collinear_views_2_3"),
    ],
)
def test_rod_collinear_projections_are_reported(offsets, tag):
    normal = np.array([0.3, -0.5, 0.8])
    normal /= np.linalg.norm(normal)
    P = rod_points(1.7, normal, 0.4 + np.array(offsets))
    sol = rod_from_three_views(P[:, :2] * 100)
    assert sol.degeneracy == tag
    assert not sol.unique and sol.consistent
    assert np.all(np.isnan(sol.depths)) and np.isnan(sol.length)


def test_rod_edge_on_plane_is_collinear_all():
    # plane containing the line of sight: every projection on one image line
    P = rod_points(1.0, np.array([1.0, 0.0, 0.0]), [0.2, 1.0, 2.5])
    sol = rod_from_three_views(P[:, :2])
    assert sol.degeneracy == "collinear_views_all"
    assert np.all(np.isnan(sol.depths))


def test_rod_plane_parallel_to_image():
    P = rod_points(3.0, np.array([0.0, 0.0, 1.0]), [0.3, 1.4, 2.9])
    sol = rod_from_three_views(P[:, :2])
    assert sol.degeneracy == "plane_parallel_to_image"
    np.testing.assert_array_equal(sol.depths, 0.0)
    np.testing.assert_allclose(sol.normal, [0, 0, 1])
    assert sol.length == pytest.approx(3.0, rel=1e-12)


def test_rod_equal_projected_lengths_2_3_still_solved():
    """r2 == r3 (paper's k1 = k2, b = 0): flagged, yet unique and correct."""
    rng = np.random.default_rng(3)
    worst = 0.0
    for _ in range(500):
        normal = random_normal(rng, 10, 80)
        e1, e2 = plane_basis(normal)
        # the image ellipse is symmetric about the projection of e1' (the in-plane
        # direction of steepest depth); mirror the view-2 angle about it.
        grad_dir = normal[:2] / np.linalg.norm(normal[:2])
        steep = np.array([grad_dir[0], grad_dir[1], -(normal[:2] @ grad_dir) / normal[2]])
        steep /= np.linalg.norm(steep)
        phi0 = np.arctan2(steep @ e2, steep @ e1)
        t1, t2 = rng.uniform(-np.pi, np.pi, 2)
        t3 = 2 * phi0 - t2
        P = rod_points(1.3, normal, [t1, t2, t3])
        r = np.linalg.norm(P[:, :2], axis=1)
        assert abs(r[1] - r[2]) < 1e-12
        diff = np.abs((np.array([t1 - t2, t1 - t3, t2 - t3]) + np.pi / 2) % np.pi - np.pi / 2)
        if diff.min() < np.radians(3):
            continue
        sol = rod_from_three_views(P[:, :2])
        assert sol.degeneracy == "equal_projected_lengths_2_3"
        assert sol.unique and sol.consistent
        worst = max(worst, depth_error_up_to_reflection(sol.depths, P[:, 2], 1.3))
    assert worst < 1e-9


def test_rod_equal_projected_lengths_1_2_is_not_degenerate():
    """r1 == r2 breaks the paper's eq. (14) (0/0) but not the conic solution."""
    normal = np.array([0.5, 0.2, 0.8])
    normal /= np.linalg.norm(normal)
    e1, e2 = plane_basis(normal)
    grad = normal[:2] / np.linalg.norm(normal[:2])
    steep = np.array([grad[0], grad[1], -(normal[:2] @ grad) / normal[2]])
    phi0 = np.arctan2(steep @ e2, steep @ e1)
    P = rod_points(2.0, normal, [0.3, 2 * phi0 - 0.3, 1.9])
    sol = rod_from_three_views(P[:, :2])
    assert sol.degeneracy is None
    assert depth_error_up_to_reflection(sol.depths, P[:, 2], 2.0) < 1e-12


def test_rod_without_planar_interpretation():
    # u1, u2 unit axes, u3 short diagonal: the only conic through them is a hyperbola
    uv = np.array([[1.0, 0.0], [0.0, 1.0], [0.4, 0.4]])
    sol = rod_from_three_views(uv)
    assert sol.degeneracy == "no_planar_interpretation"
    assert not sol.consistent and not sol.unique
    assert np.all(np.isnan(sol.depths))


def test_rod_input_validation():
    with pytest.raises(ValueError, match=r"uv must have shape \(3, 2\).*got shape \(2, 2\)"):
        rod_from_three_views(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="finite"):
        rod_from_three_views([[1, 0], [0, np.nan], [1, 1]])


def test_paper_jacobian_factorisation_prop1():
    """Doc claim: det J of the paper's eqs (4)-(6) at the solution = -4 tan^2(tilt) k3 k4 k5 / L^2."""
    rng = np.random.default_rng(11)
    for _ in range(50):
        normal = random_normal(rng, 10, 80)
        L = rng.uniform(0.5, 2)
        P = rod_points(L, normal, rng.uniform(-np.pi, np.pi, 3))
        (x1, y1, z1), (x2, y2, z2), (x3, y3, z3) = P
        k3, k4, k5 = x2 * y3 - x3 * y2, x3 * y1 - x1 * y3, x1 * y2 - x2 * y1
        J = np.array([[2 * z1, -2 * z2, 0], [2 * z1, 0, -2 * z3], [k3, k4, k5]])
        tan2 = (1 - normal[2] ** 2) / normal[2] ** 2
        assert np.linalg.det(J) == pytest.approx(
            -4 * tan2 * k3 * k4 * k5 / L**2, rel=1e-8, abs=1e-12
        )


def test_rod_repr_and_summary_are_readable():
    P = rod_points(1.0, np.array([0.0, 0.6, 0.8]), [0.1, 0.9, 2.0])
    sol = rod_from_three_views(P[:, :2])
    assert "PlanarSolution(kind='rod'" in repr(sol)
    text = sol.summary()
    assert "Proposition 1" in text and "normal" in text and "degeneracy: none" in text


# ----------------------------------------------------------------------------
# Proposition 2
# ----------------------------------------------------------------------------
def hinge_views(la, lb, normal, alphas, betas, origin=(0.0, 0.0)):
    """Absolute image positions (2, 3, 2) of (O, A, B) and the true depths (2, 2)."""
    A = rod_points(la, normal, alphas)
    B = rod_points(lb, normal, betas)
    o = np.asarray(origin, dtype=float)
    uv = np.stack([np.broadcast_to(o, (2, 2)), A[:, :2] + o, B[:, :2] + o], axis=1)
    return uv, np.stack([A[:, 2], B[:, 2]], axis=1)


def test_hinge_random_exact_recovers_depths_lengths_and_normal():
    rng = np.random.default_rng(RNG_SEED + 1)
    worst_depth = worst_len = worst_norm = 0.0
    n_done = 0
    while n_done < 3000:
        la, lb = 10 ** rng.uniform(-1, 2, 2)
        normal = random_normal(rng)
        al, be = rng.uniform(-np.pi, np.pi, 2), rng.uniform(-np.pi, np.pi, 2)
        wrap = lambda t: abs((t + np.pi / 2) % np.pi - np.pi / 2)
        if min(
            wrap(al[0] - al[1]), wrap(be[0] - be[1]), wrap(al.sum() - be.sum()), wrap(al[0] - be[0])
        ) < np.radians(5):
            continue
        origin = rng.uniform(-500, 500, 2)
        uv, z = hinge_views(la, lb, normal, al, be, origin)
        sol = hinge_from_two_views(uv)
        assert sol.unique and sol.consistent
        assert sol.degeneracy in (None, "equal_foreshortening_view_1"), sol
        scale = max(la, lb)
        worst_depth = max(worst_depth, depth_error_up_to_reflection(sol.depths, z, scale))
        worst_len = max(worst_len, np.max(np.abs(sol.lengths - [la, lb]) / [la, lb]))
        n_true = true_normal_matching(sol, normal, z)
        n_true = n_true if n_true[2] > 0 else -n_true
        worst_norm = max(worst_norm, float(np.linalg.norm(sol.normal - n_true)))
        n_done += 1
    assert worst_depth < 1e-9
    assert worst_len < 1e-9
    assert worst_norm < 1e-9


def test_hinge_scale_invariance_and_pair():
    normal = np.array([0.2, -0.4, 0.9])
    normal /= np.linalg.norm(normal)
    uv, _z = hinge_views(1.0, 0.7, normal, [0.2, 0.9], [2.0, 2.3], origin=(3.0, 4.0))
    sol = hinge_from_two_views(uv)
    for s in (1e-3, 7.3, 1024.0):
        sol_s = hinge_from_two_views(uv * s)
        np.testing.assert_allclose(sol_s.depths, sol.depths * s, rtol=1e-10, atol=1e-12 * s)
        np.testing.assert_allclose(sol_s.lengths, sol.lengths * s, rtol=1e-10)
        np.testing.assert_allclose(sol_s.normal, sol.normal, atol=1e-10)
    a, b = sol.pair()
    np.testing.assert_allclose(b.depths, -a.depths)


@pytest.mark.parametrize(
    "alphas, betas, tag, consistent",
    [
        ((0.3, 0.3), (1.5, 2.2), "collinear_views_A", True),  # A did not move
        ((0.3, 0.3 + np.pi), (1.5, 2.2), "collinear_views_A", True),  # A turned 180 deg
        ((0.3, 1.1), (1.5, 1.5 + np.pi), "collinear_views_B", True),
        ((0.3, 1.1), (1.9, 0.3 + 1.1 - 1.9), "parallel_chords", True),  # equal bisectors
        ((0.3, 1.1), (1.9, 0.3 + 1.1 - 1.9 + np.pi), "perpendicular_chords", True),
    ],
)
def test_hinge_degenerate_configurations(alphas, betas, tag, consistent):
    normal = np.array([0.4, 0.3, 0.7])
    normal /= np.linalg.norm(normal)
    uv, _ = hinge_views(1.2, 0.8, normal, alphas, betas, origin=(10.0, -4.0))
    sol = hinge_from_two_views(uv)
    assert sol.degeneracy == tag
    assert sol.consistent == consistent and not sol.unique
    assert np.all(np.isnan(sol.depths)) and np.all(np.isnan(sol.lengths))


def test_hinge_plane_parallel_to_image():
    uv, _ = hinge_views(1.0, 2.0, np.array([0.0, 0.0, 1.0]), [0.1, 0.8], [2.0, 2.9])
    sol = hinge_from_two_views(uv)
    assert sol.degeneracy == "plane_parallel_to_image"
    np.testing.assert_array_equal(sol.depths, 0.0)
    np.testing.assert_allclose(sol.lengths, [1.0, 2.0], rtol=1e-12)


def test_hinge_straight_in_view_1_is_flagged_but_solved():
    normal = np.array([-0.3, 0.5, 0.6])
    normal /= np.linalg.norm(normal)
    uv, z = hinge_views(1.0, 1.4, normal, [0.4, 1.2], [0.4 + np.pi, 2.0])
    sol = hinge_from_two_views(uv)
    assert sol.degeneracy == "straight_hinge_view_1"
    assert sol.unique
    assert depth_error_up_to_reflection(sol.depths, z, 1.4) < 1e-12


def steepest_angle(normal):
    """In-plane angle (in plane_basis coordinates) of the steepest-depth direction."""
    e1, e2 = plane_basis(normal)
    grad = normal[:2] / np.linalg.norm(normal[:2])
    steep = np.array([grad[0], grad[1], -(normal[:2] @ grad) / normal[2]])
    return np.arctan2(steep @ e2, steep @ e1)


def paper_b_coefficient(uv):
    """Linear coefficient (up to 2 k5^2) of the paper-style quadratic for Prop. 2."""
    a = uv[:, 1] - uv[:, 0]
    b = uv[:, 2] - uv[:, 0]
    cr = lambda p, q: p[0] * q[1] - p[1] * q[0]
    k1, k2 = a[0] @ a[0] - a[1] @ a[1], b[0] @ b[0] - b[1] @ b[1]
    return k1 * cr(b[0], b[1]) * cr(b[1], a[0]) - k2 * cr(b[0], a[1]) * cr(a[1], a[0])


def test_hinge_equal_foreshortening_is_flagged_but_solved():
    """|z_a1|/|OA| == |z_b1|/|OB| (the paper-style b = 0 case): flagged, unique, correct."""
    rng = np.random.default_rng(4)
    checked = 0
    for _ in range(200):
        normal = random_normal(rng, 15, 75)
        phi0 = steepest_angle(normal)
        a1, a2, b2 = rng.uniform(-np.pi, np.pi, 3)
        b1 = 2 * phi0 - a1 + rng.choice([0.0, np.pi])  # mirror about the steepest direction
        uv, z = hinge_views(1.0, 0.6, normal, (a1, a2), (b1, b2), origin=(5.0, 2.0))
        assert abs(abs(z[0, 0]) / 1.0 - abs(z[0, 1]) / 0.6) < 1e-12
        assert abs(paper_b_coefficient(uv)) < 1e-12  # the paper's b vanishes here
        sol = hinge_from_two_views(uv)
        if sol.degeneracy != "equal_foreshortening_view_1":
            # only the stronger degeneracies may pre-empt the tag
            assert sol.degeneracy in (
                "collinear_views_A",
                "collinear_views_B",
                "parallel_chords",
                "perpendicular_chords",
                "straight_hinge_view_1",
            )
            continue
        assert sol.unique
        assert depth_error_up_to_reflection(sol.depths, z, 1.0) < 1e-9
        checked += 1
    assert checked > 150


def test_hinge_without_planar_interpretation():
    uv = np.zeros((2, 3, 2))
    uv[0, 1], uv[1, 1] = (1.0, 0.0), (0.0, 2.0)
    uv[0, 2], uv[1, 2] = (1.0, 1.0), (2.0, 0.0)
    sol = hinge_from_two_views(uv)
    assert sol.degeneracy == "no_planar_interpretation"
    assert not sol.consistent


def test_paper_jacobian_factorisation_prop2():
    """Doc claim: the paper's Prop-2 Jacobian at the solution is
    4 La^3 Lb^3 cos^2 sin^2(tilt) sin(a1-a2) sin(b1-b2) sin(a1-b1) sin(a1+a2-b1-b2)
    (in-plane angles measured from the steepest-descent direction)."""
    rng = np.random.default_rng(12)
    for _ in range(50):
        tilt = rng.uniform(0.2, 1.3)
        c, s = np.cos(tilt), np.sin(tilt)
        la, lb = rng.uniform(0.5, 2, 2)
        a1, a2, b1, b2 = rng.uniform(-np.pi, np.pi, 4)
        vec = lambda L, t, c=c, s=s: np.array(
            [L * c * np.cos(t), L * np.sin(t), -L * s * np.cos(t)]
        )
        A1, A2, B1, B2 = vec(la, a1), vec(la, a2), vec(lb, b1), vec(lb, b2)
        cr = lambda p, q: p[0] * q[1] - p[1] * q[0]
        k3, k4, k5 = cr(B1, A2), cr(A2, A1), cr(A1, B1)
        k6, k7, k8 = cr(B1, B2), cr(B2, A1), cr(A1, B1)
        J = np.array(
            [
                [2 * A1[2], 0, -2 * A2[2], 0],
                [0, 2 * B1[2], 0, -2 * B2[2]],
                [k3, k4, k5, 0],
                [k6, k7, 0, k8],
            ]
        )
        expect = (
            4
            * la**3
            * lb**3
            * c**2
            * s**2
            * np.sin(a1 - a2)
            * np.sin(b1 - b2)
            * np.sin(a1 - b1)
            * np.sin(a1 + a2 - b1 - b2)
        )
        assert np.linalg.det(J) == pytest.approx(expect, rel=1e-8, abs=1e-12)


def test_paper_b_coefficient_factorisation_prop2():
    """Doc claim: k1 k6 k7 - k2 k3 k4 = -La^3 Lb^3 s^2 c^2 sin(a1-a2) sin(b1-b2)
    sin(a1+a2-b1-b2) sin(a1+b1) (the equal-foreshortening analogue of r2 = r3)."""
    rng = np.random.default_rng(13)
    for _ in range(50):
        tilt = rng.uniform(0.2, 1.3)
        c, s = np.cos(tilt), np.sin(tilt)
        la, lb = rng.uniform(0.5, 2, 2)
        a1, a2, b1, b2 = rng.uniform(-np.pi, np.pi, 4)
        img = lambda L, t, c=c: np.array([L * c * np.cos(t), L * np.sin(t)])
        uv = np.zeros((2, 3, 2))
        uv[0, 1], uv[1, 1], uv[0, 2], uv[1, 2] = img(la, a1), img(la, a2), img(lb, b1), img(lb, b2)
        expect = (
            -(la**3)
            * lb**3
            * s**2
            * c**2
            * np.sin(a1 - a2)
            * np.sin(b1 - b2)
            * np.sin(a1 + a2 - b1 - b2)
            * np.sin(a1 + b1)
        )
        assert paper_b_coefficient(uv) == pytest.approx(expect, rel=1e-8, abs=1e-12)


def test_hinge_input_validation():
    with pytest.raises(ValueError, match=r"uv must have shape \(2, 3, 2\).*got shape \(3, 2\)"):
        hinge_from_two_views(np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"got shape \(2, 2, 2\)"):
        hinge_from_two_views(np.zeros((2, 2, 2)))
