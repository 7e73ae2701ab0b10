"""Camera models: orthographic and perspective pinhole.

Camera axes are x right, y down, z forward (into the scene). ``R`` is the rotation
world -> camera (``R_cam_world``), so a world point X has camera coordinates
``x_cam = R X (+ t)``.

* :class:`Orthographic`: ``u = s * (R X)[:2] + c`` with scale ``s`` in pixels per metre
  and image centre ``c`` in pixels. Depth (camera z) is lost.
* :class:`Perspective`: ``x_cam = R X + t``, ``u = (K x_cam)[:2] / z`` with intrinsics K,
  optionally with OpenCV's lens distortion (k1, k2, p1, p2, k3) applied to ``x_cam[:2] / z``.

Both project arrays of shape (..., 3) and give the analytic Jacobian d u / d X of
shape (..., 2, 3). Both round-trip through JSON (see ``docs/formats.md``).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass

import numpy as np

from .errors import InputError

__all__ = [
    "Camera",
    "Orthographic",
    "Perspective",
    "load_camera",
    "camera_from_dict",
    "look_at_rotation",
    "distort_normalized",
    "distortion_jacobian",
    "DISTORTION_NAMES",
]

_ROT_TOL = 1e-6

DISTORTION_NAMES = ("k1", "k2", "p1", "p2", "k3")
# OpenCV's distCoeffs come as 4, 5, 8, 12 or 14 numbers: (k1, k2, p1, p2[, k3[, k4, k5, k6
# [, s1, s2, s3, s4[, tau_x, tau_y]]]]). Only the first five are modelled here.
_OPENCV_DIST_LENGTHS = (4, 5, 8, 12, 14)
_OPENCV_EXTRA_NAMES = ("k4", "k5", "k6", "s1", "s2", "s3", "s4", "tau_x", "tau_y")


def _as_distortion(value, field="dist", file=None) -> np.ndarray:
    """OpenCV distortion coefficients -> (5,) array (k1, k2, p1, p2, k3).

    Accepts any of OpenCV's lengths (0, 4, 5, 8, 12, 14); terms past k3 (rational,
    thin-prism, tilt) must be zero, since this camera model does not include them.
    """
    if value is None:
        return np.zeros(5)
    try:
        arr = np.asarray(value, dtype=float).ravel()
    except (TypeError, ValueError):
        raise InputError(
            "expected a list of numbers (k1, k2, p1, p2[, k3])", file=file, field=field
        ) from None
    n = arr.size
    if n != 0 and n not in _OPENCV_DIST_LENGTHS:
        raise InputError(
            f"expected 4 or 5 distortion coefficients (k1, k2, p1, p2[, k3]) as OpenCV "
            f"orders them, or OpenCV's 8, 12 or 14 with the extra terms zero; got {n}",
            file=file,
            field=field,
        )
    names = DISTORTION_NAMES + _OPENCV_EXTRA_NAMES
    bad = [f"{names[i]} = {arr[i]}" for i in range(n) if not np.isfinite(arr[i])]
    if bad:
        raise InputError(
            "distortion coefficients must be finite numbers, got " + ", ".join(bad),
            file=file,
            field=field,
        )
    extra = [f"{_OPENCV_EXTRA_NAMES[i - 5]} = {arr[i]:g}" for i in range(5, n) if arr[i] != 0.0]
    if extra:
        raise InputError(
            "only OpenCV's k1, k2, p1, p2, k3 distortion model is supported; the rational, "
            f"thin-prism and tilt terms must be zero, got {', '.join(extra)}",
            file=file,
            field=field,
        )
    out = np.zeros(5)
    out[: min(n, 5)] = arr[:5]
    return out


def distort_normalized(xy: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """OpenCV's lens distortion of normalised image points ``xy = x_cam[:2] / z`` (..., 2).

    With ``r2 = x^2 + y^2`` and ``radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3``::

        x_d = x radial + 2 p1 x y + p2 (r2 + 2 x^2)
        y_d = y radial + p1 (r2 + 2 y^2) + 2 p2 x y
    """
    k1, k2, p1, p2, k3 = dist
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.stack([xd, yd], axis=-1)


def distortion_jacobian(xy: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """d distort_normalized / d xy, shape (..., 2, 2)."""
    k1, k2, p1, p2, k3 = dist
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    d_radial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r2
    cross = 2.0 * x * y * d_radial + 2.0 * p1 * x + 2.0 * p2 * y  # d xd/dy = d yd/dx
    J = np.empty(xy.shape[:-1] + (2, 2))
    J[..., 0, 0] = radial + 2.0 * x * x * d_radial + 2.0 * p1 * y + 6.0 * p2 * x
    J[..., 0, 1] = cross
    J[..., 1, 0] = cross
    J[..., 1, 1] = radial + 2.0 * y * y * d_radial + 6.0 * p1 * y + 2.0 * p2 * x
    return J


#: the largest camera number accepted (a focal length, a principal point, a translation in metres)
MAX_CAMERA_VALUE = 1e7


def _as_matrix(value, shape, field, file):
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"expected a numeric array of shape {shape}", file=file, field=field)
    if arr.shape != shape:
        raise InputError(f"expected shape {shape}, got {arr.shape}", file=file, field=field)
    if not np.all(np.isfinite(arr)):
        raise InputError("contains NaN or infinite values", file=file, field=field)
    if np.any(np.abs(arr) > MAX_CAMERA_VALUE):
        raise InputError(f"a value beyond +-{MAX_CAMERA_VALUE:g} (pixels or metres)", file=file, field=field)
    return arr


def _check_rotation(R, file=None, field="R"):
    R = _as_matrix(R, (3, 3), field, file)
    with np.errstate(all="ignore"):  # subnormal entries: the test below refuses them, quietly
        err = np.abs(R @ R.T - np.eye(3)).max()
        det = np.linalg.det(R)
    if err > _ROT_TOL or det < 0:
        raise InputError(
            f"is not a rotation matrix (|R R^T - I|max = {err:.2e}, det = {det:.6f}); "
            "R must be orthonormal with determinant +1",
            file=file,
            field=field,
        )
    return R


def look_at_rotation(forward_world, up_world=(0.0, 1.0, 0.0)) -> np.ndarray:
    """R_cam_world for a camera looking along ``forward_world`` with ``up_world`` up.

    Camera z = forward, camera y = down (minus the part of ``up`` orthogonal to forward),
    camera x = y cross z (right).
    """
    z = np.asarray(forward_world, float)
    z = z / np.linalg.norm(z)
    up = np.asarray(up_world, float)
    y = -(up - z * (up @ z))
    n = np.linalg.norm(y)
    if n < 1e-9:
        raise ValueError("up_world is parallel to the viewing direction")
    y /= n
    x = np.cross(y, z)
    return np.stack([x, y, z])


class Camera:
    """Common interface: ``project(X)``, ``jacobian(X)``, ``project_with_jacobian(X)``."""

    model: str

    def project(self, p_world: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def jacobian(self, p_world: np.ndarray) -> np.ndarray:
        return self.project_with_jacobian(p_world)[1]

    def project_with_jacobian(self, p_world):  # pragma: no cover - abstract
        raise NotImplementedError

    def depth(self, p_world: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        """Camera z of world points (..., 3) -> (...)."""
        raise NotImplementedError

    def save(self, path: str | os.PathLike) -> None:
        """Write the camera JSON atomically (nothing half-written on error)."""
        from .io.atomic import atomic_write_text

        atomic_write_text(path, json.dumps(self.to_dict(), indent=2))

    def to_dict(self) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError


@dataclass(frozen=True, eq=False)
class Orthographic(Camera):
    """Scaled orthographic camera ``u = scale * (R X)[:2] + center``.

    Parameters
    ----------
    R : (3, 3) rotation world -> camera.
    scale : pixels per metre.
    center : (2,) image position (pixels) of the world origin's projection.
    """

    R: np.ndarray
    scale: float
    center: np.ndarray = (0.0, 0.0)
    model = "orthographic"

    def __post_init__(self):
        object.__setattr__(self, "R", _check_rotation(self.R))
        try:
            scale = float(self.scale)
        except (TypeError, ValueError):
            raise InputError(f"must be a positive number, got {self.scale!r}", field="scale") from None
        if isinstance(self.scale, bool) or not np.isfinite(scale) or scale <= 0:
            raise InputError(f"must be a positive number, got {self.scale!r}", field="scale")
        object.__setattr__(self, "scale", scale)
        object.__setattr__(self, "center", _as_matrix(self.center, (2,), "center", None))

    def project(self, p_world):
        p_world = np.asarray(p_world, float)
        return self.scale * (p_world @ self.R[:2].T) + self.center

    def project_with_jacobian(self, p_world):
        p_world = np.asarray(p_world, float)
        uv = self.project(p_world)
        J = np.broadcast_to(self.scale * self.R[:2], p_world.shape[:-1] + (2, 3))
        return uv, J

    def depth(self, p_world):
        return np.asarray(p_world, float) @ self.R[2]

    def backproject(self, uv, depth=0.0):
        """World points whose projection is ``uv`` (..., 2) at camera depth ``depth``."""
        uv = np.asarray(uv, float)
        xy = (uv - self.center) / self.scale
        x_cam = np.concatenate([xy, np.broadcast_to(np.asarray(depth, float), xy.shape[:-1])[..., None]], -1)
        return x_cam @ self.R

    def to_dict(self):
        return {
            "model": "orthographic",
            "R": self.R.tolist(),
            "scale": self.scale,
            "center": self.center.tolist(),
        }

    @classmethod
    def from_view(cls, forward_world, up_world=(0, 1, 0), scale=300.0, center=(0.0, 0.0)):
        """Camera looking along ``forward_world`` (see :func:`look_at_rotation`)."""
        return cls(look_at_rotation(forward_world, up_world), scale, center)


@dataclass(frozen=True, eq=False)
class Perspective(Camera):
    """Pinhole camera with OpenCV's lens distortion.

    ``x_cam = R X + t``; normalised point ``(x, y) = x_cam[:2] / x_cam[2]``; distorted
    ``(x_d, y_d) = distort_normalized((x, y), dist)``; pixels ``u = K[:2] @ (x_d, y_d, 1)``.
    Without distortion (the default) this is ``u = (K x_cam)[:2] / x_cam[2]``.

    Parameters
    ----------
    K : (3, 3) intrinsics, upper triangular with last row (0, 0, 1), positive focal lengths.
    R : (3, 3) rotation world -> camera.
    t : (3,) translation world -> camera (metres).
    dist : OpenCV distortion coefficients (k1, k2, p1, p2[, k3]); default all zero. Stored
        as a (5,) array. OpenCV's longer vectors are accepted when the extra terms are zero.
    """

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    dist: np.ndarray = None
    model = "perspective"

    def __post_init__(self):
        K = _as_matrix(self.K, (3, 3), "K", None)
        if not np.allclose(K[2], [0, 0, 1]) or K[1, 0] != 0 or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise InputError(
                "must be upper triangular with positive focal lengths and last row (0, 0, 1)",
                field="K",
            )
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "R", _check_rotation(self.R))
        object.__setattr__(self, "t", _as_matrix(self.t, (3,), "t", None))
        object.__setattr__(self, "dist", _as_distortion(self.dist))

    @property
    def has_distortion(self) -> bool:
        return bool(np.any(self.dist != 0.0))

    def camera_points(self, p_world):
        return np.asarray(p_world, float) @ self.R.T + self.t

    def project(self, p_world):
        x_cam = self.camera_points(p_world)
        if not self.has_distortion:
            w = x_cam @ self.K.T
            return w[..., :2] / w[..., 2:3]
        xy_d = distort_normalized(x_cam[..., :2] / x_cam[..., 2:3], self.dist)
        return xy_d @ self.K[:2, :2].T + self.K[:2, 2]

    def project_with_jacobian(self, p_world):
        x_cam = self.camera_points(p_world)
        if not self.has_distortion:
            w = x_cam @ self.K.T
            z = w[..., 2:3]
            uv = w[..., :2] / z
            # d uv / d x_cam = (K[:2] - uv (x) K[2]) / z ; then chain with R.
            d_uv_d_xcam = (self.K[:2] - uv[..., :, None] * self.K[2]) / z[..., None]
            return uv, d_uv_d_xcam @ self.R
        z = x_cam[..., 2:3]
        xy = x_cam[..., :2] / z
        uv = distort_normalized(xy, self.dist) @ self.K[:2, :2].T + self.K[:2, 2]
        # d xy / d x_cam = [I_2, -xy] / z
        d_xy_d_xcam = np.concatenate(
            [np.broadcast_to(np.eye(2), xy.shape[:-1] + (2, 2)), -xy[..., :, None]], axis=-1
        ) / z[..., None]
        d_uv_d_xcam = self.K[:2, :2] @ distortion_jacobian(xy, self.dist) @ d_xy_d_xcam
        return uv, d_uv_d_xcam @ self.R

    def normalized(self, uv_px, iterations: int = 20) -> np.ndarray:
        """Undistorted normalised coordinates ``x_cam[:2] / z`` of pixels ``uv_px`` (..., 2).

        Inverts K, then the distortion by Newton's method (exact to ~1e-12 inside the image
        for realistic lenses); a point where the distortion polynomial folds over (far
        outside the calibrated field of view) keeps its last iterate.
        """
        uv = np.asarray(uv_px, float)
        y_d = (uv[..., 1] - self.K[1, 2]) / self.K[1, 1]
        x_d = (uv[..., 0] - self.K[0, 2] - self.K[0, 1] * y_d) / self.K[0, 0]
        target = np.stack([x_d, y_d], axis=-1)
        if not self.has_distortion:
            return target
        xy = target.copy()
        for _ in range(iterations):
            resid = distort_normalized(xy, self.dist) - target
            if not np.any(np.abs(resid) > 1e-14):
                break
            J = distortion_jacobian(xy, self.dist)
            det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
            ok = np.abs(det) > 1e-12
            det = np.where(ok, det, 1.0)
            dx = (J[..., 1, 1] * resid[..., 0] - J[..., 0, 1] * resid[..., 1]) / det
            dy = (J[..., 0, 0] * resid[..., 1] - J[..., 1, 0] * resid[..., 0]) / det
            xy = xy - np.where(ok[..., None], np.stack([dx, dy], axis=-1), 0.0)
        return xy

    def depth(self, p_world):
        return self.camera_points(p_world)[..., 2]

    def to_dict(self):
        out = {"model": "perspective", "K": self.K.tolist(), "R": self.R.tolist()}
        out["t"] = self.t.tolist()
        if self.has_distortion:
            out["dist"] = self.dist.tolist()
        return out

    @classmethod
    def look_at(
        cls,
        eye_world,
        target_world,
        up_world=(0, 1, 0),
        f_px=1000.0,
        center=(960.0, 540.0),
        dist=None,
    ):
        """Camera at ``eye_world`` looking at ``target_world``."""
        eye = np.asarray(eye_world, float)
        R = look_at_rotation(np.asarray(target_world, float) - eye, up_world)
        K = np.array([[f_px, 0, center[0]], [0, f_px, center[1]], [0, 0, 1.0]])
        return cls(K, R, -R @ eye, dist)


def camera_from_dict(data: dict, file=None) -> Camera:
    """Build a camera from its JSON dictionary; errors name the file and field."""
    if not isinstance(data, dict):
        raise InputError("a camera must be a JSON object", file=file)
    model = data.get("model")
    try:
        if model == "orthographic":
            for key in ("R", "scale"):
                if key not in data:
                    raise InputError("is required for an orthographic camera", field=key)
            return Orthographic(data["R"], data["scale"], data.get("center", (0.0, 0.0)))
        if model == "perspective":
            for key in ("K", "R", "t"):
                if key not in data:
                    raise InputError("is required for a perspective camera", field=key)
            return Perspective(data["K"], data["R"], data["t"], data.get("dist"))
    except InputError as exc:
        raise exc.located(file=file) from None
    raise InputError(
        f"unknown camera model {model!r}; expected 'orthographic' or 'perspective'",
        file=file,
        field="model",
    )


def load_camera(path: str | os.PathLike) -> Camera:
    """Read a camera JSON file (``docs/formats.md``)."""
    from .io.jsonfile import read_json

    return camera_from_dict(read_json(path), file=path)
