"""How well the tracks fix the auto camera's focal length (issue 12): the MAP cost profile
over the focal length, its interval, and the warning when the tracks do not fix it.

Ground truth: a cost profile written out here as a parabola in log f (its 95 % interval in
closed form), and the true focal length of the camera that made the synthetic tracks.
Measured on the CMU walk (bench/bench_camera_auto.py): with the human's correlated pose
prior the cost profile is a valley (about 18 nats deep at +-30 %) near the true focal length,
but Gauss-Newton stops part-way down it; the solve is carried to its bottom
(``settle_focal``): 1106 / 1106 / 1041 px from the default and from starts 30 % off. On the
synthetic walk below it ends near 900 px from every start (18 % short, the lengths
calibrated with it), and the report says "not determined" rather than claim a value.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import pinrecon as pr
from pinrecon.starts.camera_auto import (
    AutoCamera,
    FocalLengthWarning,
    profile_interval,
    stretch_depth,
)
from pinrecon.synthetic import human_walk, perspective_side_camera, project_tracks

F_TRUE, SIZE = 1100.0, (1280.0, 720.0)
BODY = ["left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
        "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle"]


def _parabola(f_fit, a, steps=(0.1, 0.3, 0.6)):
    d = np.r_[0.0, steps, -np.asarray(steps)]
    return [(f_fit * np.exp(x), 500.0 + a * x * x) for x in d]


def test_profile_interval_of_a_valley_is_its_closed_form():
    # cost = c0 + a (log f/f*)^2 crosses c0 + 1.92 at log f/f* = +-sqrt(1.92 / a)
    a = 400.0
    (lo, hi), bounded, det = profile_interval(_parabola(1000.0, a), 1000.0)
    assert det and bounded == (True, True)
    half = np.sqrt(1.92 / a)
    assert (lo, hi) == pytest.approx((1000.0 * np.exp(-half), 1000.0 * np.exp(half)), rel=1e-9)


def test_flat_skewed_or_jumping_profiles_rule_nothing_out():
    tested = (1000.0 * np.exp(-0.6), 1000.0 * np.exp(0.6))
    for pts in (
        _parabola(1000.0, 100.0),  # rises only 1 over +-0.1: too shallow to fix f within 10 %
        [(f, 500.0 - 20.0 * np.log(f / 1000.0)) for f, _ in _parabola(1000.0, 1.0)],  # keeps falling
        [(f, c - (40.0 if abs(np.log(f / 1000.0) - 0.3) < 1e-9 else 0.0)) for f, c in _parabola(1000.0, 400.0)],
    ):
        (lo, hi), bounded, det = profile_interval(pts, 1000.0)
        assert not det and bounded == (False, False)
        assert (lo, hi) == pytest.approx(tested)


def teststretch_depth_keeps_the_image_of_the_root():
    cam = pr.Perspective.look_at([3.0, 1.4, -5.0], [0.2, 0.9, 0.3], f_px=F_TRUE, center=(640.0, 360.0))
    _fig, Q = human_walk(10, 30.0)
    Qs = stretch_depth(Q, cam, 1.3)
    K = np.array(cam.K, float)
    K[:2, :2] *= 1.3  # the focal block only: the principal point stays
    longer = pr.Perspective(K, cam.R, cam.t)
    np.testing.assert_allclose(longer.project(Qs[:, :3]), cam.project(Q[:, :3]), atol=1e-9)
    np.testing.assert_allclose(Qs[:, 3:], Q[:, 3:])


@pytest.fixture(scope="module")
def short_walk():
    """Two seconds of walking on the generic human (its own proportions: the figure is
    exact), 30 fps, towards the camera 60 degrees from side-on, 3.5 m away (the root's
    depth goes from 2.5 to 4.5 m), f = 1100 px, 1 px noise."""
    fig, Q = human_walk(60, 30.0)
    cam = perspective_side_camera(Q, 60.0, distance_m=3.5, f_px=F_TRUE, center=(640.0, 360.0))
    return project_tracks(fig, Q, cam, BODY, fps=30.0, noise_px=1.0, seed=3)


@pytest.fixture(scope="module")
def focal_inputs(short_walk):
    """What the focal stage is given (problem, solution, auto camera) on the short walk from
    a start 30 % long, its solve stopped part-way down the valley (4 iterations): observed
    by replacing ``settle_focal`` for the one call. The stages that cannot move the focal
    length's inputs here (turns, mirrors, faults, feet) are skipped."""
    from pinrecon import stages

    seen = {}
    fov = float(np.degrees(2.0 * np.arctan(SIZE[0] / 2.0 / (1.3 * F_TRUE))))
    with pytest.MonkeyPatch.context() as mp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mp.setattr(stages, "settle_focal", lambda problem, res, auto, **kw: seen.update(
            problem=problem, res=res, auto=auto) or (res, auto))
        pr.reconstruct(pr.Figure.human(), short_walk, AutoCamera(SIZE, fov_deg=fov),
                       skip=["turns", "mirrors", "faults", "feet"], options=pr.SolverOptions(max_iterations=4))
    return seen["problem"], seen["res"], seen["auto"]


