"""The result NPZ format (``docs/formats.md``).

Keys: ``q`` (T, nq), ``times`` (T,) seconds, ``keypoints3d`` (T, K, 3) world metres,
``keypoint_names`` (K,), ``joint_names`` (J,), plus optional extras written by the
reconstruction (``reprojection_error_px`` (T,), ``fps``, ``figure`` description ...).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from .atomic import atomic_path
from .fields import array_field, number_field, string_field
from .jsonfile import parse_json, read_npz

__all__ = ["save_result_npz", "load_result_npz", "text_json", "REQUIRED_KEYS", "MAX_VALUE", "MAX_FPS"]

REQUIRED_KEYS = ("q", "times", "keypoints3d", "keypoint_names", "joint_names")


def save_result_npz(path: str | os.PathLike, **arrays) -> None:
    missing = [k for k in REQUIRED_KEYS if k not in arrays]
    if missing:
        raise InputError(f"result is missing {missing}", file=path)
    T = np.shape(arrays["q"])[0]
    if np.shape(arrays["times"]) != (T,) or np.shape(arrays["keypoints3d"])[:1] != (T,):
        raise InputError("q, times and keypoints3d must have the same number of frames", file=path)
    clean = {}
    for k, v in arrays.items():
        if v is None:
            continue
        a = np.asarray(v)
        if a.dtype == object:
            a = a.astype(str)
        clean[k] = a
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **clean)


#: the largest joint value (radians or metres) and fps a result may hold
MAX_VALUE = 1e6
MAX_FPS = 1e6
#: text fields (0-d string arrays); those marked True hold JSON
TEXT_FIELDS = {"figure_name": False, "figure_urdf": False, "figure_keypoints": True, "figure_meta": True,
               "figure_limits": True, "camera": True, "cameras": True, "camera_names": True, "calibration": True,
               "solver_status": False, "stages": True}


def load_result_npz(path: str | os.PathLike) -> dict:
    """The arrays of a result NPZ, each checked (type, shape, dtype, finiteness, range);
    one :class:`~pinrecon.errors.InputError` naming the file, field and frame otherwise."""
    path = Path(path)
    data = read_npz(path)
    missing = [k for k in REQUIRED_KEYS if k not in data]
    if missing:
        raise InputError(f"not a pinrecon result: missing {missing}", file=path)
    q = array_field(data, "q", file=path, ndim=2, finite=True, bound=MAX_VALUE).astype(float)
    T = q.shape[0]
    if T == 0 or q.shape[1] == 0:
        raise InputError(f"holds no motion (shape {q.shape})", file=path, field="q")
    data["q"] = q
    data["times"] = array_field(data, "times", file=path, shape=(T,), finite=True).astype(float)
    names = array_field(data, "keypoint_names", file=path, ndim=1, kind="string")
    K = len(names)
    data["keypoints3d"] = array_field(data, "keypoints3d", file=path, shape=(T, K, 3), finite=True,
                                      bound=MAX_VALUE).astype(float)
    array_field(data, "joint_names", file=path, ndim=1, kind="string")
    if "fps" in data:
        data["fps"] = np.float64(number_field(data["fps"], file=path, field="fps", low=0, low_open=True,
                                              high=MAX_FPS))
    elif T > 1 and not np.all(np.diff(data["times"]) > 0):
        raise InputError("must increase (no 'fps' field to take the rate from)", file=path, field="times")
    if "reprojection_error_px" in data:
        data["reprojection_error_px"] = array_field(data, "reprojection_error_px", file=path, shape=(T,),
                                                    kind="number").astype(float)
    if "observed_frames" in data:
        data["observed_frames"] = array_field(data, "observed_frames", file=path, shape=(T,),
                                              kind="bool-like").astype(bool)
    if "reprojection_error_px_per_camera" in data:
        data["reprojection_error_px_per_camera"] = array_field(
            data, "reprojection_error_px_per_camera", file=path, shape=(None, T), kind="number").astype(float)
    if "keypoint_parents" in data:
        array_field(data, "keypoint_parents", file=path, shape=(K,), kind="integer")
    if "figure_floating" in data:
        a = np.asarray(data["figure_floating"])
        if a.shape != () or a.dtype.kind not in "biu":
            raise InputError(f"must be a boolean, got dtype {a.dtype} shape {a.shape}", file=path,
                             field="figure_floating")
    if "solver_iterations" in data:
        number_field(data["solver_iterations"], file=path, field="solver_iterations", integer=True, low=0)
    for key in TEXT_FIELDS:
        string_field(data, key, file=path, required=False)
    for key, a in data.items():
        if np.asarray(a).dtype.kind not in "biufU":
            raise InputError(f"has dtype {np.asarray(a).dtype}: a result holds numbers, booleans and text",
                             file=path, field=key)
    check_extras(data, path)
    return data


#: the extras the pipeline writes: key -> (shape, kind, finite); ``None`` in a shape is free
EXTRAS = {
    "floor": ((4,), "number", True), "foot_names": ((None,), "string", False),
    "foot_contact": ((None, None), "bool-like", False), "foot_contact_height_m": (None, "number", True),
    "foot_clearance_m": (None, "number", True),
    "hypothesis_chains": ((None,), "string", False), "hypothesis_spans": ((None, 5), "number", True),
    "hypothesis_threshold": ((), "number", True), "hypothesis_turns": ((None, 4), "number", True),
    "solution_turns": ((None, 4), "number", True), "solution_mirrors": ((None, 5), "number", False),
    "mirror_chains": ((None,), "string", False), "mirror_uncertain": ((None, 4), "number", True),
    "mirror_uncertain_nats": ((), "number", False),
    "repaired_frames": ((None,), "integer", False), "relabelled_frames": ((None,), "integer", False),
    "relabelled_lifted_frames": ((None,), "integer", False),
    "outlier_frames": ((None,), "integer", False),
    "outlier_points": ((None,), "string", False), "outlier_error_px": ((None,), "number", True),
    "outlier_threshold_px": ((), "number", False),
    "prior_distance": ((None,), "number", False), "prior_distance_limit": ((), "number", True),
    "prior_unfamiliar_spans": ((None, 2), "integer", False), "prior_distance_model": ((), "string", False),
    "prior_model": ((), "string", False), "prior_default_unfamiliar": ((), "number", True),
    "prior_conflict_s2": ((None,), "number", True), "prior_conflict_joints": ((None,), "string", False),
    "stability_drop": ((), "number", True), "stability_seeds": ((None,), "integer", False),
    "stability_spread_mm": ((None, None), "number", True), "stability_keypoint_spread_mm": ((None, None), "number", True),
    "stability_names": ((None,), "string", False), "stability_threshold_mm": ((), "number", True),
    "lifted_disagreement_deg": ((None, None), "number", False), "lifted_frame_deg": ((None,), "number", False),
    "lifted_bones": ((None,), "string", False), "lifted_rotation": ((None, 3, 3), "number", True),
    "lifted_threshold_deg": ((), "number", True), "lifted_spans": ((None, 4), "number", True),
}
#: extras that come together: one present, all of them must be
EXTRAS_GROUPS = [
    ("floor", "foot_names", "foot_contact", "foot_contact_height_m", "foot_clearance_m"),
    ("hypothesis_spans", "hypothesis_chains"),
    ("mirror_uncertain", "mirror_chains", "mirror_uncertain_nats"),
    ("outlier_frames", "outlier_points", "outlier_error_px"),
    ("prior_distance", "prior_distance_limit", "prior_unfamiliar_spans"),
    ("prior_default_unfamiliar", "prior_model"),
    ("prior_conflict_s2", "prior_conflict_joints"),
    ("stability_spread_mm", "stability_keypoint_spread_mm", "stability_names", "stability_threshold_mm",
     "stability_drop"),
    ("lifted_disagreement_deg", "lifted_frame_deg", "lifted_bones", "lifted_rotation", "lifted_threshold_deg",
     "lifted_spans"),
]


def check_extras(data: dict, path=None) -> None:
    """The pipeline's extras in a result (:data:`EXTRAS`): shapes, kinds, finiteness, the
    groups that come together and the indices that point into each other."""
    for key, (shape, kind, finite) in EXTRAS.items():
        if key in data:
            array_field(data, key, file=path, shape=shape, kind=kind, finite=finite)
    for group in EXTRAS_GROUPS:
        present = [k for k in group if k in data]
        if present and len(present) < len(group):
            missing = [k for k in group if k not in data]
            raise InputError(f"comes with {missing}, which the file lacks", file=path, field=present[0])

    def n(key):
        return len(data[key])

    if "hypothesis_spans" in data:
        _indices(data, "hypothesis_spans", 0, n("hypothesis_chains"), path)
    if "foot_names" in data and data["foot_contact"].shape[1:] != (n("foot_names"),):
        raise InputError(f"must have one column per foot point ({n('foot_names')})", file=path, field="foot_contact")
    if "outlier_frames" in data and not n("outlier_frames") == n("outlier_points") == n("outlier_error_px"):
        raise InputError("outlier_frames, outlier_points and outlier_error_px differ in length", file=path,
                         field="outlier_frames")
    if "prior_distance" in data:
        spans = data["prior_unfamiliar_spans"]
        if len(spans) and not (np.all(spans[:, 0] >= 0) and np.all(spans[:, 0] < spans[:, 1])
                               and np.all(spans[:, 1] <= n("prior_distance"))):
            raise InputError(f"spans must lie in the {n('prior_distance')} frames, first < last",
                             file=path, field="prior_unfamiliar_spans")
    if "lifted_spans" in data:
        _indices(data, "lifted_spans", 0, n("lifted_bones"), path)
        if data["lifted_disagreement_deg"].shape[1:] != (n("lifted_bones"),):
            raise InputError(f"must have one column per bone ({n('lifted_bones')})", file=path,
                             field="lifted_disagreement_deg")
    if "stability_spread_mm" in data:
        spread, per_point = np.atleast_2d(data["stability_spread_mm"]), data["stability_keypoint_spread_mm"]
        if per_point.shape != (spread.shape[1], n("stability_names")):
            raise InputError(f"must be (frames {spread.shape[1]}, points {n('stability_names')}), got "
                             f"{per_point.shape}", file=path, field="stability_keypoint_spread_mm")


def _indices(data, key, column, count, path) -> None:
    """Column ``column`` of ``data[key]`` holds indices into a list of ``count``."""
    col = np.asarray(data[key], float)[:, column]
    if len(col) and not (np.all(col == np.round(col)) and col.min() >= 0 and col.max() < count):
        raise InputError(f"column {column} must index the {count} labels", file=path, field=key)


def text_json(data: dict, key: str, *, file=None, default=None, expect: type | None = None):
    """The JSON embedded in text field ``key`` (``default`` when it is absent or empty),
    decoded under :mod:`pinrecon.io.jsonfile`'s limits, of type ``expect`` when given."""
    text = string_field(data, key, file=file, required=False, default="")
    if not text:
        return default
    out = parse_json(text, file=file, field=key)
    if expect is not None and not isinstance(out, expect):
        raise InputError(f"must hold a JSON {'object' if expect is dict else 'list'}, got {type(out).__name__}",
                         file=file, field=key)
    return out


