"""CMU ASF skeletons: reading them, carrying their joint limits onto a BVH figure, and the
limits files (the human figure's anatomical limits)."""

from __future__ import annotations


import numpy as np
import pytest
from conftest import data_path

import pinrecon as pr
from pinrecon.errors import InputError, UnknownNameError
from pinrecon.io.asf import bvh_limits_from_asf, read_asf
from pinrecon.joint_limits import load_limits
from pinrecon.synthetic import bundled_motion

ASF = data_path("project-test-data/cmu-asf_01.asf")


def test_read_asf_values_of_the_file():
    sk = read_asf(ASF)
    assert len(sk.bones) == 30
    assert sk.units["length"] == "0.45" and sk.units["angle"] == "deg"
    tib = sk.bones["ltibia"]
    assert tib.dof == ("rx",) and tib.limits_deg == ((-10.0, 170.0),)
    assert tib.axis_deg == (0.0, 0.0, 20.0) and tib.axis_order == "XYZ"
    assert tib.direction == pytest.approx((0.34202, -0.939693, 0.0)) and tib.length == pytest.approx(7.49137)
    fem = sk.bones["lfemur"]
    assert fem.dof == ("rx", "ry", "rz")
    assert fem.limits_deg == ((-160.0, 20.0), (-70.0, 70.0), (-60.0, 70.0))
    assert sk.bones["lhipjoint"].dof == () and sk.bones["lhipjoint"].limits_deg == ()
    assert sk.hierarchy["root"] == ["lhipjoint", "rhipjoint", "lowerback"]
    assert sk.hierarchy["thorax"] == ["lowerneck", "lclavicle", "rclavicle"]


def _asf(tmp_path, body):
    p = tmp_path / "s.asf"
    p.write_text(":version 1.10\n:name T\n:units\n  length 1\n  angle deg\n:bonedata\n" + body + ":hierarchy\n  begin\n  end\n")
    return p


def test_limits_of_an_untilted_hinge_map_to_one_channel(tmp_path):
    """A one-DOF bone whose axis frame is the world's: its rx range becomes the X channel's
    range (plus the 5 degree margin) and the other two channels stay at 0 +- 5 degrees."""
    p = _asf(tmp_path, "  begin\n    id 1\n    name ltibia\n    direction 0 -1 0\n    length 1\n"
                       "    axis 0 0 0 XYZ\n    dof rx\n    limits (-10.0 170.0)\n  end\n")
    lim = bvh_limits_from_asf(read_asf(p), ["LeftLeg_Zrotation", "LeftLeg_Yrotation", "LeftLeg_Xrotation"])
    deg = {k: np.degrees(v) for k, v in lim.items()}
    assert deg["LeftLeg_Xrotation"] == pytest.approx((-15.0, 175.0), abs=1e-6)
    assert deg["LeftLeg_Yrotation"] == pytest.approx((-5.0, 5.0), abs=1e-6)
    assert deg["LeftLeg_Zrotation"] == pytest.approx((-5.0, 5.0), abs=1e-6)


def test_a_tilted_hinge_couples_channels(tmp_path):
    """Axis tilted 90 degrees about z: the bone's rx turns about world y, so the range lands
    on the Y channel (sign kept: R_z(90) e_x = e_y)."""
    p = _asf(tmp_path, "  begin\n    id 1\n    name ltibia\n    direction 0 -1 0\n    length 1\n"
                       "    axis 0 0 90 XYZ\n    dof rx\n    limits (-10.0 60.0)\n  end\n")
    lim = bvh_limits_from_asf(read_asf(p), ["LeftLeg_Zrotation", "LeftLeg_Yrotation", "LeftLeg_Xrotation"])
    assert np.degrees(lim["LeftLeg_Yrotation"]) == pytest.approx((-15.0, 65.0), abs=1e-6)
    assert np.degrees(lim["LeftLeg_Xrotation"]) == pytest.approx((-5.0, 5.0), abs=1e-6)


