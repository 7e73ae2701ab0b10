"""Several cameras in one solve, against synthetic ground truth.

* The bundled CMU walk (the clip's own skeleton, 22 body points) seen by two and by three
  perspective cameras: MPJPE and depth flips against the clip, per-camera reprojection
  errors recomputed here from the result's keypoints.
* Points missing in one camera; frame rates that differ; lengths that do not match.
* The command line with a real Pose2Sim calibration (four cameras with lens distortion)
  and tracks projected through those cameras, paired in the TOML's order.
* The pieces: triangulation through distorted cameras, the start's placement through a
  distorted lens, per-camera reprojection pictures, the result file.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import CMU_UNIT_M, WALK, data_path
from scipy.interpolate import CubicSpline

import pinrecon as pr
from pinrecon.cli import main
from pinrecon.errors import InputError
from pinrecon.io.calibration import load_cameras
from pinrecon.planarity import limb_flip_rate
from pinrecon.problem import make_problem
from pinrecon.starts.rest import place_on_tracks
from pinrecon.starts.triangulation import triangulate
from pinrecon.synthetic import body_keypoints, bundled_motion, project_tracks

WALK_BVH = data_path(WALK)

POSE2SIM_TOML = data_path("project-test-data/calibration/pose2sim/Calib_scene.toml")


@pytest.fixture(scope="module")
def walk60():
    """The first two seconds of the walk at 60 fps: figure, q (120, nq), fps, body names."""
    fig, q, fps = bundled_motion("walk")
    return fig, q[:240:2], fps / 2, body_keypoints(fig)


def ring_cameras(q, azimuths_deg, distance_m=5.0, height_m=1.5, f_px=1200.0):
    """Perspective cameras around the motion's middle (azimuth 0: side-on)."""
    centre = q[:, :3].mean(0)
    d = q[-1, :3] - q[0, :3]
    d[1] = 0.0
    d /= np.linalg.norm(d)
    side = np.cross([0.0, 1.0, 0.0], d)
    cams = []
    for az in azimuths_deg:
        a = np.radians(az)
        eye = centre + distance_m * (np.cos(a) * side + np.sin(a) * d)
        eye[1] = height_m
        cams.append(pr.Perspective.look_at(eye, centre, f_px=f_px, center=(960.0, 540.0)))
    return cams


def mpjpe_mm(fig, P_est, q_true, names):
    idx = fig.keypoint_index(names)
    return 1000 * np.linalg.norm(P_est[:, idx] - fig.keypoints(q_true)[:, idx], axis=-1)


# ----------------------------------------------------------------------------- the walk
@pytest.mark.parametrize("azimuths, bound_mm", [((45.0, -45.0), 5.0), ((45.0, -45.0, 180.0), 4.0)])
def test_walk_seen_by_several_cameras(walk60, azimuths, bound_mm):
    fig, q, fps, names = walk60
    cams = ring_cameras(q, azimuths)
    tracks = [project_tracks(fig, q, c, names, fps=fps, noise_px=1.0, seed=20 + i) for i, c in enumerate(cams)]
    res = pr.reconstruct(fig, tracks, cams)
    err = mpjpe_mm(fig, res.keypoints3d, q, names)
    assert err.mean() < bound_mm  # issue 12: <= 12 mm (two cameras), <= 10 mm (three)
    for c in cams:
        assert limb_flip_rate(fig, res.q, q, c) == 0.0
    # every camera kept, with its own reprojection error, recomputed here from the keypoints
    assert res.camera_names == [f"camera{i + 1}" for i in range(len(cams))]
    assert all(a is b for a, b in zip(res.cameras, cams)) and res.camera is cams[0]
    per = res.reprojection_error_px_per_camera
    assert per.shape == (len(cams), len(q))
    idx = fig.keypoint_index(names)
    for c, (cam, tr) in enumerate(zip(cams, tracks)):
        d = np.linalg.norm(cam.project(res.keypoints3d[:, idx]) - tr.points, axis=-1)
        np.testing.assert_allclose(per[c], d.mean(axis=1), rtol=1e-9)
        assert 1.0 < per[c].mean() < 1.4  # 1 px noise: E|n| = 1.25 px, a little less after the fit
    all_d = np.concatenate([np.linalg.norm(cam.project(res.keypoints3d[:, idx]) - tr.points, axis=-1)
                            for cam, tr in zip(cams, tracks)], axis=1)
    np.testing.assert_allclose(res.reprojection_error_px, all_d.mean(axis=1), rtol=1e-9)
    assert "camera 'camera2'" in res.summary()


