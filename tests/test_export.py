"""BVH export of URDF figures (round trips through load_bvh), BVH write-back of BVH
figures, CSV export and the export_result helper."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path
from scipy.spatial.transform import Rotation

import pinrecon
from pinrecon import Result
from pinrecon.errors import InputError
from pinrecon.io.bvh import euler_to_matrix, load_bvh, read_bvh, write_bvh
from pinrecon.io.bvh_export import continuous_euler, export_result, urdf_figure_to_bvh
from pinrecon.io.csv_export import motion_table, write_csv

ROOT = Path(__file__).resolve().parents[1]
WALK = data_path("mocap/cmu-mb_02_01.bvh")
MIXED = data_path("project-test-data/cmu-max_131_03.bvh")
CMU = 0.056444
TOL_M = 1e-6


def human_motion(fig, T=40, fps=30.0, seed=0, yaw_turns=0.0):
    """Upright figure walking along +x, turning ``yaw_turns`` times about +Y, with every
    joint swinging inside its limits."""
    rng = np.random.default_rng(seed)
    m = fig.model
    t = np.arange(T) / fps
    Q = np.tile(fig.neutral(), (T, 1))
    if fig.floating:
        Q[:, 0] = 0.8 * t + 0.1234567
        Q[:, 1] = 0.95
        Q[:, 2] = 0.05 * np.sin(t)
        yaw = 0.3 * np.sin(np.pi * t) + 2 * np.pi * yaw_turns * t / t[-1]
        Q[:, 3:7] = Rotation.from_rotvec(yaw[:, None] * [0, 1, 0]).as_quat()
    first = 2 if fig.floating else 1
    for j in range(first, m.njoints):
        iv, iq = m.idx_vs[j], m.idx_qs[j]
        lo, hi = fig.lower_v[iv], fig.upper_v[iv]
        mid = np.clip(0.0, lo, hi)
        amp = 0.3 * min(hi - lo, 2.0) * rng.uniform(0.3, 1.0)
        Q[:, iq] = mid + amp * np.sin(2 * np.pi * rng.uniform(0.3, 1.2) * t + rng.uniform(0, 6))
    return fig.clamp(Q, 1e-3)


def result_of(fig, Q, fps=30.0, camera=None):
    T = Q.shape[0]
    return Result(
        figure=fig,
        q=Q,
        times=np.arange(T) / fps,
        fps=fps,
        keypoints3d=fig.keypoints(Q),
        reprojection_error_px=np.zeros(T),
        solve=None,
        observed_frames=np.ones(T, bool),
        camera=camera,
    )


def assert_round_trip(fig, Q, path, length_scale=1.0):
    """Read ``path`` back with load_bvh: every keypoint of ``fig`` is there, same name,
    same position on every frame."""
    back = load_bvh(path, length_scale)
    assert back.q.shape[0] == Q.shape[0]
    idx = back.figure.keypoint_index(fig.keypoint_names)
    err = np.abs(back.figure.keypoints(back.q)[:, idx] - fig.keypoints(Q)).max()
    assert err < TOL_M, err
    return back


def bvh_positions(joints, values, unit):
    """World positions (F, J, 3) in metres of BVH joints given in memory (OFFSETs in
    metres, values in file units and degrees): plain BVH forward kinematics."""
    F = values.shape[0]
    p = np.zeros((F, len(joints), 3))
    R = np.zeros((F, len(joints), 3, 3))
    col = 0
    for i, j in enumerate(joints):
        block = values[:, col : col + len(j.channels)]
        col += len(j.channels)
        pos = np.zeros((F, 3))
        rot = [k for k, c in enumerate(j.channels) if c.endswith("rotation")]
        for k, c in enumerate(j.channels):
            if c.endswith("position"):
                pos[:, "XYZ".index(c[0])] = block[:, k] * unit
        order = "".join(j.channels[k][0] for k in rot)
        R_loc = (
            euler_to_matrix(order, block[:, rot]) if rot else np.broadcast_to(np.eye(3), (F, 3, 3))
        )
        if j.parent < 0:
            p[:, i], R[:, i] = j.offset + pos, R_loc
        else:
            p[:, i] = p[:, j.parent] + np.einsum("fab,fb->fa", R[:, j.parent], j.offset + pos)
            R[:, i] = R[:, j.parent] @ R_loc
    return p


def assert_exact_skeleton(fig, Q, length_scale=1.0, tol=1e-9):
    """urdf_figure_to_bvh reproduces every keypoint exactly (before any file rounding)."""
    joints, values, unit = urdf_figure_to_bvh(fig, Q, length_scale)
    names = [j.name for j in joints]
    P = bvh_positions(joints, values, unit)
    idx = [names.index(n) for n in fig.keypoint_names]
    err = np.abs(P[:, idx] - fig.keypoints(Q)).max()
    assert err < tol, err
    return joints, values


@pytest.fixture(scope="module")
def walk_motion():
    return load_bvh(WALK, CMU, skip_frames=1)


# ---------------------------------------------------------------------------- URDF figures
@pytest.mark.parametrize("kp", ["coco17", "joints"])
def test_human_round_trip(tmp_path, kp):
    fig = pinrecon.Figure.human(kp)
    Q = human_motion(fig)
    path = tmp_path / "sub" / f"human_{kp}.bvh"
    path.parent.mkdir()
    assert_exact_skeleton(fig, Q)
    write_bvh(path, fig, Q, 30.0)
    back = assert_round_trip(fig, Q, path)
    assert back.fps == pytest.approx(30.0, rel=1e-6)
    clip = read_bvh(path)
    # one BVH joint per anatomical joint: the hip chain Z, X, Y is one joint named after its keypoint
    hip = clip.joints[clip.joint_index("left_hip")]
    assert hip.channels == ("Zrotation", "Xrotation", "Yrotation")
    np.testing.assert_allclose(hip.offset, [0.023, -0.1, -0.082], atol=1e-12)
    assert clip.joints[0].channels == (
        "Xposition",
        "Yposition",
        "Zposition",
        "Zrotation",
        "Yrotation",
        "Xrotation",
    )
    assert (
        len([j for j in clip.joints if j.rotation_channels]) == 1 + 17
    )  # root + anatomical joints
    # every leaf has an End Site
    parents = {j.parent for j in clip.joints}
    for i, j in enumerate(clip.joints):
        if i not in parents:
            assert j.end_sites, j.name
    # no temporary files are left behind
    assert [p.name for p in path.parent.iterdir()] == [path.name]


def test_human_coco17_hierarchy_names(tmp_path):
    fig = pinrecon.Figure.human("coco17")
    joints, values, unit = urdf_figure_to_bvh(fig, fig.neutral())
    names = [j.name for j in joints]
    assert unit == 1.0 and values.shape == (1, sum(len(j.channels) for j in joints))
    assert names[0] == "middle_pelvis"
    for kp in fig.keypoint_names:  # every keypoint is a BVH joint of the same name
        assert kp in names
    face = [j for j in joints if j.name == "nose"][0]
    assert face.channels == () and joints[face.parent].name == "middle_head"
    np.testing.assert_allclose(face.offset, [0.095, 0.12, 0.0])
    assert len(set(names)) == len(names)
    # file order is depth-first: every parent comes before its children
    assert all(j.parent < i for i, j in enumerate(joints))


def test_channels_are_joint_angles_and_root_pose():
    fig = pinrecon.Figure.human("coco17")
    Q = human_motion(fig, T=25, seed=3)
    joints, values, _ = urdf_figure_to_bvh(fig, Q)
    starts = np.cumsum([0] + [len(j.channels) for j in joints])
    col = {j.name: values[:, starts[i] : starts[i + 1]] for i, j in enumerate(joints)}

    def q_deg(name):
        return np.degrees(Q[:, fig.joint_slices(name)[0].start])

    # left hip axes are +Z, +X, -Y: the ZXY channels are the joint angles
    np.testing.assert_allclose(col["left_hip"][:, 0], q_deg("left_hip_Z"), atol=1e-9)
    np.testing.assert_allclose(col["left_hip"][:, 1], q_deg("left_hip_X"), atol=1e-9)
    np.testing.assert_allclose(col["left_hip"][:, 2], -q_deg("left_hip_Y"), atol=1e-9)
    np.testing.assert_allclose(col["left_knee"][:, 0], -q_deg("left_knee_Z"), atol=1e-9)
    np.testing.assert_allclose(col["left_knee"][:, 1:], 0.0, atol=1e-9)
    root = col["middle_pelvis"]
    np.testing.assert_allclose(root[:, :3], Q[:, :3], atol=1e-12)
    R = euler_to_matrix("ZYX", root[:, 3:])
    np.testing.assert_allclose(R, Rotation.from_quat(Q[:, 3:7]).as_matrix(), atol=1e-12)


def test_root_turning_is_continuous(tmp_path):
    fig = pinrecon.Figure.human("coco17")
    Q = human_motion(fig, T=60, seed=1, yaw_turns=1.5)
    joints, values, _ = urdf_figure_to_bvh(fig, Q)
    rot = values[:, 3:6]
    assert np.abs(np.diff(rot, axis=0)).max() < 30.0  # no +-360 jumps
    assert np.ptp(rot[:, 1]) > 360.0 or np.ptp(rot[:, 0]) > 360.0 or np.ptp(rot[:, 2]) > 360.0
    assert_exact_skeleton(fig, Q)
    write_bvh(tmp_path / "turn.bvh", fig, Q, 30.0)
    assert_round_trip(fig, Q, tmp_path / "turn.bvh")


def test_continuous_euler_keeps_rotations():
    rng = np.random.default_rng(0)
    w = rng.normal(size=3)
    tumble = Rotation.from_rotvec(np.linspace(0, 12, 400)[:, None] * w / np.linalg.norm(w))
    wobble = Rotation.from_rotvec(0.8 * np.sin(np.linspace(0, 9, 400))[:, None] * [0, 1, 0])
    turn = Rotation.from_rotvec(
        np.linspace(0, 20, 400)[:, None] * [0, 0, 1]
    ) * Rotation.from_rotvec(0.5 * np.sin(np.linspace(0, 7, 400))[:, None] * [1, 0, 0])
    for R in (tumble * wobble, turn):
        for order in ("ZYX", "ZXY", "XZY"):
            e = R.as_euler(order, degrees=True)
            c = continuous_euler(e)
            np.testing.assert_allclose(euler_to_matrix(order, c), R.as_matrix(), atol=1e-9)
            step = np.abs(np.diff(c, axis=0)).sum(axis=1)
            assert np.all(step <= np.abs(np.diff(e, axis=0)).sum(axis=1) + 1e-9)  # never worse
            assert step.max() < 180.0  # no wrap-around jumps
    c = continuous_euler(turn.as_euler("ZYX", degrees=True))
    assert np.abs(np.diff(c, axis=0)).max() < 5.0  # far from gimbal lock: smooth
    assert c[-1, 0] == pytest.approx(np.degrees(20.0), abs=1e-6)  # three turns, unwrapped


def test_fixed_root_figure(tmp_path):
    fig = pinrecon.Figure.human("joints", root="fixed")
    Q = human_motion(fig, T=10)
    joints, values, _ = urdf_figure_to_bvh(fig, Q)
    assert joints[0].channels[:3] == ("Xposition", "Yposition", "Zposition")
    np.testing.assert_array_equal(values[:, :6], 0.0)  # the fixed base writes constant zeros
    assert_exact_skeleton(fig, Q)
    write_bvh(tmp_path / "fixed.bvh", fig, Q, 25.0)
    assert_round_trip(fig, Q, tmp_path / "fixed.bvh")


def test_length_unit_centimetres(tmp_path):
    fig = pinrecon.Figure.human("coco17")
    Q = human_motion(fig, T=8)
    joints, values, unit = urdf_figure_to_bvh(fig, Q, length_scale=0.01)
    assert unit == 0.01
    np.testing.assert_allclose(values[:, :3], Q[:, :3] / 0.01)
    np.testing.assert_allclose(joints[1].offset, [0.023, -0.1, -0.082])  # metres in BvhJoint
    with pytest.raises(InputError, match="positive"):
        urdf_figure_to_bvh(fig, Q, length_scale=0.0)


_SLIDER_URDF = """<?xml version="1.0"?>
<robot name="slider">
  <link name="base"/>
  <link name="carriage"/>
  <link name="arm"/>
  <link name="wheel"/>
  <joint name="slide" type="prismatic">
    <parent link="base"/><child link="carriage"/>
    <origin xyz="0.1 0.2 0" rpy="0 0 0.3"/><axis xyz="1 0 0"/>
    <limit lower="-0.5" upper="0.5" effort="1" velocity="1"/>
  </joint>
  <joint name="swing" type="revolute">
    <parent link="carriage"/><child link="arm"/>
    <origin xyz="0 0 0" rpy="0.2 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/>
  </joint>
  <joint name="spin" type="continuous">
    <parent link="arm"/><child link="wheel"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>
  </joint>
