"""Plots and animations: files are valid pictures and the data drawn is the data given."""

from __future__ import annotations

import gc
import subprocess
import sys
import weakref
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path
from scipy.spatial.transform import Rotation

pytest.importorskip("matplotlib")

import matplotlib.image as mpimg  # noqa: E402
from PIL import Image  # noqa: E402

import pinrecon  # noqa: E402
from pinrecon import Orthographic, Result, Tracks  # noqa: E402
from pinrecon.errors import InputError, UnknownNameError  # noqa: E402
from pinrecon.io.bvh import load_bvh  # noqa: E402
from pinrecon.viz import (  # noqa: E402
    MissingDependencyError,
    animate,
    plot_joint_angles,
    plot_reprojection,
    plot_result,
    plot_stick_strip,
    skeleton,
)

ROOT = Path(__file__).resolve().parents[1]
WALK = data_path("mocap/cmu-mb_02_01.bvh")
CMU = 0.056444
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def result_of(fig, Q, fps, camera):
    T = Q.shape[0]
    return Result(
        figure=fig,
        q=Q,
        times=np.arange(T) / fps,
        fps=fps,
        keypoints3d=fig.keypoints(Q),
        reprojection_error_px=np.full(T, 0.5),
        solve=None,
        observed_frames=np.ones(T, bool),
        camera=camera,
    )


@pytest.fixture(scope="module")
def walk_motion():
    return load_bvh(WALK, CMU, skip_frames=1)


@pytest.fixture(scope="module")
def walk_result(walk_motion):
    cam = Orthographic.from_view([1, 0, 1], scale=300, center=(500, 500))
    return result_of(walk_motion.figure, walk_motion.q, walk_motion.fps, cam)


@pytest.fixture(scope="module")
def human_result():
    fig = pinrecon.Figure.human("coco17")
    rng = np.random.default_rng(0)
    T, fps = 30, 30.0
    t = np.arange(T) / fps
    Q = np.tile(fig.neutral(), (T, 1))
    Q[:, 0], Q[:, 1] = 0.8 * t, 0.95
    Q[:, 3:7] = Rotation.from_rotvec(0.3 * np.sin(t)[:, None] * [0, 1, 0]).as_quat()
    m = fig.model
    for j in range(2, m.njoints):
        iv, iq = m.idx_vs[j], m.idx_qs[j]
        lo, hi = fig.lower_v[iv], fig.upper_v[iv]
        Q[:, iq] = np.clip(0.0, lo, hi) + 0.3 * min(hi - lo, 2.0) * np.sin(
            2 * np.pi * rng.uniform(0.3, 1.2) * t + rng.uniform(0, 6)
        )
    Q = fig.clamp(Q, 1e-3)
    cam = Orthographic.from_view([0, 0, -1], scale=300, center=(640, 360))
    return result_of(fig, Q, fps, cam)


def assert_png(path):
    path = Path(path)
    assert path.is_file() and path.stat().st_size > 0
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[0] > 50 and img.shape[1] > 50


def assert_gif(path, min_frames=2):
    path = Path(path)
    assert path.is_file() and path.stat().st_size > 0
    with Image.open(path) as im:
        assert im.format == "GIF"
        assert im.n_frames >= min_frames
        return im.n_frames, im.size


def by_gid(ax, gid):
    found = [a for a in ax.get_children() if a.get_gid() == gid]
    assert found, f"no artist with gid {gid!r}"
    return found[0]


# ---------------------------------------------------------------------------- joint angles
def test_joint_angle_curves_are_the_angles_in_degrees(tmp_path, walk_result, walk_motion):
    joints = ["LeftLeg_Zrotation", "LeftUpLeg_Xrotation", "RightArm_Yrotation"]
    truth = result_of(walk_motion.figure, walk_motion.q + 0.01, walk_motion.fps, None)  # a second result
    out = tmp_path / "plots" / "angles.png"
    fig = plot_joint_angles(walk_result, joints, truth=truth, out=out)
    assert_png(out)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == len(joints)
    for ax, name in zip(axes, joints):
        col = walk_motion.figure.joint_slices(name)[0].start
        rec, tru = by_gid(ax, "reconstruction"), by_gid(ax, "truth")
        np.testing.assert_allclose(rec.get_xdata(), walk_result.times)
        np.testing.assert_allclose(rec.get_ydata(), np.degrees(walk_motion.q[:, col]), atol=1e-12)
        np.testing.assert_allclose(tru.get_ydata(), np.degrees(walk_motion.q[:, col] + 0.01), atol=1e-12)
        assert rec.get_linestyle() == "-" and tru.get_linestyle() == "--"
        assert ax.get_title() == name
        assert "deg" in ax.get_ylabel()
    assert axes[-1].get_xlabel() == "time (s)"
    assert axes[0].get_legend() is not None


