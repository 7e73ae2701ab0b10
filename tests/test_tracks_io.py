"""Tracks formats: pinrecon JSON/NPZ round trips, OpenPose folders and COCO files read
into the arrays the fixture files were written from, format guessing, and the JSON
examples of ``docs/formats.md`` loaded with the real loaders.
"""

from __future__ import annotations

import json
import re
from dataclasses import replace

import numpy as np
import pytest
from conftest import DATA, REPO, openpose_body25_folder

from pinrecon import (
    Figure,
    InputError,
    Orthographic,
    Tracks,
    load_camera,
    load_keyframes,
    load_keypoint_map,
    load_tracks,
)
from pinrecon.io.bvh import load_bvh
from pinrecon.io.coco import COCO_17
from pinrecon.io.openpose import BODY_25, load_openpose
from pinrecon.io.results import REQUIRED_KEYS
from pinrecon.result import Result

OPENPOSE = openpose_body25_folder()  # written by formula (tests/data/SOURCES.md)
COCO_DATASET = DATA / "coco_dataset.json"
COCO_RESULTS = DATA / "coco_results.json"


def sample_tracks(with_confidence=True):
    rng = np.random.default_rng(0)
    points = rng.uniform(0, 640, size=(4, 3, 2))
    points[1, 2] = np.nan
    points[3, 0] = np.nan
    conf = rng.uniform(0.1, 1.0, size=(4, 3)) if with_confidence else None
    return Tracks(points, ["nose", "left_knee", "right_knee"], 25.0, conf)


# ---------------------------------------------------------------- pinrecon JSON / NPZ
@pytest.mark.parametrize("suffix", [".json", ".npz"])
@pytest.mark.parametrize("with_confidence", [True, False], ids=["confidence", "no-confidence"])
def test_tracks_round_trip(tmp_path, suffix, with_confidence):
    tracks = sample_tracks(with_confidence)
    path = tmp_path / f"tracks{suffix}"
    tracks.save(path)
    back = load_tracks(path)
    np.testing.assert_array_equal(back.points, tracks.points)  # NaN where missing, bit-exact
    assert back.names == tracks.names and back.fps == 25.0
    if with_confidence:
        np.testing.assert_array_equal(back.confidence, tracks.confidence)
    else:
        assert back.confidence is None
    assert back.source == str(path)
    assert back.observed.tolist() == [
        [True, True, True],
        [True, True, False],
        [True, True, True],
        [False, True, True],
    ]


def test_tracks_json_writes_null_for_missing_points(tmp_path):
    path = tmp_path / "tracks.json"
    sample_tracks(False).save(path)
    data = json.loads(path.read_text())
    assert set(data) == {"fps", "names", "points"}
    assert data["points"][1][2] is None and data["points"][3][0] is None
    assert len(data["points"]) == 4 and all(len(row) == 3 for row in data["points"])


def test_tracks_json_null_coordinate_and_null_confidence_are_missing(tmp_path):
    path = tmp_path / "tracks.json"
    path.write_text(
        json.dumps(
            {
                "fps": 30,
                "names": ["a", "b"],
                "points": [[[1, 2], [3, None]], [None, [5, 6]]],
                "confidence": [[0.5, 1.0], [1.0, None]],
            }
        )
    )
    tracks = load_tracks(path)
    assert tracks.observed.tolist() == [[True, False], [False, False]]
    np.testing.assert_array_equal(tracks.points[0, 1], [np.nan, np.nan])
    np.testing.assert_array_equal(tracks.confidence, [[0.5, 1.0], [1.0, 0.0]])
    np.testing.assert_array_equal(tracks.weights(), [[0.5, 0.0], [0.0, 0.0]])


def test_tracks_npz_nan_is_missing(tmp_path):
    path = tmp_path / "tracks.npz"
    points = np.array([[[1.0, 2.0], [np.nan, 4.0]], [[np.inf, 0.0], [7.0, 8.0]]])
    np.savez(path, fps=np.float64(50), names=np.array(["a", "b"]), points=points)
    tracks = load_tracks(path)
    assert tracks.observed.tolist() == [[True, False], [False, True]]
    assert np.isnan(tracks.points[1, 0]).all()  # inf counts as missing too
    assert tracks.fps == 50.0 and tracks.T == 2 and tracks.K == 2


