"""BVH figures and motion against the independent reader ``tests/bvh_reference.py``.

Every joint position and end site of every frame must match to 1e-6 m, for the CMU
walk (ZYX everywhere) and for a clip with mixed ZYX/ZXY rotation orders.
"""

from __future__ import annotations

import numpy as np
import pytest
from bvh_reference import reference_positions
from conftest import CMU_UNIT_M, MIXED, WALK, data_path
from scipy.spatial.transform import Rotation

from pinrecon import Figure, InputError, UnknownNameError
from pinrecon.io.bvh import load_bvh, read_bvh, static_joints, write_bvh

WALK_BVH = data_path(WALK)
MIXED_BVH = data_path(MIXED)

TOL_M = 1e-6
CMU_STATIC = ["LHipJoint", "RHipJoint", "LeftShoulder", "RightShoulder"]


@pytest.fixture(scope="module")
def walk_reference():
    return reference_positions(WALK_BVH, CMU_UNIT_M)


@pytest.fixture(scope="module")
def mixed():
    return load_bvh(MIXED_BVH, CMU_UNIT_M)


def assert_matches_reference(motion, reference, frames=slice(None)):
    names, _, P, end_names, P_end = reference
    K = motion.keypoints()
    fig = motion.figure
    assert K.shape[0] == P[frames].shape[0]
    assert np.abs(K[:, fig.keypoint_index(names)] - P[frames]).max() < TOL_M
    assert np.abs(K[:, fig.keypoint_index(end_names)] - P_end[frames]).max() < TOL_M


# ---------------------------------------------------------------- positions
def test_walk_reproduces_every_joint_and_end_site(walk, walk_reference):
    assert walk.q.shape == (344, 97) and walk.fps == pytest.approx(120.0, rel=1e-4)
    assert_matches_reference(walk, walk_reference)


def test_mixed_rotation_orders_reproduce_every_joint_and_end_site(mixed):
    reference = reference_positions(MIXED_BVH, CMU_UNIT_M)
    assert mixed.q.shape == (1102, 97)
    assert_matches_reference(mixed, reference)


def test_mixed_clip_chains_follow_the_files_channel_order(mixed):
    names = mixed.figure.joint_names
    i = names.index("LeftElbow_Zrotation")
    assert names[i : i + 3] == ["LeftElbow_Zrotation", "LeftElbow_Xrotation", "LeftElbow_Yrotation"]
    i = names.index("LeftKnee_Zrotation")
    assert names[i : i + 3] == ["LeftKnee_Zrotation", "LeftKnee_Yrotation", "LeftKnee_Xrotation"]


def test_walk_figure_structure(walk):
    fig = walk.figure
    assert (fig.nq, fig.nv, fig.K) == (97, 96, 38)  # 30 joints x 3 rotations + free root
    assert fig.keypoint_names[:3] == ["Hips", "LHipJoint", "LeftUpLeg"]
    assert fig.keypoint_names[-7:] == [
        "LeftToeBase_end",
        "RightToeBase_end",
        "Head_end",
        "LeftHandIndex1_end",
        "LThumb_end",
        "RightHandIndex1_end",
        "RThumb_end",
    ]
    assert not fig.limited_v.any()  # BVH states no limits
    assert fig.meta["bvh"]["length_scale"] == CMU_UNIT_M


def test_walk_joint_values_are_channel_values_in_radians(walk):
    clip = walk.clip
    col = clip.channel_columns()[clip.joint_index("LeftLeg")]
    qs, _ = walk.figure.joint_slices("LeftLeg_Xrotation")
    np.testing.assert_allclose(
        walk.q[:, qs.start], np.radians(clip.values[:, col][:, 2]), atol=1e-15
    )
    np.testing.assert_allclose(walk.q[:, :3], clip.values[:, :3] * CMU_UNIT_M, atol=1e-15)


