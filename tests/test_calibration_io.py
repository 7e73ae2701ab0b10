"""Calibration readers (pinrecon.io.calibration) on real files from Pose2Sim, Sports2D and
OpenCV (tests/data/SOURCES.md), checked against numbers computed here independently:
the files' own values read with the standard library, camera centres from a Rodrigues
formula written in this file, the Qualisys calibration Pose2Sim converted from, OpenCV's
own per-view reprojection errors and, when OpenCV is installed, cv2.FileStorage files.
"""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from conftest import REPO, data_dir

from pinrecon import InputError, UnknownNameError
from pinrecon.cameras import Perspective
from pinrecon.io.calibration import CalibratedCamera, load_camera, load_cameras
from pinrecon.io.calibration.opencv_storage import decode_matrices, parse_yaml

try:
    import tomllib
except ModuleNotFoundError:  # Python < 3.11
    import tomli as tomllib

CAL = data_dir("project-test-data/calibration")
QUALISYS_TOML = CAL / "pose2sim" / "Calib_qualisys.toml"
QUALISYS_QCA = CAL / "pose2sim" / "Calib.qca.txt"
SCENE_TOML = CAL / "pose2sim" / "Calib_scene.toml"
STATIC = CAL / "pose2sim" / "static_trial"
SPORTS2D_TOML = CAL / "sports2d" / "Calib_demo.toml"
OPENCV_TUTORIAL = CAL / "opencv" / "out_camera_data.yml"
OPENCV_CHARUCO = CAL / "opencv" / "tutorial_camera_charuco.yml"


def rodrigues(rvec):
    """R = I + sin(a) [k]x + (1 - cos(a)) [k]x^2 with a = |rvec|, k = rvec / a."""
    rvec = np.asarray(rvec, float)
    a = np.linalg.norm(rvec)
    if a == 0:
        return np.eye(3)
    kx, ky, kz = rvec / a
    Kx = np.array([[0.0, -kz, ky], [kz, 0.0, -kx], [-ky, kx, 0.0]])
    return np.eye(3) + np.sin(a) * Kx + (1 - np.cos(a)) * Kx @ Kx


def opencv_project(K, dist, R, t, X):
    """OpenCV's projection with distortion (k1, k2, p1, p2, k3), from its documentation."""
    k1, k2, p1, p2, k3 = (list(dist) + [0.0] * 5)[:5]
    x_cam = X @ R.T + t
    x, y = x_cam[:, 0] / x_cam[:, 2], x_cam[:, 1] / x_cam[:, 2]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.column_stack([K[0, 0] * xd + K[0, 1] * yd + K[0, 2], K[1, 1] * yd + K[1, 2]])


def centre(rvec, tvec):
    return -rodrigues(rvec).T @ np.asarray(tvec, float)


# ---------------------------------------------------------------- Pose2Sim TOML
def test_pose2sim_toml_reads_every_camera_exactly_as_written():
    raw = tomllib.loads(QUALISYS_TOML.read_text())
    cams = load_cameras(QUALISYS_TOML)
    assert [c.name for c in cams] == ["cam_01", "cam_02", "cam_03", "cam_04"]
    assert all(isinstance(c, CalibratedCamera) and c.source == "pose2sim-toml" for c in cams)
    for c in cams:
        table = raw[c.name]
        assert c.image_size == (1088, 1920) and c.has_pose
        np.testing.assert_array_equal(c.camera.K, table["matrix"])
        np.testing.assert_array_equal(c.camera.dist, table["distortions"] + [0.0])
        np.testing.assert_allclose(c.camera.R, rodrigues(table["rotation"]), rtol=0, atol=1e-14)
        np.testing.assert_array_equal(c.camera.t, table["translation"])
    # one camera's numbers typed from the file
    np.testing.assert_array_equal(
        cams[0].camera.K,
        [
            [1681.244873046875, 0.0, 532.97369384375],
            [0.0, 1681.075439453125, 948.137390140625],
            [0.0, 0.0, 1.0],
        ],
    )
    np.testing.assert_array_equal(
        cams[0].camera.dist, [-0.000721609375, 0.002187234375, 9.5e-06, 1.078125e-05, 0.0]
    )


