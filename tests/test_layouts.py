"""The layouts registry and the human's keypoint maps, checked against the figure.

Registry-driven: every layout is walked; every bundled human map is loaded on the
human and its new points are checked against positions computed here from Pinocchio's
frame placements and the foot mesh (read from the STL here), not from the maps.
"""

from __future__ import annotations

import json
import struct

import numpy as np
import pinocchio as pin
import pytest
from conftest import data_dir, data_file

from pinrecon import Figure, InputError
from pinrecon._resources import example_robot_data_robots
from pinrecon.layouts import (
    LAYOUTS,
    MEDIAPIPE_OFF_MAP,
    Layout,
    get_layout,
    human_keypoint_map,
    human_keypoint_maps,
    known_point_names,
    layout_from_names,
    layouts_with,
)
from pinrecon.layouts.detect import check_layout, checks_for, detect_layout

DET = data_dir("project-test-data/detectors")


# ---------------------------------------------------------------------------- the registry
@pytest.mark.parametrize("name", sorted(LAYOUTS))
def test_every_layout_is_consistent(name):
    lay = LAYOUTS[name]
    assert len(set(lay.names)) == len(lay.names) <= lay.n_points
    assert lay.human_map in human_keypoint_maps()
    assert get_layout(lay.name.upper()) is lay
    for alias in lay.aliases:
        assert get_layout(alias) is lay
    if lay.file_names:
        assert len(lay.file_names) == len(lay.names) and layout_from_names(lay.file_names) is lay


@pytest.mark.parametrize("name", sorted(LAYOUTS))
def test_every_layout_points_the_human_can_carry_are_on_its_map(name):
    lay = LAYOUTS[name]
    human = Figure.human(lay.human_map)
    carried = [n for n in lay.names if n in human.keypoint_names]
    missing = [n for n in lay.names if n not in human.keypoint_names]
    # MediaPipe's hand points (no fingers) and eye and mouth corners (left off: MEDIAPIPE_OFF_MAP), H36M's
    # spine/thorax/neck-nose
    assert all(n.startswith("h36m_") or n in MEDIAPIPE_OFF_MAP for n in missing), missing
    assert len(carried) >= 12


def test_layouts_by_count_and_unknown_name():
    assert [lay.name for lay in layouts_with(25)] == ["body25", "body25b"]
    assert [lay.name for lay in layouts_with(17)] == ["coco17", "h36m17"]
    assert layouts_with(10) == []
    with pytest.raises(InputError) as exc:
        get_layout("body_26")
    assert "unknown layout 'body_26'" in str(exc.value) and "body25b (OpenPose BODY_25B, 25 points)" in str(exc.value)


def test_file_names_are_recognised():
    coco = json.loads((DET / "mmpose_coco17_dataset.json").read_text())["categories"][0]["keypoints"]
    crowd = json.loads((DET / "mmpose_crowdpose14_dataset.json").read_text())["categories"][0]["keypoints"]
    assert layout_from_names(coco).name == "coco17"
    assert layout_from_names(crowd).name == "crowdpose14"
    assert layout_from_names(["Nose", "Neck"] + ["x"] * 23) is None


def test_known_names_include_every_layout():
    names = known_point_names()
    for lay in LAYOUTS.values():
        assert set(lay.names) <= names
    assert {"neck", "upper_neck", "mid_hip", "head_top", "left_heel"} <= names


# ---------------------------------------------------------------------------- human maps
def test_bundled_maps_and_bad_names():
    assert set(human_keypoint_maps()) == {"coco17", "body25", "body25b", "halpe26", "joints", "mediapipe33"}
    assert human_keypoint_map("BODY25") == human_keypoint_maps()["body25"]
    with pytest.raises(InputError, match=r"unknown keypoint map 'body_25x'.*body25, body25b, coco17, halpe26, joints, "
                       r"mediapipe33"):
        Figure.human("body_25x")


@pytest.fixture(scope="module")
def body_maps():
    return {m: Figure.human(m) for m in ("coco17", "body25", "body25b", "halpe26", "mediapipe33")}


def frame_origin(fig, q, frame):
    data = fig.model.createData()
    pin.forwardKinematics(fig.model, data, q)
    pin.updateFramePlacements(fig.model, data)
    return data.oMf[fig.model.getFrameId(frame)]


def random_configurations(fig, n, seed=0, zero=()):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        q = pin.randomConfiguration(fig.model)
        q[:3] = rng.normal(size=3)
        for j in zero:
            jid = fig.model.getJointId(j)
            q[fig.model.idx_qs[jid]] = 0.0
        out.append(q)
    return out


def test_coco_points_are_the_same_on_every_map(body_maps):
    ref = {k.name: k for k in body_maps["coco17"].keypoints_def}
    for fig in body_maps.values():
        for k in fig.keypoints_def:
            if k.name in ref:
                assert (k.frame, k.offset) == (ref[k.name].frame, ref[k.name].offset)


