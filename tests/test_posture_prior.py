"""The generic human's pose prior (models/priors/human_pose.json) and the posture row it
makes: read back from the JSON by hand, residuals by hand, the rest-pose prior for other
figures and when turned off."""

from __future__ import annotations

import json

import numpy as np
import pytest

import pinrecon as pr
from pinrecon._resources import model_path
from pinrecon.problem import Weights, posture_row, rest_pose
from pinrecon.rows import State
from pinrecon.synthetic import bundled_motion


@pytest.fixture(scope="module")
def table():
    return json.loads(model_path("priors", "human_pose.json").read_text())


def test_prior_file_names_the_human_joints_within_their_limits(table):
    fig = pr.Figure.human()
    m = fig.model
    names = {m.names[j]: j for j in range(1, m.njoints) if m.nqs[j] == 1}
    skipped = {"left_elbow_Z", "right_elbow_Z"}  # tools/fit_pose_prior.py --skip (default)
    assert set(table["joints"]) == set(names) - skipped and table["skipped"] == "elbow_Z"
    for name, (mean, std) in table["joints"].items():
        iv = m.idx_vs[names[name]]
        assert fig.lower_v[iv] <= mean <= fig.upper_v[iv], name
        assert table["min_std_rad"] <= std < 1.0, name
    # the knees bend one way and are bent on average in the clips
    for hinge in ("left_knee_Z", "right_knee_Z"):
        assert table["joints"][hinge][0] > 0.3


def test_posture_row_of_the_human_by_hand(table):
    fig = pr.Figure.human()
    m = fig.model
    rng = np.random.default_rng(0)
    Q = np.stack([fig.integrate(fig.neutral(), 0.4 * rng.normal(size=fig.nv)) for _ in range(4)])
    row = posture_row(fig, 4, Weights())
    r = row.evaluate(State(fig, Q, np.arange(4), True)).r
    expect = {}
    rest = rest_pose(fig)
    for jid in range(1, m.njoints):
        if m.nqs[jid] == 1:  # joints the file leaves out: the rest pose, 1 rad
            mean, std = table["joints"].get(m.names[jid], (rest[m.idx_qs[jid]], 1.0))
            expect[m.idx_vs[jid]] = (Q[:, m.idx_qs[jid]] - mean) / (3.0 * std)
    np.testing.assert_allclose(r, np.stack([expect[c] for c in row.cols], 1), rtol=1e-12)
    # Weights(pose_prior=2): the same means, two standard deviations
    r2 = posture_row(fig, 4, Weights(pose_prior=2.0)).evaluate(State(fig, Q, np.arange(4), True)).r
    np.testing.assert_allclose(r2, 1.5 * r, rtol=1e-12)


def test_other_figures_and_no_prior_keep_the_rest_pose():
    fig, q, _ = bundled_motion("walk")
    row = posture_row(fig, 3, Weights())
    Q = q[:3]
    r = row.evaluate(State(fig, Q, np.arange(3), False), jacobian=False).r
    np.testing.assert_allclose(r, (Q[:, row.qidx] - rest_pose(fig)[row.qidx]) / 3.0, rtol=1e-12)
    human = pr.Figure.human()
    off = posture_row(human, 2, Weights(pose_prior=None))
    np.testing.assert_allclose(off.q_ref, rest_pose(human)[off.qidx])
    np.testing.assert_allclose(off.inv_sigma, 1.0 / 3.0)
    assert posture_row(human, 2, Weights(pose_prior=None, sigma_posture=None)) is None