def test_pose2sim_toml_camera_centres_are_the_qualisys_camera_positions():
    """Pose2Sim converted Calib.qca.txt (camera positions in mm) to Calib_qualisys.toml
    (world -> camera Rodrigues vector and translation in m): the centres -R^T t must be the
    Qualisys positions."""
    root = ET.parse(QUALISYS_QCA).getroot()
    qca = {
        cam.get("serial"): np.array([float(cam.find("transform").get(a)) for a in "xyz"]) / 1000.0
        for cam in root.iter("camera")
    }
    raw = tomllib.loads(QUALISYS_TOML.read_text())
    cams = load_cameras(QUALISYS_TOML)
    assert [c.name for c in cams] == list(qca)
    for c in cams:
        expected = qca[c.name]
        np.testing.assert_allclose(
            centre(raw[c.name]["rotation"], raw[c.name]["translation"]), expected, atol=1e-6
        )
        np.testing.assert_allclose(-c.camera.R.T @ c.camera.t, expected, atol=1e-6)
        # the world origin (the capture volume's centre) is in front and in the picture
        assert 2.5 < c.camera.depth(np.zeros(3)) < 5.0
        u, v = c.camera.project(np.zeros(3))
        assert 0 < u < 1088 and 0 < v < 1920


def test_two_independent_pose2sim_calibrations_of_the_same_cameras_agree():
    """Calib_scene.toml (clicked scene points) and Calib_qualisys.toml calibrate the same
    four phones: measured centre gaps 0.05 to 0.14 m, axis gaps 0.8 to 2.7 degrees."""
    scene = load_cameras(SCENE_TOML)
    assert [c.name for c in scene] == [
        "int_cam01_img",
        "int_cam02_img",
        "int_cam03_img",
        "int_cam04_img",
    ]
    for a, b in zip(load_cameras(QUALISYS_TOML), scene, strict=True):
        gap = np.linalg.norm(a.camera.R.T @ a.camera.t - b.camera.R.T @ b.camera.t)
        angle = np.degrees(np.arccos(np.clip(a.camera.R[2] @ b.camera.R[2], -1, 1)))
        assert gap < 0.2 and angle < 4.0
        assert abs(a.camera.K[0, 0] - b.camera.K[0, 0]) < 20.0


def read_static_trial():
    """Frame 1 of Pose2Sim's triangulated static trial (TRC, Y-up, converted back to the
    calibration's Z-up world) and frame 0 of its four BODY_25B OpenPose files."""
    rows = (STATIC / "S00_P00_T00_StaticTrial_0-12.trc").read_text().splitlines()
    names = rows[3].split("\t")[2::3]
    trc = np.array(rows[5].split("\t")[2 : 2 + 3 * len(names)], float).reshape(-1, 3)
    p_world = trc[:, [2, 0, 1]]  # Pose2Sim's zup2yup wrote (Y, Z, X)
    body25b = {
        "RHip": 12,
        "RKnee": 14,
        "RAnkle": 16,
        "RBigToe": 22,
        "RSmallToe": 23,
        "RHeel": 24,
        "LHip": 11,
        "LKnee": 13,
        "LAnkle": 15,
        "LBigToe": 19,
        "LSmallToe": 20,
        "LHeel": 21,
        "Neck": 17,
        "Head": 18,
        "Nose": 0,
        "RShoulder": 6,
        "RElbow": 8,
        "RWrist": 10,
        "LShoulder": 5,
        "LElbow": 7,
        "LWrist": 9,
    }
    idx = [body25b[n.strip()] for n in names]
    uv = []
    for k in range(1, 5):
        people = json.loads((STATIC / f"Static_cam_0{k}.00000.json").read_text())["people"]
        uv.append(np.array(people[0]["pose_keypoints_2d"]).reshape(-1, 3)[idx, :2])
    return p_world, uv