def test_generic_human_calibrated_by_default_with_several_cameras(walk60):
    """Issue 12: with ``--figure human`` and calibration, three cameras: MPJPE at most 30 mm.
    Several given cameras see depth, so the generic human's segment lengths are unknowns of
    the solve by default (the clip's subject is not the human's size); the truth is the
    clip's own joints, tracked as the 12 COCO-17 body points."""
    fig, q, fps, _ = walk60
    human = pr.Figure.human()
    coco = {"left_shoulder": "LeftArm", "right_shoulder": "RightArm", "left_elbow": "LeftForeArm",
            "right_elbow": "RightForeArm", "left_wrist": "LeftHand", "right_wrist": "RightHand",
            "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "left_knee": "LeftLeg", "right_knee": "RightLeg",
            "left_ankle": "LeftFoot", "right_ankle": "RightFoot"}
    names = list(coco)
    P = fig.keypoints(q)[:, fig.keypoint_index(list(coco.values()))]
    cams = ring_cameras(q, (45.0, -45.0, 180.0))
    rng = np.random.default_rng(7)
    tracks = [pr.Tracks(c.project(P) + rng.normal(0.0, 1.0, P.shape[:2] + (2,)), names, fps) for c in cams]
    res = pr.reconstruct(human, tracks, cams)
    assert res.calibration["mode"] == "lengths"
    err = 1000 * np.linalg.norm(res.keypoints3d[:, human.keypoint_index(names)] - P, axis=-1).mean()
    off = pr.reconstruct(human, tracks, cams, calibrate="none")
    err_off = 1000 * np.linalg.norm(off.keypoints3d[:, human.keypoint_index(names)] - P, axis=-1).mean()
    assert err < 10.0 < err_off  # measured 2.9 / 33.5 mm on the whole walk (bench_multicam.py)
    # several cameras fix the limbs' lengths and the figure's size; one camera neither
    ident = res.calibration["identifiability"]
    assert ident["size_determined"] and not {"thigh", "shank", "upper_arm", "forearm"} & set(ident["undetermined"])
    single = pr.reconstruct(human, tracks[0], cams[0], skip=["turns", "mirrors", "faults", "feet"])  # not lengths
    one = single.calibration["identifiability"]
    assert not one["size_determined"] and one["size_ratio"] > 0.9
    assert {"thigh", "shank", "upper_arm", "forearm"} <= set(one["undetermined"])
    assert "NOT fixed by the tracks alone: any of these lengths" in "\n".join(single.calibration_summary())
    assert "overall size" not in "\n".join(res.calibration_summary())  # three views: the trunk and head, if any


