"""Loading errors: one test per kind of bad input. Each asserts the exact message, that it
names the file, the field and (where meaningful) the frame, and that it is a
``pinrecon.errors.InputError`` rather than a raw NumPy/KeyError traceback. Writers leave
nothing half-written.
"""

from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest
from conftest import CMU_UNIT_M, WALK, data_path
from fuzzing_files import SMALL_BVH  # the two-segment BVH the readers' fuzzing starts from too

from pinrecon import (
    Figure,
    InputError,
    Tracks,
    UnknownNameError,
    load_camera,
    load_keyframes,
    load_tracks,
)
from pinrecon.errors import PinreconError
from pinrecon.io.bvh import load_bvh, read_bvh, write_bvh
from pinrecon.io.results import load_result_npz, save_result_npz
from pinrecon.tracks import Keyframes

WALK_BVH = data_path(WALK)


def raises_input_error(fn, *args, **kwargs) -> InputError:
    with pytest.raises(InputError) as exc:
        fn(*args, **kwargs)
    assert isinstance(exc.value, PinreconError) and isinstance(exc.value, ValueError)
    return exc.value


def write_json(path, data):
    path.write_text(json.dumps(data))
    return path


TRACKS_OK = {
    "fps": 30,
    "names": ["nose", "left_knee", "right_knee"],
    "points": [[[1, 2], [3, 4], [5, 6]]] * 3,
}


# ---------------------------------------------------------------- tracks: shapes
def test_tracks_json_row_with_wrong_number_of_points(tmp_path):
    data = dict(
        TRACKS_OK, points=[[[1, 2], [3, 4], [5, 6]], [[1, 2], [3, 4]], [[1, 2], [3, 4], [5, 6]]]
    )
    path = write_json(tmp_path / "tracks.json", data)
    err = raises_input_error(load_tracks, path)
    assert (err.file, err.field, err.frame) == (str(path), "points", 1)
    assert str(err) == f"{path}, field 'points', frame 1: expected 3 points (one per name), got 2"


def test_tracks_json_point_not_uv(tmp_path):
    data = dict(
        TRACKS_OK,
        points=[[[1, 2], [3, 4], [5, 6]], [[1, 2], [3, 4], [5, 6]], [[1, 2], [3, 4, 9], None]],
    )
    path = write_json(tmp_path / "tracks.json", data)
    err = raises_input_error(load_tracks, path)
    assert (
        str(err)
        == f"{path}, field 'points', frame 2: point 'left_knee' must be [u, v] or null, got [3, 4, 9]"
    )


def test_tracks_json_point_not_numeric(tmp_path):
    data = dict(TRACKS_OK, points=[[[1, 2], ["a", 4], [5, 6]]] * 3)
    path = write_json(tmp_path / "tracks.json", data)
    err = raises_input_error(load_tracks, path)
    assert (
        str(err) == f"{path}, field 'points', frame 0: point 'left_knee' is not numeric: ['a', 4]"
    )


def test_tracks_json_confidence_row_with_wrong_length(tmp_path):
    data = dict(TRACKS_OK, confidence=[[1, 1, 1], [1, 1], [1, 1, 1]])
    path = write_json(tmp_path / "tracks.json", data)
    err = raises_input_error(load_tracks, path)
    assert str(err) == f"{path}, field 'confidence', frame 1: expected 3 values"


def test_tracks_json_confidence_with_wrong_number_of_frames(tmp_path):
    path = write_json(tmp_path / "tracks.json", dict(TRACKS_OK, confidence=[[1, 1, 1]]))
    err = raises_input_error(load_tracks, path)
    assert str(err) == f"{path}, field 'confidence': expected 3 rows to match points"


def test_tracks_json_negative_confidence(tmp_path):
    path = write_json(
        tmp_path / "tracks.json", dict(TRACKS_OK, confidence=[[1, 1, 1], [1, 1, 1], [1, -0.5, 1]])
    )
    err = raises_input_error(load_tracks, path)
    assert str(err) == f"{path}, field 'confidence', frame 2: confidence must be >= 0"


@pytest.mark.parametrize("missing", ["fps", "names", "points"])
def test_tracks_json_missing_field(tmp_path, missing):
    data = {k: v for k, v in TRACKS_OK.items() if k != missing}
    path = write_json(tmp_path / "tracks.json", data)
    err = raises_input_error(load_tracks, path)
    assert str(err) == f"{path}, field '{missing}': required field is missing"