</robot>
"""


@pytest.fixture()
def slider():
    kps = [
        pinrecon.Keypoint("carriage_pt", "carriage"),
        pinrecon.Keypoint("arm_pt", "arm", (0.0, 0.1, 0.0)),
        pinrecon.Keypoint("rim", "wheel", (0.05, 0.0, 0.02)),
    ]
    fig = pinrecon.Figure.from_urdf_string(_SLIDER_URDF, kps, root="free")
    T = 30
    t = np.linspace(0, 2, T)
    Q = np.tile(fig.neutral(), (T, 1))
    Q[:, :3] = np.stack([t, 0.5 * t, 0 * t], 1)
    Q[:, 3:7] = Rotation.from_rotvec(np.stack([0.2 * t, t, 0 * t], 1)).as_quat()
    Q[:, fig.joint_slices("slide")[0].start] = 0.4 * np.sin(3 * t)
    Q[:, fig.joint_slices("swing")[0].start] = 1.5 * np.sin(2 * t)
    a = 5 * t  # continuous joint: (cos, sin), several turns
    sq = fig.joint_slices("spin")[0]
    Q[:, sq.start], Q[:, sq.start + 1] = np.cos(a), np.sin(a)
    return fig, Q, a


def test_prismatic_and_continuous_round_trip(tmp_path, slider):
    fig, Q, _ = slider
    joints, values, _ = urdf_figure_to_bvh(fig, Q)
    by_name = {j.name: j for j in joints}
    # slide + swing share an origin: one BVH joint, with position channels for the slide
    assert by_name["carriage_pt"].channels[:3] == ("Xposition", "Yposition", "Zposition")
    assert len(by_name["carriage_pt"].channels) == 6
    assert by_name["arm_pt"].channels == () and by_name["rim"].channels == ()
    assert_exact_skeleton(fig, Q)
    assert_exact_skeleton(fig, Q, length_scale=0.01)
    write_bvh(tmp_path / "slider.bvh", fig, Q, 20.0)
    assert_round_trip(fig, Q, tmp_path / "slider.bvh")


def test_keypoint_names_with_spaces_are_cleaned(tmp_path):
    fig = pinrecon.Figure.human("coco17")
    kps = [
        pinrecon.Keypoint("left eye", "middle_head", (0.08, 0.15, -0.032)),
        pinrecon.Keypoint("hip", "left_upperleg"),
    ]
    fig = fig.with_keypoints(kps)
    with pytest.warns(UserWarning, match="left_eye"):
        joints, _, _ = urdf_figure_to_bvh(fig, fig.neutral())
    assert "left_eye" in [j.name for j in joints]


# ---------------------------------------------------------------------------- BVH figures
def test_walk_writes_back_its_own_skeleton(tmp_path, walk_motion):
    Q = walk_motion.q[:80]
    path = tmp_path / "walk.bvh"
    write_bvh(path, walk_motion.figure, Q, walk_motion.fps)
    orig, back = read_bvh(WALK), read_bvh(path)
    assert back.names == orig.names
    assert [j.channels for j in back.joints] == [j.channels for j in orig.joints]
    for a, b in zip(orig.joints, back.joints):
        np.testing.assert_allclose(a.offset, b.offset, atol=1e-6)
    np.testing.assert_allclose(back.values, orig.values[1:81], atol=2e-6)
    assert_round_trip(walk_motion.figure, Q, path, CMU)


def test_mixed_rotation_orders_write_back(tmp_path):
    m = load_bvh(MIXED, CMU)
    Q = m.q[::10]
    path = tmp_path / "mixed.bvh"
    write_bvh(path, m.figure, Q, m.fps / 10)
    orig, back = read_bvh(MIXED), read_bvh(path)
    assert back.names == orig.names
    chans = [j.channels for j in back.joints]
    assert chans == [j.channels for j in orig.joints]
    assert ("Zrotation", "Xrotation", "Yrotation") in chans and (
        "Zrotation",
        "Yrotation",
        "Xrotation",
    ) in chans
    assert_round_trip(m.figure, Q, path, CMU)


def test_generic_export_of_a_bvh_figure_recovers_its_joints(tmp_path, walk_motion):
    """The URDF exporter merges each BVH joint's revolute chain back into one joint."""
    Q = walk_motion.q[:20]
    joints, values, _ = urdf_figure_to_bvh(walk_motion.figure, Q)
    names = [j.name for j in joints]
    orig = read_bvh(WALK)
    assert set(orig.names) <= set(names)  # same joints (Pinocchio may order siblings differently)
    for o in orig.joints[1:]:
        j = joints[names.index(o.name)]
        assert joints[j.parent].name == orig.names[o.parent]
        assert j.channels == ("Zrotation", "Yrotation", "Xrotation")
        np.testing.assert_allclose(j.offset, o.offset * CMU, atol=1e-12)
    assert_exact_skeleton(walk_motion.figure, Q)
    # through a file: write_bvh writes 6 decimals (1 um steps in metres) and CMU offsets
    # (1.65674 u = 0.09351... m) are not whole micrometres: good to a few um
    fig = pinrecon.Figure(walk_motion.figure.model, walk_motion.figure.keypoints_def, name="walk_urdf")
    path = tmp_path / "generic.bvh"
    write_bvh(path, fig, Q, walk_motion.fps)
    back = load_bvh(path)
    idx = back.figure.keypoint_index(fig.keypoint_names)
    assert np.abs(back.figure.keypoints(back.q)[:, idx] - fig.keypoints(Q)).max() < 5e-6


