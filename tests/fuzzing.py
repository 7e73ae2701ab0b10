"""Mutation fuzzing of the tracks loaders and the command line (issue 11).

Shared by ``tests/test_fuzz_loaders.py`` (hypothesis draws the choices) and
``bench/bench_fuzz.py`` (a seeded ``random.Random`` draws them, 50,000 cases). Seeds are
small cuts of the real detector fixtures; a case applies 1 to 4 mutations (wrong types,
missing keys, NaN / Inf, huge numbers, wrong shapes, out-of-range frames, truncated
files, byte flips, missing / extra / renamed frame files) and runs a loader or the CLI.

The contract checked for every case: the outcome is a result or a ``PinreconError``
(``"error"``), never another exception (``"crash"``, RuntimeWarnings count as crashes);
a result has no NaN among its non-missing values (``"nan"``); a failed CLI run leaves the
existing output file byte-identical (``"half-written"``).
"""

from __future__ import annotations

import contextlib
import copy
import io
import json
import math
import os
import tempfile
import traceback
import warnings
from pathlib import Path

import numpy as np

from pinrecon.errors import PinreconError


def detectors_folder() -> Path:
    """The real detector outputs the seeds mutate (pinrecon.datasets, project-test-data)."""
    from pinrecon import datasets

    return datasets.folder("project-test-data/detectors", progressbar=False)


JUNK = [
    None, True, False, 0, -1, 1, 0.5, 7, -1e308, 1e308, 10**400, -(10**400), 2**63, math.nan, math.inf,
    -math.inf, 1e-320, "", "x", "12", "0.jpg", [], {}, [None], [[]], [1, 2], [1.5, 2.5, 0.9], {"a": 1},
    [[1, 2]] * 3, list(range(75)), "__DEEP__", "__BIGINT__",
]
#: what the two markers above become in the written JSON: nesting past any parser's
#: recursion limit, and an integer literal past Python's int-string limit
DEEP = "[" * 3000 + "]" * 3000
BIGINT = "9" * 5000
OPTIONS_PERSON = [None] * 8 + [0, 1, 2, "largest", (0.0, 0.0, 5000.0, 5000.0), (10.0, 10.0, 20.0, 20.0), "1"]
OPTIONS_LAYOUT = [None] * 12 + ["body25", "body25b", "coco17", "halpe26", "box", "h36m17"]


def scratch_dir(fallback: Path) -> Path:
    """A scratch folder in memory (/dev/shm) when there is one: opening files there is
    ten times faster than on the disk, and a case writes a few files."""
    shm = Path("/dev/shm")
    if shm.is_dir() and os.access(shm, os.W_OK):
        return Path(tempfile.mkdtemp(prefix="pinrecon-fuzz-", dir=shm))
    return fallback


class RandomChooser:
    """Choices from a seeded ``random.Random`` (the benchmark)."""

    def __init__(self, rng):
        self.rng = rng

    def int(self, lo: int, hi: int) -> int:
        return self.rng.randint(lo, hi)

    def pick(self, seq):
        return seq[self.rng.randrange(len(seq))]


# ---------------------------------------------------------------------------- seeds
def _json(path):
    return json.loads(Path(path).read_text())


