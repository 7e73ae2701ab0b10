"""The speed work's building blocks against independent references: the active-set band
assembly against a dense J^T J built entry by entry from the row blocks, the NumPy
kinematics against Pinocchio, and the projected keypoint Jacobians against the plain
product with the keypoint Jacobians."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from dense_blocks import dense_jacobian

import pinrecon as pr
from pinrecon import kinematics
from pinrecon.banded import ActiveNormalEquations, ArrowheadFactor
from pinrecon.problem import ReconstructionProblem, keyframe_rows
from pinrecon.rows import (
    JointLimits,
    Measurement2D,
    Posture,
    RowBlock,
    Smoothing,
    State,
    smoothing_sigmas,
)
from pinrecon.solver import _flatten
from pinrecon.synthetic import bundled_motion, point_keyframes, project_tracks, smooth_motion


def _from_band(ab, n):
    H = np.zeros((n, n))
    for k in range(ab.shape[0]):
        idx = np.arange(max(n - k, 0))
        H[idx + k, idx] = ab[k, : n - k]
    return np.tril(H) + np.tril(H, -1).T


def _blocks(T, seed=1, gap=True):
    fig = pr.Figure.human()
    Q = smooth_motion(fig, T, 30.0, seed=seed)
    cam = pr.Orthographic.from_view([0, 0, -1], scale=300.0, center=(500.0, 500.0))
    tr = project_tracks(fig, Q, cam, fps=30.0, noise_px=3.0, missing=0.2, seed=seed)
    if T > 3 and gap:
        tr.points[2] = np.nan  # a frame without observations: two runs of frames
    k = fig.keypoint_index(tr.names)
    obs = tr.observed.any(1)
    rows = [Measurement2D(cam, np.where(obs)[0], k, tr.points[obs], tr.weights()[obs]), JointLimits(fig, T, 0.01),
            Smoothing(fig, T, 1 / 30, smoothing_sigmas(fig)), Posture(fig, T, fig.neutral(), 1.0)]
    rows += keyframe_rows(fig, point_keyframes(fig, Q, sorted({0, T // 2, T - 1})), 1)
    prob = ReconstructionProblem(fig, T, rows)
    Qx = np.stack([fig.integrate(q, 0.2 * np.random.default_rng(i).normal(size=fig.nv)) for i, q in enumerate(Q)])
    blocks = _flatten(prob.evaluate(Qx, True))
    rng = np.random.default_rng(seed)
    if T >= 7:  # made-up row kinds: a frame span of 3 with repeated frames, the same frame twice, repeats
        blocks.append(RowBlock(np.array([[0, 3], [1, 4], [1, 4], [2, 2]]), rng.normal(size=(4, 2)),
                               rng.normal(size=(4, 2, 2, 3)), np.array([1, 7, 20]), "span3"))
        blocks.append(RowBlock(np.array([[5], [5], [6]]), rng.normal(size=(3, 2)), rng.normal(size=(3, 1, 2)),
                               np.array([8, 30]), "diagonal repeats", diagonal=True))
    return fig, blocks


@pytest.mark.parametrize("T", [1, 7, 40])
@pytest.mark.parametrize("held", [False, True])
@pytest.mark.parametrize("gap", [True, False])
def test_active_band_equals_dense_normal_equations(T, held, gap):
    # gap=False: the measurements cover every frame, whose products are written into the
    # band without zeroing it first (the rest of the band is zeroed after them)
    fig, blocks = _blocks(T, gap=gap)
    nv = fig.nv
    J, r = dense_jacobian(blocks, T, nv)
    active = None if not held else np.arange(nv) % 3 != 1
    ne = ActiveNormalEquations(T, nv, blocks, active)
    idx = (np.arange(T)[:, None] * nv + ne.act[None, :]).ravel()
    H, g = (J.T @ J)[np.ix_(idx, idx)], (J.T @ r)[idx]
    for k in range(2):  # the buffers are reused: the second assembly must be the same
        if k:
            ne.ab[...] = 7.0  # what a factorisation leaves behind: every band entry overwritten
        g_b, _ = ne.assemble(blocks)
        Hb = _from_band(np.array(ne.ab), ne.n)
        assert np.abs(Hb - H).max() <= 1e-12 * np.abs(H).max()
        assert np.abs(g_b - g).max() <= 1e-12 * np.abs(g).max()
    assert np.abs(ne.gradient(blocks, [b.r for b in blocks]) - g).max() <= 1e-12 * np.abs(g).max()
    assert ne.kd >= ne.na  # the frame view of the band stays one-to-one
    # the factor solves the damped system
    ne.assemble(blocks)
    ne.ab[0] += 1.0
    x, _ = ArrowheadFactor(ne.ab).solve(g)
    np.testing.assert_allclose((H + np.eye(len(g))) @ x, g, rtol=1e-8, atol=1e-8 * np.abs(g).max())


def test_band_of_diagonal_blocks_only_is_rebuilt_from_zero():
    fig, blocks = _blocks(7)
    blocks = [b for b in blocks if b.diagonal]
    J, r = dense_jacobian(blocks, 7, fig.nv)
    ne = ActiveNormalEquations(7, fig.nv, blocks)
    ne.ab[...] = 1.0  # what a factorisation leaves behind
    ne.assemble(blocks)
    np.testing.assert_allclose(_from_band(np.array(ne.ab), ne.n), J.T @ J, atol=1e-12 * np.abs(J.T @ J).max())


def test_one_frame_with_many_row_groups_and_a_frame_twice():
    rng = np.random.default_rng(3)
    blocks = [RowBlock(np.array([[0], [0]]), rng.normal(size=(2, 3)), rng.normal(size=(2, 1, 3, 4)), np.array([1, 5, 7, 9]), "a"),
              RowBlock(np.array([[0, 0]]), rng.normal(size=(1, 2)), rng.normal(size=(1, 2, 2, 3)), np.array([2, 5, 8]), "b"),
              RowBlock(np.array([[0], [0], [0]]), rng.normal(size=(3, 2)), rng.normal(size=(3, 1, 2)), np.array([3, 9]),
                       "c", diagonal=True),
              RowBlock(np.array([[0, 0]]), rng.normal(size=(1, 2)), rng.normal(size=(1, 2, 2)), np.array([4, 7]), "d",
                       diagonal=True)]
    J, r = dense_jacobian(blocks, 1, 10)
    for active in (None, np.arange(10) != 5):
        ne = ActiveNormalEquations(1, 10, blocks, active)
        g_b, _ = ne.assemble(blocks)
        a = ne.act
        np.testing.assert_allclose(_from_band(np.array(ne.ab), ne.n), (J.T @ J)[np.ix_(a, a)], atol=1e-12)
        np.testing.assert_allclose(g_b, (J.T @ r)[a], atol=1e-12)


@pytest.fixture(scope="module")
def figures():
    walk, _, _ = bundled_motion("walk", lock=())
    return {"human": pr.Figure.human(), "human joints": pr.Figure.human("joints"), "bvh (92 joints)": walk}


@pytest.mark.parametrize("name", ["human", "human joints", "bvh (92 joints)"])
def test_numpy_kinematics_equal_pinocchio(figures, name):
    fig = figures[name]
    Q = np.stack([fig.random_configuration(s) for s in range(kinematics.BATCH_MIN_FRAMES + 3)])
    joints = list(range(1, fig.model.njoints))
    kinds = kinematics.joint_kinds(fig.model)
    assert kinds is not None
    R, p, Jw = kinematics.batch_joint_kinematics(fig.model, kinds, Q, joints, True)
    data = fig.model.createData()
    for t in (0, 5, len(Q) - 1):
        J_ref = pin.computeJointJacobians(fig.model, data, Q[t])
        np.testing.assert_allclose(Jw[t], J_ref, atol=1e-12)
        for u, j in enumerate(joints):
            np.testing.assert_allclose(R[t, u], data.oMi[j].rotation, atol=1e-12)
            np.testing.assert_allclose(p[t, u], data.oMi[j].translation, atol=1e-12)


def test_long_trajectories_are_formed_in_chunks(figures, monkeypatch):
    fig = figures["human"]
    Q = np.stack([fig.random_configuration(s) for s in range(150)])
    P_ref, J_ref = fig.keypoint_jacobians(Q)
    monkeypatch.setattr(kinematics, "CHUNK_FRAMES", 64)
    P, J = fig.keypoint_jacobians(Q)
    np.testing.assert_allclose(P, P_ref, atol=1e-12)
    np.testing.assert_allclose(J, J_ref, atol=1e-12)


def test_projected_point_jacobians_equal_the_product(figures):
    fig = figures["human"]
    Q = np.stack([fig.random_configuration(s) for s in range(9)])
    st = State(fig, Q, np.arange(9), True)
    slots, kp = np.array([0, 3, 4, 8]), np.array([0, 5, 9, 16])
    Jk = st.jacobians[slots][:, kp]  # (N, M, 3, nv)
    rng = np.random.default_rng(0)
    A = rng.normal(size=(2, 3))
    A_pp = rng.normal(size=(4, 4, 2, 3))
    w = rng.random((4, 4))
    cols = np.array([0, 3, 7, 12, 30])
    np.testing.assert_allclose(st.point_jacobians(slots, kp, A), np.matmul(A, Jk), atol=1e-12)
    np.testing.assert_allclose(st.point_jacobians(slots, kp, A_pp, w), np.matmul(A_pp, Jk) * w[..., None, None],
                               atol=1e-12)
    np.testing.assert_allclose(st.point_jacobians(slots, kp, None, None, cols), Jk[..., cols], atol=1e-12)


@pytest.mark.parametrize("name", ["human", "bvh (92 joints)"])
def test_trajectory_integration_equals_pinocchio(figures, name):
    fig = figures[name]
    rng = np.random.default_rng(2)
    n = 4 * kinematics.BATCH_MIN_FRAMES
    Q = np.stack([fig.random_configuration(s) for s in range(n)])
    V = rng.normal(size=(n, fig.nv)) * np.where(np.arange(n) % 2, 1.0, 1e-7)[:, None]  # small rotations too
    expected = np.stack([pin.integrate(fig.model, q, v) for q, v in zip(Q, V)])
    np.testing.assert_allclose(fig.integrate(Q, V), expected, atol=1e-13)


@pytest.mark.parametrize("n, kd, k, chunk_rows", [(185, 7, 3, 30), (400, 12, 10, 48), (90, 5, 1, 20), (50, 6, 4, 500)])
def test_forward_solve_in_chunks_equals_a_dense_triangular_solve(monkeypatch, n, kd, k, chunk_rows):
    """``forward_solve`` cuts the band factor into chunks of rows (the last one here
    shorter than ``kd`` where n allows): the result is ``L^-1 B`` computed densely."""
    from scipy.linalg import solve_triangular
    from scipy.linalg.lapack import dpbtrf

    from pinrecon import banded

    rng = np.random.default_rng(n + kd)
    A = np.zeros((n, n))
    for d in range(kd + 1):
        v = rng.uniform(-1.0, 1.0, n - d)
        A[np.arange(d, n), np.arange(n - d)] = v
        A[np.arange(n - d), np.arange(d, n)] = v
    A += (2.0 * kd + 2.0) * np.eye(n)  # diagonally dominant: positive definite
    ab = np.zeros((kd + 1, n), order="F")
    for d in range(kd + 1):
        ab[d, : n - d] = np.diagonal(A, -d)
    c, info = dpbtrf(ab, lower=1)
    assert info == 0
    B = rng.standard_normal((n, k))
    monkeypatch.setattr(banded, "_CHUNK_BYTES", 8 * (kd + 1) * chunk_rows)
    Z = banded.forward_solve(c, B)
    L = np.linalg.cholesky(A)
    ref = solve_triangular(L, B, lower=True)
    assert np.abs(Z - ref).max() <= 1e-12 * np.abs(ref).max()
