"""Lifted-pose rows (pinrecon.rows.lifted): the fault stage's left/right repair exchanges the
lifted pose's labels too, the lifter's proportions as rows (Jacobians by finite
differences), and --lifted-weight; against ground truth built independently."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from dense_blocks import dense_jacobian

import pinrecon as pr
from pinrecon.faults import repair_swaps
from pinrecon.lifted import Lifted
from pinrecon.reconstruct import build_problem
from pinrecon.rows import State
from pinrecon.rows.lifted import LiftedPose
from pinrecon.synthetic import project_tracks, side_camera, smooth_motion


@pytest.fixture(scope="module")
def seen():
    fig = pr.Figure.human()
    Q = smooth_motion(fig, 12, 30.0, seed=3)
    cam = side_camera(Q, 45.0)
    tracks = project_tracks(fig, Q, cam, fps=30.0, noise_px=1.0, seed=3)
    X = fig.keypoints(Q)[:, fig.keypoint_index(list(tracks.names))] @ cam.R.T
    X = X + 0.03 * np.random.default_rng(4).normal(size=X.shape)
    return fig, tracks, cam, X


def _problem(fig, tracks, cam, X):
    t = pr.Tracks(tracks.points.copy(), tracks.names, tracks.fps, tracks.confidence,
                  lifted=Lifted(X.copy(), list(tracks.names), None, "camera", "test"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return build_problem(fig, t, cam, seed="rest", calibrate="none").problem


def _sides(names):
    return [names.index(n.replace("left", "#").replace("right", "left").replace("#", "right")) for n in names]


def test_a_repaired_swap_exchanges_the_lifted_labels_too(seen):
    """The fault stage's repair of frames 3 and 7 leaves the same 2D and lifted rows as
    tracks whose detector (and lifter) had labelled those frames the other way round."""
    fig, tracks, cam, X = seen
    names = list(tracks.names)
    perm = _sides(names)
    frames = np.array([3, 7])
    uv_sw, X_sw = tracks.points.copy(), X.copy()
    uv_sw[frames], X_sw[frames] = tracks.points[frames][:, perm], X[frames][:, perm]
    swapped = pr.Tracks(uv_sw, names, tracks.fps, tracks.confidence)
    problem = _problem(fig, swapped, cam, X_sw)
    row = next(r for r in problem.rows if isinstance(r, LiftedPose))
    L_sw = row.L.copy()
    repair_swaps(problem, np.flatnonzero(np.isin(problem.measurement.frames, frames)))
    expect = next(r for r in _problem(fig, tracks, cam, X).rows if isinstance(r, LiftedPose))
    assert not np.allclose(L_sw[frames], expect.L[frames])  # the repair has something to do
    np.testing.assert_allclose(row.L, expect.L, atol=1e-12)
    np.testing.assert_allclose(row.w, expect.w)
    np.testing.assert_array_equal(row.observed, expect.observed)
    np.testing.assert_allclose(problem.measurement.uv_px, _problem(fig, tracks, cam, X).measurement.uv_px)


def test_the_lifted_weight_option_reaches_the_weights():
    from pinrecon.arguments import WEIGHT_OPTIONS, weights_kwargs
    from pinrecon.cli import build_parser

    base = ["reconstruct", "--figure", "human", "--tracks", "t.json", "--camera", "auto", "--out", "o"]
    for flag, expect in ((["--lifted-weight", "50"], 50.0), (["--lifted-weight", "0"], 0.0), ([], 25.0)):
        args = build_parser().parse_args(base + flag)
        assert pr.Weights(**weights_kwargs(args, WEIGHT_OPTIONS)).lifted == expect
    args = build_parser().parse_args(base + ["--lifted", "x3d.npy"])  # a file, not the weight
    assert "lifted" not in weights_kwargs(args, WEIGHT_OPTIONS)
    args = build_parser().parse_args(["video", "v.mp4", "--out", "o", "--lifted-weight", "12.5"])
    assert weights_kwargs(args, WEIGHT_OPTIONS)["lifted"] == 12.5
    with pytest.raises(SystemExit):
        build_parser().parse_args(base + ["--lifted-weight", "-1"])


def test_lifted_lengths_rows_jacobians_match_finite_differences():
    """d r / d v_t on the manifold and d r / d g (the proportions) by central differences."""
    from pinrecon.proportions import Proportions
    from pinrecon.rows.lifted import LENGTH_BONES, LiftedLengths

    fig = pr.Figure.human()
    T = 3
    Q = smooth_motion(fig, T, 30.0, seed=5)
    bones = [fig.keypoint_index([a, b]) for a, b in LENGTH_BONES]
    target = np.random.default_rng(6).normal(size=len(bones))
    row = LiftedLengths(np.arange(T), bones, target, 7.0)
    props = Proportions.default(fig)
    g = 0.1 * np.random.default_rng(7).normal(size=props.n)

    def ev(QQ, gg, jac=False):
        return row.evaluate(State(fig, QQ, np.arange(T), jac, g=gg, proportions=props), jac)

    b = ev(Q, g, True)
    J = dense_jacobian([b], T, fig.nv)[0]
    eps, cols = 1e-6, []
    for t in range(T):
        for i in range(fig.nv):
            dv = np.zeros(fig.nv)
            dv[i] = eps
            Qp, Qm = Q.copy(), Q.copy()
            Qp[t], Qm[t] = fig.integrate(Q[t], dv), fig.integrate(Q[t], -dv)
            cols.append((ev(Qp, g).r - ev(Qm, g).r).ravel() / (2 * eps))
    fd = np.stack(cols, axis=-1)
    assert np.abs(fd).max() > 0.1
    assert np.abs(J - fd).max() <= 1e-6 * np.abs(fd).max()
    fdg = np.stack([(ev(Q, g + eps * e).r - ev(Q, g - eps * e).r).ravel() / (2 * eps) for e in np.eye(props.n)], -1)
    Jg = np.zeros_like(fdg)
    Jg[:, b.gcols] = b.Jg.reshape(fdg.shape[0], -1)
    assert np.abs(fdg).max() > 0.1
    assert np.abs(Jg - fdg).max() <= 1e-6 * np.abs(fdg).max()
    # the residual: the figure's centred log lengths minus the target's (computed here from the points)
    lam = np.log(np.linalg.norm(np.diff(State(fig, Q, np.arange(T), False, g=g, proportions=props).points[
        :, np.array(bones)], axis=2)[:, :, 0], axis=-1))
    expect = np.sqrt(7.0) * (lam - lam.mean(1, keepdims=True) - (target - target.mean()))
    np.testing.assert_allclose(ev(Q, g).r, expect, atol=1e-12)
