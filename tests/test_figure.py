"""Figure: keypoint Jacobians, Lie-group operations, limits, editing, keypoint maps.

Ground truth: central finite differences taken on the manifold with ``pin.integrate``,
Pinocchio's own frame Jacobians, the URDF's numbers, and the BVH file read by the
independent ``tests/bvh_reference.py``.
"""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest
from conftest import CMU_UNIT_M, REPO, WALK, data_path

from pinrecon import Figure, InputError, Keypoint, UnknownNameError, load_keypoint_map

WALK_BVH = data_path(WALK)

EPS = 1e-6
SEEDS = [0, 1, 2]


def fd_keypoint_jacobian(fig, q, eps=EPS):
    """d p / d v by central differences on the manifold: (K, 3, nv)."""
    J = np.empty((fig.K, 3, fig.nv))
    for i in range(fig.nv):
        dv = np.zeros(fig.nv)
        dv[i] = eps
        plus = fig.keypoints(pin.integrate(fig.model, q, dv))
        minus = fig.keypoints(pin.integrate(fig.model, q, -dv))
        J[:, :, i] = (plus - minus) / (2 * eps)
    return J


def rel_err(A, B):
    return np.abs(A - B).max() / np.abs(B).max()


@pytest.fixture(scope="module")
def walk_figure():
    return Figure.from_bvh(WALK_BVH, CMU_UNIT_M)


@pytest.fixture(params=["human", "human_joints", "walk_figure"])
def any_figure(request):
    return request.getfixturevalue(request.param)


# ---------------------------------------------------------------- keypoint Jacobians
@pytest.mark.parametrize("seed", SEEDS)
def test_keypoint_jacobian_matches_manifold_finite_differences(any_figure, seed):
    fig = any_figure
    q = fig.random_configuration(seed)
    p, J = fig.keypoint_jacobians(q)
    assert J.shape == (fig.K, 3, fig.nv)
    np.testing.assert_allclose(p, fig.keypoints(q), rtol=0, atol=1e-12)
    assert rel_err(J, fd_keypoint_jacobian(fig, q)) < 1e-6


def test_keypoint_jacobian_trajectory_form_matches_finite_differences(any_figure):
    fig = any_figure
    Q = np.stack([fig.random_configuration(s) for s in (10, 11, 12)])
    P, J = fig.keypoint_jacobians(Q)
    assert P.shape == (3, fig.K, 3) and J.shape == (3, fig.K, 3, fig.nv)
    np.testing.assert_allclose(P, fig.keypoints(Q), rtol=0, atol=1e-12)
    for t in range(3):
        assert rel_err(J[t], fd_keypoint_jacobian(fig, Q[t])) < 1e-6


@pytest.mark.parametrize("seed", SEEDS)
def test_keypoint_jacobian_equals_pinocchio_frame_jacobian_with_offset_term(any_figure, seed):
    """J_p = J_lin - [R_f offset]x J_ang with Pinocchio's LOCAL_WORLD_ALIGNED frame Jacobian."""
    fig = any_figure
    q = fig.random_configuration(seed)
    _, J = fig.keypoint_jacobians(q)
    model, data = fig.model, fig.model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    assert any(
        np.linalg.norm(k.offset) > 0 for k in fig.keypoints_def
    )  # face points, toes, end sites
    for k, kp in enumerate(fig.keypoints_def):
        fid = model.getFrameId(kp.frame)
        J_frame = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        r_world = data.oMf[fid].rotation @ np.asarray(kp.offset)
        expected = J_frame[:3] - pin.skew(r_world) @ J_frame[3:]
        np.testing.assert_allclose(J[k], expected, rtol=0, atol=1e-12, err_msg=kp.name)


