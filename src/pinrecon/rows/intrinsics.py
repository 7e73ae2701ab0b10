"""Camera intrinsics as a global unknown: the log of the image scale.

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
"""

from __future__ import annotations

import dataclasses

import numpy as np

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
    """

    def __init__(self, camera: Camera, col: int = 0):
        if not isinstance(camera, (Orthographic, Perspective)):
            raise InputError(f"cannot calibrate a {type(camera).__name__} camera", field="camera")
        self.base = camera
        self.col = int(col)
        self.name = "log_scale" if isinstance(camera, Orthographic) else "log_focal"

    def camera(self, g) -> Camera:
        """The camera at the globals ``g`` (reads ``g[col]``)."""
        theta = float(np.asarray(g, float)[self.col])
        if theta == 0.0:
            return self.base
        f = float(np.exp(theta))
        if isinstance(self.base, Orthographic):
            return dataclasses.replace(self.base, scale=self.base.scale * f)
        K = np.array(self.base.K, float)
        K[:2, :2] *= f
        return dataclasses.replace(self.base, K=K)

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