def test_joint_angle_defaults_and_errors(human_result):
    fig = plot_joint_angles(human_result)  # the six joints that move most
    assert len([ax for ax in fig.axes if ax.get_visible()]) == 6
    with pytest.raises(UnknownNameError, match="left_knee_Z"):
        plot_joint_angles(human_result, ["no_such_joint"])
    # root channels are plottable too (CSV column names)
    fig = plot_joint_angles(human_result, ["root_y"])
    np.testing.assert_allclose(
        by_gid(fig.axes[0], "reconstruction").get_ydata(), human_result.q[:, 1]
    )
    assert "m" in fig.axes[0].get_ylabel()


# ---------------------------------------------------------------------------- stick strip
def test_stick_strip_camera_row_is_the_projection(tmp_path, walk_result, walk_motion):
    frames = [0, 100, 200]
    truth = result_of(walk_motion.figure, walk_motion.q, walk_motion.fps, None)
    out = tmp_path / "strip.png"
    fig = plot_stick_strip(walk_result, frames, truth=truth, out=out)
    assert_png(out)
    axes = np.array(fig.axes).reshape(2, len(frames))
    cam = walk_result.camera
    # default second view: the camera turned 90 degrees about the world up axis (+Y)
    G = Rotation.from_rotvec([0, np.pi / 2, 0]).as_matrix()
    side = Orthographic(cam.R @ G.T, 1.0)
    for k, f in enumerate(frames):
        P = walk_result.keypoints3d[f]
        line = by_gid(axes[0, k], "keypoints")
        np.testing.assert_allclose(
            np.c_[line.get_xdata(), line.get_ydata()], cam.project(P), atol=1e-9
        )
        line2 = by_gid(axes[1, k], "keypoints")
        np.testing.assert_allclose(
            np.c_[line2.get_xdata(), line2.get_ydata()], side.project(P), atol=1e-9
        )
        t_line = by_gid(axes[0, k], "truth_keypoints")
        np.testing.assert_allclose(
            np.c_[t_line.get_xdata(), t_line.get_ydata()], cam.project(P), atol=1e-9
        )
        bones = by_gid(axes[0, k], "bones")
        assert len(bones.get_segments()) == walk_motion.figure.K - 1  # a tree over the keypoints
        for ax in axes[:, k]:
            assert ax.get_aspect() == 1.0
            assert ax.yaxis_inverted()  # image y down
    # the camera's own up is +Y: turning the camera about it keeps heights
    np.testing.assert_allclose(side.R[1], cam.R[1], atol=1e-12)


def test_stick_strip_connects_coco17_through_the_torso(human_result):
    fig_ = human_result.figure
    sk = skeleton(fig_)
    assert sk.hub_joints  # pelvis, thorax and neck joint origins join the limbs
    # one connected tree over keypoints + hubs
    n = sk.K + len(sk.hub_joints)
    assert len(sk.edges) == n - 1
    adj = {i: set() for i in range(n)}
    for a, b in sk.edges:
        adj[a].add(b)
        adj[b].add(a)
    seen, stack = {0}, [0]
    while stack:
        for b in adj[stack.pop()] - seen:
            seen.add(b)
            stack.append(b)
    assert len(seen) == n
    fig = plot_stick_strip(human_result, [0, 10], second_view=45.0)
    line = by_gid(fig.axes[0], "keypoints")
    np.testing.assert_allclose(
        np.c_[line.get_xdata(), line.get_ydata()],
        human_result.camera.project(human_result.keypoints3d[0]),
        atol=1e-9,
    )


