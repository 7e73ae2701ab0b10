"""Feet on the ground: the contact and floor rows' Jacobians on the manifold, the floor
estimate and the contact detection on a clip with known contacts, the metrics, and the
floor/contact stage of ``reconstruct``."""

from __future__ import annotations

import numpy as np
import pytest
from dense_blocks import dense_jacobian

import pinrecon as pr
from pinrecon.contact import (
    ContactSettings,
    Floor,
    contacts_from_spec,
    detect_contacts,
    estimate_floor,
    foot_keypoints,
    foot_metrics,
)
from pinrecon.errors import InputError, UnknownNameError
from pinrecon.rows import State
from pinrecon.rows.contact import ContactHeight, ContactVelocity
from pinrecon.rows.floor import FloorPenetration
from pinrecon.synthetic import bundled_motion, side_camera, smooth_motion

T = 5


# ----------------------------------------------------------------------------- Jacobians
@pytest.fixture(scope="module")
def setting():
    fig = pr.Figure.human()
    rng = np.random.default_rng(0)
    Q = smooth_motion(fig, T, 30.0, seed=1)
    Q = np.stack([fig.integrate(q, 0.3 * rng.normal(size=fig.nv)) for q in Q])
    return fig, Q


def _rows(fig, Q):
    k = fig.keypoint_index(["left_ankle", "right_ankle", "left_knee"])
    C = np.array([[1, 0, 1], [1, 1, 1], [1, 1, 0], [0, 1, 0], [1, 1, 1]], bool)
    n = np.array([0.1, 1.0, -0.2])
    h = fig.keypoints(Q)[:, k] @ (n / np.linalg.norm(n))
    mid = float(np.median(h))  # a floor through the middle: some points below it, some above
    return {
        "contact_velocity/3D": ContactVelocity(k, C, 30.0, 0.05, weights=np.full((T, 3), 0.5)),
        "contact_velocity/horizontal": ContactVelocity(k, C, 30.0, 0.05, normal=n),
        "contact_height": ContactHeight(k, C, n, 0.3, [0.05, 0.07, 0.4], 0.01),
        "floor": FloorPenetration(k, np.arange(T), n, mid, [0.0, 0.02, 0.01], 0.01),
    }


@pytest.mark.parametrize("name", ["contact_velocity/3D", "contact_velocity/horizontal", "contact_height", "floor"])
def test_row_jacobian_matches_manifold_finite_differences(setting, name):
    """d r / d v_t at v = 0 against [r(q (+) eps e_i) - r(q (-) eps e_i)] / 2 eps, with
    q (+) v = pin.integrate(q, v)."""
    fig, Q = setting
    row = _rows(fig, Q)[name]
    b = row.evaluate(State(fig, Q, np.arange(T), True), True)
    J = dense_jacobian([b], T, fig.nv)[0]
    fd = np.zeros_like(J)
    eps = 1e-6
    for t in range(T):
        for i in range(fig.nv):
            dv = np.zeros(fig.nv)
            dv[i] = eps
            Qp, Qm = Q.copy(), Q.copy()
            Qp[t] = fig.integrate(Q[t], dv)
            Qm[t] = fig.integrate(Q[t], -dv)
            rp = row.evaluate(State(fig, Qp, np.arange(T), False), False).r.ravel()
            rm = row.evaluate(State(fig, Qm, np.arange(T), False), False).r.ravel()
            fd[:, t * fig.nv + i] = (rp - rm) / (2 * eps)
    assert np.abs(J).max() > 0
    assert np.abs(J - fd).max() <= 1e-6 * np.abs(J).max(), name


def test_rows_residuals_by_hand(setting):
    fig, Q = setting
    k = fig.keypoint_index(["left_ankle"])
    P = fig.keypoints(Q)[:, k[0]]
    C = np.ones((T, 1), bool)
    v = ContactVelocity(k, C, 30.0, 0.05).evaluate(State(fig, Q, np.arange(T), False), False)
    np.testing.assert_allclose(v.r, (P[1:] - P[:-1]) * 30.0 / 0.05)
    vh = ContactVelocity(k, C, 30.0, 0.05, normal=[0, 2.0, 0]).evaluate(State(fig, Q, np.arange(T), False), False)
    np.testing.assert_allclose(np.linalg.norm(vh.r, axis=1), np.linalg.norm((P[1:] - P[:-1])[:, [0, 2]], axis=1) * 600)
    h = ContactHeight(k, C, [0, 1, 0], -0.9, [0.08], 0.01).evaluate(State(fig, Q, np.arange(T), False), False)
    np.testing.assert_allclose(h.r[:, 0], (P[:, 1] + 0.9 - 0.08) / 0.01)
    f = FloorPenetration(k, np.arange(T), [0, 1, 0], P[2, 1], [0.0], 0.002).evaluate(
        State(fig, Q, np.arange(T), False), False)
    np.testing.assert_allclose(f.r[:, 0], np.minimum(0.0, P[:, 1] - P[2, 1]) / 0.002)