def test_keypoint_jacobian_root_block_is_local_twist(human):
    """The root's 6 columns: a local twist (v, w) moves p by R v + (R w) x (p - x_root)."""
    q = human.random_configuration(5)
    p, J = human.keypoint_jacobians(q)
    R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
    for k in range(human.K):
        np.testing.assert_allclose(J[k, :, :3], R, atol=1e-12)
        np.testing.assert_allclose(J[k, :, 3:6], -pin.skew(p[k] - q[:3]) @ R, atol=1e-12)


# ---------------------------------------------------------------- sizes and limits
def test_human_sizes():
    fig = Figure.human()
    assert (fig.nq, fig.nv, fig.model.njoints, len(fig.joint_names)) == (43, 42, 38, 37)
    assert fig.K == 17 and fig.floating and fig.root_v == slice(0, 6)
    joints = Figure.human("joints")
    assert joints.K == 21 and joints.nv == 42


def test_human_fixed_root():
    fig = Figure.human(root="fixed")
    assert (fig.nq, fig.nv, fig.floating, fig.root_v) == (36, 36, False, slice(0, 0))
    assert "root_joint" not in fig.joint_names
    np.testing.assert_array_equal(fig.neutral(), np.zeros(36))


def test_joint_limits_per_tangent_index(human):
    names = human.tangent_names
    assert names[:6] == [f"root_joint.{c}" for c in ("vx", "vy", "vz", "wx", "wy", "wz")]
    assert np.all(np.isneginf(human.lower_v[:6])) and np.all(np.isposinf(human.upper_v[:6]))
    assert not human.limited_v[:6].any() and human.limited_v[6:].all()
    # anatomical limits over the URDF's (docs/limits.md): knee flexion 0-150 deg (one way),
    # hip abduction 55 / adduction 35 deg (published ranges widened by about 10 deg)
    knee = names.index("left_knee_Z")
    np.testing.assert_allclose((human.lower_v[knee], human.upper_v[knee]), np.radians([0.0, 150.0]), rtol=0, atol=1e-12)
    hip = names.index("left_hip_X")
    np.testing.assert_allclose((human.lower_v[hip], human.upper_v[hip]), np.radians([-35.0, 55.0]), rtol=0, atol=1e-12)
    assert human.joint_slices("left_knee_Z") == (slice(10, 11), slice(9, 10)) and knee == 9


def test_neutral(human):
    q = human.neutral()
    expected = np.zeros(43)
    expected[6] = 1.0  # identity quaternion (x, y, z, w)
    np.testing.assert_array_equal(q, expected)


@pytest.mark.parametrize("seed", range(5))
def test_random_configuration_inside_limits(human, seed):
    q = human.random_configuration(seed)
    assert np.isclose(np.linalg.norm(q[3:7]), 1.0)
    assert np.all(np.abs(q[:3]) <= 1.0)
    v = human.difference(human.neutral(), q)[6:]  # 1-dof joints: tangent = joint value
    np.testing.assert_allclose(v, q[7:], atol=1e-12)
    assert np.all(v >= human.lower_v[6:]) and np.all(v <= human.upper_v[6:])


def test_random_configuration_is_seeded(human):
    np.testing.assert_array_equal(human.random_configuration(3), human.random_configuration(3))
    assert np.abs(human.random_configuration(3) - human.random_configuration(4)).max() > 0.1


def test_clamp(human):
    q = human.neutral()
    q[7:] = 10.0  # every 1-dof joint above its upper limit
    knee_q = human.joint_slices("left_knee_Z")[0].start
    q[knee_q] = -2.0
    clamped = human.clamp(q)
    np.testing.assert_array_equal(clamped[7:knee_q], human.upper_v[6 : knee_q - 1])
    assert clamped[knee_q] == 0.0
    np.testing.assert_array_equal(clamped[:7], q[:7])  # root untouched
    with_margin = human.clamp(q, margin=0.1)
    assert with_margin[knee_q] == pytest.approx(0.1)
    Q = human.clamp(np.stack([q, q]))
    np.testing.assert_array_equal(Q[1], clamped)


