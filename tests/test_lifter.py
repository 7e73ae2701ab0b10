"""pinrecon's own lifter: NumPy inference against the training framework's outputs, the
weights' recorded provenance, and the lifter's depth order on a clip of a subject it never saw."""

from __future__ import annotations

import re

import numpy as np
import pytest
from conftest import checkout_module, data_file

import pinrecon as pr
from pinrecon import datasets
from pinrecon.errors import InputError
from pinrecon.lifter import BODY, HALF_WINDOW, N_FEATURES, features, lift, load_lifter

SEGMENTS = [("left_shoulder", "left_elbow"), ("left_elbow", "left_wrist"), ("right_shoulder", "right_elbow"),
            ("right_elbow", "right_wrist"), ("left_hip", "left_knee"), ("left_knee", "left_ankle"),
            ("right_hip", "right_knee"), ("right_knee", "right_ankle")]


@pytest.fixture(scope="module")
def model():
    return load_lifter()


def test_numpy_inference_reproduces_torch(model):
    """The weights file carries features of a synthetic sequence and the trained torch network's
    outputs on them (tools/train_lifter.py, float64, edges padded by repeating the end frames)."""
    with np.load(model.path) as z:
        X, Y = z["fixture_X"], z["fixture_Y"]
    assert X.shape[1] == N_FEATURES and len(X) >= 2 * HALF_WINDOW
    P, log_s = model.predict(X)
    out = np.concatenate([P.reshape(len(P), -1), log_s], axis=1)
    assert out.shape == Y.shape
    assert np.abs(out - Y).max() < 1e-5


def test_provenance_is_recorded(model):
    meta = model.meta
    assert re.fullmatch(r"[0-9a-f]{40}(\+dirty)?", meta["commit"])
    assert meta["commit"].endswith("+dirty") is False, "the shipped weights come from a committed tree"
    for lib in ("python", "numpy", "torch"):
        assert re.fullmatch(r"\d+\.\d+.*", meta["versions"][lib])
    assert isinstance(meta["seed"], int)
    assert meta["held_out_subjects"] == [2, 9]  # the walk 02_01 and the run 09_01 stay unseen (model card)
    reg = datasets.registry()
    expected = {n for n in datasets.names("cmu-iclone/") if n.endswith(".bvh") and int(n.split("/")[1][:3]) not in (2, 9)}
    assert {d["name"] for d in meta["data"]} == expected | {"mocap/cmu-max_131_03.bvh"}
    for d in meta["data"]:
        assert reg[d["name"]].sha256 == d["sha256"]
        assert d["subject"] not in meta["held_out_subjects"]
    assert {"mocap/cmu-mb_09_01.bvh", "cmu-iclone/002_01.bvh"} <= set(meta["held_out_clips"])
    assert meta["body"] == list(BODY)


def test_features_ignore_where_and_how_big_the_person_is():
    """Without intrinsics the image's origin and unit carry nothing: features of a shifted,
    scaled copy are the same (centred per frame, divided by the person's size)."""
    rng = np.random.default_rng(0)
    xy = rng.normal(size=(60, len(BODY), 2)) * 50 + 400
    conf = rng.uniform(0.3, 1.0, (60, len(BODY)))
    xy[10, 3] = np.nan
    F1 = features(xy, conf)
    F2 = features(3.7 * xy + np.array([-120.0, 55.0]), conf)
    assert np.allclose(F1, F2, atol=1e-9)
    assert F1[10, 3 * 3 + 2] == 0.0 and F1[10, 3 * 3] == 0.0  # missing: zero coordinates and confidence


def test_strided_inference_is_the_model_on_every_k_th_frame(model):
    """At a rate k times the model's, each frame is predicted from every k-th frame around it:
    away from the edges the dilated convolution equals the model run on each phase alone."""
    rng = np.random.default_rng(1)
    X = rng.normal(size=(400, N_FEATURES)) * 0.3
    P2, _ = model.predict(X, stride=2)
    for phase in (0, 1):
        P1, _ = model.predict(X[phase::2], stride=1)
        inner = slice(2 * HALF_WINDOW, None)
        assert np.allclose(P2[phase::2][inner][: len(P1[inner]) - HALF_WINDOW],
                           P1[inner][: len(P1[inner]) - HALF_WINDOW], atol=1e-9)


