"""Mutation fuzzing of every reader besides the tracks loaders, and of the exports (issue 44).

Shared by ``tests/test_fuzz_files.py`` (hypothesis draws the choices) and
``bench/bench_fuzz.py``. Seeds: a camera JSON, calibrations (Pose2Sim TOML, OpenCV YAML),
a keypoint map, a limits file, a URDF, a BVH, a CMU ASF, a TRC, a keyframes file and a
result NPZ with a free-flyer root. A case mutates one (JSON: wrong types, missing keys,
NaN / Inf, huge numbers, 3000-deep nesting, 5000-digit integers; text: lines dropped,
doubled or cut, numbers replaced by junk, bytes flipped, non-UTF-8 bytes; NPZ: a field of
the wrong type, shape or dtype, a key missing, embedded JSON invalid, zero quaternions,
infinite fps or joint values, a truncated zip; the path: a symlink loop, a folder, an
empty file) and reads it. A result that loads is exported (``pinrecon export`` to BVH, CSV
and TRC over earlier files).

The contract, as in tests/fuzzing.py: a value or a ``PinreconError``, never another
exception (``crash``); nothing loaded holds a NaN or infinity where a number must be
(``nan``: also an export with ``nan``/``inf`` or a zero frame time); a failed export leaves
the earlier files byte-identical and no temporary behind (``half-written``).
"""

from __future__ import annotations

import contextlib
import copy
import io
import json
import math
import re
import traceback
from pathlib import Path

import numpy as np
from fuzzing import (
    BIGINT,
    DEEP,
    PREVIOUS,
    STICK_KEYPOINTS,
    STICK_URDF,
    mutate_bytes,
    mutate_doc,
    odd_path,
    quiet,
)

from pinrecon.errors import PinreconError

CAMERA_ORTHO = {"model": "orthographic", "R": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "scale": 300.0,
                "center": [640.0, 360.0]}
CAMERA_PERSP = {"model": "perspective", "K": [[1000.0, 0, 640.0], [0, 1000.0, 360.0], [0, 0, 1]],
                "R": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "t": [0.0, 1.0, 4.0], "dist": [0.01, -0.002, 0, 0, 0]}
LIMITS = {"units": "degrees", "limits": {"j1": [-90, 90], "j2": [0, 150]}}
KEYFRAMES = {"keyframes": [
    {"frame": 0, "sigma": 0.05, "joints": {"root_joint": [0.0, 0.95, 0.0, 0.0, 0.0, 0.0, 1.0], "j1": 0.35}},
    {"frame": 1, "sigma": 0.02, "points": {"nose": [0.1, 0.08, -0.09], "left_hip": [-0.15, 0.1, 0.09]}}]}