def test_walk_frame_zero_is_a_t_pose(walk_reference):
    names, _, P, _, _ = walk_reference
    i = names.index
    for f, hands_near_shoulders in ((0, True), (1, False)):
        drop = P[f, i("LeftArm"), 1] - P[f, [i("LeftHand"), i("RightHand")], 1]
        assert np.all(np.abs(drop) < 0.1) == hands_near_shoulders
    width = np.linalg.norm(P[0, i("LeftHand")] - P[0, i("RightHand")])
    assert width == pytest.approx(1.33, abs=0.02)  # arm span hand to hand, metres


def test_skip_frames(walk_reference):
    motion = load_bvh(WALK_BVH, CMU_UNIT_M, skip_frames=1)
    assert motion.q.shape == (343, 97)
    assert_matches_reference(motion, walk_reference, frames=slice(1, None))


def test_length_scale_scales_positions(walk):
    unit = load_bvh(WALK_BVH)  # file units
    np.testing.assert_allclose(unit.keypoints()[:5] * CMU_UNIT_M, walk.keypoints()[:5], atol=1e-12)


def test_from_bvh_figure_matches_load_bvh_figure(walk):
    fig = Figure.from_bvh(WALK_BVH, CMU_UNIT_M)
    assert fig.joint_names == walk.figure.joint_names
    np.testing.assert_allclose(fig.keypoints(walk.q[:3]), walk.keypoints()[:3], atol=1e-15)


# ---------------------------------------------------------------- non-root position channels
TWO_JOINT_BVH = """HIERARCHY
ROOT Base
{
  OFFSET 1.0 0.0 0.0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Slider
  {
    OFFSET 0.0 2.0 0.0
    CHANNELS 4 Yposition Xrotation Zrotation Yrotation
    End Site
    {
      OFFSET 0.0 0.0 3.0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.04
0 0 0 0 0 0 0 0 0 0
0.5 -1 2 30 -20 10 0.25 40 15 -60
"""


def test_non_root_position_channel_is_a_prismatic_joint_in_the_parent_frame(tmp_path):
    path = tmp_path / "slider.bvh"
    path.write_text(TWO_JOINT_BVH)
    motion = load_bvh(path, 2.0)
    assert "Slider_Yposition" in motion.figure.joint_names
    # hand computation: p_slider = p_base + R_base (offset + [0, y, 0]), end = p_slider + R_slider [0, 0, 3]
    R_base = Rotation.from_euler("ZXY", [30, -20, 10], degrees=True).as_matrix()
    p_base = 2.0 * (np.array([1.0, 0, 0]) + [0.5, -1, 2])
    p_slider = p_base + R_base @ (2.0 * np.array([0.0, 2.0 + 0.25, 0.0]))
    R_slider = R_base @ Rotation.from_euler("XZY", [40, 15, -60], degrees=True).as_matrix()
    p_end = p_slider + R_slider @ (2.0 * np.array([0.0, 0.0, 3.0]))
    K = motion.keypoints()
    idx = motion.figure.keypoint_index(["Base", "Slider", "Slider_end"])
    np.testing.assert_allclose(K[1, idx], [p_base, p_slider, p_end], atol=1e-12)
    np.testing.assert_allclose(K[0, idx], [[2, 0, 0], [2, 4, 0], [2, 4, 6]], atol=1e-12)


# ---------------------------------------------------------------- static joints and lock
def test_static_joints_on_walk(walk):
    assert static_joints(walk.clip) == CMU_STATIC


def test_lock_static_removes_twelve_dofs_and_keeps_positions(walk_reference):
    motion = load_bvh(WALK_BVH, CMU_UNIT_M, lock="static")
    assert motion.figure.meta["bvh"]["lock"] == CMU_STATIC
    assert motion.figure.nv == 96 - 12
    assert "LHipJoint_Zrotation" not in motion.figure.joint_names
    assert "LHipJoint" in motion.figure.keypoint_names  # the keypoint stays
    assert_matches_reference(motion, walk_reference)


def test_figure_from_bvh_accepts_lock_static():
    fig = Figure.from_bvh(WALK_BVH, CMU_UNIT_M, lock="static")
    assert fig.nv == 84 and fig.meta["bvh"]["lock"] == CMU_STATIC


