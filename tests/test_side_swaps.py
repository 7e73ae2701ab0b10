"""Spans of frames whose left and right labels a detector kept the other way round, found
from the tracks' continuity before any solve (:func:`pinrecon.faults.side_swap_frames`).

Ground truth independent of the code under test: synthetic clips whose swapped frames the
test (or :func:`pinrecon.synthetic.detector_faults`, which logs them) wrote; and on real
video, Pose2Sim's four-camera triangulation projected through camera 2's calibration: a
frame is swapped where MediaPipe's labels lie nearer the other side's projected points.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_file, data_path

import pinrecon as pr
from pinrecon.faults import left_right_pairs, relabel_sides, side_swap_frames
from pinrecon.layouts import COCO_17
from pinrecon.synthetic import (
    bundled_motion,
    coco_body_tracks,
    detector_faults,
    perspective_side_camera,
)

COCO12 = list(COCO_17[5:])


def _swapped(tracks, frames):
    uv = np.array(tracks.points)
    conf = np.array(tracks.confidence)
    for a, b in left_right_pairs(tracks.names):
        uv[np.ix_(frames, [a, b])] = uv[np.ix_(frames, [b, a])]
        conf[np.ix_(frames, [a, b])] = conf[np.ix_(frames, [b, a])]
    return pr.Tracks(uv, tracks.names, tracks.fps, conf)


@pytest.fixture(scope="module")
def spin():
    """CMU 05_11 (a dance with fast spins), 120 fps in the file."""
    return bundled_motion("spin")


@pytest.mark.parametrize("step, azimuth", [(2, 90.0), (3, 90.0), (3, 45.0), (6, 0.0), (6, 90.0)])
def test_a_spin_keeps_its_labels_and_a_swapped_span_is_found(spin, step, azimuth):
    """A dancer turning fast through side-on (left and right cross in the image) at 60, 40
    and 20 frames/s is not a swap; the detector's single swapped frames and a span of 20
    frames written here are found, exactly."""
    fig, q, fps = spin
    q = q[::step]
    cam = perspective_side_camera(q, azimuth)
    clean, _ = coco_body_tracks(fig, q, cam, fps=fps / step)
    tracks, log = detector_faults(clean, seed=1)
    single = log["swapped_frames"].tolist()
    assert side_swap_frames(tracks).tolist() == single
    span = [t for t in range(len(q) // 3, len(q) // 3 + 20) if t not in single]
    got = side_swap_frames(_swapped(tracks, span)).tolist()
    assert got == sorted(set(single) ^ set(span))


def test_gaps_short_clips_and_names_without_sides():
    fig, q, fps = bundled_motion("walk")
    q = q[::2]
    clean, _ = coco_body_tracks(fig, q, perspective_side_camera(q, 45.0), fps=fps / 2)
    uv = np.array(clean.points)
    uv[40:50] = np.nan  # the person not found for 10 frames, the labels swapped from 30 to 59
    gap = pr.Tracks(uv, clean.names, clean.fps, np.where(np.isnan(uv[..., 0]), 0.0, 1.0))
    assert side_swap_frames(gap).tolist() == []
    got = side_swap_frames(_swapped(gap, list(range(30, 60)))).tolist()
    assert set(range(30, 40)) | set(range(50, 60)) <= set(got) <= set(range(30, 60))
    assert side_swap_frames(clean.frames(0, 3)).tolist() == []
    unsided = pr.Tracks(np.ones((10, 2, 2)), ["nose", "neck"], 30.0)
    assert side_swap_frames(unsided).tolist() == []


def test_relabel_sides_exchanges_the_lifted_pose_too():
    from pinrecon.lifted import Lifted

    names = ["left_knee", "right_knee", "nose"]
    P = np.arange(4 * 3 * 3, dtype=float).reshape(4, 3, 3)
    uv = P[..., :2].copy()
    tracks = pr.Tracks(uv, names, 30.0, np.full((4, 3), 0.5),
                       lifted=Lifted(P, names, np.full((4, 3), 0.7), "camera", "test"))
    out = relabel_sides(tracks, [1, 2])
    assert np.array_equal(out.points[1], uv[1][[1, 0, 2]]) and np.array_equal(out.points[0], uv[0])
    assert np.array_equal(out.lifted.points[2], P[2][[1, 0, 2]]) and np.array_equal(out.lifted.points[3], P[3])
    assert np.array_equal(tracks.points, uv)  # a copy: the input is left as it was


@pytest.fixture(scope="module")
def camera_2():
    """MediaPipe Pose on the first 85 frames of Pose2Sim's camera 2 (its 2D and world landmarks)."""
    pytest.importorskip("cv2")
    pytest.importorskip("mediapipe")
    from pinrecon.video import track_video

    return track_video(data_file("pose2sim-balancing/videos/cam02.mp4"), max_frames=85)


