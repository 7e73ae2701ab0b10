"""The block-banded solver: assembly against a dense J^T J, and the guarantees it gives."""

from __future__ import annotations

import numpy as np
import pytest
from dense_blocks import dense_jacobian

import pinrecon as pr
from pinrecon.problem import ReconstructionProblem, keyframe_rows
from pinrecon.rows import JointLimits, Measurement2D, Posture, RowBlock, Smoothing, smoothing_sigmas
from pinrecon.solver import BandedNormalEquations, SolverOptions, _flatten, solve
from pinrecon.synthetic import point_keyframes, project_tracks, smooth_motion


@pytest.fixture(scope="module")
def problem():
    fig = pr.Figure.human()
    T = 7
    Q = smooth_motion(fig, T, 30.0, seed=1)
    cam = pr.Orthographic.from_view([0, 0, -1], scale=300.0, center=(500.0, 500.0))
    tr = project_tracks(fig, Q, cam, fps=30.0, noise_px=3.0, missing=0.2, seed=1)
    tr.points[2] = np.nan  # a frame without observations
    k = fig.keypoint_index(tr.names)
    obs = tr.observed.any(1)
    rows = [
        Measurement2D(cam, np.where(obs)[0], k, tr.points[obs], tr.weights()[obs]),
        JointLimits(fig, T, 0.01),
        Smoothing(fig, T, 1 / 30, smoothing_sigmas(fig)),
        Posture(fig, T, fig.neutral(), 1.0),
    ] + keyframe_rows(fig, point_keyframes(fig, Q, [0, 3, 6]), 1)
    prob = ReconstructionProblem(fig, T, rows)
    Qx = np.stack([fig.integrate(q, 0.2 * np.random.default_rng(i).normal(size=fig.nv)) for i, q in enumerate(Q)])
    return fig, prob, Qx, Q


def test_banded_assembly_equals_dense_normal_equations(problem):
    fig, prob, Qx, _ = problem
    blocks = _flatten(prob.evaluate(Qx, True))
    T, nv = prob.n_frames, prob.nv
    J, r = dense_jacobian(blocks, T, nv)
    H, g = J.T @ J, J.T @ r
    ne = BandedNormalEquations(T, nv, blocks)
    D0, Dd, g_b = ne.assemble(blocks)
    ab = ne.band(D0, Dd)
    Hb = np.zeros_like(H)
    for k in range(ab.shape[0]):
        idx = np.arange(T * nv - k)
        Hb[idx + k, idx] = ab[k, : T * nv - k]
    Hb = np.tril(Hb) + np.tril(Hb, -1).T
    assert np.abs(H - Hb).max() <= 1e-12 * np.abs(H).max()
    assert np.abs(g - g_b).max() <= 1e-12 * np.abs(g).max()
    # the derived half-bandwidth covers the true one and is the structural 2 nv + 5
    true_bw = max(abs(i - j) for i, j in zip(*np.nonzero(np.abs(H) > 0)))
    assert true_bw <= ne.kd == 2 * nv + 5


def test_band_grows_with_the_widest_row_span():
    # a made-up row kind touching frames t and t+3 with a dense 2-column block
    blk = RowBlock(np.array([[0, 3], [1, 4]]), np.ones((2, 1)), np.ones((2, 2, 1, 2)), np.array([1, 4]), "span3")
    ne = BandedNormalEquations(6, 5, [blk])
    assert ne.kd == 3 * 5 + (4 - 1)


def test_solve_decreases_cost_and_keeps_quaternions_unit(problem):
    fig, prob, Qx, Q = problem
    res = solve(prob, Qx, SolverOptions(max_iterations=50))
    assert res.cost < res.initial_cost and np.all(np.isfinite(res.x))
    assert all(r.cost <= res.initial_cost + 1e-9 for r in res.report if r.accepted)
    accepted = [r.cost for r in res.report if r.accepted]
    assert all(b <= a + 1e-9 for a, b in zip(accepted, accepted[1:]))  # monotone
    np.testing.assert_allclose(np.linalg.norm(res.x[:, 3:7], axis=1), 1.0, atol=1e-9)


def test_frozen_entries_do_not_move(problem):
    fig, prob, Qx, _ = problem
    active = np.ones(fig.nv, bool)
    active[10:20] = False
    res = solve(prob, Qx, SolverOptions(max_iterations=10), active=active)
    moved = np.abs(fig.difference(Qx, res.x))
    assert moved[:, 10:20].max() < 1e-12 and moved[:, :10].max() > 1e-4


class _Poisoned:
    """A problem whose residuals turn NaN far from the start: the solver must reject."""

    def __init__(self, prob):
        self.p, self.n_frames, self.nv = prob, prob.n_frames, prob.nv
        self.x0 = None

    def evaluate(self, x, jacobian=True):
        blocks = _flatten(self.p.evaluate(x, jacobian))
        if self.x0 is not None and np.abs(x[:, :3] - self.x0[:, :3]).max() > 0.05:
            blocks[0].r = blocks[0].r * np.nan
        return blocks

    def retract(self, x, dx):
        return self.p.retract(x, dx)


def test_non_finite_candidates_are_rejected_and_said_so(problem):
    fig, prob, Qx, _ = problem
    poisoned = _Poisoned(prob)
    poisoned.x0 = Qx
    res = solve(poisoned, Qx, SolverOptions(max_iterations=15))
    assert np.all(np.isfinite(res.x)) and np.isfinite(res.cost)
    assert any((not r.accepted) and r.message == "non-finite residuals" for r in res.report)


def test_termination_reasons(problem):
    fig, prob, Qx, _ = problem
    assert solve(prob, Qx, SolverOptions(max_iterations=2)).status == "max_iterations"
    res = solve(prob, Qx, SolverOptions(max_iterations=200, ftol=1e-4))
    assert res.converged and res.status in ("ftol", "xtol", "gtol")
    stopped = solve(prob, Qx, SolverOptions(max_iterations=50), callback=lambda rep: rep.iteration >= 3)
    assert stopped.status == "stopped by callback" and stopped.iterations == 3


def test_stop_when_sees_each_accepted_iterate_and_stops_with_its_word(problem):
    """``stop_when(iteration, x)`` sees the trajectory after each accepted step (the one a solve
    limited to that many iterations ends at) and stops the solve with the status it returns."""
    _fig, prob, Qx, _ = problem
    seen = {}

    def stop_when(iteration, x):
        seen[iteration] = x.copy()
        return "enough" if iteration == 3 else None

    res = solve(prob, Qx, SolverOptions(max_iterations=50), stop_when=stop_when)
    assert res.status == "enough" and res.iterations == 3 and not res.converged
    accepted = [r.iteration for r in res.report if r.accepted]
    assert sorted(seen) == accepted and accepted[-1] == 3
    three = solve(prob, Qx, SolverOptions(max_iterations=3))
    np.testing.assert_array_equal(res.x, three.x)
    np.testing.assert_array_equal(seen[3], three.x)
    assert res.cost == three.cost


def test_a_start_with_non_finite_residuals_is_refused(problem):
    fig, prob, Qx, _ = problem
    bad = Qx.copy()
    bad[0, 0] = np.nan
    with pytest.raises(FloatingPointError):
        solve(prob, bad)
