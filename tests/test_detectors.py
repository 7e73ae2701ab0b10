"""Real detector output in, without silent mistakes (issue 11).

Every fixture under tests/data/detectors/ is real detector output from a public
repository, or derived from one by tests/data/detectors/make_derived.py (sources and
licences in tests/data/SOURCES.md). The expected arrays are read here from the raw JSON
with the json module and plain indexing, independently of pinrecon's readers; the
expected point names are spelled out here, from each detector's documentation.

The tests named ``test_mistake_*`` are the silent mistakes of the issue: each fails on
the code of commit f2d410b (checked) and passes now.
"""

from __future__ import annotations

import json
import shutil
import warnings

import numpy as np
import pytest
from conftest import data_dir, data_folder

import pinrecon as pr
from pinrecon import InputError
from pinrecon.cli import main
from pinrecon.problem import make_problem
from pinrecon.tracks import TracksWarning, load_tracks

DET = data_dir("project-test-data/detectors")
P2S_MULTI = DET / "pose2sim_body25b_multi"
P2S_HALPE = DET / "pose2sim_halpe26"
P2S_STATIC = data_dir("project-test-data/calibration/pose2sim/static_trial")

COCO17 = ["nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder", "right_shoulder",
          "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hip", "right_hip", "left_knee",
          "right_knee", "left_ankle", "right_ankle"]
FEET_OP = ["left_big_toe", "left_small_toe", "left_heel", "right_big_toe", "right_small_toe", "right_heel"]
# OpenPose doc/02_output.md, "Pose Output Format (BODY_25)"
BODY25 = ["nose", "neck", "right_shoulder", "right_elbow", "right_wrist", "left_shoulder", "left_elbow",
          "left_wrist", "mid_hip", "right_hip", "right_knee", "right_ankle", "left_hip", "left_knee",
          "left_ankle", "right_eye", "left_eye", "right_ear", "left_ear"] + FEET_OP
# OpenPose experimental models: BODY_25B = COCO-17, UpperNeck, HeadTop, feet (Pose2Sim skeletons.py)
BODY25B = COCO17 + ["upper_neck", "head_top"] + FEET_OP
# Halpe-26 (AlphaPose, mmpose configs/_base_/datasets/halpe26.py): head, neck, hip, then the feet
HALPE26 = COCO17 + ["head_top", "upper_neck", "mid_hip", "left_big_toe", "right_big_toe", "left_small_toe",
                    "right_small_toe", "left_heel", "right_heel"]
COCO18 = BODY25[:8] + BODY25[9:19]


def raw_people(path):
    """[(K, 3) array per person] of one OpenPose JSON file, read with json only."""
    data = json.loads(path.read_text())
    return [np.array(p["pose_keypoints_2d"], float).reshape(-1, 3) for p in data["people"]]


def as_points(triples):
    """(K, 2) positions with NaN where the confidence is 0."""
    xy = triples[:, :2].copy()
    xy[triples[:, 2] <= 0] = np.nan
    return xy


