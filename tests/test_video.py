"""Video in: ``pinrecon track`` and ``pinrecon video`` on a 10-frame cut of a real video.

Ground truth independent of the code under test: OpenPose's BODY_25B detections of the same
frames (Pose2Sim's balancing trial, camera 1), which pinrecon only reads. MediaPipe's 2D
landmarks must lie near them; the overlay video's drawn keypoints must lie on them.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import data_file, data_folder

cv2 = pytest.importorskip("cv2")
pytest.importorskip("mediapipe")

import pinrecon as pr
from pinrecon.cli import main
from pinrecon.layouts import COCO_17
from pinrecon.viz.overlay import JOINT_BGR

N = 10
BODY = list(COCO_17[5:])  # shoulders, elbows, wrists, hips, knees, ankles


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    """The first N frames of camera 1's video, written again with OpenCV (mp4v)."""
    src = data_file("pose2sim-balancing/videos/cam01.mp4")
    path = tmp_path_factory.mktemp("video") / "cam01_cut.mp4"
    cap = cv2.VideoCapture(str(src))
    fps = cap.get(cv2.CAP_PROP_FPS)
    frames = [cap.read()[1] for _ in range(N)]
    cap.release()
    h, w = frames[0].shape[:2]
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    for f in frames:
        out.write(f)
    out.release()
    return path



def test_frames_decoded_ahead_are_the_same_frames(cut, monkeypatch):
    """``iter_frames(ahead=k)`` decodes in a thread: the same frames in the same order, the
    thread gone when the caller stops early, and a decoding error raised in the caller."""
    import threading

    from pinrecon.video import frames as frames_module
    from pinrecon.video.frames import iter_frames

    cap = cv2.VideoCapture(str(cut))  # ground truth: OpenCV read directly
    truth = [cap.read()[1] for _ in range(N)]
    cap.release()
    got = list(iter_frames(cut, ahead=3))
    assert len(got) == N and all(np.array_equal(a, b) for a, b in zip(got, truth))
    assert len(list(iter_frames(cut, 4, ahead=2))) == 4

    # prepare(t, frame) runs in the decoding thread, in order, and is what the caller gets
    seen = []

    def prepare(t, frame):
        seen.append((t, threading.current_thread().name))
        return t, frame[::2, ::2].copy()

    prepared = list(iter_frames(cut, ahead=2, prepare=prepare))
    assert [t for t, _ in prepared] == list(range(N)) == [t for t, _ in seen]
    assert {name for _, name in seen} == {"pinrecon-frames"}
    assert all(np.array_equal(f, truth[t][::2, ::2]) for t, f in prepared)
    assert [t for t, _ in iter_frames(cut, 3, prepare=prepare)] == [0, 1, 2]  # no thread: the same

    it = iter_frames(cut, ahead=2)
    assert np.array_equal(next(it), truth[0])
    it.close()
    assert not any(t.name == "pinrecon-frames" for t in threading.enumerate())

    read = frames_module._read

    def broken(cap, max_frames, start=0):
        yield from read(cap, 2, start)
        raise OSError("the file went away")

    monkeypatch.setattr(frames_module, "_read", broken)
    with pytest.raises(OSError, match="went away"):
        list(iter_frames(cut, ahead=2))

def test_frames_from_a_later_start_are_the_same_frames(cut):
    """``iter_frames(start=k)`` decodes the frames before ``k`` and drops them: frame ``k`` on,
    exactly as a read from the first frame gives them, numbered from ``k``."""
    from pinrecon.video.frames import iter_frames

    cap = cv2.VideoCapture(str(cut))  # ground truth: OpenCV read directly from the first frame
    truth = [cap.read()[1] for _ in range(N)]
    cap.release()
    for ahead in (0, 2):
        got = list(iter_frames(cut, 8, ahead=ahead, start=6, prepare=lambda t, f: (t, f)))
        assert [t for t, _ in got] == [6, 7] and all(np.array_equal(f, truth[t]) for t, f in got)
    assert list(iter_frames(cut, start=N + 5)) == []


