"""The floor plane: :class:`Floor` (``n . p = d``, ``n`` the unit up normal in world axes,
``d`` in metres) given as ``"y=0"``, ``"-z=1"``, ``"nx,ny,nz,d"`` or four numbers
(:func:`as_floor`). Estimated from the motion by :func:`pinrecon.contact.estimate_floor`."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .errors import InputError

__all__ = ["Floor", "as_floor"]

_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class Floor:
    """The floor plane ``normal . p = offset_m`` (``normal`` a unit vector pointing up)."""

    normal: tuple[float, float, float] = (0.0, 1.0, 0.0)
    offset_m: float = 0.0

    def __post_init__(self):
        n = np.asarray(self.normal, float).reshape(-1)
        if n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) < 1e-12:
            raise InputError(f"the floor normal must be a non-zero 3-vector, got {self.normal!r}", field="floor")
        if not np.isfinite(self.offset_m):
            raise InputError(f"the floor height must be finite, got {self.offset_m!r}", field="floor")
        object.__setattr__(self, "normal", tuple(float(x) for x in n / np.linalg.norm(n)))
        object.__setattr__(self, "offset_m", float(self.offset_m))

    @property
    def n(self) -> np.ndarray:
        return np.array(self.normal)

    def height(self, p_world) -> np.ndarray:
        """Height above the floor (metres, along the normal) of points (..., 3)."""
        return np.asarray(p_world, float) @ self.n - self.offset_m

    def horizontal(self, v_world) -> np.ndarray:
        """The component of vectors (..., 3) parallel to the floor."""
        v = np.asarray(v_world, float)
        return v - (v @ self.n)[..., None] * self.n

    def as_array(self) -> np.ndarray:
        """``[nx, ny, nz, offset_m]`` (the NPZ ``floor`` entry)."""
        return np.array([*self.normal, self.offset_m])

    @classmethod
    def from_array(cls, a) -> Floor:
        a = np.asarray(a, float).reshape(-1)
        if a.shape != (4,):
            raise InputError(f"a floor is 4 numbers nx, ny, nz, offset, got {a.tolist()}", field="floor")
        return cls(tuple(a[:3]), float(a[3]))

    @classmethod
    def parse(cls, spec: str) -> Floor:
        """``"y=0"`` / ``"z=0.05"`` / ``"-z=1"`` (the plane ``axis = value``, up along
        ``+axis``, or ``-axis`` with a minus sign), or ``"nx,ny,nz,d"`` (the plane
        ``n . p = d`` with ``n`` normalised, ``d`` in metres along it)."""
        s = str(spec).strip().replace(" ", "")
        m = re.fullmatch(r"([+-]?)([xyzXYZ])=([-+0-9.eE]+)", s)
        try:
            if m:
                sign = -1.0 if m.group(1) == "-" else 1.0
                n = np.zeros(3)
                n[_AXES[m.group(2).lower()]] = sign
                return cls(tuple(n), sign * float(m.group(3)))
            parts = [float(x) for x in s.split(",")]
        except ValueError:
            parts = []
        if len(parts) != 4:
            raise InputError(
                f"a floor is 'auto', 'y=0' (or x/z, '-z=1' for a floor whose up is -z), or 'nx,ny,nz,d', got {spec!r}",
                field="floor",
            )
        n = np.asarray(parts[:3])
        norm = np.linalg.norm(n)
        if not norm > 0:
            raise InputError(f"the floor normal must be non-zero, got {spec!r}", field="floor")
        return cls(tuple(n / norm), parts[3] / norm)


def as_floor(floor) -> Floor | str:
    """A :class:`Floor`, ``"auto"``, or an error: accepts a Floor, a spec string, or 4 numbers."""
    if isinstance(floor, Floor):
        return floor
    if isinstance(floor, str):
        return "auto" if floor.strip().lower() == "auto" else Floor.parse(floor)
    try:
        return Floor.from_array(floor)
    except (TypeError, ValueError) as exc:
        raise InputError(f"floor must be None, 'auto', a Floor, a spec or 4 numbers, got {floor!r}",
                         field="floor") from exc
