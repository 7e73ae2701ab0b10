"""Detector faults: left/right swaps found and repaired, outliers down-weighted by the
confidence-weighted robust loss (the default with confidences) and reported.

Ground truth: a known smooth motion of the human figure, projected by hand; swaps and
outliers are written into the tracks by the test itself at chosen frames and points."""

from __future__ import annotations

import inspect
from dataclasses import replace

import numpy as np
import pytest

import pinrecon as pr
from pinrecon.faults import left_right_pairs
from pinrecon.problem import Weights, resolved_loss
from pinrecon.synthetic import COCO_BODY_FROM_CMU, smooth_motion
from pinrecon.tracks import keyframes_from_points

NAMES = list(COCO_BODY_FROM_CMU)
T, FPS = 60, 30.0
SWAPPED = [7, 23, 41]
OUTLIERS = [(5, "left_knee"), (12, "right_wrist"), (18, "left_shoulder"), (30, "right_ankle"), (44, "left_elbow"),
            (52, "right_hip")]


@pytest.fixture(scope="module")
def scene():
    fig = pr.Figure.human()
    Q = smooth_motion(fig, T, FPS, seed=3, amplitude=0.3)
    cam = pr.Perspective.look_at([2.0, 0.9, 4.5], [0.5, 0.0, 0.0], f_px=1000.0, center=(960.0, 540.0))
    P = fig.keypoints(Q)[:, fig.keypoint_index(NAMES)]
    uv = cam.project(P) + np.random.default_rng(0).normal(0.0, 1.0, P.shape[:2] + (2,))
    keys = keyframes_from_points(range(0, T, 10), P + np.random.default_rng(1).normal(0.0, 0.02, P.shape), NAMES, 0.02)
    return fig, Q, cam, P, uv, keys


def _reconstruct(fig, tracks, cam, keys, **kw):
    if "calibrate" in inspect.signature(pr.reconstruct).parameters:
        kw.setdefault("calibrate", "none")
    # the test motion is random joint motion, which no pose prior knows: the human's own prior
    # is named, so that the default's switch to its broader mixture (pinrecon.unfamiliar.
    # broader_prior) does not run; with it the three solves below end at 56-61 mm, not 31-45
    kw["weights"] = replace(kw.get("weights", Weights()), pose_prior_model="human_pose")
    return pr.reconstruct(fig, tracks, cam, keys, **kw)


def _swap(uv, frames):
    uv = uv.copy()
    for a, b in left_right_pairs(NAMES):
        uv[np.ix_(frames, [a, b])] = uv[np.ix_(frames, [b, a])]
    return uv


def test_left_right_pairs():
    pairs = {(NAMES[a], NAMES[b]) for a, b in left_right_pairs(NAMES)}
    assert len(pairs) == 6 and ("left_knee", "right_knee") in pairs
    assert left_right_pairs(["LeftLeg", "RightLeg", "Hips", "LHipJoint", "RHipJoint"]) == [(0, 1), (3, 4)]


def test_auto_loss_is_robust_with_confidences():
    uv = np.zeros((2, 2, 2))
    assert Weights().loss == "auto"
    assert resolved_loss(Weights(), pr.Tracks(uv, ["a", "b"], 30.0, np.ones((2, 2)))) == "cauchy"
    assert resolved_loss(Weights(), pr.Tracks(uv, ["a", "b"], 30.0)) == "l2"
    assert resolved_loss(Weights(loss="huber"), pr.Tracks(uv, ["a", "b"], 30.0, np.ones((2, 2)))) == "huber"


def test_every_swapped_frame_is_repaired(scene):
    """The fault stage alone (the stage labels, which would relabel them first, off)."""
    fig, Q, cam, P, uv, keys = scene
    tracks = pr.Tracks(_swap(uv, SWAPPED), NAMES, FPS, np.full((T, len(NAMES)), 0.9))
    res = _reconstruct(fig, tracks, cam, keys, skip=("labels",))
    assert sorted(np.asarray(res.extras["repaired_frames"]).tolist()) == SWAPPED
    assert "relabelled_frames" not in res.extras
    assert "left/right swaps repaired in 3 frames: 7, 23, 41" in res.summary()
    # after the repair the swapped frames are as accurate as the others
    err = np.linalg.norm(res.keypoints3d[:, fig.keypoint_index(NAMES)] - P, axis=-1).mean(axis=1)
    assert err[SWAPPED].mean() < 1.5 * np.median(err) + 0.01


def test_swapped_frames_and_a_swapped_span_are_relabelled_before_the_solve(scene):
    """By default the stage labels finds single swapped frames and a span of them (which a
    solution following the labels cannot see) from the tracks' continuity."""
    fig, _, cam, P, uv, keys = scene
    swapped = SWAPPED + list(range(30, 38))
    tracks = pr.Tracks(_swap(uv, swapped), NAMES, FPS, np.full((T, len(NAMES)), 0.9))
    res = _reconstruct(fig, tracks, cam, keys)
    assert np.asarray(res.extras["relabelled_frames"]).tolist() == sorted(swapped)
    assert len(res.extras["repaired_frames"]) == 0  # nothing left for the fault stage
    assert "other way round on frames 7, 23, 30-37, 41" in res.summary()
    assert [s.name for s in res.stages][:2] == ["labels", "solve"]
    err = np.linalg.norm(res.keypoints3d[:, fig.keypoint_index(NAMES)] - P, axis=-1).mean(axis=1)
    assert err[swapped].mean() < 1.5 * np.median(err) + 0.01