def _held_out_run():
    from pinrecon.io.bvh import load_bvh
    from pinrecon.synthetic import (
        COCO_BODY_FROM_CMU,
        coco_body_tracks,
        detector_faults,
        perspective_side_camera,
    )

    m = load_bvh(data_file("mocap/cmu-mb_09_01.bvh"), 0.056444, skip_frames=1, lock="static")
    cam = perspective_side_camera(m.q, 45.0)
    clean, P = coco_body_tracks(m.figure, m.q, cam, fps=m.fps, joints=COCO_BODY_FROM_CMU)
    tracks, _ = detector_faults(clean, seed=45)
    return tracks, cam, P, list(clean.names)


def test_the_lifter_orders_depth_on_a_subject_it_never_saw():
    """CMU subject 9's run (held out of the shipped weights) with a detector's faults, a
    perspective camera 45 degrees from side-on: the share of limb segments whose depth order
    along the line of sight is wrong stays under 20 % (16.5 % with the shipped weights; a lifter
    guessing depth order gets 50 %; the issue's target for the MAP, 5 %, is not met by the
    lifter alone: bench/README.md, bench_lifter.py)."""
    tracks, cam, P, names = _held_out_run()
    L = lift(tracks, cam).select(names)
    assert L.frame == "camera" and L.points.shape == P.shape
    G = cam.camera_points(P)  # the truth in the camera's axes, the lifted frame
    flipped = counted = 0
    for a, b in SEGMENTS:
        ia, ib = names.index(a), names.index(b)
        dz_t = G[:, ib, 2] - G[:, ia, 2]
        dz_e = L.points[:, ib, 2] - L.points[:, ia, 2]
        use = np.abs(dz_t) > 0.1 * np.linalg.norm(G[:, ib] - G[:, ia], axis=-1)
        flipped += int(np.sum(use & (np.sign(dz_e) != np.sign(dz_t))))
        counted += int(use.sum())
    assert counted > 500
    assert flipped / counted < 0.20


def test_lift_takes_any_layout_and_missing_points():
    """BODY_25-named tracks with one body point absent and gaps: every frame is lifted, the
    absent point's confidence is the lifter's own, nothing is NaN."""
    rng = np.random.default_rng(2)
    names = ["nose", "neck", "right_shoulder", "right_elbow", "right_wrist", "left_shoulder", "left_elbow",
             "left_wrist", "mid_hip", "right_hip", "right_knee", "right_ankle", "left_hip", "left_knee"]
    T = 50
    base = rng.normal(size=(len(names), 2)) * 80 + 500
    uv = base + rng.normal(size=(T, len(names), 2))
    uv[5:9, 3] = np.nan
    tracks = pr.Tracks(uv, names, 30.0)
    L = lift(tracks)
    assert L.points.shape == (T, len(BODY), 3) and np.all(np.isfinite(L.points))
    assert np.all((L.confidence > 0) & (L.confidence <= 1))
    hips = L.points[:, [BODY.index("left_hip"), BODY.index("right_hip")]].mean(1)
    assert np.allclose(hips, 0.0, atol=1e-9)


def test_lift_names_what_it_needs():
    tracks = pr.Tracks(np.zeros((5, 2, 2)), ["nose", "left_eye"], 30.0)
    with pytest.raises(InputError, match="left_shoulder"):
        lift(tracks)


def _short_held_out(frames=90):
    tracks, cam, P, names = _held_out_run()
    return tracks.frames(0, frames), cam, P[:frames], names