def test_a_long_video_is_tracked_in_two_parts_the_same_on_any_number_of_cpus(cut, tracked, openpose, monkeypatch):
    """From :data:`SPLIT_FRAMES` frames on, two trackers take the two halves at once (the second
    starting :data:`WARM_FRAMES` early): the first half is the one tracker's exactly, the second
    lies on OpenPose's points as well as the one tracker's does; one CPU (the parts one after the
    other) gives the same landmarks as two; the frames kept for the overlay are all there, in
    order; an error in the second part's thread is raised in the caller's."""
    from pinrecon.video import mediapipe_pose, track_video, video_info
    from pinrecon.viz.overlay import KeptFrames

    monkeypatch.setattr(mediapipe_pose, "SPLIT_FRAMES", 6)
    monkeypatch.setattr(mediapipe_pose, "WARM_FRAMES", 2)
    assert mediapipe_pose.track_parts(N) == [(0, 0, 6), (4, 6, N)]
    assert mediapipe_pose.track_parts(5) == [(0, 0, 5)]
    info = video_info(cut)
    kept = KeptFrames(info, 64, max_width=None)
    two = track_video(cut, threads=2, on_frame=kept, info=info)
    one = track_video(cut, threads=1)
    assert np.array_equal(two.points, one.points, equal_nan=True)
    assert np.array_equal(two.lifted.points, one.lifted.points, equal_nan=True)
    assert np.array_equal(two.points[:6], tracked.points[:6], equal_nan=True)
    seen = openpose.observed[6:]
    for tr in (two, tracked):
        err = np.linalg.norm(tr.select(BODY).points[6:] - openpose.points[6:], axis=2)
        assert np.median(err[seen]) < 25.0  # as test_track_finds_the_openpose_points: 16 px measured
    cap = cv2.VideoCapture(str(cut))
    truth = [cv2.resize(cap.read()[1], kept.size, interpolation=cv2.INTER_AREA) for _ in range(N)]
    cap.release()
    assert len(kept.frames) == N and all(np.array_equal(a, b) for a, b in zip(kept.frames, truth))

    calls = []
    detect = mediapipe_pose.MediaPipePose.detect_rgb

    def failing(self, rgb):
        calls.append(threading.current_thread().name)
        if threading.current_thread().name != "MainThread" and len(calls) > 3:
            raise RuntimeError("the second tracker failed")
        return detect(self, rgb)

    monkeypatch.setattr(mediapipe_pose.MediaPipePose, "detect_rgb", failing)
    with pytest.raises(RuntimeError, match="second tracker"):
        track_video(cut, threads=2)
    assert not any(t.name.startswith("pinrecon-track") for t in threading.enumerate())


def test_kept_frames_come_in_any_order():
    """Two parts of a video decoded at once hand their frames over out of order: the kept frames
    are the frames in order all the same; with one missing, those before it."""
    from pinrecon.video import VideoInfo
    from pinrecon.viz.overlay import KeptFrames

    frames = np.random.default_rng(1).integers(0, 256, (6, 16, 10, 3), dtype=np.uint8)
    info = VideoInfo("v.mp4", 30.0, 10, 16, 6)
    kept, gap = KeptFrames(info, None, max_width=None), KeptFrames(info, None, max_width=None)
    for t in (3, 4, 5, 0, 1, 2):
        kept(t, frames[t])
        if t != 4:
            gap(t, frames[t])
    assert len(kept.frames) == 6 and all(np.array_equal(a, b) for a, b in zip(kept.frames, frames))
    assert len(gap.frames) == 4


@pytest.fixture(scope="module")
def openpose():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tracks = pr.load_tracks(data_folder("pose2sim-balancing/pose/cam01_json"), fps=60.0)
    return tracks.frames(0, N).select(BODY)


@pytest.fixture(scope="module")
def tracked(cut):
    from pinrecon.video import track_video

    return track_video(cut)


def test_track_finds_the_openpose_points(tracked, openpose):
    assert (tracked.T, tracked.K, tracked.fps, tracked.layout) == (N, 33, 60.0, "mediapipe33")
    mp = tracked.select(BODY)
    err = np.linalg.norm(mp.points - openpose.points, axis=2)  # pixels, 1080 x 1920 frames
    seen = openpose.observed
    assert seen.mean() > 0.9
    # two detectors' definitions of a joint differ: measured median 16 px, worst point 35 px
    assert np.median(err[seen]) < 25.0
    assert np.all(np.nanmedian(np.where(seen, err, np.nan), axis=0) < 35.0)
    # a coordinate slip (normalised by the wrong side, frames off by one) is far beyond that
    assert np.median(np.linalg.norm(mp.points[:, :, ::-1] - openpose.points, axis=2)[seen]) > 100.0
    assert np.all((tracked.confidence >= 0) & (tracked.confidence <= 1)) and tracked.confidence[:, 11:17].min() > 0.5


def test_lifted_are_mediapipes_world_landmarks(tracked):
    lifted = tracked.lifted
    assert (lifted.T, lifted.K, lifted.frame, lifted.source) == (N, 33, "unknown", "mediapipe")
    names = lifted.names
    hips = (lifted.points[:, names.index("left_hip")] + lifted.points[:, names.index("right_hip")]) / 2
    np.testing.assert_allclose(hips, 0.0, atol=0.01)  # hips-centred
    head_y = lifted.points[:, names.index("nose"), 1]
    ankle_y = lifted.points[:, names.index("left_ankle"), 1]
    assert np.all(ankle_y - head_y > 1.0)  # metres, y down
    np.testing.assert_array_equal(lifted.confidence, tracked.confidence)