def seeds(detectors: Path | None = None) -> dict[str, tuple[str, object]]:
    """name -> (kind, content): ``json`` a document, ``folder`` {file name: document},
    ``npz`` a dict of arrays. ``detectors``: the folder of detector outputs (default
    :func:`detectors_folder`)."""
    DET = detectors or detectors_folder()
    multi = sorted((DET / "pose2sim_body25b_multi").glob("*.json"))[:3]
    halpe = sorted((DET / "pose2sim_halpe26").glob("*.json"))[:2]
    coco = _json(DET / "mmpose_coco17_dataset.json")
    images = coco["images"][:2]
    keep = {im["id"] for im in images}
    anns = [{k: a[k] for k in ("keypoints", "image_id", "area", "bbox", "category_id", "id")}
            for a in coco["annotations"] if a["image_id"] in keep][:4]
    tr = _json(halpe[0])["people"][0]["pose_keypoints_2d"]
    names = ["nose", "left_shoulder", "right_shoulder", "left_hip", "right_hip", "left_wrist"]
    idx = [0, 5, 6, 11, 12, 9]
    pts = [[[tr[3 * k] + t, tr[3 * k + 1]] for k in idx] for t in range(4)]
    conf = [[0.9] * len(idx) for _ in range(4)]
    return {
        "openpose-multi": ("folder", {f.name: _json(f) for f in multi}),
        "openpose-halpe26": ("folder", {f.name: _json(f) for f in halpe}),
        "openpose-file": ("json", _json(DET / "spin_body25" / "im1010_openpose.json")),
        "coco-dataset": ("json", {"images": images, "annotations": anns, "categories": coco["categories"]}),
        "coco-results": ("json", _json(DET / "cocoapi_fakekeypoints100_results.json")[:6]),
        "alphapose": ("json", _json(DET / "alphapose_coco17_results.json")[:4]),
        "boxes": ("json", _json(DET / "mmpose_coco_person_boxes.json")[:6]),
        "mmpose-video": ("json", _json(DET / "mmpose_halpe26_inferencer.json")[:3]),
        "mmpose-demo": ("json", {**(d := _json(DET / "mmpose_halpe26_demo.json")), "instance_info": d["instance_info"][:3]}),
        "tracks-json": ("json", {"fps": 25.0, "names": names, "points": pts, "confidence": conf}),
        "tracks-npz": ("npz", {"fps": np.float64(25.0), "names": np.array(names), "points": np.array(pts),
                               "confidence": np.array(conf)}),
        "keyframes": ("keyframes", {"keyframes": [
            {"frame": 0, "sigma": 0.05, "joints": {"root_joint": [0.0, 0.95, 0.0, 0.0, 0.0, 0.0, 1.0], "j1": 0.35}},
            {"frame": 1, "sigma": 0.02, "points": {"nose": [0.1, 0.08, -0.09], "left_hip": [-0.15, 0.1, 0.09]}},
            {"frame": 2, "joints": {"root_joint": [0.05, 0.95, 0.0]}}]}),
    }


LOADER_SEEDS = ["openpose-multi", "openpose-halpe26", "openpose-file", "coco-dataset", "coco-results", "alphapose",
                "boxes", "mmpose-video", "mmpose-demo", "tracks-json", "tracks-npz", "keyframes"]
CLI_SEEDS = ["tracks-json", "openpose-halpe26"]


# ---------------------------------------------------------------------------- mutations
def _random_path(doc, ch):
    """A random node below the root: descend into random children, stopping at each
    container with probability 1/4 (cheap on large documents)."""
    path, node = (), doc
    while isinstance(node, (dict, list)) and node and (not path or ch.int(0, 3)):
        keys = list(node) if isinstance(node, dict) else range(len(node))
        k = ch.pick(list(keys))
        path, node = path + (k,), node[k]
    return path


def _get(doc, path):
    for k in path:
        doc = doc[k]
    return doc


def _set(doc, path, value):
    if not path:
        return value
    _get(doc, path[:-1])[path[-1]] = value
    return doc


def _junk(ch):
    return copy.deepcopy(ch.pick(JUNK))


