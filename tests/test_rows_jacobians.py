"""Every row kind's Jacobian against central finite differences on the manifold:
d r / d v_t at v = 0, with q_t (+) eps e_i = pin.integrate(q_t, eps e_i)."""

from __future__ import annotations

import numpy as np
import pytest
from dense_blocks import dense_jacobian

import pinrecon as pr
from pinrecon.rows import (
    JointKeyframes,
    JointLimits,
    Measurement2D,
    Points3D,
    Posture,
    Smoothing,
    State,
    smoothing_sigmas,
)
from pinrecon.synthetic import project_tracks, smooth_motion

T = 5


@pytest.fixture(scope="module")
def setting():
    fig = pr.Figure.human()
    rng = np.random.default_rng(0)
    Q = smooth_motion(fig, T, 30.0, seed=1)
    Q = np.stack([fig.integrate(q, 0.3 * rng.normal(size=fig.nv)) for q in Q])  # off the limits' centre
    ortho = pr.Orthographic.from_view([0.3, -0.2, -1.0], scale=300.0, center=(500.0, 500.0))
    persp = pr.Perspective.look_at([0.5, 1.0, -4.0], [0.5, 0.0, 0.0])
    return fig, Q, ortho, persp


def _rows(fig, Q, ortho, persp):
    tr = project_tracks(fig, Q, ortho, fps=30.0, noise_px=5.0, seed=2)
    k = fig.keypoint_index(tr.names)
    ones = np.ones((T, len(k)))
    uv_p = persp.project(fig.keypoints(Q)[:, k]) + 3.0
    return {
        "measurement/orthographic": Measurement2D(ortho, np.arange(T), k, tr.points, ones),
        "measurement/perspective": Measurement2D(persp, np.arange(T), k, uv_p, ones),
        "measurement/missing+confidence": Measurement2D(
            ortho, np.arange(T), k, np.where(np.arange(len(k))[None, :, None] % 3 == 0, np.nan, tr.points), 0.5 * ones
        ),
        "points3d": Points3D([1, 3], k, fig.keypoints(Q[[1, 3]])[:, k] + 0.05, 0.02),
        "limits": JointLimits(fig, T, 0.01),
        "smoothing/R3xSO3": Smoothing(fig, T, 1 / 30, smoothing_sigmas(fig)),
        "smoothing/SE3": Smoothing(fig, T, 1 / 30, smoothing_sigmas(fig), root_group="SE3"),
        "posture": Posture(fig, T, fig.neutral(), 1.0),
        "keyframe joints": JointKeyframes(
            fig,
            [(2, 0.1, {"root_joint": np.r_[0.1, 0.2, 0.3, 0.0, 0.0, 0.38, 0.92], "left_knee_Z": 0.5}),
             (4, 0.1, {"root_joint": [1.0, 2.0, 3.0], "right_elbow_Z": 1.0})],
        ),
    }


def _evaluate(row, fig, Q, jacobian):
    out = row.evaluate(State(fig, Q, np.arange(T), jacobian), jacobian)
    return out if isinstance(out, list) else [out]


@pytest.mark.parametrize(
    "name",
    [
        "measurement/orthographic",
        "measurement/perspective",
        "measurement/missing+confidence",
        "points3d",
        "limits",
        "smoothing/R3xSO3",
        "smoothing/SE3",
        "posture",
        "keyframe joints",
    ],
)
def test_row_jacobian_matches_manifold_finite_differences(setting, name):
    """d r / d v against central differences (the lifted-pose rows' two rows per bone are not
    the derivative's own residuals, their normal equations are: tests/test_lifted_rows.py)."""
    fig, Q, ortho, persp = setting
    row = _rows(fig, Q, ortho, persp)[name]
    blocks = _evaluate(row, fig, Q, True)
    eps = 1e-6
    for bi, b in enumerate(blocks):
        J = dense_jacobian([b], T, fig.nv)[0]
        fd = np.zeros_like(J)
        for t in range(T):
            for i in range(fig.nv):
                dv = np.zeros(fig.nv)
                dv[i] = eps
                Qp, Qm = Q.copy(), Q.copy()
                Qp[t] = fig.integrate(Q[t], dv)
                Qm[t] = fig.integrate(Q[t], -dv)
                rp = _evaluate(row, fig, Qp, False)[bi].r.ravel()
                rm = _evaluate(row, fig, Qm, False)[bi].r.ravel()
                fd[:, t * fig.nv + i] = (rp - rm) / (2 * eps)
        scale = max(np.abs(J).max(), 1e-12)
        assert np.abs(J - fd).max() <= 1e-6 * scale, name
        assert np.abs(J).max() > 0 or name == "limits"


@pytest.mark.parametrize("loss", ["huber", "cauchy"])
def test_robust_loss_gradient_is_exact(setting, loss):
    """IRLS rows: J^T r of the reweighted rows is the gradient of 0.5 sum rho."""
    fig, Q, ortho, _ = setting
    tr = project_tracks(fig, Q, ortho, fps=30.0, noise_px=8.0, seed=3)
    k = fig.keypoint_index(tr.names)
    row = Measurement2D(ortho, np.arange(T), k, tr.points, np.ones((T, len(k))), loss=loss, loss_scale_px=4.0)
    b = _evaluate(row, fig, Q, True)[0]
    grad = dense_jacobian([b], T, fig.nv)[0].T @ b.r.ravel()
    eps = 1e-6
    fd = np.zeros_like(grad)
    for t in range(T):
        for i in range(fig.nv):
            dv = np.zeros(fig.nv)
            dv[i] = eps
            Qp, Qm = Q.copy(), Q.copy()
            Qp[t] = fig.integrate(Q[t], dv)
            Qm[t] = fig.integrate(Q[t], -dv)
            fd[t * fig.nv + i] = (_evaluate(row, fig, Qp, False)[0].cost - _evaluate(row, fig, Qm, False)[0].cost) / (2 * eps)
    assert np.abs(grad - fd).max() <= 1e-6 * np.abs(grad).max()
    # rho(s) <= s for both losses: the robust cost is below the plain least-squares cost
    l2 = Measurement2D(ortho, np.arange(T), k, tr.points, np.ones((T, len(k))))
    assert b.cost < _evaluate(l2, fig, Q, False)[0].cost


def test_vectorised_so3_difference_equals_pinocchio():
    import pinocchio as pin
    from scipy.spatial.transform import Rotation

    from pinrecon.rows.smoothing import _jlog3

    so3 = pin.liegroups.SO3()
    rng = np.random.default_rng(4)
    qa = np.array([so3.random() for _ in range(40)])
    qb = np.array([so3.random() for _ in range(40)])
    qb[:4] = qa[:4] + 1e-7 * rng.normal(size=(4, 4))  # tiny relative rotations
    qb[:4] /= np.linalg.norm(qb[:4], axis=1, keepdims=True)
    rel = Rotation.from_quat(qa).inv() * Rotation.from_quat(qb)
    d = rel.as_rotvec()
    J1 = _jlog3(d)
    J0 = -J1 @ np.swapaxes(rel.as_matrix(), 1, 2)
    for k in range(40):
        assert np.allclose(d[k], so3.difference(qa[k], qb[k]), atol=1e-12)
        assert np.allclose(J0[k], so3.dDifference(qa[k], qb[k], pin.ARG0), atol=1e-10)
        assert np.allclose(J1[k], so3.dDifference(qa[k], qb[k], pin.ARG1), atol=1e-10)
