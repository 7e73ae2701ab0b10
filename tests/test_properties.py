"""Property-based tests of the reading layer (issue 44), with Hypothesis.

Two properties for every reader: on generated malformed input it loads or raises
``InputError``, never anything else; on generated valid data, writing then reading gives
the data back (tracks JSON and NPZ, cameras, keyframes, result NPZ, BVH export/import, TRC
export/import, JSON text). Example counts come from the Hypothesis profile (conftest:
``ci`` by default, ``PINRECON_HYPOTHESIS_PROFILE=long`` for a deeper run).
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from fuzzing_files import SMALL_BVH, STICK_KEYPOINTS, STICK_URDF
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pinrecon.errors import InputError

SETTINGS = settings(deadline=None, suppress_health_check=list(HealthCheck))

# ---------------------------------------------------------------------------- strategies
FLOATS = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -0.0, 1e300, -1e300, 1e-320]))
SCALARS = st.one_of(st.none(), st.booleans(), st.integers(), st.integers(min_value=-(10**60), max_value=10**60),
                    FLOATS, st.text(max_size=8))
JSON_VALUES = st.recursive(SCALARS, lambda kids: st.one_of(st.lists(kids, max_size=5),
                                                          st.dictionaries(st.text(max_size=8), kids, max_size=5)),
                           max_leaves=25)


def _dumps(value) -> bytes:
    return json.dumps(value, allow_nan=True).encode()


def keyed(base: dict):
    """A dict shaped like ``base`` whose values are replaced, dropped or kept at random."""
    return st.fixed_dictionaries({}, optional={k: st.one_of(st.just(v), JSON_VALUES) for k, v in base.items()})


CAMERA = {"model": "orthographic", "R": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "scale": 300.0, "center": [640.0, 360.0]}
PERSP = {"model": "perspective", "K": [[1000.0, 0, 640.0], [0, 1000.0, 360.0], [0, 0, 1]],
         "R": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "t": [0.0, 1.0, 4.0], "dist": [0.01, -0.002, 0, 0, 0]}
TRACKS = {"fps": 25.0, "names": ["a", "b"], "points": [[[1.0, 2.0], None], [[3.0, 4.0], [5.0, 6.0]]],
          "confidence": [[0.9, 0.0], [0.8, 0.7]]}
KEYFRAME = {"frame": 0, "sigma": 0.05, "joints": {"j1": 0.3}}


def _loads_or_input_error(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        warnings.simplefilter("error", RuntimeWarning)
        try:
            return fn(*args, **kw)
        except InputError:
            return None


def _readers():
    from pinrecon import Figure
    from pinrecon.cameras import load_camera
    from pinrecon.figure import load_keypoint_map
    from pinrecon.io.asf import read_asf
    from pinrecon.io.bvh import load_bvh
    from pinrecon.io.calibration import load_cameras
    from pinrecon.io.trc import load_trc
    from pinrecon.joint_limits import load_limits
    from pinrecon.result import load_result
    from pinrecon.tracks import load_keyframes, load_tracks

    return {
        ".tracks.json": lambda p: load_tracks(p, fps=25.0), "tracks.npz": lambda p: load_tracks(p, fps=25.0),
        ".keyframes.json": load_keyframes, ".camera.json": load_camera, ".calib.json": load_cameras,
        ".toml": load_cameras, ".yml": load_cameras, ".kp.json": load_keypoint_map, ".limits.json": load_limits,
        ".urdf": Figure.from_urdf, ".bvh": load_bvh, ".asf": read_asf, ".trc": load_trc, "result.npz": load_result,
    }


READERS = _readers()
TEXT_READERS = [".urdf", ".bvh", ".asf", ".trc", ".toml", ".yml"]
JSON_READERS = [k for k in READERS if k.endswith(".json")]


# ---------------------------------------------------------------------------- malformed input
@pytest.mark.parametrize("suffix", JSON_READERS)
@SETTINGS
@given(doc=st.one_of(JSON_VALUES, keyed(TRACKS), keyed(CAMERA), keyed(PERSP),
                     st.builds(lambda k: {"keyframes": [k]}, keyed(KEYFRAME)),
                     st.builds(lambda v: {"keypoints": v}, JSON_VALUES),
                     st.builds(lambda v: {"units": "degrees", "limits": v}, JSON_VALUES)))
def test_json_readers_load_or_raise_input_error(tmp_path_factory, suffix, doc):
    path = tmp_path_factory.mktemp("j") / f"case{suffix}"
    path.write_bytes(_dumps(doc))
    _loads_or_input_error(READERS[suffix], path)


@pytest.mark.parametrize("suffix", list(READERS))
@SETTINGS
@given(data=st.binary(max_size=300))
def test_every_reader_takes_any_bytes(tmp_path_factory, suffix, data):
    path = tmp_path_factory.mktemp("b") / f"case{suffix}"
    path.write_bytes(data)
    _loads_or_input_error(READERS[suffix], path)


def _lines_strategy(text: str):
    lines = text.split("\n")
    numbers = st.sampled_from(["nan", "inf", "-1e300", "1e999", "0", "-4", "x", "9" * 5000, ""])
    return st.lists(st.tuples(st.integers(0, len(lines) - 1), st.integers(0, 40), numbers), max_size=4).map(
        lambda edits: _edit(lines, edits))


def _edit(lines, edits):
    out = list(lines)
    for i, col, new in edits:
        words = out[i].split(" ")
        words[col % len(words)] = new
        out[i] = " ".join(words)
    return "\n".join(out)


@pytest.mark.parametrize("suffix, seed", [(".bvh", SMALL_BVH), (".urdf", STICK_URDF)])
@SETTINGS
@given(data=st.data())
def test_text_readers_with_bad_numbers(tmp_path_factory, suffix, seed, data):
    path = tmp_path_factory.mktemp("t") / f"case{suffix}"
    path.write_text(data.draw(_lines_strategy(seed)))
    _loads_or_input_error(READERS[suffix], path)


ARRAYS = st.one_of(
    st.builds(np.array, st.lists(FLOATS, max_size=6)),
    st.builds(lambda t, v: np.full((t, 8), v), st.integers(0, 4), FLOATS),
    st.builds(lambda s: np.array(s), st.text(max_size=40)),
    st.builds(lambda s: np.array(s), JSON_VALUES.map(json.dumps)),
    st.just(np.ones((5, 8), complex)), st.just(np.array(7)), st.just(np.ones((5, 3, 3))),
)


@pytest.fixture(scope="module")
def result_arrays():
    from fuzzing_files import stick_result_arrays

    return stick_result_arrays()


@SETTINGS
@given(changes=st.dictionaries(st.sampled_from(["q", "times", "keypoints3d", "keypoint_names", "joint_names", "fps",
                                                "figure_urdf", "figure_keypoints", "figure_limits", "figure_meta",
                                                "camera", "calibration", "observed_frames", "figure_floating"]),
                               st.one_of(st.none(), ARRAYS), min_size=1, max_size=3),
       cut=st.one_of(st.none(), st.integers(0, 4000)))
def test_result_npz_loads_or_raises_input_error(tmp_path_factory, result_arrays, changes, cut):
    arrays = dict(result_arrays)
    for k, v in changes.items():
        if v is None:
            arrays.pop(k, None)
        else:
            arrays[k] = v
    path = tmp_path_factory.mktemp("r") / "result.npz"
    np.savez(path, **arrays)
    if cut is not None:
        path.write_bytes(path.read_bytes()[:cut])
    res = _loads_or_input_error(READERS["result.npz"], path)
    if res is not None:
        assert np.all(np.isfinite(res.q)) and math.isfinite(res.fps) and res.fps > 0


# ---------------------------------------------------------------------------- round trips
def _rotation(v):
    q = np.asarray(v, float)
    q = q / np.linalg.norm(q)
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


UNIT = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda v: np.linalg.norm(v) > 0.1)
COORD = st.floats(-1e4, 1e4, allow_nan=False)


@SETTINGS
@given(T=st.integers(1, 6), K=st.integers(1, 5), fps=st.floats(1, 1000), seed=st.integers(0, 2**32 - 1),
       suffix=st.sampled_from([".json", ".npz"]))
def test_tracks_round_trip(tmp_path_factory, T, K, fps, seed, suffix):
    from pinrecon.tracks import Tracks, load_tracks

    rng = np.random.default_rng(seed)
    pts = rng.uniform(-1e4, 1e4, (T, K, 2))
    pts[rng.random((T, K)) < 0.3] = np.nan
    conf = np.where(np.isfinite(pts[..., 0]), rng.uniform(0.01, 1, (T, K)), 0.0)
    names = [f"p{k}" for k in range(K)]
    path = tmp_path_factory.mktemp("tr") / f"t{suffix}"
    Tracks(pts, names, fps, conf).save(path)
    back = load_tracks(path)
    np.testing.assert_allclose(back.points, pts, rtol=1e-12, equal_nan=True)
    assert back.names == names and back.fps == pytest.approx(fps, rel=1e-12)
    np.testing.assert_allclose(back.confidence, conf, rtol=1e-12)


@SETTINGS
@given(R=UNIT, scale=st.floats(1e-3, 1e5), center=st.tuples(COORD, COORD), f=st.floats(10, 1e5),
       t=st.tuples(COORD, COORD, COORD), dist=st.lists(st.floats(-0.5, 0.5), min_size=5, max_size=5),
       model=st.sampled_from(["orthographic", "perspective"]))
def test_camera_round_trip(tmp_path_factory, R, scale, center, f, t, dist, model):
    from pinrecon.cameras import Orthographic, Perspective, load_camera

    Rm = _rotation(R)
    if model == "orthographic":
        cam = Orthographic(Rm, scale, center)
    else:
        cam = Perspective(np.array([[f, 0, center[0]], [0, f, center[1]], [0, 0, 1]]), Rm, np.array(t), dist)
    path = tmp_path_factory.mktemp("c") / "camera.json"
    cam.save(path)
    back = load_camera(path)
    for key, value in vars(cam).items():
        if isinstance(value, np.ndarray):
            np.testing.assert_allclose(getattr(back, key), value, rtol=1e-12, atol=1e-12)
        elif isinstance(value, float):
            assert getattr(back, key) == pytest.approx(value, rel=1e-12)


@SETTINGS
@given(st.lists(st.tuples(st.integers(0, 10**6), st.floats(1e-6, 10), st.booleans(),
                          st.lists(st.floats(-1e4, 1e4), min_size=3, max_size=3)), min_size=1, max_size=5))
def test_keyframes_round_trip(tmp_path_factory, items):
    from pinrecon.tracks import Keyframe, Keyframes, load_keyframes

    kfs = Keyframes([Keyframe(f, s, points={"a": np.array(v)}) if p else Keyframe(f, s, joints={"j": np.array(v[0])})
                     for f, s, p, v in items])
    path = tmp_path_factory.mktemp("k") / "keyframes.json"
    kfs.save(path)
    back = load_keyframes(path)
    assert [(k.frame, k.sigma, k.kind) for k in back] == [(k.frame, k.sigma, k.kind) for k in kfs]
    for a, b in zip(back, kfs):
        for name, v in (b.points or b.joints).items():
            np.testing.assert_array_equal((a.points or a.joints)[name], v)


@pytest.fixture(scope="module")
def stick():
    from pinrecon import Figure
    from pinrecon.figure import parse_keypoint_entries

    return Figure.from_urdf_string(STICK_URDF, parse_keypoint_entries(STICK_KEYPOINTS["keypoints"]), root="free")


MOTION = st.tuples(st.integers(1, 6), st.integers(0, 2**32 - 1), st.floats(1, 500))


def _motion(fig, T, seed):
    rng = np.random.default_rng(seed)
    q = np.zeros((T, fig.nq))
    q[:, :3] = rng.uniform(-5, 5, (T, 3))
    quat = rng.normal(size=(T, 4))
    q[:, 3:7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    q[:, 7] = rng.uniform(-2, 2, T)
    return q


@SETTINGS
@given(MOTION)
def test_result_round_trip(tmp_path_factory, stick, motion):
    from pinrecon.result import Result, load_result

    T, seed, fps = motion
    q = _motion(stick, T, seed)
    path = tmp_path_factory.mktemp("res") / "r.npz"
    Result.from_motion(stick, q, fps).save(path)
    back = load_result(path)
    np.testing.assert_array_equal(back.q, q)
    assert back.fps == fps and back.keypoint_names == stick.keypoint_names
    np.testing.assert_allclose(back.keypoints3d, stick.keypoints(q), atol=1e-12)


@SETTINGS
@given(MOTION)
def test_bvh_export_import(tmp_path_factory, stick, motion):
    """A URDF figure's motion written as BVH and read back moves its keypoints the same."""
    from pinrecon.io.bvh import load_bvh, write_bvh

    T, seed, fps = motion
    q = _motion(stick, T, seed)
    folder = tmp_path_factory.mktemp("bvh")
    write_bvh(folder / "m.bvh", stick, q, fps)
    back = load_bvh(folder / "m.bvh")
    assert back.q.shape[0] == T and back.fps == pytest.approx(fps, rel=1e-6)
    np.testing.assert_allclose(back.q[:, :3], q[:, :3], atol=1e-6)  # the root's path, metres
    write_bvh(folder / "again.bvh", back.figure, back.q, back.fps)  # and a BVH figure writes back to itself
    again = load_bvh(folder / "again.bvh")
    np.testing.assert_allclose(again.q, back.q, atol=1e-6)


