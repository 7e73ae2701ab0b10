"""Camera calibration files as other tools write them.

:func:`load_cameras` reads every camera of a calibration file; :func:`load_camera` reads
the one camera of a file (or the one named). Supported:

* **Pose2Sim / Sports2D TOML** (``.toml``): one table per camera with ``name``,
  ``size = [width, height]`` (pixels), ``matrix`` (3 x 3 K), ``distortions``
  (``[k1, k2, p1, p2]``, optionally ``k3``), ``rotation`` (Rodrigues vector) and
  ``translation``, both **world -> camera** as OpenCV's ``solvePnP`` gives them
  (``x_cam = R(rotation) X + translation``, metres), and ``fisheye``. Tables named
  ``metadata``, ``capture_volume``, ``charuco`` and ``checkerboard`` are skipped, exactly as
  Pose2Sim's ``common.retrieve_calib_params`` does; cameras keep the file's order.
* **OpenCV-style YAML / XML / JSON** (``.yml``, ``.yaml``, ``.xml``, ``.json``): what
  ``cv::FileStorage`` writes (``%YAML:1.0``, ``!!opencv-matrix`` nodes, ``<opencv_storage>``,
  ``"type_id": "opencv-matrix"``) or plain JSON/YAML lists, with the camera matrix under
  ``K`` / ``camera_matrix`` / ``cameraMatrix`` / ``intrinsic_matrix`` / ``mtx``, the
  distortion under ``dist`` / ``dist_coeffs`` / ``distortion_coefficients`` / ``D``, and an
  optional world -> camera pose ``rvec`` (or ``R``, Rodrigues vector or 3 x 3 matrix) with
  ``tvec`` (or ``t``). Several cameras: a ``cameras`` list or mapping, or one top-level
  mapping per camera. A file with intrinsics only gives a camera at the world origin
  (``R = I``, ``t = 0``, :attr:`CalibratedCamera.has_pose` false).
* **pinrecon camera JSON** (a ``.json`` object with ``model``; ``docs/formats.md``).

Translations are read as metres; pass ``metres_per_unit`` (e.g. 0.001 for a calibration
made with a board measured in millimetres) otherwise. Fisheye models are refused with a
clear error. Every problem is one :class:`~pinrecon.errors.InputError` naming the file and
the field.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...cameras import Camera, Perspective, camera_from_dict
from ...errors import InputError, UnknownNameError
from ..jsonfile import read_json, read_text
from .opencv_storage import decode_matrices, parse_xml, parse_yaml

__all__ = [
    "CalibratedCamera",
    "load_cameras",
    "load_camera",
    "rodrigues_to_matrix",
    "SUPPORTED_FORMATS",
]

SUPPORTED_FORMATS = (
    "Pose2Sim / Sports2D calibration TOML (.toml)",
    "OpenCV FileStorage or plain YAML (.yml, .yaml) with camera_matrix / K and "
    "distortion_coefficients / dist (+ rvec, tvec)",
    "OpenCV FileStorage XML (.xml, <opencv_storage>)",
    "OpenCV-style JSON (.json) with K / camera_matrix, dist / dist_coeffs (+ rvec, tvec)",
    "pinrecon camera JSON (.json with 'model', docs/formats.md section 5)",
)
_FORMATS = ("toml", "yaml", "xml", "json")

# Pose2Sim's common.retrieve_calib_params skips these tables.
_TOML_NOT_CAMERAS = ("metadata", "capture_volume", "charuco", "checkerboard")
_TOML_FIELDS = ("size", "matrix", "distortions", "rotation", "translation")

# OpenCV-style keys, compared after lower-casing and dropping everything but [a-z0-9].
_K_KEYS = ("k", "cameramatrix", "intrinsicmatrix", "intrinsics", "mtx")
_DIST_KEYS = (
    "dist",
    "distcoeffs",
    "distortioncoefficients",
    "distortioncoeffs",
    "distortion",
    "distortions",
    "d",
)
_ROT_KEYS = ("rvec", "rotationvector", "rotation", "rotationmatrix", "r")
_T_KEYS = ("tvec", "translationvector", "translation", "t")
_SIZE_KEYS = ("imagesize", "size", "resolution")
_FISHEYE_WORDS = ("fisheye", "equidistant", "kannala", "omni")


@dataclass(frozen=True)
class CalibratedCamera:
    """One camera of a calibration file.

    name : the camera's name in the file (Pose2Sim ``name``, the table or mapping key, or
        the file's stem for a single-camera file).
    camera : the :class:`~pinrecon.cameras.Camera` (a :class:`Perspective` with distortion
        for calibration formats).
    image_size : ``(width, height)`` in pixels, or None when the file does not say.
    has_pose : False when the file holds intrinsics only (the camera then sits at the world
        origin, ``R = I``, ``t = 0``).
    source : "pose2sim-toml", "opencv-yaml", "opencv-xml", "opencv-json" or "pinrecon-json".
    """

    name: str
    camera: Camera
    image_size: tuple[int, int] | None
    has_pose: bool
    source: str


def rodrigues_to_matrix(rvec) -> np.ndarray:
    """Rotation matrix of a Rodrigues (axis * angle) vector, as OpenCV's ``cv2.Rodrigues``."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(np.asarray(rvec, float).reshape(3)).as_matrix()


