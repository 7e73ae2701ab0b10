"""Camera models: orthographic and perspective pinhole.

Camera axes are x right, y down, z forward (into the scene). ``R`` is the rotation
world -> camera (``R_cam_world``), so a world point X has camera coordinates
``x_cam = R X (+ t)``.

* :class:`Orthographic`: ``u = s * (R X)[:2] + c`` with scale ``s`` in pixels per metre
  and image centre ``c`` in pixels. Depth (camera z) is lost.
* :class:`Perspective`: ``x_cam = R X + t``, ``u = (K x_cam)[:2] / z`` with intrinsics K.

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
]

_ROT_TOL = 1e-6


def _as_matrix(value, shape, field, file):
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"expected a numeric array of shape {shape}", file=file, field=field)
    if arr.shape != shape:
        raise InputError(f"expected shape {shape}, got {arr.shape}", file=file, field=field)
    if not np.all(np.isfinite(arr)):
        raise InputError("contains NaN or infinite values", file=file, field=field)
    return arr


def _check_rotation(R, file=None, field="R"):
    R = _as_matrix(R, (3, 3), field, file)
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
    """Pinhole camera: ``x_cam = R X + t``, ``u = (K x_cam)[:2] / x_cam[2]``.

    Parameters
    ----------
    K : (3, 3) intrinsics, upper triangular with last row (0, 0, 1), positive focal lengths.
    R : (3, 3) rotation world -> camera.
    t : (3,) translation world -> camera (metres).
    """

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
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

    def camera_points(self, p_world):
        return np.asarray(p_world, float) @ self.R.T + self.t

    def project(self, p_world):
        x_cam = self.camera_points(p_world)
        w = x_cam @ self.K.T
        return w[..., :2] / w[..., 2:3]

    def project_with_jacobian(self, p_world):
        x_cam = self.camera_points(p_world)
        w = x_cam @ self.K.T
        z = w[..., 2:3]
        uv = w[..., :2] / z
        # d uv / d x_cam = (K[:2] - uv (x) K[2]) / z ; then chain with R.
        d_uv_d_xcam = (self.K[:2] - uv[..., :, None] * self.K[2]) / z[..., None]
        return uv, d_uv_d_xcam @ self.R

    def depth(self, p_world):
        return self.camera_points(p_world)[..., 2]

    def to_dict(self):
        return {"model": "perspective", "K": self.K.tolist(), "R": self.R.tolist(), "t": self.t.tolist()}

    @classmethod
    def look_at(cls, eye_world, target_world, up_world=(0, 1, 0), f_px=1000.0, center=(960.0, 540.0)):
        """Camera at ``eye_world`` looking at ``target_world``."""
        eye = np.asarray(eye_world, float)
        R = look_at_rotation(np.asarray(target_world, float) - eye, up_world)
        K = np.array([[f_px, 0, center[0]], [0, f_px, center[1]], [0, 0, 1.0]])
        return cls(K, R, -R @ eye)


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
            return Perspective(data["K"], data["R"], data["t"])
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
