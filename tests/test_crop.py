"""A problem cropped to a range of frames (``ReconstructionProblem.cropped``): its rows are
the whole problem's row groups that lie in the range, residual for residual and Jacobian for
Jacobian (the whole problem's own evaluation is the reference); what it cannot crop it
refuses, and a range outside the clip is an InputError."""

from __future__ import annotations

import numpy as np
import pytest

import pinrecon as pr
from pinrecon.errors import InputError
from pinrecon.lifted import Lifted
from pinrecon.problem import make_problem
from pinrecon.rows import JointKeyframes
from pinrecon.solver import SolverOptions, flatten_blocks, solve
from pinrecon.synthetic import (
    perspective_side_camera,
    point_keyframes,
    project_tracks,
    smooth_motion,
)

T = 40


def _case(lifted_frame: str):
    fig = pr.Figure.human()
    Q = smooth_motion(fig, T, 30.0, seed=2)
    cam = perspective_side_camera(Q, 45.0)
    tr = project_tracks(fig, Q, cam, fps=30.0, noise_px=1.0, seed=2)
    K = fig.keypoints(Q)[:, fig.keypoint_index(list(tr.names))]
    rng = np.random.default_rng(4)
    lifted = Lifted(K + rng.normal(0.0, 0.03, K.shape), list(tr.names), None, lifted_frame, "test")
    tracks = pr.Tracks(tr.points, tr.names, tr.fps, lifted=lifted)
    keys = point_keyframes(fig, Q, [0, 20, T - 1], seed=3)
    problem = make_problem(fig, tracks, cam, keys, calibrate="lengths")
    joint = fig.joint_names[3]
    m = fig.model
    jid = m.getJointId(joint)
    value = Q[12, m.idx_qs[jid] : m.idx_qs[jid] + m.nqs[jid]]
    problem = problem.with_rows([JointKeyframes(fig, [(12, 0.05, {joint: value}), (33, 0.05, {joint: value})])])
    X = fig.clamp(Q + rng.normal(0.0, 0.02, Q.shape), 1e-3)
    return fig, problem, fig.normalize(X)


@pytest.mark.parametrize("lo, hi", [(0, 25), (9, 31), (15, T), (0, T), (21, 33)])
def test_the_cropped_rows_are_the_whole_problems_rows_in_range(lo, hi):
    _, problem, X = _case("camera")
    kinds = {type(r).__name__ for r in problem.rows}
    assert {"Measurement2D", "JointLimits", "Smoothing", "PosePrior", "LiftedPose", "LiftedLengths", "Points3D",
            "JointKeyframes", "GlobalPrior"} <= kinds, kinds
    sub = problem.cropped(lo, hi)
    assert sub.n_frames == hi - lo and sub.g0 is not None and np.array_equal(sub.g0, problem.g0)
    g = problem.g0 + 0.05
    full = flatten_blocks(problem.evaluate(X, True, g))
    crop = flatten_blocks(sub.evaluate(X[lo:hi], True, g))
    # a kind without a row group in the range gives no block
    full = [b for b in full if not b.frames.shape[1] or np.all((b.frames >= lo) & (b.frames < hi), axis=1).any()]
    assert [b.name for b in full] == [b.name for b in crop]
    for bf, bc in zip(full, crop):
        inside = np.all((bf.frames >= lo) & (bf.frames < hi), axis=1)
        assert np.array_equal(bf.frames[inside] - lo, bc.frames), bf.name
        np.testing.assert_allclose(bc.r, bf.r[inside], rtol=0, atol=1e-12, err_msg=bf.name)
        if bc.r.size:
            np.testing.assert_allclose(np.asarray(bc.J), np.asarray(bf.J)[inside], rtol=0, atol=1e-12, err_msg=bf.name)
        if bf.Jg is not None and bf.frames.shape[1]:
            np.testing.assert_allclose(bc.Jg, bf.Jg[inside], rtol=0, atol=1e-12, err_msg=bf.name)
        elif bf.Jg is not None:  # the globals' own prior: the same rows
            np.testing.assert_allclose(bc.Jg, bf.Jg, rtol=0, atol=1e-12)
    # the smoothing rows across the crop's ends are the ones left out
    n_smooth = sum(len(b.r) for b in crop if b.name == "smoothing")
    assert n_smooth == 2 * (hi - lo - 2)  # two smoothing kinds (joints, root) on every inner frame


def test_rows_that_cannot_be_cropped_refuse_and_a_range_outside_the_clip_is_an_error():
    _, problem, _ = _case("unknown")  # the lifter's axes estimated from every frame: not croppable
    assert problem.cropped(5, 20) is None
    _, problem, _ = _case("camera")
    for lo, hi in [(-1, 10), (10, 10), (30, T + 1), (20, 5)]:
        with pytest.raises(InputError) as exc:
            problem.cropped(lo, hi)
        assert exc.value.field == "frames"


def test_a_crop_without_keyframes_in_its_range_solves():
    _, problem, X = _case("camera")
    sub = problem.cropped(21, 33)  # no point or joint keyframe among these frames
    names = {b.name for b in flatten_blocks(sub.evaluate(X[21:33], False))}
    assert "keyframe_points" not in names and "keyframe_joints" not in names and "measurement" in names
    res = solve(sub, X[21:33], SolverOptions(max_iterations=5), active=sub.active, g0=sub.g0)
    assert res.x.shape == X[21:33].shape and res.cost < res.initial_cost


def test_lifted_rows_of_an_estimated_rotation_are_cropped_with_the_whole_clips_rotation_held():
    """Given the whole clip's state, the lifter's rows whose axes the solve estimates from every
    frame are cropped with that rotation held: the cropped rows are the whole problem's in
    range, residual for residual (its own evaluation, with the rotation it estimates, is the
    reference)."""
    _, problem, X = _case("unknown")
    g = problem.g0 + 0.05
    lo, hi = 9, 31
    sub = problem.cropped(lo, hi, problem.state(X, False, g=g))
    row = next(r for r in problem.rows if type(r).__name__ == "LiftedPose")
    held = next(r for r in sub.rows if type(r).__name__ == "LiftedPose")
    assert row.R_fixed is None and held.R_fixed is not None
    np.testing.assert_allclose(held.R_fixed, row.rotation(problem.state(X, False, g=g)), atol=1e-12)
    full = next(b for b in flatten_blocks(problem.evaluate(X, True, g)) if b.name == "lifted")
    crop = next(b for b in flatten_blocks(sub.evaluate(X[lo:hi], True, g)) if b.name == "lifted")
    inside = np.all((full.frames >= lo) & (full.frames < hi), axis=1)
    np.testing.assert_allclose(crop.r, full.r[inside], rtol=0, atol=1e-12)
    assert problem.cropped(lo, hi) is None  # without the state: refused, as before