def test_neck_is_the_shoulders_midpoint(body_maps):
    """Exact with the clavicle joints at zero, whatever the rest of the pose."""
    fig = body_maps["body25"]
    clav = [n for n in fig.model.names if "clavicle" in n]
    for q in random_configurations(fig, 5, zero=clav):
        P = dict(zip(fig.keypoint_names, fig.keypoints(q[None])[0]))
        ls = frame_origin(fig, q, "left_upperarm").translation
        rs = frame_origin(fig, q, "right_upperarm").translation
        np.testing.assert_allclose(P["neck"], (ls + rs) / 2, atol=1e-9)


@pytest.mark.parametrize("m", ["body25", "halpe26"])
def test_mid_hip_is_the_hips_midpoint(body_maps, m):
    fig = body_maps[m]
    for q in random_configurations(fig, 5, seed=1):
        P = dict(zip(fig.keypoint_names, fig.keypoints(q[None])[0]))
        lh = frame_origin(fig, q, "left_upperleg").translation
        rh = frame_origin(fig, q, "right_upperleg").translation
        np.testing.assert_allclose(P["mid_hip"], (lh + rh) / 2, atol=1e-9)


def test_upper_neck_and_head_top(body_maps):
    fig = body_maps["body25b"]
    q = pin.neutral(fig.model)
    P = dict(zip(fig.keypoint_names, fig.keypoints(q[None])[0]))
    head = frame_origin(fig, q, "middle_head")
    np.testing.assert_allclose(P["upper_neck"], head.translation, atol=1e-12)
    mid = (frame_origin(fig, q, "left_upperarm").translation + frame_origin(fig, q, "right_upperarm").translation) / 2
    frac = (P["upper_neck"][1] - mid[1]) / (P["nose"][1] - mid[1])
    assert 0.46 <= frac <= 0.58  # measured on real BODY_25B and Halpe-26 detections
    assert P["head_top"][1] > P["nose"][1] > P["upper_neck"][1]


def foot_mesh_box():
    path = example_robot_data_robots() / "human_description" / "meshes" / "foot_mesh.STL"
    b = path.read_bytes()
    n = struct.unpack("<I", b[80:84])[0]
    tri = np.frombuffer(b[84 : 84 + 50 * n], dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]))
    v = tri["v"].reshape(-1, 3) * 0.0067  # the URDF's mesh scale
    return v.min(axis=0), v.max(axis=0)


@pytest.mark.parametrize("m", ["body25", "body25b", "halpe26"])
def test_feet_points_sit_on_the_foot(body_maps, m):
    fig = body_maps[m]
    lo, hi = foot_mesh_box()
    for side, medial in (("left", +1), ("right", -1)):
        off = {k.name: np.array(k.offset) for k in fig.keypoints_def if k.frame == f"{side}_foot"}
        for name in ("big_toe", "small_toe", "heel"):
            p = off[f"{side}_{name}"]
            assert np.all(p >= lo - 1e-3) and np.all(p <= hi + 1e-3), (side, name, p)  # on the mesh surface
            assert p[1] < -0.05  # near the sole, below the ankle
        assert off[f"{side}_heel"][0] < -0.05 < 0.15 < off[f"{side}_small_toe"][0] < off[f"{side}_big_toe"][0]
        assert medial * (off[f"{side}_big_toe"][2] - off[f"{side}_small_toe"][2]) > 0.03  # big toe inside


def test_mediapipe_feet_and_face_points(body_maps):
    """BlazePose's heel and foot tip on the foot mesh (the tip at its front, on the mid-line);
    its face points those of COCO-17 (the eye and mouth corners on no map)."""
    fig = body_maps["mediapipe33"]
    lo, hi = foot_mesh_box()
    off = {k.name: np.array(k.offset) for k in fig.keypoints_def}
    for side, out in (("left", -1), ("right", +1)):
        tip, heel = off[f"{side}_foot_index"], off[f"{side}_heel"]
        for p in (tip, heel):
            assert np.all(p >= lo - 1e-3) and np.all(p <= hi + 1e-3) and p[1] < -0.05
        assert tip[0] > hi[0] - 0.01 and abs(tip[2]) < 0.01 and heel[0] < lo[0] + 0.01
        assert off[f"{side}_eye"][2] * out > 0 and off[f"{side}_ear"][2] * out > 0
    coco = {k.name: np.array(k.offset) for k in body_maps["coco17"].keypoints_def}
    face = {n for n in off if fig.keypoints_def[fig.keypoint_names.index(n)].frame == "middle_head"}
    assert face == {"nose", "left_eye", "right_eye", "left_ear", "right_ear"}
    assert all(np.allclose(off[n], coco[n]) for n in face)


# ---------------------------------------------------------------------------- geometry
def raw_points(path, index=0):
    p = np.array(json.loads(path.read_text())["people"][index]["pose_keypoints_2d"], float).reshape(-1, 3)
    xy = p[:, :2].copy()
    xy[p[:, 2] <= 0] = np.nan
    return xy[None]