@pytest.mark.parametrize("suffix", [".json", ".npz"])
def test_tracks_file_round_trips_2d_visibility_and_3d(tracked, tmp_path, suffix):
    path = tmp_path / f"tracks{suffix}"
    tracked.save(path)
    back = pr.load_tracks(path)
    assert back.names == tracked.names and back.fps == tracked.fps
    np.testing.assert_array_equal(back.points, tracked.points)
    np.testing.assert_array_equal(back.confidence, tracked.confidence)
    assert back.lifted is not None and back.lifted.frame == "unknown" and back.lifted.names == tracked.names
    np.testing.assert_array_equal(back.lifted.points, tracked.lifted.points)
    np.testing.assert_array_equal(back.lifted.confidence, tracked.lifted.confidence)


def test_track_command_writes_the_tracks_file(cut, tracked, tmp_path, capsys):
    out = tmp_path / "t.json"
    assert main(["track", str(cut), "--out", str(out)]) == 0
    assert "10 frames of 1080 x 1920 at 60 fps" in capsys.readouterr().err
    back = pr.load_tracks(out)
    assert back.T == N and back.lifted is not None
    np.testing.assert_allclose(back.points, tracked.points, atol=0.5)  # the same detector on the same frames


@pytest.fixture(scope="module")
def video_run(cut, tmp_path_factory):
    out = tmp_path_factory.mktemp("video_out")
    t0 = time.perf_counter()
    status = main(["video", str(cut), "--out", str(out), "--no-plots", "--quiet"])
    return status, out, time.perf_counter() - t0


def test_video_command_writes_result_exports_and_overlay(video_run):
    status, out, _ = video_run
    assert status == 0
    for name in ("tracks.json", "result.npz", "motion.bvh", "motion.csv", "motion.trc", "overlay.mp4"):
        assert (out / name).stat().st_size > 0, name
    res = pr.load_result(out / "result.npz")
    assert res.keypoints3d.shape[0] == N and len(res.figure.keypoint_names) == 21  # the mediapipe33 map



