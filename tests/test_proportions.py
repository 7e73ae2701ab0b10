"""Proportions as parameters: segments, groups, the scaled figure and the analytic
derivatives of every keypoint w.r.t. every log factor.

Ground truth is independent of the code under test: central finite differences of the
*calibrated figure's* forward kinematics (a new Figure built from the edited URDF text,
through Pinocchio's URDF parser), and distances between keypoints, which a scale factor
on the bone between them multiplies exactly."""

from __future__ import annotations

import numpy as np
import pytest

import pinrecon as pr
from pinrecon.errors import InputError, UnknownNameError
from pinrecon.proportions import HUMAN_GROUPS, Proportions, mirror_name
from pinrecon.synthetic import smooth_motion

from conftest import CMU_UNIT_M, WALK, data_path

WALK_BVH = data_path(WALK)


@pytest.fixture(scope="module")
def bvh_locked():
    # LeftLeg welded: its BVH offset becomes a fixed URDF joint (a "fixed" segment)
    return pr.Figure.from_bvh(WALK_BVH, CMU_UNIT_M, lock=["LeftLeg", "Spine1"])


def _figures(human_joints, bvh_locked):
    return {
        "human coco17, named groups": Proportions.human(pr.Figure.human()),
        "human joints map, named groups": Proportions.human(human_joints),
        "human, one factor per bone": Proportions.bones(human_joints, symmetric=False),
        "bvh with welded joints, symmetric bones": Proportions.bones(bvh_locked),
    }


@pytest.mark.parametrize(
    "which",
    [
        "human coco17, named groups",
        "human joints map, named groups",
        "human, one factor per bone",
        "bvh with welded joints, symmetric bones",
    ],
)
def test_keypoint_derivatives_match_finite_differences_of_the_calibrated_figure(human_joints, bvh_locked, which):
    props = _figures(human_joints, bvh_locked)[which]
    fig = props.figure
    rng = np.random.default_rng(1)
    Q = np.stack([fig.random_configuration(s) for s in (3, 4, 5)])
    theta = rng.normal(0.0, 0.15, props.n)
    p, J, dp = props.kinematics(theta, Q)
    eps = 1e-6
    fd = np.zeros_like(dp)
    for i in range(props.n):
        e = np.zeros(props.n)
        e[i] = eps
        plus = props.calibrated_figure(theta + e).keypoints(Q)
        minus = props.calibrated_figure(theta - e).keypoints(Q)
        fd[..., i] = (plus - minus) / (2 * eps)
    scale = np.abs(dp).max()
    assert np.abs(dp - fd).max() <= 1e-6 * scale
    # every group moves some keypoint
    assert np.all(np.abs(dp).max(axis=(0, 1, 2)) > 1e-3)
    # positions and configuration Jacobians equal the calibrated figure's own
    cal = props.calibrated_figure(theta)
    p_ref, J_ref = cal.keypoint_jacobians(Q)
    np.testing.assert_allclose(p, p_ref, atol=1e-12)
    np.testing.assert_allclose(J, J_ref, atol=1e-12)
    np.testing.assert_allclose(props.keypoints(theta, Q), p_ref, atol=1e-12)


def test_segments_of_a_welded_bvh_joint_are_fixed_urdf_joints(bvh_locked):
    props = Proportions.bones(bvh_locked)
    kinds = {s.name: s.kind for s in props.segments}
    assert kinds["LeftLeg_weld"] == "fixed" and kinds["Spine1_weld"] == "fixed"
    assert kinds["RightLeg_Zrotation"] == "joint"
    # the welded left shank pairs with the right one
    assert any(set(props.members(g)) == {"LeftLeg_weld", "RightLeg_Zrotation"} for g in props.names)