def test_pose2sim_static_trial_reprojects_through_the_calibration():
    """Pose2Sim's 3D markers, projected through the cameras read from the TOML, land on
    its 2D detections: measured mean errors 7.2 to 14.5 px per camera on a 1088 x 1920
    image (the triangulation and the calibration are not exactly consistent). Reading the
    pose the other way round (camera -> world) would miss by hundreds of pixels."""
    p_world, uv = read_static_trial()
    cams = load_cameras(QUALISYS_TOML)
    for cam, uv_obs in zip(cams, uv, strict=True):
        err = np.linalg.norm(cam.camera.project(p_world) - uv_obs, axis=1)
        assert err.mean() < 20.0 and err.max() < 40.0
        assert np.all(cam.camera.depth(p_world) > 1.0)
        inverted = Perspective(cam.camera.K, cam.camera.R.T, -cam.camera.R.T @ cam.camera.t)
        wrong = np.linalg.norm(inverted.project(p_world) - uv_obs, axis=1)
        assert np.median(wrong) > 200.0


def test_sports2d_single_camera_file():
    raw = tomllib.loads(SPORTS2D_TOML.read_text())["demo"]
    (cal,) = load_cameras(SPORTS2D_TOML)
    assert cal.name == "demo" and cal.image_size == (1768, 994)
    cam = load_camera(SPORTS2D_TOML)
    np.testing.assert_array_equal(cam.K, raw["matrix"])
    assert not cam.has_distortion
    # Sports2D puts the camera 10 m from the origin along +X, looking horizontally along -X
    # in its Z-up world, at the subject's height.
    C = centre(raw["rotation"], raw["translation"])
    np.testing.assert_allclose(-cam.R.T @ cam.t, C, atol=1e-12)
    np.testing.assert_allclose(C, [10.0, 3.5078116, 1.7126332], atol=1e-6)
    np.testing.assert_allclose(cam.R[2], [-1.0, 0.0, 0.0], atol=1e-12)


def test_load_camera_refuses_a_multi_camera_file_and_lists_the_names():
    with pytest.raises(InputError) as exc:
        load_camera(QUALISYS_TOML)
    assert "holds 4 cameras (cam_01, cam_02, cam_03, cam_04)" in str(exc.value)
    assert exc.value.file == str(QUALISYS_TOML)
    cam = load_camera(QUALISYS_TOML, "cam_03")
    np.testing.assert_array_equal(cam.K, load_cameras(QUALISYS_TOML)[2].camera.K)
    with pytest.raises(
        UnknownNameError, match="valid camera names are: cam_01, cam_02, cam_03, cam_04"
    ):
        load_camera(QUALISYS_TOML, "cam_9")


def test_translation_unit_scale():
    metres = load_cameras(QUALISYS_TOML)[0].camera
    mm = load_cameras(QUALISYS_TOML, metres_per_unit=0.001)[0].camera
    np.testing.assert_allclose(mm.t, metres.t / 1000.0, rtol=1e-15)
    np.testing.assert_array_equal(mm.R, metres.R)


# ---------------------------------------------------------------- OpenCV YAML
def test_opencv_tutorial_yaml_intrinsics_read_exactly():
    (cal,) = load_cameras(OPENCV_TUTORIAL)
    assert cal.name == "out_camera_data" and cal.source == "opencv-yaml"
    assert cal.image_size == (640, 480) and not cal.has_pose
    np.testing.assert_array_equal(
        cal.camera.K,
        [[6.5746697810243404e02, 0.0, 319.5], [0.0, 6.5746697810243404e02, 239.5], [0, 0, 1]],
    )
    np.testing.assert_array_equal(
        cal.camera.dist,
        [-4.1802327018241026e-01, 5.0715243805833121e-01, 0.0, 0.0, -5.7843596847939704e-01],
    )
    np.testing.assert_array_equal(cal.camera.R, np.eye(3))
    np.testing.assert_array_equal(cal.camera.t, np.zeros(3))