# ---------------------------------------------------------------------------- CSV
def read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array(rows[1:], float)


def test_csv_columns_and_values(tmp_path):
    fig = pinrecon.Figure.human("coco17")
    Q = human_motion(fig, T=21, yaw_turns=0.8)
    res = result_of(fig, Q)
    path = tmp_path / "out" / "motion.csv"
    cols = write_csv(path, res)
    header, data = read_csv(path)
    assert header == cols
    assert header[:7] == ["time", "root_x", "root_y", "root_z", "root_rz", "root_ry", "root_rx"]
    names, angles = res.joint_angles()
    assert header[7:] == names
    assert data.shape == (21, 7 + len(names))
    np.testing.assert_array_equal(data[:, 0], res.times)
    np.testing.assert_array_equal(data[:, 1:4], Q[:, :3])
    np.testing.assert_allclose(data[:, 7:], np.degrees(angles), rtol=0, atol=1e-12)
    R = euler_to_matrix("ZYX", data[:, 4:7])
    np.testing.assert_allclose(R, Rotation.from_quat(Q[:, 3:7]).as_matrix(), atol=1e-12)
    assert np.abs(np.diff(data[:, 4:7], axis=0)).max() < 90  # continuous root angles
    assert [p.name for p in path.parent.iterdir()] == ["motion.csv"]