@pytest.mark.parametrize("k", [pytest.param(0.7, marks=pytest.mark.slow), 1.3])  # 11 s each: the short start in CI
def test_focal_from_a_start_30_percent_off_is_found_or_said_to_be_unknown(short_walk, k):
    """The issue's target is recovery within 10 % of the true focal length from a start
    30 % off. Measured here it is not: from 770 px and from 1430 px the solve ends near
    900 px, with the exact figure and 1 px noise. The contract tested: the solve ends at
    the bottom of its own profile (no profiled focal length more than 0.5 nats lower),
    and the fitted focal is within 10 % of the truth, or the report says it is not
    determined (with a FocalLengthWarning), and then its interval of what is not ruled
    out contains the truth."""
    fov = float(np.degrees(2.0 * np.arctan(SIZE[0] / 2.0 / (k * F_TRUE))))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = pr.reconstruct(pr.Figure.human(), short_walk, AutoCamera(SIZE, fov_deg=fov))
    rep = res.calibration["camera_auto"]["focal"]
    fitted = res.calibration["cameras"]["camera1"]["fitted"]
    assert rep["focal_px"] == pytest.approx(fitted) and rep["start_px"] == pytest.approx(k * F_TRUE)
    cost_at = {round(f, 6): c for f, c in rep["profile"]}
    assert min(cost_at.values()) >= cost_at[round(fitted, 6)] - 0.5  # settled at the profile's bottom
    warned = [w for w in caught if issubclass(w.category, FocalLengthWarning)]
    if abs(fitted / F_TRUE - 1.0) <= 0.10:
        return
    assert not rep["determined"] and warned and "NOT determined" in str(warned[0].message)
    lo, hi = rep["interval_px"]
    assert lo <= F_TRUE <= hi


def test_the_last_move_may_report_from_the_profile_already_solved(focal_inputs, monkeypatch):
    """``settle_focal(final_profile=False)`` (the cue path's focal stage): the same move, and a
    report made from the first profile's points and the moved solve instead of six more
    solves. Ground truth: the same call with the profile solved again (the moved solutions
    equal), and the points the first profile printed."""
    from pinrecon import solver
    from pinrecon.starts.camera_auto import settle_focal

    problem, res0, auto = focal_inputs
    calls, real = [], solver.solve
    monkeypatch.setattr(solver, "solve", lambda *a, **k: calls.append(1) or real(*a, **k))
    monkeypatch.setattr("pinrecon.starts.camera_auto.forkable", lambda *a: False)  # every solve here, where it is counted
    out = {}
    for final in (True, False):
        calls.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            first = settle_focal(problem, res0, auto, rounds=0)[1]["focal"]
            n_first = len(calls)
            res, a = settle_focal(problem, res0, auto, rounds=1, final_profile=final)
        out[final] = res, a["focal"], len(calls) - n_first
    assert n_first == 6
    (res_t, rep_t, n_t), (res_f, rep_f, n_f) = out[True], out[False]
    assert res_f is not res0  # it moved
    np.testing.assert_array_equal(res_f.x, res_t.x)
    assert (n_t, n_f) == (6 + 1 + 6, 6 + 1)
    assert rep_f["focal_px"] == pytest.approx(rep_t["focal_px"])
    want = sorted([(rep_t["focal_px"], float(res_t.cost)), *map(tuple, first["profile"])])
    np.testing.assert_allclose(sorted(map(tuple, rep_f["profile"])), want, rtol=1e-9)
    assert len(rep_t["profile"]) == 7 and len(rep_f["profile"]) == 8


