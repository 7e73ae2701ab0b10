"""No calibration file (issue 12): the auto camera, cameras from keyframes, the CLI.

Ground truth: cameras built here with ``Perspective.look_at`` / ``Orthographic.from_view``
and points projected through them; the field-of-view formula written out; accuracy of
the end-to-end runs from the CMU clip's own joints (PA-MPJPE written out in
``tests/alignment.py``).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from alignment import pa_mpjpe_mm

import pinrecon as pr
from pinrecon.cli import main
from pinrecon.starts.camera_auto import (
    AutoCamera,
    auto_camera,
    camera_from_keyframes,
    camera_pose_from_keyframes,
    camera_scale_from_keyframes,
    orthographic_from_keyframes,
)
from pinrecon.tracks import keyframes_from_points

SIZE = (1280.0, 720.0)


def _cloud(n=40, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform([-1.5, 0.0, -1.0], [1.5, 1.8, 1.0], (n, 3))


def test_auto_perspective_camera_is_the_documented_gauge():
    tracks = pr.Tracks(np.full((3, 4, 2), 100.0), ["a", "b", "c", "d"], 30.0)
    cam = auto_camera(tracks, None, SIZE)
    f = 640.0 / np.tan(np.radians(30.0))  # 60 degrees across 1280 px
    np.testing.assert_allclose(cam.K, [[f, 0, 640.0], [0, f, 360.0], [0, 0, 1]], rtol=1e-12)
    # at the world origin, looking along +Z, image up = world +Y
    np.testing.assert_allclose(cam.project(np.array([0.0, 0.0, 5.0])), [640.0, 360.0], atol=1e-9)
    up, = cam.project(np.array([[0.0, 1.0, 5.0]]))
    assert up[1] < 360.0 and abs(up[0] - 640.0) < 1e-9 and up[1] == pytest.approx(360.0 - f / 5.0)
    wide = auto_camera(tracks, None, SIZE, fov_deg=90.0)
    assert wide.K[0, 0] == pytest.approx(640.0)


def test_auto_camera_needs_an_image_size():
    tracks = pr.Tracks(np.full((3, 4, 2), 100.0), ["a", "b", "c", "d"], 30.0, source="t.json")
    with pytest.raises(pr.InputError, match="image-size"):
        auto_camera(tracks)
    with pytest.raises(pr.InputError, match="image_size"):
        auto_camera(tracks, None, (0, 720))
    with pytest.raises(pr.InputError, match="projection"):
        AutoCamera(SIZE, "fisheye")


def test_perspective_camera_from_keyframes_is_exact_on_exact_data():
    truth = pr.Perspective.look_at([3.0, 1.4, -5.0], [0.2, 0.9, 0.3], f_px=1100.0, center=(640.0, 360.0))
    X = _cloud()
    cam = camera_from_keyframes(X, truth.project(X), SIZE, f0=800.0)
    np.testing.assert_allclose(cam.K, truth.K, atol=1e-6)
    np.testing.assert_allclose(cam.R, truth.R, atol=1e-9)
    np.testing.assert_allclose(cam.t, truth.t, atol=1e-8)
    assert camera_from_keyframes(X[:5], truth.project(X[:5]), SIZE, 800.0) is None  # too few points
    flat = X.copy()
    flat[:, 2] = 0.0
    assert camera_from_keyframes(flat, truth.project(flat), SIZE, 800.0) is None  # coplanar: no DLT


def test_camera_pose_from_keyframes_is_exact_on_exact_data_from_four_points():
    """Perspective-n-point with the focal length known: 4 and 40 exact points give the true
    pose; points in one plane, or too few, give None."""
    truth = pr.Perspective.look_at([3.0, 1.4, -5.0], [0.2, 0.9, 0.3], f_px=1100.0, center=(640.0, 360.0))
    X = _cloud()
    for n in (4, 40):
        cam = camera_pose_from_keyframes(X[:n], truth.project(X[:n]), SIZE, 1100.0)
        np.testing.assert_allclose(cam.R, truth.R, atol=1e-6)
        np.testing.assert_allclose(cam.t, truth.t, atol=1e-6)
        np.testing.assert_allclose(cam.K, truth.K, atol=1e-9)
    assert camera_pose_from_keyframes(X[:3], truth.project(X[:3]), SIZE, 1100.0) is None
    flat = X.copy()
    flat[:, 2] = 0.0
    assert camera_pose_from_keyframes(flat, truth.project(flat), SIZE, 1100.0) is None


def test_one_keyframe_places_the_auto_camera_at_its_default_focal_length():
    """One 3D keyframe (the walk's 12 body points at frame 0, 5 cm noise) cannot fix the
    focal length: the resection with it free failed here at 45 degrees (and landed 1.2 m
    off at 60; on bench_real's detector tracks 84 and 13 m off). ``auto_camera`` places it at
    the default focal length instead (1663 px for 60 degrees across 1920 px; true 1200), as
    far off as that focal length makes it: the distance 1663 / 1200 of the true one, in
    about the true direction (measured 1.43 and 1.35 times the distance, 7.9 and 12.4
    degrees off, 2.5 and 2.3 m). Without noise the same keyframe fixes the focal length
    and the camera is the true one."""
    from pinrecon.synthetic import bundled_motion, coco_body_tracks, perspective_side_camera

    fig, q, fps = bundled_motion("walk")
    q = q[:240]
    for azimuth in (45.0, 60.0):
        cam = perspective_side_camera(q, azimuth)
        tracks, P = coco_body_tracks(fig, q, cam, fps=fps)
        rng = np.random.default_rng(int(azimuth))
        keys = keyframes_from_points([0], P + rng.normal(0.0, 0.05, P.shape), tracks.names, 0.05)
        got = auto_camera(tracks, None, (1920, 1080), keyframes=keys)
        C, C0 = -got.R.T @ got.t, -cam.R.T @ cam.t
        mid = P[0].mean(0)
        assert got.K[0, 0] == pytest.approx(960.0 / np.tan(np.radians(30.0)))
        along = (C - mid) @ (C0 - mid) / np.linalg.norm(C0 - mid) ** 2  # the true direction, scaled
        assert along == pytest.approx(got.K[0, 0] / cam.K[0, 0], rel=0.15)
        assert np.degrees(np.arccos(np.clip((C - mid) @ (C0 - mid) / np.linalg.norm(C - mid)
                                            / np.linalg.norm(C0 - mid), -1, 1))) < 15.0
        exact = auto_camera(tracks, None, (1920, 1080), keyframes=keyframes_from_points([0], P, tracks.names, 0.05))
        np.testing.assert_allclose(-exact.R.T @ exact.t, C0, atol=1e-3)
        assert exact.K[0, 0] == pytest.approx(cam.K[0, 0], rel=1e-4)


def test_too_few_keyframe_points_for_the_auto_camera_are_one_clear_error():
    """Point keyframes that cannot place the auto camera (3 points) are refused: the gauge
    camera's world is not theirs (solving with both put the walk 2.2 m off)."""
    names = ["left_hip", "right_hip", "left_knee", "right_knee"]
    tracks = pr.Tracks(np.random.default_rng(0).uniform(400, 600, (10, 4, 2)), names, 30.0)
    key = pr.Keyframe(0, 0.05, points={"left_hip": [0.0, 0.0, 3.0], "right_hip": [0.2, 0.0, 3.0],
                                       "left_knee": [0.0, -0.4, 3.0]})
    with pytest.raises(pr.InputError) as e:
        pr.reconstruct(pr.Figure.human(), tracks, "auto", pr.Keyframes([key]), image_size=(1280, 720))
    assert e.value.field == "keyframes" and "3 point(s)" in str(e.value)


def test_too_few_keyframe_points_on_the_command_line_name_the_file(tmp_path, capsys):
    """The same refusal from ``pinrecon reconstruct``: one line naming the keyframes file,
    nothing written. The keyframes are saved from points given as plain lists."""
    names = ["left_hip", "right_hip", "left_knee", "right_knee"]
    pr.Tracks(np.random.default_rng(0).uniform(400, 600, (10, 4, 2)), names, 30.0).save(tmp_path / "t.json")
    pr.Keyframes([pr.Keyframe(0, 0.05, points={"left_hip": [0.0, 0.0, 3.0], "right_hip": [0.2, 0.0, 3.0],
                                               "left_knee": [0.0, -0.4, 3.0]})]).save(tmp_path / "k.json")
    code = main(["reconstruct", "--figure", "human", "--tracks", str(tmp_path / "t.json"), "--camera", "auto",
                 "--image-size", "1280", "720", "--keyframes", str(tmp_path / "k.json"), "--out",
                 str(tmp_path / "r.npz")])
    err = capsys.readouterr().err
    assert code != 0 and "k.json" in err and "3 point(s)" in err and "Traceback" not in err
    assert not (tmp_path / "r.npz").exists()


def test_orthographic_camera_from_keyframes_is_exact_on_exact_data():
    truth = pr.Orthographic.from_view([0.4, -0.2, 1.0], scale=260.0, center=(700.0, 300.0))
    X = _cloud(seed=1)
    cam = orthographic_from_keyframes(X, truth.project(X))
    assert cam.scale == pytest.approx(260.0, rel=1e-10)
    np.testing.assert_allclose(cam.R[:2], truth.R[:2], atol=1e-10)
    np.testing.assert_allclose(cam.project(_cloud(seed=2)), truth.project(_cloud(seed=2)), atol=1e-8)


def test_focal_length_and_scale_start_from_keyframes():
    X = _cloud(seed=3)
    names = [f"p{i}" for i in range(len(X))]
    truth = pr.Perspective.look_at([2.0, 1.0, -6.0], [0.0, 0.9, 0.0], f_px=1100.0, center=(640.0, 360.0))
    tracks = pr.Tracks(truth.project(X)[None], names, 30.0)
    keys = keyframes_from_points([0], X[None], names, 0.05)
    short = pr.Perspective(np.diag([770.0, 770.0, 1.0]) + np.array([[0, 0, 640.0], [0, 0, 360.0], [0, 0, 0]]),
                           truth.R, truth.t)
    assert camera_scale_from_keyframes(short, tracks, keys).K[0, 0] == pytest.approx(1100.0, rel=1e-10)
    ortho = pr.Orthographic.from_view([0.3, 0.0, 1.0], scale=300.0, center=(600.0, 350.0))
    tracks_o = pr.Tracks(ortho.project(X)[None], names, 30.0)
    guess = pr.Orthographic(ortho.R, 200.0, (0.0, 0.0))
    fitted = camera_scale_from_keyframes(guess, tracks_o, keys)
    assert fitted.scale == pytest.approx(300.0, rel=1e-10)
    np.testing.assert_allclose(fitted.center, [600.0, 350.0], atol=1e-8)
    assert camera_scale_from_keyframes(guess, tracks_o, keyframes_from_points([0], X[None, :3], names[:3], 0.05)) is guess


def _pa(res, tracks, P):
    return pa_mpjpe_mm(res.keypoints3d[:, res.figure.keypoint_index(list(tracks.names))], P)


@pytest.mark.slow
def test_auto_camera_against_the_true_camera(coco_walk):
    """Without keyframes (measured: PA-MPJPE 38.2 against 39.7 mm, 56.7 before the perspective auto camera
    measured the limb lengths from the tracks; 76.1 against 75.8 mm before the pose prior; focal 1105 px from the
    default 1108.5 px): the focal length is within 10 % only because the default field of
    view is near this camera's; one view barely moves it (docs/globals.md section 6), so
    the result must say the tracks do not determine it. With keyframes the camera comes
    from them (measured: 30.7 against 30.3 mm, focal 1087 px)."""
    cam, tracks, P, kf = coco_walk
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        true = pr.reconstruct(pr.Figure.human(), tracks, cam)
        auto = pr.reconstruct(pr.Figure.human(), tracks, "auto", image_size=SIZE)
        true_kf = pr.reconstruct(pr.Figure.human(), tracks, cam, kf)
        auto_kf = pr.reconstruct(pr.Figure.human(), tracks, AutoCamera(SIZE), kf)
    # the perspective auto camera measures the limb lengths from the tracks too, as the true camera does
    assert auto.calibration["mode"] == "lengths+camera" and auto_kf.calibration["mode"] == "lengths+camera"
    assert "lengths_from_tracks" in auto.calibration
    assert _pa(auto, tracks, P) <= 1.15 * _pa(true, tracks, P)
    assert auto.camera.K[0, 0] == pytest.approx(1100.0, rel=0.10)
    assert auto.calibration["camera_auto"]["focal"]["determined"] is False  # the start's, not the data's
    np.testing.assert_allclose(auto.camera.K[:2, 2], [640.0, 360.0])
    assert _pa(auto_kf, tracks, P) <= 1.15 * _pa(true_kf, tracks, P)
    assert auto_kf.camera.K[0, 0] == pytest.approx(1100.0, rel=0.10)
    assert auto_kf.calibration["camera_auto"]["pose"] == "from the point keyframes, then refined by the solve with the tracks"
    # the keyframes put the auto camera in the clip's world: MPJPE is meaningful there
    Pe = auto_kf.keypoints3d[:, auto_kf.figure.keypoint_index(list(tracks.names))]
    assert 1000 * np.linalg.norm(Pe - P, axis=-1).mean() < 80.0


def _centre(R, t):
    return -np.asarray(R, float).T @ np.asarray(t, float)


def _angle_deg(A, B):
    return float(np.degrees(np.arccos(np.clip((np.trace(np.asarray(A) @ np.asarray(B).T) - 1.0) / 2.0, -1.0, 1.0))))


@pytest.mark.slow
def test_the_tracks_refine_where_two_keyframes_put_the_auto_camera(coco_walk):
    """First and last keyframes only (frames 0 and 105 of the 2 s walk, 5 cm noise): alone
    they place the auto camera 0.61 m and 3.6 degrees from the camera that made the tracks.
    With its pose among the solve's unknowns the tracks of every frame move it to 0.39 m and
    3.0 degrees, and the MPJPE in the clip's world falls from 71.5 mm (held where the
    keyframes put it, measured before this change) to 39.7."""
    from pinrecon.tracks import Keyframes

    cam, tracks, P, kf = coco_walk
    keys = Keyframes([kf[0], kf[len(kf) - 1]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct(pr.Figure.human(), tracks, AutoCamera(SIZE), keys)
    start = res.calibration["camera_auto"]["start"]
    c0, c1, truth = _centre(start["R"], start["t"]), _centre(res.camera.R, res.camera.t), _centre(cam.R, cam.t)
    assert np.linalg.norm(c0 - truth) > 0.5 and np.linalg.norm(c1 - truth) < 0.45
    assert _angle_deg(res.camera.R, cam.R) < _angle_deg(start["R"], cam.R) - 0.3
    moved = res.calibration["cameras"]["camera1"]
    assert moved["shift_m"] == pytest.approx(float(np.linalg.norm(c1 - c0)), rel=1e-9)
    assert moved["rotation_deg"] > 0.1
    Pe = res.keypoints3d[:, res.figure.keypoint_index(list(tracks.names))]
    assert 1000 * np.linalg.norm(Pe - P, axis=-1).mean() < 50.0
    # two keyframes do not fix the focal length, and the report says so from the solve's own profile
    assert res.calibration["camera_auto"]["focal"]["determined"] is False
    assert "keyframes" not in res.calibration["camera_auto"]["focal"]


def test_a_camera_pose_unknown_needs_keyframes_and_a_perspective_camera(coco_walk):
    from pinrecon.problem import make_problem
    from pinrecon.tracks import Keyframes

    cam, tracks, _, kf = coco_walk
    fig = pr.Figure.human()
    p = make_problem(fig, tracks, cam, Keyframes(list(kf)), calibrate="camera", camera_pose=True)
    assert p.global_names[-6:] == [f"camera1.{n}" for n in ("rot_x", "rot_y", "rot_z", "shift_x_m", "shift_y_m",
                                                           "shift_z_m")]
    assert make_problem(fig, tracks, cam, Keyframes(list(kf)), calibrate="none", camera_pose=True).g0 is None
    from pinrecon.reconstruct import build_problem  # the unsolved problem of reconstruct: the same unknowns

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert build_problem(fig, tracks, AutoCamera(SIZE), kf).problem.global_names[-6:] == p.global_names[-6:]
        assert "camera1.rot_x" not in build_problem(fig, tracks, AutoCamera(SIZE)).problem.global_names
    ortho = pr.Orthographic.from_view([0.3, 0.0, 1.0], scale=300.0, center=(600.0, 350.0))
    for camera, keys in ((cam, None), (ortho, Keyframes(list(kf)))):
        with pytest.raises(pr.InputError) as e:
            make_problem(fig, tracks, camera, keys, calibrate="camera", camera_pose=True)
        assert e.value.field == "camera_pose"


def test_orthographic_auto_recovers_the_scale_with_the_subjects_own_figure():
    from pinrecon.synthetic import human_walk, project_tracks, side_camera

    fig, q = human_walk(60, 30.0)
    cam = side_camera(q, 45.0, scale=300.0, center=(640, 360))
    names = ["left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
             "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle"]
    tracks = project_tracks(fig, q, cam, names, fps=30.0, noise_px=1.0, seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct(pr.Figure.human(), tracks, "auto:orthographic", image_size=SIZE)
    assert res.calibration["mode"] == "camera"
    assert res.camera.scale == pytest.approx(300.0, rel=0.01)  # measured 277 -> 300.1


def test_cli_camera_auto_and_save_camera(coco_walk, tmp_path, capsys):
    cam, tracks, P, kf = coco_walk
    tracks.frames(0, 60).save(tmp_path / "tracks.json")
    base = ["reconstruct", "--figure", "human", "--tracks", str(tmp_path / "tracks.json"), "--camera", "auto",
            "--out", str(tmp_path / "r.npz")]
    assert main(base) == 2
    assert "--image-size" in capsys.readouterr().err
    assert main(base + ["--image-size", "1280", "720", "--save-camera", str(tmp_path / "cam.json")]) == 0
    err = capsys.readouterr().out  # the summary is the command's output, on stdout
    assert "auto camera (perspective)" in err and "focal length 1108.5 ->" in err
    # what the tracks say of the focal length is in the summary, not only in a warning
    assert res_focal_line(err) == pr.load_result(tmp_path / "r.npz").calibration["camera_auto"]["focal"]["message"]
    res = pr.load_result(tmp_path / "r.npz")
    saved = pr.load_camera(tmp_path / "cam.json")
    np.testing.assert_allclose(saved.K, res.camera.K)
    np.testing.assert_allclose(saved.R, res.camera.R)
    assert saved.K[0, 0] == pytest.approx(res.calibration["cameras"]["camera1"]["fitted"])
    # the saved camera is the fitted one: it reprojects the result onto the tracks with
    # the result's own reprojection error
    short = tracks.frames(0, 60)
    uv = saved.project(res.keypoints3d[:, res.figure.keypoint_index(list(short.names))])
    np.testing.assert_allclose(np.linalg.norm(uv - short.points, axis=-1).mean(axis=1), res.reprojection_error_px,
                               rtol=1e-9)
    # and it is a camera file like any other
    assert main(["reconstruct", "--figure", "human", "--tracks", str(tmp_path / "tracks.json"), "--camera",
                 str(tmp_path / "cam.json"), "--out", str(tmp_path / "r2.npz"), "--quiet"]) == 0
    assert main(["reconstruct", "--figure", "human", "--tracks", str(tmp_path / "tracks.json"), "--camera",
                 str(tmp_path / "cam.json"), "--image-size", "1280", "720", "--out", str(tmp_path / "r3.npz")]) == 2
    assert "--camera auto" in capsys.readouterr().err


def res_focal_line(summary: str) -> str:
    """The summary line that carries the auto camera's focal-length report."""
    lines = [ln.strip() for ln in summary.splitlines() if "focal length" in ln and ("determined" in ln or "95 %" in ln)]
    assert lines, summary
    return lines[-1].removeprefix("WARNING: ")