def test_csv_figure_and_q_prismatic_continuous(tmp_path, slider):
    fig, Q, a = slider
    cols = write_csv(tmp_path / "s.csv", fig, Q, fps=20.0, precision=9)
    header, data = read_csv(tmp_path / "s.csv")
    assert (
        header
        == cols
        == [
            "time",
            "root_x",
            "root_y",
            "root_z",
            "root_rz",
            "root_ry",
            "root_rx",
            "slide_m",
            "swing",
            "spin",
        ]
    )
    np.testing.assert_allclose(data[:, 0], np.arange(len(Q)) / 20.0, atol=1e-9)
    np.testing.assert_allclose(data[:, 7], Q[:, fig.joint_slices("slide")[0].start], atol=1e-9)
    np.testing.assert_allclose(
        data[:, 8], np.degrees(Q[:, fig.joint_slices("swing")[0].start]), atol=1e-7
    )
    np.testing.assert_allclose(data[:, 9], np.degrees(a), atol=1e-7)  # unwrapped over turns
    with pytest.raises(InputError, match="fps"):
        write_csv(tmp_path / "x.csv", fig, Q)
    with pytest.raises(InputError, match="q"):
        write_csv(tmp_path / "x.csv", fig)


def test_motion_table_fixed_root():
    fig = pinrecon.Figure.human("coco17", root="fixed")
    Q = human_motion(fig, T=5)
    names, table = motion_table(fig, Q, np.arange(5) * 0.1)
    assert names[0] == "time" and names[1] == "left_hip_Z" and table.shape == (5, 1 + fig.nv)


