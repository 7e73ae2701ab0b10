"""The README's "Your own video": a real detector folder (Pose2Sim's balancing trial, camera 1,
OpenPose BODY_25B, 100 frames at 60 fps) to a BVH and pictures with no camera file, by the
three commands the README gives, run here as a user runs them.

Ground truth: Pose2Sim's own triangulation of the same 100 frames from all four calibrated
cameras (``S00_P00_T01_BalancingTrial_0-100.trc``, read here by hand), against which the
one-camera reconstruction is scored after a per-frame similarity alignment (PA-MPJPE)."""

from __future__ import annotations

import numpy as np
import pytest
from alignment import pa_mpjpe_mm
from conftest import REPO, data_dir, data_path

import pinrecon as pr
from pinrecon.cli import main
from pinrecon.io.bvh import load_bvh
from pinrecon.io.trc import load_trc
from pinrecon.layouts import COCO_17

TRACKS = data_dir("pose2sim-balancing/pose/cam01_json")
TRC = data_path("pose2sim-balancing/pose-3d/S00_P00_T01_BalancingTrial_0-100.trc")
CALIB = data_path("pose2sim-balancing/calibration/Calib_qualisys.toml")
COCO12 = list(COCO_17[5:])  # the 12 body points: shoulders, elbows, wrists, hips, knees, ankles


def _truth():
    """(T, 12, 3) the triangulated body points of the TRC file, in metres, Z up, in the
    calibration's world (``pinrecon.io.trc.load_trc``: checked against the file's own
    numbers in tests/test_trc.py)."""
    m = load_trc(TRC, names="pinrecon")
    return m.points[:, [m.names.index(n) for n in COCO12]]


@pytest.fixture(scope="module")
def your_video(tmp_path_factory):
    out = tmp_path_factory.mktemp("balance")
    track_args = ["--tracks", str(TRACKS), "--fps", "60"]
    assert main(["reconstruct", "--figure", "human", *track_args, "--camera", "auto", "--image-size", "1088", "1920",
                 "--save-camera", str(out / "camera.json"), "--out", str(out / "result.npz"), "--quiet"]) == 0
    assert main(["export", str(out / "result.npz"), "--bvh", str(out / "motion.bvh")]) == 0
    assert main(["plot", str(out / "result.npz"), *track_args, "--no-animation", "--out", str(out)]) == 0
    return out


def test_three_commands_write_a_bvh_and_pictures(your_video):
    for name in ("result.npz", "camera.json", "motion.bvh", "reprojection.png", "stick_strip.png", "joint_angles.png"):
        assert (your_video / name).is_file() and (your_video / name).stat().st_size > 100, name
    res = pr.load_result(your_video / "result.npz")
    assert res.q.shape[0] == 100
    motion = load_bvh(your_video / "motion.bvh", 0.01)
    assert motion.q.shape[0] == 100
    cam = pr.load_camera(your_video / "camera.json")
    assert cam.K[0, 2] == pytest.approx(544.0) and cam.K[1, 2] == pytest.approx(960.0)  # the image centre


def test_against_pose2sims_four_camera_triangulation(your_video):
    """Measured: 86.2 mm PA-MPJPE with the default (every frame is unlike the single
    Gaussian's clips of walking, running and jumping, so the clip is solved again with the
    broader mixture; 141 mm with ``--pose-prior-model human_pose`` and 107 mm with
    ``--pose-prior none``, both measured before the mirror stage); mean reprojection 5.9 px
    of a 1920 px image (7.3 before the six nose points written at x = 0 were read as missing). The bound keeps what there is (the
    single Gaussian's 141 passed it too); the gap to the lab (10 mm) is the point of the
    test's numbers."""
    res = pr.load_result(your_video / "result.npz")
    G = _truth()
    P = res.keypoints3d[:, res.figure.keypoint_index(COCO12)]
    assert len(P) == len(G) == 100
    pa = pa_mpjpe_mm(P, G)
    assert str(res.extras["prior_model"]) == "human_pose_mixture"
    assert pa < 110.0, pa
    assert float(np.nanmean(res.reprojection_error_px)) < 10.0


