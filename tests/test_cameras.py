"""Cameras: projections against hand-written formulas, Jacobians against finite
differences, JSON round trips, look-at axes, and a real calibrated camera (ASPset-510).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import DATA
from scipy.spatial.transform import Rotation

from pinrecon import InputError, Orthographic, Perspective, load_camera
from pinrecon.cameras import camera_from_dict, look_at_rotation

ASPSET = DATA / "aspset510_04ac-0026-right_frame.json"


def random_rotation(seed):
    return Rotation.random(random_state=seed).as_matrix()


def random_points(seed, n=20):
    """World points in front of the cameras below (camera z > 1 m)."""
    return np.random.default_rng(seed).uniform(-1.0, 1.0, size=(n, 3))


def ortho(seed=0):
    return Orthographic(random_rotation(seed), 350.0, (640.0, 360.0))


def persp(seed=0):
    R = random_rotation(seed)
    K = np.array([[1100.0, 0.5, 950.0], [0.0, 1050.0, 530.0], [0.0, 0.0, 1.0]])
    return Perspective(K, R, np.array([0.1, -0.2, 4.0]))


def fd_jacobian(camera, X, eps=1e-6):
    """(n, 2, 3) by central differences."""
    J = np.empty(X.shape[:-1] + (2, 3))
    for i in range(3):
        d = np.zeros(3)
        d[i] = eps
        J[..., i] = (camera.project(X + d) - camera.project(X - d)) / (2 * eps)
    return J


# ---------------------------------------------------------------- projections
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_orthographic_projection_formula(seed):
    cam = ortho(seed)
    X = random_points(seed)
    expected = np.array([350.0 * (cam.R @ x)[:2] + [640.0, 360.0] for x in X])
    np.testing.assert_allclose(cam.project(X), expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(cam.depth(X), [(cam.R @ x)[2] for x in X], atol=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_perspective_projection_formula(seed):
    cam = persp(seed)
    X = random_points(seed)
    expected = []
    for x in X:
        w = cam.K @ (cam.R @ x + cam.t)
        expected.append(w[:2] / w[2])
    np.testing.assert_allclose(cam.project(X), np.array(expected), rtol=0, atol=1e-9)
    np.testing.assert_allclose(cam.depth(X), [(cam.R @ x + cam.t)[2] for x in X], atol=1e-12)


def test_projection_keeps_leading_shape():
    X = random_points(3, 12).reshape(3, 4, 3)
    for cam in (ortho(), persp()):
        uv, J = cam.project_with_jacobian(X)
        assert uv.shape == (3, 4, 2) and J.shape == (3, 4, 2, 3)
        np.testing.assert_allclose(uv.reshape(12, 2), cam.project(X.reshape(12, 3)), atol=1e-12)


# ---------------------------------------------------------------- Jacobians
@pytest.mark.parametrize("make", [ortho, persp], ids=["orthographic", "perspective"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_camera_jacobian_matches_finite_differences(make, seed):
    cam = make(seed)
    X = random_points(seed + 10)
    J = cam.jacobian(X)
    num = fd_jacobian(cam, X)
    assert np.abs(J - num).max() / np.abs(num).max() < 1e-6


def test_orthographic_jacobian_is_scaled_rotation_rows():
    cam = ortho(4)
    np.testing.assert_array_equal(cam.jacobian(np.zeros((2, 3)))[1], 350.0 * cam.R[:2])


def test_orthographic_backproject_inverts_project():
    cam = ortho(5)
    X = random_points(5)
    back = cam.backproject(cam.project(X), cam.depth(X))
    np.testing.assert_allclose(back, X, atol=1e-12)


# ---------------------------------------------------------------- look-at
def test_look_at_rotation_axes():
    """Looking along +z with +y up: camera x is world -x (right), y is world -y (down)."""
    R = look_at_rotation([0.0, 0.0, 1.0], [0.0, 1.0, 0.0])
    np.testing.assert_allclose(R, np.diag([-1.0, -1.0, 1.0]), atol=1e-15)


@pytest.mark.parametrize(
    "forward, up",
    [
        ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        ([1.0, -0.5, 2.0], [0.0, 1.0, 0.0]),
        ([0.0, 1.0, 0.0], [0.0, 0.0, 1.0]),
    ],
)
def test_look_at_rotation_is_right_handed_x_right_y_down_z_forward(forward, up):
    R = look_at_rotation(forward, up)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    f = np.asarray(forward) / np.linalg.norm(forward)
    np.testing.assert_allclose(R[2], f, atol=1e-12)  # z forward
    assert R[1] @ np.asarray(up) < 0  # y down
    assert R[1] @ f == pytest.approx(0.0, abs=1e-12)
    right = np.cross(f, up)  # forward x up points to the viewer's right
    assert R[0] @ right > 0


def test_perspective_look_at_projects_target_to_centre_and_up_to_smaller_v():
    cam = Perspective.look_at([3.0, 1.0, 4.0], [0.0, 1.0, 0.0], f_px=800.0, center=(320.0, 240.0))
    np.testing.assert_allclose(cam.project(np.array([0.0, 1.0, 0.0])), [320.0, 240.0], atol=1e-9)
    above = cam.project(np.array([0.0, 1.5, 0.0]))
    assert above[1] < 240.0 and above[0] == pytest.approx(320.0)
    assert cam.depth(np.array([0.0, 1.0, 0.0])) == pytest.approx(5.0)


def test_look_at_rejects_up_parallel_to_forward():
    with pytest.raises(ValueError, match="parallel"):
        look_at_rotation([0.0, 1.0, 0.0], [0.0, 2.0, 0.0])


# ---------------------------------------------------------------- JSON
@pytest.mark.parametrize("make", [ortho, persp], ids=["orthographic", "perspective"])
def test_camera_json_round_trip(make, tmp_path):
    cam = make(7)
    path = tmp_path / "camera.json"
    cam.save(path)
    back = load_camera(path)
    assert type(back) is type(cam)
    assert json.loads(path.read_text())["model"] == cam.model
    X = random_points(7)
    np.testing.assert_array_equal(back.project(X), cam.project(X))
    assert back.to_dict() == cam.to_dict()


def test_orthographic_center_defaults_to_zero():
    cam = camera_from_dict({"model": "orthographic", "R": np.eye(3).tolist(), "scale": 2.0})
    np.testing.assert_array_equal(cam.project(np.array([1.0, 2.0, 3.0])), [2.0, 4.0])


# ---------------------------------------------------------------- real calibration
def aspset_camera(units="mm"):
    d = json.loads(ASPSET.read_text())
    K = np.array(d["intrinsic_matrix_3x4"])[:, :3]
    E = np.array(d["extrinsic_matrix_4x4_world_to_camera"])
    t = E[:3, 3] / (1000.0 if units == "m" else 1.0)
    return d, Perspective(K, E[:3, :3], t)


def test_aspset_camera_reproduces_the_datasets_2d_points():
    d, cam = aspset_camera("mm")
    uv = cam.project(np.array(d["joints_3d_world_mm"]))
    expected = np.array(d["joints_2d_px"])
    assert expected.shape == (17, 2)
    np.testing.assert_allclose(uv, expected, rtol=0, atol=1e-6)
    w, h = d["image_size"]
    assert np.all((uv >= 0) & (uv <= [w, h]))


def test_aspset_camera_in_metres_gives_same_pixels():
    d, cam = aspset_camera("m")
    p_world_m = np.array(d["joints_3d_world_mm"]) / 1000.0
    np.testing.assert_allclose(
        cam.project(p_world_m), np.array(d["joints_2d_px"]), rtol=0, atol=1e-6
    )
    depth_m = cam.depth(p_world_m)  # the subject stands about 20 m in front of this camera
    assert np.all((depth_m > 15) & (depth_m < 25))


def test_aspset_camera_json_round_trip_and_jacobian(tmp_path):
    d, cam = aspset_camera("m")
    path = tmp_path / "aspset_camera.json"
    cam.save(path)
    back = load_camera(path)
    X = np.array(d["joints_3d_world_mm"]) / 1000.0
    np.testing.assert_allclose(back.project(X), np.array(d["joints_2d_px"]), atol=1e-6)
    J = back.jacobian(X)
    num = fd_jacobian(back, X)
    assert np.abs(J - num).max() / np.abs(num).max() < 1e-6


# ---------------------------------------------------------------- validation
@pytest.mark.parametrize(
    "R, what",
    [
        (np.diag([1.0, 1.0, -1.0]), "det = -1.000000"),
        (np.diag([1.0, 1.0, 1.01]), "|R R^T - I|max = 2.01e-02"),
    ],
    ids=["reflection", "non-orthonormal"],
)
def test_constructor_rejects_non_rotation(R, what):
    with pytest.raises(InputError) as exc:
        Orthographic(R, 100.0)
    assert exc.value.field == "R" and what in str(exc.value)


@pytest.mark.parametrize("bad_scale", [0.0, -3.0, float("nan")])
def test_orthographic_rejects_bad_scale(bad_scale):
    with pytest.raises(InputError, match="field 'scale': must be a positive number"):
        Orthographic(np.eye(3), bad_scale)


def test_perspective_rejects_bad_intrinsics():
    K = np.array([[1000.0, 0, 5], [0, -1000.0, 5], [0, 0, 1]])
    with pytest.raises(
        InputError, match="field 'K': must be upper triangular with positive focal lengths"
    ):
        Perspective(K, np.eye(3), np.zeros(3))