def test_mediapipe_keeps_the_sides_the_other_way_round_on_a_span_of_camera_2(camera_2):
    """MediaPipe Pose on the first 85 frames of Pose2Sim's camera 2: from frame 41 it keeps
    the subject's left and right the other way round for 33 frames (a flicker back at 64 and
    66), which the triangulation says and the tracks' continuity finds."""
    from pinrecon.io.calibration import load_cameras
    from pinrecon.io.trc import load_trc

    n = 85
    tracks = camera_2.select(COCO12)
    m = load_trc(data_path("pose2sim-balancing/pose-3d/S00_P00_T01_BalancingTrial_0-100.trc"), names="pinrecon")
    G = m.points[:n, [m.names.index(c) for c in COCO12]]
    cam = load_cameras(data_path("pose2sim-balancing/calibration/Calib_qualisys.toml"))[1]
    assert cam.name == "cam_02"
    uvG = cam.camera.project(G)
    perm = np.arange(12)
    for a, b in left_right_pairs(COCO12):
        perm[a], perm[b] = b, a
    kept = np.nanmean(np.linalg.norm(tracks.points - uvG, axis=-1), axis=1)
    other = np.nanmean(np.linalg.norm(tracks.points[:, perm] - uvG, axis=-1), axis=1)
    clear = np.abs(kept - other) > 30.0  # px: frames where MediaPipe's labelling is plain
    truth = np.flatnonzero(clear & (other < kept))
    assert len(truth) > 25 and truth.min() == 41
    found = side_swap_frames(tracks)
    assert np.array_equal(np.intersect1d(found, np.flatnonzero(clear)), truth)
    assert len(np.setdiff1d(found, truth)) <= 2  # frames where MediaPipe's labels are neither


@pytest.mark.parametrize("k", [57, 71, 74])
def test_one_exchanged_frame_of_the_3d_does_not_turn_the_rest_over(camera_2, k):
    """MediaPipe's world landmarks are smoothed over time: where it exchanges the sides for one
    frame, its 3D comes back over the next frames (seen on a 2400-frame video of camera 2:
    frame k exchanged, k + 1 half-way back). Judged by its continuity alone, from such a kink
    on the 3D's labels were taken the other way round for the rest of the clip (against its
    2D, which its sides follow). With the 2D's frames as the prior, the 3D's frames are the
    2D's. Ground truth: the frames exchanged here, and the 2D's own (the test above)."""
    import dataclasses

    names = list(camera_2.lifted.names)
    perm = np.arange(len(names))
    for a, b in left_right_pairs(names):
        perm[a], perm[b] = b, a
    W0 = camera_2.lifted.points
    W = np.array(W0)
    W[k] = W0[k][perm]
    for j, w in enumerate((0.5, 0.2), 1):  # coming back
        W[k + j] = w * W0[k + j][perm] + (1 - w) * W0[k + j]
    lifted = dataclasses.replace(camera_2.lifted, points=W)
    in_2d = sorted(set(side_swap_frames(camera_2).tolist()) ^ {k})  # the 2D exchanged on frame k too
    assert len(set(side_swap_frames(lifted).tolist()) ^ set(in_2d)) >= 10  # by continuity alone: a span turned over
    assert side_swap_frames(lifted, prior=in_2d).tolist() == in_2d


def test_long_lists_of_frames_are_cut_in_the_summaries():
    """A long clip's relabelled frames (2400 frames of a video played back and forth: about 130
    ranges) are said as their first ranges and a count; the result's extras keep them all."""
    from pinrecon.result import spans_text

    frames = np.r_[3:6, 9, 20:23]
    assert spans_text(frames) == "3-5, 9, 20-22"
    assert spans_text(frames, 2) == "3-5, 9, ... (3 ranges, 7 frames in all)"
    assert spans_text(frames, 3) == spans_text(frames)
    assert spans_text([], 2) == ""


def test_a_span_of_one_frame_is_said_as_one_frame():
    """The summaries' spans (a disagreement with the lifter, an unfamiliar pose, frames not
    observed) say ``frame 93 (1.55 s)`` for one frame, not ``frames 93-93``."""
    from pinrecon.result import span_text

    assert span_text(93, 94, 60.0) == "frame 93 (1.55 s)"
    assert span_text(84, 91, 60.0) == "frames 84-90 (1.40-1.50 s)"
    assert span_text(np.int64(0), np.int64(30), 60.0) == "frames 0-29 (0.00-0.48 s)"