def test_the_focal_length_the_prior_gives_is_not_claimed(your_video):
    """Every frame's pose is unlike the prior's clips, and one view owes its focal length to
    the prior: the fit (990 px, its cost profile 963-1031 px) is far from the 1681 px of
    Pose2Sim's own calibration of this camera, so the report must not call it determined. The
    default prior knew none of the poses, so the clip was solved with the broader mixture,
    and the report says the focal length rests on that fallback."""
    from pinrecon.io.calibration import load_cameras

    res = pr.load_result(your_video / "result.npz")
    rep = res.calibration["camera_auto"]["focal"]
    cams = load_cameras(CALIB)
    assert cams[0].name == "cam_01"  # the trial's camera 1
    true_f = float(cams[0].camera.K[0, 0])
    lo, hi = rep["interval_px"]
    assert not lo <= true_f <= hi  # the profile's interval misses the truth ...
    assert rep["determined"] is False and rep["unfamiliar_share"] > 0.5  # ... and the report says so
    assert "NOT determined" in res.summary() and "default pose prior did not know 100 %" in rep["message"]
    assert "human_pose_mixture" in rep["message"]  # the clip was solved with the broader prior, named


# slow (three solves of the real trial, ~85 s of CPU): the trial end to end is the module's
# other tests, stability's copies are tests/test_stability.py's, Pose2Sim's calibration is read
# in tests/test_calibration_io.py; .ci/run runs it
@pytest.mark.slow
def test_coco17_points_through_pose2sims_calibration_of_camera_1():
    """The trial's 17 COCO points (what a COCO-17 detector gives: no feet, no head top)
    through Pose2Sim's calibration of camera 1, against the four-camera triangulation, with
    the depth signs of the limb segments counted here from the camera's rotation.
    Measured: 188.6 mm PA-MPJPE and 17.7 % of the counted limb segment-frames flipped; with
    1 % of the detections left out (seed 2) 143.4 mm. The bounds guard this input, not the
    setting: the MAP alone lands in one of several basins on this trial (bench/bench_video_spread.py:
    over 10 seeds of 1 % removed detections the scores spread over about 100-190 mm), and
    what the test asserts is that pinrecon.stability reports that spread without the
    triangulation."""
    from pinrecon.io.calibration import load_cameras

    cam = load_cameras(CALIB)[0]
    assert cam.name == "cam_01"
    fig = pr.Figure.human()
    tracks = pr.load_tracks(TRACKS, fps=60)
    tracks = tracks.select([n for n in tracks.names if n in fig.keypoint_names])
    assert len(tracks.names) == 17
    # the MAP without pinrecon's lifter (it joins with the broader prior by default): this guards
    # the basins of the MAP alone; the lifter's numbers on this trial are bench_lifter.py's
    res = pr.reconstruct(fig, tracks, cam.camera, lifter="none")
    G = _truth()
    P = res.keypoints3d[:, res.figure.keypoint_index(COCO12)]
    pa = pa_mpjpe_mm(P, G)
    z_axis = cam.camera.R[2]  # depth along the line of sight: the camera's z (t adds the same to both ends)
    limbs = [("shoulder", "elbow"), ("elbow", "wrist"), ("hip", "knee"), ("knee", "ankle")]
    idx = COCO12
    flipped = counted = 0
    for side in ("left", "right"):
        for a, b in limbs:
            i, j = idx.index(f"{side}_{a}"), idx.index(f"{side}_{b}")
            dz_true, dz_est = (G[:, j] - G[:, i]) @ z_axis, (P[:, j] - P[:, i]) @ z_axis
            count = np.abs(dz_true) > 0.1 * np.linalg.norm(G[:, j] - G[:, i], axis=-1)
            counted += int(count.sum())
            flipped += int((count & (np.sign(dz_true) != np.sign(dz_est))).sum())
    assert pa < 195.0, pa
    assert 100.0 * flipped / counted < 20.0, (flipped, counted)
    # the same with 1 % of the detections left out (seed 2): another basin, over 50 mm from
    # this one; pinrecon.stability sees it without the triangulation
    from pinrecon.result import unstable_spans
    from pinrecon.stability import drop_detections, stability

    s = stability(fig, tracks, cam.camera, result=res, runs=1, random_seed=2, lifter="none")
    copy = pr.reconstruct(fig, drop_detections(tracks, 0.01, 2), cam.camera, lifter="none")
    P2 = copy.keypoints3d[:, copy.figure.keypoint_index(COCO12)]
    assert 100.0 < pa_mpjpe_mm(P2, G) < 195.0, pa_mpjpe_mm(P2, G)
    idx = res.figure.keypoint_index(list(tracks.names))
    apart = pa_mpjpe_mm(copy.keypoints3d[:, idx], res.keypoints3d[:, idx])
    assert float(s.spread_mm[0].mean()) == pytest.approx(apart, rel=1e-6) and apart > 50.0
    spans = unstable_spans(s.to_extras())
    assert sum(b - a for a, b, *_ in spans) > 50  # most of the clip reported
    assert "differ by more than 30 mm in some copy" in s.summary()


