"""Lifted-pose rows (pinrecon.rows.lifted): Jacobians against finite differences on the
manifold, the profiled rotation of an unknown lifter frame, and what the rows do in a
reconstruction (a mirrored limb the image cannot decide, a lifter wrong on a span, scale
and translation of the lifted points, the rotation recovered), against ground truth."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from dense_blocks import dense_jacobian
from scipy.spatial.transform import Rotation

import pinrecon as pr
from pinrecon.lifted import Lifted
from pinrecon.proportions import Proportions
from pinrecon.rows import State
from pinrecon.rows.lifted import LiftedPose, lifted_bones, procrustes_rotation
from pinrecon.synthetic import smooth_motion

T = 5


@pytest.fixture(scope="module")
def setting():
    fig = pr.Figure.human()
    rng = np.random.default_rng(0)
    Q = smooth_motion(fig, T, 30.0, seed=1)
    Q = np.stack([fig.integrate(q, 0.3 * rng.normal(size=fig.nv)) for q in Q])
    cam = pr.Perspective.look_at([0.5, 1.0, -4.0], [0.5, 0.0, 0.0])
    return fig, Q, cam


def _lifted_row(fig, Q, cam, frame, loss="l2", seed=3):
    """A lifted row whose lifter saw Q (camera axes, or axes turned by a known rotation) with
    noisy directions and uneven confidences."""
    rng = np.random.default_rng(seed)
    pairs = lifted_bones(fig, fig.keypoint_names)
    bones = np.array([[fig.keypoint_names.index(a), fig.keypoint_names.index(b)] for a, b in pairs])
    P = fig.keypoints(Q)
    v = P[:, bones[:, 1]] - P[:, bones[:, 0]]
    v += 0.05 * rng.normal(size=v.shape)
    L = v / np.linalg.norm(v, axis=-1, keepdims=True) @ cam.R.T  # camera axes
    R_lifter_cam = Rotation.from_rotvec([0.3, -1.2, 0.5]).as_matrix()
    if frame == "unknown":
        L = L @ R_lifter_cam.T
    conf = rng.uniform(0.3, 1.0, L.shape[:2])
    L[1, 2] = np.nan  # a missing bone
    R = cam.R.T if frame == "camera" else None
    return LiftedPose(np.arange(T), bones, L, conf, R, weight=30.0, loss=loss, loss_scale=0.3), R_lifter_cam


def _eval(row, fig, Q, jacobian, g=None, props=None, **kw):
    st = State(fig, Q, np.arange(T), jacobian, g=g, proportions=props)
    return row.evaluate(st, jacobian, **kw)


def _fd_jacobian(f, fig, Q, eps=1e-6):
    cols = []
    for t in range(T):
        for i in range(fig.nv):
            dv = np.zeros(fig.nv)
            dv[i] = eps
            Qp, Qm = Q.copy(), Q.copy()
            Qp[t] = fig.integrate(Q[t], dv)
            Qm[t] = fig.integrate(Q[t], -dv)
            cols.append((f(Qp) - f(Qm)) / (2 * eps))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("frame", ["camera", "unknown"])
def test_jacobian_matches_manifold_finite_differences(setting, frame):
    """d r / d v_t against central differences of pin.integrate; an unknown frame's rotation
    held at its profiled value (the rows' Jacobian is the one at fixed R)."""
    fig, Q, cam = setting
    row, _ = _lifted_row(fig, Q, cam, frame)
    R = row.rotation(State(fig, Q, np.arange(T), False))
    b = _eval(row, fig, Q, True, R=R)
    J = dense_jacobian([b], T, fig.nv)[0]
    fd = _fd_jacobian(lambda QQ: _eval(row, fig, QQ, False, R=R).r.ravel(), fig, Q)
    assert np.abs(J).max() > 0.1
    assert np.abs(J - fd).max() <= 1e-6 * np.abs(J).max()


@pytest.mark.parametrize("frame", ["camera", "unknown"])
@pytest.mark.parametrize("loss", ["l2", "cauchy", "huber"])
def test_gradient_of_the_profiled_robust_cost_is_exact(setting, frame, loss):
    """J^T r of the reweighted rows is the gradient of the row's own cost, the unknown
    frame's rotation re-solved at every evaluation (the envelope theorem); the robust cost
    is below the plain one."""
    fig, Q, cam = setting
    row, _ = _lifted_row(fig, Q, cam, frame, loss)
    row.irls = 100  # the robust Procrustes converged, so the profiled cost is stationary in R
    b = _eval(row, fig, Q, True)
    grad = dense_jacobian([b], T, fig.nv)[0].T @ b.r.ravel()
    fd = _fd_jacobian(lambda QQ: np.array(_eval(row, fig, QQ, False).cost), fig, Q)
    assert np.abs(grad - fd).max() <= 2e-5 * np.abs(grad).max()
    if loss != "l2":
        l2, _ = _lifted_row(fig, Q, cam, frame, "l2")
        assert b.cost < _eval(l2, fig, Q, False).cost


def test_proportions_columns_match_finite_differences(setting):
    """With the figure's segment scale factors as globals: d r / d g by central differences."""
    fig, Q, cam = setting
    props = Proportions.default(fig)
    g = 0.1 * np.random.default_rng(5).normal(size=props.n)
    row, _ = _lifted_row(fig, Q, cam, "camera")
    b = _eval(row, fig, Q, True, g=g, props=props)
    eps = 1e-6
    fd = np.stack([(_eval(row, fig, Q, False, g=g + eps * e, props=props).r - _eval(row, fig, Q, False, g=g - eps * e,
                    props=props).r).ravel() / (2 * eps) for e in np.eye(props.n)], axis=-1)
    Jg = np.zeros_like(fd)
    Jg[:, b.gcols] = b.Jg.reshape(fd.shape[0], -1)
    assert np.abs(fd).max() > 0.01
    assert np.abs(Jg - fd).max() <= 1e-6 * np.abs(fd).max()


def test_procrustes_recovers_a_rotation_from_noisy_directions():
    rng = np.random.default_rng(1)
    L = rng.normal(size=(200, 3))
    L /= np.linalg.norm(L, axis=1, keepdims=True)
    R = Rotation.from_rotvec([2.0, -0.4, 1.1]).as_matrix()
    D = L @ R.T + 0.02 * rng.normal(size=L.shape)
    R_est = procrustes_rotation(D, L, np.ones(len(L)))
    assert np.degrees(Rotation.from_matrix(R_est @ R.T).magnitude()) < 1.0
    assert np.isclose(np.linalg.det(R_est), 1.0)
    # mirrored data gives the best rotation, never a reflection
    assert np.isclose(np.linalg.det(procrustes_rotation(D * [1, 1, -1], L, np.ones(len(L)))), 1.0)