# ---------------------------------------------------------------- Lie group
@pytest.mark.parametrize("seed", SEEDS)
def test_difference_inverts_integrate(human, seed):
    rng = np.random.default_rng(seed)
    q = human.random_configuration(seed)
    v = rng.normal(scale=0.3, size=human.nv)
    np.testing.assert_allclose(human.difference(q, human.integrate(q, v)), v, atol=1e-10)
    # trajectory forms
    Q = np.stack([q, human.random_configuration(seed + 10)])
    V = rng.normal(scale=0.3, size=(2, human.nv))
    np.testing.assert_allclose(human.difference(Q, human.integrate(Q, V)), V, atol=1e-10)


def test_integrate_root_is_local_twist(human):
    """q (+) v moves the root by R v_lin (local twist), not by v_lin."""
    q = human.random_configuration(7)
    v = np.zeros(human.nv)
    v[:3] = [0.1, -0.2, 0.3]
    R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
    np.testing.assert_allclose(human.integrate(q, v)[:3], q[:3] + R @ v[:3], atol=1e-12)


@pytest.mark.parametrize("seed", SEEDS)
def test_d_difference_matches_manifold_finite_differences(human, seed):
    q0 = human.random_configuration(seed)
    q1 = human.random_configuration(seed + 100)
    J0, J1 = human.d_difference(q0, q1)
    num0 = np.empty((human.nv, human.nv))
    num1 = np.empty((human.nv, human.nv))
    for i in range(human.nv):
        dv = np.zeros(human.nv)
        dv[i] = EPS
        num0[:, i] = (
            human.difference(human.integrate(q0, dv), q1)
            - human.difference(human.integrate(q0, -dv), q1)
        ) / (2 * EPS)
        num1[:, i] = (
            human.difference(q0, human.integrate(q1, dv))
            - human.difference(q0, human.integrate(q1, -dv))
        ) / (2 * EPS)
    assert rel_err(J0, num0) < 1e-6
    assert rel_err(J1, num1) < 1e-6


def test_interpolate_midpoint(human):
    q0, q1 = human.random_configuration(1), human.random_configuration(2)
    mid = human.interpolate(q0, q1, 0.5)
    np.testing.assert_allclose(
        human.difference(q0, mid), 0.5 * human.difference(q0, q1), atol=1e-10
    )


def test_normalize_restores_unit_quaternion(human):
    q = human.random_configuration(0)
    q[3:7] *= 1.5
    assert np.linalg.norm(human.normalize(q)[3:7]) == pytest.approx(1.0)
    assert np.linalg.norm(human.normalize(np.stack([q, q]))[1, 3:7]) == pytest.approx(1.0)


# ---------------------------------------------------------------- structure
def test_support_mask(human):
    names = human.tangent_names
    root = {"root_joint." + c for c in ("vx", "vy", "vz", "wx", "wy", "wz")}
    # the knee point lies on the axes of left_hip_Y (along the thigh) and left_knee_Z
    knee = human.support_mask(["left_knee"])
    assert {n for n, m in zip(names, knee) if m} == root | {"left_hip_Z", "left_hip_X"}
    ankle = human.support_mask(["left_ankle"])
    assert {n for n, m in zip(names, ankle) if m} == root | {
        "left_hip_Z",
        "left_hip_X",
        "left_hip_Y",
        "left_knee_Z",
    }
    assert not human.support_mask([]).any()


def test_coincident_keypoints_on_bvh_figure(walk_figure):
    groups = walk_figure.coincident_keypoints()
    assert ["Hips", "LHipJoint", "RHipJoint", "LowerBack"] in groups
    assert ["Spine1", "Neck", "LeftShoulder", "RightShoulder"] in groups
    assert ["LeftHand", "LeftFingerBase", "LThumb"] in groups
    assert ["LeftUpLeg"] in groups
    distinct = walk_figure.distinct_keypoint_names
    assert len(distinct) == len(groups) == 28
    assert "Hips" in distinct and "LHipJoint" not in distinct and "Neck" not in distinct