def test_no_camera_file_with_four_keyframes_from_the_triangulation():
    """A user with no camera file but four 3D keyframes (the triangulation's 13 COCO points
    at frames 0, 33, 66 and 99, 2 cm): the keyframes place the auto camera in the
    calibration's world and the solve refines it. Measured: 0.87 m from Pose2Sim's camera 1,
    MPJPE 89.8 mm in that world against the triangulation (143.9 with the calibrated camera
    and no keyframes), PA-MPJPE 70.1. The focal length (1222 px against the calibration's
    1681) is reported NOT determined, and the advice is more keyframes, not keyframes. The
    keyframes alone (their reprojection profile) put it at 1613-2044 px, which holds the
    calibration's and excludes the fit: the report says so and gives their interval."""
    import warnings

    from pinrecon.io.calibration import load_cameras

    cal = load_cameras(CALIB)[0].camera
    tracks = pr.load_tracks(TRACKS, fps=60)
    fig = pr.Figure.human("auto", tracks=tracks)
    tracks = tracks.select([n for n in tracks.names if n in fig.keypoint_names])
    m = load_trc(TRC, names="pinrecon")
    names = [n for n in COCO_17 if n in m.names and n in fig.keypoint_names]
    keys = pr.Keyframes([pr.Keyframe(f, 0.02, points={n: m.points[f, m.names.index(n)] for n in names})
                         for f in (0, 33, 66, 99)])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = pr.reconstruct(fig, tracks, "auto", keys, image_size=(1088, 1920))
    cam = res.cameras[0]
    assert np.linalg.norm(cam.R.T @ cam.t - cal.R.T @ cal.t) < 1.2
    P, G = res.keypoints3d[:, res.figure.keypoint_index(COCO12)], _truth()
    assert 1000.0 * np.linalg.norm(P - G, axis=-1).mean() < 110.0
    focal = res.calibration["camera_auto"]["focal"]
    assert not focal["determined"] and "more 3D keyframes" in focal["message"]
    assert any("more 3D keyframes" in str(w.message) for w in caught)
    lo, hi = focal["interval_px"]  # the keyframes' own: the calibration inside, the fit outside
    assert focal["keyframes"]["excludes_fit"] and lo < cal.K[0, 0] < hi
    assert not lo / 1.1 <= cam.K[0, 0] <= hi * 1.1 and focal["focal_px"] == pytest.approx(cam.K[0, 0])
    assert f"{lo:.0f}-{hi:.0f} px" in focal["message"] and "outside that" in focal["message"]
