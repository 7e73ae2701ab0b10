"""pinrecon's own lifter: NumPy inference against the training framework's outputs, the
weights' recorded provenance, and the lifter's depth order on a clip of a subject it never saw."""

from __future__ import annotations

import re

import numpy as np
import pytest
from conftest import data_file

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
