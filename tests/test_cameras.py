"""Cameras: projections against hand-written formulas, Jacobians against finite
differences, JSON round trips, look-at axes, and a real calibrated camera (ASPset-510).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import data_file
from scipy.spatial.transform import Rotation

from pinrecon import InputError, Orthographic, Perspective, load_camera
from pinrecon.cameras import camera_from_dict, look_at_rotation



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
    d = json.loads(data_file("project-test-data/aspset510_04ac-0026-right_frame.json").read_text())
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


# ---------------------------------------------------------------- lens distortion
# Coefficients (k1, k2, p1, p2, k3) of real calibrations: OpenCV's tutorial camera
# (tests/data/calibration/opencv/out_camera_data.yml), OpenCV's ChArUco tutorial camera and a
# Pose2Sim phone camera (tests/data/calibration/pose2sim/Calib_scene.toml), plus tangential
# terms large enough to matter.
REAL_DISTORTIONS = {
    "opencv-tutorial": [-0.41802327018241026, 0.50715243805833121, 0.0, 0.0, -0.57843596847939704],
    "opencv-charuco": [0.12136925618707872, -1.0854664722560681, 1.1786843796668460e-04,
                       -4.6240686046485508e-04, 2.9542589406810080],
    "pose2sim-phone": [-0.05310342256182765, 0.1510044676505964, -0.00011989435671705446,
                       0.0006503403122568441, 0.0],
    "tangential": [-0.28, 0.09, 2.5e-3, -1.7e-3, -0.02],
}


def opencv_projection(K, R, t, dist, X):
    """OpenCV's pinhole + distortion model, written from the calib3d documentation, one
    point at a time: x' = x/z, y' = y/z, r^2 = x'^2 + y'^2,
    x'' = x'(1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x'y' + p2 (r^2 + 2 x'^2),
    y'' = y'(1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y'^2) + 2 p2 x'y',
    u = fx x'' + cx, v = fy y'' + cy (OpenCV has no skew; with one, u gets + s y'')."""
    k1, k2, p1, p2, k3 = dist
    out = []
    for p in X:
        x, y, z = R @ p + t
        xp, yp = x / z, y / z
        r2 = xp * xp + yp * yp
        radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
        xpp = xp * radial + 2 * p1 * xp * yp + p2 * (r2 + 2 * xp * xp)
        ypp = yp * radial + p1 * (r2 + 2 * yp * yp) + 2 * p2 * xp * yp
        out.append([K[0, 0] * xpp + K[0, 1] * ypp + K[0, 2], K[1, 1] * ypp + K[1, 2]])
    return np.array(out)


def distorted_camera(seed, dist, skew=0.0):
    K = np.array([[1100.0, skew, 950.0], [0.0, 1050.0, 530.0], [0.0, 0.0, 1.0]])
    return Perspective(K, random_rotation(seed), np.array([0.1, -0.2, 4.0]), dist)


def points_in_view(cam, seed, n=40, half_width=0.55):
    """World points whose normalised image coordinates lie in [-half_width, half_width]^2
    (about a 60 degree field of view) at depths 1.5 to 6 m."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-half_width, half_width, size=(n, 2))
    z = rng.uniform(1.5, 6.0, size=n)
    x_cam = np.column_stack([xy * z[:, None], z])
    return (x_cam - cam.t) @ cam.R  # R^T (x_cam - t), row-wise


@pytest.mark.parametrize("name", sorted(REAL_DISTORTIONS))
@pytest.mark.parametrize("skew", [0.0, 0.7])
def test_distorted_projection_matches_opencv_definition(name, skew):
    cam = distorted_camera(3, REAL_DISTORTIONS[name], skew)
    X = points_in_view(cam, 4)
    expected = opencv_projection(cam.K, cam.R, cam.t, REAL_DISTORTIONS[name], X)
    np.testing.assert_allclose(cam.project(X), expected, rtol=0, atol=1e-9)
    uv, _ = cam.project_with_jacobian(X)
    np.testing.assert_allclose(uv, expected, rtol=0, atol=1e-9)


@pytest.mark.parametrize("name", sorted(REAL_DISTORTIONS))
@pytest.mark.parametrize("seed", [0, 1])
def test_distorted_jacobian_matches_finite_differences(name, seed):
    cam = distorted_camera(seed, REAL_DISTORTIONS[name], skew=0.4)
    X = points_in_view(cam, seed + 20)
    J = cam.jacobian(X)
    num = fd_jacobian(cam, X)
    assert np.abs(J - num).max() / np.abs(num).max() < 1e-6
    # the distortion changes the Jacobian: it is not the pinhole one
    pinhole = Perspective(cam.K, cam.R, cam.t)
    assert np.abs(pinhole.jacobian(X) - J).max() / np.abs(J).max() > 1e-3