@pytest.mark.parametrize("fps", [0, -30, "30", True, None])
def test_tracks_json_bad_fps(tmp_path, fps):
    path = write_json(tmp_path / "tracks.json", dict(TRACKS_OK, fps=fps))
    err = raises_input_error(load_tracks, path)
    assert str(err) == f"{path}, field 'fps': must be a positive number, got {fps!r}"


def test_tracks_json_duplicate_names(tmp_path):
    path = write_json(
        tmp_path / "tracks.json", dict(TRACKS_OK, names=["nose", "nose", "left_knee"])
    )
    err = raises_input_error(load_tracks, path)
    assert str(err) == f"{path}, field 'names': duplicate names ['nose']"


def test_tracks_json_not_json(tmp_path):
    path = tmp_path / "tracks.json"
    path.write_text('{"fps": 30,\n "names": [}')
    err = raises_input_error(load_tracks, path)
    assert str(err) == f"{path}: not valid JSON (Expecting value at line 2)"


def test_tracks_file_not_found(tmp_path):
    err = raises_input_error(load_tracks, tmp_path / "nope.json")
    assert str(err) == f"{tmp_path / 'nope.json'}: file not found"


def test_tracks_npz_points_with_wrong_ndim(tmp_path):
    path = tmp_path / "tracks.npz"
    np.savez(path, fps=np.float64(30), names=np.array(["a", "b"]), points=np.zeros((4, 2)))
    err = raises_input_error(load_tracks, path)
    assert str(err) == f"{path}, field 'points': expected shape (T, K, 2), got (4, 2)"


def test_tracks_npz_confidence_with_wrong_shape(tmp_path):
    path = tmp_path / "tracks.npz"
    np.savez(
        path,
        fps=np.float64(30),
        names=np.array(["a", "b"]),
        points=np.zeros((4, 2, 2)),
        confidence=np.ones((4, 3)),
    )
    err = raises_input_error(load_tracks, path)
    assert (
        str(err) == f"{path}, field 'confidence': expected shape (4, 2) to match points, got (4, 3)"
    )


def test_tracks_npz_names_do_not_match_points(tmp_path):
    path = tmp_path / "tracks.npz"
    np.savez(path, fps=np.float64(30), names=np.array(["a"]), points=np.zeros((4, 2, 2)))
    err = raises_input_error(load_tracks, path)
    assert str(err) == f"{path}, field 'names': 1 names but points have 2 columns"


def test_tracks_npz_fps_not_a_number(tmp_path):
    path = tmp_path / "tracks.npz"
    np.savez(path, fps=np.array("fast"), names=np.array(["a"]), points=np.zeros((4, 1, 2)))
    err = raises_input_error(load_tracks, path)
    assert str(err) == f"{path}, field 'fps': must be a number, got <U4 array of shape ()"


def test_tracks_npz_missing_points(tmp_path):
    path = tmp_path / "tracks.npz"
    np.savez(path, fps=np.float64(30), names=np.array(["a"]))
    err = raises_input_error(load_tracks, path)
    assert str(err) == f"{path}, field 'points': required field is missing"


def test_tracks_npz_not_an_npz(tmp_path):
    path = tmp_path / "tracks.npz"
    path.write_text("fps,names\n30,a\n")
    err = raises_input_error(load_tracks, path)
    assert str(err) == f"{path}: not an NPZ file (an NPZ is a zip archive of .npy arrays)"


# ---------------------------------------------------------------- OpenPose / COCO
def test_openpose_unknown_layout(tmp_path):
    """Every frame has 10 points per person: no known layout has 10 (a frame whose count
    disagrees with the majority is a missing frame instead: tests/test_detectors.py)."""
    folder = tmp_path / "op"
    folder.mkdir()
    for i in range(2):
        write_json(
            folder / f"a_{i:012d}_keypoints.json",
            {"people": [{"pose_keypoints_2d": [1, 2, 1] * 10}]},
        )
    err = raises_input_error(load_tracks, folder, fps=30)
    assert err.file == str(folder)
    assert err.message.startswith("10 points per person: no known layout has 10 points (known: 14 (CrowdPose-14)")


def test_openpose_frame_without_people_list(tmp_path):
    folder = tmp_path / "op"
    folder.mkdir()
    write_json(folder / "a_000000000000_keypoints.json", {"version": 1.3})
    err = raises_input_error(load_tracks, folder, fps=30)
    assert (
        str(err)
        == f"{folder / 'a_000000000000_keypoints.json'}, field 'people', frame 0: no 'people' list"
    )


