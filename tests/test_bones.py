"""Bone rows (``pinrecon.rows.bones``): a CMU BVH joint whose ASF bone has two or three
DOFs keeps the DOFs it lacks at zero and its angles inside the ASF's limits, measured in
the bone's own angles. The frames and limits come from the ASF file by hand; the captured
clips' feet keep their missing DOF at zero; the angles are checked against scipy's Euler
decomposition, the rows' values by hand, the Jacobian by finite differences."""

from __future__ import annotations


import numpy as np
import pytest
from conftest import data_path
from dense_blocks import row_jacobian_error
from scipy.spatial.transform import Rotation

from pinrecon.io.asf import bvh_bones_from_asf, read_asf
from pinrecon.problem import Weights, make_problem
from pinrecon.rows import State
from pinrecon.rows.bones import Bones, bone_row
from pinrecon.synthetic import body_keypoints, bundled_motion, project_tracks, side_camera

ASF = data_path("project-test-data/cmu-asf_01.asf")


def _channels(fig, joint):
    m = fig.model
    ids = [j for j in range(1, m.njoints) if m.names[j].startswith(joint + "_")]
    return "".join(m.names[j].split("_")[-1][0] for j in ids), [m.idx_qs[j] for j in ids]


def test_bones_of_the_asf_file():
    """lfoot: ``dof rx rz``, limits (-45 90) (-70 20), ``axis -90 0 20 XYZ`` (x first):
    C = Rz(20) Ry(0) Rx(-90); lhumerus: three DOFs, ``axis 180 -30 -90``."""
    fig, _, _ = bundled_motion("walk", lock=())
    b = bvh_bones_from_asf(read_asf(ASF), fig.joint_names)
    foot = b["LeftFoot"]
    assert foot["dof"] == ["rx", "rz"] and foot["limits"] == [[-45.0, 90.0], [-70.0, 20.0]]
    np.testing.assert_allclose(foot["axis"], Rotation.from_euler("ZYX", [20.0, 0.0, -90.0], degrees=True).as_matrix(),
                               atol=1e-9)
    arm = b["LeftArm"]
    assert arm["dof"] == ["rx", "ry", "rz"] and arm["limits"] == [[-60.0, 90.0], [-90.0, 90.0], [-90.0, 90.0]]
    np.testing.assert_allclose(arm["axis"], Rotation.from_euler("ZYX", [-90.0, -30.0, 180.0], degrees=True).as_matrix(),
                               atol=1e-9)
    assert "LeftLeg" not in b and "LeftForeArm" not in b  # one DOF: hinges
    assert not any("Hand" in j or "Finger" in j or "Thumb" in j for j in b)  # no captured data


@pytest.mark.parametrize("clip", ["walk", "run", "spin"])
def test_bone_angles_and_the_captured_feet(clip):
    """The row's angles are scipy's ZYX angles of ``C^T R C``; the clips' feet turn about
    their two ASF axes only (``ry`` = 0 in every frame)."""
    fig, q, _ = bundled_motion(clip)
    limited = fig.with_limits(ASF)
    row = bone_row(limited, len(q))
    A = row.angles(q)
    for h, joint in enumerate(row.joints):
        order, qi = _channels(limited, joint)
        R = Rotation.from_euler(order, q[:, qi]).as_matrix()
        C = np.asarray(limited.meta["bones"][joint]["axis"])
        want = Rotation.from_matrix(C.T @ R @ C).as_euler("ZYX")
        np.testing.assert_allclose(A[:, h], want, atol=1e-9)
    for foot in ("LeftFoot", "RightFoot"):
        assert np.abs(A[:, row.joints.index(foot), 1]).max() < 1e-4


def test_rows_by_hand():
    """A foot turned 0.05 rad about its missing axis pays 0.05 / sigma_lock; an upper arm
    at rz = 100 degrees (limit 90, margin 5) pays 5 degrees / sigma_limit; inside, nothing."""
    fig, q, _ = bundled_motion("walk")
    limited = fig.with_limits(ASF)
    bones = {j: limited.meta["bones"][j] for j in ("LeftFoot", "LeftArm")}
    row = Bones(limited, 2, bones, sigma_lock=0.01, sigma_limit=0.1, margin_deg=5.0)
    Q = np.repeat(q[:1], 2, axis=0)
    for j, angles in (("LeftFoot", [[0.0, 0.0, 0.3], [0.0, 0.05, 0.3]]), ("LeftArm", [[1.5, 0.1, -0.5], [np.radians(100.0), 0.1, -0.5]])):
        order, qi = _channels(limited, j)
        C = np.asarray(bones[j]["axis"])
        for t in range(2):
            R = C @ Rotation.from_euler("ZYX", angles[t]).as_matrix() @ C.T
            Q[t, qi] = Rotation.from_matrix(R).as_euler(order)
    r = row.evaluate(State(limited, Q, np.zeros(0, int), False), False).r.reshape(2, 2, 3)
    assert np.abs(r[0]).max() == pytest.approx(0.0, abs=1e-9)
    assert r[1, 0] == pytest.approx([0.0, 0.05 / 0.01, 0.0], abs=1e-6)
    assert r[1, 1] == pytest.approx([np.radians(5.0) / 0.1, 0.0, 0.0], abs=1e-6)


def test_jacobian_against_finite_differences():
    fig, q, _ = bundled_motion("run")
    limited = fig.with_limits(ASF)
    row = bone_row(limited, 4)
    row.lower[:], row.upper[:], row.inv_sigma[:] = 0.01, 0.02, 1.0  # every angle outside: every row live
    rng = np.random.default_rng(0)
    Q = q[:4].copy()
    Q[:, row.qidx.ravel()] += rng.normal(0.0, 0.3, (4, row.qidx.size))
    assert row_jacobian_error(row, limited, Q) < 1e-5


def test_the_problem_has_them_with_an_asf_and_not_without():
    fig, q, fps = bundled_motion("walk")
    names = body_keypoints(fig)
    cam = side_camera(q[:20], 45.0)
    tracks = project_tracks(fig, q[:20], cam, names, fps=fps)
    assert "bones" in {r.name for r in make_problem(fig.with_limits(ASF), tracks, cam, weights=Weights()).rows}
    assert "bones" not in {r.name for r in make_problem(fig, tracks, cam, weights=Weights()).rows}