def test_attach_lifter_puts_the_lifters_depths_on_the_detections_rays():
    """The attached cues (Tracks.lifted) are the lifter's, in the camera's axes, under the tracks'
    own names; each observed point lies on its detection's ray (it projects back onto the
    detection), and ``"none"`` leaves the tracks as they were."""
    from pinrecon.lifter import attach_lifter

    tracks, cam, _, _ = _short_held_out()
    fig = pr.Figure.human()
    assert attach_lifter(fig, tracks, cam, "none") is tracks
    assert attach_lifter(fig, tracks, cam, None) is tracks
    out = attach_lifter(fig, tracks, cam, "auto")
    # a calibration file's camera, as the command line passes it, is the same camera
    from pinrecon.io.calibration import CalibratedCamera

    calibrated = CalibratedCamera("cam", cam, None, True, "pinrecon-json")
    named = attach_lifter(fig, tracks, calibrated, "auto")
    np.testing.assert_array_equal(named.lifted.points, out.lifted.points)
    np.testing.assert_array_equal(lift(tracks, calibrated).points, lift(tracks, cam).points)
    assert not np.array_equal(lift(tracks, None).points, lift(tracks, cam).points)  # the intrinsics count
    L = out.lifted
    assert L is not None and L.frame == "camera" and set(L.names) == set(BODY) <= set(tracks.names)
    uv_true = tracks.select(L.names).points
    seen = np.all(np.isfinite(uv_true), axis=-1) & (L.confidence > 0)
    ray = L.points / L.points[..., 2:3]  # normalised coordinates of the lifted points
    uv = (ray @ np.asarray(cam.K).T)[..., :2]
    assert seen.mean() > 0.9
    assert np.abs(uv - uv_true)[seen].max() < 1e-6
    assert np.all(L.points[..., 2][seen] > 0)
    # several cameras see depth: left alone; a figure that is not the generic human: "auto" leaves it
    assert attach_lifter(fig, [tracks, tracks], [cam, cam], "auto")[0].lifted is None
    other = pr.Figure.human()
    other.meta = {**other.meta, "generic": None}
    assert attach_lifter(other, tracks, cam, "auto").lifted is None


def test_a_lifter_file_of_the_wrong_shape_is_refused_by_name(tmp_path, model):
    """Weights whose layers do not chain (another width, another number of points) are refused
    with an InputError naming the file and the layer, by load_lifter and by reconstruct."""
    layers = {k: v.astype(np.float32) for k, v in model.layers.items()}
    layers["out_W"] = layers["out_W"][:, :40]  # 10 points' worth of outputs, not 12
    bad = tmp_path / "lifter_10points.npz"
    np.savez(bad, **layers)
    with pytest.raises(InputError, match="out_W") as err:
        load_lifter(bad)
    assert "lifter_10points.npz" in str(err.value)
    tracks, cam, _, _ = _short_held_out(30)
    with pytest.raises(InputError, match="out_W"):
        pr.reconstruct(pr.Figure.human(), tracks, cam, lifter=str(bad))
    wide = {**layers, "out_W": model.layers["out_W"], "b1_W1": np.zeros((3, 128, 256), np.float32)}
    np.savez(tmp_path / "narrow.npz", **wide)
    with pytest.raises(InputError, match="b1_W1"):
        load_lifter(tmp_path / "narrow.npz")


def test_lifter_option_reaches_reconstruct(monkeypatch):
    """``--lifter none|auto|FILE`` of the shared reconstruct options is reconstruct's ``lifter=``;
    without it reconstruct's own default holds."""
    import argparse
    import importlib

    from pinrecon import arguments

    rec = importlib.import_module("pinrecon.reconstruct")

    seen = {}

    def fake(*args, **kwargs):
        seen.clear()
        seen.update(kwargs)
        raise SystemExit(0)

    monkeypatch.setattr(rec, "reconstruct", fake)
    ap = argparse.ArgumentParser()
    arguments.add_reconstruct_options(ap, inputs=lambda r: r.add_argument("--tracks", nargs="+"))
    for given, expect in (["--lifter", "none"], "none"), (["--lifter", "auto"], "auto"), ([], None):
        args = ap.parse_args(["--figure", "human", "--camera", "auto", "--tracks", "t.json", *given])
        assert args.lifter == expect
    monkeypatch.setattr(arguments, "auto_camera_from_args", lambda a: "auto")
    monkeypatch.setattr("pinrecon.tracks.load_tracks", lambda *a, **k: _short_held_out(30)[0])
    for given, expect in (["--lifter", "none"], "none"), (["--lifter", "x.npz"], "x.npz"), ([], "absent"):
        args = ap.parse_args(["--figure", "human", "--camera", "auto", "--tracks", "t.json", *given])
        with pytest.raises(SystemExit):
            arguments.reconstruct_from_args(args)
        assert seen.get("lifter", "absent") == expect


