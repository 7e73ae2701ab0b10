"""The pose prior yields to strong data (pinrecon.prior_yield): scored against the true motion
and against the solve without the prior, both computed without the code under test."""

from __future__ import annotations

import numpy as np
import pytest

import pinrecon as pr
from pinrecon.prior_yield import CONFLICT, prior_conflict, yield_to_data
from pinrecon.problem import make_problem
from pinrecon.reconstruct import build_problem
from pinrecon.rows.posture import PosePrior
from pinrecon.solver import solve
from pinrecon.starts import initial_trajectory
from pinrecon.synthetic import human_walk, point_keyframes, project_tracks, side_camera


def _mm(fig, a, b):
    return 1000.0 * float(np.linalg.norm(fig.keypoints(a) - fig.keypoints(b), axis=-1).mean())


def _walk(n, q_edit=None):
    fig, q = human_walk(n, 30.0)
    if q_edit is not None:
        q = q_edit(fig, q)
    cam = side_camera(q, 45.0, scale=300.0, center=(640, 360))
    tracks = project_tracks(fig, q, cam, fps=30.0, noise_px=1.0, seed=1)
    keys = point_keyframes(fig, q, range(0, n, 8), sigma_m=0.02, seed=2)
    return fig, q, cam, tracks, keys


@pytest.fixture(scope="module")
def dense_walk():
    """bench_engine's problem: the walk, one orthographic view 45 degrees from side-on, 1 px,
    3D point keyframes (2 cm) every 8 frames; its spine and neck sit far from the prior's mean."""
    return _walk(300)


def _held(fig, tracks, cam, keys):
    """The problem with the default prior as its clips fitted it, and the keyframes' start."""
    problem = make_problem(fig, tracks, cam, keys, calibrate="none")
    return problem, initial_trajectory(problem, "auto")


def test_the_prior_yields_to_dense_keyframes(dense_walk):
    fig, q, cam, tracks, keys = dense_walk
    free = build_problem(fig, tracks, cam, keys, calibrate="none", weights=pr.Weights(pose_prior=None))
    no_prior = _mm(fig, solve(free.problem, free.q0, active=free.active).x, q)
    problem, q0 = _held(fig, tracks, cam, keys)
    res = solve(problem, q0, active=problem.active)
    _, out, conflict = yield_to_data(problem, res)  # after a solve: the stage 'yield'
    setup = build_problem(fig, tracks, cam, keys, calibrate="none")  # at the start, as reconstruct's solve stage
    adapted = solve(setup.problem, setup.q0, active=setup.active)
    assert no_prior < 12.0
    assert _mm(fig, res.x, q) > no_prior + 30.0  # the prior held overrides the keyframes (75 against 11 mm) ...
    assert _mm(fig, out.x, q) < no_prior + 5.0  # ... yields to them after the solve (14.6)
    assert _mm(fig, adapted.x, q) < no_prior + 2.0  # ... and, adapted at their start, ends with them (11.4)
    assert "cervical flexion/extension" in conflict.conflicting  # the neck the prior's clips never bent


def test_a_prior_that_fits_the_clip_is_kept(dense_walk):
    fig, q, cam, tracks, keys = dense_walk
    row = next(r for r in _held(fig, tracks, cam, keys)[0].rows if isinstance(r, PosePrior))

    def at_the_prior_mean(fig, q):  # the walk's motion about the mean posture of the prior's clips
        q = q.copy()
        q[:, row.qidx[row.diag]] = row.q_ref[row.diag]
        q[:, row.qcorr] += row.means[0] - q[:, row.qcorr].mean(axis=0)
        return q

    fig, q2, cam, tracks, keys = _walk(300, at_the_prior_mean)
    problem, q0 = _held(fig, tracks, cam, keys)
    res = solve(problem, q0, active=problem.active)
    conflict = prior_conflict(problem, res.x)
    assert conflict.s2.max() < CONFLICT
    problem2, out, _ = yield_to_data(problem, res)
    assert out is res and problem2 is problem


