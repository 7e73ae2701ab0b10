"""`pinrecon demo` and the other CLI commands, run as a user runs them."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import numpy as np
import pytest

import pinrecon as pr
from pinrecon.cli import main
from pinrecon.io.bvh import load_bvh
from pinrecon.io.results import load_result_npz

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    assert main(["demo", "--out", str(out), "--quiet"]) == 0
    return out


@pytest.mark.slow  # the demo: about a minute
def test_demo_writes_every_file(demo_dir):
    for name in (
        "tracks.json", "camera.json", "keyframes.json", "result.npz", "joint_angles.csv", "motion.bvh",
        "joint_angles.png", "stick_strip.png", "reprojection.png", "animation.gif",
    ):
        assert (demo_dir / name).is_file() and (demo_dir / name).stat().st_size > 100, name
    assert not list(demo_dir.glob("*.tmp*"))


@pytest.mark.slow  # the demo: about a minute
def test_demo_pictures_open(demo_dir):
    import matplotlib.image as mpimg
    from PIL import Image

    for name in ("joint_angles.png", "stick_strip.png", "reprojection.png"):
        assert (demo_dir / name).read_bytes()[:8] == PNG
        img = mpimg.imread(demo_dir / name)
        assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 400 and img.std() > 0.01
    with Image.open(demo_dir / "animation.gif") as gif:
        assert gif.n_frames > 20


@pytest.mark.slow  # the demo: about a minute
def test_demo_result_is_accurate_and_bvh_reads_back(demo_dir):
    res = pr.load_result(demo_dir / "result.npz")
    data = load_result_npz(demo_dir / "result.npz")
    assert res.q.shape == (343, res.figure.nq) and np.all(np.isfinite(res.q))
    assert data["keypoints3d"].shape == (343, res.figure.K, 3)
    # the written BVH is in metres (as every export), and read back with pinrecon's own reader
    # it reproduces the result's keypoints
    back = load_bvh(demo_dir / "motion.bvh", 1.0)
    names = res.figure.keypoint_names
    np.testing.assert_allclose(back.figure.keypoints(back.q)[:, back.figure.keypoint_index(names)], res.keypoints3d, atol=1e-6)
    assert back.fps == pytest.approx(res.fps, rel=1e-7)  # CMU: Frame Time .0083333, i.e. 120.00048 fps
    # and the error against the clip is what the demo promises
    from pinrecon.synthetic import body_keypoints, bundled_motion

    fig, q, fps = bundled_motion("walk")
    idx = fig.keypoint_index(body_keypoints(fig))
    err = np.linalg.norm(res.keypoints3d[:, idx] - fig.keypoints(q)[:, idx], axis=-1).mean()
    assert err < 0.02


@pytest.mark.slow  # the demo: about a minute
def test_demo_csv_columns_and_rows(demo_dir):
    res = pr.load_result(demo_dir / "result.npz")
    with open(demo_dir / "joint_angles.csv") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    names, values = res.joint_angles()
    assert header[:7] == ["time", "root_x", "root_y", "root_z", "root_rz", "root_ry", "root_rx"]
    assert header[7:] == names and len(body) == 343
    table = np.array(body, float)
    np.testing.assert_allclose(table[:, 0], res.times, atol=1e-9)
    np.testing.assert_allclose(table[:, 7:], np.degrees(values), atol=1e-6)


@pytest.mark.slow  # the demo: about a minute
def test_reconstruct_command_repeats_the_demo_from_its_files(demo_dir, tmp_path):
    from pinrecon._resources import bundled_clip

    out = tmp_path / "again.npz"
    code = main([
        "reconstruct", "--figure", str(bundled_clip("walk")), "--length-scale", "0.056444",
        "--lock", "LHipJoint", "RHipJoint", "LeftShoulder", "RightShoulder",
        "--tracks", str(demo_dir / "tracks.json"), "--camera", str(demo_dir / "camera.json"),
        "--keyframes", str(demo_dir / "keyframes.json"), "--out", str(out), "--quiet",
    ])
    assert code == 0
    first, again = pr.load_result(demo_dir / "result.npz"), pr.load_result(out)
    # the same inputs and the same figure give the same motion
    names = first.figure.distinct_keypoint_names
    a = first.keypoints3d[:, first.figure.keypoint_index(names)]
    b = again.keypoints3d[:, again.figure.keypoint_index(names)]
    assert np.linalg.norm(a - b, axis=-1).mean() < 0.005


@pytest.mark.slow  # the demo: about a minute
def test_export_and_plot_commands(demo_dir, tmp_path, capsys):
    assert main(["export", str(demo_dir / "result.npz"), "--bvh", str(tmp_path / "m.bvh"), "--csv", str(tmp_path / "m.csv")]) == 0
    assert (tmp_path / "m.bvh").is_file() and (tmp_path / "m.csv").is_file()
    assert main(["plot", str(demo_dir / "result.npz"), "--out", str(tmp_path / "p"), "--no-animation",
                 "--tracks", str(demo_dir / "tracks.json")]) == 0
    assert (tmp_path / "p" / "joint_angles.png").read_bytes()[:8] == PNG
    assert (tmp_path / "p" / "reprojection.png").is_file()


@pytest.mark.slow  # the demo: about a minute
def test_links_command_names_the_knees(demo_dir, capsys):
    assert main(["links", str(demo_dir / "tracks.json"), "--camera", str(demo_dir / "camera.json"),
                 "--names", "LeftUpLeg", "LeftLeg", "LeftFoot"]) == 0
    out = capsys.readouterr().out
    assert "LeftLeg" in out and "hinge" in out.lower()


def test_cli_errors_are_one_clear_line(tmp_path, capsys):
    bad = tmp_path / "cam.json"
    bad.write_text(json.dumps({"model": "orthographic", "R": [[1, 0, 0], [0, 1, 0], [0, 0, -1]], "scale": 300}))
    tracks = pr.Tracks(np.zeros((3, 1, 2)), ["nose"], 30.0)
    tracks.save(tmp_path / "t.json")
    code = main(["reconstruct", "--figure", "human", "--tracks", str(tmp_path / "t.json"), "--camera", str(bad),
                 "--out", str(tmp_path / "r.npz"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "cam.json" in err and "field 'R'" in err and "Traceback" not in err
    assert not (tmp_path / "r.npz").exists()


def test_console_script_help():
    out = subprocess.run([sys.executable, "-m", "pinrecon.cli", "--help"], capture_output=True, text=True)
    assert out.returncode == 0
    for cmd in ("reconstruct", "demo", "plot", "export", "links"):
        assert cmd in out.stdout


def test_pose_prior_flags_reach_the_weights_of_reconstruct_and_edit(monkeypatch):
    from pinrecon.cli import build_parser, pose_prior_weights
    from pinrecon.workbench import app

    p = build_parser()
    base = ["--figure", "human", "--tracks", "t.json", "--camera", "c.json"]
    r = ["reconstruct", "--out", "o", *base]
    assert pose_prior_weights(p.parse_args(r)) == {}
    got = pose_prior_weights(p.parse_args([*r, "--pose-prior", "3", "--pose-prior-loss", "cauchy"]))
    assert got == {"pose_prior": 3.0, "pose_prior_loss": "cauchy", "pose_prior_k": 3.0}
    assert pr.Weights(**got).pose_prior_loss == "cauchy"
    assert pose_prior_weights(p.parse_args([*r, "--pose-prior-loss", "huber"]))["pose_prior_k"] == 2.0
    with pytest.raises(SystemExit):
        p.parse_args([*r, "--pose-prior-loss", "tukey"])
    seen = {}
    monkeypatch.setattr(app, "edit_from_args", lambda args, figure=None, weights=None: seen.update(weights) or 0)
    assert main(["edit", *base, "--sigma-px", "3", "--pose-prior-loss", "cauchy"]) == 0
    assert seen == {"sigma_px": 3.0, "pose_prior_loss": "cauchy", "pose_prior_k": 3.0}
    # the feet stage: reconstruct's default unless --floor says otherwise, on edit too
    assert p.parse_args(["edit", *base]).floor is None and p.parse_args(r).floor is None
    assert p.parse_args(["edit", *base, "--floor", "none"]).floor == "none"


@pytest.mark.slow  # the demo: about a minute
def test_stability_flags_reach_the_check_and_the_result(demo_dir, tmp_path, monkeypatch):
    """``reconstruct --stability N --jobs J``: the check runs N copies in J processes, and what
    it measured is in the saved result. (The check itself: tests/test_stability.py.)"""
    from pinrecon.stability import Stability

    seen = {}

    def check(fig, tracks, cam, kf, *, result, runs, n_jobs, **kw):
        seen.update(runs=runs, n_jobs=n_jobs, seed=kw["seed"])
        T = len(result.times)
        return Stability(0.01, tuple(range(runs)), np.full((runs, T), 4.0), np.zeros((T, 1)), ["left_knee"], 30.0,
                         result.fps)

    from pinrecon._resources import bundled_clip

    monkeypatch.setattr(sys.modules["pinrecon.stability"], "stability", check)
    out = tmp_path / "r.npz"
    assert main(["reconstruct", "--figure", str(bundled_clip("walk")), "--length-scale", "0.056444",
                 "--tracks", str(demo_dir / "tracks.json"), "--camera", str(demo_dir / "camera.json"),
                 "--max-iterations", "2", "--seed", "rest", "--stability", "3", "--jobs", "2", "--out", str(out), "--quiet"]) == 0
    assert seen == {"runs": 3, "n_jobs": 2, "seed": "rest"}  # the copies are solved as the result was
    back = pr.load_result(out)
    assert back.extras["stability_spread_mm"].shape == (3, len(back.times))
    assert "stability: solved again on 3 copies" in back.summary()


@pytest.mark.slow  # the demo: about a minute
def test_demo_your_video_says_the_data_fix_none_of_its_lengths(demo_dir):
    """One camera, no keyframe: the table's "lengths the data fix" row reads the result's
    identifiability report, which flags all 9 fitted groups and the size (the one-view
    rule of pinrecon.identifiability)."""
    import pinrecon as pr
    from pinrecon.demo import DemoSummary, _lengths_fixed

    res = pr.load_result(demo_dir / "your_video" / "result.npz")
    fixed = _lengths_fixed(res.calibration)
    assert fixed == {"groups": 9, "fixed": 0, "size_fixed": False}
    summary = DemoSummary(1, 120.0, 1, "ftol", 0.1, 0.1, 1.0, 1.0, [], video=fixed)
    assert "lengths the data fix         0 of 9, size not fixed" in summary.table()