def test_distortion_default_is_zero_and_changes_nothing():
    cam = persp(5)
    assert cam.dist.shape == (5,) and not cam.dist.any() and not cam.has_distortion
    explicit = Perspective(cam.K, cam.R, cam.t, [0.0, 0.0, 0.0, 0.0, 0.0])
    X = random_points(5)
    np.testing.assert_array_equal(explicit.project(X), cam.project(X))
    np.testing.assert_array_equal(explicit.jacobian(X), cam.jacobian(X))
    assert "dist" not in cam.to_dict()


def test_distortion_leaves_the_principal_ray_alone():
    cam = distorted_camera(6, REAL_DISTORTIONS["tangential"])
    on_axis = cam.R.T @ (np.array([0.0, 0.0, 3.0]) - cam.t)
    np.testing.assert_allclose(cam.project(on_axis), [950.0, 530.0], atol=1e-9)


def test_four_coefficients_mean_k3_zero_and_long_opencv_vectors_with_zero_tail_are_accepted():
    d4 = distorted_camera(1, [-0.2, 0.05, 1e-3, 2e-3])
    d14 = distorted_camera(1, [-0.2, 0.05, 1e-3, 2e-3, 0.0] + [0.0] * 9)
    np.testing.assert_array_equal(d4.dist, [-0.2, 0.05, 1e-3, 2e-3, 0.0])
    np.testing.assert_array_equal(d14.dist, d4.dist)


def test_distortion_json_round_trip(tmp_path):
    cam = distorted_camera(8, REAL_DISTORTIONS["opencv-charuco"], skew=0.3)
    path = tmp_path / "camera.json"
    cam.save(path)
    data = json.loads(path.read_text())
    assert data["dist"] == REAL_DISTORTIONS["opencv-charuco"]
    back = load_camera(path)
    np.testing.assert_array_equal(back.dist, cam.dist)
    X = points_in_view(cam, 8)
    np.testing.assert_array_equal(back.project(X), cam.project(X))
    assert back.to_dict() == cam.to_dict()


def test_camera_json_with_four_distortion_coefficients():
    data = persp(2).to_dict() | {"dist": [-0.1, 0.02, 0.0, 0.001]}
    cam = camera_from_dict(data)
    np.testing.assert_array_equal(cam.dist, [-0.1, 0.02, 0.0, 0.001, 0.0])


@pytest.mark.parametrize(
    "dist, message",
    [
        ([-0.1, float("nan"), 0.0, 0.0, 0.0], "k2 = nan"),
        ([-0.1, 0.0, float("inf"), 0.0], "p1 = inf"),
        ([0.1, 0.2, 0.3], "expected 4 or 5 distortion coefficients"),
        ([0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0], "k5 = 0.5"),
        ("barrel", "expected a list of numbers"),
    ],
    ids=["nan", "inf", "three", "rational", "text"],
)
def test_bad_distortion_is_an_input_error_naming_the_field(dist, message, tmp_path):
    data = persp(1).to_dict() | {"dist": dist}
    path = tmp_path / "cam.json"
    path.write_text(json.dumps(data, allow_nan=True))
    with pytest.raises(InputError) as exc:
        load_camera(path)
    assert exc.value.field == "dist" and exc.value.file == str(path)
    assert message in str(exc.value)


def test_normalized_inverts_the_distorted_projection():
    for name, dist in REAL_DISTORTIONS.items():
        cam = distorted_camera(9, dist, skew=0.5)
        X = points_in_view(cam, 9, n=200)
        x_cam = cam.camera_points(X)
        np.testing.assert_allclose(
            cam.normalized(cam.project(X)), x_cam[:, :2] / x_cam[:, 2:], rtol=0, atol=1e-10,
            err_msg=name,
        )


def test_look_at_takes_distortion():
    cam = Perspective.look_at([0.0, 1.0, 4.0], [0.0, 1.0, 0.0], dist=REAL_DISTORTIONS["tangential"])
    np.testing.assert_array_equal(cam.dist, REAL_DISTORTIONS["tangential"])
    np.testing.assert_allclose(cam.project(np.array([0.0, 1.0, 0.0])), [960.0, 540.0], atol=1e-9)


def test_distorted_projection_matches_cv2_project_points():
    """Skipped only when OpenCV is not installed (it is not a test dependency: the
    opencv-python-headless wheel is about 61 MB)."""
    cv2 = pytest.importorskip("cv2")
    for name, dist in REAL_DISTORTIONS.items():
        cam = distorted_camera(11, dist)  # OpenCV's camera matrix has no skew
        X = points_in_view(cam, 11, n=100)
        rvec = cv2.Rodrigues(cam.R)[0]
        uv_cv, jac_cv = cv2.projectPoints(X, rvec, cam.t, cam.K, np.asarray(dist, float))
        np.testing.assert_allclose(
            cam.project(X), uv_cv.reshape(-1, 2), rtol=0, atol=1e-9, err_msg=name
        )
        # cv2's Jacobian w.r.t. tvec is d uv / d x_cam; ours times R^T gives the same.
        d_uv_d_t = jac_cv[:, 3:6].reshape(-1, 2, 3)
        np.testing.assert_allclose(
            cam.jacobian(X) @ cam.R.T, d_uv_d_t, rtol=1e-7, atol=1e-7, err_msg=name
        )