def test_select_and_frames():
    tracks = sample_tracks()
    sub = tracks.select(["right_knee", "nose"])
    np.testing.assert_array_equal(sub.points, tracks.points[:, [2, 0]])
    np.testing.assert_array_equal(sub.confidence, tracks.confidence[:, [2, 0]])
    half = tracks.frames(0, None, 2)
    assert half.T == 2 and half.fps == 12.5
    np.testing.assert_array_equal(half.points, tracks.points[::2])
    np.testing.assert_allclose(tracks.times, [0.0, 0.04, 0.08, 0.12])


# ---------------------------------------------------------------- OpenPose
def openpose_expected(t, shift=0.0):
    """The fixture's formula (see tests/data/SOURCES.md)."""
    k = np.arange(25)
    return np.stack([100.0 + 10 * k + t + shift, 200.0 + 5.0 * k], axis=1)


def test_openpose_body25_folder():
    tracks = load_tracks(OPENPOSE, fps=30.0)
    assert (
        tracks.names == BODY_25
        and tracks.names[:2] == ["nose", "neck"]
        and tracks.names[8] == "mid_hip"
    )
    assert (tracks.T, tracks.K, tracks.fps) == (3, 25, 30.0)
    expected0 = openpose_expected(0)
    expected0[3] = np.nan  # written as 0 0 0 (confidence 0)
    np.testing.assert_array_equal(tracks.points[0], expected0)
    assert np.isnan(tracks.points[1]).all()  # a frame without people
    np.testing.assert_array_equal(tracks.points[2], openpose_expected(2))  # person 0 of two
    conf = np.full((3, 25), 0.9)
    conf[0, 3] = 0.0
    conf[1] = 0.0
    np.testing.assert_array_equal(tracks.confidence, conf)
    assert tracks.observed.sum() == 2 * 25 - 1


def test_openpose_second_person():
    tracks = load_openpose(OPENPOSE, fps=30.0, person=1)
    assert np.isnan(tracks.points[:2]).all()
    np.testing.assert_array_equal(tracks.points[2], openpose_expected(2, shift=1000.0))


def test_openpose_names_match_human_keypoints(human):
    shared = [n for n in BODY_25 if n in human.keypoint_names]
    assert shared == [n for n in BODY_25 if n in COCO_17]
    assert len(shared) == 17


# ---------------------------------------------------------------- COCO
def coco_expected(t, shift=0.0):
    k = np.arange(17)
    return np.stack([50.0 + 4 * k + t + shift, 80.0 + 3.0 * k], axis=1)


def test_coco_dataset_file():
    tracks = load_tracks(COCO_DATASET, fps=10.0)
    assert tracks.names == COCO_17 and (tracks.T, tracks.K, tracks.fps) == (3, 17, 10.0)
    expected0 = coco_expected(0)
    expected0[4] = np.nan  # v = 0
    np.testing.assert_array_equal(tracks.points[0], expected0)
    np.testing.assert_array_equal(tracks.points[1], coco_expected(1))  # larger area of two people
    assert np.isnan(tracks.points[2]).all()  # image without annotation
    conf0 = np.ones(17)
    conf0[4] = 0.0
    np.testing.assert_array_equal(tracks.confidence[0], conf0)  # v = 1 and v = 2 both count as seen
    np.testing.assert_array_equal(tracks.confidence[2], np.zeros(17))


def test_coco_results_list():
    tracks = load_tracks(COCO_RESULTS, fps=10.0)
    assert tracks.names == COCO_17 and tracks.T == 2  # image ids 5 and 7, sorted
    k = np.arange(17)
    exp5 = np.stack([30.0 + 2 * k + 5, 60.0 + k], axis=1)
    exp7 = np.stack([30.0 + 2 * k + 7, 60.0 + k], axis=1)  # the score 0.8 detection, not 0.4
    exp5[16] = exp7[16] = np.nan  # third value 0
    np.testing.assert_array_equal(tracks.points, np.stack([exp5, exp7]))
    conf = np.round(0.05 * (k + 1), 2)
    conf[16] = 0.0
    np.testing.assert_allclose(tracks.confidence, np.stack([conf, conf]), atol=0)