# ----------------------------------------------------------------------------- a clip with known contacts
def stepping_clip(fps=60.0, seconds=4.0, seed=0, noise_m=0.001):
    """Two feet (heel and toe each) stepping on a tilted floor, with a jump.

    Built here, independently of pinrecon.contact: each foot alternates 0.6 s of stance
    (heel 3 cm and toe 1 cm above the floor, still) and 0.4 s of swing (0.6 m forward, up
    to 12 cm high), the right foot half a cycle later; from 2.4 s to 2.9 s both feet are
    in the air (a 25 cm jump). Returns the world points (T, 4, 3), the contacts (T, 4),
    the floor's normal and offset, and fps.
    """
    rng = np.random.default_rng(seed)
    n = np.array([np.sin(np.radians(6.0)), np.cos(np.radians(6.0)), 0.0])  # 6 degrees of tilt about z
    d = 0.3
    forward = np.array([0.0, 0.0, 1.0])
    side = np.cross(n, forward)
    t = np.arange(int(seconds * fps)) / fps
    heights = np.array([0.03, 0.01, 0.03, 0.01])  # left heel, left toe, right heel, right toe
    along = np.array([0.0, 0.15, 0.0, 0.15])
    lateral = np.array([0.1, 0.1, -0.1, -0.1])
    P = np.zeros((len(t), 4, 3))
    C = np.zeros((len(t), 4), bool)
    for foot, phase0 in ((0, 0.0), (1, 0.5)):
        ph = (t / 1.0 + phase0) % 1.0
        steps = np.floor(t / 1.0 + phase0)
        stance = ph < 0.6
        s = np.clip((ph - 0.6) / 0.4, 0.0, 1.0)
        pos = 0.6 * (steps + np.where(stance, 0.0, 0.5 - 0.5 * np.cos(np.pi * s)))
        lift = np.where(stance, 0.0, 0.12 * np.sin(np.pi * s))
        jump = (t >= 2.4) & (t < 2.9)
        lift = lift + np.where(jump, 0.25 * np.sin(np.pi * (t - 2.4) / 0.5), 0.0)
        for j in (2 * foot, 2 * foot + 1):
            base = (pos + along[j])[:, None] * forward + lateral[j] * side
            P[:, j] = base + (d + heights[j] + lift)[:, None] * n
            C[:, j] = stance & ~jump
    P += rng.normal(0.0, noise_m, P.shape)
    return P, C, n, d, fps


def test_floor_estimate_on_the_stepping_clip():
    P, C, n, d, fps = stepping_clip()
    up_guess = np.array([0.0, 1.0, 0.0])  # 6 degrees off the true normal
    fl = estimate_floor(P, up=up_guess, fps=fps)
    # the feet spread along z only: the tilt about z (in x) is not seen -> along z it must be right
    tilt_seen = np.degrees(np.arcsin(abs(fl.n @ np.array([0.0, 0.0, 1.0]))))
    assert tilt_seen < 0.5
    # a floor perpendicular to the prior up, through the toes' height at (0, ., 0)
    assert abs(fl.n @ up_guess - 1.0) < 1e-6
    # walked twice, side by side 1.2 m apart: the planted points span the plane, the whole tilt is found
    fl2 = estimate_floor(_two_lanes(P, n), up=up_guess, fps=fps)
    ang = np.degrees(np.arccos(np.clip(fl2.n @ n, -1, 1)))
    assert ang < 0.3, ang
    assert abs(fl2.offset_m - (d + 0.01)) < 0.003  # through the planted toes (1 cm above the plane)