def check_calibration(c: dict, path=None) -> dict:
    """The ``calibration`` JSON of a result: the types the summary reads (``mode`` text;
    ``lengths_m``, ``generic_lengths_m``, ``lengths_from_tracks`` {group: number};
    ``cameras`` {name: {start, fitted: numbers}}; ``identifiability`` and ``camera_auto``
    objects)."""
    def fail(what, field):
        raise InputError(what, file=path, field=f"calibration.{field}")

    def numbers(d, field):
        if not isinstance(d, dict) or not all(_number(v) for v in d.values()):
            fail("must be an object {name: number}", field)

    for key in ("lengths_m", "generic_lengths_m", "lengths_from_tracks"):
        if c.get(key) is not None:
            numbers(c[key], key)
    cams = c.get("cameras") or {}
    if not isinstance(cams, dict) or not all(isinstance(v, dict) and _number(v.get("start")) and
                                             _number(v.get("fitted")) for v in cams.values()):
        fail("must be an object {camera: {start, fitted}} of numbers", "cameras")
    for key in ("identifiability", "camera_auto"):
        if c.get(key) is not None and not isinstance(c[key], dict):
            fail("must be an object", key)
    ident = c.get("identifiability") or {}
    if not isinstance(ident.get("undetermined", []), list):
        fail("must be a list of group names", "identifiability.undetermined")
    focal = (c.get("camera_auto") or {}).get("focal")
    if focal is not None and not isinstance(focal, dict):
        fail("must be an object", "camera_auto.focal")
    return c


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x)