def test_keypoint_index_unknown_name_lists_valid(human):
    with pytest.raises(UnknownNameError) as exc:
        human.keypoint_index(["nose", "tail"])
    assert "unknown keypoint name(s) 'tail'" in str(exc.value)
    assert "left_ankle" in str(exc.value)


# ---------------------------------------------------------------- editing and saving
def test_scaled_knee_origin_scales_thigh_length(human):
    left = Figure.human().rescaled({"left_knee_Z": 1.5})
    for seed in SEEDS:
        q = human.random_configuration(seed)
        P0, P1 = human.keypoints(q), left.keypoints(q)
        idx = human.keypoint_index(["left_hip", "left_knee", "right_hip", "right_knee"])
        thigh0 = np.linalg.norm(P0[idx[0]] - P0[idx[1]])
        thigh1 = np.linalg.norm(P1[idx[0]] - P1[idx[1]])
        assert thigh0 == pytest.approx(0.439, abs=1e-9)  # URDF: left_knee_Z origin xyz="0 -0.439 0"
        assert thigh1 == pytest.approx(1.5 * 0.439, abs=1e-9)
        assert np.linalg.norm(P1[idx[2]] - P1[idx[3]]) == pytest.approx(thigh0, abs=1e-9)
    np.testing.assert_array_equal(left.lower_v, human.lower_v)


def test_uniform_rescale_scales_every_keypoint(human):
    big = human.rescaled(2.0)
    q = human.neutral()
    np.testing.assert_allclose(big.keypoints(q), 2.0 * human.keypoints(q), atol=1e-12)


def test_scaled_urdf_unknown_joint_lists_valid_names(human):
    with pytest.raises(UnknownNameError) as exc:
        human.scaled_urdf({"left_knee": 2.0})
    assert "'left_knee'" in str(exc.value) and "left_knee_Z" in str(exc.value)


def test_save_urdf_and_reload_gives_same_keypoints(human, tmp_path):
    fig = human.rescaled({"left_knee_Z": 1.2})
    path = tmp_path / "human_scaled.urdf"
    fig.save_urdf(path)
    back = Figure.from_urdf(path, fig.keypoints_def)
    assert (back.nq, back.nv) == (fig.nq, fig.nv)
    np.testing.assert_array_equal(back.lower_v, fig.lower_v)
    for seed in SEEDS:
        q = fig.random_configuration(seed)
        np.testing.assert_allclose(back.keypoints(q), fig.keypoints(q), atol=1e-12)


def test_save_urdf_of_bvh_figure_and_reload(walk_figure, tmp_path):
    assert isinstance(walk_figure.urdf_xml, str)
    path = tmp_path / "walk.urdf"
    walk_figure.save_urdf(path)
    back = Figure.from_urdf(path, walk_figure.keypoints_def)
    assert (back.nq, back.nv) == (walk_figure.nq, walk_figure.nv)
    q = walk_figure.random_configuration(4)
    np.testing.assert_allclose(back.keypoints(q), walk_figure.keypoints(q), atol=1e-12)
    assert np.all(back.upper_v[6:] == pytest.approx(4 * np.pi))  # the written wide limits


TWO_LINK_URDF = """<robot name="arm">
  <link name="base"/><link name="upper"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0.5"/><axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="2.0" effort="0" velocity="0"/>
  </joint>
</robot>
"""


