"""Poses the pose prior does not know (``pinrecon.unfamiliar``): the distance is the
Mahalanobis distance of the prior file's covariance, spans are where it passes the
clips' 99th percentile, and on real motion capture it tells a dance from a walk."""

from __future__ import annotations

import json
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

import pinrecon as pr
from pinrecon._resources import model_path
from pinrecon.problem import Weights, posture_row
from pinrecon.result import Result
from pinrecon.rows.posture import pose_prior_distances
from pinrecon.synthetic import COCO_BODY_FROM_CMU, bundled_motion
from pinrecon.unfamiliar import unfamiliar_poses

FIG = pr.Figure.human()


def _prior_file():
    """The correlated joints' q indices, means and covariance, read from the file here."""
    data = json.loads(model_path("priors", "human_pose.json").read_text())
    m = FIG.model
    jid = {m.names[j]: j for j in range(1, m.njoints)}
    names = data["correlated"]["joints"]
    qi = np.array([m.idx_qs[jid[n]] for n in names])
    mean = np.array([data["joints"][n][0] for n in names])
    return qi, mean, np.array(data["correlated"]["covariance"], float)


def _at_distance(T, frames, dist, seed=0):
    """(T, nq) poses at the prior's mean, ``frames`` moved to Mahalanobis distance ``dist``."""
    qi, mean, C = _prior_file()
    Q = np.tile(FIG.neutral(), (T, 1))
    Q[:, qi] = mean
    u = np.random.default_rng(seed).normal(size=(len(frames), len(qi)))
    u *= dist / np.linalg.norm(u, axis=1, keepdims=True)
    Q[np.ix_(frames, qi)] = mean + u @ np.linalg.cholesky(C).T
    return Q


@pytest.mark.parametrize("scale", [2.0, 3.0])
def test_distances_are_the_mahalanobis_distance(scale):
    qi, mean, C = _prior_file()
    Q = np.tile(FIG.neutral(), (30, 1))
    Q[:, qi] = mean + np.random.default_rng(1).normal(0.0, 0.3, (30, len(qi)))
    x = Q[:, qi] - mean
    want = np.sqrt(np.einsum("ij,ij->i", x @ np.linalg.inv(C), x))
    row = posture_row(FIG, 30, Weights(pose_prior=scale))
    np.testing.assert_allclose(row.distances(Q), want, rtol=1e-4)  # the file's means are rounded to 1e-5 rad


def test_the_limit_is_the_clips_percentile():
    d = pose_prior_distances()
    assert 0 < d["50"] < d["90"] < d["99"] <= d["100"]
    assert d["99"] == pytest.approx(9.004)


def test_unfamiliar_spans_by_construction():
    T = 40
    Q = _at_distance(T, [10, 11, 12, 13, 14, 17, 18, 19], 15.0)
    Q[25] = _at_distance(T, [25], 8.0)[25]  # inside the clips' 99 %: not flagged
    problem = SimpleNamespace(rows=[posture_row(FIG, T, Weights())], fps=30.0)
    rep = unfamiliar_poses(problem, Q)
    np.testing.assert_allclose(rep.distance[[10, 17, 25, 0]], [15.0, 15.0, 8.0, 0.0], atol=2e-3)
    assert rep.spans == [(10, 20)]  # 2 frames apart: one span (merged within 0.2 s)
    assert unfamiliar_poses(problem, Q, merge_s=0.0).spans == [(10, 15), (17, 20)]
    assert rep.share == pytest.approx(8 / 40)
    assert unfamiliar_poses(SimpleNamespace(rows=[posture_row(FIG, T, Weights(pose_prior=None))], fps=30.0), Q) is None
    # the summary names them
    res = Result(FIG, Q, np.arange(T) / 30.0, 30.0, FIG.keypoints(Q), np.zeros(T), None, np.ones(T, bool),
                 extras=rep.to_extras())
    text = res.summary()
    assert "poses unlike the pose prior's clips in 8 of 40 frames (20 %" in text
    assert "frames 10-19 (0.33-0.63 s), up to 15.0 standard deviations" in text


def _leg(P, names):
    i = {n: k for k, n in enumerate(names)}
    return float(np.median(sum(np.linalg.norm(P[:, i[f"{s}_{a}"]] - P[:, i[f"{s}_{b}"]], axis=-1)
                               for s in ("left", "right") for a, b in (("hip", "knee"), ("knee", "ankle")))))


def _human_poses(clip):
    """The clip's 12 COCO body points at 30 fps, fitted with the human figure (markers)."""
    fig_c, q, fps = bundled_motion(clip)
    step = round(fps / 30.0)
    names = list(COCO_BODY_FROM_CMU)
    P = fig_c.keypoints(q[::step])[:, fig_c.keypoint_index([COCO_BODY_FROM_CMU[n] for n in names])]
    rest = FIG.keypoints(FIG.neutral()[None])[:, FIG.keypoint_index(names)]
    P = P * (_leg(rest, names) / _leg(P, names))  # the figure's leg length, as tools/fit_pose_prior.py
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct_markers(FIG, pr.Markers(P, names, fps / step), weights=Weights(pose_prior=None),
                                     calibrate="none")
    return res.q


def test_a_dance_is_unfamiliar_and_a_walk_is_not():
    """CMU 02_01 (walk) and 05_11 (a dance), neither among the prior's clips, fitted from
    their true 3D points (scaled to the figure's leg length): no walking frame lies beyond
    the limit, the dance's frames do."""
    limit = pose_prior_distances()["99"]
    row = posture_row(FIG, 1, Weights())
    walk, dance = (row.distances(_human_poses(c)) for c in ("walk", "spin"))
    assert np.max(walk) < limit  # measured: median 6.7, max 8.2
    assert np.mean(dance > limit) > 0.9  # measured: every frame, median 17.6