def test_the_lifter_joins_from_the_start_where_the_default_prior_holds():
    """CMU subject 9's run (held out of the shipped weights), 90 frames, the issue's detector
    faults, one perspective camera, no keyframes: the run's poses are familiar to the default
    pose prior, and pinrecon's lifter's rows are in from the start at ``Weights.own_lifter``
    (the solve stage says so, the result carries their report). Against the true points the
    flipped limb segments and PA-MPJPE are within issue 42's bounds for the run (5 %, 30 mm;
    measured 4.2 % and 25.0 mm, 8.0 % and 28.5 mm without the lifter: bench_lifter.py
    ``--seeds``)."""
    from pinrecon.metrics import flip_rate, pa_mpjpe

    tracks, cam, P, names = _short_held_out(90)
    fig = pr.Figure.human()
    segs = [(names.index(a), names.index(b)) for a, b in SEGMENTS]
    res = pr.reconstruct(fig, tracks, cam)
    said = {s.name: s.changed for s in res.stages}
    assert "with pinrecon's lifter's rows (weight 3)" in said["solve"] and said["prior"] == "skipped: nothing to do"
    assert "lifted_bones" in res.extras
    Pe = res.keypoints3d[:, res.figure.keypoint_index(names)]
    assert flip_rate(Pe, P, cam, segs) < 0.05
    assert pa_mpjpe(Pe, P) < 30.0  # mm


@pytest.mark.slow
def test_a_prior_switch_takes_the_lifter_as_without_the_start_join(monkeypatch):
    """``own_lifter=None`` and 3D keyframes leave the lifter out of the start; where the prior
    switches to its broader mixture (here every clip, ``switch_share`` patched), the lifter
    joined from the start leaves: the clip is solved with the lifter at ``Weights.lifted``
    exactly as when it never joined from the start (ground truth: the same call with
    ``Weights(own_lifter=None)``), to the last digit."""
    import sys

    tracks, cam, P, names = _short_held_out(60)
    fig = pr.Figure.human()
    off = pr.reconstruct(fig, tracks, cam, weights=pr.Weights(own_lifter=None))
    assert "lifter" not in {s.name: s.changed for s in off.stages}["solve"] and "lifted_bones" not in off.extras
    keys = pr.Keyframes([pr.Keyframe(t, 0.05, points=dict(zip(names, P[t]))) for t in (0, 59)])
    keyed = pr.reconstruct(fig, tracks, cam, keys)
    assert "lifter" not in {s.name: s.changed for s in keyed.stages}["solve"]
    monkeypatch.setattr(sys.modules["pinrecon.reconstruct"], "switch_share", lambda *a: -1.0)
    joined = pr.reconstruct(fig, tracks, cam)
    never = pr.reconstruct(fig, tracks, cam, weights=pr.Weights(own_lifter=None))
    for res in (joined, never):
        assert {s.name: s.changed for s in res.stages}["prior"].startswith("pose prior human_pose -> human_pose_mixture")
        assert "lifted_bones" in res.extras
    np.testing.assert_array_equal(joined.q, never.q)
    np.testing.assert_array_equal(joined.keypoints3d, never.keypoints3d)


