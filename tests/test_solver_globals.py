"""Global unknowns in the solver: row Jacobian columns w.r.t. the globals, the Schur
complement against a dense solve, and a calibration solved end to end.

Ground truth: central finite differences of the residuals in ``g``; a dense (T nv + n_g)
least-squares system built entry by entry from the row blocks; and a synthetic subject
whose true proportions and focal length are known."""

from __future__ import annotations

import numpy as np
import pytest
from dense_blocks import dense_jacobian

import pinrecon as pr
from pinrecon.proportions import Proportions
from pinrecon.rows import (
    CameraScale,
    GlobalPrior,
    JointLimits,
    Measurement2D,
    Points3D,
    Posture,
    Smoothing,
    State,
    smoothing_sigmas,
)
from pinrecon.rows.contact import ContactHeight, ContactVelocity
from pinrecon.rows.floor import FloorPenetration
from pinrecon.solver import ArrowheadFactor, BandedNormalEquations, SolverOptions, solve
from pinrecon.synthetic import smooth_motion

T = 5


class Problem:
    """Rows on a time grid; the figure's log factors are ``g[:proportions.n]``."""

    def __init__(self, figure, n_frames, rows, proportions=None):
        self.figure, self.n_frames, self.nv, self.rows = figure, n_frames, figure.nv, rows
        self.proportions = proportions
        self.kinematic_frames = np.unique(np.concatenate([np.asarray(r.kinematic_frames, int) for r in rows]))

    def evaluate(self, Q, jacobian=True, g=None):
        props = self.proportions if g is not None else None
        st = State(self.figure, Q, self.kinematic_frames, jacobian, g=g, proportions=props)
        return [r.evaluate(st, jacobian) for r in self.rows]

    def retract(self, Q, dQ):
        return self.figure.integrate(Q, dQ)


def _flat(out):
    return [b for item in out for b in (item if isinstance(item, list) else [item])]


@pytest.fixture(scope="module")
def setting():
    fig = pr.Figure.human()
    props = Proportions.human(fig)
    rng = np.random.default_rng(0)
    Q = smooth_motion(fig, T, 30.0, seed=1)
    Q = np.stack([fig.integrate(q, 0.3 * rng.normal(size=fig.nv)) for q in Q])
    ortho = pr.Orthographic.from_view([0.3, -0.2, -1.0], scale=300.0, center=(500.0, 500.0))
    persp = pr.Perspective.look_at([0.5, 1.0, -4.0], [0.5, 0.0, 0.0])
    g = np.r_[rng.normal(0.0, 0.1, props.n), 0.07, rng.normal(0.0, 0.05, 6)]  # log factors, log f, camera pose
    return fig, props, Q, ortho, persp, g


def _rows(fig, props, Q, ortho, persp):
    n = props.n
    k = np.arange(fig.K)
    P = fig.keypoints(Q)
    ones = np.ones((T, fig.K))
    uv_o = ortho.project(P) + 4.0
    uv_p = persp.project(P) + 3.0
    missing = np.where(np.arange(fig.K)[None, :, None] % 3 == 0, np.nan, uv_p)
    distorted = pr.Perspective(persp.K, persp.R, persp.t, dist=[-0.2, 0.05, 0.001, -0.002, 0.01])
    return {
        "measurement/orthographic+scale": Measurement2D(
            ortho, np.arange(T), k, uv_o, ones, intrinsics=CameraScale(ortho, n)
        ),
        "measurement/perspective+focal": Measurement2D(
            persp, np.arange(T), k, uv_p, ones, intrinsics=CameraScale(persp, n)
        ),
        "measurement/perspective, proportions only": Measurement2D(persp, np.arange(T), k, uv_p, ones),
        "measurement/missing+confidence": Measurement2D(
            persp, np.arange(T), k, missing, 0.5 * ones, intrinsics=CameraScale(persp, n)
        ),
        "measurement/distorted perspective+focal": Measurement2D(
            distorted, np.arange(T), k, uv_p, ones, intrinsics=CameraScale(distorted, n)
        ),
        "measurement/perspective+focal+pose": Measurement2D(
            persp, np.arange(T), k, missing, 0.5 * ones, intrinsics=CameraScale(persp, n, pose_col=n + 1)
        ),
        "measurement/distorted perspective+focal+pose": Measurement2D(
            distorted, np.arange(T), k, uv_p, ones, intrinsics=CameraScale(distorted, n, pose_col=n + 1)
        ),
        "points3d": Points3D([1, 3], k, P[[1, 3]] + 0.05, 0.02),
        "prior": GlobalPrior(np.arange(n), np.linspace(-0.1, 0.1, n), 0.1),
        # feet rows on every keypoint, a tilted floor (every point below it: the hinge is on)
        "contact velocity": ContactVelocity(k, np.ones((T, fig.K), bool), 30.0, normal=[0.1, 0.2, 1.0]),
        "contact height": ContactHeight(k, np.ones((T, fig.K), bool), [0.1, 0.2, 1.0], 0.0, 0.03),
        "floor penetration": FloorPenetration(k, np.arange(T), [0.1, 0.2, 1.0], 5.0, 0.01),
    }