def test_redundancy_is_the_share_the_data_decide(dense_walk):
    """Hutchinson's estimate against the exact leverage, row by row (a short clip)."""
    fig, q, cam, tracks, keys = dense_walk
    n = 24
    tracks = pr.Tracks(tracks.points[:n], tracks.names, tracks.fps)
    keys = point_keyframes(fig, q[:n], range(0, n, 8), sigma_m=0.02, seed=2)
    problem, q0 = _held(fig, tracks, cam, keys)
    res = solve(problem, q0, active=problem.active)
    est = prior_conflict(problem, res.x, probes=400, seed=3)
    # exact: rebuild J and H densely from the row blocks
    from pinrecon.solver import flatten_blocks

    blocks = flatten_blocks(problem.evaluate(res.x, True))
    nv = problem.nv
    rows_J = []
    for b in blocks:
        for k in range(b.r.shape[0]):
            Jk = np.zeros((b.r.shape[1], n * nv))
            for i, t in enumerate(b.frames[k]):
                blk = np.diag(b.J[k, i]) if b.diagonal else b.J[k, i]
                Jk[:, t * nv + np.asarray(b.cols)] += blk
            rows_J.append((b.name, k, Jk))
    J = np.vstack([Jk for _, _, Jk in rows_J])
    H = J.T @ J
    H += 1e-9 * H.diagonal().max() * np.eye(len(H))
    Jp = np.stack([Jk for name, _, Jk in rows_J if name == "posture"])  # (n, m, n nv)
    lev = np.einsum("tmk,tmk->m", Jp, np.linalg.solve(H, Jp.reshape(-1, n * nv).T).T.reshape(Jp.shape))
    exact = 1.0 - lev[: len(est.redundancy)] / n
    np.testing.assert_allclose(est.redundancy, np.clip(exact, 1.0 / n, 1.0), atol=0.08)


def test_reconstruct_adapts_the_prior_to_dense_keyframes_and_says_so(tmp_path):
    fig, q, cam, tracks, keys = _walk(64)
    res = pr.reconstruct(fig, tracks, cam, keys, skip=("feet",))
    free = pr.reconstruct(fig, tracks, cam, keys, skip=("feet",), weights=pr.Weights(pose_prior=None))
    held = pr.reconstruct(fig, tracks, cam, keys, skip=("feet", "yield"))

    def err(r):
        return 1000.0 * float(np.linalg.norm(r.keypoints3d - fig.keypoints(q), axis=-1).mean())

    assert err(held) > err(free) + 5.0  # the prior, held, overrides the keyframes (23.5 against 14.9 mm)
    assert err(res) < err(free) + 2.0
    solve_stage = next(s for s in res.stages if s.name == "solve")
    assert "pose prior adapted to the keyframes" in solve_stage.changed
    assert next(s for s in res.stages if s.name == "prior").changed.startswith("skipped")  # no broader prior
    joints = [str(j) for j in res.extras["prior_conflict_joints"]]
    assert "cervical flexion/extension" in joints
    assert "the data disagree with the pose prior" in res.summary()
    res.save(tmp_path / "r.npz")
    back = pr.load_result(tmp_path / "r.npz")
    assert [str(j) for j in back.extras["prior_conflict_joints"]] == joints
    assert "prior_conflict_joints" not in held.extras


@pytest.fixture(scope="module")
def camera_1_cued():
    """MediaPipe Pose on the first 60 frames of Pose2Sim's camera 1 (2D and world landmarks),
    and the four-camera triangulation of those frames (12 COCO body points, metres)."""
    pytest.importorskip("cv2")
    pytest.importorskip("mediapipe")
    from conftest import data_file, data_path

    from pinrecon.io.trc import load_trc
    from pinrecon.layouts import COCO_17
    from pinrecon.video import track_video

    n, names = 60, list(COCO_17[5:])
    tracks = track_video(data_file("pose2sim-balancing/videos/cam01.mp4"), max_frames=n)
    m = load_trc(data_path("pose2sim-balancing/pose-3d/S00_P00_T01_BalancingTrial_0-100.trc"), names="pinrecon")
    return tracks, names, m.points[:n, [m.names.index(c) for c in names]]


def test_with_lifted_cues_the_yield_is_solved_in_the_feet_stages_solve(camera_1_cued, monkeypatch):
    """With the tracks' own 3D the yield stage makes no solve of its own: the feet stage adapts the
    prior where the data disagree (the same joints the yield's own judgement names) and solves
    once. Ground truth: the four-camera triangulation; the yield solving on its own (the feet
    stage switched off) as the reference."""
    from pinrecon import stages
    from pinrecon.metrics import pa_mpjpe

    tracks, names, G = camera_1_cued
    human = pr.Figure.human()

    def run(**kw):
        with pytest.warns(Warning):  # the auto camera's focal length, MediaPipe's points off the figure
            return pr.reconstruct(human, tracks, "auto", image_size=(1080, 1920), **kw)

    alone = run(skip=("feet",))
    monkeypatch.setattr(stages, "yield_to_data", lambda *a, **k: pytest.fail("the yield solved on its own"))
    res = run()
    said = {s.name: s.changed for s in res.stages}
    joints = [str(j) for j in res.extras["prior_conflict_joints"]]
    assert said["yield"].startswith("left to the feet stage")
    assert joints and joints == [str(j) for j in alone.extras["prior_conflict_joints"]]
    assert f"pose prior widened and re-centred on {len(joints)} joint(s)" in said["feet"]
    assert "the data disagree with the pose prior" in res.summary()
    kp = human.keypoint_index(names)
    err, ref = pa_mpjpe(res.keypoints3d[:, kp], G), pa_mpjpe(alone.keypoints3d[:, kp], G)
    assert err < 84.0 and err < ref + 1.0, (err, ref)  # 81.1 against 81.1