def test_floor_tilt_found_where_the_planted_points_spread_over_10_cm():
    """A dancer's planted ankles (a few stances over a 40 cm patch, spread 15 cm along one
    direction and 4 cm across it), the prior up leaning 8 degrees along the spread (a
    one-camera reconstruction's leg depths; bench_contact's generic dance): the floor's tilt
    along the spread is the points' own."""
    rng = np.random.default_rng(4)
    n = np.array([0.0, 1.0, 0.0])
    along, across = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    fps, T = 60.0, 600
    P = np.zeros((T, 2, 3))
    for f in range(2):  # stances of 1 s at random spots, the foot still within each
        for a in range(0, T, 60):
            spot = rng.normal(0.0, 0.15) * along + rng.normal(0.0, 0.04) * across + 0.2 * f * across
            P[a : a + 60, f] = spot + 0.08 * n
    P += rng.normal(0.0, 0.002, P.shape)
    tilt = np.radians(8.0)
    up = np.cos(tilt) * n + np.sin(tilt) * along
    fl = estimate_floor(P, up=up, fps=fps)
    tilt_along = np.degrees(np.arcsin(abs(fl.n @ along)))
    assert tilt_along < 1.0, tilt_along  # the points' own tilt (0), not the prior's 8 degrees
    # across, where the stances spread 4 cm, the prior holds (it leans 0 there; the
    # stances' sampled spread turns the stiff direction by a few degrees)
    assert np.degrees(np.arccos(np.clip(fl.n @ n, -1, 1))) < 1.5
    # with the old 25 cm the whole floor followed the prior
    assert np.degrees(np.arcsin(abs(estimate_floor(P, up=up, fps=fps, min_spread_m=0.25).n @ along))) > 7.5
    assert abs(fl.height(P).mean()) < 0.005  # through the planted points


def _two_lanes(P, n):
    """The stepping clip walked twice, the second time 1.2 m to the side on the same plane."""
    u = np.cross(n, [0.0, 0.0, 1.0])
    u /= np.linalg.norm(u)
    return np.concatenate([P, P + 1.2 * u])


def test_contact_detection_finds_the_known_contacts():
    P, C, n, d, fps = stepping_clip()
    fl = Floor(tuple(n), d)
    found = detect_contacts(P, fl, fps)
    # away from the switches (3 frames either side) detection agrees with the truth
    switch = np.zeros_like(C)
    for j in range(C.shape[1]):
        for t in np.where(np.diff(C[:, j].astype(int)) != 0)[0]:
            switch[max(0, t - 3) : t + 4, j] = True
    agree = (found == C)[~switch].mean()
    assert agree > 0.97, agree
    # never in contact in the air: mid-swing and during the jump
    t = np.arange(len(P)) / fps
    assert not found[(t >= 2.5) & (t < 2.8)].any()
    # and the same with the floor estimated from the clip (given the tilted up direction)
    fl_est = estimate_floor(P, up=n, fps=fps)
    assert abs(fl_est.offset_m - (d + 0.01)) < 0.005  # through the planted toes
    found2 = detect_contacts(P, fl_est, fps)
    assert (found2 == C)[~switch].mean() > 0.97


def test_contact_detection_ignores_the_unseen_direction():
    """A planted point whose depth wanders (as a one-camera reconstruction's does) is in
    contact when that direction is declared unseen."""
    P, C, n, d, fps = stepping_clip()
    Pw = P.copy()
    Pw[..., 0] += 0.02 * np.sin(np.arange(len(P)) / fps * 2 * np.pi * 3.0)[:, None]  # up to 38 cm/s along x
    fl = Floor(tuple(n), d)
    assert detect_contacts(Pw, fl, fps).sum() < 0.5 * C.sum()
    assert (detect_contacts(Pw, fl, fps, unseen=[1.0, 0.0, 0.0]) == C).mean() > 0.9


def test_foot_metrics_by_hand():
    fl = Floor((0.0, 1.0, 0.0), 0.5)
    P = np.zeros((4, 1, 3))
    P[:, 0, 0] = [0.0, 0.01, 0.03, 0.03]  # x: moves 1 cm, 2 cm, 0 cm per frame
    P[:, 0, 1] = [0.5, 0.49, 0.52, 0.5]  # heights 0, -1 cm, +2 cm, 0
    C = np.array([[True], [True], [True], [False]])
    m = foot_metrics(P, fl, C, fps=10.0)
    assert m["skating_mps"] == pytest.approx((0.1 + 0.2) / 2)
    assert m["penetration_m"] == pytest.approx(0.01 / 4)
    assert m["penetration_max_m"] == pytest.approx(0.01)
    assert m["floating_m"] == pytest.approx(0.02 / 3)
    assert m["contact_frames"] == 3


