"""Seeding from planarity: segment lengths, calibration, scale, the seed trajectory,
the flip metric and the links report.

Ground truth comes from the bundled CMU clips themselves (the figure built from the
clip's skeleton and its recorded motion), never from the code under test.
"""

from __future__ import annotations

import re

import numpy as np
import pinocchio as pin
import pytest

import pinrecon as pr
from pinrecon.planarity import (
    RelativeDepth,
    calibrate_figure,
    estimate_scale,
    limb_flip_rate,
    links_report,
    seed_trajectory,
    segment_lengths,
)
from pinrecon.synthetic import body_keypoints, bundled_motion, point_keyframes, project_tracks

LIMBS = [
    (s + a, s + b)
    for s in ("Left", "Right")
    for a, b in (("UpLeg", "Leg"), ("Leg", "Foot"), ("Arm", "ForeArm"), ("ForeArm", "Hand"))
]


def _camera(az_deg=45.0, scale=300.0):
    az = np.radians(az_deg)
    return pr.Orthographic.from_view([np.cos(az), 0.0, np.sin(az)], scale=scale, center=(500.0, 500.0))


@pytest.fixture(scope="module")
def walk_clip():
    fig, q, fps = bundled_motion("walk")
    return fig, q, fps, body_keypoints(fig)


@pytest.fixture(scope="module")
def walk_tracks(walk_clip):
    fig, q, fps, names = walk_clip
    cam = _camera()
    return cam, project_tracks(fig, q, cam, names, fps=fps, noise_px=1.0, seed=0)


def _true_length(fig, q, a, b):
    """Segment length from the recorded motion (mean over frames; rigid, so constant)."""
    P = fig.keypoints(q[::20])
    i, j = fig.keypoint_index([a, b])
    return float(np.linalg.norm(P[:, j] - P[:, i], axis=-1).mean())


# ---------------------------------------------------------------- lengths
def test_segment_lengths_walk_px_and_m(walk_clip, walk_tracks):
    fig, q, _, _ = walk_clip
    cam, tracks = walk_tracks
    L = segment_lengths(tracks, fig, camera=cam)
    for a, b in LIMBS:
        it = L[(a, b)]
        assert it.method == "limb" and it.reliable, it
        true_m = _true_length(fig, q, a, b)
        assert it.length_m == pytest.approx(true_m, rel=0.03), (a, b)
        assert it.length == pytest.approx(true_m * cam.scale, rel=0.03), (a, b)
    # every segment of the tree is reported, with a grade
    assert {it.method for it in L} <= {"limb", "short", "triple", "projected"}
    assert "LeftUpLeg" in L.summary()


def test_segment_lengths_without_figure_and_scale(walk_clip, walk_tracks):
    _, q, _, _ = walk_clip
    _, tracks = walk_tracks
    segs = [("LeftUpLeg", "LeftLeg"), ("LeftLeg", "LeftFoot")]
    L = segment_lengths(tracks, segments=segs)
    assert L[segs[0]].method == "limb" and np.isnan(L[segs[0]].length_m)
    fig = walk_clip[0]
    assert L[segs[1]].length == pytest.approx(300.0 * _true_length(fig, q, *segs[1]), rel=0.03)


def test_calibrate_wrongly_scaled_figure(walk_clip, walk_tracks, tmp_path):
    fig, q, _, names = walk_clip
    cam, tracks = walk_tracks
    wrong = fig.rescaled(1.1)
    cal = calibrate_figure(wrong, tracks, camera=cam)
    assert cal.global_scale == pytest.approx(1 / 1.1, rel=0.03)
    P = cal.figure.keypoints(cal.figure.neutral())
    segs = LIMBS + [("Hips", "Spine"), ("Spine1", "Neck1"), ("Spine1", "LeftArm")]
    for a, b in segs:
        i, j = cal.figure.keypoint_index([a, b])
        assert np.linalg.norm(P[j] - P[i]) == pytest.approx(_true_length(fig, q, a, b), rel=0.03), (a, b)
    path = tmp_path / "calibrated.urdf"
    cal.save_urdf(path)
    back = pr.Figure.from_urdf(path, cal.figure.keypoints_def)
    assert back.nq == fig.nq
    np.testing.assert_allclose(back.keypoints(back.neutral()), P, atol=1e-8)