def test_locking_a_moving_joint_names_joint_and_frame():
    with pytest.raises(InputError) as exc:
        load_bvh(WALK_BVH, CMU_UNIT_M, lock=["LeftShoulder", "LeftLeg"])
    err = exc.value
    assert (err.field, err.frame) == ("LeftLeg", 1)  # frame 0 (T-pose) has LeftLeg at zero
    assert err.file == str(WALK_BVH)
    assert (
        str(err)
        == f"{WALK_BVH}, field 'LeftLeg', frame 1: joint 'LeftLeg' is locked but its channels are non-zero"
    )


def test_lock_unknown_joint_lists_valid_names():
    with pytest.raises(UnknownNameError) as exc:
        load_bvh(WALK_BVH, CMU_UNIT_M, lock=["LeftKnee"])
    assert "unknown BVH joint name(s) 'LeftKnee'" in str(exc.value) and "LeftLeg" in str(exc.value)
    assert exc.value.field == "lock"


@pytest.mark.parametrize(
    "lock, message",
    [
        ("Hips", "lock must be a list of joint names or 'static'"),
        (["Hips"], "the root joint cannot be locked"),
    ],
)
def test_lock_bad_values(lock, message):
    with pytest.raises(InputError, match=message):
        load_bvh(WALK_BVH, CMU_UNIT_M, lock=lock)


# ---------------------------------------------------------------- writer
@pytest.mark.parametrize("lock", [(), "static"], ids=["free", "locked"])
def test_write_bvh_round_trip_walk(walk_reference, tmp_path, lock):
    motion = load_bvh(WALK_BVH, CMU_UNIT_M, lock=lock)
    out = tmp_path / "walk_out.bvh"
    write_bvh(out, motion.figure, motion.q, motion.fps)
    names, _, P, end_names, P_end = reference_positions(out, CMU_UNIT_M)
    assert names == walk_reference[0] and end_names == walk_reference[3]
    assert np.abs(P - walk_reference[2]).max() < TOL_M
    assert np.abs(P_end - walk_reference[4]).max() < TOL_M
    back = read_bvh(out)
    assert back.n_frames == 344 and back.frame_time == pytest.approx(1 / motion.fps, rel=1e-9)
    assert [j.channels for j in back.joints] == [j.channels for j in motion.clip.joints]


def test_write_bvh_round_trip_mixed_orders(mixed, tmp_path):
    out = tmp_path / "mixed_out.bvh"
    write_bvh(out, mixed.figure, mixed.q[:200], mixed.fps)
    _, _, P, _, P_end = reference_positions(out, CMU_UNIT_M)
    _, _, P0, _, P0_end = reference_positions(MIXED_BVH, CMU_UNIT_M)
    assert np.abs(P - P0[:200]).max() < TOL_M
    assert np.abs(P_end - P0_end[:200]).max() < TOL_M


def test_write_bvh_of_a_new_motion_reads_back_as_the_same_configurations(walk, tmp_path):
    """Random configurations (not from a file): writing and reading gives the same keypoints."""
    fig = walk.figure
    Q = np.stack([fig.random_configuration(s, unlimited=1.0) for s in range(5)])
    out = tmp_path / "random.bvh"
    write_bvh(out, fig, Q, 30.0)
    back = load_bvh(out, CMU_UNIT_M)
    assert np.abs(back.keypoints() - fig.keypoints(Q)).max() < TOL_M


def test_result_of_a_bvh_figure_reloads_with_the_same_keypoints(walk, tmp_path):
    """The figure's URDF is embedded in the result NPZ and rebuilt by load_result."""
    from pinrecon import load_result
    from pinrecon.result import Result

    Q = walk.q[1:4]
    result = Result(
        walk.figure,
        Q,
        np.arange(3) / 120.0,
        120.0,
        walk.figure.keypoints(Q),
        np.zeros(3),
        None,
        np.ones(3, bool),
    )
    result.save(tmp_path / "walk_result.npz")
    back = load_result(tmp_path / "walk_result.npz")
    assert back.figure.keypoint_names == walk.figure.keypoint_names
    assert np.abs(back.figure.keypoints(Q) - walk.keypoints()[1:4]).max() < 1e-12
    assert back.figure.meta["bvh"]["names"] == walk.clip.names