def test_opencv_tutorial_chessboard_reprojects_to_opencvs_own_errors():
    """The file stores, for 8 views of a 9 x 6 chessboard (50 mm squares), OpenCV's
    rvec / tvec, the detected corners, and the RMS reprojection error OpenCV computed. The
    camera read from the file, posed by each view's rvec / tvec, must give the same RMS."""
    doc = decode_matrices(parse_yaml(OPENCV_TUTORIAL.read_text()))
    extrinsics, corners = doc["Extrinsic_Parameters"], doc["Image_points"]
    assert extrinsics.shape == (8, 6) and corners.shape == (8, 54, 2)
    board = np.array([[50.0 * j, 50.0 * i, 0.0] for i in range(6) for j in range(9)])
    intr = load_camera(OPENCV_TUTORIAL)
    rms = []
    for view in range(8):
        rvec, tvec = extrinsics[view, :3], extrinsics[view, 3:]
        cam = Perspective(intr.K, rodrigues(rvec), tvec, intr.dist)
        uv = cam.project(board)
        np.testing.assert_allclose(
            uv, opencv_project(intr.K, intr.dist, rodrigues(rvec), tvec, board), atol=1e-9
        )
        rms.append(np.sqrt(np.mean(np.sum((uv - corners[view]) ** 2, axis=1))))
    np.testing.assert_allclose(rms, doc["Per_View_Reprojection_Errors"].ravel(), rtol=0, atol=1e-5)
    # without the (strong) distortion the same poses miss by pixels
    pinhole = Perspective(intr.K, rodrigues(extrinsics[0, :3]), extrinsics[0, 3:])
    assert np.sqrt(np.mean(np.sum((pinhole.project(board) - corners[0]) ** 2, axis=1))) > 2.0


def test_opencv_charuco_yaml_with_crlf_line_ends():
    assert b"\r\n" in OPENCV_CHARUCO.read_bytes()
    cam = load_camera(OPENCV_CHARUCO)
    np.testing.assert_array_equal(
        cam.K,
        [
            [4.5251072219637672e02, 0.0, 3.1770297317353277e02],
            [0.0, 4.5676707935146891e02, 2.7775155919135995e02],
            [0.0, 0.0, 1.0],
        ],
    )
    np.testing.assert_array_equal(
        cam.dist,
        [
            1.2136925618707872e-01,
            -1.0854664722560681e00,
            1.1786843796668460e-04,
            -4.6240686046485508e-04,
            2.9542589406810080e00,
        ],
    )
    assert load_cameras(OPENCV_CHARUCO)[0].image_size == (640, 480)


# ---------------------------------------------------------------- OpenCV-style JSON / YAML / XML
K_TEST = np.array([[1402.5, 0.0, 955.25], [0.0, 1398.75, 541.5], [0.0, 0.0, 1.0]])
DIST_TEST = [-0.2468, 0.0912, 0.0013, -0.0007, -0.0151]
RVEC_TEST = [0.31, -1.27, 0.22]
TVEC_TEST = [0.45, -0.9, 4.2]
X_TEST = np.array([[0.1, 0.2, 0.3], [-0.5, 1.0, 0.2], [0.4, -0.3, -0.6], [0.0, 1.6, 0.0]])


def check_test_camera(cal, name):
    assert cal.name == name and cal.has_pose and cal.image_size == (1920, 1080)
    np.testing.assert_array_equal(cal.camera.K, K_TEST)
    np.testing.assert_array_equal(cal.camera.dist, DIST_TEST)
    expected = opencv_project(K_TEST, DIST_TEST, rodrigues(RVEC_TEST), np.array(TVEC_TEST), X_TEST)
    np.testing.assert_allclose(cal.camera.project(X_TEST), expected, rtol=0, atol=1e-9)


