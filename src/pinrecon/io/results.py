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

__all__ = ["save_result_npz", "load_result_npz", "REQUIRED_KEYS"]

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


def load_result_npz(path: str | os.PathLike) -> dict:
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", file=path)
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (ValueError, OSError) as exc:
        raise InputError(f"not a readable NPZ file ({exc})", file=path) from None
    missing = [k for k in REQUIRED_KEYS if k not in data]
    if missing:
        raise InputError(f"not a pinrecon result: missing {missing}", file=path)
    T = data["q"].shape[0]
    if data["times"].shape != (T,) or data["keypoints3d"].shape[0] != T:
        raise InputError("q, times and keypoints3d disagree on the number of frames", file=path)
    return data