def _supported_list() -> str:
    return "; ".join(SUPPORTED_FORMATS)


def _unsupported(path, why: str) -> InputError:
    return InputError(f"{why}. Supported calibration formats: {_supported_list()}", file=path)


def _read_text(path: Path) -> str:
    try:
        return read_text(path)
    except InputError as exc:
        if "UTF-8" in exc.message:
            raise _unsupported(path, "is not a text file") from None
        raise


def _detect(path: Path, text: str) -> str:
    suffix = path.suffix.lower()
    if suffix == ".toml":
        return "toml"
    if suffix in (".yml", ".yaml"):
        return "yaml"
    if suffix == ".xml":
        return "xml"
    if suffix == ".json":
        return "json"
    head = text.lstrip()
    if head.startswith("%YAML"):
        return "yaml"
    if head.startswith("<") and "<opencv_storage" in head[:4000]:
        return "xml"
    if head.startswith("{"):
        return "json"
    if head.startswith("<"):
        raise _unsupported(
            path,
            "is an XML file that is not OpenCV FileStorage (a Qualisys .qca.txt, for "
            "example, converts to a Pose2Sim TOML with Pose2Sim's calibration step)",
        )
    raise _unsupported(path, f"has an unknown calibration format (suffix {suffix or 'none'!r})")


# ---------------------------------------------------------------- shared checks
def _finite_array(value, field, path, what="numbers") -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"expected {what}, got {value!r}", file=path, field=field) from None
    if not np.all(np.isfinite(arr)):
        raise InputError("contains NaN or infinite values", file=path, field=field)
    return arr


def _rotation(value, field, path) -> np.ndarray:
    arr = _finite_array(value, field, path, "a Rodrigues vector (3) or a 3 x 3 rotation matrix")
    if arr.size == 3:
        return rodrigues_to_matrix(arr)
    if arr.size == 9:
        return arr.reshape(3, 3)
    raise InputError(
        "expected a Rodrigues vector (3 numbers) or a 3 x 3 rotation matrix, "
        f"got shape {arr.shape}",
        file=path,
        field=field,
    )


def _translation(value, field, path, metres_per_unit) -> np.ndarray:
    arr = _finite_array(value, field, path, "3 numbers")
    if arr.size != 3:
        raise InputError(f"expected 3 numbers, got shape {arr.shape}", file=path, field=field)
    return arr.reshape(3) * metres_per_unit


def _matrix33(value, field, path) -> np.ndarray:
    arr = _finite_array(value, field, path, "a 3 x 3 camera matrix")
    if arr.size != 9:
        raise InputError(
            f"expected a 3 x 3 camera matrix, got shape {arr.shape}", file=path, field=field
        )
    return arr.reshape(3, 3)


def _image_size(value, field, path) -> tuple[int, int]:
    arr = _finite_array(value, field, path, "[width, height]").ravel()
    if arr.size != 2 or np.any(arr <= 0):
        raise InputError(
            f"expected [width, height] in pixels, got {value!r}", file=path, field=field
        )
    return int(round(arr[0])), int(round(arr[1]))


def _perspective(K, dist, R, t, path, fields: dict) -> Perspective:
    """Build the camera; the camera's own validation errors are renamed to the file's
    field names (``fields`` maps K / R / t / dist to them)."""
    try:
        return Perspective(K, R, t, dist)
    except InputError as exc:
        raise InputError(exc.message, file=path, field=fields.get(exc.field, exc.field)) from None