def test_from_urdf_small_file(tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text(TWO_LINK_URDF)
    fig = Figure.from_urdf(path, root="fixed")
    assert (fig.nq, fig.nv, fig.keypoint_names) == (1, 1, ["shoulder"])
    assert (fig.lower_v[0], fig.upper_v[0]) == (-1.5, 2.0)
    np.testing.assert_allclose(fig.keypoints(np.array([0.3])), [[0.0, 0.0, 0.5]], atol=1e-15)


def test_from_urdf_with_xml_encoding_declaration(tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text('<?xml version="1.0" encoding="utf-8"?>\n' + TWO_LINK_URDF)
    fig = Figure.from_urdf(path, root="fixed")
    assert (fig.lower_v[0], fig.upper_v[0]) == (-1.5, 2.0)


# ---------------------------------------------------------------- keypoint maps
def test_load_keypoint_map(tmp_path):
    path = tmp_path / "map.json"
    path.write_text(
        json.dumps({"keypoints": {"a": {"frame": "f1", "offset": [1, 2, 3]}, "b": "f2"}})
    )
    assert load_keypoint_map(path) == [Keypoint("a", "f1", (1.0, 2.0, 3.0)), Keypoint("b", "f2")]


def test_keypoint_map_offset_moves_point(human):
    """A keypoint at an offset sits at oMf * offset."""
    q = human.random_configuration(3)
    nose = human.keypoints_def[human.keypoint_index(["nose"])[0]]
    M = human.frame_placement(q, nose.frame)
    expected = M.rotation @ np.array(nose.offset) + M.translation
    np.testing.assert_allclose(
        human.keypoints(q)[human.keypoint_index(["nose"])[0]], expected, atol=1e-12
    )


KEYPOINT_MAPS = sorted((REPO / "models" / "keypoints").glob("*.json"))
# the figure a map's "figure" field names -> how to build that figure with the map
FIGURE_BUILDERS = {"human": lambda path: Figure.human(str(path))}


@pytest.mark.parametrize("path", KEYPOINT_MAPS, ids=lambda p: p.name)
def test_every_bundled_keypoint_map_loads_on_its_figure(path):
    data = json.loads(path.read_text())
    assert data["figure"] in FIGURE_BUILDERS, f"add a builder for figure {data['figure']!r}"
    fig = FIGURE_BUILDERS[data["figure"]](path)
    kps = load_keypoint_map(path)
    assert fig.keypoint_names == list(data["keypoints"]) == [k.name for k in kps]
    for kp in kps:
        assert fig.model.existFrame(kp.frame), kp.frame
        assert np.linalg.norm(kp.offset) < 0.3  # offsets are centimetres, not a wrong unit
    P = fig.keypoints(fig.neutral())
    assert np.all(np.isfinite(P)) and len({tuple(np.round(p, 9)) for p in P}) == fig.K


def test_bundled_keypoint_maps_found():
    assert {"human_coco17.json", "human_joints.json"} <= {p.name for p in KEYPOINT_MAPS}


def test_with_keypoints_keeps_model_and_limits(human):
    fig = human.with_keypoints([Keypoint("head", "middle_head", (0.0, 0.2, 0.0))])
    assert fig.K == 1 and fig.nv == human.nv
    np.testing.assert_array_equal(fig.upper_v, human.upper_v)


def test_check_q_rejects_wrong_size(human):
    with pytest.raises(
        InputError, match=r"field 'q': expected configurations of size nq=43, got shape \(42,\)"
    ):
        human.keypoints(np.zeros(42))


def test_a_pickled_figure_is_the_same_figure_without_its_workspace(any_figure):
    """What ``pinrecon.stability(..., n_jobs=2)`` sends to another process: the same
    keypoints at random configurations, a fresh Pinocchio workspace of its own, and not the
    workspace's megabytes (94 MB for the CMU skeleton when it went along)."""
    import pickle

    blob = pickle.dumps(any_figure)
    back = pickle.loads(blob)
    assert len(blob) < 1_000_000, len(blob)
    assert back.data is not any_figure.data and back.keypoint_names == any_figure.keypoint_names
    for seed in range(3):
        q = any_figure.random_configuration(seed)
        np.testing.assert_array_equal(back.keypoints(q), any_figure.keypoints(q))
