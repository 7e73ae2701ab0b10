"""Camera intrinsics (and a perspective camera's pose) as global unknowns.

One global ``theta`` multiplies the camera's scale by ``exp(theta)`` about a fixed point:

* :class:`~pinrecon.cameras.Orthographic` ``u = s (R X)[:2] + c``: ``s -> s exp(theta)``,
  so ``d u / d theta = s (R X)[:2] = u - c`` (``c`` the image of the world origin);
* :class:`~pinrecon.cameras.Perspective` ``u = (K x)[:2] / z``: the focal block
  ``K[:2, :2] -> exp(theta) K[:2, :2]`` (fx and fy together, so square pixels stay
  square; the principal point ``K[:2, 2]`` is fixed), so ``d u / d theta = u - K[:2, 2]``
  (with lens distortion applied to normalised coordinates before ``K`` this still holds).

``theta = 0`` is the camera as given (the start). Not observable together with the
figure's overall size without 3D information (a 3D keyframe or marker): an orthographic
scale against a uniform scaling of every segment, a focal length against the distance
along the optical axis.

With ``pose_col`` (a perspective camera placed by 3D point keyframes: the keyframes fix the
world, so the camera's place in it is observable) six more globals move the camera:
``x_cam = exp(w) (R0 X + t0) + dt``, ``w = g[pose_col:pose_col+3]`` a rotation vector about
the camera's centre (in its own axes) and ``dt = g[pose_col+3:pose_col+6]`` metres in its
axes; ``w = dt = 0`` is the camera as given. ``d x_cam / d w = -exp(w) [y]_x Jr(w)`` with
``y = R0 X + t0`` and ``Jr`` SO(3)'s right Jacobian (Pinocchio's ``Jexp3``), ``d x_cam / d dt
= I``; ``d uv / d x_cam`` is ``d uv / d X`` (which :meth:`~pinrecon.cameras.Camera.
project_with_jacobian` returns) times ``R^T``, lens distortion included.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin

from ..cameras import Camera, Orthographic, Perspective
from ..errors import InputError

__all__ = ["CameraScale"]


class CameraScale:
    """The camera's log scale (orthographic) or log focal length (perspective) as the
    global unknown ``g[col]``.

    Parameters
    ----------
    camera : the camera at ``theta = 0``.
    col : index of this unknown in the global vector.
    pose_col : with a perspective camera, the first of six more globals that move it
        (see the module doc); None keeps its pose.
    """

    #: names of the six pose globals, in order
    POSE_NAMES = ("rot_x", "rot_y", "rot_z", "shift_x_m", "shift_y_m", "shift_z_m")

    def __init__(self, camera: Camera, col: int = 0, pose_col: int | None = None):
        if not isinstance(camera, (Orthographic, Perspective)):
            raise InputError(f"cannot calibrate a {type(camera).__name__} camera", field="camera")
        if pose_col is not None and not isinstance(camera, Perspective):
            raise InputError("only a perspective camera's pose can be an unknown", field="camera")
        self.base = camera
        self.col = int(col)
        self.pose_col = None if pose_col is None else int(pose_col)
        self.name = "log_scale" if isinstance(camera, Orthographic) else "log_focal"

    @property
    def cols(self) -> np.ndarray:
        """The global columns this camera reads: the scale's, then the pose's six."""
        pose = [] if self.pose_col is None else list(range(self.pose_col, self.pose_col + 6))
        return np.array([self.col, *pose], dtype=int)

    def _pose(self, g):
        """(w, dt) of the globals ``g``; zeros without pose unknowns."""
        if self.pose_col is None:
            return np.zeros(3), np.zeros(3)
        v = np.asarray(g, float)[self.pose_col : self.pose_col + 6]
        return v[:3], v[3:]

    def camera(self, g) -> Camera:
        """The camera at the globals ``g`` (reads ``g[col]`` and, with pose unknowns, the pose's)."""
        theta = float(np.asarray(g, float)[self.col])
        w, dt = self._pose(g)
        if theta == 0.0 and not (w.any() or dt.any()):
            return self.base
        f = float(np.exp(theta))
        if isinstance(self.base, Orthographic):
            return dataclasses.replace(self.base, scale=self.base.scale * f)
        K = np.array(self.base.K, float)
        K[:2, :2] *= f
        E = pin.exp3(w)
        return dataclasses.replace(self.base, K=K, R=E @ self.base.R, t=E @ self.base.t + dt)

    def pose_change(self, g) -> dict:
        """How far the pose globals ``g`` move the camera from its start: ``rotation_deg``
        (about its centre) and ``shift_m`` (of its centre in the world)."""
        w, _ = self._pose(g)
        cam = self.camera(g)
        centre = -cam.R.T @ cam.t
        start = -self.base.R.T @ self.base.t
        return {"rotation_deg": float(np.degrees(np.linalg.norm(w))), "shift_m": float(np.linalg.norm(centre - start))}

    def jacobian(self, g, uv_px: np.ndarray, d_uv: np.ndarray, points: np.ndarray) -> np.ndarray:
        """d uv / d g[cols] (..., 2, len(cols)) at the projections ``uv_px`` (..., 2) of world
        ``points`` (..., 3) by the camera at ``g``, whose ``d uv / d X`` is ``d_uv`` (..., 2, 3)."""
        out = np.empty((*np.shape(uv_px), len(self.cols)))
        out[..., 0] = self.d_uv(uv_px)
        if self.pose_col is not None:
            w, _ = self._pose(g)
            E = pin.exp3(w)
            A = d_uv @ self.base.R.T  # d uv / d x_cam times E: d uv / d X R^T E with R = E R0
            y = np.asarray(points, float) @ self.base.R.T + self.base.t  # (..., 3)
            # d x_cam / d w = -E [y]_x Jr, and a row a times [y]_x is (a x y)
            out[..., 1:4] = -np.cross(A, y[..., None, :]) @ pin.Jexp3(w)
            out[..., 4:7] = A @ E.T  # d uv / d x_cam
        return out

    @property
    def fixed_point_px(self) -> np.ndarray:
        """(2,) the image point the scaling keeps fixed (centre or principal point)."""
        if isinstance(self.base, Orthographic):
            return np.asarray(self.base.center, float)
        return np.asarray(self.base.K[:2, 2], float)

    def d_uv(self, uv_px: np.ndarray) -> np.ndarray:
        """d uv / d theta (..., 2) at projections ``uv_px`` (..., 2) of the current camera."""
        return np.asarray(uv_px, float) - self.fixed_point_px

    def value(self, g) -> float:
        """The scale (px/m) or focal length (px) at the globals ``g``."""
        cam = self.camera(g)
        return float(cam.scale) if isinstance(cam, Orthographic) else float(cam.K[0, 0])