def test_factors_scale_bone_lengths_exactly():
    fig = pr.Figure.human()
    props = Proportions.human(fig)
    theta = np.zeros(props.n)
    theta[props.names.index("forearm")] = np.log(1.2)
    theta[props.names.index("shank")] = np.log(0.9)
    theta[props.names.index("pelvis_width")] = np.log(1.1)
    cal = props.calibrated_figure(theta)
    Q = smooth_motion(fig, 5, 30.0, seed=2)

    def dist(f, a, b):
        P = f.keypoints(Q)
        return np.linalg.norm(P[:, f.keypoint_index([a])[0]] - P[:, f.keypoint_index([b])[0]], axis=-1)

    for a, b, s in [
        ("left_elbow", "left_wrist", 1.2),
        ("right_elbow", "right_wrist", 1.2),
        ("left_knee", "left_ankle", 0.9),
        ("right_knee", "right_ankle", 0.9),
        ("left_hip", "right_hip", 1.1),
        ("left_shoulder", "left_elbow", 1.0),
        ("left_hip", "left_knee", 1.0),
    ]:
        np.testing.assert_allclose(dist(cal, a, b), s * dist(fig, a, b), rtol=1e-12)
    # the generic figure's URDF says the shank is 0.44 m long
    np.testing.assert_allclose(dist(cal, "left_knee", "left_ankle"), 0.9 * 0.44, rtol=1e-12)
    assert props.lengths_m(theta)["shank"] == pytest.approx(0.9 * 0.44)
    assert props.factors(theta)["forearm"] == pytest.approx(1.2)


def test_zero_factors_reproduce_the_figure_and_the_urdf_round_trips(tmp_path):
    fig = pr.Figure.human()
    props = Proportions.human(fig)
    Q = smooth_motion(fig, 4, 30.0, seed=5)
    np.testing.assert_allclose(props.calibrated_figure(np.zeros(props.n)).keypoints(Q), fig.keypoints(Q), atol=1e-15)
    theta = np.linspace(-0.2, 0.2, props.n)
    cal = props.calibrated_figure(theta)
    path = tmp_path / "calibrated.urdf"
    cal.save_urdf(path)
    again = pr.Figure.from_urdf(path, cal.keypoints_def)
    np.testing.assert_allclose(again.keypoints(Q), props.keypoints(theta, Q), atol=1e-12)
    assert cal.meta["proportions"]["factors"]["head"] == pytest.approx(np.exp(theta[props.names.index("head")]))
    # limits survive
    np.testing.assert_array_equal(cal.lower_v, fig.lower_v)


def test_human_groups_are_named_and_cover_both_sides():
    props = Proportions.default(pr.Figure.human())
    assert set(props.names) >= {
        "thigh", "shank", "upper_arm", "forearm", "pelvis_width", "shoulder_width", "trunk", "neck", "head",
    }
    # COCO-17 has no point on the feet or hands: those groups only exist with such keypoints
    assert "foot" not in props.names
    assert {"foot", "hand"} <= set(Proportions.default(pr.Figure.human("joints")).names)
    for g in ("thigh", "shank", "upper_arm", "forearm"):
        assert props.members(g) == HUMAN_GROUPS[g]


@pytest.mark.parametrize(
    "name, mirror, stem",
    [
        ("left_knee_Z", "right_knee_Z", "knee_Z"),
        ("RightForeArm_Zrotation", "LeftForeArm_Zrotation", "ForeArm_Zrotation"),
        ("l_elbow", "r_elbow", "elbow"),
        ("R_hip", "L_hip", "hip"),
        ("knee_l", "knee_r", "knee"),
        ("upperarm.L", "upperarm.R", "upperarm"),
        ("LHipJoint", "RHipJoint", "HipJoint"),
        ("LEFT_FOOT", "RIGHT_FOOT", "FOOT"),
    ],
)
def test_mirror_names(name, mirror, stem):
    assert mirror_name(name) == (mirror, stem)


@pytest.mark.parametrize("name", ["Spine1", "Hips", "LowerBack", "neck"])
def test_names_without_a_side(name):
    assert mirror_name(name) is None


def test_bad_groups_and_factors_are_clear_errors():
    fig = pr.Figure.human()
    with pytest.raises(UnknownNameError, match="left_knee_Z"):
        Proportions(fig, {"thigh": ["left_kne_Z"]})
    with pytest.raises(InputError, match="two groups"):
        Proportions(fig, {"a": ["left_knee_Z"], "b": ["left_knee_Z"]})
    props = Proportions.human(fig)
    with pytest.raises(InputError, match="log factors"):
        props.kinematics(np.zeros(props.n + 1), smooth_motion(fig, 2, 30.0))
    with pytest.raises(UnknownNameError):
        props.log_factors_for_lengths({"tail": 0.3})