# ---------------------------------------------------------------- Pose2Sim TOML
def _toml_camera(key, table, path, metres_per_unit) -> CalibratedCamera:
    missing = [f for f in _TOML_FIELDS if f not in table]
    if missing:
        raise InputError(
            f"camera table [{key}] lacks {', '.join(missing)}; a Pose2Sim calibration camera "
            f"has {', '.join(_TOML_FIELDS)} (tables {', '.join(_TOML_NOT_CAMERAS)} are skipped)",
            file=path,
            field=key,
        )
    if table.get("fisheye", False) not in (False, 0):
        raise InputError(
            "fisheye cameras are not supported (only the pinhole model with OpenCV's k1, k2, "
            "p1, p2, k3 distortion); set fisheye = false only if the lens really is a pinhole one",
            file=path,
            field=f"{key}.fisheye",
        )
    name = table.get("name", key)
    if not isinstance(name, str) or not name:
        raise InputError(
            f"expected a camera name (text), got {name!r}", file=path, field=f"{key}.name"
        )
    fields = {
        "K": f"{key}.matrix",
        "dist": f"{key}.distortions",
        "R": f"{key}.rotation",
        "t": f"{key}.translation",
    }
    camera = _perspective(
        _matrix33(table["matrix"], fields["K"], path),
        table["distortions"],
        _rotation(table["rotation"], fields["R"], path),
        _translation(table["translation"], fields["t"], path, metres_per_unit),
        path,
        fields,
    )
    size = _image_size(table["size"], f"{key}.size", path)
    return CalibratedCamera(name, camera, size, True, "pose2sim-toml")


def _read_toml(text, path, metres_per_unit):
    try:
        import tomllib
    except ModuleNotFoundError:  # Python < 3.11
        import tomli as tomllib
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML ({exc})", file=path) from None
    except (ValueError, RecursionError) as exc:  # an integer past Python's int-string limit; nesting past recursion
        raise InputError(f"not valid TOML ({type(exc).__name__}: {str(exc)[:80]})", file=path) from None
    cameras = [
        _toml_camera(key, table, path, metres_per_unit)
        for key, table in doc.items()
        if key not in _TOML_NOT_CAMERAS and isinstance(table, dict)
    ]
    if not cameras:
        raise InputError(
            "no camera table found; a Pose2Sim / Sports2D calibration has one [table] per camera "
            f"with {', '.join(_TOML_FIELDS)}",
            file=path,
        )
    return cameras


# ---------------------------------------------------------------- OpenCV-style
def _norm(key) -> str:
    return re.sub(r"[^a-z0-9]", "", str(key).lower())


def _lookup(d: dict, candidates) -> tuple[str | None, object]:
    keys = {}
    for k in d:
        keys.setdefault(_norm(k), k)
    for c in candidates:
        if c in keys:
            return keys[c], d[keys[c]]
    return None, None


def _has_intrinsics(d) -> bool:
    return isinstance(d, dict) and _lookup(d, _K_KEYS)[0] is not None


def _check_not_fisheye(d, prefix, path):
    for key in ("distortion_model", "distortionmodel", "model", "camera_model", "fisheye"):
        k, v = _lookup(d, (_norm(key),))
        if k is None:
            continue
        if (isinstance(v, bool) and v) or (
            isinstance(v, str) and any(w in v.lower() for w in _FISHEYE_WORDS)
        ):
            raise InputError(
                f"fisheye / wide-angle models are not supported (got {v!r}); only the pinhole "
                "model with OpenCV's k1, k2, p1, p2, k3 distortion is",
                file=path,
                field=prefix + k,
            )


def _opencv_camera(d, name, path, source, metres_per_unit, prefix="") -> CalibratedCamera:
    _check_not_fisheye(d, prefix, path)
    k_key, K = _lookup(d, _K_KEYS)
    d_key, dist = _lookup(d, _DIST_KEYS)
    r_key, rot = _lookup(d, _ROT_KEYS)
    t_key, trans = _lookup(d, _T_KEYS)
    fields = {
        "K": prefix + str(k_key),
        "dist": prefix + str(d_key),
        "R": prefix + str(r_key),
        "t": prefix + str(t_key),
    }
    if (r_key is None) != (t_key is None):
        given, lacking = (r_key, "tvec / t") if t_key is None else (t_key, "rvec / R")
        raise InputError(
            f"a camera pose needs both a rotation and a translation; {lacking} is missing",
            file=path,
            field=prefix + str(given),
        )
    has_pose = r_key is not None
    R = _rotation(rot, fields["R"], path) if has_pose else np.eye(3)
    t = _translation(trans, fields["t"], path, metres_per_unit) if has_pose else np.zeros(3)
    if dist is not None:
        dist = _finite_array(dist, fields["dist"], path, "distortion coefficients").ravel()
    camera = _perspective(_matrix33(K, fields["K"], path), dist, R, t, path, fields)
    w_key, width = _lookup(d, ("imagewidth", "width"))
    h_key, height = _lookup(d, ("imageheight", "height"))
    s_key, size = _lookup(d, _SIZE_KEYS)
    if w_key is not None and h_key is not None:
        size = _image_size([width, height], prefix + f"{w_key}, {h_key}", path)
    elif s_key is not None:
        size = _image_size(size, prefix + s_key, path)
    else:
        size = None
    return CalibratedCamera(name, camera, size, has_pose, source)