def test_a_profile_that_is_no_valley_moves_the_focal_length_only_within_the_range(short_walk, monkeypatch):
    """``settle_focal(undetermined_range=(lo, hi))``: a profile falling all the way to its longest
    focal length (no valley: nothing determined) moves the solve only to its lowest point inside
    the range, and not at all when no point inside is lower than the fit. With lifted cues the
    focal stage passes ``stages.FOCAL_PLAUSIBLE`` times the image's diagonal (0.3 to 1.0: a wide
    angle to a normal lens). Ground truth: the profile written out here, its lowest point inside
    the range picked by hand."""
    from pinrecon import solver, stages
    from pinrecon.lifted import Lifted
    from pinrecon.starts import camera_auto

    seen = {}

    def observe(problem, res, auto, **kw):
        seen.update(problem=problem, res=res, auto=auto, kw=kw)
        return res, auto

    monkeypatch.setattr(stages, "settle_focal", observe)
    cued = short_walk.frames(0, short_walk.T)
    X = np.random.default_rng(0).normal(0.0, 0.3, (cued.T, len(cued.names), 3))  # cues: only the path they take
    cued.lifted = Lifted(X, list(cued.names), np.ones(X.shape[:2]), "camera", "test")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pr.reconstruct(pr.Figure.human(), cued, "auto", image_size=SIZE, skip=["feet"],
                       options=pr.SolverOptions(max_iterations=3))
    diagonal = float(np.hypot(*SIZE))
    assert seen["kw"]["undetermined_range"] == pytest.approx((0.3 * diagonal, 1.0 * diagonal))
    problem, res0, auto = seen["problem"], seen["res"], seen["auto"]
    f_fit = camera_auto.fitted_focal(problem, res0)
    g_fit = np.asarray(res0.g, float)
    marks = {}

    def profile(problem, res, steps, options):  # falling to the longest: no valley
        out = [(f_fit, float(res0.cost), np.asarray(res0.x), g_fit)]
        for k, f in enumerate((0.5, 0.8, 1.2, 1.5, 2.0, 3.0)):
            g = g_fit.copy()
            g[-1] += 1e-3 * (k + 1)  # a mark: which point a solve started from
            marks[float(g[-1])] = f * f_fit
            out.append((f * f_fit, float(res0.cost) + (5.0 if f < 1 else -10.0 * f), np.asarray(res0.x), g))
        return out

    starts = []
    monkeypatch.setattr(camera_auto, "_profile_solves", profile)
    monkeypatch.setattr(solver, "solve", lambda problem, x0, options=None, *a, g0=None, **k: starts.append(
        marks.get(float(np.asarray(g0)[-1]))) or res0)
    real_settle = camera_auto.settle_focal
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        real_settle(problem, res0, auto, rounds=1, final_profile=False, undetermined_range=(0.4 * f_fit, 1.6 * f_fit))
        assert starts == [pytest.approx(1.5 * f_fit)]  # the lowest inside: not 2.0 or 3.0 times the fit
        starts.clear()
        real_settle(problem, res0, auto, rounds=1, final_profile=False, undetermined_range=(0.4 * f_fit, 1.1 * f_fit))
        assert starts == []  # the points inside (0.5, 0.8) cost more than the fit: it stays
        real_settle(problem, res0, auto, rounds=1, final_profile=False)
        assert starts == [pytest.approx(3.0 * f_fit)]  # no range: the lowest of all


def test_the_longer_focal_lengths_are_profiled_beside_with_the_same_points(focal_inputs, monkeypatch):
    """Where a child can be forked, it solves the profile's longer focal lengths while this
    process solves the shorter ones: the same points to the last digit, three of the six solves
    here. Ground truth: the profile solved here alone."""
    from pinrecon import solver
    from pinrecon.starts.camera_auto import check_focal

    calls, real = [], solver.solve
    monkeypatch.setattr(solver, "solve", lambda *a, **k: calls.append(1) or real(*a, **k))
    out = {}
    for fork in (False, True):
        monkeypatch.setattr("pinrecon.starts.camera_auto.forkable", lambda *a, fork=fork: fork)
        calls.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out[fork] = check_focal(*focal_inputs)["focal"], len(calls)
    (here, n_here), (beside, n_beside) = out[False], out[True]
    assert (n_here, n_beside) == (6, 3)
    assert len(here["profile"]) == 7 and here["profile"] == beside["profile"]
    assert here["interval_px"] == beside["interval_px"]


# ----------------------------------------------------------------------------- keyframes place the camera
def _figure_cloud(frames, rng, noise_m):
    """The generic human's 12 body points at ``frames`` of a walk 6 m in front of a camera
    45 degrees from side-on (f = 1100 px), with ``noise_m`` of 3D noise on the world points
    (the keyframes') and none on the pixels (exact tracks): the truth is the camera."""
    fig, Q = human_walk(120, 30.0)
    cam = perspective_side_camera(Q, 45.0, distance_m=6.0, f_px=F_TRUE, center=(640.0, 360.0))
    P = fig.keypoints(Q[list(frames)])[:, fig.keypoint_index(BODY)].reshape(-1, 3)
    return cam, P + rng.normal(0.0, noise_m, P.shape), cam.project(P)