def test_plain_opencv_style_json(tmp_path):
    path = tmp_path / "cam.json"
    path.write_text(
        json.dumps(
            {
                "K": K_TEST.tolist(),
                "dist": DIST_TEST,
                "rvec": RVEC_TEST,
                "tvec": TVEC_TEST,
                "image_size": [1920, 1080],
            }
        )
    )
    (cal,) = load_cameras(path)
    assert cal.source == "opencv-json"
    check_test_camera(cal, "cam")


def test_opencv_json_variants_flat_matrix_column_vectors_rotation_matrix(tmp_path):
    path = tmp_path / "calib.json"
    path.write_text(
        json.dumps(
            {
                "camera_name": "left",
                "cameraMatrix": K_TEST.ravel().tolist(),
                "distCoeffs": [DIST_TEST],
                "R": rodrigues(RVEC_TEST).tolist(),
                "T": [[v] for v in TVEC_TEST],
                "image_width": 1920,
                "image_height": 1080,
            }
        )
    )
    check_test_camera(load_cameras(path)[0], "left")


def test_several_cameras_in_json_yaml_and_mapping_forms(tmp_path):
    cam = {
        "camera_matrix": K_TEST.tolist(),
        "dist_coeffs": DIST_TEST,
        "rvec": RVEC_TEST,
        "tvec": TVEC_TEST,
        "size": [1920, 1080],
    }
    a = tmp_path / "list.json"
    a.write_text(json.dumps({"cameras": [cam | {"name": "c1"}, cam | {"name": "c2"}]}))
    b = tmp_path / "mapping.json"
    b.write_text(json.dumps({"cameras": {"c1": cam, "c2": cam}}))
    c = tmp_path / "top.json"
    c.write_text(json.dumps({"c1": cam, "c2": cam, "board": {"rows": 6}}))
    for path in (a, b, c):
        cals = load_cameras(path)
        assert [x.name for x in cals] == ["c1", "c2"]
        for x in cals:
            check_test_camera(x, x.name)


def ros_style_yaml():
    flat = ", ".join(repr(float(v)) for v in K_TEST.ravel())
    return f"""# a ROS camera_info-style file: plain YAML, matrices as rows / cols / data
image_width: 1920
image_height: 1080
camera_name: "side cam"
camera_matrix:
  rows: 3
  cols: 3
  data: [{flat}]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [{", ".join(map(repr, DIST_TEST))}]
rvec: [{", ".join(map(repr, RVEC_TEST))}]
tvec:
  - {TVEC_TEST[0]!r}
  - {TVEC_TEST[1]!r}
  - {TVEC_TEST[2]!r}
"""


def test_ros_style_plain_yaml(tmp_path):
    path = tmp_path / "side.yaml"
    path.write_text(ros_style_yaml())
    check_test_camera(load_cameras(path)[0], "side cam")