def mutate_doc(doc, ch):
    """One structural mutation of a JSON document, in place (returns the new root)."""
    p = _random_path(doc, ch)
    node = _get(doc, p)
    op = ch.pick(["junk", "junk", "number", "delete", "insert", "truncate", "duplicate", "retype", "swap"])
    if op == "number" and isinstance(node, (int, float)) and not isinstance(node, bool) and abs(node) < 1e300:
        v = float(node)
        return _set(doc, p, ch.pick([v * 1e6, -v, v + 1e4, math.nan, math.inf, 0, 10**400, v * 1e300]))
    if op == "delete" and isinstance(node, (dict, list)) and node:
        keys = list(node) if isinstance(node, dict) else list(range(len(node)))
        del node[ch.pick(keys)]
        return doc
    if op == "insert" and isinstance(node, (dict, list)):
        if isinstance(node, dict):
            node[ch.pick(["people", "keypoints", "image_id", "instances", "frame_id", "x", "score", "points"])] = _junk(ch)
        else:
            node.insert(ch.int(0, len(node)), _junk(ch) if not node or ch.int(0, 1) else copy.deepcopy(node[0]))
        return doc
    if op == "truncate" and isinstance(node, list) and node:
        del node[ch.int(0, len(node) - 1):]
        return doc
    if op == "duplicate" and isinstance(node, list) and node:
        node.append(copy.deepcopy(node[ch.int(0, len(node) - 1)]))
        return doc
    if op == "retype" and isinstance(node, (dict, list)):
        return _set(doc, p, list(node.values()) if isinstance(node, dict) else {str(i): v for i, v in enumerate(node)})
    if op == "swap" and isinstance(node, list) and len(node) > 1:
        i, j = ch.int(0, len(node) - 1), ch.int(0, len(node) - 1)
        node[i], node[j] = node[j], node[i]
        return doc
    return _set(doc, p, _junk(ch))


def mutate_bytes(data: bytes, ch) -> bytes:
    op = ch.pick(["truncate", "flip", "insert"])
    if not data:
        return bytes([ch.int(0, 255)])
    i = ch.int(0, len(data) - 1)
    if op == "truncate":
        return data[:i]
    if op == "flip":
        b = bytearray(data)
        for _ in range(ch.int(1, 4)):
            b[ch.int(0, len(b) - 1)] = ch.int(0, 255)
        return bytes(b)
    return data[:i] + ch.pick([b"{", b"]", b",", b"\xff\xfe", b"NaN", b"1e999", b'"x"', b"\x00", b"[" * 3000,
                               BIGINT.encode(), b"-Infinity"]) + data[i:]


def _dump(doc) -> bytes:
    return json.dumps(doc).replace('"__DEEP__"', DEEP).replace('"__BIGINT__"', BIGINT).encode()


def odd_path(path: Path, ch) -> Path:
    """Now and then (1 case in 16) the path itself is the fault: a symbolic link to itself, a
    folder, an empty file, a link to nowhere; else ``path``."""
    kind = ch.pick(["keep"] * 15 + ["odd"])
    if kind == "keep":
        return path
    odd = path.with_name("odd" + path.suffix)
    if odd.is_symlink() or odd.is_file():
        odd.unlink()
    elif odd.is_dir():
        odd.rmdir()
    what = ch.pick(["loop", "folder", "empty", "dangling"])
    if what == "loop":
        odd.symlink_to(odd.name)
    elif what == "folder":
        odd.mkdir()
    elif what == "empty":
        odd.write_bytes(b"")
    else:
        odd.symlink_to("nowhere" + path.suffix)
    return odd


def _npz_array(ch):
    return ch.pick([
        np.array([]), np.zeros((2, 3)), np.full((4, 6, 2), np.nan), np.full((4, 6, 2), np.inf),
        np.full((4, 6, 2), 1e300), np.ones((4, 6, 3)), np.ones((4, 6, 2), complex), np.array(["a", "b"]),
        np.ones((4, 6), bool), np.array(7), np.array(-1.0), np.array([np.nan]), np.ones((1, 6, 2)),
        np.array([["a"] * 6] * 4), np.full((4, 6), -0.5), np.int8(3) * np.ones((4, 6, 2), np.int8),
    ])