def test_keyframes_on_many_frames_fix_the_focal_length_and_two_frames_do_not():
    from pinrecon.starts.camera_auto import camera_from_keyframes, keyframe_focal_interval

    rng = np.random.default_rng(8)
    _, X, uv = _figure_cloud(range(0, 120, 8), rng, 0.02)  # 15 frames, 2 cm
    fit = camera_from_keyframes(X, uv, SIZE, 900.0)
    (lo, hi), bounded = keyframe_focal_interval(X, uv, fit)
    assert bounded == (True, True) and lo < F_TRUE < hi  # the truth is not ruled out
    assert fit.K[0, 0] / 1.1 < lo and hi < fit.K[0, 0] * 1.1  # and the rest is, within 10 %
    _, X, uv = _figure_cloud([0, 119], rng, 0.05)  # first and last frame, 5 cm
    fit = camera_from_keyframes(X, uv, SIZE, 900.0)
    (lo, hi), _ = keyframe_focal_interval(X, uv, fit)
    assert lo < F_TRUE < hi and (lo < fit.K[0, 0] / 1.1 or hi > fit.K[0, 0] * 1.1)


def test_a_camera_placed_by_two_keyframes_says_its_focal_length_is_not_determined():
    """Issue 10's detector walk with an unknown camera and keyframes on the first and last
    frame only. With the camera held where the two keyframes put it (before its pose became
    an unknown of the solve): 1464 px against a true 1200, the camera 4.45 m from the true
    one and MPJPE 367 mm in the clip's world. Now the tracks refine its place: 0.39 m and
    60 mm, 1170 px, and the report, from the solve's own profile (the pose re-solved at
    every focal length), says the focal length is not determined, and warns."""
    fig, Q = human_walk(60, 30.0)
    cam = perspective_side_camera(Q, 45.0, distance_m=6.0, f_px=F_TRUE, center=(640.0, 360.0))
    tracks = project_tracks(fig, Q, cam, BODY, fps=30.0, noise_px=1.0, seed=5)
    rng = np.random.default_rng(9)
    P = fig.keypoints(Q)[:, fig.keypoint_index(BODY)]
    keys = pr.tracks.keyframes_from_points([0, 59], P + rng.normal(0.0, 0.05, P.shape), BODY, 0.05)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = pr.reconstruct(pr.Figure.human(), tracks, AutoCamera(SIZE), keys, floor="none")
    rep = res.calibration["camera_auto"]["focal"]
    assert res.calibration["camera_auto"]["pose"] == "from the point keyframes, then refined by the solve with the tracks"
    assert rep["determined"] is False and "keyframes" not in rep
    lo, hi = rep["interval_px"]
    assert lo <= F_TRUE <= hi and hi / lo > 1.2
    warned = [w for w in caught if issubclass(w.category, FocalLengthWarning)]
    assert warned and "on more frames" in str(warned[0].message) and "NOT determined" in res.summary()
    centre = -res.camera.R.T @ res.camera.t
    assert np.linalg.norm(centre - (-cam.R.T @ cam.t)) < 0.6
    E = res.keypoints3d[:, res.figure.keypoint_index(BODY)]
    assert 1000 * np.linalg.norm(E - P, axis=-1).mean() < 80.0
    # keyframes on every 6th frame with 2 cm of noise fix it: determined, the truth inside
    keys = pr.tracks.keyframes_from_points(list(range(0, 60, 6)), P + rng.normal(0.0, 0.02, P.shape), BODY, 0.02)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct(pr.Figure.human(), tracks, AutoCamera(SIZE), keys, floor="none")
    rep = res.calibration["camera_auto"]["focal"]
    lo, hi = rep["interval_px"]
    assert rep["determined"] is True and lo <= F_TRUE <= hi and hi / lo < 1.15
    klo, khi = res.calibration["camera_auto"]["keyframe_focal"]["interval_px"]
    assert klo <= rep["focal_px"] <= khi and "keyframes" not in rep  # the fit within their own: no doubt
    E = res.keypoints3d[:, res.figure.keypoint_index(BODY)]
    assert 1000 * np.linalg.norm(E - P, axis=-1).mean() < 20.0