def test_openpose_empty_folder(tmp_path):
    err = raises_input_error(load_tracks, tmp_path, fps=30)
    assert str(err) == f"{tmp_path}: no OpenPose *_keypoints.json files in this folder"


def test_coco_keypoints_with_wrong_length(tmp_path):
    data = {
        "images": [{"id": 1}, {"id": 2}],
        "annotations": [{"image_id": 2, "keypoints": [0, 0, 2] * 16}],
    }
    path = write_json(tmp_path / "coco.json", data)
    err = raises_input_error(load_tracks, path, fps=30)
    assert (
        str(err)
        == f"{path}, field 'annotations[0].keypoints', frame 1: expected 51 numbers (x, y, v for 17 points)"
    )


def test_coco_annotation_of_unknown_image(tmp_path):
    data = {"images": [{"id": 1}], "annotations": [{"image_id": 9, "keypoints": [0, 0, 2] * 17}]}
    path = write_json(tmp_path / "coco.json", data)
    err = raises_input_error(load_tracks, path, fps=30)
    assert str(err) == f"{path}, field 'annotations[0]': image_id 9 is not in 'images'"


# ---------------------------------------------------------------- unknown names
def test_unknown_track_name_lists_valid_names():
    tracks = Tracks(np.zeros((2, 2, 2)), ["nose", "neck"], 30.0, source="t.json")
    err = raises_input_error(tracks.select, ["nose", "tail"])
    assert isinstance(err, UnknownNameError)
    assert (
        str(err)
        == "t.json, field 'names': unknown track name(s) 'tail'; valid track names are: nose, neck"
    )


def test_unknown_keypoint_in_keyframes_lists_valid_names(human, tmp_path):
    path = write_json(
        tmp_path / "keys.json",
        {"keyframes": [{"frame": 0, "points": {"nose": [0, 0, 1], "tail": [0, 0, 0]}}]},
    )
    err = raises_input_error(load_keyframes(path).validate, human, 10)
    assert isinstance(err, UnknownNameError) and err.names == ["tail"]
    assert str(err) == (
        f"{path}, field 'keyframes[0].points': unknown keypoint name(s) 'tail'; valid keypoint names are: "
        + ", ".join(human.keypoint_names)
    )


def test_unknown_joint_in_keyframes_lists_valid_names(human, tmp_path):
    path = write_json(
        tmp_path / "keys.json", {"keyframes": [{"frame": 3, "joints": {"left_knee": 0.5}}]}
    )
    err = raises_input_error(load_keyframes(path).validate, human, 10)
    assert (err.file, err.field, err.frame) == (str(path), "keyframes[0].joints", 3)
    assert err.message.startswith(
        "unknown joint name(s) 'left_knee'; valid joint names are: root_joint, left_hip_Z,"
    )
    assert "left_knee_Z" in err.valid


def test_unknown_frame_in_keypoint_map_lists_valid_frames(tmp_path):
    path = write_json(
        tmp_path / "map.json", {"keypoints": {"nose": {"frame": "skull", "offset": [0, 0.1, 0]}}}
    )
    err = raises_input_error(Figure.human, str(path))
    assert isinstance(err, UnknownNameError) and err.names == ["skull"] and err.field == "keypoints"
    assert "valid frame names are: universe, root_joint" in str(err) and "middle_head" in err.valid


def test_unknown_frame_in_keypoint_map_names_the_file(tmp_path):
    path = write_json(tmp_path / "map.json", {"keypoints": {"nose": {"frame": "skull"}}})
    err = raises_input_error(Figure.human, str(path))
    assert err.file == str(path)


def test_keypoint_map_bad_offset(tmp_path):
    path = write_json(
        tmp_path / "map.json", {"keypoints": {"nose": {"frame": "middle_head", "offset": [0, 1]}}}
    )
    err = raises_input_error(Figure.human, str(path))
    assert (
        str(err) == f"{path}, field 'keypoints.nose': offset must be 3 finite numbers, got [0, 1]"
    )


def test_unknown_bvh_joint():
    clip = read_bvh(WALK_BVH)
    err = raises_input_error(clip.joint_index, "Pelvis")
    assert str(err).startswith(
        f"{WALK_BVH}: unknown BVH joint name(s) 'Pelvis'; valid BVH joint names are: Hips, LHipJoint,"
    )