def test_measured_lengths_start_the_factors():
    props = Proportions.human(pr.Figure.human())
    theta = props.log_factors_for_lengths({"shank": 0.40, "forearm": 0.30})
    lengths = props.lengths_m(theta)
    assert lengths["shank"] == pytest.approx(0.40) and lengths["forearm"] == pytest.approx(0.30)
    assert lengths["thigh"] == pytest.approx(0.439)


def test_a_calibrated_bvh_figure_describes_its_scaled_skeleton(bvh_locked):
    """The BVH description a calibrated figure carries (for export) has the offsets and
    end sites its forward kinematics shows: each joint's distance to its parent."""
    props = Proportions.bones(bvh_locked)
    theta = np.random.default_rng(7).normal(0.0, 0.2, props.n)
    cal = props.calibrated_figure(theta)
    bvh = cal.meta["bvh"]
    P = cal.keypoints(cal.random_configuration(2))
    names, parents = bvh["names"], bvh["parents"]
    for i in range(1, len(names)):
        d = np.linalg.norm(P[cal.keypoint_index([names[i]])[0]] - P[cal.keypoint_index([names[parents[i]]])[0]])
        assert d == pytest.approx(np.linalg.norm(bvh["offsets"][i]), rel=1e-9, abs=1e-12)
    ends = [(i, n) for i, n in enumerate(names) if bvh["end_sites"][i]]
    assert ends
    for i, n in ends:
        d = np.linalg.norm(P[cal.keypoint_index([n + "_end"])[0]] - P[cal.keypoint_index([n])[0]])
        assert d == pytest.approx(np.linalg.norm(bvh["end_sites"][i][0]), rel=1e-9)


_ARM_URDF = """<robot name="arm">
  <link name="base"/><link name="upper"/><link name="fore"/><link name="tool"/>
  <joint name="shoulder" type="continuous"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0.3" rpy="0 0 0"/><axis xyz="0 0 1"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/>
    <origin xyz="0.1 0 0.4" rpy="0.2 0 0"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="tool_mount" type="fixed"><parent link="fore"/><child link="tool"/>
    <origin xyz="0 0.05 0.35" rpy="0 0.3 0"/></joint>
</robot>"""


def test_a_urdf_with_a_continuous_joint_and_a_fixed_frame():
    """Joints Pinocchio models with nq = 2 (continuous) take the per-frame path; the fixed
    tool mount is a segment of its own."""
    from pinrecon.figure import Keypoint

    kps = [Keypoint("elbow", "fore"), Keypoint("tool", "tool"), Keypoint("tip", "tool", (0.0, 0.0, 0.1))]
    fig = pr.Figure.from_urdf_string(_ARM_URDF, kps, root="fixed")
    props = Proportions.bones(fig)
    assert {s.name: s.kind for s in props.segments} == {
        "shoulder": "joint", "elbow": "joint", "tool_mount": "fixed", "tool.keypoints": "keypoints",
    }
    Q = np.stack([fig.random_configuration(s) for s in (1, 2)])
    theta = np.array([0.1, -0.2, 0.15, 0.3])[: props.n]
    p, J, dp = props.kinematics(theta, Q)
    eps = 1e-6
    fd = np.stack([
        (props.calibrated_figure(theta + eps * e).keypoints(Q) - props.calibrated_figure(theta - eps * e).keypoints(Q))
        / (2 * eps)
        for e in np.eye(props.n)
    ], -1)
    assert np.abs(dp - fd).max() <= 1e-6 * np.abs(dp).max()
    p_ref, J_ref = props.calibrated_figure(theta).keypoint_jacobians(Q)
    np.testing.assert_allclose(p, p_ref, atol=1e-12)
    np.testing.assert_allclose(J, J_ref, atol=1e-12)


def test_no_groups_is_the_figure_as_given():
    """A Proportions with no group (nothing to scale) gives the figure's own keypoints and
    an empty derivative (was an IndexError)."""
    fig = pr.Figure.human()
    prop = Proportions(fig, groups={})
    q = np.stack([fig.neutral(), fig.random_configuration(np.random.default_rng(3))])
    assert prop.n == 0
    np.testing.assert_array_equal(prop.keypoints(np.zeros(0), q), fig.keypoints(q))
    P, Jw, dP = prop.world_kinematics(np.zeros(0), q)
    np.testing.assert_allclose(P, fig.keypoints(q), atol=1e-12)
    assert dP.shape == (2, fig.K, 3, 0)
