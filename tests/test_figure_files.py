"""The URDF text pinrecon writes and reads with the standard library, checked against
yourdfpy (an independent URDF parser, the test extra's) and against the BVH file."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path

from pinrecon import Figure
from pinrecon.errors import UnknownNameError
from pinrecon.figure_files import scale_urdf_origins, urdf_joint_limits
from pinrecon.io.bvh_format import read_bvh

yourdfpy = pytest.importorskip("yourdfpy")

BVH = data_path("mocap/cmu-mb_05_02.bvh")
SCALE = 0.056444


def _load(xml: str):
    return yourdfpy.URDF.load(io.BytesIO(xml.encode()), build_scene_graph=False, load_meshes=False).robot


def test_limits_match_yourdfpy_on_the_human_urdf():
    fig = Figure.human()
    xml = open(fig.source).read() if fig.source and str(fig.source).endswith(".urdf") else fig.urdf_xml
    ours = urdf_joint_limits(xml)
    theirs = {
        j.name: (float(j.limit.lower), float(j.limit.upper))
        for j in _load(xml).joints
        if j.type in ("revolute", "prismatic") and j.limit is not None
        and j.limit.lower is not None and j.limit.upper is not None and j.limit.lower < j.limit.upper
    }
    assert len(theirs) >= 30
    assert ours == theirs


def test_bvh_urdf_reads_back_in_yourdfpy_with_the_files_offsets():
    clip = read_bvh(str(BVH))
    fig = Figure.from_bvh_clip(clip, SCALE)
    robot = _load(fig.urdf_xml)
    joints = {j.name: j for j in robot.joints}
    # every non-root BVH joint: its first URDF joint carries the file's OFFSET in metres
    checked = 0
    for j in clip.joints[1:]:
        chain = list(j.position_channels) + list(j.rotation_channels)
        first = joints[f"{j.name}_{chain[0]}"] if chain else joints[f"{j.name}_weld"]
        np.testing.assert_allclose(first.origin[:3, 3], np.asarray(j.offset, float) * SCALE, atol=1e-12)
        np.testing.assert_allclose(first.origin[:3, :3], np.eye(3), atol=1e-12)
        for ch in chain:
            uj = joints[f"{j.name}_{ch}"]
            assert uj.type == ("revolute" if ch.endswith("rotation") else "prismatic")
            np.testing.assert_array_equal(uj.axis, np.eye(3)["XYZ".index(ch[0])])
        checked += 1
    assert checked == len(clip.joints) - 1
    # one revolute URDF joint per rotation channel of the file, each with +-4 pi limits
    n_rot = sum(len(j.rotation_channels) for j in clip.joints[1:])
    revolute = [j for j in robot.joints if j.type == "revolute"]
    assert len(revolute) == n_rot
    assert all(np.isclose(j.limit.upper, 4 * np.pi) and np.isclose(j.limit.lower, -4 * np.pi) for j in revolute)
    assert fig.nv == 6 + n_rot


def test_scaled_origins_against_yourdfpy():
    fig = Figure.human()
    robot = _load(fig.urdf_xml)
    names = [j.name for j in robot.joints if j.origin is not None]
    factors = {names[0]: 1.5, names[3]: 0.8}
    scaled = _load(scale_urdf_origins(fig.urdf_xml, factors))
    before = {j.name: j.origin for j in robot.joints}
    for j in scaled.joints:
        f = factors.get(j.name, 1.0)
        np.testing.assert_allclose(j.origin[:3, 3], f * before[j.name][:3, 3], rtol=0, atol=1e-15)
        np.testing.assert_allclose(j.origin[:3, :3], before[j.name][:3, :3], atol=1e-12)
    # one factor for every joint: the whole figure scales, keypoints with it
    big = Figure.from_urdf_string(fig.scaled_urdf(2.0), fig.keypoints_def, root="free")
    assert big.nv == fig.nv
    import pinocchio as pin

    pos = []
    for f in (fig, big):
        d = f.model.createData()
        pin.forwardKinematics(f.model, d, f.neutral())
        pos.append(np.array([d.oMi[i].translation for i in range(1, f.model.njoints)]))
    np.testing.assert_allclose(pos[1], 2.0 * pos[0], atol=1e-12)
    with pytest.raises(UnknownNameError):
        scale_urdf_origins(fig.urdf_xml, {"no_such_joint": 2.0})
