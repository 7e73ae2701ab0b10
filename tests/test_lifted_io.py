"""A lifter's 3D cues in files: the ``lifted`` block of pinrecon's tracks JSON and NPZ
(exact round trips, located errors)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pinrecon import InputError, Tracks, load_tracks
from pinrecon.lifted import Lifted

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
