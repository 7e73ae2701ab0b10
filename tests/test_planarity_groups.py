"""Tests for the robust group fit and link discovery (pinrecon.planarity.groups).

Ground truth comes from 3D geometry built here (planar limbs, rods on spheres,
the CMU walk through the independent BVH reader) projected orthographically
(camera x right, y down, z forward; u = s * (R X)[:2] + c).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path

from pinrecon.planarity import (
    LinkGraph,
    discover_links,
    estimate_noise_sigma,
    fit_planar_group,
)

TESTS_DIR = Path(__file__).resolve().parent
REPO = TESTS_DIR.parent
WALK = data_path("mocap/cmu-mb_02_01.bvh")
CMU_UNIT_M = 0.056444


# ----------------------------------------------------------------------------
# independent ground truth
# ----------------------------------------------------------------------------
def unit_normal(tilt_deg: float, azim_deg: float) -> np.ndarray:
    t, a = np.radians(tilt_deg), np.radians(azim_deg)
    return np.array([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)])


def plane_axes(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """In-plane 'down' axis (image y projected into the plane) and 'forward' axis."""
    down = np.array([0.0, 1.0, 0.0])
    e_down = down - (down @ normal) * normal
    e_down /= np.linalg.norm(e_down)
    return e_down, np.cross(normal, e_down)


def planar_leg(
    T=100,
    tilt_deg=45.0,
    azim_deg=20.0,
    thigh=125.0,
    shank=120.0,
    swing_deg=30.0,
    knee_deg=60.0,
    noise=0.0,
    rng=None,
    cycles=1.0,
):
    """Hip, knee, ankle image tracks (T, 3, 2) in px of a leg swinging in one plane.

    The thigh swings +-swing_deg about the in-plane 'down' axis, the knee bends
    0..knee_deg; the hip translates in the image (walking).  Returns
    (uv_px, X (T, 3, 3) camera-frame points, plane normal).
    """
    n = unit_normal(tilt_deg, azim_deg)
    e_down, e_fwd = plane_axes(n)
    t = np.arange(T) / T * 2 * np.pi * cycles
    psi = np.radians(swing_deg) * np.sin(t)
    kappa = np.radians(knee_deg) * 0.5 * (1 - np.cos(t + 0.6))
    hip = np.stack([200 + 40 * t, 150 + 3 * np.sin(2 * t), 5 * np.cos(t)], axis=1)
    d1 = np.cos(psi)[:, None] * e_down + np.sin(psi)[:, None] * e_fwd
    d2 = np.cos(psi - kappa)[:, None] * e_down + np.sin(psi - kappa)[:, None] * e_fwd
    knee = hip + thigh * d1
    ankle = knee + shank * d2
    X = np.stack([hip, knee, ankle], axis=1)
    uv = X[..., :2].copy()
    if noise:
        uv += rng.normal(0.0, noise, uv.shape)
    return uv, X, n


def angle_up_to_reflection_deg(n_est, n_true) -> float:
    """Angle to the true normal or to its reflection about the image plane."""
    refl = n_true * np.array([1.0, 1.0, -1.0])

    def ang(a, b):  # sign-free angle between plane normals, accurate near 0
        return np.arctan2(np.linalg.norm(np.cross(a, b)), abs(a @ b))

    return float(np.degrees(min(ang(n_est, n_true), ang(n_est, refl))))


# ----------------------------------------------------------------------------
# exact data
# ----------------------------------------------------------------------------
def test_exact_planar_rod_and_hinge_are_accepted_with_consistent_sign():
    rng = np.random.default_rng(0)
    worst = 0.0
    for trial in range(40):
        n = unit_normal(rng.uniform(10, 80), rng.uniform(-180, 180))
        e1, e2 = plane_axes(n)
        T = int(rng.integers(4, 12))
        L = 10 ** rng.uniform(0, 3)
        th = rng.uniform(-np.pi, np.pi, (T, 2))
        A = L * (np.cos(th[:, :1]) * e1 + np.sin(th[:, :1]) * e2)
        B = 0.7 * L * (np.cos(th[:, 1:]) * e1 + np.sin(th[:, 1:]) * e2)
        O = rng.uniform(-1000, 1000, (T, 3))  # arbitrary translation
        if trial % 2:
            tracks = np.stack([O, O + A], axis=1)[..., :2]
            truth = A[:, 2:3]
        else:
            tracks = np.stack([O + A, O, O + B], axis=1)[..., :2]
            truth = np.concatenate([A[:, 2:3], B[:, 2:3]], axis=1)
        hinge = 0 if trial % 2 else 1
        fit = fit_planar_group(tracks, hinge=hinge, sigma=1e-9 * L, model_tol=0.0)
        assert fit.planar, fit
        assert fit.degeneracy is None
        # one global reflection for all frames
        err = min(np.max(np.abs(fit.depths - truth)), np.max(np.abs(-fit.depths - truth))) / L
        worst = max(worst, err)
        lengths_true = [L] if trial % 2 else [L, 0.7 * L]
        np.testing.assert_allclose(fit.lengths, lengths_true, rtol=1e-9)
        assert angle_up_to_reflection_deg(fit.normal, n) < 1e-7
    assert worst < 1e-9


def test_non_planar_or_non_rigid_groups_are_rejected_with_four_or_more_views():
    rng = np.random.default_rng(1)
    kinds = ["rod_sphere", "rod_stretch", "hinge_two_planes", "hinge_stretch"]
    n_rejected = {k: 0 for k in kinds}
    n_trials = 60
    for kind in kinds:
        for _ in range(n_trials):
            T = int(rng.integers(4, 10))
            L = 100.0
            n = unit_normal(rng.uniform(20, 70), rng.uniform(-180, 180))
            e1, e2 = plane_axes(n)
            th = rng.uniform(-np.pi, np.pi, (T, 2))
            A = L * (np.cos(th[:, :1]) * e1 + np.sin(th[:, :1]) * e2)
            if kind == "rod_sphere":  # rigid, not planar: random directions
                d = rng.normal(size=(T, 3))
                A = L * d / np.linalg.norm(d, axis=1, keepdims=True)
            elif kind == "rod_stretch":  # planar, not rigid (+-10..30 %)
                A *= 1 + rng.uniform(0.1, 0.3, (T, 1)) * rng.choice([-1, 1], (T, 1))
            n2 = unit_normal(rng.uniform(20, 70), rng.uniform(-180, 180))
            f1, f2 = plane_axes(n2 if kind == "hinge_two_planes" else n)
            B = 0.8 * L * (np.cos(th[:, 1:]) * f1 + np.sin(th[:, 1:]) * f2)
            if kind == "hinge_stretch":
                B *= 1 + rng.uniform(0.1, 0.3, (T, 1)) * rng.choice([-1, 1], (T, 1))
            O = np.zeros((T, 3))
            pts = [O, O + A] if kind.startswith("rod") else [O, O + A, O + B]
            tracks = np.stack(pts, axis=1)[..., :2]
            fit = fit_planar_group(tracks, hinge=0, sigma=1e-9 * L, model_tol=0.0, find_spans=False)
            n_rejected[kind] += not fit.planar
    assert n_rejected == {k: n_trials for k in kinds}


def test_minimal_views_are_exactly_determined_not_tested():
    uv, X, _n = planar_leg(T=7)
    uv, X = uv[[1, 3]], X[[1, 3]]
    fit = fit_planar_group(uv, hinge=1, sigma=1e-9, model_tol=0.0)
    assert fit.planar and "not testable" in fit.reason
    d_true = X[:, [0, 2], 2] - X[:, [1], 2]
    assert min(np.abs(fit.depths - d_true).max(), np.abs(fit.depths + d_true).max()) < 1e-8


# ----------------------------------------------------------------------------
# noisy data
# ----------------------------------------------------------------------------
@pytest.mark.parametrize("tilt_deg", [30.0, 45.0, 60.0])
def test_noisy_planar_leg_lengths_and_normal(tilt_deg):
    """1 px noise, ~500 px figure (thigh 125 px, shank 120 px), 100 frames."""
    rng = np.random.default_rng(int(tilt_deg))
    worst_len = worst_ang = 0.0
    for k in range(8):
        uv, X, n = planar_leg(
            T=100, tilt_deg=tilt_deg, azim_deg=rng.uniform(-180, 180), noise=1.0, rng=rng
        )
        for sigma in (None, 1.0):
            fit = fit_planar_group(uv, hinge=1, sigma=sigma)
            assert fit.planar, fit
            assert fit.points == (0, 2)
            worst_len = max(
                worst_len, float(np.max(np.abs(fit.lengths - [125.0, 120.0]) / [125.0, 120.0]))
            )
            worst_ang = max(worst_ang, angle_up_to_reflection_deg(fit.normal, n))
            # depths: one global reflection, close to the truth
            d_true = X[:, [0, 2], 2] - X[:, [1], 2]
            err = min(np.abs(fit.depths - d_true).max(), np.abs(fit.depths + d_true).max())
            assert err < 10.0
    # measured: lengths <= 0.9 %, normals <= 0.6 deg
    assert worst_len < 0.02
    assert worst_ang < 3.0


def test_noise_estimate_from_dense_tracks():
    rng = np.random.default_rng(5)
    uv, _, _ = planar_leg(T=300, noise=1.0, rng=rng)
    assert estimate_noise_sigma(uv) == pytest.approx(1.0, rel=0.15)


def test_non_planar_wobble_is_rejected_with_default_tolerance():
    """A leg whose shank leaves the plane by up to +-25 deg is not planar."""
    rng = np.random.default_rng(8)
    uv, X, n = planar_leg(T=100, tilt_deg=45, noise=1.0, rng=rng)
    t = np.arange(100) / 100 * 2 * np.pi
    off = np.radians(25) * np.sin(3 * t)
    shank = X[:, 2] - X[:, 1]
    X2 = X.copy()
    X2[:, 2] = X[:, 1] + np.cos(off)[:, None] * shank + 120.0 * np.sin(off)[:, None] * n
    uv2 = X2[..., :2] + rng.normal(0, 1.0, (100, 3, 2))
    assert not fit_planar_group(uv2, hinge=1, find_spans=False).planar
    assert fit_planar_group(uv, hinge=1, find_spans=False).planar


def test_spans_when_planarity_holds_for_part_of_the_sequence():
    rng = np.random.default_rng(9)
    T = 120
    _uv, X, n = planar_leg(T=T, tilt_deg=40, noise=1.0, rng=rng, cycles=2.0)
    # after frame 70 the leg plane precesses by up to 35 deg
    t = np.arange(T)
    ang = np.where(t >= 70, np.radians(35) * np.sin((t - 70) / 50 * np.pi * 1.5), 0.0)
    rel = X - X[:, :1]
    axis = np.array([0.0, 1.0, 0.0])
    c, s = np.cos(ang)[:, None, None], np.sin(ang)[:, None, None]
    cross = np.cross(axis, rel)
    rot = rel * c + cross * s + axis * (rel @ axis)[..., None] * (1 - c)
    uv2 = (X[:, :1] + rot)[..., :2] + rng.normal(0, 1.0, (T, 3, 2))
    fit = fit_planar_group(uv2, hinge=1, sigma=1.0)
    assert not fit.planar
    assert len(fit.spans) >= 1
    first = fit.spans[0]
    assert first[0] <= 5 and 60 <= first[1] <= 90
    assert len(fit.span_fits) == len(fit.spans) and all(f.planar for f in fit.span_fits)
    assert angle_up_to_reflection_deg(fit.span_fits[0].normal, n) < 3.0


def test_missing_frames_are_skipped():
    rng = np.random.default_rng(10)
    uv, _X, _n = planar_leg(T=80, tilt_deg=50, noise=1.0, rng=rng)
    uv[[3, 10, 11, 50], 2] = np.nan
    uv[20, 0, 1] = np.nan
    fit = fit_planar_group(uv, hinge=1, sigma=1.0)
    assert fit.planar
    assert fit.n_frames == 75
    assert np.all(np.isnan(fit.depths[[3, 10, 11, 20, 50]]))
    assert np.all(np.isfinite(np.delete(fit.depths, [3, 10, 11, 20, 50], axis=0)))
    assert not fit.used[20] and fit.used[21]


def test_robustness_to_outlier_frames():
    """A few gross tracking errors: RANSAC start + soft_l1 refinement keep the geometry."""
    rng = np.random.default_rng(11)
    uv, _X, n = planar_leg(T=100, tilt_deg=45, noise=1.0, rng=rng)
    bad = rng.choice(100, 8, replace=False)
    ang = rng.uniform(-np.pi, np.pi, 8)
    uv[bad, 2] += rng.uniform(30, 60, (8, 1)) * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    fit = fit_planar_group(uv, hinge=1, sigma=1.0, loss="soft_l1", find_spans=False)
    np.testing.assert_allclose(fit.lengths, [125.0, 120.0], rtol=0.03)
    assert angle_up_to_reflection_deg(fit.normal, n) < 4.0
    assert not fit.planar  # the outliers themselves violate the model
    assert np.all(fit.frame_rms[bad] > 10) and np.median(np.delete(fit.frame_rms, bad)) < 3


def test_reflected_and_summary():
    uv, _, _ = planar_leg(T=30)
    fit = fit_planar_group(uv, hinge=1, sigma=1e-6, model_tol=0.0)
    a, b = fit.pair()
    np.testing.assert_allclose(b.depths, -a.depths)
    np.testing.assert_allclose(b.normal, a.normal * [-1, -1, 1])
    text = fit.summary(names=["hip", "knee", "ankle"])
    assert "hinge=knee" in text and "|knee-hip|" in text and "PLANAR" in text
    assert repr(fit).startswith("GroupFit(hinge=1")


def test_input_validation():
    with pytest.raises(
        ValueError, match=r"tracks must have shape \(T, 2 or 3, 2\).*got shape \(10, 4, 2\)"
    ):
        fit_planar_group(np.zeros((10, 4, 2)))
    with pytest.raises(
        ValueError, match=r"tracks must have shape \(T, N, 2\).*got shape \(10, 3\)"
    ):
        fit_planar_group(np.zeros((10, 3)))
    with pytest.raises(ValueError, match="hinge must be an integer index in \\[0, 3\\)"):
        fit_planar_group(np.zeros((10, 3, 2)), hinge=3)
    with pytest.raises(ValueError, match="names must have one entry per point"):
        discover_links(np.zeros((10, 3, 2)), names=["a", "b"])
    with pytest.raises(ValueError, match="sigma must be"):
        fit_planar_group(np.ones((10, 2, 2)) * np.arange(10)[:, None, None], sigma=-1.0)


# ----------------------------------------------------------------------------
# link discovery
# ----------------------------------------------------------------------------
@pytest.mark.parametrize("order", [(0, 1, 2), (2, 0, 1), (1, 2, 0)])
def test_discover_links_picks_the_knee_of_a_synthetic_leg(order):
    rng = np.random.default_rng(12)
    uv, _, _ = planar_leg(T=100, tilt_deg=50, azim_deg=-30, noise=1.0, rng=rng)
    names = np.array(["hip", "knee", "ankle"])
    graph = discover_links(uv[:, list(order)], names=list(names[list(order)]))
    assert isinstance(graph, LinkGraph)
    assert graph.hinge == list(order).index(1)
    assert graph.degeneracy is None
    assert not graph.candidates[list(order).index(0)].planar  # hip as hinge: hip-ankle not rigid
    assert not graph.candidates[list(order).index(2)].planar
    np.testing.assert_allclose(sorted(graph.lengths), [120.0, 125.0], rtol=0.02)
    pairs = {tuple(sorted(names[list(order)][list(ln.points)])) for ln in graph.links}
    assert pairs == {("hip", "knee"), ("ankle", "knee")}
    assert "<- hinge" in graph.summary()


def synthetic_figure(T, rng, noise=1.0):
    """17 tracked points: two planar legs, a rigid pelvis/torso block, arms, jitter points."""
    _uvL, XL, _ = planar_leg(T=T, tilt_deg=40, azim_deg=10, noise=0.0)
    _uvR, XR, _ = planar_leg(T=T, tilt_deg=40, azim_deg=10, noise=0.0, swing_deg=-30)
    off = np.array([25.0, 0.0, 10.0])
    hips = XL[:, 0]
    pts = [hips, hips + off]  # left/right hip (translating pelvis)
    pts += [XL[:, 1], XL[:, 2], XR[:, 1] + off, XR[:, 2] + off]  # knees/ankles
    t = np.arange(T) / T * 2 * np.pi
    # a torso that sways out of any plane (not planar), points rigidly attached
    ax = np.stack([np.sin(0.3 * np.sin(t)), -np.cos(0.3 * np.sin(t)), 0.2 * np.cos(2 * t)], axis=1)
    ax /= np.linalg.norm(ax, axis=1, keepdims=True)
    for k in range(1, 5):
        pts.append(hips + 40 * k * ax)
    # arms: shoulders swinging in their own plane, elbows
    sh = hips + 160 * ax
    for sgn in (1, -1):
        psi = sgn * np.radians(25) * np.sin(t)
        d = np.stack([np.sin(psi), np.cos(psi), 0.3 * np.sin(psi)], axis=1)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        pts.append(sh + 90 * d)
    pts += [hips + rng.normal(0, 30, (T, 3)) + 100 for _ in range(5)]  # unrelated jittering points
    X = np.stack(pts, axis=1)
    return X[..., :2] + rng.normal(0, noise, (T, X.shape[1], 2))


def test_discover_links_on_a_figure_is_tractable_and_finds_the_knees():
    rng = np.random.default_rng(13)
    uv = synthetic_figure(150, rng)
    assert uv.shape[1] == 17
    t0 = time.perf_counter()
    graph = discover_links(
        uv, sigma=1.0, model_tol=0.0
    )  # exact planar legs: test against noise only
    elapsed = time.perf_counter() - t0
    assert elapsed < 10.0
    links = {ln.points for ln in graph.links}
    assert {(0, 2), (2, 3), (1, 4), (4, 5)} <= links  # thighs and shanks
    assert (0, 3) not in links and (1, 5) not in links  # hip-ankle is not rigid
    knee_triples = {(t.points, t.hinge) for t in graph.triples if t.hinge in (2, 4)}
    assert ((0, 2, 3), 2) in knee_triples and ((1, 4, 5), 4) in knee_triples
    for t in graph.triples:
        assert t.hinge == t.points[1]
    assert graph.n_pairs == 17 * 16 // 2 and graph.n_pairs_fitted < graph.n_pairs
    assert "link" in graph.summary()


# ----------------------------------------------------------------------------
# real motion: CMU 02_01 walk
# ----------------------------------------------------------------------------
def camera_rotation(azimuth_deg: float) -> np.ndarray:
    """R_cam_world for a horizontal camera `azimuth_deg` away from side-on.

    Side-on looks along world +X.  Camera axes: x right, y down (= world -Y),
    z forward (viewing direction).
    """
    a = np.radians(azimuth_deg)
    forward = np.array([np.cos(a), 0.0, np.sin(a)])
    down = np.array([0.0, -1.0, 0.0])
    right = np.cross(down, forward)
    return np.stack([right, down, forward])


@pytest.fixture(scope="module")
def walk():
    sys.path.insert(0, str(TESTS_DIR))
    from bvh_reference import reference_positions

    names, _parents, P, _end_names, _P_end = reference_positions(WALK, CMU_UNIT_M)
    return names, P[1:]  # frame 0 is the synthetic T-pose


@pytest.mark.parametrize("azimuth_deg", [30.0, 45.0, 60.0])
def test_cmu_walk_knee_is_the_hinge_and_lengths_within_5_percent(walk, azimuth_deg):
    names, P = walk
    s_px_per_m = 300.0
    R = camera_rotation(azimuth_deg)
    rng = np.random.default_rng(int(azimuth_deg))
    uv = s_px_per_m * np.einsum("ij,fkj->fki", R, P)[..., :2] + np.array([640.0, 360.0])
    uv += rng.normal(0.0, 1.0, uv.shape)
    for side in ("Left", "Right"):
        idx = [names.index(side + j) for j in ("UpLeg", "Leg", "Foot")]  # hip, knee, ankle
        graph = discover_links(uv[:, idx], names=["hip", "knee", "ankle"])
        assert graph.hinge == 1, graph.summary()
        fit = graph.candidates[1]
        thigh_true = np.linalg.norm(P[:, idx[0]] - P[:, idx[1]], axis=-1).mean()
        shank_true = np.linalg.norm(P[:, idx[2]] - P[:, idx[1]], axis=-1).mean()
        thigh, shank = fit.lengths / s_px_per_m  # points (0, 2) = (hip, ankle)
        assert thigh == pytest.approx(thigh_true, rel=0.05)
        assert shank == pytest.approx(shank_true, rel=0.05)
        # the sagittal plane is tilted by about the azimuth from the image plane
        assert abs(fit.tilt_deg - azimuth_deg) < 15.0