# ---------------------------------------------------------------------------- reprojection
def test_reprojection_plot(tmp_path, human_result):
    cam = human_result.camera
    rng = np.random.default_rng(1)
    uv = cam.project(human_result.keypoints3d) + rng.normal(0, 2.0, (30, 17, 2))
    uv[5, 3] = np.nan  # a missing point
    names = human_result.figure.keypoint_names
    tracks = Tracks(uv[:, ::-1], names[::-1], 30.0)  # another column order
    out = tmp_path / "rep.png"
    fig = plot_reprojection(human_result, tracks, [0, 5, 29], out=out)
    assert_png(out)
    for ax, f in zip(fig.axes, [0, 5, 29]):
        tr = by_gid(ax, "tracks")
        np.testing.assert_allclose(
            np.c_[tr.get_xdata(), tr.get_ydata()], tracks.points[f], equal_nan=True
        )
        rp = by_gid(ax, "reprojection")
        np.testing.assert_allclose(
            np.c_[rp.get_xdata(), rp.get_ydata()],
            cam.project(human_result.keypoints3d[f]),
            atol=1e-9,
        )
        assert ax.yaxis_inverted()
    assert len(by_gid(fig.axes[1], "residuals").get_segments()) == 16  # the missing point has none
    with pytest.raises(InputError, match="out of range"):
        plot_reprojection(human_result, tracks, [30])
    no_cam = result_of(human_result.figure, human_result.q, 30.0, None)
    with pytest.raises(InputError, match="camera"):
        plot_reprojection(no_cam, tracks, [0])


# ---------------------------------------------------------------------------- animation
def test_animation_gif(tmp_path, walk_result):
    out = tmp_path / "anim" / "walk.gif"
    path = animate(walk_result, out, frames=range(0, 60), max_frames=12)
    assert path == out
    n, size = assert_gif(out)
    assert n == 12 and size == (640, 336)
    assert [p.name for p in out.parent.iterdir()] == ["walk.gif"]  # no temporary file left


def test_animation_default_size_and_mp4_errors(tmp_path, walk_result, monkeypatch):
    out = tmp_path / "walk.gif"
    animate(walk_result, out)  # 343 frames -> subsampled to <= 150
    n, _ = assert_gif(out)
    assert 100 <= n <= 150
    assert out.stat().st_size < 2_500_000
    with pytest.raises(InputError, match="gif"):
        animate(walk_result, tmp_path / "walk.avi")
    import shutil

    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(MissingDependencyError, match="ffmpeg"):
        animate(walk_result, tmp_path / "walk.mp4")


# ---------------------------------------------------------------------------- plot_result
def test_plot_result_files(tmp_path, walk_motion):
    T = 48
    cam = Orthographic.from_view([1, 0, 1], scale=300, center=(500, 500))
    res = result_of(walk_motion.figure, walk_motion.q[:T] + 0.02, walk_motion.fps, cam)
    res.save(tmp_path / "r.npz")
    uv = cam.project(walk_motion.figure.keypoints(walk_motion.q[:T]))
    tracks = Tracks(uv, walk_motion.figure.keypoint_names, walk_motion.fps)
    out = tmp_path / "figs"
    files = plot_result(tmp_path / "r.npz", out, truth=WALK, tracks=tracks, truth_skip_frames=1)
    names = sorted(p.name for p in files)
    assert names == sorted(
        [
            "joint_angles.png",
            "stick_strip.png",
            "reprojection.png",
            "reprojection_error.png",
            "animation.gif",
        ]
    )
    for p in files:
        assert p.parent == out
        if p.suffix == ".png":
            assert_png(p)
    assert_gif(out / "animation.gif")
    assert sorted(p.name for p in out.iterdir()) == names


