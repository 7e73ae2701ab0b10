"""The windowed solve of long clips: the plan of windows, agreement with the batch solve
against ground truth, memory that does not grow with the clip, the pipeline and CLI
entry points, and clear errors."""

from __future__ import annotations

import itertools
import multiprocessing
import os
import tracemalloc

import numpy as np
import pytest

import pinrecon as pr
from pinrecon import windowed
from pinrecon.errors import InputError
from pinrecon.problem import make_problem
from pinrecon.solver import SolverOptions
from pinrecon.synthetic import human_walk, point_keyframes, project_tracks, side_camera
from pinrecon.windowed import (
    AUTO_WINDOW_FRAMES,
    DEFAULT_WINDOW,
    _jobs,
    solve_windowed,
    window_plan,
    windowed_length,
)


def _walk(n, every=8, seed=0):
    fig, q = human_walk(n, 30.0)
    cam = side_camera(q, 45.0, scale=300.0, center=(640.0, 360.0))
    tracks = project_tracks(fig, q, cam, fps=30.0, noise_px=1.0, seed=seed + 1)
    keys = point_keyframes(fig, q, range(0, n, every), sigma_m=0.02, seed=seed + 2) if every else None
    return fig, q, cam, tracks, keys


@pytest.mark.parametrize("n, window, overlap, unit", [(3000, 1000, 200, 1), (100000, 2000, 200, 1), (1121, 400, 100, 4),
                                                      (50, 400, 100, 1), (801, 200, 60, 2)])
def test_window_plan_covers_every_frame_with_the_asked_overlap(n, window, overlap, unit):
    plan = window_plan(n, window, overlap, unit)
    assert plan[0][0] == 0 and plan[-1][1] == n - 1
    for (a, e), (a2, e2) in itertools.pairwise(plan):
        assert a < a2 <= e < e2  # ordered, overlapping, no gap
        assert e - a2 + 1 >= min(overlap, window)  # at least the overlap asked for
    assert all(a % unit == 0 and (e - a) % unit == 0 for a, e in plan[:-1])
    assert all(e - a + 1 <= max(window, 1) for a, e in plan) or len(plan) == 1


def test_windows_are_automatic_past_a_frame_count_and_can_be_forced_or_refused():
    assert windowed_length(AUTO_WINDOW_FRAMES, None) is None
    assert windowed_length(AUTO_WINDOW_FRAMES + 1, None) == DEFAULT_WINDOW
    assert windowed_length(5000, 1000) == 1000
    assert windowed_length(10**6, 0) is None
    assert windowed_length(500, 1000) is None  # one window is the batch solve
    for bad in (-5, 2.5, "100", True):
        with pytest.raises(InputError) as exc:
            windowed_length(5000, bad)
        assert exc.value.field == "window"


@pytest.fixture(scope="module")
def walk_300():
    return _walk(300)


def test_windowed_solve_is_within_a_millimetre_of_the_batch_solve(walk_300):
    """The human walking 300 frames (10 s), 1 px noise, 3D keyframes every 8 frames: the
    batch solve against three overlapping windows; both scored against the true walk."""
    fig, q, cam, tracks, keys = walk_300
    batch = pr.reconstruct(fig, tracks, cam, keys, window=0, floor="none")  # windows have no feet stage
    win = pr.reconstruct(fig, tracks, cam, keys, window=120)
    truth = fig.keypoints(q)
    err_batch = 1000 * np.linalg.norm(batch.keypoints3d - truth, axis=-1).mean()
    err_win = 1000 * np.linalg.norm(win.keypoints3d - truth, axis=-1).mean()
    between = 1000 * np.linalg.norm(win.keypoints3d - batch.keypoints3d, axis=-1).mean()
    assert win.solve.status.startswith("windowed (4 windows of 120 frames") and win.solve.converged
    assert between < 1.0, (between, err_batch, err_win)
    assert abs(err_win - err_batch) < 1.0 and err_win < 25.0
    assert win.q.shape == batch.q.shape and np.all(np.isfinite(win.q))
    np.testing.assert_allclose(np.linalg.norm(win.q[:, 3:7], axis=1), 1.0, atol=1e-9)
    # the globals (the human's segment lengths, calibrated by default) come from one leading stretch (here all)
    assert win.solve.g is not None and win.solve.g.shape == batch.solve.g.shape
    assert np.abs(win.solve.g - batch.solve.g).max() < 0.05
    # and so does the word on which of them the data fix: the same groups as the batch's
    got, want = win.calibration["identifiability"], batch.calibration["identifiability"]
    assert got["undetermined"] == want["undetermined"] and got["size_determined"] == want["size_determined"]