def test_coco_dataset_with_long_images_list_is_guessed_as_coco(tmp_path):
    """Real COCO files list thousands of images before 'annotations'."""
    data = json.loads(COCO_DATASET.read_text())
    data["images"] = [
        {"id": i, "file_name": f"frame_{i:06d}.jpg", "width": 640, "height": 480}
        for i in range(300)
    ]
    for i, ann in enumerate(data["annotations"]):
        ann["image_id"] = 100 + i
    path = tmp_path / "person_keypoints.json"
    path.write_text(json.dumps(data))
    assert path.read_text().index('"annotations"') > 4096
    tracks = load_tracks(path, fps=10.0)
    assert tracks.T == 300
    assert tracks.observed.sum(axis=1)[100:103].tolist() == [16, 17, 17]


# ---------------------------------------------------------------- format guessing
@pytest.mark.parametrize(
    "path, fmt, T",
    [
        (OPENPOSE, None, 3),
        (COCO_DATASET, None, 3),
        (COCO_RESULTS, None, 2),
        (COCO_RESULTS, "coco", 2),
    ],
    ids=["folder", "coco-dataset", "coco-results", "explicit"],
)
def test_load_tracks_guesses_format(path, fmt, T):
    assert load_tracks(path, fps=24.0, fmt=fmt).T == T


def test_load_tracks_json_ignores_fps_argument(tmp_path):
    path = tmp_path / "t.json"
    sample_tracks().save(path)
    assert load_tracks(path, fps=99.0).fps == 25.0


@pytest.mark.parametrize("path, fmt", [(OPENPOSE, "openpose"), (COCO_DATASET, "coco")])
def test_openpose_and_coco_need_fps(path, fmt):
    with pytest.raises(InputError) as exc:
        load_tracks(path)
    assert (
        str(exc.value) == f"{path}, field 'fps': {fmt} files store no frame rate: pass fps (--fps)"
    )


def test_unknown_format(tmp_path):
    path = tmp_path / "t.json"
    sample_tracks().save(path)
    with pytest.raises(InputError, match=r"field 'format': unknown tracks format 'csv'"):
        load_tracks(path, fmt="csv")


# ---------------------------------------------------------------- docs/formats.md examples
FORMATS_MD = REPO / "docs" / "formats.md"
_EXAMPLE = re.compile(
    r"<!-- example: (?P<name>[\w./-]+) -->\s*```(?:json|text)\n(?P<body>.*?)```", re.S
)


def doc_examples():
    text = FORMATS_MD.read_text()
    found = {m["name"]: m["body"] for m in _EXAMPLE.finditer(text)}
    n_json = sum(name.endswith(".json") for name in found)
    assert n_json == text.count("```json"), (
        "every JSON example in docs/formats.md needs a <!-- example: NAME --> tag"
    )
    return found


def test_every_docs_json_example_loads(tmp_path):
    examples = doc_examples()
    for name, body in examples.items():
        if name.endswith(".json"):
            json.loads(body)  # valid JSON, no comments
    assert set(examples) == {
        "minimal.bvh",
        "tracks.json",
        "tracks_lifted.json",
        "openpose/clip_000000000000_keypoints.json",
        "openpose/clip_000000000001_keypoints.json",
        "coco_dataset.json",
        "coco_results.json",
        "camera_orthographic.json",
        "camera_perspective.json",
        "keyframes.json",
        "keypoints.json",
    }
    for name, body in examples.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(body)

    tracks = load_tracks(tmp_path / "tracks.json")
    assert tracks.names == ["nose", "left_knee", "right_knee"] and tracks.T == 3
    assert tracks.observed.tolist() == [
        [True, True, True],
        [True, False, True],
        [True, True, False],
    ]

    lifted = load_tracks(tmp_path / "tracks_lifted.json").lifted
    assert lifted.names == ["nose", "left_knee", "pelvis"] and lifted.source == "mediapipe"
    assert lifted.confidence.tolist() == [[0.9, 0.8, 1.0], [0.9, 0.0, 1.0]]

    openpose = load_tracks(tmp_path / "openpose", fps=30.0)
    assert openpose.names == BODY_25 and openpose.T == 2 and not openpose.observed[1].any()

    coco = load_tracks(tmp_path / "coco_dataset.json", fps=30.0)
    assert coco.names == COCO_17 and coco.T == 2
    results = load_tracks(tmp_path / "coco_results.json", fps=30.0)
    assert results.names == COCO_17 and results.T == 2

    ortho = load_camera(tmp_path / "camera_orthographic.json")
    np.testing.assert_allclose(ortho.project(np.array([0.0, 1.0, 0.0])), [640.0, 360.0 - 300.0])
    persp = load_camera(tmp_path / "camera_perspective.json")
    np.testing.assert_allclose(persp.project(np.array([0.0, 1.0, 0.0])), [960.0, 540.0])

    human = Figure.human()
    keyframes = load_keyframes(tmp_path / "keyframes.json")
    keyframes.validate(human, tracks.T)
    assert [k.kind for k in keyframes] == ["joints", "points", "joints"]

    kp_path = tmp_path / "keypoints.json"
    assert [k.name for k in load_keypoint_map(kp_path)] == ["head_top", "left_knee"]
    assert Figure.human(str(kp_path)).K == 2

    bvh = load_bvh(tmp_path / "minimal.bvh", 0.1)
    assert bvh.figure.keypoint_names == ["Hips", "Leg", "Leg_end"]
    assert bvh.figure.joint_names == [
        "root_joint",
        "Leg_Zrotation",
        "Leg_Yrotation",
        "Leg_Xrotation",
    ]
    assert (bvh.figure.nq, bvh.figure.nv, bvh.q.shape[0]) == (10, 9, 2)


