"""A lifter's 3D cues in files: the ``lifted`` block of pinrecon's tracks JSON and NPZ
(exact round trips, located errors), and other lifters' own files (MotionBERT /
VideoPose3D ``.npy``, MMPose's 3D JSON) written here to their projects' documented layout
and read back: numbers, joint names, axes, wrong joint count or order, NaN, frame count."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pinrecon import InputError, Tracks, load_tracks
from pinrecon.cli import main
from pinrecon.lifted import Lifted, load_lifted

NAMES = ["nose", "left_knee", "right_knee"]


def tracks_with_lifted(camera=1, source="mediapipe", confidence=True):
    rng = np.random.default_rng(7)
    pts3 = rng.normal(size=(5, 3, 3))
    pts3[2, 1] = np.nan
    conf = rng.uniform(0.05, 1.0, size=(5, 3)) if confidence else None
    lifted = Lifted(pts3, NAMES, conf, "camera", source, camera)
    return Tracks(rng.uniform(0, 640, size=(5, 3, 2)), NAMES, 30.0, lifted=lifted)


@pytest.mark.parametrize("suffix", [".json", ".npz"])
@pytest.mark.parametrize("source", ["mediapipe", None])
def test_tracks_carry_lifted_exactly(tmp_path, suffix, source):
    tracks = tracks_with_lifted(source=source)
    path = tmp_path / f"tracks{suffix}"
    tracks.save(path)
    back = load_tracks(path).lifted
    assert isinstance(back, Lifted)
    np.testing.assert_array_equal(back.points, tracks.lifted.points)  # NaN where missing, bit-exact
    np.testing.assert_array_equal(back.confidence, tracks.lifted.confidence)
    assert np.isnan(back.points[2, 1]).all() and back.confidence[2, 1] == 0.0
    assert back.names == NAMES and back.frame == "camera" and back.source == source and back.camera == 1


@pytest.mark.parametrize("suffix", [".json", ".npz"])
def test_tracks_without_lifted_stay_without(tmp_path, suffix):
    t = tracks_with_lifted()
    plain = Tracks(t.points, t.names, t.fps)
    plain.save(tmp_path / f"t{suffix}")
    assert load_tracks(tmp_path / f"t{suffix}").lifted is None
    if suffix == ".json":
        assert "lifted" not in json.loads((tmp_path / "t.json").read_text())


def test_lifted_json_block_by_hand_and_its_errors(tmp_path):
    doc = {
        "fps": 25, "names": ["nose"], "points": [[[1.0, 2.0]], [[3.0, 4.0]]],
        "lifted": {"names": ["nose", "left_hip"], "frame": "unknown",
                   "points": [[[0.1, 0.2, 0.3], None], [[0.4, 0.5, 0.6], [1.0, 2.0, 3.0]]]},
    }
    path = tmp_path / "t.json"
    path.write_text(json.dumps(doc))
    lf = load_tracks(path).lifted
    np.testing.assert_array_equal(lf.points[1], [[0.4, 0.5, 0.6], [1.0, 2.0, 3.0]])
    assert np.isnan(lf.points[0, 1]).all()
    np.testing.assert_array_equal(lf.confidence, [[1.0, 0.0], [1.0, 1.0]])  # default 1, 0 where missing
    assert lf.frame == "unknown" and lf.source is None and lf.camera == 0

    def refused(mutate):
        bad = json.loads(json.dumps(doc))
        mutate(bad["lifted"])
        path.write_text(json.dumps(bad))
        with pytest.raises(InputError) as err:
            load_tracks(path)
        assert err.value.file == str(path)
        return err.value

    e = refused(lambda b: b["points"][1].__setitem__(0, [1.0, "x", 3.0]))
    assert e.field == "lifted.points" and e.frame == 1 and "'nose'" in str(e)
    e = refused(lambda b: b["points"][1].__setitem__(0, [1.0, 2.0]))
    assert e.field == "lifted.points" and e.frame == 1 and "[x, y, z]" in str(e)
    e = refused(lambda b: b["points"].pop())
    assert e.field == "lifted" and "1 frames of lifted 3D for 2 frames" in str(e)
    e = refused(lambda b: b.__setitem__("frame", "world"))
    assert e.field == "lifted frame"
    e = refused(lambda b: b.__setitem__("confidence", [[1.0, 1.0]]))
    assert e.field == "lifted.confidence"
    e = refused(lambda b: b.__setitem__("names", ["nose", "nose"]))
    assert e.field == "lifted names"


def test_lifted_npz_frame_count_is_checked(tmp_path):
    t = tracks_with_lifted()
    path = tmp_path / "t.npz"
    t.save(path)
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["lifted_points"] = arrays["lifted_points"][:4]
    arrays["lifted_confidence"] = arrays["lifted_confidence"][:4]
    np.savez(path, **arrays)
    with pytest.raises(InputError, match="4 frames of lifted 3D for 5 frames") as err:
        load_tracks(path)
    assert err.value.file == str(path) and err.value.field == "lifted"


# ------------------------------------------------------------- other lifters' files

# a standing person facing the camera, Human3.6M-17 order, camera axes (x right, y down,
# z forward), metres: the pose MotionBERT / VideoPose3D files hold per frame
H36M_POSE = np.array([
    [0.0, 0.0, 3.0], [-0.12, 0.0, 3.0], [-0.13, 0.45, 3.02], [-0.13, 0.88, 3.05],      # pelvis, right leg
    [0.12, 0.0, 3.0], [0.13, 0.45, 3.0], [0.14, 0.88, 3.0],                             # left leg
    [0.0, -0.25, 3.0], [0.0, -0.5, 3.0], [0.0, -0.6, 2.95], [0.0, -0.72, 3.0],          # spine, thorax, nose, head
    [0.18, -0.48, 3.0], [0.2, -0.2, 3.0], [0.22, 0.05, 2.95],                           # left arm
    [-0.18, -0.48, 3.0], [-0.2, -0.2, 3.0], [-0.22, 0.05, 2.9],                         # right arm
])
H36M_NAMES = ["mid_hip", "right_hip", "right_knee", "right_ankle", "left_hip", "left_knee", "left_ankle",
              "h36m_spine", "h36m_thorax", "h36m_neck_nose", "head_top", "left_shoulder", "left_elbow", "left_wrist",
              "right_shoulder", "right_elbow", "right_wrist"]


def clip3d(T=4):
    """(T, 17, 3): the pose walking 1 cm per frame to the right."""
    return H36M_POSE[None] + np.arange(T)[:, None, None] * np.array([0.01, 0.0, 0.0])


@pytest.mark.parametrize("fmt", [None, "motionbert", "videopose3d"])
def test_motionbert_videopose3d_npy(tmp_path, fmt):
    pts = clip3d().astype(np.float32)  # MotionBERT saves float32
    np.save(tmp_path / "X3D.npy", pts)
    lf = load_lifted(tmp_path / "X3D.npy", fmt=fmt)
    np.testing.assert_array_equal(lf.points, pts.astype(float))
    assert lf.names == H36M_NAMES and lf.frame == "camera" and lf.source == str(tmp_path / "X3D.npy")
    np.testing.assert_array_equal(lf.confidence, np.ones((4, 17)))
    assert load_lifted(tmp_path / "X3D.npy", fmt=fmt, frame="unknown").frame == "unknown"
    # a leading axis of 1 (one clip) is dropped
    np.save(tmp_path / "batch.npy", pts[None])
    np.testing.assert_array_equal(load_lifted(tmp_path / "batch.npy").points, pts.astype(float))


def _refused(path, **kw):
    with pytest.raises(InputError) as err:
        load_lifted(path, **kw)
    assert err.value.file == str(path)
    return err.value


def test_npy_errors_name_file_field_frame(tmp_path):
    path = tmp_path / "x.npy"
    np.save(path, clip3d()[:, :16])
    e = _refused(path)
    assert e.field == "points" and "expected 17 joints per frame (Human3.6M-17), got 16" in str(e)
    np.save(path, clip3d()[..., :2])
    assert "(T, joints, 3)" in str(_refused(path))
    bad = clip3d()
    bad[2, 12, 1] = np.nan
    np.save(path, bad)
    e = _refused(path)
    assert (e.field, e.frame) == ("points", 2) and "'left_elbow'" in str(e)
    np.save(path, np.array(["a", "b"]))
    assert "numeric" in str(_refused(path))
    path.write_text("not an array")
    assert "not a NumPy .npy array" in str(_refused(path))


def test_a_joint_order_that_cannot_be_h36m_is_refused(tmp_path):
    path = tmp_path / "x.npy"
    # COCO-17's order (nose, eyes, ears, shoulders, elbows, wrists, hips, knees, ankles)
    coco = [9, 10, 10, 10, 10, 11, 14, 12, 15, 13, 16, 4, 1, 5, 2, 6, 3]
    np.save(path, clip3d()[:, coco])
    e = _refused(path)
    assert e.field == "points" and "not in Human3.6M-17 order" in str(e) and "layout=" in str(e)
    # the legs before the pelvis
    np.save(path, clip3d()[:, [1, 2, 3, 4, 5, 6, 0] + list(range(7, 17))])
    assert "not in Human3.6M-17 order" in str(_refused(path))
    # the COCO-ordered file is read when its layout is named
    np.save(path, clip3d()[:, coco])
    lf = load_lifted(path, layout="coco17")
    assert lf.names[0] == "nose" and lf.names[-1] == "right_ankle"
    np.testing.assert_array_equal(lf.points, clip3d()[:, coco])
    # or its names
    own = [f"p{i}" for i in range(17)]
    assert load_lifted(path, names=own).names == own
    assert "3 names given for 17 joints" in str(_refused(path, names=["a", "b", "c"]))


def mmpose3d_frames(T=4, track_ids=False):
    """MMPose's 3D inferencer video output: display axes X = -x, Y = z, Z = -y (camera x, y, z),
    two people in track order; with ``track_ids`` (as some scripts add them) the order changes
    after the first frame."""
    cam = clip3d(T)
    disp = np.stack([-cam[..., 0], cam[..., 2], -cam[..., 1]], axis=-1)
    other = disp + np.array([1.5, 0.0, 0.0])
    frames = []
    for t in range(T):
        me = {"keypoints": disp[t].tolist(), "keypoint_scores": [0.5 + 0.01 * k for k in range(17)],
              "bbox": [10.0, 20.0, 200.0, 400.0], "bbox_score": 0.9}
        them = {"keypoints": other[t].tolist(), "keypoint_scores": [1.0] * 17}
        instances = [me, them]
        if track_ids:
            me["track_id"], them["track_id"] = 3, 1
            instances = [me, them] if t == 0 else [them, me]
        frames.append({"frame_id": t, "instances": [] if t == 2 else instances})
    return frames


@pytest.mark.parametrize("track_ids", [False, True], ids=["mmpose", "with-track-ids"])
def test_mmpose3d_json_back_in_camera_axes(tmp_path, track_ids):
    path = tmp_path / "video.json"
    path.write_text(json.dumps(mmpose3d_frames(track_ids=track_ids)))
    lf = load_lifted(path)
    truth = clip3d()
    for t in (0, 1, 3):  # the first person followed (by its track id where the file has them)
        np.testing.assert_array_equal(lf.points[t], truth[t])
    assert np.isnan(lf.points[2]).all() and (lf.confidence[2] == 0).all()  # nobody in frame 2
    np.testing.assert_allclose(lf.confidence[3], 0.5 + 0.01 * np.arange(17), rtol=0, atol=0)
    assert lf.names == H36M_NAMES and lf.frame == "camera"
    # the inferencer's result dumped as is: {"predictions": [[instances of frame 0], ...]}
    path.write_text(json.dumps({"predictions": [f["instances"] for f in mmpose3d_frames()]}))
    np.testing.assert_array_equal(load_lifted(path, fmt="mmpose3d").points[3], truth[3])
    # the other person
    path.write_text(json.dumps(mmpose3d_frames()))
    other = load_lifted(path, person=1).points
    np.testing.assert_allclose(other[1], truth[1] + [-1.5, 0.0, 0.0], atol=1e-12)


def test_mmpose3d_errors_name_file_field_frame(tmp_path):
    path = tmp_path / "video.json"

    def broken(mutate):
        frames = mmpose3d_frames()
        mutate(frames)
        path.write_text(json.dumps(frames))
        return _refused(path)

    e = broken(lambda f: f[1]["instances"][0]["keypoints"].pop())
    assert (e.field, e.frame) == ("[1].instances[0].keypoints", 1) and "expected 17 keypoints, got 16" in str(e)
    e = broken(lambda f: f[3]["instances"][0]["keypoints"][4].__setitem__(0, "x"))
    assert (e.field, e.frame) == ("[3].instances[0].keypoints", 3)
    e = broken(lambda f: f[3]["instances"][0]["keypoint_scores"].pop())
    assert e.field == "[3].instances[0].keypoint_scores" and e.frame == 3
    e = broken(lambda f: [i["keypoints"].pop() for fr in f for i in fr["instances"]])
    assert "expected 17 joints per frame" in str(e) and e.frame is None
    e = broken(lambda f: f.pop(1))
    assert e.field == "frame_id" and "without gaps" in str(e)
    path.write_text(json.dumps(mmpose3d_frames()).replace("NaN", "0").replace("0.13,", "NaN,", 1))
    e = _refused(path)
    assert "NaN or infinite" in str(e) and e.frame == 0


def test_lifted_frame_count_must_match_the_tracks(tmp_path, capsys):
    np.save(tmp_path / "X3D.npy", clip3d(5))
    e = _refused(tmp_path / "X3D.npy", frames=4)
    assert e.field == "points" and "5 frames of lifted 3D for 4 frames of tracks" in str(e)
    Tracks(np.full((4, 1, 2), 300.0), ["nose"], 30.0).save(tmp_path / "t.json")
    code = main(["reconstruct", "--figure", "human", "--tracks", str(tmp_path / "t.json"), "--camera", "auto",
                 "--image-size", "640", "480", "--lifted", str(tmp_path / "X3D.npy"), "--out", str(tmp_path / "r.npz")])
    err = capsys.readouterr().err
    assert code == 2 and "X3D.npy" in err and "5 frames of lifted 3D for 4 frames" in err and "Traceback" not in err
    assert not (tmp_path / "r.npz").exists()
    code = main(["reconstruct", "--figure", "human", "--tracks", str(tmp_path / "t.json"), "--camera", "auto",
                 "--lifted", str(tmp_path / "X3D.npy"), "--lifted", str(tmp_path / "X3D.npy"), "--out",
                 str(tmp_path / "r.npz")])
    assert code == 2 and "2 --lifted for 1 --tracks" in capsys.readouterr().err


def test_lifted_file_attached_to_tracks_round_trips(tmp_path):
    from dataclasses import replace

    np.save(tmp_path / "X3D.npy", clip3d(4))
    tracks = Tracks(np.full((4, 1, 2), 300.0), ["nose"], 30.0)
    with_3d = replace(tracks, lifted=load_lifted(tmp_path / "X3D.npy", frames=tracks.T))
    with_3d.save(tmp_path / "t.npz")
    back = load_tracks(tmp_path / "t.npz").lifted
    np.testing.assert_array_equal(back.points, clip3d(4))
    assert back.names == H36M_NAMES and back.source == str(tmp_path / "X3D.npy")


def test_reconstruct_lifted_reaches_the_pipeline(tmp_path, monkeypatch):
    """``pinrecon reconstruct --lifted FILE``: the tracks handed to ``reconstruct`` carry the
    file's points (the solve itself is replaced here; it is the rows' business)."""
    import importlib

    pipeline = importlib.import_module("pinrecon.reconstruct")  # the module (the package exports the function)
    seen = {}

    class Stop(Exception):
        pass

    def fake(figure, tracks, camera, keyframes=None, **kw):
        seen["tracks"] = tracks
        raise Stop

    monkeypatch.setattr(pipeline, "reconstruct", fake)
    np.save(tmp_path / "X3D.npy", clip3d(4))
    Tracks(np.full((4, 1, 2), 300.0), ["nose"], 30.0).save(tmp_path / "t.json")
    with pytest.raises(Stop):
        main(["reconstruct", "--figure", "human", "--tracks", str(tmp_path / "t.json"), "--camera", "auto",
              "--image-size", "640", "480", "--lifted", str(tmp_path / "X3D.npy"), "--out", str(tmp_path / "r.npz")])
    lf = seen["tracks"].lifted
    np.testing.assert_array_equal(lf.points, clip3d(4))
    assert lf.names == H36M_NAMES and lf.frame == "camera" and lf.camera == 0