def test_a_clip_solved_in_windows_is_relabelled_too(scene):
    fig, _, cam, P, uv, keys = scene
    swapped = list(range(30, 38))
    tracks = pr.Tracks(_swap(uv, swapped), NAMES, FPS, np.full((T, len(NAMES)), 0.9))
    res = _reconstruct(fig, tracks, cam, keys, window=30, floor="none")
    assert [s.name for s in res.stages] == ["windowed"]
    assert np.asarray(res.extras["relabelled_frames"]).tolist() == swapped
    assert "relabelled_lifted_frames" not in res.extras  # the tracks carry no lifter's 3D
    off = _reconstruct(fig, tracks, cam, keys, window=30, floor="none", skip=("labels",))
    assert "relabelled_frames" not in off.extras


def test_no_repair_on_a_clean_clip(scene):
    fig, Q, cam, P, uv, keys = scene
    res = _reconstruct(fig, pr.Tracks(uv, NAMES, FPS, np.full((T, len(NAMES)), 0.9)), cam, keys)
    assert len(res.extras["repaired_frames"]) == 0
    assert "relabelled_frames" not in res.extras and res.stages[0].changed == "skipped: nothing to do"
    assert len(res.extras["outlier_frames"]) == 0


def test_frames_the_detector_missed_are_said_in_the_summary(scene):
    """Frames 20-29 without any 2D point (a detector that found nobody) are named as not
    observed; the clean clip, and a single missing frame (a gap under 0.1 s), say nothing."""
    from pinrecon.result import unobserved_lines

    fig, Q, cam, P, uv, keys = scene
    gap = uv.copy()
    gap[20:30] = np.nan
    gap[45] = np.nan
    res = _reconstruct(fig, pr.Tracks(gap, NAMES, FPS, np.full((T, len(NAMES)), 0.9)), cam, keys)
    said = res.summary()
    assert "not observed: 10 of 60 frames have no 2D point" in said and "frames 20-29 (0.67-0.97 s)" in said
    assert "frames 45-45" not in said
    np.testing.assert_array_equal(np.flatnonzero(~res.observed_frames), [*range(20, 30), 45])
    assert unobserved_lines(np.ones(T, bool), FPS) == []
    every_other = np.arange(4 * T) % 2 == 0  # a result at twice the tracks' rate: nothing to say
    assert unobserved_lines(every_other, 2 * FPS) == []


def test_outliers_reported_and_down_weighted(scene):
    fig, Q, cam, P, uv, keys = scene
    bad = uv.copy()
    conf = np.full((T, len(NAMES)), 0.9)
    rng = np.random.default_rng(2)
    for f, n in OUTLIERS:
        ang = rng.uniform(0, 2 * np.pi)
        bad[f, NAMES.index(n)] += 60.0 * np.array([np.cos(ang), np.sin(ang)])
        conf[f, NAMES.index(n)] = 0.3
    tracks = pr.Tracks(bad, NAMES, FPS, conf)
    idx = fig.keypoint_index(NAMES)
    robust = _reconstruct(fig, tracks, cam, keys)  # loss "auto": Cauchy, the tracks have confidences
    l2 = _reconstruct(fig, tracks, cam, keys, weights=Weights(loss="l2"))
    clean = _reconstruct(fig, pr.Tracks(uv, NAMES, FPS, np.full((T, len(NAMES)), 0.9)), cam, keys)
    found = set(zip(np.asarray(robust.extras["outlier_frames"]).tolist(), np.asarray(robust.extras["outlier_points"]).tolist()))
    assert set(OUTLIERS) <= found and len(found) <= len(OUTLIERS) + 2
    e = {k: 1000 * np.linalg.norm(r.keypoints3d[:, idx] - P, axis=-1).mean() for k, r in
         (("robust", robust), ("l2", l2), ("clean", clean))}
    assert e["robust"] < e["l2"] and e["robust"] < 1.2 * e["clean"] + 2.0, e
    assert "points stayed far off after convergence" in robust.summary()


def test_outliers_are_found_again_for_a_later_solve(scene):
    """report_outliers re-reads the outliers of the solve it is given into the fault
    stage's report (reconstruct calls it when an auto camera's focal restarts the solve)."""
    from types import SimpleNamespace

    from pinrecon.faults import fault_stage, report_outliers
    from pinrecon.problem import make_problem
    from pinrecon.solver import solve

    fig, Q, cam, _P, uv, keys = scene
    bad = uv.copy()
    for f, n in OUTLIERS:
        bad[f, NAMES.index(n)] += 60.0
    problem = make_problem(fig, pr.Tracks(bad, NAMES, FPS, np.full((T, len(NAMES)), 0.9)), cam, keys)
    res = fault_stage(problem, solve(problem, Q))
    report = problem.reports["faults"]
    assert set(zip(report.outlier_frames.tolist(), report.outlier_points.tolist())) == set(OUTLIERS)
    # a trajectory whose frame 20 holds frame 40's pose: frame 20's points are far off
    moved = Q.copy()
    moved[20] = Q[40]
    report_outliers(problem, SimpleNamespace(x=moved, g=None))
    assert problem.reports["faults"] is report and 20 in report.outlier_frames.tolist()
    report_outliers(problem, res)
    assert set(zip(report.outlier_frames.tolist(), report.outlier_points.tolist())) == set(OUTLIERS)
