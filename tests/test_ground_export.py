"""Exports that land well (floor at height zero, root start over the origin, Y up, facing
+Z, metres or centimetres) and pictures that read right (truth under the reconstruction,
a legend, heights positive, the floor and contacts drawn, ``plot --fps``, no half set of
pictures after a failure)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import openpose_body25_folder
from scipy.spatial.transform import Rotation

import pinrecon as pr
from pinrecon.cli import main
from pinrecon.contact import Floor, FootContact, estimate_floor, foot_keypoints
from pinrecon.errors import InputError
from pinrecon.io.bvh import load_bvh, transform_motion, write_bvh
from pinrecon.io.bvh_export import export_result, facing_direction, ground_frame
from pinrecon.result import Result
from pinrecon.synthetic import bundled_motion, smooth_motion

CMU = 0.056444
TILT = Rotation.from_euler("xyz", [14.0, 35.0, -9.0], degrees=True).as_matrix()  # a camera's world
SHIFT = np.array([0.4, -1.1, 2.7])


def _facing(fig, P, up):
    return facing_direction(list(fig.keypoint_names), P, up)


@pytest.fixture(scope="module")
def tilted_walk():
    """The bundled walk (its own skeleton, 30 fps) moved into a tilted, shifted world."""
    fig, q, fps = bundled_motion("walk")
    q, fps = q[::4], fps / 4
    return fig, q, transform_motion(fig, q, TILT, SHIFT), fps


def test_bvh_from_a_reconstruction_stands_on_the_floor(tmp_path, tilted_walk):
    """Reconstruct the tilted walk with the floor, export it, read the BVH back: the feet
    stand on y = 0, the root starts over the origin, the figure faces +Z."""
    from pinrecon.synthetic import body_keypoints, point_keyframes, project_tracks

    fig, q_true, q_world, fps = tilted_walk
    names = body_keypoints(fig)
    cam = pr.Orthographic.from_view(TILT @ np.array([1.0, 0.0, -1.0]), tuple(TILT @ [0.0, 1.0, 0.0]), scale=300.0)
    tracks = project_tracks(fig, q_world, cam, names, fps=fps, noise_px=1.0, seed=1)
    keys = point_keyframes(fig, q_world, range(0, len(q_world), 8), names, sigma_m=0.02, seed=2)
    res = pr.reconstruct(fig, tracks, cam, keys, floor="auto", contact="auto")
    res.save(tmp_path / "r.npz")
    out = tmp_path / "walk.bvh"
    assert export_result(tmp_path / "r.npz", bvh=out, units="cm") == [out]
    assert "CHANNELS" in out.read_text()
    back = load_bvh(out, 0.01)
    P = back.figure.keypoints(back.q)
    feet = FootContact.from_extras(res.extras)
    fidx = back.figure.keypoint_index(feet.names)
    h = P[:, fidx, 1]
    # planted foot points sit at their contact heights above y = 0 (to 1 cm), the lowest at 0
    for k in range(len(feet.names)):
        c = feet.contact[:, k]
        if c.any():
            assert abs(np.median(h[c, k]) - feet.contact_height_m[k]) < 0.01
    assert abs(min(np.median(h[feet.contact[:, k], k]) for k in range(len(fidx)) if feet.contact[:, k].any())) < 0.01
    assert h.min() > -0.02
    # the floor is level: the truth's own floor (estimated under its feet) has height 0 everywhere
    Pt = fig.keypoints(q_true)
    tf = estimate_floor(Pt[:, fig.keypoint_index(foot_keypoints(fig))], p_upper=q_true[:, :3], fps=fps)
    assert np.degrees(np.arccos(abs(tf.n[1]))) < 2.0  # the clip's floor is Y up in its own world
    planted = P[:, fidx][feet.contact]
    assert np.ptp(planted[:, 1]) < 0.15  # no 0.3 m+ height change along 3 m of floor (a 14 degree tilt would give 70 cm)
    # the root starts over the origin, the figure faces +Z
    np.testing.assert_allclose(back.q[0, [0, 2]], 0.0, atol=1e-6)
    f = _facing(back.figure, P[0], [0.0, 1.0, 0.0])
    assert f @ np.array([0.0, 0.0, 1.0]) > 0.999


def test_ground_frame_puts_a_given_floor_at_zero(tmp_path):
    """A URDF figure whose result carries a tilted floor: every exported point's height is
    its height above that floor, exactly."""
    fig = pr.Figure.human()
    q = smooth_motion(fig, 12, 30.0, seed=4)
    q = transform_motion(fig, q, TILT, SHIFT)
    n = TILT @ np.array([0.0, 1.0, 0.0])
    floor = Floor(tuple(n), float(n @ SHIFT) - 1.05)
    res = Result.from_motion(fig, q, 30.0)
    T, F = len(q), 2
    res.extras.update(FootContact(floor, ["left_ankle", "right_ankle"], np.zeros((T, F), bool), np.zeros(F),
                                  np.zeros(F)).to_extras())
    res.save(tmp_path / "h.npz")
    for units, scale in (("m", 1.0), ("cm", 0.01)):
        out = tmp_path / f"h_{units}.bvh"
        export_result(tmp_path / "h.npz", bvh=out, units=units)
        back = load_bvh(out, scale)
        P = back.figure.keypoints(back.q)[:, back.figure.keypoint_index(fig.keypoint_names)]
        np.testing.assert_allclose(P[..., 1], floor.height(fig.keypoints(q)), atol=1e-6)
        np.testing.assert_allclose(back.q[0, [0, 2]], 0.0, atol=1e-6)
        # rigid: distances between points are kept
        D0 = np.linalg.norm(fig.keypoints(q)[:, :, None] - fig.keypoints(q)[:, None], axis=-1)
        np.testing.assert_allclose(np.linalg.norm(P[:, :, None] - P[:, None], axis=-1), D0, atol=1e-6)
        assert _facing(fig, P[0], [0, 1, 0]) @ [0, 0, 1] > 0.999
    # Z up: the heights go to z, the figure faces -Y
    R, t = ground_frame(pr.load_result(tmp_path / "h.npz"), up="z")
    Pz = fig.keypoints(q) @ R.T + t
    np.testing.assert_allclose(Pz[..., 2], floor.height(fig.keypoints(q)), atol=1e-9)
    assert _facing(fig, Pz[0], [0, 0, 1]) @ [0, -1, 0] > 0.999


def test_export_options_and_errors(tmp_path, tilted_walk):
    fig, q_true, q_world, fps = tilted_walk
    res = Result.from_motion(fig, q_world[:20], fps)
    res.save(tmp_path / "w.npz")
    # a CMU figure in its own unit, as reconstructed: the file reads back in the tilted world
    export_result(tmp_path / "w.npz", bvh=tmp_path / "own.bvh", units=None, ground=False)
    back = load_bvh(tmp_path / "own.bvh", CMU)
    np.testing.assert_allclose(back.figure.keypoints(back.q), fig.keypoints(q_world[:20]), atol=1e-6)
    # grounded without a floor in the result: estimated under the feet, the clip lands level
    export_result(tmp_path / "w.npz", bvh=tmp_path / "g.bvh", csv=tmp_path / "g.csv")
    back = load_bvh(tmp_path / "g.bvh", 1.0)
    P = back.figure.keypoints(back.q)
    toes = back.figure.keypoint_index(["LeftToeBase_end", "RightToeBase_end"])
    assert abs(np.percentile(P[:, toes, 1], 5)) < 0.02
    header = (tmp_path / "g.csv").read_text().splitlines()
    cols = header[0].split(",")
    row0 = [float(x) for x in header[1].split(",")]
    assert row0[cols.index("root_x")] == pytest.approx(0.0, abs=1e-9)
    assert row0[cols.index("root_z")] == pytest.approx(0.0, abs=1e-9)
    assert row0[cols.index("root_y")] == pytest.approx(back.q[0, 1], abs=1e-6)
    for kw, match in (({"units": "ft"}, "unit"), ({"up": "w"}, "axis"), ({"up": "-y"}, "up"),
                      ({"facing": "y"}, "horizontal")):
        with pytest.raises(InputError, match=match):
            export_result(tmp_path / "w.npz", bvh=tmp_path / "x.bvh", **kw)
    with pytest.raises(InputError, match="world"):
        write_bvh(tmp_path / "x.bvh", fig, q_world[:3], fps, world=(np.ones((3, 3)), np.zeros(3)))


def test_export_cli_options(tmp_path, tilted_walk, capsys):
    fig, _, q_world, fps = tilted_walk
    Result.from_motion(fig, q_world[:10], fps).save(tmp_path / "w.npz")
    assert main(["export", str(tmp_path / "w.npz"), "--bvh", str(tmp_path / "a.bvh"), "--units", "cm",
                 "--up", "y", "--facing=-x"]) == 0
    back = load_bvh(tmp_path / "a.bvh", 0.01)
    assert _facing(back.figure, back.figure.keypoints(back.q[0]), [0, 1, 0]) @ [-1, 0, 0] > 0.999
    assert main(["export", str(tmp_path / "w.npz"), "--bvh", str(tmp_path / "b.bvh"), "--as-reconstructed",
                 "--units", "own"]) == 0
    back = load_bvh(tmp_path / "b.bvh", CMU)
    np.testing.assert_allclose(back.q[:, :3], q_world[:10, :3], atol=1e-6)


# ----------------------------------------------------------------------------- pictures
@pytest.fixture(scope="module")
def floor_result():
    """The walk (30 fps, 40 frames) with a floor and contacts from its own feet."""
    from pinrecon.contact import contact_heights, detect_contacts

    fig, q, fps = bundled_motion("walk")
    q, fps = q[::4][:40], fps / 4
    res = Result.from_motion(fig, q, fps, camera=pr.Orthographic.from_view([1.0, 0.0, -1.0], scale=300.0))
    names = foot_keypoints(fig)
    feet = res.keypoints3d[:, fig.keypoint_index(names)]
    fl = estimate_floor(feet, p_upper=q[:, :3], fps=fps)
    C = detect_contacts(feet, fl, fps)
    h, c = contact_heights(feet, fl, C)
    res.extras.update(FootContact(fl, names, C, h, c).to_extras())
    return res


def test_stick_strip_draws_floor_contacts_legend_and_heights(floor_result):
    from pinrecon.viz import plot_stick_strip

    frames = [0, 20, 39]
    fig = plot_stick_strip(floor_result, frames, truth=floor_result)
    axes = np.array(fig.axes).reshape(2, 3)
    feet = FootContact.from_extras(floor_result.extras)
    fidx = floor_result.figure.keypoint_index(feet.names)
    cam = floor_result.camera
    for k, f in enumerate(frames):
        ax = axes[0, k]
        floor_line = [a for a in ax.get_children() if a.get_gid() == "floor"]
        assert len(floor_line) == 1
        seg = np.c_[floor_line[0].get_xdata(), floor_line[0].get_ydata()]
        # the floor line's two ends are points of the floor plane
        A = np.vstack([cam.R[:2] * cam.scale, feet.floor.n])
        for uv in seg:
            X = np.linalg.solve(A, np.r_[uv - cam.center, feet.floor.offset_m])
            assert abs(feet.floor.height(X)) < 1e-9
        con = [a for a in ax.get_children() if a.get_gid() == "contacts"][0]
        np.testing.assert_allclose(np.c_[con.get_xdata(), con.get_ydata()],
                                   cam.project(floor_result.keypoints3d[f, fidx[feet.contact[f]]]).reshape(-1, 2))
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert {"left", "right", "ground truth", "floor", "foot in contact"} <= set(labels)
    # the second row reads heights above the floor, positive up (the data stay y-down)
    ax = axes[1, 0]
    fig.canvas.draw()
    ticks = [t for t in ax.get_yticklabels() if t.get_text()]
    vals = np.array([float(t.get_text().replace("\u2212", "-")) for t in ticks])
    pos = np.array([t.get_position()[1] for t in ticks])
    np.testing.assert_allclose(vals, -pos - feet.floor.offset_m * np.sign(feet.floor.n[1]), atol=1e-9)
    assert len(vals) >= 3 and np.allclose(vals * 10, np.round(vals * 10))  # round heights
    assert "height above the floor" in ax.get_ylabel()
    top = ax.get_ylim()[1]  # inverted axis: the top of the picture is the smallest v
    assert -top - feet.floor.offset_m > 1.0  # the head is over a metre above the floor


def test_gif_draws_the_reconstruction_over_the_truth(tmp_path, floor_result):
    from PIL import Image

    from pinrecon.viz import animate
    from pinrecon.viz._common import SIDE_COLORS

    out = animate(floor_result, tmp_path / "a.gif", truth=floor_result, max_frames=3)
    im = Image.open(out)
    im.seek(1)
    rgb = np.asarray(im.convert("RGB")).reshape(-1, 3).astype(int)
    blue = np.array([int(SIDE_COLORS["L"][i : i + 2], 16) for i in (1, 3, 5)])
    # truth and reconstruction coincide: drawn on top, the thin coloured bones show
    assert (np.abs(rgb - blue).sum(axis=1) < 40).sum() > 30


def test_plot_reads_an_openpose_folder_with_fps_and_leaves_nothing_when_it_fails(tmp_path):
    fig = pr.Figure.human()
    q = smooth_motion(fig, 3, 30.0, seed=2)
    cam = pr.Orthographic.from_view([0.0, 0.0, -1.0], scale=300.0, center=(500.0, 500.0))
    Result.from_motion(fig, q, 30.0, camera=cam).save(tmp_path / "r.npz")
    folder = str(openpose_body25_folder())
    out = tmp_path / "pics"
    # without --fps: one clear error, no picture written
    assert main(["plot", str(tmp_path / "r.npz"), "--out", str(out), "--tracks", folder, "--no-animation"]) == 2
    assert not out.exists() or not any(out.iterdir())
    assert main(["plot", str(tmp_path / "r.npz"), "--out", str(out), "--tracks", folder, "--fps", "30",
                 "--no-animation"]) == 0
    assert (out / "reprojection.png").exists() and (out / "stick_strip.png").exists()
    # a failure after some pictures were drawn removes them again
    from pinrecon.viz import plot_result

    out2 = tmp_path / "pics2"
    bad = pr.Tracks(np.zeros((3, 1, 2)), ["not_a_keypoint"], 30.0)
    with pytest.raises(InputError):
        plot_result(tmp_path / "r.npz", out2, tracks=bad, animation=False)
    assert not any(out2.iterdir())