@pytest.mark.parametrize("clip", ["walk", "run"])
def test_captured_motion_stays_inside_the_asf_limits(clip):
    """The ASF's limits carried onto the MotionBuilder-friendly BVH hold for the captured
    walk and run in every frame: the mapping's conventions (axis frame, Euler order) agree
    with the data's (a wrong sign or axis would put the knees outside)."""
    fig, q, _ = bundled_motion(clip, lock=())
    lim = bvh_limits_from_asf(read_asf(ASF), fig.joint_names)
    assert {"LeftLeg_Xrotation", "RightLeg_Xrotation", "LeftForeArm_Xrotation", "RightUpLeg_Yrotation"} <= set(lim)
    assert np.degrees(lim["LeftLeg_Xrotation"][0]) == pytest.approx(-10.0 * np.cos(np.radians(20)) - 5, abs=0.6)
    outside = []
    for name, (lo, hi) in lim.items():
        qs, _ = fig.joint_slices(name)
        v = q[:, qs][:, 0]
        frac = np.mean((v < lo) | (v > hi))
        if frac > 0.05:
            outside.append((name, frac))
    assert outside == [] if clip == "walk" else all(n.startswith("RightToeBase") for n, _ in outside)


def test_with_limits_from_an_asf_file():
    fig, _, _ = bundled_motion("walk")
    limited = fig.with_limits(ASF)
    iv = fig.joint_slices("LeftLeg_Xrotation")[1].start
    assert not np.isfinite(fig.lower_v[iv]) and np.isfinite(limited.lower_v[iv])
    assert limited.lower_v[iv] < 0 < np.radians(90) < limited.upper_v[iv]


def test_bad_asf_is_one_located_error(tmp_path):
    p = _asf(tmp_path, "  begin\n    id 1\n    name lfemur\n    direction 0 -1 0\n    length 1\n"
                       "    axis 0 0 0 XYZ\n    dof rx ry\n    limits (10.0 -10.0)\n  end\n")
    with pytest.raises(InputError) as e:
        read_asf(p)
    assert "s.asf" in str(e.value) and "lfemur" in str(e.value)
    with pytest.raises(InputError, match="file not found"):
        read_asf(tmp_path / "missing.asf")
    q = tmp_path / "empty.asf"
    q.write_text(":version 1.10\n")
    with pytest.raises(InputError, match="bonedata"):
        read_asf(q)


def test_human_limits_are_anatomical():
    """Figure.human() applies models/limits/human.json: one-way knees and elbows inside the
    published ranges (docs/limits.md), hip flexion and shoulder rotation tightened."""
    fig = pr.Figure.human()
    lim = {k: np.degrees(v) for k, v in fig.limits_dict().items()}
    assert lim["left_knee_Z"] == pytest.approx((0.0, 150.0)) and lim["right_elbow_Z"] == pytest.approx((0.0, 160.0))
    assert lim["left_hip_Z"][1] == pytest.approx(135.0) and lim["right_shoulder_Y"] == pytest.approx((-100.0, 100.0))
    # the knee bends backwards: +knee_Z moves the ankle behind the knee (x is forward)
    q = fig.neutral()
    a0 = fig.keypoints(q)[fig.keypoint_index(["left_ankle"])[0]]
    q[fig.joint_slices("left_knee_Z")[0]] = 1.0
    a1 = fig.keypoints(q)[fig.keypoint_index(["left_ankle"])[0]]
    assert a1[0] < a0[0] - 0.2


def test_limits_json(tmp_path):
    p = tmp_path / "l.json"
    p.write_text('{"units": "degrees", "limits": {"left_knee_Z": [0, 90]}}')
    assert load_limits(p)["left_knee_Z"] == pytest.approx((0.0, np.pi / 2))
    assert np.degrees(pr.Figure.human().with_limits(p).limits_dict()["left_knee_Z"][1]) == pytest.approx(90.0)
    p.write_text('{"units": "degrees", "limits": {"left_knee_Z": [90, 0]}}')
    with pytest.raises(InputError, match="limits.left_knee_Z"):
        load_limits(p)
    p.write_text('{"limits": {"no_such_joint": [0, 1]}}')
    with pytest.raises(UnknownNameError, match="no_such_joint"):
        pr.Figure.human().with_limits(p)