def test_a_focal_length_resting_on_an_unfamiliar_prior_is_doubted():
    from pinrecon.starts.camera_auto import doubt_focal

    rep = {"focal_px": 960.0, "interval_px": [927.0, 987.0], "determined": True, "message": "focal length 960 px"}
    auto = {"projection": "perspective", "focal": rep}
    assert doubt_focal(auto, 0.3) is auto and doubt_focal(None, 1.0) is None
    assert doubt_focal({**auto, "focal": {**rep, "keyframes": {"frames": 10}}}, 1.0)["focal"]["determined"] is True
    assert doubt_focal({**auto, "focal": {**rep, "determined": False}}, 1.0)["focal"]["message"] == rep["message"]
    with pytest.warns(FocalLengthWarning, match="80 % of the frames"):
        out = doubt_focal(auto, 0.8)
    assert out["focal"]["determined"] is False and out["focal"]["unfamiliar_share"] == 0.8
    assert rep["determined"] is True  # the input is not changed
    # solved again with a broader prior because the default knew 84 % of the poses not: doubted
    # on the default's share, whatever the broader prior's own
    assert doubt_focal(auto, 0.4, broader="human_pose_mixture") is auto
    with pytest.warns(FocalLengthWarning, match="default pose prior did not know 84 %"):
        out = doubt_focal(auto, 0.84, broader="human_pose_mixture")
    assert out["focal"]["determined"] is False and "broader human_pose_mixture" in out["focal"]["message"]


def test_a_focal_length_no_lens_has_is_said():
    """239 px for a 1920 x 1080 image: 0.11 of its 2203 px diagonal, 2 atan(1101 / 239) = 156
    degrees across it (the bench's fast spin ended there, a degenerate solve)."""
    from pinrecon.starts.camera_auto import implausible_focal

    assert implausible_focal(1200.0, (1920, 1080)) is None
    assert implausible_focal(1681.0, (1088, 1920)) is None  # Pose2Sim's phones
    msg = implausible_focal(239.0, (1920, 1080))
    assert "239 px, 0.11 image diagonals" in msg and "156 degrees" in msg and "--fov" in msg
    assert "longer than a telephoto" in implausible_focal(20000.0, (1920, 1080))


def test_a_long_clip_is_profiled_on_its_stretch_nearest_the_camera_and_moved_whole(focal_inputs, monkeypatch):
    """``settle_focal(profile_frames=n)`` (the cue path's focal stage on clips longer than
    ``stages.FOCAL_PROFILE_FRAMES``): the profile's solves run on a stretch of ``n`` frames, the
    one where the subject's depth changes most, and the move on the whole clip. Ground truth:
    the short walk's true root depths (it walks from the camera at a steady pace, 2.5 -> 4.5 m:
    the ratio over 30 frames is largest on the half nearest the camera); and the whole clip's own
    profile, whose valley the stretch must find too (the same move, within 10 %)."""
    from pinrecon import solver
    from pinrecon.starts.camera_auto import fitted_focal, settle_focal

    fig, Q = human_walk(60, 30.0)
    z = perspective_side_camera(Q, 60.0, distance_m=3.5, f_px=F_TRUE, center=(640.0, 360.0)).depth(Q[:, :3])
    near = [0, 30] if z[:30].max() / z[:30].min() > z[30:].max() / z[30:].min() else [30, 60]
    problem, res0, auto = focal_inputs
    lengths, real = [], solver.solve
    monkeypatch.setattr(solver, "solve", lambda problem, *a, **k: lengths.append(problem.n_frames) or real(
        problem, *a, **k))
    monkeypatch.setattr("pinrecon.starts.camera_auto.forkable", lambda *a: False)  # every solve here, where it is seen
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        whole, _ = settle_focal(problem, res0, auto, rounds=1, final_profile=False)
        lengths.clear()
        part, a = settle_focal(problem, res0, auto, rounds=1, final_profile=False, profile_frames=30)
    assert z[0] < 2.8 < 4.2 < z[-1] and near == [0, 30]  # the walk as its docstring says
    assert problem.n_frames == 60 and a["focal"]["frames"] == near
    assert "along frames 0-29, where the profile was taken" in a["focal"]["message"] or a["focal"]["determined"]
    assert lengths == [30] * 7 + [60, 30]  # the stretch solved, profiled (6), the whole moved, the stretch again
    assert part is not res0 and whole is not res0  # both moved down the valley
    f_whole, f_part = fitted_focal(problem, whole), fitted_focal(problem, part)
    assert f_part == pytest.approx(f_whole, rel=0.10)
    assert a["focal"]["focal_px"] == pytest.approx(f_part)
    assert settle_focal(problem, res0, auto, rounds=0, profile_frames=60)[1]["focal"].get("frames") is None