def test_geometry_tells_body25_from_body25b():
    body25 = np.concatenate([raw_points(DET / "spin_body25" / "im1010_openpose.json"),
                             raw_points(next((DET / "prohmr_body25").glob("*.json")))])
    body25b = raw_points(data_file("project-test-data/calibration/pose2sim/static_trial/Static_cam_01.00000.json"))
    a, b = LAYOUTS["body25"], LAYOUTS["body25b"]
    assert check_layout(body25, a).fits and check_layout(body25, b).contradicted
    assert check_layout(body25b, b).fits and check_layout(body25b, a).contradicted
    assert detect_layout(body25, [a, b]) == (a, None)
    assert detect_layout(body25b, [a, b]) == (b, None)


def test_geometry_refuses_to_guess_when_two_fit():
    pts = raw_points(DET / "spin_body25" / "im1010_openpose.json")
    twin = Layout("body25_twin", "a twin of BODY_25", 25, LAYOUTS["body25"].names, "body25")
    with pytest.raises(InputError, match="cannot tell OpenPose BODY_25 and a twin of BODY_25 apart"):
        detect_layout(pts, [LAYOUTS["body25"], twin])


def test_geometry_falls_back_to_the_default_with_a_warning():
    line = np.stack([100.0 + 10 * np.arange(25), 200.0 + 5.0 * np.arange(25)], axis=1)[None]
    lay, note = detect_layout(line, layouts_with(25), default=LAYOUTS["body25"])
    assert lay.name == "body25" and "fit none of" in note and "read as OpenPose BODY_25" in note
    with pytest.raises(InputError, match="fit none of the layouts"):
        detect_layout(line, layouts_with(25))


def test_checks_follow_the_names():
    names = {c.point for c in checks_for(LAYOUTS["body25"].names)}
    assert {"neck", "mid_hip", "left_eye", "left_big_toe"} <= names
    assert "neck" not in {c.point for c in checks_for(LAYOUTS["body25b"].names)}


# ------------------------------------------------- Figure.human("auto", tracks=...): the CLI's choice
def _quiet_load(path, **kw):
    import warnings

    from pinrecon import load_tracks

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_tracks(path, **kw)


@pytest.mark.parametrize(("folder", "expected"), [("pose2sim_body25b_multi", "body25b"),
                                                  ("pose2sim_halpe26", "halpe26"),
                                                  ("openpose_coco18", "body25")])
def test_human_auto_takes_the_map_of_real_detector_files(folder, expected):
    tracks = _quiet_load(DET / folder, fps=25.0)
    fig = Figure.human("auto", tracks=tracks)
    assert fig.keypoint_names == Figure.human(expected).keypoint_names
    assert Figure.human("auto", tracks=[tracks, tracks]).keypoint_names == fig.keypoint_names  # one per camera


def test_human_auto_without_a_layout_takes_the_map_carrying_most_names():
    from pinrecon import Tracks

    def tracks(names):
        return Tracks(np.zeros((2, len(names), 2)), list(names), 30.0)

    coco = list(LAYOUTS["coco17"].names)
    assert Figure.human("auto", tracks=tracks(coco)).keypoint_names == Figure.human("coco17").keypoint_names
    # BODY_25B's names without their layout: body25b and halpe26 carry all 25, body25 only 23
    b25b = tracks(LAYOUTS["body25b"].names)
    assert b25b.layout is None
    chosen = set(Figure.human("auto", tracks=b25b).keypoint_names)
    assert set(LAYOUTS["body25b"].names) <= chosen
    # names no map carries: COCO-17
    assert Figure.human("auto", tracks=tracks(["a", "b", "c", "d"])).keypoint_names == Figure.human().keypoint_names


def test_human_auto_needs_tracks_and_tracks_need_auto():
    tracks = _quiet_load(DET / "pose2sim_halpe26", fps=25.0)
    with pytest.raises(InputError) as e:
        Figure.human("auto")
    assert e.value.field == "keypoints" and "tracks=" in str(e.value)
    with pytest.raises(InputError) as e:
        Figure.human("coco17", tracks=tracks)
    assert e.value.field == "tracks"


def test_points_the_generic_human_ignores_name_the_map_that_carries_them():
    from pinrecon.problem import shared_keypoints

    names = list(LAYOUTS["body25b"].names)
    with pytest.warns(UserWarning, match=r"ignored: .*Figure\.human\('body25b'\)") as rec:
        shared = shared_keypoints(Figure.human(), names, "t.json")
    assert len(rec) == 1 and len(shared) == 17
    # the map that carries them all: nothing ignored, no warning
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(shared_keypoints(Figure.human("body25b"), names, "t.json")) == 25
    # a figure that is not the generic human gets no hint
    joints = Figure.human("joints")
    joints.meta.pop("generic")
    with pytest.warns(UserWarning) as rec:
        shared_keypoints(joints, names[:17] + ["left_wrist"], "t.json")
    assert all("Figure.human(" not in str(w.message) for w in rec)