def test_opencv_filestorage_xml_and_json_hand_written(tmp_path):
    data = " ".join(repr(float(v)) for v in K_TEST.ravel())
    xml = tmp_path / "cam.xml"
    xml.write_text(f"""<?xml version="1.0"?>
<opencv_storage>
<image_width>1920</image_width>
<image_height>1080</image_height>
<camera_matrix type_id="opencv-matrix">
  <rows>3</rows><cols>3</cols><dt>d</dt>
  <data>{data}</data></camera_matrix>
<distortion_coefficients type_id="opencv-matrix">
  <rows>5</rows><cols>1</cols><dt>d</dt>
  <data>{" ".join(map(repr, DIST_TEST))}</data></distortion_coefficients>
<rvec type_id="opencv-matrix"><rows>3</rows><cols>1</cols><dt>d</dt>
  <data>{" ".join(map(repr, RVEC_TEST))}</data></rvec>
<tvec type_id="opencv-matrix"><rows>3</rows><cols>1</cols><dt>d</dt>
  <data>{" ".join(map(repr, TVEC_TEST))}</data></tvec>
</opencv_storage>
""")
    (cal,) = load_cameras(xml)
    assert cal.source == "opencv-xml"
    check_test_camera(cal, "cam")

    def node(rows, cols, values):
        return {
            "type_id": "opencv-matrix",
            "rows": rows,
            "cols": cols,
            "dt": "d",
            "data": list(values),
        }

    js = tmp_path / "cam.json"
    js.write_text(
        json.dumps(
            {
                "image_width": 1920,
                "image_height": 1080,
                "camera_matrix": node(3, 3, K_TEST.ravel()),
                "distortion_coefficients": node(1, 5, DIST_TEST),
                "rvec": node(3, 1, RVEC_TEST),
                "tvec": node(3, 1, TVEC_TEST),
            }
        )
    )
    check_test_camera(load_cameras(js)[0], "cam")


@pytest.mark.parametrize("suffix", [".yml", ".xml", ".json"])
def test_files_written_by_cv2_filestorage(suffix, tmp_path):
    """Skipped only when OpenCV is not installed (opencv-python-headless is a 61 MB wheel,
    not a test dependency)."""
    cv2 = pytest.importorskip("cv2")
    path = tmp_path / f"calib{suffix}"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 1920)
    fs.write("image_height", 1080)
    fs.write("camera_matrix", K_TEST)
    fs.write("distortion_coefficients", np.array(DIST_TEST).reshape(5, 1))
    fs.write("rvec", np.array(RVEC_TEST).reshape(3, 1))
    fs.write("tvec", np.array(TVEC_TEST).reshape(3, 1))
    fs.release()
    cal = load_cameras(path)[0]
    check_test_camera(cal, "calib")
    uv_cv, _ = cv2.projectPoints(
        X_TEST, np.array(RVEC_TEST), np.array(TVEC_TEST), K_TEST, np.array(DIST_TEST)
    )
    np.testing.assert_allclose(cal.camera.project(X_TEST), uv_cv.reshape(-1, 2), rtol=0, atol=1e-9)


def test_pinrecon_camera_json_through_load_cameras(tmp_path):
    cam = Perspective(K_TEST, rodrigues(RVEC_TEST), TVEC_TEST, DIST_TEST)
    path = tmp_path / "mine.json"
    cam.save(path)
    (cal,) = load_cameras(path)
    assert cal.name == "mine" and cal.source == "pinrecon-json" and cal.image_size is None
    np.testing.assert_array_equal(cal.camera.project(X_TEST), cam.project(X_TEST))


# ---------------------------------------------------------------- errors
def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


GOOD_TABLE = """[cam_a]
name = "cam_a"
size = [ 1920.0, 1080.0]
matrix = [ [ 1400.0, 0.0, 960.0], [ 0.0, 1400.0, 540.0], [ 0.0, 0.0, 1.0]]
distortions = [ -0.1, 0.01, 0.0, 0.0]
rotation = [ 0.1, 0.2, 0.3]
translation = [ 0.0, 0.0, 4.0]
fisheye = false
"""