def _eval(row, fig, props, Q, g, jacobian):
    st = State(fig, Q, np.arange(T), jacobian, g=g, proportions=props)
    return row.evaluate(st, jacobian)


def _dense_g(block, n_g):
    N, m = block.r.shape
    J = np.zeros((N * m, n_g))
    if block.Jg is not None:
        J[:, np.asarray(block.gcols)] = block.Jg.reshape(N * m, -1)
    return J


@pytest.mark.parametrize(
    "name",
    [
        "measurement/orthographic+scale",
        "measurement/perspective+focal",
        "measurement/perspective, proportions only",
        "measurement/missing+confidence",
        "measurement/distorted perspective+focal",
        "measurement/perspective+focal+pose",
        "measurement/distorted perspective+focal+pose",
        "points3d",
        "prior",
        "contact velocity",
        "contact height",
        "floor penetration",
    ],
)
def test_global_jacobian_columns_match_finite_differences(setting, name):
    fig, props, Q, ortho, persp, g = setting
    row = _rows(fig, props, Q, ortho, persp)[name]
    b = _eval(row, fig, props, Q, g, True)
    n_g = len(g)
    J = _dense_g(b, n_g)
    fd = np.zeros_like(J)
    eps = 1e-6
    for i in range(n_g):
        e = np.zeros(n_g)
        e[i] = eps
        plus = _eval(row, fig, props, Q, g + e, False).r.ravel()
        minus = _eval(row, fig, props, Q, g - e, False).r.ravel()
        fd[:, i] = (plus - minus) / (2 * eps)
    assert np.abs(J - fd).max() <= 1e-6 * np.abs(J).max()
    assert np.abs(J[:, : props.n]).max() > 0  # every kind here depends on the proportions
    if "+" in name or "missing" in name:
        assert np.abs(J[:, props.n]).max() > 0  # and on the camera scale
    pose = np.abs(J[:, props.n + 1 :]).max(axis=0)
    assert np.all(pose > 0) if "pose" in name else not pose.any()  # each of the six pose globals, or none


def test_robust_measurement_gradient_in_the_globals_is_exact(setting):
    fig, props, Q, ortho, persp, g = setting
    k = np.arange(fig.K)
    uv = persp.project(fig.keypoints(Q)) + np.random.default_rng(3).normal(0.0, 8.0, (T, fig.K, 2))
    row = Measurement2D(persp, np.arange(T), k, uv, np.ones((T, fig.K)), loss="huber", loss_scale_px=4.0,
                        intrinsics=CameraScale(persp, props.n))
    b = _eval(row, fig, props, Q, g, True)
    grad = _dense_g(b, len(g)).T @ b.r.ravel()
    eps = 1e-6
    def cost(gg):
        return _eval(row, fig, props, Q, gg, False).cost

    fd = np.array([(cost(g + eps * e) - cost(g - eps * e)) / (2 * eps) for e in np.eye(len(g))])
    assert np.abs(grad - fd).max() <= 1e-6 * np.abs(grad).max()


@pytest.fixture(scope="module")
def small_problem():
    fig = pr.Figure.human()
    props = Proportions.human(fig)
    T_ = 6
    Q = smooth_motion(fig, T_, 30.0, seed=4)
    cam = pr.Perspective.look_at([2.5, 1.2, 4.0], [0.3, 0.0, 0.0])
    P = fig.keypoints(Q)
    rng = np.random.default_rng(5)
    k = np.arange(fig.K)
    rows = [
        Measurement2D(cam, np.arange(T_), k, cam.project(P) + rng.normal(0, 2.0, (T_, fig.K, 2)), np.ones((T_, fig.K)),
                      intrinsics=CameraScale(cam, props.n)),
        JointLimits(fig, T_, 0.01),
        Smoothing(fig, T_, 1 / 30, smoothing_sigmas(fig)),
        Posture(fig, T_, fig.neutral(), 3.0),
        Points3D([0, 5], k, P[[0, 5]], 0.02),
        GlobalPrior(np.arange(props.n), 0.0, 0.1),
    ]
    Qx = np.stack([fig.integrate(q, 0.2 * rng.normal(size=fig.nv)) for q in Q])
    g = np.r_[rng.normal(0, 0.1, props.n), -0.2]
    return Problem(fig, T_, rows, props), Qx, g