def test_docs_result_keys_are_the_keys_result_save_writes(human, tmp_path):
    text = FORMATS_MD.read_text()
    section = text[text.index("## 8. Result NPZ") : text.index("## 9.")]
    always, sometimes = section.split("Written only when they apply:")
    documented = re.findall(r"^\| `(\w+)` \|", always, re.M)
    Q = np.stack([human.random_configuration(s) for s in range(3)])
    result = Result(
        figure=human,
        q=Q,
        times=np.arange(3) / 30.0,
        fps=30.0,
        keypoints3d=human.keypoints(Q),
        reprojection_error_px=np.zeros(3),
        solve=None,
        observed_frames=np.ones(3, bool),
        camera=Orthographic(np.eye(3), 100.0),
    )
    result.save(tmp_path / "result.npz")
    with np.load(tmp_path / "result.npz") as z:
        written = list(z.files)
        assert z["keypoint_parents"].shape == (human.K,) and str(z["figure_name"]) == "human"
    assert sorted(documented) == sorted(written)
    assert documented[:5] == list(REQUIRED_KEYS)
    # the keys written only when they apply: two cameras, a calibration, the hypothesis
    # search, the turn and mirror stages, the fault stage, the floor stage, the pose prior's check, the
    # stability check (each producer's own key list)
    from pinrecon.contact import FOOT_EXTRAS
    from pinrecon.faults import FaultReport
    from pinrecon.starts.hypotheses import HypothesisReport
    from pinrecon.starts.mirrors import MirrorStage
    from pinrecon.stability import Stability
    from pinrecon.starts.turns import TurnStage
    from pinrecon.unfamiliar import UnfamiliarPoses, switch_extras

    two = replace(result, cameras=[result.camera, Orthographic(np.eye(3), 90.0)], camera_names=["a", "b"],
                  reprojection_error_px_per_camera=np.zeros((2, 3)), calibration={"mode": "camera"})
    two.save(tmp_path / "two.npz")
    with np.load(tmp_path / "two.npz") as z:
        extra = set(z.files) - set(written)
    extra |= set(FOOT_EXTRAS) | set(FaultReport().to_extras())
    extra |= set(HypothesisReport(chains=[], states=np.zeros((3, 0), int), gaps=np.zeros((3, 0))).to_extras())
    extra |= set(UnfamiliarPoses(np.zeros(3), 9.0, model="human_pose").to_extras()) | set(switch_extras("human_pose_mixture", 0.9))
    extra |= set(TurnStage([]).to_extras()) | set(MirrorStage([]).to_extras())
    extra |= set(Stability(0.01, (0,), np.zeros((1, 3)), np.zeros((3, 1)), ["nose"], 30.0, 30.0).to_extras())
    cells = re.findall(r"^\| ([^|]+) \|", sometimes, re.M)
    conditional = {k for c in cells for k in re.findall(r"`(\w+)`", c)}
    assert conditional == extra