# ---------------------------------------------------------------- URDF
@pytest.mark.parametrize(
    "text",
    ["this is not xml <<<", '<robot name="r"><link name="a"></robot>', ""],
    ids=["garbage", "unclosed-tag", "empty"],
)
def test_urdf_that_does_not_parse(tmp_path, text):
    path = tmp_path / "robot.urdf"
    path.write_text(text)
    err = raises_input_error(Figure.from_urdf, path)
    assert (
        str(err)
        == f"{path}: URDF does not parse: The XML stream does not contain a valid URDF model."
    )


def test_urdf_file_not_found(tmp_path):
    err = raises_input_error(Figure.from_urdf, tmp_path / "none.urdf")
    assert str(err) == f"{tmp_path / 'none.urdf'}: file not found"


# ---------------------------------------------------------------- BVH


def bvh_file(tmp_path, text):
    path = tmp_path / "clip.bvh"
    path.write_text(text)
    return path


def test_small_bvh_fixture_is_valid(tmp_path):
    motion = load_bvh(bvh_file(tmp_path, SMALL_BVH))
    assert motion.q.shape == (3, 10) and motion.figure.keypoint_names == ["Hips", "Leg", "Leg_end"]


def test_bvh_truncated_hierarchy(tmp_path):
    lines = SMALL_BVH.splitlines()
    text = "\n".join(
        lines[:9] + lines[14:]
    )  # cut after "OFFSET 0 -4 0" of Leg: braces never closed
    err = raises_input_error(read_bvh, bvh_file(tmp_path, text))
    assert (
        str(err)
        == f"{tmp_path / 'clip.bvh'}, field 'HIERARCHY': unbalanced braces: hierarchy not closed"
    )


def test_bvh_missing_motion(tmp_path):
    text = SMALL_BVH.split("MOTION")[0]
    err = raises_input_error(read_bvh, bvh_file(tmp_path, text))
    assert (
        str(err)
        == f"{tmp_path / 'clip.bvh'}, field 'MOTION': no MOTION section found; not a BVH file?"
    )


def test_bvh_motion_row_with_wrong_number_of_values(tmp_path):
    text = SMALL_BVH.replace(
        "1 2 3 4 5 6 7 8 9\n1 2 3 4 5 6 7 8 9", "1 2 3 4 5 6 7 8 9\n1 2 3 4 5 6 7 8"
    )
    err = raises_input_error(read_bvh, bvh_file(tmp_path, text))
    assert (
        str(err)
        == f"{tmp_path / 'clip.bvh'}, field 'MOTION', frame 2: expected 9 channel values, got 8"
    )


def test_bvh_non_numeric_motion_value(tmp_path):
    text = SMALL_BVH.replace("0 0 0 0 0 0 0 0 0", "0 0 0 0 zero 0 0 0 0")
    err = raises_input_error(read_bvh, bvh_file(tmp_path, text))
    assert (
        str(err) == f"{tmp_path / 'clip.bvh'}, field 'MOTION', frame 0: non-numeric channel value"
    )


def test_bvh_nan_motion_value(tmp_path):
    text = SMALL_BVH.replace("1 2 3 4 5 6 7 8 9\n1 2", "1 2 3 4 5 6 7 8 9\nnan 2")
    err = raises_input_error(read_bvh, bvh_file(tmp_path, text))
    assert (
        str(err)
        == f"{tmp_path / 'clip.bvh'}, field 'MOTION', frame 2: NaN or infinite channel value"
    )


def test_bvh_fewer_rows_than_frames(tmp_path):
    text = SMALL_BVH.replace("Frames: 3", "Frames: 5")
    err = raises_input_error(read_bvh, bvh_file(tmp_path, text))
    assert (
        str(err)
        == f"{tmp_path / 'clip.bvh'}, field 'MOTION', frame 3: header says 5 frames but only 3 rows follow"
    )


def test_bvh_non_numeric_offset(tmp_path):
    text = SMALL_BVH.replace("OFFSET 0 -4 0\n    CHANNELS", "OFFSET 0 -four 0\n    CHANNELS")
    err = raises_input_error(read_bvh, bvh_file(tmp_path, text))
    assert (
        str(err)
        == f"{tmp_path / 'clip.bvh'}, field 'HIERARCHY': line 8: OFFSET: expected 3 numbers, found '-four'"
    )


def test_bvh_bad_channel_name(tmp_path):
    text = SMALL_BVH.replace(
        "CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS 3 Zrotation Yrotation Xrot"
    )
    err = raises_input_error(read_bvh, bvh_file(tmp_path, text))
    assert err.message.startswith(
        "line 9: bad CHANNELS for joint 'Leg': ['Zrotation', 'Yrotation', 'Xrot']"
    )


