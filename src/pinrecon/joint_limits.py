"""Joint-limit files: anatomical ranges for a figure, or a CMU ASF skeleton's limits.

A limits JSON (``models/limits/human.json`` is the human figure's; ``docs/limits.md``
documents its sources)::

    {"units": "degrees", "limits": {"left_knee_Z": [0, 150], ...}}

``Figure.with_limits(path)`` applies one; ``pinrecon reconstruct --limits FILE`` too.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = ["load_limits", "urdf_with_limits"]


def load_limits(path: str | os.PathLike, joint_names: Iterable[str] | None = None) -> dict[str, tuple[float, float]]:
    """Joint limits (radians) from a file: a limits JSON ``{"units": "degrees" | "radians",
    "limits": {joint: [lower, upper]}}`` (``models/limits/human.json``), or a CMU ASF
    skeleton whose per-bone limits are carried onto a BVH figure's joints ``joint_names``
    (:func:`pinrecon.io.asf.bvh_limits_from_asf`). Errors name the file and the joint."""
    from .io.jsonfile import read_json

    path = Path(path)
    if path.suffix.lower() == ".asf":
        from .io.asf import bvh_limits_from_asf, read_asf

        return bvh_limits_from_asf(read_asf(path), list(joint_names or ()))
    data = read_json(path)
    if not isinstance(data, Mapping) or not isinstance(data.get("limits"), Mapping):
        raise InputError("missing top-level 'limits' object {joint: [lower, upper]}", file=path, field="limits")
    units = data.get("units", "radians")
    if units not in ("degrees", "radians"):
        raise InputError(f"must be 'degrees' or 'radians', got {units!r}", file=path, field="units")
    k = np.pi / 180.0 if units == "degrees" else 1.0
    out = {}
    for jname, v in data["limits"].items():
        try:
            lo, hi = (float(x) * k for x in v)
        except (TypeError, ValueError):
            raise InputError(f"must be [lower, upper], got {v!r}", file=path, field=f"limits.{jname}") from None
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise InputError(f"must be two finite numbers, lower < upper, got {v!r}", file=path, field=f"limits.{jname}")
        out[str(jname)] = (lo, hi)
    return out


def urdf_with_limits(xml: str, limits, *, add_missing: bool = False) -> str:
    """URDF text with the ``<limit lower upper>`` of the named joints set to ``limits``
    (radians; joints the URDF does not have, or without a ``<limit>`` element, are left),
    so that a figure's saved URDF carries the limits it was given. With ``add_missing``
    only revolute and prismatic joints are written, and one without a ``<limit>`` gets
    one (effort and velocity 0): a file that carries every limit of the figure."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(xml.encode() if isinstance(xml, str) else xml)
    for joint in root.findall("joint"):
        name = joint.get("name")
        if name not in limits:
            continue
        lim = joint.find("limit")
        if add_missing:
            if joint.get("type") not in ("revolute", "prismatic"):
                continue
            if lim is None:
                lim = ET.SubElement(joint, "limit", effort="0", velocity="0")
        elif lim is None:
            continue
        lo, hi = limits[name]
        lim.set("lower", repr(float(lo)))
        lim.set("upper", repr(float(hi)))
    return ET.tostring(root, encoding="unicode")
