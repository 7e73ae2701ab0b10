"""Rotation conversions shared by the formats (BVH, CSV): intrinsic Euler angles in
degrees <-> rotation matrices, quaternions (x, y, z, w) <-> matrices, and continuous
Euler angles over time.

Conventions: ``euler_to_matrix("ZYX", [a, b, c]) = Rz(a) Ry(b) Rx(c)`` (intrinsic, BVH's
``CHANNELS ... Zrotation Yrotation Xrotation``); quaternions are stored ``(x, y, z, w)``
like Pinocchio's free flyer ``q[3:7]``. Everything is vectorised over leading axes.

This module is the floor under :mod:`pinrecon.io`: it imports numpy and scipy only.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

__all__ = [
    "euler_to_matrix",
    "matrix_to_euler",
    "continuous_euler",
    "quat_xyzw_to_matrix",
    "matrix_to_quat_xyzw",
]


def _axis_rotation(axis: str, angle_rad: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    z, o = np.zeros_like(c), np.ones_like(c)
    if axis == "X":
        rows = [[o, z, z], [z, c, -s], [z, s, c]]
    elif axis == "Y":
        rows = [[c, z, s], [z, o, z], [-s, z, c]]
    else:
        rows = [[c, -s, z], [s, c, z], [z, z, o]]
    return np.moveaxis(np.array(rows), (0, 1), (-2, -1))


def euler_to_matrix(axes: str, angles_deg: np.ndarray) -> np.ndarray:
    """Intrinsic rotation ``R = R_a1 R_a2 R_a3`` for ``axes`` like 'ZYX'; angles (..., n)
    in degrees; returns (..., 3, 3)."""
    angles = np.radians(np.asarray(angles_deg, float))
    R = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for k, a in enumerate(axes):
        R = R @ _axis_rotation(a, angles[..., k])
    return R


def matrix_to_euler(axes: str, R: np.ndarray) -> np.ndarray:
    """Inverse of :func:`euler_to_matrix` (degrees, (..., 3)) for three distinct axes.

    At gimbal lock scipy's "Gimbal lock detected" warning is silenced: the angles
    returned still reproduce ``R`` exactly (the third angle is set to zero).
    """
    from scipy.spatial.transform import Rotation

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return Rotation.from_matrix(R).as_euler(axes.upper(), degrees=True)


def _euler_alternative(e: np.ndarray) -> np.ndarray:
    """The other intrinsic Tait-Bryan triple of the same rotation: (a+180, 180-b, c+180)."""
    return np.stack([e[..., 0] + 180.0, 180.0 - e[..., 1], e[..., 2] + 180.0], axis=-1)


def continuous_euler(angles_deg: np.ndarray) -> np.ndarray:
    """Make intrinsic Tait-Bryan angles (F, 3) continuous over frames (or (F, ..., 3):
    every triple along the middle axes on its own, in one pass over the frames).

    Each frame keeps its rotation; it may switch to the equivalent triple
    ``(a + 180, 180 - b, c + 180)`` and shift any angle by multiples of 360 degrees,
    whichever lands closest to the previous frame. Frame 0 is left as given.
    """
    e = np.array(angles_deg, float)
    if e.shape[0] < 2:
        return e
    alt = _euler_alternative(e)
    out = e.copy()
    prev = e[0]
    for f in range(1, e.shape[0]):
        c0 = e[f] + 360.0 * np.round((prev - e[f]) / 360.0)
        c1 = alt[f] + 360.0 * np.round((prev - alt[f]) / 360.0)
        take_alt = np.abs(c1 - prev).sum(axis=-1) < np.abs(c0 - prev).sum(axis=-1) - 1e-12
        prev = out[f] = np.where(take_alt[..., None], c1, c0)
    return out


def quat_xyzw_to_matrix(quat_xyzw: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of quaternions (..., 4) stored (x, y, z, w)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(quat_xyzw).as_matrix()


def matrix_to_quat_xyzw(R: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) stored (x, y, z, w) of rotation matrices (..., 3, 3); the sign
    is scipy's (w >= 0 is not enforced)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_quat()