# ----------------------------------------------------------------------------- floors and specs
def test_floor_specs_and_errors():
    assert Floor.parse("y=0") == Floor((0.0, 1.0, 0.0), 0.0)
    f = Floor.parse("z=0.05")
    assert f.normal == (0.0, 0.0, 1.0) and f.offset_m == pytest.approx(0.05)
    f = Floor.parse("-z=1")
    assert f.normal == (0.0, 0.0, -1.0) and f.height([0, 0, 0.5]) == pytest.approx(0.5)
    f = Floor.parse("0, 2, 0, 0.2")
    assert f.normal == (0.0, 1.0, 0.0) and f.offset_m == pytest.approx(0.1)
    assert Floor.from_array(f.as_array()) == f
    for bad in ("w=0", "1,2", "0,0,0,1", "floor"):
        with pytest.raises(InputError, match="floor"):
            Floor.parse(bad)


def test_contacts_from_spec():
    names = ["left_ankle", "right_ankle"]
    C = contacts_from_spec({"left_ankle": [[1, 2]], "right_ankle": [[0, 0], [3, 3]]}, names, 4)
    np.testing.assert_array_equal(C, [[0, 1], [1, 0], [1, 0], [0, 1]])
    # on a grid twice as fine: frames between two contact frames are in contact
    C2 = contacts_from_spec({"left_ankle": [[1, 2]]}, names, 7, factor=2)
    np.testing.assert_array_equal(C2[:, 0], [0, 0, 1, 1, 1, 0, 0])
    with pytest.raises(UnknownNameError, match="left_ankle"):
        contacts_from_spec({"nose": [[0, 1]]}, names, 4)
    with pytest.raises(InputError, match="outside"):
        contacts_from_spec({"left_ankle": [[0, 9]]}, names, 4)
    with pytest.raises(InputError, match="shape"):
        contacts_from_spec(np.zeros((3, 2), bool), names, 4)


def test_foot_keypoints_of_the_figures():
    assert foot_keypoints(pr.Figure.human()) == ["left_ankle", "right_ankle"]
    assert foot_keypoints(pr.Figure.human("joints")) == ["left_ankle", "left_toe", "right_ankle", "right_toe"]
    assert foot_keypoints(pr.Figure.human(), ["left_ankle", "nose"]) == ["left_ankle"]


def test_settings_are_checked():
    with pytest.raises(InputError, match="sigma_velocity_mps"):
        ContactSettings(sigma_velocity_mps=0.0)
    with pytest.raises(InputError, match="refine_iterations"):
        ContactSettings(refine_iterations=0)


def test_every_round_but_the_last_is_capped(monkeypatch):
    """The rounds before the last only refine the next round's contacts and floor: their solves
    stop after ``refine_iterations``; the last runs with the caller's options. Ground truth: the
    options each solve was given."""
    from pinrecon import contact
    from pinrecon.reconstruct import build_problem
    from pinrecon.synthetic import project_tracks, side_camera

    fig = pr.Figure.human()
    q = smooth_motion(fig, 20, 30.0, seed=3)
    cam = side_camera(q, 45.0)
    tracks = project_tracks(fig, q, cam, fps=30.0, noise_px=0.5, seed=4)
    setup = build_problem(fig, tracks, cam, calibrate="none")
    real = contact.solve
    res = real(setup.problem, setup.q0, active=setup.active, g0=setup.g0)
    given = []
    monkeypatch.setattr(contact, "solve", lambda p, x, options, *a, **k: given.append(options) or real(p, x, options, *a, **k))
    options = pr.SolverOptions(max_iterations=50)
    low = float(fig.keypoints(q)[:, fig.keypoint_index(["left_ankle", "right_ankle"]), 1].min())
    settings = ContactSettings(rounds=3, refine_iterations=2)
    contact.solve_on_the_floor(setup.problem, res, f"y={low - 0.07}", {"left_ankle": [[2, 8]]}, settings=settings,
                               options=options)
    assert [o.max_iterations for o in given] == [2, 2, 50]