def _solver_peak_mb(n, window):
    fig, q, cam, tracks, _ = _walk(n, every=0)
    problem = make_problem(fig, tracks, cam, None, calibrate="none")
    q0 = fig.integrate(q, 0.05 * np.random.default_rng(0).normal(size=(n, fig.nv)))  # a given start
    tracemalloc.start()
    res = solve_windowed(problem, q0, SolverOptions(max_iterations=3), window=window, overlap=20, faults=False)
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    return peak, res


def test_memory_of_the_windowed_solve_does_not_grow_with_the_clip():
    """Peak Python allocation during the windowed solve of 300 and 900 frames in windows
    of 80: the same windows' buffers, plus only the output trajectory and the clip-wide
    cost evaluation growing (about 1 KB a frame, against ~55 KB a frame for a batch solve)."""
    small, _ = _solver_peak_mb(300, 80)
    large, res_large = _solver_peak_mb(900, 80)
    assert res_large.x.shape == (900, 43) and np.all(np.isfinite(res_large.x))
    per_frame_kb = 1024 * (large - small) / 600
    assert per_frame_kb < 15.0, (small, large)


def test_progress_reports_every_window_and_stops_on_request(walk_300):
    fig, _, cam, tracks, keys = walk_300
    problem = make_problem(fig, tracks, cam, keys, calibrate="none")
    windows, iters = [], []

    class Progress:
        def __call__(self, rep):
            iters.append(rep.iteration)

        def window(self, rep):
            windows.append(rep)

    res = solve_windowed(problem, "auto", SolverOptions(max_iterations=3), Progress(), window=120, overlap=30)
    plan = window_plan(300, 120, 30)
    assert [w.index for w in windows] == list(range(1, len(plan) + 1)) and all(w.count == len(plan) for w in windows)
    assert [(w.first, w.last) for w in windows] == plan and plan[-1][1] == 299
    assert f"window 2/{len(plan)}" in str(windows[1])
    assert len(iters) >= 3 and res.iterations == sum(w.iterations for w in windows)

    stop = solve_windowed(problem, "auto", SolverOptions(max_iterations=5), lambda rep: True, window=120)
    assert stop.status == "stopped by callback" and stop.x.shape == (300, fig.nq) and np.all(np.isfinite(stop.x))


class _Progress:
    def __init__(self):
        self.windows, self.iterations = [], []

    def __call__(self, rep):
        self.iterations.append(rep.iteration)

    def window(self, rep):
        self.windows.append(rep)


def test_windows_in_worker_processes_match_the_truth_and_report_every_window(walk_300):
    """Two worker processes, each solving a run of consecutive windows (the second run's first
    window starts cold): every window reported once, with its place in the plan; the iteration
    reports come back over the queue; the answer as close to the true walk as the windows one
    after another (both scored against the truth, not against each other)."""
    fig, q, cam, tracks, keys = walk_300
    truth = fig.keypoints(q)
    plan = window_plan(300, 100, 30)
    errors = {}
    for jobs in (None, 2):  # no pose prior: the keyframes decide the walk's poses (bench_prior_yield)
        problem = make_problem(fig, tracks, cam, keys, calibrate="none", weights=pr.Weights(pose_prior=None))
        progress = _Progress()
        res = solve_windowed(problem, "auto", None, progress, window=100, overlap=30, n_jobs=jobs)
        windows, iters = progress.windows, progress.iterations
        assert sorted((w.index, w.first, w.last) for w in windows) == [(k + 1, a, e) for k, (a, e) in enumerate(plan)]
        assert all(w.count == len(plan) for w in windows) and res.converged
        assert len(iters) == res.iterations == sum(w.iterations for w in windows)
        assert res.x.shape == (300, fig.nq) and np.all(np.isfinite(res.x))
        np.testing.assert_allclose(np.linalg.norm(res.x[:, 3:7], axis=1), 1.0, atol=1e-9)
        errors[jobs] = 1000 * np.linalg.norm(problem.keypoints(res.x) - truth, axis=-1).mean()
    assert errors[2] < 15.0 and abs(errors[2] - errors[None]) < 1.0, errors


