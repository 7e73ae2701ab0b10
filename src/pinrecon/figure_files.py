"""The files a figure is made of: keypoint maps (JSON) and URDF text.

:class:`Keypoint` and the keypoint-map readers, and the few URDF text helpers the
figure needs (a file object for XML parsers, the joints, their names and the limits a
URDF states, scaled joint origins), read and written with the standard library. :mod:`pinrecon.figure` re-exports the public names.
"""

from __future__ import annotations

import io
import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError, UnknownNameError

__all__ = [
    "Keypoint",
    "load_keypoint_map",
    "parse_keypoint_entries",
    "scale_urdf_origins",
    "urdf_joint_limits",
    "urdf_joint_names",
    "urdf_joints",
    "urdf_numbers",
    "xml_file",
]


@dataclass(frozen=True)
class Keypoint:
    """A named point fixed in a Pinocchio frame: ``p_world = oMf * offset``."""

    name: str
    frame: str
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)


def parse_keypoint_entries(entries, file=None) -> list[Keypoint]:
    """Keypoints from a keypoint map's ``keypoints`` object: ``{name: {"frame": f,
    "offset": [x, y, z]}}`` (a bare string is a frame name with zero offset).

    Used by :func:`load_keypoint_map`, by result files (which embed the map) and by
    :meth:`Figure.from_bvh`. Bad entries raise :class:`~pinrecon.errors.InputError`
    naming ``file`` and the keypoint.
    """
    if isinstance(entries, Mapping):
        items = list(entries.items())
    else:
        raise InputError("must be an object {name: {frame, offset}}", file=file, field="keypoints")
    out = []
    for name, spec in items:
        field = f"keypoints.{name}"
        if isinstance(spec, str):
            spec = {"frame": spec}
        if not isinstance(spec, Mapping) or "frame" not in spec:
            raise InputError("needs a 'frame' (and optional 'offset')", file=file, field=field)
        offset = spec.get("offset", (0.0, 0.0, 0.0))
        try:
            off = np.asarray(offset, dtype=float)
        except (TypeError, ValueError):
            raise InputError("offset must be 3 numbers", file=file, field=field) from None
        if off.shape != (3,) or not np.all(np.isfinite(off)):
            raise InputError(f"offset must be 3 finite numbers, got {offset!r}", file=file, field=field)
        out.append(Keypoint(str(name), str(spec["frame"]), tuple(float(x) for x in off)))
    return out


def load_keypoint_map(path: str | os.PathLike) -> list[Keypoint]:
    """Read a keypoint map JSON: ``{"keypoints": {name: {"frame": f, "offset": [x, y, z]}}}``."""
    from .io.jsonfile import read_json

    path = Path(path)
    data = read_json(path)
    if not isinstance(data, Mapping) or "keypoints" not in data:
        raise InputError("missing top-level 'keypoints' object", file=path, field="keypoints")
    return parse_keypoint_entries(data["keypoints"], file=path)


def xml_file(xml: str | bytes) -> io.BytesIO:
    """A file object XML parsers accept even when the text carries an encoding
    declaration (a ``str`` with one is refused)."""
    return io.BytesIO(xml.encode() if isinstance(xml, str) else xml)


def urdf_numbers(values) -> str:
    """Numbers as a URDF attribute (``xyz``, ``rpy``, ``axis``): full precision."""
    return " ".join(repr(float(v)) for v in values)


def urdf_joints(xml: str | bytes) -> list[ET.Element]:
    """The ``<joint>`` children of ``<robot>`` (a ``<transmission>``'s ``<joint>`` is not
    one), parsed with the standard library's ElementTree: yourdfpy reads the same, but
    its import (trimesh) costs about a second on every figure built."""
    return ET.parse(xml_file(xml)).getroot().findall("joint")


def urdf_joint_names(xml: str | bytes) -> list[str]:
    """The names of the URDF's joints, in file order."""
    return [j.get("name") for j in urdf_joints(xml) if j.get("name") is not None]


def urdf_joint_limits(xml: str | bytes) -> dict[str, tuple[float, float]]:
    """Joint name -> (lower, upper) for revolute/prismatic joints whose URDF sets both
    (the ``<joint type><limit lower upper>`` elements of the URDF specification)."""
    out = {}
    for j in urdf_joints(xml):
        limit = j.find("limit")
        if j.get("type") not in ("revolute", "prismatic") or limit is None or j.get("name") is None:
            continue
        lo, hi = limit.get("lower"), limit.get("upper")
        if lo is None or hi is None:
            continue
        lo, hi = float(lo), float(hi)
        if lo < hi:
            out[j.get("name")] = (lo, hi)
    return out


def scale_urdf_origins(urdf_xml: str | bytes, joint_factors: Mapping[str, float]) -> str:
    """URDF text with the origin translation (``xyz``) of the named joints multiplied by
    their factors (full precision; rotations and everything else untouched). Joints are
    those of :func:`urdf_joints`; an unknown name raises
    :class:`~pinrecon.errors.UnknownNameError`."""
    root = ET.parse(xml_file(urdf_xml)).getroot()
    joints = {j.get("name"): j for j in root.findall("joint")}
    unknown = [n for n in joint_factors if n not in joints]
    if unknown:
        raise UnknownNameError("URDF joint", unknown, list(joints), field="joint_factors")
    for n, f in joint_factors.items():
        origin = joints[n].find("origin")
        if origin is None or origin.get("xyz") is None:
            continue
        origin.set("xyz", urdf_numbers(np.array([float(v) for v in origin.get("xyz").split()]) * float(f)))
    return ET.tostring(root, encoding="unicode")
