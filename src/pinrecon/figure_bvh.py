"""A figure builder: a parsed BVH skeleton as plain figure data (URDF text, keypoint
entries, limits, metadata), which :meth:`pinrecon.Figure.from_bvh` turns into a Figure.

It imports the BVH parser (:mod:`pinrecon.io.bvh_format`), never :mod:`pinrecon.figure`,
so that ``figure -> figure_bvh -> io.bvh_format`` has no way back.

Construction (see ``docs/formats.md``, "BVH figures"):

* The root becomes a free flyer: its position channels and rotation channels become the
  free-flyer pose ``q[:7]`` (the root OFFSET is added to the position).
* Every other BVH joint becomes a **revolute chain**, one URDF joint per channel, in the
  file's channel order, named ``<joint>_<channel>`` (``LeftLeg_Zrotation``...). The first
  URDF joint of the chain carries the BVH OFFSET; the chain ends in a link named exactly
  as the BVH joint. So for ``CHANNELS 3 Zrotation Yrotation Xrotation`` the local
  rotation is ``Rz Ry Rx`` (intrinsic), exactly BVH's convention, and the joint values
  are the channel values in radians: motion conversion is exact and BVH export is the
  inverse map. Position channels on non-root joints become prismatic joints placed
  before the rotations (local transform ``T(offset + p) R``).
* Keypoints: one per BVH joint, named exactly as in the file, at the origin of its link,
  and one per End Site, named ``<joint>_end``.
* Joints with zero OFFSET sit at their parent: their keypoint coincides with the
  parent's (see :meth:`pinrecon.Figure.coincident_keypoints`; solvers and metrics use
  :attr:`~pinrecon.Figure.distinct_keypoint_names` so no point counts twice). Their
  rotation is kept (CMU's LowerBack and Neck carry real motion); joints whose channels
  the user knows to be static can be welded with ``lock=[...]`` so that they add no
  redundant degrees of freedom (e.g. CMU's LHipJoint/RHipJoint/LeftShoulder/
  RightShoulder, all zero in every frame; see :func:`pinrecon.io.bvh.static_joints`).
* BVH states no joint limits, so the figure has none. The URDF written for it gives
  revolute joints wide limits of +-4 pi (URDF requires a limit on revolute joints).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError, UnknownNameError
from .figure_files import urdf_numbers
from .io.bvh_format import BvhClip, BvhJoint, static_joints

__all__ = ["BvhFigureData", "bvh_figure_data"]

_WIDE_LIMIT = 4 * math.pi


@dataclass
class BvhFigureData:
    """Everything :meth:`pinrecon.Figure.from_bvh` needs, as plain data.

    Attributes
    ----------
    urdf_xml : URDF text (no XML declaration) of the skeleton, lengths in metres.
    keypoints : ``(name, frame, offset_m)`` per keypoint, in figure order.
    limits : joint name -> (lower, upper); always empty (BVH states no limits).
    name : robot name (the file's stem, or ``"bvh_figure"``).
    source : the BVH file.
    meta : ``{"bvh": {...}}``, the skeleton in metres, used to convert motion and to write
        the figure back as BVH (:mod:`pinrecon.io.bvh`).
    """

    urdf_xml: str
    keypoints: list[tuple[str, str, tuple[float, float, float]]]
    limits: dict[str, tuple[float, float]]
    name: str
    source: str | None
    meta: dict


def _link_name(j: BvhJoint) -> str:
    return j.name


def bvh_figure_data(clip: BvhClip, length_scale: float = 1.0, *, lock: Iterable[str] | str = ()) -> BvhFigureData:
    """The figure data of a BVH skeleton (see the module docstring).

    Parameters
    ----------
    clip : parsed BVH (:func:`pinrecon.io.bvh.read_bvh`).
    length_scale : metres per file unit (CMU files: 0.056444).
    lock : BVH joint names whose channels are welded at zero (fixed joints), or
        ``"static"`` for every joint :func:`pinrecon.io.bvh.static_joints` finds.
    """
    length_scale = float(length_scale)
    if not (length_scale > 0 and math.isfinite(length_scale)):
        raise InputError(f"must be a positive number, got {length_scale}", field="length_scale")
    if isinstance(lock, str):
        if lock != "static":
            raise InputError(f"lock must be a list of joint names or 'static', got {lock!r}", field="lock")
        lock = static_joints(clip)
    lock = list(lock)
    unknown = [n for n in lock if n not in clip.names]
    if unknown:
        raise UnknownNameError("BVH joint", unknown, clip.names, file=clip.path, field="lock")
    if clip.joints[0].name in lock:
        raise InputError("the root joint cannot be locked", file=clip.path, field="lock")

    robot_name = Path(clip.path).stem if clip.path else "bvh_figure"
    robot = ET.Element("robot", name=robot_name)
    links = [clip.joints[0].name]
    ujoints = []  # (name, type, parent, child, offset, axis, limit)
    keypoints = []
    for idx, j in enumerate(clip.joints):
        if idx > 0:
            parent_link = _link_name(clip.joints[j.parent])
            offset = np.asarray(j.offset, float) * length_scale
            chain = [] if j.name in lock else list(j.position_channels) + list(j.rotation_channels)
            if not chain:
                ujoints.append((f"{j.name}_weld", "fixed", parent_link, j.name, offset, None, None))
                links.append(j.name)
            else:
                prev = parent_link
                for c_i, ch in enumerate(chain):
                    child = j.name if c_i == len(chain) - 1 else f"{j.name}__{ch}"
                    axis = np.eye(3)["XYZ".index(ch[0])]
                    if ch.endswith("rotation"):
                        jt, limit = "revolute", _WIDE_LIMIT
                    else:
                        jt, limit = "prismatic", 1e3
                    ujoints.append((f"{j.name}_{ch}", jt, prev, child, offset if c_i == 0 else np.zeros(3), axis, limit))
                    links.append(child)
                    prev = child
        keypoints.append((j.name, _link_name(j), (0.0, 0.0, 0.0)))
    for i, end_name in clip.end_site_names():
        j = clip.joints[i]
        k = int(end_name[len(j.name) + 4 :] or 1) - 1
        keypoints.append((end_name, _link_name(j), tuple(np.asarray(j.end_sites[k]) * length_scale)))

    # URDF written with the standard library's ElementTree, the layout yourdfpy writes
    # (links, then joints: parent, child, origin, axis, limit); yourdfpy itself costs about
    # a second of import (trimesh) on every BVH figure built
    for name in links:
        ET.SubElement(robot, "link", name=name)
    for name, jt, parent, child, offset, axis, limit in ujoints:
        el = ET.SubElement(robot, "joint", name=name, type=jt)
        ET.SubElement(el, "parent", link=parent)
        ET.SubElement(el, "child", link=child)
        ET.SubElement(el, "origin", xyz=urdf_numbers(offset), rpy="0.0 0.0 0.0")
        if axis is not None:
            ET.SubElement(el, "axis", xyz=urdf_numbers(axis))
        if limit is not None:
            ET.SubElement(el, "limit", effort="0.0", velocity="0.0", lower=repr(-float(limit)), upper=repr(float(limit)))
    ET.indent(robot)
    xml = ET.tostring(robot, encoding="unicode") + "\n"
    meta = {
        "bvh": {
            "names": clip.names,
            "parents": [j.parent for j in clip.joints],
            "offsets": [list(np.asarray(j.offset, float) * length_scale) for j in clip.joints],
            "channels": [list(j.channels) for j in clip.joints],
            "end_sites": [[list(np.asarray(e) * length_scale) for e in j.end_sites] for j in clip.joints],
            "length_scale": length_scale,
            "lock": lock,
            "source": clip.path,
        }
    }
    return BvhFigureData(xml, keypoints, {}, robot_name, clip.path, meta)
