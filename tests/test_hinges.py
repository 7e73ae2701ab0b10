"""Hinge rows (``pinrecon.rows.hinges``): a CMU BVH joint whose ASF bone has one DOF is
held on its axis. The axes come from the ASF file; the captured clips' own knees and
elbows lie on them; the rows' values and analytic Jacobian are checked by hand and by
finite differences."""

from __future__ import annotations


import numpy as np
import pytest
from conftest import data_path
from dense_blocks import row_jacobian_error
from scipy.spatial.transform import Rotation

from pinrecon.io.asf import bvh_hinges_from_asf, read_asf
from pinrecon.problem import Weights, make_problem
from pinrecon.rows import State
from pinrecon.rows.hinges import Hinges, hinge_row
from pinrecon.synthetic import body_keypoints, bundled_motion, project_tracks, side_camera

ASF = data_path("project-test-data/cmu-asf_01.asf")


def test_hinge_axes_of_the_asf_file():
    """ltibia: ``dof rx``, ``axis 0 0 20 XYZ``: the knee turns about Rz(20 deg) e_x;
    lradius: ``axis 180 -30 -90 XYZ`` (x first): Rz(-90) Ry(-30) Rx(180) e_x."""
    fig, _, _ = bundled_motion("walk", lock=())
    h = bvh_hinges_from_asf(read_asf(ASF), fig.joint_names)
    a = np.radians(20.0)
    np.testing.assert_allclose(h["LeftLeg"], [np.cos(a), np.sin(a), 0.0], atol=1e-8)
    np.testing.assert_allclose(h["RightLeg"], [np.cos(a), -np.sin(a), 0.0], atol=1e-8)
    want = Rotation.from_euler("ZYX", [-90.0, -30.0, 180.0], degrees=True).apply([1.0, 0.0, 0.0])
    np.testing.assert_allclose(h["LeftForeArm"], want, atol=1e-8)
    assert "LeftArm" not in h and "LeftUpLeg" not in h  # three DOFs: no hinge
    assert not any("Hand" in j or "Finger" in j or "Thumb" in j for j in h)  # no captured data


@pytest.mark.parametrize("clip", ["walk", "run", "spin"])
def test_captured_knees_and_elbows_lie_on_their_asf_axes(clip):
    fig, q, _ = bundled_motion(clip)
    limited = fig.with_limits(ASF)
    assert {"LeftLeg", "RightLeg", "LeftForeArm", "RightForeArm"} <= set(limited.meta["hinges"])
    row = hinge_row(limited, len(q))
    r = row.evaluate(State(limited, q, np.zeros(0, int), False), False).r
    assert np.abs(r).max() * row.sigma < 1e-4  # radians off the axis, every frame


def test_rows_measure_the_angle_off_the_axis():
    """A rotation about the axis costs nothing; one by phi about an axis normal to it,
    |r| sigma = phi (the channels set from the rotation by scipy's Euler angles)."""
    fig, q, _ = bundled_motion("walk")
    a = np.array([0.0, -0.866025404, 0.5])
    row = Hinges(fig, 2, {"LeftForeArm": a}, sigma=0.01)
    names = [fig.model.names[j] for j in range(1, fig.model.njoints) if fig.model.names[j].startswith("LeftForeArm_")]
    order = "".join(n.split("_")[1][0] for n in names)
    n = np.cross(a, [1.0, 0.0, 0.0])
    n /= np.linalg.norm(n)
    Q = np.repeat(q[:1], 2, axis=0)
    for t, R in enumerate([Rotation.from_rotvec(1.1 * a), Rotation.from_rotvec(0.05 * n)]):
        Q[t, row.qidx[0]] = R.as_euler(order, degrees=False)
    r = row.evaluate(State(fig, Q, np.zeros(0, int), False), False).r
    assert np.linalg.norm(r[0]) * 0.01 == pytest.approx(0.0, abs=1e-9)
    assert np.linalg.norm(r[1]) * 0.01 == pytest.approx(0.05, rel=1e-6)


def test_jacobian_against_finite_differences():
    fig, q, _ = bundled_motion("run")
    limited = fig.with_limits(ASF)
    row = hinge_row(limited, 3)
    rng = np.random.default_rng(0)
    Q = q[:3].copy()
    Q[:, row.qidx.ravel()] += rng.normal(0.0, 0.3, (3, row.qidx.size))
    assert row_jacobian_error(row, limited, Q) < 1e-5
    m = limited.model
    for k, iq in enumerate(row.qidx.ravel()):  # column k is the tangent entry of q entry iq
        assert row.cols[k] == m.idx_vs[next(j for j in range(1, m.njoints) if m.idx_qs[j] == iq)]


def test_the_problem_has_them_with_an_asf_and_not_without():
    fig, q, fps = bundled_motion("walk")
    names = body_keypoints(fig)
    cam = side_camera(q[:20], 45.0)
    tracks = project_tracks(fig, q[:20], cam, names, fps=fps)
    kinds = {r.name for r in make_problem(fig.with_limits(ASF), tracks, cam, weights=Weights()).rows}
    assert "hinges" in kinds
    assert "hinges" not in {r.name for r in make_problem(fig, tracks, cam, weights=Weights()).rows}