def test_stopping_one_worker_stops_them_all(walk_300):
    fig, _, cam, tracks, keys = walk_300
    problem = make_problem(fig, tracks, cam, keys, calibrate="none")
    seen = []

    def stop_after_two(rep):
        seen.append(rep)
        return len(seen) >= 2

    res = solve_windowed(problem, "auto", None, stop_after_two, window=100, overlap=30, n_jobs=2)
    assert res.status == "stopped by callback" and res.x.shape == (300, fig.nq) and np.all(np.isfinite(res.x))
    assert len(seen) < 20  # the workers stopped at the next iteration, not at the end of their windows
    last = int(np.flatnonzero(np.any(res.x != res.x[-1], axis=1)).max()) + 1  # frames after it hold its pose
    assert last < 300


def _jobs_in_a_worker(said):
    said.put(_jobs(-1, 4))


def test_a_worker_process_solves_its_windows_itself():
    """Every core in the main process; one in a process that is itself a worker (pinrecon
    batch's, Dask's), whose pool already uses the cores."""
    assert _jobs(-1, 4) == min(4, len(os.sched_getaffinity(0))) and _jobs(-1, 1) == 1 and _jobs(None, 4) == 1
    ctx = multiprocessing.get_context("fork")
    said = ctx.Queue()
    worker = ctx.Process(target=_jobs_in_a_worker, args=(said,))
    worker.start()
    got = said.get(timeout=60)
    worker.join()
    assert got == 1


def _dies(*args):
    os._exit(3)  # a worker killed (the system out of memory, say)


def test_a_dead_worker_is_said_and_the_windows_solved_one_after_another(walk_300, monkeypatch):
    fig, q, cam, tracks, keys = walk_300
    problem = make_problem(fig, tracks, cam, keys, calibrate="none", weights=pr.Weights(pose_prior=None))
    monkeypatch.setattr(windowed, "_worker_run", _dies)
    with pytest.warns(RuntimeWarning, match="worker process solving the windows died"):
        res = solve_windowed(problem, "auto", None, window=100, overlap=30, n_jobs=2)
    assert res.converged and res.x.shape == (300, fig.nq)
    assert 1000 * np.linalg.norm(problem.keypoints(res.x) - fig.keypoints(q), axis=-1).mean() < 15.0


@pytest.mark.parametrize("bad", [0, -2, 1.5, True, "2"])
def test_worker_count_is_checked(walk_300, bad):
    fig, _, cam, tracks, keys = walk_300
    problem = make_problem(fig, tracks, cam, keys, calibrate="none")
    with pytest.raises(InputError) as exc:
        solve_windowed(problem, "auto", window=100, n_jobs=bad)
    assert exc.value.field == "n_jobs"


def test_feet_need_the_batch_solve(walk_300):
    fig, _, cam, tracks, keys = walk_300
    with pytest.raises(InputError, match="window=0"):
        pr.reconstruct(fig, tracks, cam, keys, window=100, floor="auto")


