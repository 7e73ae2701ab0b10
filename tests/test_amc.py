"""CMU's AMC motion on its ASF skeleton: a hand-computed two-bone case, the CMU trial
01_01 against the BVH conversion of the same capture (read by the BVH reader, its
rotations composed here with scipy), and the errors a broken AMC file gets."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_file
from scipy.spatial.transform import Rotation

from pinrecon.errors import InputError, UnknownNameError
from pinrecon.io.amc import asf_length_scale, load_amc
from pinrecon.io.asf import read_asf
from pinrecon.io.bvh_format import read_bvh

TINY_ASF = """:version 1.10
:name tiny
:units
  length 1
  angle deg
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name a
     direction 0 1 0
     length 1
     axis 0 0 90 XYZ
     dof rx
  end
  begin
     id 2
     name b
     direction 1 0 0
     length 2
     axis 0 0 0 XYZ
     dof ry rz
  end
:hierarchy
  begin
    root a
    a b
  end
"""

# frame 1: root at (1, 2, 3), unrotated; a turns 90 degrees about its axis C e_x = e_y
# (C = Rz(90)); b unrotated. frame 2: the root turned 90 degrees about z, a and b at rest.
TINY_AMC = """:FULLY-SPECIFIED
:DEGREES
1
root 1 2 3 0 0 0
a 90
b 0 0
2
root 0 0 0 0 0 90
a 0
b 0 0
"""


def tiny(tmp_path, amc=TINY_AMC):
    (tmp_path / "t.asf").write_text(TINY_ASF)
    (tmp_path / "t.amc").write_text(amc)
    return tmp_path / "t.asf", tmp_path / "t.amc"


def test_two_bones_by_hand(tmp_path):
    m = load_amc(*tiny(tmp_path), length_scale=1.0, fps=30.0)
    names = m.figure.keypoint_names
    assert names == ["root", "a", "b", "b_end"] and m.fps == 30.0 and m.q.shape[0] == 2
    kp = m.keypoints()
    # frame 0: a starts at the root; b at a's end, (0, 1, 0) turned about y by 90: unchanged;
    # b's end: (2, 0, 0) turned 90 degrees about y is (0, 0, -2)
    np.testing.assert_allclose(kp[0], [[1, 2, 3], [1, 2, 3], [1, 3, 3], [1, 3, 1]], atol=1e-12)
    # frame 1: at the origin, Rz(90): (0, 1, 0) -> (-1, 0, 0), (2, 0, 0) -> (0, 2, 0)
    np.testing.assert_allclose(kp[1], [[0, 0, 0], [0, 0, 0], [-1, 0, 0], [-1, 2, 0]], atol=1e-12)


def test_length_scale_and_radians(tmp_path):
    asf, amc = tiny(tmp_path, TINY_AMC.replace(":DEGREES", ":RADIANS").replace("a 90", f"a {np.pi / 2!r}"))
    m = load_amc(asf, amc, length_scale=0.5)
    np.testing.assert_allclose(m.keypoints()[0, 3], [0.5, 1.5, 0.5], atol=1e-12)
    assert asf_length_scale(read_asf(data_file("mocap/cmu-asf_01.asf"))) == pytest.approx(0.0254 / 0.45)


@pytest.mark.parametrize(
    "line, replacement, field, frame, message",
    [
        ("b 0 0\n2", "c 0 0\n2", "c", 0, "unknown ASF bone name(s) 'c'; valid ASF bone names are: root, a, b"),
        ("a 90", "a 90 1", "a", 0, "expected 1 values (rx), got 2"),
        ("a 0", "a zero", "a", 1, "non-numeric value"),
        ("a 0", "a nan", "a", 1, "NaN or infinite value"),
        ("root 0 0 0 0 0 90", "root 0 0 0 0 inf 90", "root", 1, "NaN or infinite value"),
        ("b 0 0\n2", "2", "b", 0, "missing"),
        ("b 0 0\n2", "b 0 0\nb 0 0\n2", "b", 0, "given twice"),
    ],
)
def test_broken_amc_is_located(tmp_path, line, replacement, field, frame, message):
    asf, amc = tiny(tmp_path, TINY_AMC.replace(line, replacement, 1))
    with pytest.raises(InputError) as err:
        load_amc(asf, amc)
    e = err.value
    assert (e.file, e.field, e.frame) == (str(amc), field, frame)
    assert message in str(e)
    if field == "c":
        assert isinstance(e, UnknownNameError)


def test_values_before_any_frame_and_unsupported_dofs(tmp_path):
    asf, amc = tiny(tmp_path, "a 90\n" + TINY_AMC)
    with pytest.raises(InputError, match="before the first frame number"):
        load_amc(asf, amc)
    amc.write_text(TINY_AMC)
    asf.write_text(TINY_ASF.replace("dof rx", "dof rx l"))
    with pytest.raises(InputError, match="only rotations") as err:
        load_amc(asf, amc)
    assert err.value.field == "bonedata.a.dof"


def _bvh_world_rotation(clip, name):
    """World rotation (F, 3, 3) of a BVH joint: its and its ancestors' ZYX channels, with scipy."""
    cols = clip.channel_columns()
    chain, i = [], clip.joint_index(name)
    while i >= 0:
        chain.append(i)
        i = clip.joints[i].parent
    R = np.broadcast_to(np.eye(3), (clip.n_frames, 3, 3))
    for i in reversed(chain):
        j = clip.joints[i]
        rot = [k for k, c in enumerate(j.channels) if c.endswith("rotation")]
        axes = "".join(j.channels[k][0] for k in rot)
        R = R @ Rotation.from_euler(axes, clip.values[:, cols[i]][:, rot], degrees=True).as_matrix()
    return R