def test_bvh_bad_frame_time(tmp_path):
    text = SMALL_BVH.replace("Frame Time: 0.0333333", "Frame Time: 0")
    err = raises_input_error(read_bvh, bvh_file(tmp_path, text))
    assert str(err) == f"{tmp_path / 'clip.bvh'}, field 'Frame Time': must be positive, got 0.0"


# ---------------------------------------------------------------- cameras
ORTHO = {"model": "orthographic", "R": np.eye(3).tolist(), "scale": 300.0, "center": [640, 360]}
PERSP = {
    "model": "perspective",
    "K": [[1000, 0, 960], [0, 1000, 540], [0, 0, 1]],
    "R": np.eye(3).tolist(),
    "t": [0, 0, 3],
}


@pytest.mark.parametrize(
    "R, detail",
    [
        ([[1, 0, 0], [0, 1, 0], [0, 0, -1]], "|R R^T - I|max = 0.00e+00, det = -1.000000"),
        ([[1, 0, 0], [0, 1, 0.1], [0, 0, 1]], "|R R^T - I|max = 1.00e-01, det = 1.000000"),
        ([[2, 0, 0], [0, 2, 0], [0, 0, 2]], "|R R^T - I|max = 3.00e+00, det = 8.000000"),
    ],
    ids=["reflection", "sheared", "scaled"],
)
@pytest.mark.parametrize("base", [ORTHO, PERSP], ids=["orthographic", "perspective"])
def test_camera_R_not_a_rotation(tmp_path, base, R, detail):
    path = write_json(tmp_path / "camera.json", dict(base, R=R))
    err = raises_input_error(load_camera, path)
    assert str(err) == (
        f"{path}, field 'R': is not a rotation matrix ({detail}); R must be orthonormal with determinant +1"
    )


@pytest.mark.parametrize(
    "base, missing, kind",
    [
        (ORTHO, "R", "an orthographic"),
        (ORTHO, "scale", "an orthographic"),
        (PERSP, "K", "a perspective"),
        (PERSP, "R", "a perspective"),
        (PERSP, "t", "a perspective"),
    ],
)
def test_camera_missing_field(tmp_path, base, missing, kind):
    path = write_json(tmp_path / "camera.json", {k: v for k, v in base.items() if k != missing})
    err = raises_input_error(load_camera, path)
    assert str(err) == f"{path}, field '{missing}': is required for {kind} camera"


@pytest.mark.parametrize(
    "change, message",
    [
        ({"scale": "big"}, "field 'scale': must be a positive number, got 'big'"),
        ({"scale": None}, "field 'scale': must be a positive number, got None"),
        ({"scale": -1}, "field 'scale': must be a positive number, got -1"),
        ({"center": [1, 2, 3]}, "field 'center': expected shape (2,), got (3,)"),
        ({"R": "identity"}, "field 'R': expected a numeric array of shape (3, 3)"),
        ({"R": [[1, 0], [0, 1]]}, "field 'R': expected shape (3, 3), got (2, 2)"),
        (
            {"model": "fisheye"},
            "field 'model': unknown camera model 'fisheye'; expected 'orthographic' or 'perspective'",
        ),
    ],
)
def test_camera_bad_values(tmp_path, change, message):
    path = write_json(tmp_path / "camera.json", dict(ORTHO, **change))
    err = raises_input_error(load_camera, path)
    assert str(err) == f"{path}, {message}"


def test_camera_bad_perspective_values(tmp_path):
    path = write_json(tmp_path / "camera.json", dict(PERSP, t=[0, 0]))
    assert (
        str(raises_input_error(load_camera, path))
        == f"{path}, field 't': expected shape (3,), got (2,)"
    )
    path = write_json(
        tmp_path / "camera.json", dict(PERSP, K=[[1000, 0, 960], [0, 1000, 540], [0, 0, 2]])
    )
    err = raises_input_error(load_camera, path)
    assert (
        str(err)
        == f"{path}, field 'K': must be upper triangular with positive focal lengths and last row (0, 0, 1)"
    )


def test_camera_not_json(tmp_path):
    path = tmp_path / "camera.json"
    path.write_text("model: orthographic\n")
    assert (
        str(raises_input_error(load_camera, path))
        == f"{path}: not valid JSON (Expecting value at line 1)"
    )