@pytest.mark.parametrize(
    "text, field, message",
    [
        (
            GOOD_TABLE.replace("fisheye = false", "fisheye = true"),
            "cam_a.fisheye",
            "fisheye cameras are not supported",
        ),
        (
            GOOD_TABLE.replace("distortions = [ -0.1", "distortions = [ nan"),
            "cam_a.distortions",
            "k1 = nan",
        ),
        (
            GOOD_TABLE.replace("rotation = [ 0.1, 0.2, 0.3]", "rotation = [ 0.1, 0.2]"),
            "cam_a.rotation",
            "expected a Rodrigues vector",
        ),
        (GOOD_TABLE.replace("translation = [ 0.0, 0.0, 4.0]\n", ""), "cam_a", "lacks translation"),
        (
            GOOD_TABLE.replace("[ 0.0, 1400.0, 540.0]", "[ 5.0, 1400.0, 540.0]"),
            "cam_a.matrix",
            "must be upper triangular",
        ),
        (
            GOOD_TABLE.replace("size = [ 1920.0, 1080.0]", "size = [ 1920.0]"),
            "cam_a.size",
            "[width, height]",
        ),
        (GOOD_TABLE + GOOD_TABLE.replace("[cam_a]", "[cam_b]"), None, "repeated: cam_a"),
        ("[metadata]\nadjusted = false\n", None, "no camera table found"),
        ("[cam_a\nname = 1", None, "not valid TOML"),
    ],
    ids=["fisheye", "nan", "rotation", "missing", "K", "size", "duplicate", "empty", "syntax"],
)
def test_toml_errors_name_file_and_field(tmp_path, text, field, message):
    path = write(tmp_path, "calib.toml", text)
    with pytest.raises(InputError) as exc:
        load_cameras(path)
    assert exc.value.file == str(path) and exc.value.field == field
    assert message in str(exc.value)


def test_metadata_table_is_skipped(tmp_path):
    path = write(
        tmp_path, "calib.toml", GOOD_TABLE + "\n[metadata]\nadjusted = false\nerror = 0.0\n"
    )
    assert [c.name for c in load_cameras(path)] == ["cam_a"]


@pytest.mark.parametrize(
    "name, text, field, message",
    [
        (
            "a.yml",
            "%YAML:1.0\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
            "   data: [ 1., 0., 1., 0., 1., 1. ]\n",
            "camera_matrix",
            "expected rows x cols x channels = 3 x 3 x 1",
        ),
        (
            "b.yml",
            "K: [[1000, 0, 500], [0, 1000, 400], [0, 0, 1]]\ntvec: [0, 0, 1]\n",
            "tvec",
            "rvec / R is missing",
        ),
        (
            "c.yml",
            "K: [[1000, 0, 500], [0, 1000, 400], [0, 0, 1]]\ndistortion_model: equidistant\n",
            "distortion_model",
            "fisheye / wide-angle models are not supported",
        ),
        ("d.yml", "K: [[1000, 0, 500], [0, 1000, 400]\nD: [0, 0]\n", None, "line 1: unclosed"),
        ("e.yml", "K:\n  rows: 3\n    cols: 3\n", None, "line 3: unexpected indentation"),
        ("f.json", '{"intrinsics": {"fx": 1000}}', "intrinsics", "expected a 3 x 3 camera matrix"),
        ("g.json", '{"focal": 1000}', None, "holds no camera matrix"),
        ("h.json", "[1, 2]", None, "is JSON but not an object"),
        (
            "i.json",
            '{"K": [[1000, 0, 500], [0, 1000, 400], [0, 0, 1]], '
            '"dist": [0.1, 0, 0, 0, 0, 0.2, 0, 0]}',
            "dist",
            "k4 = 0.2",
        ),
        (
            "j.yml",
            "K: [[1000, 0, 500], [0, 1000, 400], [0, 0, 1]]\nrvec: [0, 0, .Nan]\ntvec: [0, 0, 1]\n",
            "rvec",
            "contains NaN",
        ),
        ("k.qca.txt", QUALISYS_QCA.read_text(), None, "Qualisys"),
        ("l.csv", "K,1000\n", None, "unknown calibration format (suffix '.csv')"),
    ],
)
def test_opencv_style_errors_name_file_and_field(tmp_path, name, text, field, message):
    path = write(tmp_path, name, text)
    with pytest.raises(InputError) as exc:
        load_cameras(path)
    assert exc.value.file == str(path) and exc.value.field == field
    assert message in str(exc.value)