def test_the_own_lifter_weight_option_reaches_the_weights():
    from pinrecon.arguments import WEIGHT_OPTIONS, weights_kwargs
    from pinrecon.cli import build_parser

    base = ["reconstruct", "--figure", "human", "--tracks", "t.json", "--camera", "auto", "--out", "o"]
    for flag, expect in ((["--own-lifter-weight", "5"], 5.0), (["--own-lifter-weight", "0"], None), ([], 3.0)):
        args = build_parser().parse_args(base + flag)
        assert pr.Weights(**weights_kwargs(args, WEIGHT_OPTIONS)).own_lifter == expect
    with pytest.raises(SystemExit):
        build_parser().parse_args(base + ["--own-lifter-weight", "-1"])


@pytest.mark.slow
def test_reconstruct_with_the_lifter_on_a_held_out_clip():
    """CMU subject 9's run (never seen by the shipped weights), the issue's detector faults,
    one perspective camera 45 degrees from side-on, no keyframes, the lifter's rows attached to
    the tracks as a lifter's 3D cues (the lifted start, weight ``Weights.lifted``): the result
    carries the lifted rows' report and its flipped limb segments stay under 10 %
    (bench/README.md, bench_lifter.py: 3.3 % on the whole run); ``lifter="none"`` adds no rows."""
    from pinrecon.lifter import attach_lifter
    from pinrecon.metrics import flip_rate
    from pinrecon.reconstruct import build_problem

    tracks, cam, P, names = _short_held_out(240)
    fig = pr.Figure.human()
    res = pr.reconstruct(fig, attach_lifter(fig, tracks, cam, "auto"), cam)
    assert "lifted_bones" in res.extras
    Pe = res.keypoints3d[:, res.figure.keypoint_index(names)]
    segs = [(names.index(a), names.index(b)) for a, b in SEGMENTS]
    assert flip_rate(Pe, P, cam, segs) < 0.10
    assert [r for r in build_problem(fig, tracks, cam, lifter="auto").problem.rows if r.name == "lifted"]
    assert not [r for r in build_problem(fig, tracks, cam, lifter="none").problem.rows if r.name == "lifted"]


def test_training_spins_turn_the_body_at_a_steady_rate():
    """``--spin``: the chosen samples turn about the vertical through the hips' midpoint at one
    rate of 0.25-``turns`` turns a second; heights and every distance between points kept, the
    window's middle frame (the target's) unchanged, the other samples untouched."""
    tool = checkout_module("tools/train_lifter.py")
    rng = np.random.default_rng(3)
    B, S, K = 40, tool.SEG, len(BODY)
    P = rng.normal(size=(B, S, K, 3)) * 0.3
    P[..., 1] += 1.0
    dt = rng.choice([1 / 30, 1 / 20, 1 / 50], B)
    Q = tool.spun(P, dt, np.random.default_rng(5), 0.5, 2.0)
    moved = np.flatnonzero(np.abs(Q - P).max(axis=(1, 2, 3)) > 0)
    kept = np.setdiff1d(np.arange(B), moved)
    assert 8 < len(moved) < 32 and np.array_equal(Q[kept], P[kept])
    assert np.array_equal(Q[..., 1], P[..., 1]) and np.abs(Q[:, S // 2] - P[:, S // 2]).max() < 1e-12
    dist = [np.linalg.norm(X[:, :, :, None] - X[:, :, None], axis=-1) for X in (Q, P)]
    assert np.abs(dist[0] - dist[1]).max() < 1e-12
    for b in moved:  # the angle between a point's bearing from the hips' midpoint before and after
        c = P[b, :, [6, 7]].mean(0)
        a0 = np.arctan2(P[b, :, 0, 2] - c[:, 2], P[b, :, 0, 0] - c[:, 0])
        a1 = np.arctan2(Q[b, :, 0, 2] - c[:, 2], Q[b, :, 0, 0] - c[:, 0])
        step = np.diff(np.unwrap(a0 - a1)) / dt[b] / (2 * np.pi)  # turns a second
        assert np.ptp(step) < 1e-9 and 0.25 - 1e-9 <= abs(step[0]) <= 2.0 + 1e-9