# ----------------------------------------------------------------------------- the pipeline
@pytest.fixture(scope="module")
def walk_on_the_floor():
    """The bundled walk at 30 fps, its own skeleton, 22 body points with 1 px noise,
    keyframes every 8 frames: without and with the floor and contact rows."""
    from pinrecon.synthetic import (
        body_keypoints,
        bundled_motion,
        point_keyframes,
        project_tracks,
        side_camera,
    )

    fig, q, fps = bundled_motion("walk")
    q, fps = q[::4], fps / 4
    names = body_keypoints(fig)
    cam = side_camera(q, 45.0)
    tracks = project_tracks(fig, q, cam, names, fps=fps, noise_px=1.0, seed=1)
    keys = point_keyframes(fig, q, range(0, len(q), 8), names, sigma_m=0.02, seed=2)
    base = pr.reconstruct(fig, tracks, cam, keys)
    feet = pr.reconstruct(fig, tracks, cam, keys, floor="auto", contact="auto")
    return fig, q, fps, names, base, feet


def test_reconstruct_with_the_floor_keeps_the_feet_still(walk_on_the_floor, tmp_path):
    fig, q, fps, names, base, res = walk_on_the_floor
    m = res.foot_metrics()
    assert m is not None and m["contact_frames"] > 0.2 * len(q)
    assert m["skating_mps"] < 0.02 and m["penetration_max_m"] < 0.01
    # the same contact frames in the reconstruction without the rows slide far more
    from pinrecon.contact import FootContact

    feet = FootContact.from_extras(res.extras)
    P0 = base.keypoints3d[:, fig.keypoint_index(feet.names)]
    m0 = foot_metrics(P0, feet.floor, feet.contact, fps)
    assert m0["skating_mps"] > 3 * m["skating_mps"]
    # the floor found under the walk is the clip's (Y up, the CMU floor within 2 degrees)
    assert feet.floor.n[1] > np.cos(np.radians(2.0))
    text = res.summary()
    assert "floor:" in text and "skating" in text
    res.save(tmp_path / "r.npz")
    back = pr.load_result(tmp_path / "r.npz")
    assert back.foot_metrics() == pytest.approx(m)
    assert "skating" in back.summary()


def test_reconstruct_default_has_no_floor(walk_on_the_floor):
    *_, base, _ = walk_on_the_floor
    assert base.foot_metrics() is None and "floor:" not in base.summary()


def test_reconstruct_with_a_given_floor_and_contacts():
    from pinrecon.synthetic import project_tracks, side_camera

    fig = pr.Figure.human()
    q = smooth_motion(fig, 12, 30.0, seed=3)
    cam = side_camera(q, 45.0)
    tracks = project_tracks(fig, q, cam, fps=30.0, noise_px=0.5, seed=4)
    low = float(fig.keypoints(q)[:, fig.keypoint_index(["left_ankle", "right_ankle"]), 1].min())
    res = pr.reconstruct(fig, tracks, cam, floor=f"y={low - 0.07}", contact={"left_ankle": [[2, 5]]})
    feet = pr.contact.FootContact.from_extras(res.extras)
    assert feet.floor.offset_m == pytest.approx(low - 0.07)
    assert feet.contact[:, feet.names.index("left_ankle")].sum() == 4
    P = res.keypoints3d[2:6, fig.keypoint_index(["left_ankle"])[0]]
    assert np.linalg.norm(np.diff(P[:, [0, 2]], axis=0), axis=1).max() < 0.002
    with pytest.raises(InputError, match="floor"):
        pr.reconstruct(fig, tracks, cam, floor="sideways")


