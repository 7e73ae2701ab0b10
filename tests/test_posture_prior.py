"""The generic human's pose prior (models/priors/human_pose.json) and the posture row it
makes: read back from the JSON by hand, its cost by hand (Mahalanobis distance of the
correlated joints, standard deviations of the others), its Jacobian against finite
differences, the rest-pose prior for other figures and when turned off."""

from __future__ import annotations

import json

import numpy as np
import pytest

import pinrecon as pr
from pinrecon._resources import model_path
from pinrecon.errors import InputError
from pinrecon.problem import Weights, posture_row, rest_pose
from pinrecon.rows import State
from pinrecon.rows.posture import pose_prior
from pinrecon.synthetic import bundled_motion


@pytest.fixture(scope="module")
def table():
    return json.loads(model_path("priors", "human_pose.json").read_text())


#: the human's bundled priors: one Gaussian (the default) and a mixture
MODELS = ["human_pose", "human_pose_mixture"]


def _table(name):
    return json.loads(model_path("priors", f"{name}.json").read_text())


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
    # the correlated block: the joints that move (std above the floor), their covariance
    # symmetric positive definite, its diagonal their variance (+ 1e-4, rounding of std)
    corr = table["correlated"]
    moving = [n for n, (_, std) in table["joints"].items() if std > table["min_std_rad"]]
    assert sorted(corr["joints"]) == sorted(moving) and len(moving) >= 12
    C = np.array(corr["covariance"])
    np.testing.assert_allclose(C, C.T, atol=1e-7)
    assert np.linalg.eigvalsh(C).min() > 0
    std = np.array([table["joints"][n][1] for n in corr["joints"]])
    np.testing.assert_allclose(np.diag(C), std**2 + 1e-4, rtol=2e-3, atol=1e-6)
    # a walking hip's flexion and its knee's flexion move together
    k = {n: i for i, n in enumerate(corr["joints"])}
    rho = C[k["left_hip_Z"], k["left_knee_Z"]] / np.sqrt(C[k["left_hip_Z"], k["left_hip_Z"]] * C[k["left_knee_Z"], k["left_knee_Z"]])
    assert abs(rho) > 0.2


def _prior_cost_by_hand(table, fig, Q, scale, huber=None, cauchy=False):
    """Per frame: 0.5 m^2 (Huber beyond ``huber``, or Cauchy at scale ``huber``), m the
    correlated joints' Mahalanobis distance / scale, plus :func:`_diag_cost`; of a mixture
    (``"mixture"`` in the file), the least over its components of that plus the component's
    ``(-log w + 0.5 log det C) / scale^2`` (less the least of those)."""
    dist, const = _components_by_hand(table, fig, Q, scale)
    if huber is None:
        cost = 0.5 * dist**2
    elif cauchy:
        cost = 0.5 * huber**2 * np.log(1.0 + (dist / huber) ** 2)
    else:
        cost = np.where(dist <= huber, 0.5 * dist**2, huber * dist - 0.5 * huber**2)
    return (cost + const).min(axis=1) + _diag_cost(table, fig, Q, scale)


def _components_by_hand(table, fig, Q, scale):
    """((T, K) each frame's Mahalanobis distance / scale from each component, (K,) their
    constants); one component, the file's mean and covariance, when it has no mixture."""
    m = fig.model
    q_of = {m.names[j]: m.idx_qs[j] for j in range(1, m.njoints) if m.nqs[j] == 1}
    corr = table["correlated"]["joints"]
    X = Q[:, [q_of[n] for n in corr]]
    mix = table["correlated"].get("mixture")
    if mix is None:
        mix = {"weights": [1.0], "means": [[table["joints"][n][0] for n in corr]],
               "covariances": [table["correlated"]["covariance"]]}
    dist, const = [], []
    for w, mu, C in zip(mix["weights"], mix["means"], mix["covariances"]):
        D, C = X - np.array(mu), np.array(C)
        dist.append(np.sqrt(np.einsum("ti,ti->t", D, np.linalg.solve(C, D.T).T)) / scale)
        const.append(-np.log(w) + 0.5 * np.log(np.linalg.det(C)))
    return np.stack(dist, 1), (np.array(const) - min(const)) / scale**2  # the density tempered by scale^2


def _diag_cost(table, fig, Q, scale):
    """Per frame: 0.5 * the squared z / scale^2 of the joints outside the correlated ones
    (the file's mean and std, or the rest pose and 1 rad)."""
    m = fig.model
    q_of = {m.names[j]: m.idx_qs[j] for j in range(1, m.njoints) if m.nqs[j] == 1}
    corr = table["correlated"]["joints"]
    rest = rest_pose(fig)
    cost = np.zeros(len(Q))
    for name, iq in q_of.items():
        if name not in corr:
            mean, std = table["joints"].get(name, (rest[iq], 1.0))
            cost += 0.5 * ((Q[:, iq] - mean) / (scale * std)) ** 2
    return cost


def _poses(fig, n, amplitude, seed):
    rng = np.random.default_rng(seed)
    return np.stack([fig.integrate(fig.neutral(), amplitude * rng.normal(size=fig.nv)) for _ in range(n)])