def test_calibrate_needs_a_scale(walk_clip, walk_tracks):
    fig = walk_clip[0]
    _, tracks = walk_tracks
    with pytest.raises(pr.InputError, match="scale"):
        calibrate_figure(fig, tracks)


@pytest.mark.parametrize("scale", [300.0, 180.0])
def test_estimate_scale_known_figure(walk_clip, scale):
    fig, q, fps, names = walk_clip
    cam = _camera(40.0, scale)
    tracks = project_tracks(fig, q, cam, names, fps=fps, noise_px=1.0, seed=1)
    est = estimate_scale(fig, tracks)
    assert est.scale == pytest.approx(scale, rel=0.03)
    assert est.n_segments >= 6


# ---------------------------------------------------------------- seed
@pytest.fixture(scope="module")
def walk_seed(walk_clip):
    """The walk at 60 fps (every other frame, to keep the test short), 45 deg from
    side-on, keyframes on the first and last frame only."""
    fig, q, fps, names = walk_clip
    q = q[::2]
    cam = _camera()
    tracks = project_tracks(fig, q, cam, names, fps=fps / 2, noise_px=1.0, seed=0)
    kf = point_keyframes(fig, q, [0, len(q) - 1], names, sigma_m=0.02)
    sd = seed_trajectory(fig, tracks, cam, kf)
    return fig, q, cam, tracks, kf, sd


def test_seed_lowers_flip_rate_against_default_start(walk_seed):
    fig, q, cam, tracks, kf, sd = walk_seed
    # the keyframe start (sparse keyframes' default before the multi-hypothesis start, which
    # weighs this seed itself): a solve with no iteration returns it unchanged
    start = pr.reconstruct(fig, tracks, cam, kf, seed="keyframes", options=pr.SolverOptions(max_iterations=0)).q
    flip_start = limb_flip_rate(fig, start, q, cam, LIMBS)
    flip_seed = limb_flip_rate(fig, sd.q, q, cam, LIMBS)
    assert flip_seed < 0.5 * flip_start, (flip_seed, flip_start)
    assert flip_seed < 0.08
    # every leg and arm was lifted, each with one reflection for its whole span
    lifted = {lf.triple[1] for lf in sd.lifts}
    assert {"LeftLeg", "RightLeg", "LeftForeArm", "RightForeArm"} <= lifted
    assert sd.q.shape == q.shape
    # root-relative pose error drops too
    idx = fig.keypoint_index(body_keypoints(fig))
    P = fig.keypoints(q)[:, idx]

    def rel_err(Q):
        Pe = fig.keypoints(Q)[:, idx]
        return np.linalg.norm((Pe - Pe[:, :1]) - (P - P[:, :1]), axis=-1).mean()

    assert rel_err(sd.q) < 0.6 * rel_err(start)


def test_lift_depth_signs_match_truth(walk_seed):
    fig, q, cam, _, _, sd = walk_seed
    Z = cam.depth(fig.keypoints(q))
    for lf in sd.lifts:
        a, j, b = fig.keypoint_index(list(lf.triple))
        fr = lf.frames
        for k, end in enumerate((a, b)):
            dz_true = Z[fr, end] - Z[fr, j]
            assert np.sum(lf.depths_m[fr, k] * dz_true) > 0, lf