# ----------------------------------------------------------------------------- softened no-sliding rows, trimmed contacts
def test_contact_velocity_rows_soften_where_the_point_is_seen_to_move():
    from pinrecon.contact import FootContact, contact_rows

    fig = pr.Figure.human()
    names = ["left_ankle", "right_ankle"]
    C = np.array([[1, 1], [1, 1], [1, 0], [0, 0]], bool)
    seen = np.array([[0.00, 0.30], [0.10, 0.30], [0.30, 0.30], [0.30, 0.30]])  # m/s
    feet = FootContact(Floor((0.0, 1.0, 0.0), 0.0), names, C, np.zeros(2), np.zeros(2),
                       extra={"seen_speed_mps": seen})
    s = ContactSettings(sigma_velocity_mps=0.02, velocity_slack=1.0, slack_from_mps=0.05, lift_s=0.0)
    vel = [r for r in contact_rows(fig, feet, 50.0, s) if isinstance(r, ContactVelocity)][0]
    # pairs (0,1) and (1,2); by hand: mean seen speed of the pair, 5 cm/s free, then added in quadrature
    # left (0,1): 0.05 -> sigma 0.02; left (1,2): 0.20 -> sqrt(0.02^2 + 0.15^2); right (0,1): 0.30 -> sqrt(0.02^2 + 0.25^2)
    expect = 50.0 / np.array([[0.02, np.hypot(0.02, 0.25)], [np.hypot(0.02, 0.15), np.inf]])  # right: no contact at 2
    np.testing.assert_allclose(vel.frames, [[0, 1], [1, 2]])
    np.testing.assert_allclose(vel.sqrt_w, expect, rtol=1e-12)
    # velocity_slack = 0: the uniform pin of sigma_velocity_mps
    s0 = ContactSettings(sigma_velocity_mps=0.02, velocity_slack=0.0, lift_s=0.0)
    vel0 = [r for r in contact_rows(fig, feet, 50.0, s0) if isinstance(r, ContactVelocity)][0]
    np.testing.assert_allclose(vel0.sqrt_w, [[2500.0, 2500.0], [2500.0, 0.0]])
    # lift_s = 20 ms (one frame at 50 fps): each detected contact's rows go on one frame after it
    # ends (left to frame 3, right to frame 2), softened the same way: the seen speed there is 0.30
    s1 = ContactSettings(sigma_velocity_mps=0.02, velocity_slack=1.0, slack_from_mps=0.05, lift_s=0.02)
    vel1 = [r for r in contact_rows(fig, feet, 50.0, s1) if isinstance(r, ContactVelocity)][0]
    np.testing.assert_allclose(vel1.frames, [[0, 1], [1, 2], [2, 3]])
    late = 50.0 / np.hypot(0.02, 0.25)
    np.testing.assert_allclose(vel1.sqrt_w, np.vstack([expect[:1], [expect[1, 0], late], [late, 0.0]]), rtol=1e-12)
    # contacts given by the user are held as given (no seen speed: no lift)
    given = FootContact(Floor((0.0, 1.0, 0.0), 0.0), names, C, np.zeros(2), np.zeros(2))
    vel2 = [r for r in contact_rows(fig, given, 50.0, s1) if isinstance(r, ContactVelocity)][0]
    np.testing.assert_allclose(vel2.frames, [[0, 1], [1, 2]])


def test_contact_detection_trim_shortens_each_contact_at_both_ends():
    P, C, n, d, fps = stepping_clip()
    fl = Floor(tuple(n), d)
    full = detect_contacts(P, fl, fps)
    trimmed = detect_contacts(P, fl, fps, ContactSettings(trim_s=2.0 / fps))
    T = len(P)
    for j in range(C.shape[1]):
        runs_full = np.flatnonzero(np.diff(np.r_[0, full[:, j].astype(int), 0]))
        runs_trim = np.flatnonzero(np.diff(np.r_[0, trimmed[:, j].astype(int), 0]))
        a_full, b_full = runs_full[::2], runs_full[1::2]
        a_trim, b_trim = runs_trim[::2], runs_trim[1::2]
        assert len(a_full) == len(a_trim)
        # 2 frames off each end, except at the clip's own first and last frame
        np.testing.assert_array_equal(a_trim, np.where(a_full > 0, a_full + 2, a_full))
        np.testing.assert_array_equal(b_trim, np.where(b_full < T, b_full - 2, b_full))
    assert not (trimmed & ~full).any()
    # still within the true stances (3 frames of slack either side of a switch)
    assert (trimmed & ~C).sum() <= 3 * 2 * C.shape[1] * 4


# ----------------------------------------------------------------------------- the feet stage holds the first solve
COCO12_FROM_CMU = {
    "left_shoulder": "LeftArm", "right_shoulder": "RightArm", "left_elbow": "LeftForeArm",
    "right_elbow": "RightForeArm", "left_wrist": "LeftHand", "right_wrist": "RightHand",
    "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "left_knee": "LeftLeg", "right_knee": "RightLeg",
    "left_ankle": "LeftFoot", "right_ankle": "RightFoot",
}