def test_plot_result_truth_in_joint_angles(tmp_path, walk_motion):
    """A BVH truth is read with the result figure's length scale and overlaid by name."""
    res = result_of(walk_motion.figure, walk_motion.q[:20], walk_motion.fps, None)
    files = plot_result(res, tmp_path, truth=WALK, animation=False, truth_skip_frames=1)
    assert sorted(p.name for p in files) == [
        "joint_angles.png",
        "reprojection_error.png",
        "stick_strip.png",
    ]
    # an explicit length scale for a truth BVH (needed when the result is not a BVH figure)
    files = plot_result(res, tmp_path / "b", truth=WALK, animation=False, truth_length_scale=CMU)
    assert len(files) == 3
    fig = plot_joint_angles(res, ["LeftLeg_Zrotation"], truth=load_bvh(WALK, CMU, skip_frames=1))
    tru = by_gid(fig.axes[0], "truth")
    col = walk_motion.figure.joint_slices("LeftLeg_Zrotation")[0].start
    np.testing.assert_allclose(tru.get_ydata(), np.degrees(walk_motion.q[:, col]), atol=1e-9)


# ---------------------------------------------------------------------------- hygiene
def test_figures_are_freed(human_result):
    refs = []
    for _ in range(3):
        fig = plot_stick_strip(human_result, [0, 5])
        refs.append(weakref.ref(fig))
        del fig
    gc.collect()
    assert all(r() is None for r in refs)
    if "matplotlib.pyplot" in sys.modules:
        assert sys.modules["matplotlib.pyplot"].get_fignums() == []


def test_missing_matplotlib_names_the_extra(monkeypatch):
    from pinrecon.viz import _common

    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    with pytest.raises(MissingDependencyError, match=r"pip install \"\.\[viz\]\""):
        _common.require_matplotlib()
    assert issubclass(MissingDependencyError, ImportError)
    assert issubclass(MissingDependencyError, pinrecon.PinreconError)


def test_import_does_not_need_matplotlib():
    code = (
        "import sys, pinrecon, pinrecon.viz, pinrecon.io.bvh_export, pinrecon.io.csv_export; "
        "assert 'matplotlib' not in sys.modules, 'matplotlib imported'"
    )
    env_path = str(ROOT / "src")
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env={"PYTHONPATH": env_path, "PATH": ""},
    )
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("animation", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_pictures_drawn_beside_are_the_pictures_drawn_here(tmp_path, walk_motion, monkeypatch, spy_beside,
                                                           animation):
    """With a second CPU, plot_result draws some pictures in a forked child (the stick strip
    and the error plot, or the animation) and writes their bytes here: the same files, byte
    for byte, as all drawn here; staged and published with the rest under Outputs.commit; and
    when a picture drawn here fails, nothing is left, the child's pictures included."""
    from pinrecon import processes
    from pinrecon.io.atomic import Outputs
    from pinrecon.viz import plots as plots_module

    T = 24
    cam = Orthographic.from_view([1, 0, 1], scale=300, center=(500, 500))
    res = result_of(walk_motion.figure, walk_motion.q[:T] + 0.02, walk_motion.fps, cam)
    tracks = Tracks(cam.project(walk_motion.figure.keypoints(walk_motion.q[:T])), walk_motion.figure.keypoint_names,
                    walk_motion.fps)
    forked = spy_beside(processes)
    monkeypatch.setattr(processes, "forkable", lambda frames=None: False)
    here = plot_result(res, tmp_path / "here", tracks=tracks, animation=animation)
    monkeypatch.setattr(processes, "forkable", lambda frames=None: True)
    outs = Outputs()
    outs.add_folder(tmp_path / "beside")
    with outs.commit():
        beside = plot_result(res, tmp_path / "beside", tracks=tracks, animation=animation)
    assert forked == [False, True]
    names = ["joint_angles.png", "stick_strip.png", "reprojection.png", "reprojection_error.png"] + \
        (["animation.gif"] if animation else [])
    assert [p.name for p in here] == [p.name for p in beside] == names  # the documented order
    assert sorted(p.name for p in (tmp_path / "beside").iterdir()) == sorted(names)  # no temporary file left
    for a, b in zip(here, beside):
        assert a.read_bytes() == b.read_bytes(), a.name

    def broken(*args, **kwargs):
        raise RuntimeError("the reprojection failed")

    monkeypatch.setattr(plots_module, "plot_reprojection", broken)
    with pytest.raises(RuntimeError, match="reprojection failed"):
        plot_result(res, tmp_path / "failed", tracks=tracks, animation=animation)
    assert list((tmp_path / "failed").iterdir()) == []