def test_schur_solve_equals_a_dense_solve_of_the_damped_normal_equations(small_problem):
    prob, Qx, g = small_problem
    T_, nv, n_g = prob.n_frames, prob.nv, len(g)
    blocks = _flat(prob.evaluate(Qx, True, g))
    J, r = dense_jacobian(blocks, T_, nv, n_g)
    H, grad = J.T @ J, J.T @ r
    ne = BandedNormalEquations(T_, nv, blocks)
    D0, Dd, gx = ne.assemble(blocks)
    B, C, gg = ne.assemble_globals(blocks, n_g)
    n = T_ * nv
    # the border is assembled exactly
    assert np.abs(B - H[:n, n:]).max() <= 1e-12 * np.abs(H).max()
    assert np.abs(C - H[n:, n:]).max() <= 1e-12 * np.abs(H).max()
    np.testing.assert_allclose(np.r_[gx, gg], grad, rtol=0, atol=1e-12 * np.abs(grad).max())
    lam = 1e-2
    ab = ne.band(D0, Dd)
    d_x, d_g = ab[0].copy(), np.diag(C).copy()
    ab[0] += lam * d_x
    dx, dg = ArrowheadFactor(ab, B, C + lam * np.diag(d_g)).solve(-gx, -gg)
    step = np.linalg.solve(H + lam * np.diag(np.r_[d_x, d_g]), -grad)
    assert np.abs(np.r_[dx, dg] - step).max() <= 1e-9 * np.abs(step).max()


@pytest.mark.parametrize("held", [None, "unseen", [0, 1, 2, 9, 20]])
def test_the_active_assembler_border_equals_the_dense_one(small_problem, held):
    """What the solver uses (``ActiveNormalEquations``) against J^T J of the dense
    Jacobian, over the active tangent entries: all, those the measurements see (their
    columns are then consecutive and their product is written straight into the border)
    or some held."""
    from pinrecon.banded import ActiveNormalEquations

    prob, Qx, g = small_problem
    T_, nv, n_g = prob.n_frames, prob.nv, len(g)
    blocks = _flat(prob.evaluate(Qx, True, g))
    J, r = dense_jacobian(blocks, T_, nv, n_g)
    active = np.ones(nv, bool)
    if held == "unseen":
        active[:] = False
        active[np.asarray(blocks[0].cols)] = True
    elif held is not None:
        active[held] = False
    cols = np.r_[(np.arange(T_)[:, None] * nv + np.flatnonzero(active)[None, :]).ravel(), T_ * nv + np.arange(n_g)]
    Ja = J[:, cols]
    H, grad = Ja.T @ Ja, Ja.T @ r
    n = len(cols) - n_g
    ne = ActiveNormalEquations(T_, nv, blocks, active)
    gx, (B, C, gg) = ne.assemble(blocks, n_g)
    tol = 1e-12 * np.abs(H).max()
    assert np.abs(B - H[:n, n:]).max() <= tol
    assert np.abs(C - H[n:, n:]).max() <= tol
    np.testing.assert_allclose(np.r_[gx, gg], grad, rtol=0, atol=1e-12 * np.abs(grad).max())


def test_solve_with_globals_descends_and_holds_frozen_globals(small_problem):
    prob, Qx, g = small_problem
    res = solve(prob, Qx, SolverOptions(max_iterations=30), g0=g)
    assert res.g is not None and res.g.shape == g.shape and res.cost < res.initial_cost
    accepted = [r.cost for r in res.report if r.accepted]
    assert all(b <= a + 1e-9 for a, b in zip(accepted, accepted[1:]))
    geo = solve(prob, Qx, SolverOptions(max_iterations=30, geodesic_acceleration=True), g0=g)
    assert geo.cost < geo.initial_cost and np.all(np.isfinite(geo.g))
    frozen = np.ones(len(g), bool)
    frozen[[0, 3, len(g) - 1]] = False
    held = solve(prob, Qx, SolverOptions(max_iterations=10), g0=g, active_globals=frozen)
    np.testing.assert_array_equal(held.g[~frozen], g[~frozen])
    assert np.abs(held.g[frozen] - g[frozen]).max() > 1e-4


def test_without_globals_the_solve_is_unchanged(small_problem):
    prob, Qx, _ = small_problem
    motion = Problem(prob.figure, prob.n_frames, prob.rows[1:4] + [prob.rows[4]])  # no global rows
    a = solve(motion, Qx, SolverOptions(max_iterations=8))
    b = solve(motion, Qx, SolverOptions(max_iterations=8), g0=np.zeros(0))
    assert a.g is None and b.g.shape == (0,)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)
    assert a.iterations == b.iterations and a.cost == pytest.approx(b.cost, rel=1e-12)