@pytest.fixture(scope="module")
def generic_walk():
    """The bundled walk at 60 fps seen as the generic human's 12 COCO-17 points (1 px),
    orthographic 45 degrees from side-on, 3D keyframes on the first and last frame only:
    depth between them is all but unobserved, where contact rows alone used to move the
    whole figure (83.8 -> 112.3 mm)."""
    from pinrecon.synthetic import bundled_motion, side_camera

    cfig, q, fps = bundled_motion("walk")
    q, fps = q[::2], fps / 2
    cam = side_camera(q, 45.0)
    names = list(COCO12_FROM_CMU)
    truth = cfig.keypoints(q)[:, cfig.keypoint_index([COCO12_FROM_CMU[n] for n in names])]
    rng = np.random.default_rng(3)
    tracks = pr.Tracks(cam.project(truth) + rng.normal(0.0, 1.0, truth.shape[:2] + (2,)), names, fps)
    keys = pr.tracks.keyframes_from_points([0, len(q) - 1], truth + rng.normal(0.0, 0.02, truth.shape), names, 0.02)
    fig = pr.Figure.human()
    base = pr.reconstruct(fig, tracks, cam, keys, floor="none")
    feet = pr.reconstruct(fig, tracks, cam, keys)  # the human's default: floor and contacts "auto"
    return fig, names, truth, fps, base, feet


# slow (~15 s of CPU, its two solves): the feet stage's contacts and floor are tested on the
# walk's own figure above; .ci/run runs it on the generic human
@pytest.mark.slow
def test_feet_stage_refines_the_first_solve_on_the_generic_figure(generic_walk):
    fig, names, truth, _, base, res = generic_walk
    idx = fig.keypoint_index(names)

    def mpjpe(r):
        return 1000 * np.linalg.norm(r.keypoints3d[:, idx] - truth, axis=-1).mean()

    # no worse than without the rows (83.8 mm; 112.3 mm when the rows could move the whole figure)
    assert mpjpe(res) <= mpjpe(base) + 0.5
    m = res.foot_metrics()
    assert m["contact_frames"] > 0.5 * len(truth) and m["skating_mps"] < 0.02
    # the held points stay near the first solve (hold_m = 10 cm), the legs (knees, ankles) move
    held = fig.keypoint_index([n for n in names if "ankle" not in n and "knee" not in n])
    moved = np.linalg.norm(res.keypoints3d[:, held] - base.keypoints3d[:, held], axis=-1)
    assert np.median(moved) < 0.03
    assert "hold" in res.solve.costs
    assert base.foot_metrics() is None and "floor:" not in base.summary()  # floor="none": off


def test_feet_stage_is_the_generic_humans_default():
    from pinrecon.reconstruct import default_feet

    fig = pr.Figure.human()
    one = pr.Tracks(np.zeros((3, 2, 2)), ["left_hip", "left_ankle"], 30.0)
    arms = pr.Tracks(np.zeros((3, 2, 2)), ["left_shoulder", "left_wrist"], 30.0)
    assert default_feet(fig, one) and default_feet(fig, [arms, one])
    assert not default_feet(fig, arms) and not default_feet(fig, one, keypoints=["left_hip"])
    hip_only = np.concatenate([np.zeros((3, 1, 2)), np.full((3, 1, 2), np.nan)], axis=1)
    unseen = pr.Tracks(hip_only, ["left_hip", "left_ankle"], 30.0)
    assert not default_feet(fig, unseen)  # an ankle never seen: no contact to detect
    walker = bundled_motion("walk")[0]  # a BVH skeleton: not by default
    assert not default_feet(walker, pr.Tracks(np.zeros((3, 1, 2)), ["LeftFoot"], 30.0))
    with pytest.raises(InputError, match="contacts need a floor") as e:
        pr.reconstruct(fig, one, side_camera(np.tile(fig.neutral(), (3, 1)), 45.0), floor="none", contact="auto")
    assert e.value.field == "contact"