# ---------------------------------------------------------------- keyframes JSON
@pytest.mark.parametrize(
    "item, field, frame, message",
    [
        (
            {"frame": 2.5, "points": {"nose": [0, 0, 1]}},
            "keyframes[0]",
            None,
            "'frame' must be an integer, got 2.5",
        ),
        (
            {"frame": "3", "points": {"nose": [0, 0, 1]}},
            "keyframes[0]",
            None,
            "'frame' must be an integer, got '3'",
        ),
        (
            {"frame": float("nan"), "points": {"nose": [0, 0, 1]}},
            "keyframes[0]",
            None,
            "'frame' must be an integer, got nan",
        ),
        (
            {"points": {"nose": [0, 0, 1]}},
            "keyframes[0]",
            None,
            "'frame' must be an integer, got None",
        ),
        (
            {"frame": 4, "sigma": 0, "points": {"nose": [0, 0, 1]}},
            "keyframes[0]",
            4,
            "'sigma' must be a positive number, got 0",
        ),
        (
            {"frame": 4, "sigma": -0.1, "points": {"nose": [0, 0, 1]}},
            "keyframes[0]",
            4,
            "'sigma' must be a positive number, got -0.1",
        ),
        (
            {"frame": 4, "points": {"nose": [0, 0, 1]}, "joints": {"left_knee_Z": 0.3}},
            "keyframes[0]",
            4,
            "needs exactly one of 'points' or 'joints'",
        ),
        ({"frame": 4}, "keyframes[0]", 4, "needs exactly one of 'points' or 'joints'"),
        (
            {"frame": 4, "points": {"nose": [0, 1]}},
            "keyframes[0].points.nose",
            4,
            "expected [x, y, z], got shape (2,)",
        ),
        (
            {"frame": 4, "points": {"nose": 1.0}},
            "keyframes[0].points.nose",
            4,
            "expected [x, y, z], got shape ()",
        ),
        (
            {"frame": 4, "points": {"nose": [0, "y", 1]}},
            "keyframes[0].points.nose",
            4,
            "not numeric: [0, 'y', 1]",
        ),
        (
            {"frame": 4, "points": {"nose": [0, None, 1]}},
            "keyframes[0].points.nose",
            4,
            "NaN or infinite value",
        ),
        (
            {"frame": 4, "joints": {}},
            "keyframes[0].joints",
            4,
            "'joints' must be a non-empty object",
        ),
        (
            {"frame": 4, "joints": {"left_knee_Z": [[1]]}},
            "keyframes[0].joints.left_knee_Z",
            4,
            "expected a number or a list, got shape (1, 1)",
        ),
    ],
)
def test_keyframes_json_errors(tmp_path, item, field, frame, message):
    ok = {"frame": 0, "joints": {"left_knee_Z": 0.2}}
    path = tmp_path / "keys.json"
    path.write_text(json.dumps({"keyframes": [item, ok]}))
    err = raises_input_error(load_keyframes, path)
    assert (err.file, err.field, err.frame, err.message) == (str(path), field, frame, message)


def test_keyframes_json_error_in_second_item(tmp_path):
    path = write_json(
        tmp_path / "keys.json",
        {"keyframes": [{"frame": 0, "joints": {"a": 1}}, {"frame": 7, "sigma": 0}]},
    )
    err = raises_input_error(load_keyframes, path)
    assert (
        str(err)
        == f"{path}, field 'keyframes[1]', frame 7: 'sigma' must be a positive number, got 0"
    )


@pytest.mark.parametrize(
    "data", [[], {"frames": []}, {"keyframes": {}}], ids=["list", "wrong-key", "not-a-list"]
)
def test_keyframes_json_wrong_top_level(tmp_path, data):
    path = write_json(tmp_path / "keys.json", data)
    err = raises_input_error(load_keyframes, path)
    assert (err.file, err.field) == (str(path), "keyframes")


# ---------------------------------------------------------------- Keyframes.validate
@pytest.mark.parametrize("frame", [10, -1])
def test_keyframes_validate_frame_outside_sequence(human, tmp_path, frame):
    path = write_json(
        tmp_path / "keys.json", {"keyframes": [{"frame": frame, "points": {"nose": [0, 0, 1]}}]}
    )
    err = raises_input_error(load_keyframes(path).validate, human, 10)
    assert (
        str(err)
        == f"{path}, field 'keyframes[0]', frame {frame}: frame {frame} is outside the sequence (0..9)"
    )