def test_reconstruct_with_planarity_seed_and_fps_out():
    fig, q, fps = bundled_motion("run")
    names = body_keypoints(fig)
    q = q[:60:3]
    cam = _camera(35.0)
    tracks = project_tracks(fig, q, cam, names, fps=fps / 3, noise_px=1.0, seed=2)
    kf = point_keyframes(fig, q, [0, len(q) - 1], names, sigma_m=0.02)
    res = pr.reconstruct(
        fig, tracks, cam, kf, seed="planarity", fps_out=fps / 3 * 2, options=pr.SolverOptions(max_iterations=3)
    )
    assert res.q.shape == (2 * len(q) - 1, fig.nq)
    assert np.all(np.isfinite(res.q))


def test_relative_depth_jacobian_matches_finite_differences(walk_clip):
    from pinrecon.problem import ReconstructionProblem

    fig = walk_clip[0]
    cam = _camera(30.0)
    rng = np.random.default_rng(0)
    Q = np.stack([fig.random_configuration(s, unlimited=1.0) for s in (0, 1)])
    a, b = fig.keypoint_index(["LeftLeg", "LeftFoot"])
    row = RelativeDepth(cam, [0, 1, 1], [a, a, b], [b, b, a], [0.1, -0.2, 0.05], 0.03)
    prob = ReconstructionProblem(fig, 2, [row])
    blk = prob.evaluate(Q)[0]
    eps = 1e-6
    for t in (0, 1):
        v = rng.normal(size=fig.nv)
        Qp, Qm = Q.copy(), Q.copy()
        Qp[t] = pin.integrate(fig.model, Q[t], eps * v)
        Qm[t] = pin.integrate(fig.model, Q[t], -eps * v)
        fd = (prob.evaluate(Qp, False)[0].r - prob.evaluate(Qm, False)[0].r)[:, 0] / (2 * eps)
        an = np.array([blk.J[n, 0, 0] @ v if blk.frames[n, 0] == t else 0.0 for n in range(3)])
        np.testing.assert_allclose(an, fd, atol=1e-6)


def test_limb_flip_rate_counts(walk_clip):
    fig, q, _, _ = walk_clip
    cam = _camera()
    q = q[::10]
    assert limb_flip_rate(fig, q, q, cam, LIMBS) == 0.0
    rate, per = limb_flip_rate(fig, q, q, cam, LIMBS, per_limb=True)
    assert set(per) == set(LIMBS) and all(f == 0 and n > 0 for f, n in per.values())
    # holding the first pose flips a limb whenever its true depth sign changes
    held = np.repeat(q[:1], len(q), axis=0)
    assert 0.1 < limb_flip_rate(fig, held, q, cam, LIMBS) < 0.9
    with pytest.raises(pr.InputError):
        limb_flip_rate(fig, q[:3], q, cam, LIMBS)


# ---------------------------------------------------------------- links report
def test_links_report_names_hinges_and_lengths(walk_clip, walk_tracks):
    fig, q, _, _ = walk_clip
    cam, tracks = walk_tracks
    legs = ["LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot"]
    text = links_report(tracks, scale=cam.scale, names=legs)
    for side in ("Left", "Right"):
        m = re.search(
            rf"{side}UpLeg -\[{side}Leg\]- {side}Foot: \|{side}Leg-{side}UpLeg\| ([\d.]+) px \(([\d.]+) m\), "
            rf"\|{side}Leg-{side}Foot\| ([\d.]+) px \(([\d.]+) m\), normal \(",
            text,
        )
        assert m, text
        thigh = _true_length(fig, q, side + "UpLeg", side + "Leg")
        shank = _true_length(fig, q, side + "Leg", side + "Foot")
        assert float(m.group(2)) == pytest.approx(thigh, rel=0.03)
        assert float(m.group(4)) == pytest.approx(shank, rel=0.03)
        assert float(m.group(1)) == pytest.approx(300.0 * thigh, rel=0.03)
    assert "links:" in text and "tilt" in text
    plain = links_report(tracks, names=legs[:3])
    assert " m)" not in plain and "-[LeftLeg]-" in plain