def test_leg_points_are_the_knees():
    from pinrecon.contact import leg_points

    fig = pr.Figure.human()
    assert leg_points(fig, ["left_ankle", "right_ankle"]) == ["left_knee", "right_knee"]
    names = ["left_hip", "left_knee", "left_ankle", "left_shoulder", "left_wrist"]
    assert leg_points(fig, ["left_ankle"], names) == ["left_knee"]
    assert leg_points(fig, ["left_ankle"], ["left_hip", "left_shoulder"]) == []
    walker = bundled_motion("walk")[0]
    assert leg_points(walker, foot_keypoints(walker)) == ["LeftLeg", "RightLeg"]


def test_hold_rows_by_hand():
    from pinrecon.contact import hold_rows
    from pinrecon.problem import make_problem
    from pinrecon.synthetic import project_tracks, side_camera

    fig = pr.Figure.human()
    q = smooth_motion(fig, 6, 30.0, seed=5)
    cam = side_camera(q, 45.0)
    names = ["left_hip", "left_knee", "left_ankle", "right_hip"]
    problem = make_problem(fig, project_tracks(fig, q, cam, names, fps=30.0), cam)
    (row,) = hold_rows(problem, q, None, ["left_ankle"], 0.05)
    np.testing.assert_array_equal(row.keypoints, fig.keypoint_index(["left_hip", "left_knee", "right_hip"]))
    rng = np.random.default_rng(6)
    Q = np.stack([fig.integrate(x, 0.05 * rng.normal(size=fig.nv)) for x in q])
    r = row.evaluate(State(fig, Q, np.arange(len(Q)), False), jacobian=False).r
    P, P0 = fig.keypoints(Q)[:, row.keypoints], fig.keypoints(q)[:, row.keypoints]
    np.testing.assert_allclose(np.asarray(r).reshape(-1), ((P - P0) / 0.05).reshape(-1), atol=1e-9)
    assert hold_rows(problem, q, None, names, 0.05) == []


# ----------------------------------------------------------------------------- ankles only: a raised heel is still a contact
def test_ankle_only_feet_detect_a_raised_heel_stance():
    from pinrecon.contact import detection_settings

    s = ContactSettings()
    assert detection_settings(["left_toe", "left_ankle"], s) is s
    a = detection_settings(["left_ankle", "right_ankle"], s)
    assert (a.height_on_m, a.height_off_m) == pytest.approx((s.height_on_m + 0.05, s.height_off_m + 0.05))
    # an ankle (built here): 0.5 s flat on the floor at 7 cm, 0.5 s still on the ball of the
    # foot (heel raised: the ankle 6 cm higher, reached in 0.1 s), 0.5 s of swing at 1 m/s
    fps = 60.0
    t = np.arange(int(1.5 * fps)) / fps
    y = 0.07 + 0.06 * np.clip((t - 0.5) / 0.1, 0.0, 1.0)
    x = np.where(t > 1.0, t - 1.0, 0.0)
    P = np.stack([x, y, np.zeros_like(t)], axis=1)[:, None]
    fl = Floor((0.0, 1.0, 0.0), 0.0)
    raised = (t >= 0.65) & (t <= 0.95)  # the rise itself (0.6 m/s) and the push-off are not still
    assert not detect_contacts(P, fl, fps, s)[raised, 0].any()  # toe thresholds: heel up = in the air
    found = detect_contacts(P, fl, fps, a)[:, 0]
    assert found[raised].all() and found[t < 0.5].all()
    assert not found[t > 1.1].any()


def test_contact_velocity_rows_start_land_s_before_each_detected_contact():
    from pinrecon.contact import FootContact, contact_rows

    fig = pr.Figure.human()
    C = np.zeros((6, 2), bool)
    C[3:, 0] = True  # left ankle planted from frame 3
    seen = np.zeros((6, 2))
    feet = FootContact(Floor((0.0, 1.0, 0.0), 0.0), ["left_ankle", "right_ankle"], C, np.zeros(2), np.zeros(2),
                       extra={"seen_speed_mps": seen})
    for land_s, first in ((0.0, 3), (0.02, 2), (0.04, 1)):  # 50 fps: 0, 1 and 2 frames before
        s = ContactSettings(lift_s=0.0, land_s=land_s)
        vel = next(r for r in contact_rows(fig, feet, 50.0, s) if isinstance(r, ContactVelocity))
        assert vel.frames[0][0] == first and vel.frames[-1][1] == 5