def load_quietly(path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_tracks(path, **kw)


def identity(person):
    """Who a Pose2Sim multi-person detection is, from its raw numbers: the participant
    walking in from the right (C) has points at x > 200 px; of the two at the left edge,
    A is detected with confidence 1, B with about 0.4."""
    ok = person[:, 2] > 0
    if person[ok, 0].mean() > 200:
        return "C"
    return "A" if person[ok, 2].mean() > 0.9 else "B"


def who_is_followed(tracks, folder):
    """The identity of the detection each frame of ``tracks`` was taken from (None if missing)."""
    out = []
    for t, f in enumerate(sorted(folder.glob("*.json"))):
        found = None
        try:
            people = raw_people(f)
        except (json.JSONDecodeError, ValueError):
            people = []
        for p in people:
            want = as_points(p)
            want[(p[:, 2] > 0) & np.any(p[:, :2] == 0, axis=1)] = np.nan  # a detector's 0 is no position
            if len(p) == tracks.K and np.array_equal(want, tracks.points[t], equal_nan=True):
                found = identity(p)
        out.append(found)
    return out


# ---------------------------------------------------------------------------- silent mistakes
@pytest.mark.parametrize("cam", [1, 2, 3, 4])
def test_mistake_body25b_is_not_read_as_body25(tmp_path, cam):
    """Pose2Sim's BODY_25B (one camera's frame): under BODY_25's names the 'neck' would be
    the left eye. Read as BODY_25B, point 17 is the upper neck, above the shoulders."""
    src = P2S_STATIC / f"Static_cam_0{cam}.00000.json"
    shutil.copy(src, tmp_path / src.name)
    tracks = load_quietly(tmp_path, fps=30.0)
    assert tracks.names == BODY25B and "neck" not in tracks.names
    np.testing.assert_array_equal(tracks.points[0], as_points(raw_people(src)[0]))
    upper = tracks.points[0, BODY25B.index("upper_neck")]
    mid = (tracks.points[0, 5] + tracks.points[0, 6]) / 2
    assert upper[1] < mid[1]  # image y down: above the shoulders' midpoint


def test_body25b_read_as_body25_puts_the_neck_off_the_shoulders():
    """The measured size of the mistake on the real multi-person trial: BODY_25's neck
    (index 1) against the midpoint of BODY_25's shoulders (indices 2 and 5)."""
    off = []
    for f in sorted(P2S_MULTI.glob("*.json")):
        for p in raw_people(f):
            if len(p) and identity(p) == "C" and np.all(p[[1, 2, 5], 2] > 0):
                off.append(np.linalg.norm(p[1, :2] - (p[2, :2] + p[5, :2]) / 2) / np.linalg.norm(p[2, :2] - p[5, :2]))
    assert len(off) > 30 and np.median(off) > 0.3


def test_mistake_multi_person_sequence_follows_one_person(tmp_path):
    """Pose2Sim's two-participant trial (OpenPose BODY_25B, 2 to 4 entries per frame in
    changing order, an empty entry in frame 1): the subject is one person in every frame."""
    tracks = load_quietly(P2S_MULTI, fps=25.0)
    assert who_is_followed(tracks, P2S_MULTI) == ["A"] * 40
    # the same without the empty entry (which stopped the old reader before it could mix)
    for f in sorted(P2S_MULTI.glob("*.json")):
        data = json.loads(f.read_text())
        data["people"] = [p for p in data["people"] if p["pose_keypoints_2d"]]
        (tmp_path / f.name).write_text(json.dumps(data))
    tracks = load_quietly(tmp_path, fps=25.0)
    who = who_is_followed(tracks, tmp_path)
    assert who == ["A"] * 40
    moving = load_quietly(P2S_MULTI, fps=25.0, person=(300, 300, 800, 1200))
    who = who_is_followed(moving, P2S_MULTI)
    assert who[:2] == [None, None] and who[2:] == ["C"] * 38  # C walks in at frame 2
    assert load_quietly(P2S_MULTI, fps=25.0, person=1).T == 40
    assert set(who_is_followed(load_quietly(P2S_MULTI, fps=25.0, person=1), P2S_MULTI)) == {"B"}


def test_multi_person_report_counts_the_order_changes():
    order = []  # the subject's entry index per frame, from the raw files
    for f in sorted(P2S_MULTI.glob("*.json"))[2:]:
        people = raw_people(f)
        order.append(next(i for i, p in enumerate(people) if len(p) and identity(p) == "C"))
    expected = sum(a != b for a, b in zip(order, order[1:]))
    with pytest.warns(TracksWarning) as rec:
        load_tracks(P2S_MULTI, fps=25.0, person="300,300,800,1200")
    text = " ".join(str(w.message) for w in rec)
    assert f"{expected} identity switches of the detector's order resolved" in text
    assert expected >= 10


def test_mistake_alphapose_frames_in_numeric_order():
    """AlphaPose names frames by file name ('0.jpg' ... '11.jpg'): frame 2 is image 2, not 10."""
    tracks = load_quietly(DET / "alphapose_coco17_results.json", fps=25.0)
    halpe = [raw_people(f)[0] for f in sorted(P2S_HALPE.glob("*.json"))]
    assert tracks.T == 12 and tracks.names == COCO17
    for t in range(12):
        np.testing.assert_array_equal(tracks.points[t], as_points(halpe[t][:17]))


def test_mistake_one_bad_frame_is_a_missing_frame(tmp_path):
    """In the real multi-person trial: one entry with 26 triples (a Halpe-26 frame put in
    place of frame 5) and a truncated file (frame 9) are missing frames of the subject,
    counted in one warning each; the rest loads (frame 1's real empty entry too)."""
    folder = tmp_path / "op"
    shutil.copytree(P2S_MULTI, folder)
    files = sorted(folder.glob("*.json"))
    files[5].write_text((P2S_HALPE / "frame_00001.json").read_text())  # 26 triples
    files[9].write_text(files[9].read_text()[:200])  # truncated
    with pytest.warns(TracksWarning) as rec:
        tracks = load_tracks(folder, fps=25.0)
    assert tracks.T == 40 and tracks.observed.sum(axis=1)[[5, 9]].tolist() == [0, 0]
    who = who_is_followed(tracks, folder)
    assert [w for t, w in enumerate(who) if t not in (5, 9)] == ["A"] * 38
    text = [str(w.message) for w in rec]
    assert any("1 of 40 frames could not be read" in m and "frames 9;" in m for m in text)
    assert any("2 detection(s) could not be read" in m and "frames 1, 5;" in m for m in text)


def test_mistake_a_coordinate_exactly_zero_is_missing_not_a_point_at_the_edge():
    """Pose2Sim's balancing trial (camera 1, OpenPose BODY_25B): in six frames the nose is
    written as x = 0 beside a real y and a confidence of 0.65-0.69, its neighbours 530 px
    away. Read as missing, in one warning naming the point and the frames (before, they
    were points at the image's left edge that the robust loss had to report as outliers).
    The frames are found here from the raw JSON; COCO's whole-pixel annotations keep their
    zeros (``test_coco_results_by_image_and_score``)."""
    folder = data_folder("pose2sim-balancing/pose/cam01_json")
    files = sorted(folder.glob("*.json"))
    raw = [raw_people(f) for f in files]
    zero = sorted(t for t, people in enumerate(raw) for k in people[0]  # the first person: the subject
                  if k[2] > 0 and (k[0] == 0) != (k[1] == 0))
    assert zero == [4, 5, 6, 7, 8, 15]
    with pytest.warns(TracksWarning) as rec:
        tracks = load_tracks(folder, fps=60.0)
    text = [str(w.message) for w in rec]
    assert any("6 detected point(s) had a coordinate exactly 0" in m and "nose in frames 4, 5, 6, 7, 8, 15" in m
               for m in text), text
    nose = tracks.names.index("nose")
    assert np.isnan(tracks.points[zero, nose]).all() and (tracks.confidence[zero, nose] == 0).all()
    assert np.isfinite(tracks.points[[3, 9, 14, 16], nose]).all()  # their neighbours are read as written


def test_real_empty_entry_is_dropped_and_the_load_goes_on():
    """Frame 1 of the real multi-person trial holds an entry with no numbers."""
    assert raw_people(P2S_MULTI / "cam01.0001.json")[0].size == 0
    with pytest.warns(TracksWarning, match="1 detection"):
        tracks = load_tracks(P2S_MULTI, fps=25.0)
    assert tracks.observed[1].sum() == 21


def test_nothing_usable_left_is_an_error(tmp_path):
    folder = tmp_path / "op"
    folder.mkdir()
    (folder / "a_0_keypoints.json").write_text("{")
    (folder / "a_1_keypoints.json").write_text('{"people": [{"pose_keypoints_2d": "x"}]}')
    with pytest.raises(InputError) as exc:
        load_tracks(folder, fps=30.0)
    assert exc.value.frame == 0 and "not valid JSON" in str(exc.value)


# ---------------------------------------------------------------------------- every format
@pytest.mark.parametrize(
    "path, names",
    [(DET / "spin_body25" / "im1010_openpose.json", BODY25), (DET / "prohmr_body25", BODY25),
     (P2S_HALPE, HALPE26), (P2S_STATIC, BODY25B)],
    ids=["body25-file", "body25-folder", "halpe26-openpose", "body25b-4-cameras"],
)
def test_openpose_fixtures(path, names):
    tracks = load_quietly(path, fps=25.0, person="largest")
    files = [path] if path.is_file() else sorted(path.glob("*.json"))
    assert tracks.names == names and tracks.T == len(files)
    for t, f in enumerate(files):
        np.testing.assert_array_equal(tracks.points[t], as_points(raw_people(f)[0]))
        c = raw_people(f)[0][:, 2]
        np.testing.assert_allclose(tracks.confidence[t], np.clip(c, 0, 1))


def test_openpose_files_in_natural_order(tmp_path):
    for i, f in enumerate(sorted(P2S_HALPE.glob("*.json"))):
        shutil.copy(f, tmp_path / f"clip_{i}_keypoints.json")  # clip_2 before clip_10
    tracks = load_quietly(tmp_path, fps=25.0)
    for t, f in enumerate(sorted(P2S_HALPE.glob("*.json"))):
        np.testing.assert_array_equal(tracks.points[t], as_points(raw_people(f)[0]))


def test_openpose_coco18_and_largest_person():
    tracks = load_quietly(DET / "openpose_coco18", fps=25.0, person="largest")
    assert tracks.names == COCO18 and tracks.T == 2 and tracks.layout == "coco18"
    files = sorted((DET / "openpose_coco18").glob("*.json"))
    assert files[0].name.startswith("im1010")
    for t, f in enumerate(files):
        np.testing.assert_array_equal(tracks.points[t], as_points(raw_people(f)[0]))


def coco_largest(data, names_len):
    """Expected frames of a COCO dataset: images by file name, each image's largest area."""
    images = sorted(data["images"], key=lambda im: im["file_name"])
    out = []
    for im in images:
        anns = [a for a in data["annotations"] if a["image_id"] == im["id"]]
        if not anns:
            out.append(None)
            continue
        a = max(anns, key=lambda a: a["area"])
        k = np.array(a["keypoints"], float).reshape(-1, 3)[:names_len]
        xy = k[:, :2].copy()
        xy[k[:, 2] <= 0] = np.nan
        out.append(xy)
    return out


@pytest.mark.parametrize(
    "name, names, layout",
    [("mmpose_coco17_dataset.json", COCO17, "coco17"),
     ("mmpose_halpe136_dataset.json", HALPE26, "halpe136"),
     ("mmpose_crowdpose14_dataset.json", COCO17[5:] + ["head_top", "upper_neck"], "crowdpose14")],
)
def test_coco_datasets(name, names, layout):
    data = json.loads((DET / name).read_text())
    if "area" not in data["annotations"][0]:
        for a in data["annotations"]:  # CrowdPose has no area: the box's
            a["area"] = a["bbox"][2] * a["bbox"][3]
    tracks = load_quietly(DET / name, fps=25.0)
    assert tracks.names == names and tracks.layout == layout
    for t, xy in enumerate(coco_largest(data, len(names))):
        if xy is None:
            assert not tracks.observed[t].any()
        else:
            np.testing.assert_array_equal(tracks.points[t], xy)


def test_coco_results_by_image_and_score():
    data = json.loads((DET / "cocoapi_fakekeypoints100_results.json").read_text())
    tracks = load_quietly(DET / "cocoapi_fakekeypoints100_results.json", fps=25.0, person="largest")
    ids = sorted({a["image_id"] for a in data})
    assert tracks.T == len(ids) == 47 and tracks.names == COCO17
    for t, iid in enumerate(ids):
        a = max((a for a in data if a["image_id"] == iid), key=lambda a: a["score"])
        k = np.array(a["keypoints"], float).reshape(17, 3)
        np.testing.assert_array_equal(tracks.points[t], as_points(k))


def test_alphapose_halpe26_keeps_frames_without_detection():
    tracks = load_quietly(DET / "alphapose_halpe26_results.json", fps=25.0)
    halpe = [raw_people(f)[0] for f in sorted(P2S_HALPE.glob("*.json"))]
    assert tracks.T == 12 and tracks.names == HALPE26 and not tracks.observed[7].any()
    for t in [0, 6, 8, 11]:
        np.testing.assert_array_equal(tracks.points[t], as_points(halpe[t]))


@pytest.mark.parametrize("name", ["mmpose_halpe26_inferencer.json", "mmpose_halpe26_demo.json"])
def test_mmpose_outputs(name):
    tracks = load_quietly(DET / name, fps=25.0)
    halpe = [raw_people(f)[0] for f in sorted(P2S_HALPE.glob("*.json"))]
    assert tracks.T == 12 and tracks.names == HALPE26 and tracks.layout == "halpe26"
    for t in range(12):
        np.testing.assert_array_equal(tracks.points[t], as_points(halpe[t]))


def test_h36m_told_from_coco17_by_geometry():
    tracks = load_quietly(DET / "h36m17_from_halpe26_results.json", fps=25.0)
    assert tracks.layout == "h36m17" and tracks.names[0] == "mid_hip" and tracks.names[10] == "head_top"
    coco = load_quietly(DET / "alphapose_coco17_results.json", fps=25.0)
    assert coco.layout == "coco17"


def test_boxes_only():
    data = json.loads((DET / "mmpose_coco_person_boxes.json").read_text())
    tracks = load_quietly(DET / "mmpose_coco_person_boxes.json", fps=25.0, person="largest")
    ids = sorted({a["image_id"] for a in data})
    assert tracks.names == ["box_top_left", "box_bottom_right"] and tracks.T == len(ids)
    for t, iid in enumerate(ids):
        x, y, w, h = max((a for a in data if a["image_id"] == iid), key=lambda a: a["score"])["bbox"]
        np.testing.assert_allclose(tracks.points[t], [[x, y], [x + w, y + h]])


# ---------------------------------------------------------------------------- layouts named
def test_layout_option_and_refusal(tmp_path):
    spin = raw_people(DET / "spin_body25" / "im1010_openpose.json")[0]
    keep = np.zeros_like(spin)
    keep[[6, 10]] = spin[[6, 10]]  # an elbow and a knee: no check of either layout applies
    (tmp_path / "f_keypoints.json").write_text(json.dumps({"people": [{"pose_keypoints_2d": keep.ravel().tolist()}]}))
    with pytest.raises(InputError, match="cannot tell .* apart.*body25, body25b"):
        load_tracks(tmp_path, fps=25.0)
    assert load_tracks(tmp_path, fps=25.0, layout="BODY_25").names == BODY25
    with pytest.raises(InputError, match="layout halpe26 has 26 points per person but the file has 25"):
        load_tracks(tmp_path, fps=25.0, layout="halpe26")
    with pytest.raises(InputError, match="unknown layout 'body26'; valid layouts are: coco17"):
        load_tracks(tmp_path, fps=25.0, layout="body26")


@pytest.fixture
def camera_json(tmp_path):
    path = tmp_path / "cam.json"
    path.write_text(json.dumps({"model": "perspective", "K": [[5000.0, 0, 2000.0], [0, 5000.0, 3000.0], [0, 0, 1]],
                                "R": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "t": [0.0, 1.0, 4.0]}))
    return path


# ---------------------------------------------------------------------------- names
def halpe_tracks(names=None):
    """The RTMPose Halpe-26 frames as Tracks built here from the raw JSON (COCO-17 part)."""
    frames = [as_points(raw_people(f)[0])[:17] for f in sorted(P2S_HALPE.glob("*.json"))]
    return pr.Tracks(np.stack(frames), names or COCO17, 25.0, source="halpe.json")


def test_mistake_typo_and_too_few_shared_points_are_errors(human):
    cam = pr.Orthographic(np.eye(3), 500.0)
    typo = halpe_tracks([("left_wrst" if n == "left_wrist" else n) for n in COCO17])
    with pytest.raises(InputError, match=r"look like typos.*'left_wrst' \(did you mean 'left_wrist'\?\)"):
        make_problem(human, typo, cam)
    tracks = halpe_tracks()
    few = pr.Tracks(tracks.points[:, :3], ["nose", "neck_x", "tail"], 25.0)
    with pytest.raises(InputError, match=r"share only 1 point\(s\) with the figure \(nose\): at least 4"):
        make_problem(human, few, cam)


def test_mistake_figure_and_keypoints_errors_list_the_choices(tmp_path, capsys, camera_json):
    base = ["reconstruct", "--tracks", str(P2S_HALPE), "--fps", "25", "--camera", str(camera_json), "--out",
            str(tmp_path / "r.npz")]
    assert main(base + ["--figure", "Human"]) == 2
    err = capsys.readouterr().err
    assert "did you mean 'human'?" in err and "'human', a URDF file (.urdf) or a BVH file (.bvh)" in err
    assert main(base + ["--figure", "human", "--keypoints", "body25x"]) == 2
    err = capsys.readouterr().err
    assert "body25, body25b, coco17, halpe26, joints" in err and "Traceback" not in err


# ---------------------------------------------------------------------------- the command line
def test_reconstruct_human_uses_the_body25_points(tmp_path, camera_json, capsys):
    out = tmp_path / "r.npz"
    assert main(["reconstruct", "--figure", "human", "--tracks", str(DET / "prohmr_body25"), "--fps", "25",
                 "--camera", str(camera_json), "--out", str(out), "--quiet", "--max-iterations", "30"]) == 0
    res = pr.load_result(out)
    assert res.figure.keypoint_names == BODY25
    for n in ["neck", "mid_hip", "left_heel", "right_heel", "left_big_toe", "right_small_toe"]:
        assert n in res.figure.keypoint_names
    err = capsys.readouterr().err
    assert "iter " not in err and "pinrecon: stage" not in err  # --quiet: no progress


def test_warnings_are_printed_also_with_quiet(capsys):
    """--quiet silences progress only: a warning is still said."""
    assert main(["links", str(P2S_MULTI), "--fps", "25", "--names", "left_shoulder", "left_elbow", "left_wrist"]) == 0
    err = capsys.readouterr().err
    assert "pinrecon: warning:" in err and "1 detection(s) could not be read" in err
    assert main(["links", str(P2S_MULTI), "--fps", "25", "--quiet", "--names", "left_shoulder", "left_elbow",
                 "left_wrist"]) == 0
    assert "1 detection(s) could not be read" in capsys.readouterr().err


def test_links_on_real_data_with_never_detected_joints(tmp_path, capsys):
    """Participant A of the real trial: eyes and ears never detected (0 0 0 in every
    frame). ``pinrecon links`` ended in LinAlgError: Singular matrix."""
    frames = []
    for f in sorted(P2S_MULTI.glob("*.json")):
        a = [p for p in raw_people(f) if len(p) and identity(p) == "A"]
        frames.append(as_points(a[0]))
    tracks = pr.Tracks(np.stack(frames), BODY25B, 25.0)
    assert np.isnan(tracks.points[:, 1:5]).all()
    tracks.save(tmp_path / "a.json")
    names = ["--names", "left_eye", "left_shoulder", "left_elbow", "left_wrist", "left_hip"]
    assert main(["links", str(tmp_path / "a.json"), *names]) == 0
    assert "hinged triples" in capsys.readouterr().out
    assert main(["links", str(P2S_MULTI), "--fps", "25", "--quiet", *names]) == 0


def test_cli_person_and_layout_options(tmp_path, capsys):
    assert main(["links", str(P2S_MULTI), "--fps", "25", "--person", "300,300,800,1200", "--layout", "body25b",
                 "--names", "left_hip", "left_knee", "left_ankle"]) == 0
    err = capsys.readouterr().err
    assert "followed one person from frame 2" in err
    assert main(["links", str(P2S_MULTI), "--fps", "25", "--person", "5,5"]) == 2
    assert "expected an index, 'largest' or a box" in capsys.readouterr().err