@pytest.mark.parametrize("model", MODELS)
def test_posture_row_of_the_human_by_hand(model):
    table = _table(model)
    fig = pr.Figure.human()
    Q = _poses(fig, 6, 0.4, 0)
    Q[0] = fig.integrate(pose_prior(fig, rest_pose(fig))[0], 0.02 * np.ones(fig.nv))  # near the mean
    quadratic = posture_row(fig, 6, Weights(pose_prior_k=None, pose_prior_model=model)).evaluate(
        State(fig, Q, np.arange(6), True))
    np.testing.assert_allclose(0.5 * (quadratic.r**2).sum(1), _prior_cost_by_hand(table, fig, Q, 2.0), rtol=1e-9)
    if model == "human_pose":  # Weights(pose_prior=1): the same means, one standard deviation: four times the cost
        r1 = posture_row(fig, 6, Weights(pose_prior=1.0, pose_prior_k=None)).evaluate(State(fig, Q, np.arange(6), True)).r
        np.testing.assert_allclose((r1**2).sum(1), 4 * (quadratic.r**2).sum(1), rtol=1e-9)
    # the default: Huber at a distance of 2 (some of these random poses are beyond it, some not)
    blk = posture_row(fig, 6, Weights(pose_prior_model=model)).evaluate(State(fig, Q, np.arange(6), True))
    expect = _prior_cost_by_hand(table, fig, Q, 2.0, huber=2.0)
    assert blk.cost == pytest.approx(expect.sum(), rel=1e-9)
    assert (expect < _prior_cost_by_hand(table, fig, Q, 2.0)).any()
    assert (expect <= _prior_cost_by_hand(table, fig, Q, 2.0)).all()
    if model == "human_pose":  # the pose near the mean is within the quadratic part
        assert (expect == _prior_cost_by_hand(table, fig, Q, 2.0)).any()
    # Cauchy at 3: 0.5 k^2 log(1 + m^2 / k^2); its rows are the Mahalanobis rows scaled by
    # (1 + m^2 / k^2)^(-1/2), and frame_costs gives each frame's loss
    w = Weights(pose_prior_loss="cauchy", pose_prior_k=3.0, pose_prior_model=model)
    row = posture_row(fig, 6, w)
    blk = row.evaluate(State(fig, Q, np.arange(6), True))
    expect = _prior_cost_by_hand(table, fig, Q, 2.0, huber=3.0, cauchy=True)
    assert blk.cost == pytest.approx(expect.sum(), rel=1e-9)
    np.testing.assert_allclose(row.frame_costs(Q), expect, rtol=1e-9)
    dist, const = _components_by_hand(table, fig, Q, 2.0)
    k = np.argmin(0.5 * 9.0 * np.log1p(dist**2 / 9.0) + const, axis=1)  # each frame's component under the loss
    m, c = dist[np.arange(len(Q)), k], const[k]
    np.testing.assert_allclose(0.5 * (blk.r**2).sum(1), 0.5 * m**2 / (1.0 + m**2 / 9.0) + c + _diag_cost(table, fig, Q, 2.0),
                               rtol=1e-9)
    with pytest.raises(InputError, match="pose_prior_loss"):
        Weights(pose_prior_loss="tukey")


def _fd(row, fig, Q, col, f, eps=1e-6):
    v = np.zeros(fig.nv)
    v[col] = eps
    Qp = np.stack([fig.integrate(q, v) for q in Q])
    Qm = np.stack([fig.integrate(q, -v) for q in Q])
    return (f(row.evaluate(State(fig, Qp, np.arange(len(Q)), False), False))
            - f(row.evaluate(State(fig, Qm, np.arange(len(Q)), False), False))) / (2 * eps)


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("some_inactive", [False, True])
def test_posture_row_jacobian_against_finite_differences(some_inactive, model):
    fig = pr.Figure.human()
    Q = _poses(fig, 3, 0.3, 1)
    active = None
    if some_inactive:  # e.g. one leg only, as the hypothesis search's inverse kinematics
        active = np.zeros(fig.nv, bool)
        active[fig.support_mask(["left_knee", "left_ankle"])] = True
    row = posture_row(fig, 3, Weights(pose_prior_k=None, pose_prior_model=model), active)
    blk = row.evaluate(State(fig, Q, np.arange(3), True))
    J = np.asarray(blk.J)[:, 0]  # (T, m, c)
    for k, col in enumerate(row.cols):
        np.testing.assert_allclose(J[:, :, k], _fd(row, fig, Q, col, lambda b: b.r), atol=1e-7)
    if some_inactive:  # rows of every correlated joint, columns of the active ones only
        assert set(row.cols) <= set(np.flatnonzero(active)) and 0 < len(row.cols) < 6
        assert blk.r.shape[1] >= len(row.qcorr) > len(row.cols)


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("loss", ["huber", "cauchy"])
def test_robust_rows_give_the_gradient_of_their_cost(loss, model):
    """Reweighted rows (J, r scaled by sqrt(w)): J^T r is the gradient of the robust cost."""
    fig = pr.Figure.human()
    Q = _poses(fig, 4, 0.5, 2)
    row = posture_row(fig, 4, Weights(pose_prior_loss=loss, pose_prior_model=model))
    blk = row.evaluate(State(fig, Q, np.arange(4), True))
    grad = np.einsum("tmc,tm->tc", np.asarray(blk.J)[:, 0], blk.r)
    for k, col in enumerate(row.cols):
        fd = np.array([_fd(row, fig, Q[t : t + 1], col, lambda b: b.cost) for t in range(4)])
        np.testing.assert_allclose(grad[:, k], fd, rtol=1e-5, atol=1e-7)


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
    assert type(off) is not type(posture_row(human, 2, Weights()))
    assert posture_row(human, 2, Weights(pose_prior=None, sigma_posture=None)) is None