SMALL_BVH = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT Leg
  {
    OFFSET 0 -4 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0 -4 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.0333333
0 0 0 0 0 0 0 0 0
1 2 3 4 5 6 7 8 9
1 2 3 4 5 6 7 8 9
"""
JUNK_NUMBERS = ["1e300", "-1e300", "nan", "NaN", "inf", "-inf", "1e-320", "0", "-0", "x", "", BIGINT, "1e999",
                "0x10", "1_0", "--1"]
NUMBER = re.compile(r"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")

FILE_SEEDS = ["camera-ortho", "camera-persp", "calibration-toml", "calibration-opencv", "keypoint-map", "limits",
              "urdf", "bvh", "asf", "trc", "keyframes-file", "result-npz"]


def file_seeds(data_file) -> dict[str, tuple[str, object]]:
    """name -> (kind, content); ``data_file(name)`` gives a registered data file's path
    (conftest's, or :func:`pinrecon.datasets.fetch`)."""
    trc = data_file("project-test-data/calibration/pose2sim/static_trial/S00_P00_T00_StaticTrial_0-12.trc")
    trc_rows = Path(trc).read_text().splitlines()
    return {
        "camera-ortho": ("json", CAMERA_ORTHO),
        "camera-persp": ("json", CAMERA_PERSP),
        "calibration-toml": ("text", Path(data_file("project-test-data/calibration/pose2sim/Calib_scene.toml")).read_text()),
        "calibration-opencv": ("text", Path(data_file(
            "project-test-data/calibration/opencv/tutorial_camera_charuco.yml")).read_text()),
        "keypoint-map": ("json", STICK_KEYPOINTS),
        "limits": ("json", LIMITS),
        "urdf": ("text", STICK_URDF),
        "bvh": ("text", SMALL_BVH),
        "asf": ("text", Path(data_file("project-test-data/cmu-asf_01.asf")).read_text()),
        "trc": ("text", "\n".join(trc_rows) + "\n"),
        "keyframes-file": ("json", KEYFRAMES),
        "result-npz": ("result", stick_result_arrays()),
    }


SUFFIX = {"camera-ortho": ".json", "camera-persp": ".json", "calibration-toml": ".toml", "calibration-opencv": ".yml",
          "keypoint-map": ".json", "limits": ".json", "urdf": ".urdf", "bvh": ".bvh", "asf": ".asf", "trc": ".trc",
          "keyframes-file": ".json", "result-npz": ".npz"}


def stick_result_arrays() -> dict:
    """The arrays of a small result (the stick figure on a free-flyer root, 5 frames)."""
    import tempfile

    from pinrecon import Figure
    from pinrecon.figure import parse_keypoint_entries
    from pinrecon.result import Result

    fig = Figure.from_urdf_string(STICK_URDF, parse_keypoint_entries(STICK_KEYPOINTS["keypoints"]), root="free")
    q = np.zeros((5, fig.nq))
    q[:, 1] = 0.9
    q[:, 6] = 1.0
    q[:, 7] = np.linspace(-0.5, 0.5, 5)
    with tempfile.TemporaryDirectory() as d:
        Result.from_motion(fig, q, 25.0).save(Path(d) / "r.npz")
        with np.load(Path(d) / "r.npz") as z:
            return {k: z[k] for k in z.files}


# ---------------------------------------------------------------------------- mutations
def mutate_text(text: str, ch) -> str:
    """One mutation of a text file by lines or numbers."""
    lines = text.split("\n")
    op = ch.pick(["number", "number", "number", "drop", "double", "cut", "swap", "deep"])
    i = ch.int(0, max(len(lines) - 1, 0))
    if op == "number":
        spans = [m.span() for m in NUMBER.finditer(text)]
        if spans:
            a, b = spans[ch.int(0, len(spans) - 1)]
            return text[:a] + ch.pick(JUNK_NUMBERS) + text[b:]
    if op == "drop" and len(lines) > 1:
        del lines[i]
    elif op == "double":
        lines.insert(i, lines[i])
    elif op == "cut":
        lines = lines[:i]
    elif op == "swap" and len(lines) > 1:
        j = ch.int(0, len(lines) - 1)
        lines[i], lines[j] = lines[j], lines[i]
    elif op == "deep":
        lines.insert(i, "{" * 3000)
    return "\n".join(lines)


def _bad_json_text(ch) -> str:
    return ch.pick(["{", "", "null", "5", '"x"', "[]", "{}", DEEP, BIGINT, '{"keypoints": 5}', '{"a": NaN}',
                    '{"keypoints": {"a": {"frame": "nowhere", "offset": [0, 0, 0]}}}', "[1e999]", "\udcff"])


def _float_q(arrays) -> bool:
    return "q" in arrays and np.ndim(arrays["q"]) == 2 and np.asarray(arrays["q"]).dtype.kind in "iuf"


def mutate_result(arrays: dict, ch) -> dict:
    """One mutation of a result NPZ's arrays (in place; returns them)."""
    op = ch.pick(["junk", "junk", "delete", "text", "text", "zero-quaternion", "fps", "q-value", "shape", "extra",
                  "extra"])
    keys = sorted(arrays)
    key = ch.pick(keys) if keys else "q"
    if op == "junk":
        from fuzzing import _npz_array

        arrays[key] = _npz_array(ch)
    elif op == "delete" and keys:
        del arrays[key]
    elif op == "text":
        arrays[ch.pick(["figure_keypoints", "figure_meta", "figure_limits", "camera", "calibration", "figure_urdf",
                        "cameras", "camera_names", "figure_name"])] = np.array(_bad_json_text(ch).encode(
                            "utf-8", "surrogatepass").decode("utf-8", "replace"))
    elif op == "zero-quaternion" and _float_q(arrays) and np.shape(arrays["q"])[1] >= 7:
        q = np.array(arrays["q"], float)
        q[ch.int(0, len(q) - 1), 3:7] = 0.0
        arrays["q"] = q
    elif op == "fps":
        arrays["fps"] = np.float64(ch.pick([math.inf, 0.0, -1.0, math.nan, 1e300, 1e-300]))
    elif op == "q-value" and _float_q(arrays) and np.size(arrays["q"]):
        q = np.array(arrays["q"], float)
        q[ch.int(0, q.shape[0] - 1), ch.int(0, q.shape[1] - 1)] = ch.pick([math.inf, -math.inf, math.nan, 1e300])
        arrays["q"] = q
    elif op == "extra":  # a pipeline extra (faults, mirrors, stability, feet ...), usually with its group
        from fuzzing import _npz_array

        from pinrecon.io.results import EXTRAS, EXTRAS_GROUPS

        group = ch.pick(EXTRAS_GROUPS)
        for k in group if ch.int(0, 2) else [ch.pick(sorted(EXTRAS))]:
            arrays[k] = ch.pick([_npz_array(ch), np.zeros((0, 5)), np.ones((2, 5)), np.array(["a", "b"]),
                                 np.array([[0, 3], [2, 1]]), np.float64(2.0), np.ones((5, 2), bool), np.array([7])])
    elif op == "shape" and key in arrays and np.ndim(arrays[key]) >= 1 and len(arrays[key]) > 1:
        arrays[key] = np.asarray(arrays[key])[:-1]
    return arrays


def write_file_case(name: str, content, ch, root: Path) -> Path:
    """Write a mutated copy of seed ``name`` under ``root``; return the path to read."""
    kind, seed = content
    root.mkdir(parents=True, exist_ok=True)
    path = root / f"case{SUFFIX[name]}"
    n = ch.int(1, 3)
    if kind == "result":
        arrays = dict(seed)
        for _ in range(n):
            arrays = mutate_result(arrays, ch)
        with open(path, "wb") as fh:
            np.savez(fh, **arrays)
        if ch.int(0, 5) == 0:
            path.write_bytes(mutate_bytes(path.read_bytes(), ch))
    elif kind == "json":
        doc = copy.deepcopy(seed)
        for _ in range(n):
            doc = mutate_doc(doc, ch)
        from fuzzing import _dump

        data = _dump(doc)
        if ch.int(0, 4) == 0:
            data = mutate_bytes(data, ch)
        path.write_bytes(data)
    else:
        text = seed
        for _ in range(n):
            text = mutate_text(text, ch)
        data = text.encode()
        if ch.int(0, 4) == 0:
            data = mutate_bytes(data, ch)
        path.write_bytes(data)
    return odd_path(path, ch)


# ---------------------------------------------------------------------------- reading and checking
def _finite(*arrays) -> bool:
    return all(np.all(np.isfinite(np.asarray(a, float))) for a in arrays)


def _camera_ok(cam) -> bool:
    return _finite(*[v for k, v in vars(cam).items() if isinstance(v, np.ndarray) and v.dtype.kind in "if"])


def read_file_case(name: str, path: Path, fixed: Path):
    """Read ``path`` with seed ``name``'s reader; (value, why it breaks the contract or None)."""
    if name.startswith("camera"):
        from pinrecon.cameras import load_camera

        cam = load_camera(path)
        return cam, None if _camera_ok(cam) else "camera with NaN"
    if name.startswith("calibration"):
        from pinrecon.io.calibration import load_cameras

        cams = load_cameras(path)
        return cams, None if all(_camera_ok(c) for c in cams) else "camera with NaN"
    if name == "keypoint-map":
        from pinrecon.figure import load_keypoint_map

        kps = load_keypoint_map(path)
        return kps, None if all(_finite(k.offset) for k in kps) else "offset with NaN"
    if name == "limits":
        from pinrecon.joint_limits import load_limits

        lim = load_limits(path)
        return lim, None if all(_finite(v) for v in lim.values()) else "limit with NaN"
    if name == "urdf":
        from pinrecon import Figure

        fig = Figure.from_urdf(path, fixed / "stick_keypoints.json")
        return fig, None if _finite(fig.keypoints(fig.neutral() if hasattr(fig, "neutral") else np.zeros(fig.nq))) \
            else "keypoints with NaN"
    if name == "bvh":
        from pinrecon.io.bvh import load_bvh

        m = load_bvh(path)
        return m, None if _finite(m.q) and np.isfinite(m.fps) and m.fps > 0 else "motion with NaN or bad fps"
    if name == "asf":
        from pinrecon.io.asf import read_asf

        sk = read_asf(path)
        return sk, None
    if name == "trc":
        from pinrecon.io.trc import load_trc

        mk = load_trc(path)
        ok = not np.any(np.isinf(mk.points)) and np.isfinite(mk.fps) and mk.fps > 0
        return mk, None if ok else "markers with inf or bad fps"
    if name == "keyframes-file":
        from pinrecon.tracks import load_keyframes

        kf = load_keyframes(path)
        vals = [v for k in kf for v in (k.points or k.joints or {}).values()]
        return kf, None if all(_finite(v) and np.all(np.abs(v) <= 1e4) for v in vals) else "keyframe values"
    raise KeyError(name)


def _fixed(fixed: Path) -> None:
    fixed.mkdir(parents=True, exist_ok=True)
    kp = fixed / "stick_keypoints.json"
    if not kp.exists():
        kp.write_text(json.dumps(STICK_KEYPOINTS))


def export_case(path: Path, out: Path) -> tuple[str, str]:
    """``pinrecon export`` of a result that loaded: BVH, CSV and TRC over earlier files."""
    from pinrecon.cli import main

    out.mkdir(parents=True, exist_ok=True)
    files = [out / "m.bvh", out / "m.csv", out / "m.trc"]
    for f in files:
        f.write_bytes(PREVIOUS)
    for f in out.iterdir():
        if f not in files:
            f.unlink()
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        rc = main(["export", str(path), "--bvh", str(files[0]), "--csv", str(files[1]), "--trc", str(files[2])])
    left = sorted(f.name for f in out.iterdir())
    if left != sorted(f.name for f in files):
        return "half-written", f"files left: {left}"
    if rc != 0:
        changed = [f.name for f in files if f.read_bytes() != PREVIOUS]
        return ("half-written", f"rc {rc}, changed {changed}") if changed else ("error", err.getvalue()[:200])
    written = [f.read_text() for f in files]
    if any(f == PREVIOUS.decode() for f in written):
        return "half-written", "rc 0 but an output kept the earlier content"
    low = " ".join(written).lower()
    if re.search(r"(?<![a-z])(nan|inf)(?![a-z])", low):
        return "nan", "an export holds nan or inf"
    m = re.search(r"Frame Time:\s*(\S+)", written[0])
    if not m or not float(m.group(1)) > 0:
        return "nan", f"BVH frame time {m.group(1) if m else None}"
    return "result", ""


def run_file_case(name: str, content, ch, root: Path) -> tuple[str, str]:
    """(outcome, detail) of one mutated file of seed ``name``: ``result``, ``error``,
    ``crash``, ``nan`` or ``half-written`` (exports of results)."""
    _fixed(root / "fixed")
    path = write_file_case(name, content, ch, root / "case")
    with quiet():
        try:
            if name == "result-npz":
                from pinrecon.result import load_result

                res = load_result(path)
                if not (_finite(res.q, res.keypoints3d, res.times) and np.isfinite(res.fps) and res.fps > 0):
                    return "nan", "result with NaN or bad fps"
                res.summary()  # what the summary reads is checked on load too
                if res.figure is None:
                    return "result", ""
                return export_case(path, root / "out")
            _value, bad = read_file_case(name, path, root / "fixed")
        except PinreconError as exc:
            return "error", str(exc)[:200]
        except Exception:  # noqa: BLE001 - the contract: nothing else may escape
            return "crash", traceback.format_exc(limit=8)
    return ("nan", bad) if bad else ("result", "")