def write_case(name: str, content, ch, root: Path) -> Path:
    """Write a mutated copy of seed ``name`` under ``root``; return the path to load."""
    kind, seed = content
    root.mkdir(parents=True, exist_ok=True)
    n = ch.int(1, 4)
    if kind == "folder":
        files = dict(seed)  # file name -> document (until a byte mutation makes it bytes)
        for _ in range(n):
            op = ch.pick(["doc", "doc", "doc", "bytes", "delete", "junkfile", "rename", "duplicate"])
            key = ch.pick(sorted(files))
            if op == "doc" and not isinstance(files[key], bytes):
                files[key] = mutate_doc(copy.deepcopy(files[key]), ch)
            elif op in ("bytes", "junkfile"):
                blob = mutate_bytes(files[key] if isinstance(files[key], bytes) else _dump(files[key]), ch)
                files[key if op == "bytes" else "zz_9_keypoints.json"] = blob
            elif op == "delete" and len(files) > 1:
                del files[key]
            elif op == "rename":
                files[f"f{ch.int(0, 20)}.json"] = files.pop(key)
            elif op == "duplicate":
                files[f"{key}.copy.json"] = files[key]
        folder = root / "frames"
        folder.mkdir(exist_ok=True)
        for old in folder.iterdir():  # the folder is reused: creating folders is slow on some file systems
            if old.name not in files:
                old.unlink()
        for k, v in files.items():
            (folder / k).write_bytes(v if isinstance(v, bytes) else _dump(v))
        return folder
    if kind == "npz":
        arrays = dict(seed)
        blob = None
        for _ in range(n):
            op = ch.pick(["array", "array", "delete", "bytes"])
            if op == "array":
                arrays[ch.pick(["fps", "names", "points", "confidence"])] = _npz_array(ch)
            elif op == "delete" and arrays:
                del arrays[ch.pick(sorted(arrays))]
            else:
                blob = True
        path = root / "tracks.npz"
        np.savez(path, **arrays)
        if blob:
            path.write_bytes(mutate_bytes(path.read_bytes(), ch))
        return path
    ops = [ch.int(0, 5) > 0 for _ in range(n)]  # True: a structural mutation, False: bytes
    doc = copy.deepcopy(seed)
    for _ in range(sum(ops)):
        doc = mutate_doc(doc, ch)
    data = _dump(doc)
    for _ in range(n - sum(ops)):
        data = mutate_bytes(data, ch)
    path = root / ("keyframes.json" if kind == "keyframes" else "tracks.json")
    path.write_bytes(data)
    return path


# ---------------------------------------------------------------------------- running a case
def check_tracks(tracks) -> str | None:
    """Why a loaded result breaks the contract (None when it does not)."""
    from pinrecon.tracks import Tracks

    if not isinstance(tracks, Tracks):
        return f"not a Tracks: {type(tracks).__name__}"
    p = tracks.points
    if p.ndim != 3 or p.shape[2] != 2 or len(tracks.names) != p.shape[1]:
        return f"bad shape {p.shape} for {len(tracks.names)} names"
    fin = np.isfinite(p)
    if np.any(fin[..., 0] != fin[..., 1]) or np.any(np.isinf(p)):
        return "a point with one coordinate missing, or inf"
    if tracks.confidence is not None and not np.all(np.isfinite(tracks.confidence) & (tracks.confidence >= 0)):
        return "NaN or negative confidence"
    if not (np.isfinite(tracks.fps) and tracks.fps > 0):
        return "bad fps"
    return None


def quiet():
    stack = contextlib.ExitStack()
    stack.enter_context(warnings.catch_warnings())
    warnings.simplefilter("ignore")
    warnings.simplefilter("error", RuntimeWarning)
    return stack


def run_loader_case(name: str, content, ch, root: Path) -> tuple[str, str]:
    """(outcome, detail): outcome is ``result``, ``error``, ``crash`` or ``nan``."""
    from pinrecon.tracks import load_keyframes, load_tracks

    path = odd_path(write_case(name, content, ch, root), ch)
    person, layout = ch.pick(OPTIONS_PERSON), ch.pick(OPTIONS_LAYOUT)
    with quiet():
        try:
            if content[0] == "keyframes":
                k = load_keyframes(path)
                bad = [v for kf in k for v in (kf.points or kf.joints or {}).values() if not np.all(np.isfinite(v))]
                return ("nan", "keyframe values") if bad else ("result", "")
            tracks = load_tracks(path, fps=25.0, person=person, layout=layout)
        except PinreconError as exc:
            return "error", str(exc)[:200]
        except Exception:  # noqa: BLE001 - the contract: nothing else may escape
            return "crash", traceback.format_exc(limit=6)
    bad = check_tracks(tracks)
    return ("nan", bad) if bad else ("result", "")


