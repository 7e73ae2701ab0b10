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
    return data


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