# ---------------------------------------------------------------------------- export_result
def test_export_result_human(tmp_path):
    fig = pinrecon.Figure.human("coco17")
    Q = human_motion(fig, T=15)
    res = result_of(fig, Q, camera=pinrecon.Orthographic.from_view([0, 0, -1], scale=300))
    res.save(tmp_path / "r.npz")
    written = export_result(
        tmp_path / "r.npz", bvh=tmp_path / "o" / "r.bvh", csv=tmp_path / "o" / "r.csv", ground=False
    )
    assert written == [tmp_path / "o" / "r.bvh", tmp_path / "o" / "r.csv"]
    assert_round_trip(fig, Q, tmp_path / "o" / "r.bvh")
    header, data = read_csv(tmp_path / "o" / "r.csv")
    assert data.shape[0] == 15 and header[0] == "time"
    with pytest.raises(InputError, match="nothing to do"):
        export_result(tmp_path / "r.npz")


def test_export_result_bvh_figure(tmp_path, walk_motion):
    res = result_of(walk_motion.figure, walk_motion.q[:30], fps=walk_motion.fps)
    res.save(tmp_path / "w.npz")
    (out,) = export_result(tmp_path / "w.npz", bvh=tmp_path / "w.bvh", ground=False, units=None)
    assert read_bvh(out).names == read_bvh(WALK).names
    assert_round_trip(walk_motion.figure, walk_motion.q[:30], out, CMU)


def test_fk_of_written_file_matches_independent_reader(tmp_path):
    """The written human BVH, read by the plain reference reader of the tests."""
    from bvh_reference import reference_positions

    fig = pinrecon.Figure.human("joints")
    Q = human_motion(fig, T=6)
    write_bvh(tmp_path / "h.bvh", fig, Q, 30.0)
    names, _, pos, _, _ = reference_positions(tmp_path / "h.bvh")
    P = fig.keypoints(Q)
    for k, n in enumerate(fig.keypoint_names):
        np.testing.assert_allclose(pos[:, names.index(n)], P[:, k], atol=TOL_M)