@pytest.mark.parametrize(
    "joint, value, sizes",
    [
        ("left_knee_Z", [0.1, 0.2], "1"),
        ("root_joint", [0, 0, 1, 0], "3 or 7"),
        ("root_joint", [0, 0, 0, 0, 0, 0, 1, 0], "3 or 7"),
    ],
)
def test_keyframes_validate_joint_with_wrong_number_of_values(human, tmp_path, joint, value, sizes):
    path = write_json(
        tmp_path / "keys.json", {"keyframes": [{"frame": 2, "joints": {joint: value}}]}
    )
    err = raises_input_error(load_keyframes(path).validate, human, 10)
    assert str(err) == (
        f"{path}, field 'keyframes[0].joints.{joint}', frame 2: joint '{joint}' takes {sizes} value(s), got {len(value)}"
    )


def test_keyframes_validate_accepts_root_3_and_7_vectors(human):
    keys = Keyframes.from_dict(
        {
            "keyframes": [
                {"frame": 0, "joints": {"root_joint": [0, 0.9, 0], "left_knee_Z": 0.4}},
                {"frame": 9, "joints": {"root_joint": [0, 0.9, 0, 0, 0, 0, 1]}},
            ]
        }
    )
    keys.validate(human, 10)
    assert [sorted(k.joints) for k in keys] == [["left_knee_Z", "root_joint"], ["root_joint"]]


# ---------------------------------------------------------------- nothing half-written
def assert_untouched(path, original: bytes):
    assert path.read_bytes() == original
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name]  # no temporary left


@pytest.fixture(scope="module")
def small_bvh_motion(tmp_path_factory):
    path = tmp_path_factory.mktemp("bvh") / "small.bvh"
    path.write_text(SMALL_BVH)
    return load_bvh(path)


@pytest.mark.parametrize("bad", ["shape", "nan"])
def test_write_bvh_with_bad_data_leaves_existing_file_untouched(small_bvh_motion, tmp_path, bad):
    out = tmp_path / "out.bvh"
    out.write_bytes(b"previous content")
    q = small_bvh_motion.q.copy()
    if bad == "shape":
        q = q[:, :-1]
    else:
        q[2, 5] = np.nan
    err = raises_input_error(write_bvh, out, small_bvh_motion.figure, q, 30.0)
    expected = (
        "field 'q': expected q of shape (frames, 10), got (3, 9)"
        if bad == "shape"
        else "field 'q', frame 2: NaN or infinite configuration value"
    )
    assert str(err) == f"{out}, {expected}"
    assert_untouched(out, b"previous content")


def test_write_bvh_with_bad_data_creates_no_file(small_bvh_motion, tmp_path):
    out = tmp_path / "new.bvh"
    raises_input_error(write_bvh, out, small_bvh_motion.figure, small_bvh_motion.q, -1.0)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("suffix", [".json", ".npz"])
def test_tracks_save_with_bad_data_leaves_existing_file_untouched(tmp_path, suffix):
    out = tmp_path / f"tracks{suffix}"
    out.write_bytes(b"previous content")
    tracks = Tracks(np.zeros((3, 2, 2)), ["a", "b"], 30.0)
    tracks.points = np.zeros((3, 3, 2))  # replaced after construction: 3 columns, 2 names
    err = raises_input_error(tracks.save, out)
    assert str(err) == f"{out}, field 'names': 2 names but points have 3 columns"
    assert_untouched(out, b"previous content")


@pytest.mark.parametrize("suffix", [".json", ".npz"])
def test_tracks_save_failing_mid_write_leaves_existing_file_untouched(
    tmp_path, suffix, monkeypatch
):
    """A crash while writing (disk full, ...) leaves the old file and no temporary."""
    out = tmp_path / f"tracks{suffix}"
    out.write_bytes(b"previous content")

    def half_write(self, *args, **kwargs):
        with open(self, "wb") as fh:
            fh.write(b"half")
        raise OSError(28, "No space left on device")

    if suffix == ".npz":

        def half_savez(fh, **arrays):
            fh.write(b"half")
            raise OSError(28, "No space left on device")

        monkeypatch.setattr(np, "savez", half_savez)
    else:
        monkeypatch.setattr(pathlib.Path, "write_text", half_write)
    with pytest.raises(OSError, match="No space left"):
        Tracks(np.zeros((3, 2, 2)), ["a", "b"], 30.0).save(out)
    assert_untouched(out, b"previous content")