def test_cmu_01_01_against_its_bvh_conversion():
    asf, amc = data_file("mocap/cmu-asf_01.asf"), data_file("mocap/cmu-asf_01_01.amc")
    motion = load_amc(asf, amc, length_scale=1.0, names="bvh")  # CMU units, as the BVH
    assert motion.q.shape[0] == 2751 and motion.fps == 120.0
    kp = motion.keypoints()
    names = motion.figure.keypoint_names

    # the BVH side: the file's own offsets and channels, forward kinematics here
    clip = read_bvh(data_file("mocap/cmu-mb_01_01.bvh"))
    assert clip.n_frames == 2752  # frame 0 is the converter's T-pose: BVH frame k + 1 = AMC frame k
    cols = clip.channel_columns()
    F = clip.n_frames
    pos = np.zeros((F, len(clip.joints), 3))
    Rw = np.zeros((F, len(clip.joints), 3, 3))
    for i, j in enumerate(clip.joints):
        v = clip.values[:, cols[i]]
        rot = [k for k, c in enumerate(j.channels) if c.endswith("rotation")]
        R = Rotation.from_euler("".join(j.channels[k][0] for k in rot), v[:, rot], degrees=True).as_matrix()
        if j.parent < 0:
            pos[:, i] = j.offset + v[:, [k for k, c in enumerate(j.channels) if c.endswith("position")]]
            Rw[:, i] = R
        else:
            pos[:, i] = pos[:, j.parent] + Rw[:, j.parent] @ j.offset
            Rw[:, i] = Rw[:, j.parent] @ R
    bvh = {j.name: pos[1:, i] for i, j in enumerate(clip.joints)}

    legs_spine = ["Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "RHipJoint", "RightUpLeg",
                  "RightLeg", "RightFoot", "RightToeBase", "LowerBack", "Spine", "Spine1"]
    for n in legs_spine:
        err = np.abs(kp[:, names.index(n)] - bvh[n]).max()
        assert err < 1e-4, (n, err)

    # neck, head and arms: the BVH has no thorax length, so they sit the thorax vector
    # (turned with Spine1, the thorax's joint) away from the BVH's, in every frame
    sk = read_asf(asf)
    thorax = np.asarray(sk.bones["thorax"].direction) * sk.bones["thorax"].length
    assert np.linalg.norm(thorax) == pytest.approx(2.065, abs=1e-3)
    shift = _bvh_world_rotation(clip, "Spine1")[1:] @ thorax
    for n in ["Neck", "Neck1", "Head", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand", "RightShoulder",
              "RightArm", "RightForeArm", "RightHand"]:
        err = np.abs(kp[:, names.index(n)] - bvh[n] - shift).max()
        assert err < 1e-4, (n, err)
        assert np.abs(kp[:, names.index(n)] - bvh[n]).max() > 2.0  # the shift is really there


def test_cmu_motion_is_continuous_and_in_metres_by_default():
    motion = load_amc(data_file("mocap/cmu-asf_01.asf"), data_file("mocap/cmu-asf_01_01.amc"))
    # no joint value jumps (no 360-degree wraps) between frames at 120 fps
    assert np.abs(np.diff(motion.q[:, 7:], axis=0)).max() < np.radians(30)
    kp = motion.keypoints()
    names = motion.figure.keypoint_names
    # the femur is 7.1578 CMU units along (0.34202, -0.939693, 0) (a unit vector to 6 digits): 0.404 m
    femur = np.linalg.norm(kp[:, names.index("ltibia")] - kp[:, names.index("lfemur")], axis=1)
    np.testing.assert_allclose(femur, 7.1578 * np.hypot(0.34202, 0.939693) * 0.0254 / 0.45, rtol=1e-12)


@pytest.mark.parametrize(
    "old, new, field, message",
    [
        ("    a b\n", "    a b\n    b a\n", "hierarchy.b", "two parents"),
        ("    a b\n", "    a b\n    b b\n", "hierarchy.b", "two parents"),
        ("axis 0 0 90 XYZ", "axis 0 0 90 XYW", "bonedata.a.axis", "three of X, Y, Z"),
        ("    root a\n", "    root b\n", "hierarchy", "two parents"),
        ("    root a\n", "", "hierarchy", "no 'root' line"),
    ],
)
def test_broken_skeleton_is_refused_not_looped(tmp_path, old, new, field, message):
    asf, amc = tiny(tmp_path)
    asf.write_text(TINY_ASF.replace(old, new))
    with pytest.raises(InputError) as err:
        load_amc(asf, amc)
    assert err.value.file == str(asf) and err.value.field.startswith(field) and message in str(err.value)