@SETTINGS
@given(T=st.integers(1, 5), K=st.integers(1, 4), fps=st.floats(1, 500), seed=st.integers(0, 2**32 - 1),
       up=st.sampled_from(["y", "z"]))
def test_trc_export_import(tmp_path_factory, T, K, fps, seed, up):
    from pinrecon.io.trc import load_trc, write_trc
    from pinrecon.tracks import Markers

    rng = np.random.default_rng(seed)
    P = rng.uniform(-10, 10, (T, K, 3))
    P[rng.random((T, K)) < 0.2] = np.nan
    names = [f"m{k}" for k in range(K)]
    path = tmp_path_factory.mktemp("trc") / "m.trc"
    write_trc(path, Markers(P, names, fps), up=up, precision=9)
    back = load_trc(path, up=up)
    assert back.names == names
    np.testing.assert_allclose(back.points, P, atol=1e-8, equal_nan=True)


@SETTINGS
@given(JSON_VALUES.filter(lambda v: "nan" not in json.dumps(v, allow_nan=True).lower()
                          and "infinity" not in json.dumps(v, allow_nan=True).lower()))
def test_json_text_round_trip(value):
    from pinrecon.io.jsonfile import parse_json

    text = json.dumps(value)
    try:
        back = parse_json(text)
    except InputError as exc:  # only what the limits refuse: a long integer
        assert "digits" in str(exc)
        return
    assert back == value


@pytest.mark.parametrize("depth, ok", [(64, True), (65, False), (100_000, False)])
def test_json_depth_limit(depth, ok):
    from pinrecon.io.jsonfile import parse_json

    text = "[" * depth + "]" * depth
    if ok:
        parse_json(text)
    else:
        with pytest.raises(InputError, match="nested"):
            parse_json(text, file="f.json", field="x")


def test_json_big_integer_refused():
    from pinrecon.io.jsonfile import parse_json

    assert parse_json("[" + "9" * 20 + "]") == [int("9" * 20)]
    for text in ["[" + "9" * 21 + "]", '{"a": ' + "1" * 5000 + "}"]:
        with pytest.raises(InputError, match="not valid JSON"):
            parse_json(text)
    assert parse_json("[1e999, -Infinity]") == [math.inf, -math.inf]  # the readers refuse them by field
