"""A pose prior that is a mixture of Gaussians (``models/priors/human_pose_mixture.json``,
``tools/fit_pose_prior.py --components``): each frame is held by its least-cost component
(the max-mixture of SMPLify), its distance from the prior is the nearest component's, and
the fitting tool's mixture finds clusters it was given. Costs by hand are in
tests/test_posture_prior.py (parametrized over both bundled priors)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import checkout_module

import pinrecon as pr
from pinrecon._resources import model_path
from pinrecon.problem import Weights, posture_row
from pinrecon.rows import State
from pinrecon.rows.posture import pose_prior_distances

FIG = pr.Figure.human()
NAME = "human_pose_mixture"


def _file():
    return json.loads(model_path("priors", f"{NAME}.json").read_text())


def _qidx(names):
    m = FIG.model
    jid = {m.names[j]: j for j in range(1, m.njoints)}
    return np.array([m.idx_qs[jid[n]] for n in names])


def _tool():
    return checkout_module("tools/fit_pose_prior.py")


def test_the_bundled_mixture_is_a_mixture_of_proper_gaussians():
    corr = _file()["correlated"]
    mix = corr["mixture"]
    d = len(corr["joints"])
    assert len(mix["weights"]) == 8 and sum(mix["weights"]) == pytest.approx(1.0, abs=1e-5)
    assert np.array(mix["means"]).shape == (8, d)
    for C in mix["covariances"]:
        C = np.array(C)
        np.testing.assert_allclose(C, C.T, atol=1e-7)
        assert np.linalg.eigvalsh(C).min() > 1e-4 * 0.99  # shrunk, plus 1e-4 on the diagonal


def test_distance_is_the_nearest_components_and_the_row_follows_it():
    corr = _file()["correlated"]
    mix = corr["mixture"]
    qi = _qidx(corr["joints"])
    rng = np.random.default_rng(3)
    T = 24
    Q = np.tile(FIG.neutral(), (T, 1))
    # three frames at each of the first components' means, the rest random about them
    k_of = np.arange(T) % 8
    Q[:, qi] = np.array(mix["means"])[k_of] + rng.normal(0.0, 0.05, (T, len(qi))) * (np.arange(T) >= 8)[:, None]
    dist = []
    for mu, C in zip(mix["means"], mix["covariances"]):
        D = Q[:, qi] - np.array(mu)
        dist.append(np.sqrt(np.einsum("ti,ti->t", D, np.linalg.solve(np.array(C), D.T).T)))
    dist = np.stack(dist, 1)
    row = posture_row(FIG, T, Weights(pose_prior_model=NAME))
    np.testing.assert_allclose(row.distances(Q), dist.min(1), rtol=1e-9)
    np.testing.assert_allclose(row.distances(Q)[:8], 0.0, atol=1e-9)  # a frame at a mean is at distance 0
    # each frame is held by the component of least Huber cost (the default: scale 2, k = 2)
    # plus constant; the constant row carries that component's -log w + 0.5 log det C
    blk = row.evaluate(State(FIG, Q, np.arange(T), True))
    w, C = np.array(mix["weights"]), [np.array(c) for c in mix["covariances"]]
    c_hand = np.array([-np.log(w[k]) + 0.5 * np.log(np.linalg.det(C[k])) for k in range(8)])
    c_hand = (c_hand - c_hand.min()) / 2.0**2  # tempered by the scale squared
    m = dist / 2.0
    k_hand = np.argmin(np.where(m <= 2.0, 0.5 * m**2, 2.0 * m - 2.0) + c_hand, axis=1)
    np.testing.assert_allclose(0.5 * blk.r[:, -1] ** 2, c_hand[k_hand], rtol=1e-9, atol=1e-12)
    assert len(set(k_hand.tolist())) >= 3  # the frames are held by several components
    assert (k_hand[:8] != np.arange(8)).any()  # and a mean with a large constant by another


def test_unfamiliar_limit_is_the_mixtures_own():
    d = pose_prior_distances(NAME)
    assert 0 < d["50"] < d["90"] < d["99"] <= d["100"]
    assert d == {k: pytest.approx(v) for k, v in _file()["correlated"]["distance_quantiles"].items()}


def test_the_tools_mixture_finds_the_clusters_it_was_given():
    tool = _tool()
    rng = np.random.default_rng(0)
    A = rng.normal([0.0, 0.0, 0.0], 0.1, (400, 3))
    B = rng.normal([1.0, -0.5, 0.3], [0.05, 0.2, 0.1], (200, 3))
    mix, means, covs = tool.mixture(np.vstack([A, B]), 2, 0.0)
    order = np.argsort([m[0] for m in means])
    np.testing.assert_allclose(np.array(mix["weights"])[order], [2 / 3, 1 / 3], atol=0.01)
    # well apart (10 standard deviations), each component is its cluster's sample statistics
    np.testing.assert_allclose(np.array(means)[order], [A.mean(0), B.mean(0)], atol=2e-3)
    np.testing.assert_allclose(covs[order[1]], np.cov(B, rowvar=False, bias=True) + 1e-4 * np.eye(3), atol=2e-3)