def test_unsupported_file_lists_the_supported_formats():
    with pytest.raises(InputError) as exc:
        load_cameras(QUALISYS_QCA)
    text = str(exc.value)
    assert text.startswith(str(QUALISYS_QCA))
    for fmt in (
        "Pose2Sim / Sports2D calibration TOML",
        "OpenCV FileStorage or plain YAML",
        "OpenCV FileStorage XML",
        "OpenCV-style JSON",
        "pinrecon camera JSON",
    ):
        assert fmt in text


def test_missing_file_folder_and_unknown_format(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        load_cameras(tmp_path / "nope.toml")
    with pytest.raises(InputError, match="is a folder"):
        load_cameras(tmp_path)
    with pytest.raises(InputError, match="field 'format': unknown calibration format 'ini'"):
        load_cameras(QUALISYS_TOML, fmt="ini")
    with pytest.raises(InputError, match="field 'metres_per_unit'"):
        load_cameras(QUALISYS_TOML, metres_per_unit=0.0)
    # forcing a reader works on any suffix
    copy = write(tmp_path, "calibration.txt", QUALISYS_TOML.read_text())
    assert len(load_cameras(copy, fmt="toml")) == 4


# ---------------------------------------------------------------- YAML subset
def test_yaml_subset_parser_structures():
    text = """%YAML:1.0
---
# comment
name: "a # not a comment"   # a comment
plain: some text
numbers: [ 1, -2.5, 3.e+002, .Inf, -.Inf ]
nested:
  inner: { a: 1, b: [ 2, 3 ] }
  deeper:
    x: 'it''s'
names:
  - "01"
  - two
cams:
  - name: c1
    f: 10
  - name: c2
    f: 20
multi: [ 1, 2,
   3, 4 ]
empty:
flag: true
"""
    doc = parse_yaml(text)
    assert doc["name"] == "a # not a comment" and doc["plain"] == "some text"
    assert doc["numbers"][:3] == [1, -2.5, 300.0] and doc["numbers"][3:] == [np.inf, -np.inf]
    assert doc["nested"] == {"inner": {"a": 1, "b": [2, 3]}, "deeper": {"x": "it's"}}
    assert doc["names"] == ["01", "two"]
    assert doc["cams"] == [{"name": "c1", "f": 10}, {"name": "c2", "f": 20}]
    assert doc["multi"] == [1, 2, 3, 4] and doc["empty"] is None and doc["flag"] is True


# ---------------------------------------------------------------- docs/formats.md
def test_calibration_examples_in_docs_load(tmp_path):
    text = (REPO / "docs" / "formats.md").read_text()
    blocks = dict(
        re.findall(r"<!-- calibration example: ([\w.]+) -->\s*```\w+\n(.*?)```", text, re.S)
    )
    assert set(blocks) == {"calib.toml", "camera.yml"}
    for name, body in blocks.items():
        (tmp_path / name).write_text(body)
    cams = load_cameras(tmp_path / "calib.toml")
    assert [c.name for c in cams] == ["cam_left", "cam_right"]
    # as documented: both cameras see the world origin, 4 m away, at the principal point;
    # cam_right stands at (-4, 0, 0)
    for cal in cams:
        np.testing.assert_allclose(cal.camera.project(np.zeros(3)), [960.0, 540.0], atol=1e-9)
        assert cal.camera.depth(np.zeros(3)) == pytest.approx(4.0)
    np.testing.assert_allclose(-cams[1].camera.R.T @ cams[1].camera.t, [-4.0, 0.0, 0.0], atol=1e-12)
    (yml,) = load_cameras(tmp_path / "camera.yml")
    assert yml.image_size == (1280, 720) and not yml.has_pose
    np.testing.assert_array_equal(yml.camera.dist, [-0.25, 0.08, 0.0, 0.0, 0.0])