@pytest.mark.parametrize("focal_start", [1.0, 0.7])
def test_calibration_recovers_true_proportions_and_focal_length(focal_start):
    """A subject whose forearms are 20 % longer and shanks 10 % shorter than the generic
    human, noiseless 2D tracks through a perspective camera and 3D point keyframes every
    8 frames; solved from the generic figure (and a focal length 30 % short)."""
    generic = pr.Figure.human()
    props = Proportions.human(generic)
    truth = np.zeros(props.n)
    truth[props.names.index("forearm")] = np.log(1.2)
    truth[props.names.index("shank")] = np.log(0.9)
    subject = props.calibrated_figure(truth)
    T_ = 60
    Q = smooth_motion(subject, T_, 30.0, seed=3)
    cam = pr.Perspective.look_at([2.5, 1.2, 4.0], [1.0, 0.0, 0.0], f_px=1000.0)
    P = subject.keypoints(Q)
    K0 = cam.K.copy()
    K0[:2, :2] *= focal_start
    cam0 = pr.Perspective(K0, cam.R, cam.t)
    intr = CameraScale(cam0, props.n)
    k = np.arange(generic.K)
    keys = np.arange(0, T_, 8)
    rows = [
        Measurement2D(cam0, np.arange(T_), k, cam.project(P), np.ones((T_, generic.K)), intrinsics=intr),
        JointLimits(generic, T_, 0.01),
        Smoothing(generic, T_, 1 / 30, smoothing_sigmas(generic)),
        Points3D(keys, k, P[keys], 0.005),
        GlobalPrior(np.arange(props.n), 0.0, 0.1),
    ]
    rng = np.random.default_rng(0)
    Q0 = np.stack([generic.integrate(q, 0.05 * rng.normal(size=generic.nv)) for q in Q])
    res = solve(Problem(generic, T_, rows, props), Q0, SolverOptions(max_iterations=200, ftol=1e-10),
                g0=np.zeros(props.n + 1))
    factors = np.exp(res.g[: props.n])
    np.testing.assert_allclose(factors, np.exp(truth), rtol=0.02)
    assert factors[props.names.index("forearm")] == pytest.approx(1.2, rel=0.005)
    assert factors[props.names.index("shank")] == pytest.approx(0.9, rel=0.005)
    assert intr.value(res.g) == pytest.approx(1000.0, rel=0.005)
    # the calibrated figure reproduces the subject's bone lengths
    cal = props.calibrated_figure(res.g[: props.n])
    i = cal.keypoint_index(["left_elbow", "left_wrist"])
    forearm = np.linalg.norm(np.diff(cal.keypoints(Q)[:, i], axis=1), axis=-1)
    forearm_true = np.linalg.norm(np.diff(P[:, i], axis=1), axis=-1)
    np.testing.assert_allclose(forearm, forearm_true, rtol=0.005)


@pytest.mark.parametrize("data_only", [False, True])
def test_globals_information_is_the_schur_complement_of_the_dense_normal_equations(small_problem, data_only):
    """``globals_information``: ``C - B^T A^-1 B`` of ``J^T J``, over every row or over the
    kept ones (the 2D measurements and 3D points), against the dense Jacobian, with the
    same jitter on the motion block (1e-9 of its largest diagonal entry; a unit diagonal
    where no kept row touches a tangent entry): 2D rows alone leave a frame's motion
    rank-deficient, and the jitter is what makes that block invertible at all."""
    from pinrecon.solver import globals_information

    prob, Qx, g = small_problem
    T_, nv, n_g = prob.n_frames, prob.nv, len(g)
    keep = (lambda b: b.name in ("measurement", "points3d")) if data_only else None
    blocks = [b for b in _flat(prob.evaluate(Qx, True, g)) if keep is None or keep(b)]
    J, _ = dense_jacobian(blocks, T_, nv, n_g)
    H = J.T @ J
    n = T_ * nv
    A, B, C = H[:n, :n], H[:n, n:], H[n:, n:]
    jitter = 1e-9 * np.diag(A).max()
    A = A + np.diag(jitter + np.where(np.diag(A) > jitter, 0.0, 1.0))
    want = C - B.T @ np.linalg.solve(A, B)
    got = globals_information(prob, Qx, g, rows=keep)
    assert np.abs(got - want).max() <= 1e-6 * np.abs(want).max()
    assert np.abs(got - got.T).max() == 0.0