RESULT = {
    "q": np.zeros((3, 8)),
    "times": np.arange(3) / 30.0,
    "keypoints3d": np.zeros((3, 2, 3)),
    "keypoint_names": np.array(["a", "b"]),
    "joint_names": np.array(["root"]),
}


@pytest.mark.parametrize(
    "change, message",
    [
        (
            {"times": np.arange(4) / 30.0},
            "q, times and keypoints3d must have the same number of frames",
        ),
        (
            {"keypoints3d": np.zeros((2, 2, 3))},
            "q, times and keypoints3d must have the same number of frames",
        ),
        ({"joint_names": None}, "result is missing ['joint_names']"),
    ],
)
def test_save_result_npz_with_bad_data_leaves_existing_file_untouched(tmp_path, change, message):
    out = tmp_path / "result.npz"
    out.write_bytes(b"previous content")
    arrays = {k: v for k, v in dict(RESULT, **change).items() if v is not None}
    err = raises_input_error(save_result_npz, out, **arrays)
    assert str(err) == f"{out}: {message}"
    assert_untouched(out, b"previous content")


def test_save_result_npz_round_trip(tmp_path):
    out = tmp_path / "result.npz"
    save_result_npz(out, **RESULT, fps=np.float64(30), extra=None)
    back = load_result_npz(out)
    assert sorted(back) == ["fps", "joint_names", "keypoint_names", "keypoints3d", "q", "times"]
    np.testing.assert_array_equal(back["times"], RESULT["times"])


def test_load_result_npz_missing_keys(tmp_path):
    out = tmp_path / "result.npz"
    np.savez(out, q=np.zeros((3, 8)))
    err = raises_input_error(load_result_npz, out)
    assert (
        str(err)
        == f"{out}: not a pinrecon result: missing ['times', 'keypoints3d', 'keypoint_names', 'joint_names']"
    )


def test_bvh_walk_lock_error_is_input_error():
    """The locked-joint error of a real clip (details in test_bvh.py) is an InputError."""
    err = raises_input_error(load_bvh, WALK_BVH, CMU_UNIT_M, lock=["LeftLeg"])
    assert (err.field, err.frame) == ("LeftLeg", 1)


@pytest.mark.parametrize("camera", ["given", "auto"])
@pytest.mark.parametrize("key, field, words", [
    ({"frame": 5, "sigma": 0.0, "points": {"left_hip": [0.0, 0.0, 3.0]}}, "keyframes[0]", "'sigma' must be a positive"),
    ({"frame": 5, "sigma": 0.02, "points": {"left_hip": [np.nan, 0.0, 3.0]}}, "keyframes[0].points.left_hip", "NaN"),
    ({"frame": 500, "sigma": 0.02, "points": {"left_hip": [0.0, 0.0, 3.0]}}, "keyframes[0]", "outside the sequence"),
    ({"frame": 5, "sigma": 0.02, "points": {"lefthip": [0.0, 0.0, 3.0]}}, "keyframes[0].points", "unknown keypoint"),
])
def test_keyframes_built_in_python_get_the_files_checks(camera, key, field, words):
    """Keyframes made with ``pr.Keyframe`` skip the file reader; ``reconstruct`` checks them
    as it would the file (a sigma of 0 was a FloatingPointError from the solver), and with
    the auto camera before asking whether they place it (which named none of these)."""
    import pinrecon as pr

    human = pr.Figure.human()
    tracks = pr.Tracks(np.random.default_rng(0).uniform(400, 600, (10, 4, 2)),
                       ["left_hip", "right_hip", "left_knee", "right_knee"], 30.0)
    cam = pr.Perspective.look_at([0.0, 1.0, -4.0], [0.0, 1.0, 0.0]) if camera == "given" else "auto"
    err = raises_input_error(pr.reconstruct, human, tracks, cam, pr.Keyframes([pr.Keyframe(**key)]),
                             image_size=(1280, 720))
    assert err.field == field and words in str(err)


def test_tracks_with_no_observed_point_are_one_clear_error():
    """Every shared point missing in every frame: one InputError naming the points, not a
    NumPy reshape error from the first start's solve."""
    import pinrecon as pr

    names = ["left_hip", "right_hip", "left_knee", "right_knee"]
    tracks = pr.Tracks(np.full((10, 4, 2), np.nan), names, 30.0, source="empty.json")
    err = raises_input_error(pr.reconstruct, pr.Figure.human(), tracks, pr.Perspective.look_at([0, 1, -4], [0, 1, 0]))
    assert err.file == "empty.json" and err.field == "points" and "observed in any frame" in str(err)