def test_video_progress_names_each_stage(cut, tracked, tmp_path, capsys):
    """Without --quiet the command says each stage of the reconstruction as it starts, and labels
    the solver's iterations with it (as ``pinrecon reconstruct``)."""
    from pinrecon.cli import build_parser
    from pinrecon.commands.video import run_video
    from pinrecon.stages import STAGES

    args = build_parser().parse_args(["video", str(cut), "--out", str(tmp_path / "out"), "--no-plots",
                                      "--no-overlay"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run_video(args, tracked=[tracked])
    err = capsys.readouterr().err.splitlines()
    said = [line.split()[2] for line in err if line.startswith("pinrecon: stage ")]
    assert said == list(STAGES)
    solve_lines = [line for line in err if line.startswith("solve: iter ")]
    assert solve_lines and all("/100  cost " in line for line in solve_lines)


@pytest.mark.parametrize("how", ["another process", "here: no interpreter", "here: the process failed"])
def test_plots_are_drawn_beside_the_overlay_or_here(cut, tracked, tmp_path, monkeypatch, how):
    """The plots come from ``pinrecon plot`` in another process while the overlay is written;
    where that process cannot start or fails, they are drawn in the command's own process:
    the same four pictures either way."""
    import subprocess

    from pinrecon.cli import build_parser
    from pinrecon.commands.video import run_video

    started = []
    popen = subprocess.Popen
    monkeypatch.setattr(subprocess, "Popen", lambda cmd, **kw: started.append(cmd) or popen(cmd, **kw))
    monkeypatch.setattr("pinrecon.processes.usable_cpus", lambda: 2)
    if how == "another process":  # and not here
        monkeypatch.setattr("pinrecon.viz.plot_result", lambda *a, **k: pytest.fail("plots drawn here"))
    else:
        monkeypatch.setattr(sys, "executable", str(tmp_path / "no-python") if "no" in how else "false")
    args = build_parser().parse_args(["video", str(cut), "--out", str(tmp_path / "out"), "--quiet"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = run_video(args, tracked=[tracked])
    pngs = sorted(p.name for p in run["files"] if p.suffix == ".png")
    assert pngs == ["joint_angles.png", "reprojection.png", "reprojection_error.png", "stick_strip.png"]
    for name in pngs:
        assert cv2.imread(str(tmp_path / "out" / "plots" / name)).shape[0] > 100, name
    assert len(started) == 1 and started[0][3:6] == ["plot", str(tmp_path / "out" / "result.npz"), "--out"]
    assert (tmp_path / "out" / "overlay.mp4").stat().st_size > 0


def test_an_overlay_that_fails_stops_the_plots_and_leaves_no_half_written_folder(cut, tracked, tmp_path,
                                                                                 monkeypatch):
    import subprocess

    from pinrecon.cli import build_parser
    from pinrecon.commands import video as video_module
    from pinrecon.errors import InputError

    procs = []
    popen = subprocess.Popen
    monkeypatch.setattr(subprocess, "Popen", lambda cmd, **kw: procs.append(popen(cmd, **kw)) or procs[-1])
    monkeypatch.setattr("pinrecon.processes.usable_cpus", lambda: 2)

    def fails(*a):
        time.sleep(0.3)  # the plots' process is under way (it takes seconds)
        raise InputError("the disk is full", file="overlay.mp4")

    monkeypatch.setattr(video_module, "_write_overlays", fails)
    args = build_parser().parse_args(["video", str(cut), "--out", str(tmp_path / "out"), "--quiet"])
    ignored = signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a test runner's worker may: the child inherits it
    try:
        with warnings.catch_warnings(), pytest.raises(InputError, match="disk is full"):
            warnings.simplefilter("ignore")
            video_module.run_video(args, tracked=[tracked])
    finally:
        signal.signal(signal.SIGINT, ignored)
    assert len(procs) == 1 and procs[0].returncode not in (None, 0)  # stopped, not finished
    plots = tmp_path / "out" / "plots"
    assert not plots.exists() or not any(plots.iterdir())

def test_the_plots_seconds_are_their_process_s_not_the_wait_for_the_overlay(tmp_path, monkeypatch):
    """``pinrecon video`` collects the plots after the overlay is written: the seconds it prints
    for them are their process's, from "go" to its end, not that wait. Ground truth: a process
    that takes 0.3 s, collected 1.5 s after it was told to go."""
    from pinrecon.commands import video as video_module

    monkeypatch.setattr("pinrecon.processes.usable_cpus", lambda: 2)
    plots = video_module._Plots(tmp_path / "result.npz", tmp_path / "plots", [tmp_path / "tracks.json"])
    plots.CODE = ("import os, sys, time; sys.stdin.readline(); time.sleep(0.3); print('drawn.png'); "
                  "sys.stdout.flush(); os._exit(0)")
    plots.start()
    time.sleep(0.5)  # its Python started
    plots.go()
    time.sleep(1.5)  # the overlay being written
    assert plots.result(None, [None]) == [Path("drawn.png")]
    assert 0.3 <= plots.seconds < 1.0


def test_the_plots_process_starts_after_the_detector_and_ends_without_drawing_when_it_fails(cut, tracked, tmp_path,
                                                                                             monkeypatch):
    """The plots' process is started once the detector is done (it imports while the solve runs,
    not beside the detector's decoding) and draws only once the result is saved: a solve that
    fails leaves it to end on its own, with nothing drawn."""
    import subprocess

    import pinrecon.arguments
    from pinrecon.cli import build_parser
    from pinrecon.commands import video as video_module
    from pinrecon.errors import InputError

    procs = []
    popen = subprocess.Popen
    monkeypatch.setattr(subprocess, "Popen", lambda cmd, **kw: procs.append(popen(cmd, **kw)) or procs[-1])
    monkeypatch.setattr("pinrecon.processes.usable_cpus", lambda: 2)

    def fails(*a, **k):
        assert len(procs) == 1 and procs[0].poll() is None  # started before the solve, waiting
        raise InputError("no solution", file="tracks.json")

    def detector(*a, **k):
        assert not procs  # not yet started while the detector runs
        return tracked

    monkeypatch.setattr(pinrecon.arguments, "reconstruct_from_args", fails)
    monkeypatch.setattr("pinrecon.video.track_video", detector)
    args = build_parser().parse_args(["video", str(cut), "--out", str(tmp_path / "out"), "--quiet"])
    with warnings.catch_warnings(), pytest.raises(InputError, match="no solution"):
        warnings.simplefilter("ignore")
        video_module.run_video(args)
    assert len(procs) == 1 and procs[0].returncode == 0  # told nothing: it ended without drawing
    assert not (tmp_path / "out" / "plots").exists()


def test_overlay_plays_and_its_skeleton_lies_on_the_detections(video_run, openpose):
    _, out, _ = video_run
    cap = cv2.VideoCapture(str(out / "overlay.mp4"))
    assert cap.isOpened()
    frames = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(f)
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == N == len(frames)
    assert frames[0].shape == (960, 2 * 540, 3)  # 1080 x 1920 scaled to 960 rows, a side view beside
    diff = np.array(frames, np.int16) - np.array(JOINT_BGR, np.int16)
    magenta = np.einsum("...c,...c->...", diff, diff, dtype=np.int32) < 90**2  # the drawn keypoints

    def hit_rate(dx_px, r=12):
        hits = []
        for t in range(N):
            for k in np.flatnonzero(openpose.observed[t]):
                x, y = np.round(openpose.points[t, k] * 0.5).astype(int)  # into the overlay's scale
                x += dx_px
                hits.append(magenta[t, max(0, y - r): y + r + 1, max(0, x - r): min(540, x + r + 1)].any())
        return np.mean(hits)

    assert hit_rate(0) > 0.9  # measured 0.98 on the whole clip
    assert hit_rate(120) < 0.4  # the same test, beside the body, fails (measured 0.10)
    assert magenta[:, :, 540:].any()  # the side view has its keypoints too


def test_overlay_stops_where_the_result_does(video_run, tmp_path):
    """The result covers the cut's 10 frames; drawn over the whole 100-frame video, the
    overlay stops there too (and may be drawn at the input's size)."""
    from pinrecon.viz.overlay import write_overlay

    _, out, _ = video_run
    path = write_overlay(pr.load_result(out / "result.npz"), data_file("pose2sim-balancing/videos/cam01.mp4"),
                         tmp_path / "o.mp4", max_height=None, max_width=None)
    cap = cv2.VideoCapture(str(path))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == N
    assert (cap.get(cv2.CAP_PROP_FRAME_WIDTH), cap.get(cv2.CAP_PROP_FRAME_HEIGHT)) == (2 * 1080, 1920)


def test_overlay_from_the_detectors_frames_is_the_overlay_decoded_again(video_run, cut, tracked, tmp_path,
                                                                       monkeypatch):
    """``pinrecon video`` keeps the frames the detector decoded (scaled to the overlay's size,
    :class:`KeptFrames`) and draws the overlay on them: the same video, frame for frame, as
    the overlay drawn on the video decoded again; a video over the budget is decoded again."""
    from pinrecon.video import video_info
    from pinrecon.viz import overlay as overlay_module

    res = pr.load_result(video_run[1] / "result.npz")
    info = video_info(cut)
    kept = overlay_module.KeptFrames(info, 960)
    small = overlay_module.KeptFrames(info, 960, budget=3 * 960 * 540 * 3)  # room for 3 of the 10 frames
    for t, frame in enumerate(overlay_module.iter_frames(cut)):
        kept(t, frame)
        small(t, frame)
    assert len(kept.frames) == N and kept.frames[0].shape == (960, 540, 3) and small.frames is None

    def read(path):
        cap = cv2.VideoCapture(str(path))
        frames = [cap.read()[1] for _ in range(N)]
        cap.release()
        return np.array(frames)

    decoded = read(overlay_module.write_overlay(res, cut, tmp_path / "decoded.mp4", tracks=tracked))
    again = read(overlay_module.write_overlay(res, cut, tmp_path / "small.mp4", tracks=tracked, frames=small))
    monkeypatch.setattr(overlay_module, "iter_frames", lambda *a, **k: pytest.fail("decoded the video again"))
    from_kept = read(overlay_module.write_overlay(res, cut, tmp_path / "kept.mp4", tracks=tracked, frames=kept))
    assert decoded.shape == (N, 960, 1080, 3)
    assert np.array_equal(from_kept, decoded) and np.array_equal(again, decoded)



def test_plot_draws_the_overlay_of_a_saved_result_and_marks_frames_nothing_was_seen_on(video_run, cut, tmp_path,
                                                                                    capsys):
    """``pinrecon plot RESULT --video VIDEO`` writes the overlay ``pinrecon video`` writes, from the
    saved result (``write_overlay`` takes its path), beside the plots; a frame without a 2D point
    says so. Ground truth: the same result with frames 3-5 set unobserved, against its overlay
    with every frame observed: the label's pixels differ in the panels' top rows there only."""
    from pinrecon.viz.overlay import write_overlay

    _, out, _ = video_run
    res = pr.load_result(out / "result.npz")
    assert res.observed_frames.all()
    res.observed_frames[3:6] = False
    res.save(tmp_path / "gap.npz")
    assert main(["plot", str(tmp_path / "gap.npz"), "--out", str(tmp_path / "p"), "--video", str(cut),
                 "--tracks", str(out / "tracks.json"), "--no-animation"]) == 0
    written = capsys.readouterr().out.split()
    assert str(tmp_path / "p" / "overlay.mp4") in written and str(tmp_path / "p" / "joint_angles.png") in written
    seen = write_overlay(str(out / "result.npz"), cut, tmp_path / "seen.mp4", tracks=pr.load_tracks(out / "tracks.json"))

    def read(path):
        cap = cv2.VideoCapture(str(path))
        frames = [cap.read()[1] for _ in range(N)]
        assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == N
        return np.array(frames, np.int16)

    band = np.abs(read(tmp_path / "p" / "overlay.mp4") - read(seen))[:, :40].max(axis=-1) > 80  # (N, 40, 1080)
    left, right = band[..., :540].sum(axis=(1, 2)), band[..., 540:].sum(axis=(1, 2))
    assert (left[3:6] > 100).all() and (right[3:6] > 30).all()  # "not observed ...", "NOT OBSERVED"
    assert left[[0, 1, 2, 6, 7, 8, 9]].max() < 20 and right[[0, 1, 2, 6, 7, 8, 9]].max() < 20

    assert main(["plot", str(out / "result.npz"), "--out", str(tmp_path / "q"), "--video", str(cut), str(cut)]) == 2
    assert "2 video(s) for a result of 1 camera(s)" in capsys.readouterr().err
    text = tmp_path / "notes.mp4"
    text.write_text("not a video\n")
    assert main(["plot", str(out / "result.npz"), "--out", str(tmp_path / "r"), "--video", str(text)]) == 2
    assert "notes.mp4" in capsys.readouterr().err and not (tmp_path / "r").exists()  # refused before any picture


def test_an_encoder_that_fails_midway_stops_the_overlay_and_leaves_no_file(video_run, cut, tmp_path, monkeypatch):
    """The overlay's frames are encoded in a thread of their own beside the drawing: an encoder
    failing at its fourth frame is raised in the caller (not lost in the thread, nor a hang), and
    the half-written video is removed."""
    from pinrecon.viz import overlay as overlay_module

    real, written = cv2.VideoWriter, []

    class Failing:
        def __init__(self, *a):
            self.inner = real(*a)

        def isOpened(self):
            return self.inner.isOpened()

        def write(self, frame):
            written.append(frame.copy())
            if len(written) == 4:
                raise OSError("No space left on device")
            self.inner.write(frame)

        def release(self):
            self.inner.release()

    monkeypatch.setattr(cv2, "VideoWriter", Failing)
    res = pr.load_result(video_run[1] / "result.npz")
    with pytest.raises(OSError, match="No space left"):
        overlay_module.write_overlay(res, cut, tmp_path / "o.mp4")
    assert len(written) == 4 and not list(tmp_path.iterdir())
    assert not any(t.name == "pinrecon-overlay-encoder" for t in threading.enumerate())

def test_kept_frames_fill_a_store_mapped_at_once_and_go_on_past_it():
    """The kept frames' memory is mapped in before the first frame (:func:`frame_store`): they are
    OpenCV's scaled frames all the same, frame for frame; a video with more frames than its file
    says goes on in arrays of their own; one the budget cannot hold keeps none from the start."""
    from pinrecon.video import VideoInfo
    from pinrecon.viz.overlay import KeptFrames, frame_store

    frames = np.random.default_rng(0).integers(0, 256, (6, 64, 36, 3), dtype=np.uint8)
    info = VideoInfo("v.mp4", 30.0, 36, 64, 4)  # the file says 4 frames; 6 come
    kept, whole = KeptFrames(info, 32, max_width=None), KeptFrames(info, None, max_width=None)
    for t, f in enumerate(frames):
        kept(t, f)
        whole(t, f)
    frames[:] = 0  # the caller's buffers reused: what was kept stays
    again = np.random.default_rng(0).integers(0, 256, (6, 64, 36, 3), dtype=np.uint8)
    expected = [cv2.resize(f, (18, 32), interpolation=cv2.INTER_AREA) for f in again]
    assert kept.size == (18, 32) and len(kept.frames) == 6
    assert all(np.array_equal(a, b) for a, b in zip(kept.frames, expected))
    assert all(np.array_equal(a, b) for a, b in zip(whole.frames, again))
    assert kept.frames[0].base is not None and kept.frames[5].base is None  # in the store, then its own
    assert KeptFrames(info, 32, max_width=None, budget=3 * 18 * 32 * 3).frames is None
    counted, uncounted = VideoInfo("v.mp4", 30.0, 36, 64, 100), VideoInfo("v.mp4", 30.0, 36, 64, 0)
    assert [counted.frames_read(m) for m in (None, 20, 200)] == [100, 20, 100]
    assert [uncounted.frames_read(m) for m in (None, 50)] == [0, 50]
    store = frame_store(3, 4, 5)
    store[2, 3, 4, 1] = 9
    assert store.shape == (3, 4, 5, 3) and store.dtype == np.uint8 and store.sum() == 9


def test_two_calibrated_videos_are_one_solve(cut, tmp_path):
    """Cameras 1 and 2 of the trial with their calibration (pinrecon camera files from the
    Pose2Sim TOML): one solve of 5 frames, in the calibration's world, near the four-camera
    triangulation."""
    from pinrecon.io.calibration import load_cameras
    from pinrecon.io.trc import load_trc

    cams = load_cameras(data_file("pose2sim-balancing/calibration/Calib_qualisys.toml"))
    files = []
    for c in cams[:2]:
        c.camera.save(tmp_path / f"{c.name}.json")
        files += ["--camera", str(tmp_path / f"{c.name}.json")]
    video2 = data_file("pose2sim-balancing/videos/cam02.mp4")
    out = tmp_path / "two"
    assert main(["video", str(cut), str(video2), *files, "--max-frames", "5", "--no-plots", "--quiet",
                 "--out", str(out)]) == 0
    for name in ("tracks_cam01_cut.json", "tracks_cam02.json", "overlay_cam01_cut.mp4", "overlay_cam02.mp4"):
        assert (out / name).stat().st_size > 0, name
    assert int(cv2.VideoCapture(str(out / "overlay_cam02.mp4")).get(cv2.CAP_PROP_FRAME_COUNT)) == 5
    res = pr.load_result(out / "result.npz")
    assert len(res.cameras) == 2 and pr.load_tracks(out / "tracks_cam02.json").lifted.camera == 1
    m = load_trc(data_file("pose2sim-balancing/pose-3d/S00_P00_T01_BalancingTrial_0-100.trc"), names="pinrecon")
    G = m.points[:5, [m.names.index(n) for n in BODY]]
    P = res.keypoints3d[:, res.figure.keypoint_index(BODY)]
    err_mm = 1000 * np.linalg.norm(P - G, axis=2)
    assert np.median(err_mm) < 80.0  # two calibrated views fix depth: no alignment needed (4 views: 49 mm)


def test_bad_input_is_one_clear_error(cut, tmp_path, capsys):
    text = tmp_path / "notes.mp4"
    text.write_text("not a video\n")
    assert main(["track", str(text), "--out", str(tmp_path / "a.json")]) == 2
    err = capsys.readouterr().err
    assert "not a video" in err and "notes.mp4" in err and "Traceback" not in err

    assert main(["video", str(tmp_path / "missing.mp4"), "--out", str(tmp_path / "o")]) == 2
    assert "file not found" in capsys.readouterr().err

    blocker = tmp_path / "a_file"
    blocker.write_text("")
    t0 = time.perf_counter()
    assert main(["video", str(cut), "--out", str(blocker / "out")]) == 2
    err = capsys.readouterr().err
    assert "cannot write" in err and "--out" in err
    assert time.perf_counter() - t0 < 3.0  # before the detector ran
    assert main(["track", str(cut), "--out", str(blocker / "t.json")]) == 2
    assert "cannot write" in capsys.readouterr().err

    assert main(["video", str(cut), str(cut), "--out", str(tmp_path / "o2")]) == 2
    assert "--calibration" in capsys.readouterr().err
    t0 = time.perf_counter()
    calib = str(data_file("pose2sim-balancing/calibration/Calib_qualisys.toml"))
    assert main(["video", str(cut), str(cut), "--calibration", calib, "--out", str(tmp_path / "o4")]) == 2
    err = capsys.readouterr().err  # four cameras for two videos: said before the detector, nothing written
    assert "'--calibration': 2 videos but the calibration holds 4 cameras" in err and "--camera-name" in err
    assert time.perf_counter() - t0 < 3.0 and not (tmp_path / "o4").exists()
    t0 = time.perf_counter()  # a BVH figure names its joints, not MediaPipe's points: said before the detector
    bvh = str(data_file("mocap/cmu-mb_02_01.bvh"))
    assert main(["video", str(cut), "--figure", bvh, "--length-scale", "0.056444", "--out", str(tmp_path / "o5")]) == 2
    err = capsys.readouterr().err
    assert "MediaPipe landmarks and the figure share no keypoint name" in err and "--keypoints MAP.json" in err
    assert "cmu-mb_02_01.bvh" in err and time.perf_counter() - t0 < 3.0 and not (tmp_path / "o5").exists()
    assert main(["video", str(cut), "--out", str(tmp_path / "o3"), "--overlay-height", "0"]) == 2
    assert "--overlay-height" in capsys.readouterr().err and not (tmp_path / "o3").exists()


def test_overlay_panels_fit_a_square_by_default_or_take_the_height_given():
    """Each panel within 960 x 960 by default, whatever the orientation (a landscape video's
    overlay was 3412 x 960: four times the pixels to encode); ``--overlay-height`` sets the
    height alone; never enlarged; even sizes."""
    from types import SimpleNamespace

    from pinrecon.commands.video import _overlay_bounds
    from pinrecon.video import VideoInfo
    from pinrecon.viz.overlay import KeptFrames

    def size(w, h, height=None):
        return KeptFrames(VideoInfo("v.mp4", 30.0, w, h, 10), **_overlay_bounds(SimpleNamespace(overlay_height=height))).size

    assert size(1080, 1920) == (540, 960)
    assert size(1920, 1080) == (960, 540)
    assert size(1920, 1080, 720) == (1280, 720)
    assert size(640, 360) == (640, 360)
    assert size(641, 361, 1000) == (640, 360)  # to even sizes


def test_a_small_person_in_a_wide_shot_is_found_in_a_crop(cut, tracked, tmp_path, capsys):
    """The cut shrunk to 0.3 of its size in the middle of a black frame as large: MediaPipe finds
    nobody in it (the error says why and names --crop); run on a crop around the person it finds
    them in every frame, and the landmarks are the whole frame's pixels: 0.3 times the full-size
    video's, shifted by where the small picture sits, to a few pixels. A crop outside the frame,
    or with two videos, is refused before any work."""
    from pinrecon.video import track_video

    cap = cv2.VideoCapture(str(cut))
    frames = [cap.read()[1] for _ in range(N)]
    cap.release()
    H, W = frames[0].shape[:2]
    h, w, y0, x0 = int(0.3 * H), int(0.3 * W), 900, 400
    small = tmp_path / "small.mp4"
    out = cv2.VideoWriter(str(small), cv2.VideoWriter_fourcc(*"mp4v"), 60.0, (W, H))
    for f in frames:
        canvas = np.zeros_like(f)
        canvas[y0:y0 + h, x0:x0 + w] = cv2.resize(f, (w, h), interpolation=cv2.INTER_AREA)
        out.write(canvas)
    out.release()

    assert main(["video", str(small), "--out", str(tmp_path / "o"), "--quiet", "--no-plots"]) == 2
    assert "--crop X Y W H" in capsys.readouterr().err
    found = track_video(small, crop=(x0 - 20, y0 - 20, w + 40, h + 40))
    assert found.observed.all(axis=1).sum() == N
    body = [found.names.index(n) for n in BODY]
    truth = tracked.points[:, body] * [w / W, h / H] + [x0, y0]
    assert np.nanmedian(np.linalg.norm(found.points[:, body] - truth, axis=-1)) < 3.0  # pixels of the small picture

    assert main(["video", str(small), "--out", str(tmp_path / "o2"), "--crop", "900", "0", "400", "100"]) == 2
    assert "reaches outside the 1080 x 1920 frame" in capsys.readouterr().err
    assert main(["video", str(small), str(small), "--out", str(tmp_path / "o3"), "--crop", "0", "0", "100", "100",
                 "--calibration", "x.toml"]) == 2
    assert "--crop" in capsys.readouterr().err and not (tmp_path / "o3").exists()


@pytest.mark.slow  # MediaPipe over the cut twice (12 s): CI runs it
def test_the_detectors_threads_reach_its_graph_and_change_no_landmark(cut, tracked, monkeypatch):
    """MediaPipe's legacy Pose takes no thread count: pinrecon sets its networks' XNNPACK threads
    as the graph is built (every CPU by default, 22 -> 14.5 ms a 1080 x 1920 frame on two). The
    graph MediaPipe builds carries the count asked for; the landmarks are the same, digit for digit."""
    from mediapipe.calculators.tensor import inference_calculator_pb2
    from mediapipe.python import solution_base

    from pinrecon.video import MediaPipePose, detector_threads, track_video

    ext = inference_calculator_pb2.InferenceCalculatorOptions.ext
    built, real = [], solution_base.calculator_graph.CalculatorGraph

    def spy(*, graph_config):
        built.append([n.options.Extensions[ext].delegate.xnnpack.num_threads for n in graph_config.node
                      if n.calculator.startswith("InferenceCalculator")])
        return real(graph_config=graph_config)

    monkeypatch.setattr(solution_base.calculator_graph, "CalculatorGraph", spy)
    one, three = track_video(cut, threads=1), track_video(cut, threads=3)
    assert built == [[1, 1], [3, 3]]  # the pose detector's network and the landmarks'
    for other in (one, three):
        np.testing.assert_array_equal(other.points, tracked.points)
        np.testing.assert_array_equal(other.lifted.points, tracked.lifted.points)
        np.testing.assert_array_equal(other.confidence, tracked.confidence)
    with pytest.raises(ValueError, match="threads must be at least 1"):
        MediaPipePose(threads=0)
    monkeypatch.delenv("PINRECON_DETECTOR_THREADS", raising=False)
    monkeypatch.setattr("pinrecon.video.mediapipe_pose.usable_cpus", lambda: 8)
    assert (detector_threads(), detector_threads(2), detector_threads(3), detector_threads(16)) == (4, 4, 2, 1)
    monkeypatch.setenv("PINRECON_DETECTOR_THREADS", "3")
    with MediaPipePose() as pose:
        assert detector_threads() == 3 and pose.threads == 3
    monkeypatch.setattr("pinrecon.video.mediapipe_pose.usable_cpus", lambda: 2)  # 3 threads on 2 CPUs: 20x slower
    with pytest.warns(UserWarning, match="PINRECON_DETECTOR_THREADS=3 is more than the 2 CPU"):
        assert detector_threads() == 2
    for bad in ("0", "two", "-1"):
        monkeypatch.setenv("PINRECON_DETECTOR_THREADS", bad)
        with pytest.raises(pr.InputError, match="PINRECON_DETECTOR_THREADS"):
            detector_threads()


def test_mediapipe_is_imported_without_matplotlib_which_stays_importable():
    """MediaPipe's package imports matplotlib.pyplot for drawing helpers its Pose never uses (0.3 s
    of every ``pinrecon video``): pinrecon imports it without them; afterwards matplotlib imports
    as usual, and MediaPipe's helpers reach the real pyplot. A fresh interpreter: this one may hold
    matplotlib already."""
    import subprocess

    code = ("import sys; from pinrecon.video.mediapipe_pose import _import_mediapipe; mp = _import_mediapipe(); "
            "print('matplotlib' in sys.modules, 'matplotlib.pyplot' in sys.modules); "
            "import matplotlib; matplotlib.use('Agg'); import matplotlib.pyplot as plt; "
            "print(mp.solutions.drawing_utils.plt.figure is plt.figure, type(plt.figure(figsize=(1, 1))).__name__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "False", "True", "Figure"]


def test_missing_extra_names_it(cut, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "mediapipe", None)  # import mediapipe now raises ImportError
    assert main(["track", str(cut), "--out", str(tmp_path / "t.json")]) == 2
    err = capsys.readouterr().err
    assert 'pip install ".[video]"' in err and "Traceback" not in err
    assert main(["video", str(cut), "--out", str(tmp_path / "o")]) == 2  # before any work
    assert 'pip install ".[video]"' in capsys.readouterr().err and not (tmp_path / "o").exists()