def test_cli_window_option(tmp_path, walk_300):
    from pinrecon.cli import main

    fig, _, cam, tracks, keys = walk_300
    tracks.save(tmp_path / "tracks.json")
    cam.save(tmp_path / "camera.json")
    keys.save(tmp_path / "keyframes.json")
    base = ["reconstruct", "--figure", "human", "--tracks", str(tmp_path / "tracks.json"), "--camera",
            str(tmp_path / "camera.json"), "--keyframes", str(tmp_path / "keyframes.json"), "--max-iterations", "3"]
    assert main(base + ["--window", "150", "--out", str(tmp_path / "r.npz")]) == 0
    res = pr.load_result(tmp_path / "r.npz")
    assert res.q.shape == (300, fig.nq)
    assert main(base + ["--window", "-3", "--out", str(tmp_path / "bad.npz")]) == 2


@pytest.mark.parametrize("cues", [True, False])
def test_with_the_tracks_own_lifted_cues_the_windows_have_no_mirror_stage(coco_walk, human, monkeypatch, cues):
    """As in the batch path (``pinrecon.stages``): the lifter's 3D decides the limbs'
    reflections and the heading, so the windows run no mirror stage with the broader prior and
    no turn stage when the tracks carry it, and run them when they do not. Ground truth: the
    true walk."""
    from pinrecon.lifted import Lifted
    from pinrecon.metrics import pa_mpjpe
    from pinrecon.weights import Weights

    cam, tracks, P, _ = coco_walk
    tr = tracks.frames(0, 60)
    if cues:  # the true points in the camera's axes, a lifter's own size and origin, 3 cm noise
        X = 1.7 * (P[:60] @ np.asarray(cam.R).T) + np.random.default_rng(4).normal(0.0, 0.05, P[:60].shape)
        tr.lifted = Lifted(X, list(tr.names), np.ones(X.shape[:2]), "camera", "truth")
    calls = []
    real = windowed.mirror_stage
    monkeypatch.setattr(windowed, "mirror_stage", lambda *a: calls.append(1) or real(*a))
    turned, real_turns = [], windowed.turn_stage
    monkeypatch.setattr(windowed, "turn_stage", lambda *a, **k: turned.append(1) or real_turns(*a, **k))
    monkeypatch.setattr(windowed, "usable_cpus", lambda: 1)  # the windows here, where the calls are counted
    res = pr.reconstruct(human, tr, cam, window=40, weights=Weights(pose_prior_model="human_pose_mixture"),
                         options=SolverOptions(max_iterations=15))
    assert (len(calls), len(turned)) == ((0, 0) if cues else (2, 2))  # two windows of 40 frames over 60
    kp = res.figure.keypoint_index(list(tr.names))
    assert pa_mpjpe(res.keypoints3d[:, kp], P[:60]) < 60.0


def test_one_cameras_windows_measure_the_limb_lengths_on_the_leading_stretch(coco_walk, human):
    """As the batch solve does for one camera and no keyframe, a clip solved in windows starts
    its limb lengths where the tracks measure them (on its first frames, before the globals are
    solved on the leading stretch) instead of keeping the generic figure's. Ground truth: the true walk's thigh, shank,
    upper-arm and forearm lengths (its own skeleton, not the generic human's)."""
    import warnings

    _, tracks, P, _ = coco_walk
    names = list(tracks.names)

    def limb_lengths(X):
        pairs = [("left_hip", "left_knee"), ("left_knee", "left_ankle"), ("left_shoulder", "left_elbow"),
                 ("left_elbow", "left_wrist")]
        return np.array([np.median(np.linalg.norm(X[:, names.index(a)] - X[:, names.index(b)], axis=-1))
                         for a, b in pairs])

    truth = limb_lengths(P)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct(human, tracks, "auto", image_size=(1280, 720), window=60, floor="none")
    assert sorted(res.calibration["lengths_from_tracks"]) == ["forearm", "shank", "thigh", "upper_arm"]
    got = limb_lengths(res.keypoints3d[:, res.figure.keypoint_index(names)])
    generic = limb_lengths(human.keypoints(human.neutral()[None])[:, human.keypoint_index(names)])
    assert np.abs(got / truth - 1.0).mean() < 0.6 * np.abs(generic / truth - 1.0).mean()