def test_points_missing_in_one_camera(walk60):
    """Camera 2 loses 20 % of its points, the far leg for half a second and everything for
    a tenth: those points are seen by camera 1 alone, and are still right."""
    fig, q, fps, names = walk60
    cams = ring_cameras(q, (45.0, -45.0))
    tracks = [project_tracks(fig, q, c, names, fps=fps, noise_px=1.0, seed=30 + i) for i, c in enumerate(cams)]
    rng = np.random.default_rng(3)
    uv = tracks[1].points.copy()
    uv[rng.random(uv.shape[:2]) < 0.2] = np.nan
    leg = [names.index(n) for n in ("LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "LeftToeBase_end")]
    uv[40:70, leg] = np.nan
    uv[90:96] = np.nan
    tracks[1] = pr.Tracks(uv, names, fps)
    res = pr.reconstruct(fig, tracks, cams)
    err = mpjpe_mm(fig, res.keypoints3d, q, names)
    missing = ~tracks[1].observed
    assert missing.mean() > 0.25
    assert err.mean() < 7.0  # measured 5.0
    assert err[missing].mean() < 14.0  # measured 9.4
    # the far leg, seen by camera 1 alone for half a second (near-tangent rays: depth is
    # weakly observed) beats a cubic spline through the exact truth around the gap
    P = fig.keypoints(q)[:, fig.keypoint_index(names)]
    seen = np.r_[0:40, 70:len(q)]
    spline = CubicSpline(seen, P[seen], axis=0)(np.arange(40, 70))
    oracle = 1000 * np.linalg.norm(spline - P[40:70], axis=-1)[:, leg].mean()
    assert err[40:70][:, leg].mean() < 0.75 * oracle  # measured 34 mm vs 64 mm
    for c in cams:
        assert limb_flip_rate(fig, res.q, q, c) <= 0.01  # measured 0.5 % and 0 %
    assert np.isnan(res.reprojection_error_px_per_camera[1, 90:96]).all()
    assert np.isfinite(res.reprojection_error_px_per_camera[0, 90:96]).all()


def test_cameras_at_different_rates(walk60):
    """60 fps and 30 fps tracks of the same two seconds: one grid at 60 fps."""
    fig, q, fps, names = walk60
    q = q[:61]
    cams = ring_cameras(q, (45.0, -45.0))
    fast = project_tracks(fig, q, cams[0], names, fps=fps, noise_px=1.0, seed=1)
    slow = project_tracks(fig, q[::2], cams[1], names, fps=fps / 2, noise_px=1.0, seed=2)
    problem = make_problem(fig, [fast, slow], cams)
    assert problem.n_frames == 61 and problem.fps == fps
    assert [v.factor for v in problem.views] == [1, 2]
    np.testing.assert_array_equal(problem.views[1].measurement.frames, np.arange(0, 61, 2))
    res = pr.reconstruct(fig, [fast, slow], cams)
    assert mpjpe_mm(fig, res.keypoints3d, q, names).mean() < 6.0
    # rates that do not divide the fastest: an error saying what to do
    other = pr.Tracks(slow.points[:25], names, 24.0)
    with pytest.raises(InputError, match=r"fps_out.*common multiple.*fps_out=120"):
        make_problem(fig, [pr.Tracks(fast.points[:31], names, 30.0), other], cams)


def test_mismatched_inputs_are_one_clear_error(walk60):
    fig, q, fps, names = walk60
    cams = ring_cameras(q[:40], (45.0, -45.0))
    a = project_tracks(fig, q[:40], cams[0], names, fps=fps)
    b = project_tracks(fig, q[:30], cams[1], names, fps=fps)
    with pytest.raises(InputError) as e:
        pr.reconstruct(fig, [a, b], cams)
    msg = str(e.value)
    assert "'camera2' has 30 frames" in msg and "'camera1' has 40 frames" in msg and "Tracks.frames" in msg
    with pytest.raises(InputError, match="2 tracks but 3 cameras"):
        pr.reconstruct(fig, [a, a], cams + cams[:1])
    with pytest.raises(InputError, match="1 tracks but 2 cameras"):
        pr.reconstruct(fig, a, cams)
    with pytest.raises(InputError, match=r"field 'camera\[1\]'.*pinrecon camera"):
        pr.reconstruct(fig, [a, a], [cams[0], "camera.json"])
    with pytest.raises(InputError, match="unknown track"):
        make_problem(fig, [a, a], cams, keypoints=["Hips", "Nose"])


# ----------------------------------------------------------------------------- Pose2Sim calibration
def _walk_in_scene(cams, n_frames=60):
    """The walk (60 fps) moved into the calibrated scene: world z up, as in the TOML, its
    middle where the cameras' optical axes meet; every point inside every image."""
    import pinocchio as pin

    fig, q, fps = bundled_motion("walk")
    q = q[: 2 * n_frames : 2].copy()
    A, b = np.zeros((3, 3)), np.zeros(3)
    for c in cams:
        d = c.R[2]
        P = np.eye(3) - np.outer(d, d)
        A += P
        b += P @ (-c.R.T @ c.t)
    target = np.linalg.solve(A, b)
    R_w = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # BVH y up -> scene z up
    mid = R_w @ q[:, :3].mean(0)
    t_w = np.array([target[0] - mid[0], target[1] - mid[1], 0.95 - mid[2]])  # hips 0.95 m above z = 0
    M = pin.SE3(R_w, t_w)
    for t in range(len(q)):
        q[t, :7] = pin.SE3ToXYZQUAT(M * pin.XYZQUATToSE3(q[t, :7]))
    return fig, q, fps / 2, M


def test_cli_pairs_tracks_with_a_pose2sim_toml(tmp_path, capsys):
    calib = load_cameras(POSE2SIM_TOML)
    cams = [c.camera for c in calib]
    assert len(cams) == 4 and all(c.has_distortion for c in cams)
    fig, q, fps, M = _walk_in_scene(cams)
    names = body_keypoints(fig)
    # the scene placement is a rigid motion of the clip's points
    fig0, q0, _ = bundled_motion("walk")
    P0 = fig0.keypoints(q0[:120:2])
    np.testing.assert_allclose(fig.keypoints(q), P0 @ M.rotation.T + M.translation, atol=1e-9)
    paths = []
    for i, (c, cam) in enumerate(zip(calib, cams)):
        tr = project_tracks(fig, q, cam, names, fps=fps, noise_px=0.5, seed=40 + i)
        w, h = c.image_size
        assert np.all((tr.points >= 0) & (tr.points <= [w, h]))
        paths.append(tmp_path / f"{c.name}.json")
        tr.save(paths[-1])
    figure_args = ["--figure", str(WALK_BVH), "--length-scale", str(CMU_UNIT_M),
                   "--lock", "LHipJoint", "RHipJoint", "LeftShoulder", "RightShoulder"]
    out = tmp_path / "r.npz"
    args = ["reconstruct", *figure_args]
    for p in paths:
        args += ["--tracks", str(p)]
    code = main(args + ["--camera", str(POSE2SIM_TOML), "--out", str(out), "--quiet"])
    assert code == 0
    res = pr.load_result(out)
    assert res.camera_names == [c.name for c in calib]
    for a, b in zip(res.cameras, cams):
        np.testing.assert_allclose(a.K, b.K)
        np.testing.assert_allclose(a.dist, b.dist)
    assert res.reprojection_error_px_per_camera.shape == (4, len(q))
    assert np.nanmean(res.reprojection_error_px_per_camera) < 0.8  # 0.5 px noise: E|n| = 0.63 px
    idx = fig.keypoint_index(names)
    err = 1000 * np.linalg.norm(res.keypoints3d[:, idx] - fig.keypoints(q)[:, idx], axis=-1)
    assert err.mean() < 4.0
    # three tracks for four cameras: one line naming them, no traceback, nothing written
    capsys.readouterr()
    bad = ["reconstruct", *figure_args]
    for p in paths[:3]:
        bad += ["--tracks", str(p)]
    code = main(bad + ["--camera", str(POSE2SIM_TOML), "--out", str(tmp_path / "bad.npz"), "--quiet"])
    err_text = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err_text
    assert "3 --tracks but the --camera files hold 4 cameras" in err_text
    assert all(c.name in err_text for c in calib)
    assert not (tmp_path / "bad.npz").exists()


def test_cli_help_says_how_cameras_pair(capsys):
    with pytest.raises(SystemExit):
        main(["reconstruct", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "Pose2Sim" in text and "file's order" in text and "repeat it" in text


def test_cli_one_camera_file_per_tracks(tmp_path, walk60):
    """Two pinrecon camera JSON files and two tracks files: paired in order."""
    fig, q, fps, names = walk60
    q = q[:30]
    cams = ring_cameras(q, (45.0, -45.0))
    args = ["reconstruct", "--figure", str(WALK_BVH), "--length-scale", str(CMU_UNIT_M),
            "--lock", "LHipJoint", "RHipJoint", "LeftShoulder", "RightShoulder"]
    for i, c in enumerate(cams):
        c.save(tmp_path / f"cam{i}.json")
        project_tracks(fig, q, c, names, fps=fps, noise_px=0.5, seed=i).save(tmp_path / f"t{i}.json")
    for i in range(2):
        args += ["--tracks", str(tmp_path / f"t{i}.json"), "--camera", str(tmp_path / f"cam{i}.json")]
    assert main(args + ["--out", str(tmp_path / "r.npz"), "--quiet"]) == 0
    res = pr.load_result(tmp_path / "r.npz")
    assert res.camera_names == ["cam0", "cam1"]
    assert mpjpe_mm(fig, res.keypoints3d, q, names).mean() < 6.0


# ----------------------------------------------------------------------------- the pieces
def test_triangulation_through_distorted_cameras():
    cams = [c.camera for c in load_cameras(POSE2SIM_TOML)]
    rng = np.random.default_rng(0)
    X = np.array([-0.94, 0.0, 0.9]) + rng.uniform(-0.5, 0.5, (40, 3))
    uv = [c.project(X) for c in cams]
    uv[2][10:20] = np.nan  # seen by three cameras
    uv[1][:5] = uv[3][:5] = np.nan  # seen by two
    uv[0][5:8] = uv[1][5:8] = uv[3][5:8] = np.nan  # seen by one: not triangulated
    got = triangulate(cams, uv)
    ok = np.ones(40, bool)
    ok[5:8] = False
    np.testing.assert_allclose(got[ok], X[ok], atol=1e-6)
    assert np.isnan(got[~ok]).all()


def test_placement_through_a_distorted_lens(walk60):
    """place_on_tracks converts pixels through the lens model: near the edge of a wide
    lens with barrel distortion it lands the root on the truth (K alone: 11 cm off)."""
    fig, q, fps, names = walk60
    q = q[:30]
    centre = q[:, :3].mean(0)
    cam = pr.Perspective.look_at(centre + [-2.2, 0.0, 3.5], centre + [-2.2, 0.0, 0.0], f_px=450.0,
                                 center=(640.0, 360.0), dist=[-0.3, 0.05, 0.0, 0.0, 0.0])
    tr = project_tracks(fig, q, cam, names, fps=fps, noise_px=0.5)
    assert np.nanmax(np.abs(cam.normalized(tr.points)[..., 0])) > 0.55  # far from the centre
    problem = make_problem(fig, tr, cam)
    Q = q.copy()
    Q[:, 0] -= 0.4
    placed = place_on_tracks(fig, Q, cam, problem.measurement)
    assert np.linalg.norm(placed[:, :3] - q[:, :3], axis=1).mean() < 0.01


def test_planarity_seed_with_several_cameras(walk60):
    """The planarity seed reads the first camera; the solve uses all of them."""
    fig, q, fps, names = walk60
    q = q[:40]
    cams = ring_cameras(q, (45.0, -45.0))
    tracks = [project_tracks(fig, q, c, names, fps=fps, noise_px=1.0, seed=50 + i) for i, c in enumerate(cams)]
    res = pr.reconstruct(fig, tracks, cams, seed="planarity")
    assert mpjpe_mm(fig, res.keypoints3d, q, names).mean() < 6.0


def test_result_file_keeps_every_camera(tmp_path, walk60):
    fig, q, fps, names = walk60
    q = q[:20]
    cams = ring_cameras(q, (45.0, -45.0, 180.0))
    calib = load_cameras(POSE2SIM_TOML)[:1]
    per = np.arange(3 * 20, dtype=float).reshape(3, 20)
    res = pr.Result.from_motion(fig, q, fps)
    res.cameras, res.camera_names = cams, ["left", "right", "back"]
    res.camera = cams[0]
    res.reprojection_error_px_per_camera = per
    res.save(tmp_path / "r.npz")
    back = pr.load_result(tmp_path / "r.npz")
    assert back.camera_names == ["left", "right", "back"]
    for a, b in zip(back.cameras, cams):
        np.testing.assert_allclose(a.K, b.K)
        np.testing.assert_allclose(a.R, b.R)
        np.testing.assert_allclose(a.t, b.t)
    np.testing.assert_array_equal(back.reprojection_error_px_per_camera, per)
    np.testing.assert_allclose(back.camera.K, cams[0].K)
    # a one-camera result: cameras = [camera], named camera1; a calibration camera keeps its name
    one = pr.Result.from_motion(fig, q, fps, camera=cams[0])
    assert one.cameras == [cams[0]] and one.camera_names == ["camera1"]
    problem = make_problem(fig, project_tracks(fig, q, calib[0].camera, names, fps=fps), calib[0])
    assert problem.camera_names == [calib[0].name]
    meta = json.loads(str(np.load(tmp_path / "r.npz")["camera_names"]))
    assert meta == ["left", "right", "back"]


def test_reprojection_pictures_per_camera(tmp_path, walk60):
    pytest.importorskip("matplotlib")
    from pinrecon.viz import plot_reprojection, plot_reprojection_error, plot_result

    fig, q, fps, names = walk60
    q = q[:20]
    cams = ring_cameras(q, (45.0, -45.0))
    tracks = [project_tracks(fig, q, c, names, fps=fps, noise_px=1.0, seed=i) for i, c in enumerate(cams)]
    res = pr.reconstruct(fig, tracks, cams, options=pr.SolverOptions(max_iterations=3))
    picture = plot_reprojection(res, tracks[1], [0, 10], camera="camera2")
    idx = fig.keypoint_index(names)
    for ax, f in zip(picture.axes, [0, 10]):
        drawn = {a.get_gid(): a for a in ax.get_lines()}
        tr = drawn["tracks"]
        np.testing.assert_allclose(np.c_[tr.get_xdata(), tr.get_ydata()], tracks[1].points[f])
        rp = drawn["reprojection"]
        np.testing.assert_allclose(np.c_[rp.get_xdata(), rp.get_ydata()][idx],
                                   cams[1].project(res.keypoints3d[f, idx]), atol=1e-9)
        assert ax.get_title().startswith("camera2: ")
    with pytest.raises(pr.UnknownNameError, match="camera3"):
        plot_reprojection(res, tracks[1], camera="camera3")
    err_fig = plot_reprojection_error(res)
    lines = {a.get_gid(): a for a in err_fig.axes[0].get_lines()}
    for c, name in enumerate(res.camera_names):
        ok = np.isfinite(res.reprojection_error_px_per_camera[c])
        np.testing.assert_allclose(lines[f"reprojection_error:{name}"].get_ydata(),
                                   res.reprojection_error_px_per_camera[c][ok])
    files = plot_result(res, tmp_path / "pics", tracks=tracks, animation=False)
    got = sorted(p.name for p in files)
    assert "reprojection_camera1.png" in got and "reprojection_camera2.png" in got
    with pytest.raises(InputError, match="1 tracks for a result with 2 cameras"):
        plot_result(res, tmp_path / "pics2", tracks=tracks[:1], animation=False)