STICK_URDF = """<robot name="stick"><link name="base"/><link name="arm"/>
<joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0 0.5 0"/>
<axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="0" velocity="0"/></joint></robot>"""
STICK_KEYPOINTS = {"keypoints": {
    "nose": {"frame": "arm", "offset": [0.0, 0.3, 0.0]}, "left_wrist": {"frame": "arm", "offset": [0.0, 0.5, 0.0]},
    "left_shoulder": {"frame": "base", "offset": [0.1, 0.0, 0.0]},
    "right_shoulder": {"frame": "base", "offset": [-0.1, 0.0, 0.0]},
    "left_hip": {"frame": "base", "offset": [0.1, -0.5, 0.0]}, "right_hip": {"frame": "base", "offset": [-0.1, -0.5, 0.0]},
}}
CAMERA = {"model": "orthographic", "R": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "scale": 300.0, "center": [640.0, 360.0]}
PREVIOUS = b"an earlier result that a failed run must not touch"


def run_cli_case(name: str, content, ch, root: Path, fixed: Path) -> tuple[str, str]:
    """Run ``pinrecon reconstruct`` (a small URDF figure) or ``pinrecon links`` on mutated
    tracks; (outcome, detail) as :func:`run_loader_case`, plus ``half-written``."""
    from pinrecon.cli import main

    fixed.mkdir(parents=True, exist_ok=True)
    urdf, kp, cam = fixed / "stick.urdf", fixed / "stick_keypoints.json", fixed / "camera.json"
    if not urdf.exists():
        urdf.write_text(STICK_URDF)
        kp.write_text(json.dumps(STICK_KEYPOINTS))
        cam.write_text(json.dumps(CAMERA))
    path = write_case(name, content, ch, root)
    out = fixed / "result.npz"
    out.write_bytes(PREVIOUS)
    blocker = fixed / "blocker"
    if not blocker.exists():
        blocker.write_text("a file where a folder is expected")
    command = ch.pick(["reconstruct", "reconstruct", "links"])
    # now and then a second output that cannot be written: the run must fail before the solve
    unwritable = ch.pick([None] * 5 + [blocker / "camera.json", blocker / "sub" / "camera.json", fixed])
    opts = ["--fps", "25"]
    person = ch.pick(OPTIONS_PERSON[:11])
    if person is not None:
        opts += ["--person", str(person)]
    if command == "reconstruct":
        argv = ["reconstruct", "--figure", str(urdf), "--keypoints", str(kp), "--tracks", str(path), "--camera",
                str(cam), "--out", str(out), "--quiet", "--max-iterations", "2", *opts]
        if unwritable is not None:
            argv += ["--save-camera", str(unwritable)]
    else:
        argv = ["links", str(path), "--quiet", "--names", "nose", "left_shoulder", "left_hip", *opts]
    err = io.StringIO()
    with quiet(), contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except Exception:  # noqa: BLE001
            return "crash", traceback.format_exc(limit=6)
    if "Traceback" in err.getvalue():
        return "crash", err.getvalue()[-500:]
    if command == "reconstruct":
        if rc != 0 and out.read_bytes() != PREVIOUS:
            return "half-written", f"rc {rc} and the output changed"
        left = sorted(p.name for p in fixed.iterdir() if p.name.startswith("."))
        if left:
            return "half-written", f"temporaries left: {left}"
        if unwritable is not None and (rc == 0 or "cannot write the output" not in err.getvalue()):
            return "half-written", f"rc {rc} with an unwritable --save-camera: {err.getvalue()[:200]}"
        if rc == 0:
            from pinrecon.result import load_result

            res = load_result(out)
            if not np.all(np.isfinite(res.q)):
                return "nan", "NaN in the result's motion"
    return ("result" if rc == 0 else "error"), err.getvalue()[:200]