def _opencv_cameras(doc, path, source, metres_per_unit):
    doc = decode_matrices(doc, path)
    if _has_intrinsics(doc):
        _, name = _lookup(doc, ("cameraname", "name", "camera"))
        name = name if isinstance(name, str) and name else path.stem
        return [_opencv_camera(doc, name, path, source, metres_per_unit)]
    c_key, node = _lookup(doc, ("cameras",))
    if isinstance(node, list):
        items = [(f"{c_key}[{i}]", c) for i, c in enumerate(node)]
    elif isinstance(node, dict):
        items = [(f"{c_key}.{k}", c) for k, c in node.items()]
    else:
        items = [(str(k), c) for k, c in doc.items() if _has_intrinsics(c)]
    cameras = []
    for where, cam in items:
        if not _has_intrinsics(cam):
            raise InputError(
                "is not a camera: no camera matrix (K / camera_matrix)", file=path, field=where
            )
        _, name = _lookup(cam, ("name", "cameraname"))
        if not (isinstance(name, str) and name):
            name = where.split(".", 1)[1] if "." in where else where
        cameras.append(_opencv_camera(cam, name, path, source, metres_per_unit, where + "."))
    if not cameras:
        raise _unsupported(
            path,
            "holds no camera matrix (looked for K, camera_matrix, cameraMatrix, "
            "intrinsic_matrix or mtx, at the top level, under 'cameras' or one level down)",
        )
    return cameras


def _read_json(path, metres_per_unit):
    doc = read_json(path)
    if isinstance(doc, dict) and (
        doc.get("model") in ("orthographic", "perspective")
        or ("model" in doc and not _has_intrinsics(doc))
    ):
        return [
            CalibratedCamera(
                path.stem, camera_from_dict(doc, file=path), None, True, "pinrecon-json"
            )
        ]
    if not isinstance(doc, dict):
        raise _unsupported(path, "is JSON but not an object")
    return _opencv_cameras(doc, path, "opencv-json", metres_per_unit)


# ---------------------------------------------------------------- public
def load_cameras(
    path: str | os.PathLike, fmt: str | None = None, *, metres_per_unit: float = 1.0
) -> list[CalibratedCamera]:
    """Every camera of a calibration file, in the file's order.

    ``fmt`` forces the reader ("toml", "yaml", "xml" or "json"); by default the suffix
    decides (or the content, for other suffixes). ``metres_per_unit`` scales translations
    (pinrecon camera JSON is always metres and is not scaled).
    """
    path = Path(path)
    if fmt is not None and fmt not in _FORMATS:
        raise InputError(
            f"unknown calibration format {fmt!r}; expected one of {', '.join(_FORMATS)}",
            file=path,
            field="format",
        )
    try:
        ok = bool(np.isfinite(float(metres_per_unit)) and float(metres_per_unit) > 0)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InputError(
            f"must be a positive number, got {metres_per_unit!r}", field="metres_per_unit"
        )
    text = _read_text(path)
    fmt = fmt or _detect(path, text)
    if fmt == "toml":
        cameras = _read_toml(text, path, metres_per_unit)
    elif fmt == "json":
        cameras = _read_json(path, metres_per_unit)
    elif fmt == "xml":
        cameras = _opencv_cameras(parse_xml(text, path), path, "opencv-xml", metres_per_unit)
    else:
        cameras = _opencv_cameras(parse_yaml(text, path), path, "opencv-yaml", metres_per_unit)
    names = [c.name for c in cameras]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(f"camera names must be unique; repeated: {', '.join(dup)}", file=path)
    return cameras


def load_camera(
    path: str | os.PathLike,
    name: str | None = None,
    fmt: str | None = None,
    *,
    metres_per_unit: float = 1.0,
) -> Camera:
    """The camera of a one-camera calibration file, or the camera called ``name``.

    A file with several cameras and no ``name`` is refused with an error listing them.
    """
    cameras = load_cameras(path, fmt, metres_per_unit=metres_per_unit)
    names = [c.name for c in cameras]
    if name is not None:
        if name not in names:
            raise UnknownNameError("camera", [name], names, file=path)
        return cameras[names.index(name)].camera
    if len(cameras) > 1:
        raise InputError(
            f"holds {len(cameras)} cameras ({', '.join(names)}); choose one with "
            "load_camera(path, name=...) or read them all with load_cameras(path)",
            file=path,
        )
    return cameras[0].camera
