"""Acclaim skeleton files (ASF, the CMU motion-capture database's original skeletons)
and their joint limits carried over to the matching BVH skeleton.

:func:`read_asf` returns plain data (:class:`AsfSkeleton`): units, the root, every bone's
direction, length, ``axis`` frame, degrees of freedom and ``limits`` (degrees), and the
hierarchy. :func:`bvh_limits_from_asf` turns the per-bone limits into limits on a BVH
figure's one-axis rotation joints (``LeftLeg_Xrotation`` ...), matching ASF bones to BVH
joints by name (:data:`CMU_BVH_FROM_ASF`, the cgspeed MotionBuilder-friendly release).

Conventions (Acclaim, as the CMU files use them): a bone's local rotation is
``C M C^-1`` in the world-aligned rest frame, ``C`` the bone's ``axis`` (three angles in
the given order, e.g. ``XYZ``: ``C = Rz(az) Ry(ay) Rx(ax)``) and ``M = Rz(rz) Ry(ry)
Rx(rx)`` over the bone's DOFs. The BVH conversions keep world-aligned rest frames, so a
BVH joint's rotation (its channels, e.g. ``Zrotation Yrotation Xrotation``: ``Rz Ry Rx``)
is the same matrix. The limits a box of ASF angles allows are mapped to the box that
contains their image in the BVH channels (sampled on a grid, 5 degrees of margin): exact
in shape for one-DOF bones (knee, elbow: a rotation about the tilted axis ``C e_x``),
a bounding box for the others. A channel whose image spans more than 300 degrees stays
unlimited; so do BVH joints without an ASF bone.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from .jsonfile import read_text

__all__ = ["CMU_BVH_FROM_ASF", "NO_CAPTURED_LIMITS", "AsfBone", "AsfSkeleton", "bvh_limits_from_asf", "read_asf"]

#: ASF bones whose limits are not carried over by default (no captured data in CMU, or
#: captured rotations outside the ASF range)
NO_CAPTURED_LIMITS = ("lwrist", "lhand", "lfingers", "lthumb", "rwrist", "rhand", "rfingers", "rthumb")

#: CMU ASF bone -> joint of the cgspeed MotionBuilder-friendly BVH skeletons carrying its rotation
CMU_BVH_FROM_ASF = {
    "lhipjoint": "LHipJoint", "lfemur": "LeftUpLeg", "ltibia": "LeftLeg", "lfoot": "LeftFoot", "ltoes": "LeftToeBase",
    "rhipjoint": "RHipJoint", "rfemur": "RightUpLeg", "rtibia": "RightLeg", "rfoot": "RightFoot",
    "rtoes": "RightToeBase", "lowerback": "LowerBack", "upperback": "Spine", "thorax": "Spine1",
    "lowerneck": "Neck", "upperneck": "Neck1", "head": "Head", "lclavicle": "LeftShoulder", "lhumerus": "LeftArm",
    "lradius": "LeftForeArm", "lwrist": "LeftHand", "lhand": "LeftFingerBase", "lfingers": "LeftHandIndex1",
    "lthumb": "LThumb", "rclavicle": "RightShoulder", "rhumerus": "RightArm", "rradius": "RightForeArm",
    "rwrist": "RightHand", "rhand": "RightFingerBase", "rfingers": "RightHandIndex1", "rthumb": "RThumb",
}


@dataclass(frozen=True)
class AsfBone:
    """One ``:bonedata`` entry; angles in degrees, lengths in file units."""

    name: str
    direction: tuple[float, float, float]
    length: float
    axis_deg: tuple[float, float, float]
    axis_order: str = "XYZ"
    dof: tuple[str, ...] = ()
    limits_deg: tuple[tuple[float, float], ...] = ()


@dataclass(frozen=True)
class AsfSkeleton:
    """A parsed ASF file: ``units`` (e.g. ``{"length": "0.45", "angle": "deg"}``),
    ``bones`` by name, ``hierarchy`` (parent -> children, ``root`` first), ``source``,
    ``root`` (the ``:root`` section: ``order`` e.g. ``("TX", "TY", "TZ", "RX", "RY", "RZ")``,
    ``axis`` e.g. ``"XYZ"``, ``position`` and ``orientation`` as three numbers each)."""

    name: str
    units: dict
    bones: dict
    hierarchy: dict = field(default_factory=dict)
    source: str | None = None
    root: dict = field(default_factory=dict)


_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def _floats(tokens, n, where, file, lineno):
    try:
        vals = [float(t) for t in tokens[:n]]
    except ValueError:
        vals = []
    if len(vals) != n or not np.all(np.isfinite(vals)):
        raise InputError(f"line {lineno}: expected {n} numbers, got {' '.join(tokens)!r}", file=file, field=where)
    return vals


def read_asf(path: str | os.PathLike) -> AsfSkeleton:
    """Read an ASF skeleton; errors name the file, the bone and the line."""
    path = Path(path)
    text = read_text(path)
    section, name, units, bones, hierarchy, root = None, "", {}, {}, {}, {}
    cur: dict | None = None
    pending_limits = 0
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith(":"):
            head = line.split()
            section = head[0][1:]
            if section == "name" and len(head) > 1:
                name = head[1]
            continue
        tokens = line.split()
        if section == "units" and len(tokens) >= 2:
            units[tokens[0]] = tokens[1]
        elif section == "root" and len(tokens) >= 2:
            key = tokens[0].lower()
            if key == "order":
                root["order"] = tuple(t.upper() for t in tokens[1:])
            elif key == "axis":
                root["axis"] = tokens[1].upper()
            elif key in ("position", "orientation"):
                root[key] = tuple(_floats(tokens[1:], 3, f"root.{key}", path, lineno))
        elif section == "bonedata":
            if tokens[0] == "begin":
                cur, pending_limits = {"limits": []}, 0
                continue
            if cur is None:
                raise InputError(f"line {lineno}: bone data outside begin/end", file=path, field="bonedata")
            where = f"bonedata.{cur.get('name', '?')}"
            if tokens[0] == "end":
                bones[cur["name"]] = _make_bone(cur, path, lineno)
                cur = None
            elif pending_limits and line.startswith("("):
                cur["limits"].append(_limit(line, where, path, lineno))
                pending_limits -= 1
            elif tokens[0] == "name":
                cur["name"] = tokens[1] if len(tokens) > 1 else ""
            elif tokens[0] == "direction":
                cur["direction"] = tuple(_floats(tokens[1:], 3, where + ".direction", path, lineno))
            elif tokens[0] == "length":
                cur["length"] = _floats(tokens[1:], 1, where + ".length", path, lineno)[0]
            elif tokens[0] == "axis":
                cur["axis"] = tuple(_floats(tokens[1:], 3, where + ".axis", path, lineno))
                cur["axis_order"] = tokens[4].upper() if len(tokens) > 4 else "XYZ"
            elif tokens[0] == "dof":
                cur["dof"] = tuple(t.lower() for t in tokens[1:])
            elif tokens[0] == "limits":
                cur["limits"].append(_limit(line[len("limits"):].strip(), where + ".limits", path, lineno))
                pending_limits = len(cur.get("dof", ())) - 1
        elif section == "hierarchy":
            if tokens[0] in ("begin", "end"):
                continue
            hierarchy[tokens[0]] = tokens[1:]
    if cur is not None:
        raise InputError("the last bone has no 'end'", file=path, field="bonedata")
    if not bones:
        raise InputError("no :bonedata found: not an ASF skeleton", file=path)
    return AsfSkeleton(name, units, bones, hierarchy, str(path), root)


def _limit(text, where, file, lineno):
    m = re.fullmatch(rf"\(\s*({_NUM}|-?inf)\s+({_NUM}|-?inf)\s*\)", text.strip(), flags=re.IGNORECASE)
    if not m:
        raise InputError(f"line {lineno}: expected '(lower upper)', got {text!r}", file=file, field=where)
    lo, hi = float(m.group(1)), float(m.group(2))
    if lo > hi:
        raise InputError(f"line {lineno}: lower limit {lo} above upper limit {hi}", file=file, field=where)
    return lo, hi


def _make_bone(d, file, lineno) -> AsfBone:
    where = f"bonedata.{d.get('name', '?')}"
    for key in ("name", "direction", "length", "axis"):
        if key not in d or d[key] in ("", None):
            raise InputError(f"line {lineno}: bone has no '{key}'", file=file, field=where)
    dof = d.get("dof", ())
    bad = [x for x in dof if x not in ("rx", "ry", "rz", "tx", "ty", "tz", "l")]
    if bad:
        raise InputError(f"unknown degree(s) of freedom {bad}", file=file, field=where + ".dof")
    lim = tuple(d["limits"])
    if lim and len(lim) != len(dof):
        raise InputError(f"{len(dof)} degrees of freedom but {len(lim)} limits", file=file, field=where + ".limits")
    return AsfBone(d["name"], d["direction"], d["length"], d["axis"], d.get("axis_order", "XYZ"), dof, lim)


# ----------------------------------------------------------------------------- onto BVH
def _rot(axis: str, deg):
    a = np.radians(np.asarray(deg, float))
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    i = "XYZ".index(axis.upper())
    j, k = (i + 1) % 3, (i + 2) % 3
    R[..., i, i] = 1.0
    R[..., j, j], R[..., j, k], R[..., k, j], R[..., k, k] = c, -s, s, c
    return R


def _axis_matrix(bone: AsfBone) -> np.ndarray:
    """``C``: the axis angles applied in the given order (``XYZ``: x first, ``Rz Ry Rx``)."""
    C = np.eye(3)
    for ax, ang in zip(bone.axis_order, bone.axis_deg):
        C = _rot(ax, ang) @ C
    return C


def _euler(R: np.ndarray, order: str) -> np.ndarray:
    """Intrinsic angles (degrees) with ``R = R_{order[0]} R_{order[1]} R_{order[2]}``."""
    import warnings

    from scipy.spatial.transform import Rotation

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # gimbal lock on a grid corner: any split is fine
        return Rotation.from_matrix(R).as_euler(order.upper(), degrees=True)


def _rotation_channels(joint_names: Iterable[str]) -> dict[str, list[str]]:
    """A BVH figure's rotation channels per joint: ``J_Zrotation``, ``J_Yrotation``,
    ``J_Xrotation`` -> ``{"J": ["Z", "Y", "X"]}`` (in the names' order)."""
    channels: dict[str, list[str]] = {}
    for jn in joint_names:
        m = re.fullmatch(r"(.+)_([XYZ])rotation", jn)
        if m:
            channels.setdefault(m.group(1), []).append(m.group(2))
    return channels


def bvh_limits_from_asf(skeleton: AsfSkeleton, joint_names: Iterable[str], *, bone_map: Mapping[str, str] | None = None,
                        skip_bones: Iterable[str] | None = None, samples: int = 13,
                        margin_deg: float = 5.0) -> dict[str, tuple[float, float]]:
    """Limits (radians) of a BVH figure's rotation joints from an ASF skeleton's limits.

    ``skip_bones`` are left unlimited (default :data:`NO_CAPTURED_LIMITS`: CMU's hands,
    fingers and thumbs carry no captured data, and its captured wrist rotations leave the
    ASF's wrist range in most frames of the bundled clips; see ``docs/limits.md``).
    ``joint_names`` are the figure's joint names; a BVH joint ``J`` with channels
    ``Zrotation Yrotation Xrotation`` appears as ``J_Zrotation``, ``J_Yrotation``,
    ``J_Xrotation`` in that order. ``bone_map`` maps ASF bones to BVH joints (default
    :data:`CMU_BVH_FROM_ASF`). Every bone with rotational DOFs and limits is sampled on a
    ``samples``-per-DOF grid of its limit box; each channel gets the range of its angle
    over the samples, widened by ``margin_deg``. Returns ``{joint name: (lower, upper)}``.
    """
    bone_map = dict(CMU_BVH_FROM_ASF if bone_map is None else bone_map)
    skip = set(NO_CAPTURED_LIMITS if skip_bones is None else skip_bones)
    channels = _rotation_channels(joint_names)
    out: dict[str, tuple[float, float]] = {}
    for bname, bone in skeleton.bones.items():
        bvh = bone_map.get(bname)
        if bname in skip or bvh is None or bvh not in channels or len(channels[bvh]) != 3:
            continue
        rot = [(d, lim) for d, lim in zip(bone.dof, bone.limits_deg) if d in ("rx", "ry", "rz")]
        if not rot or len(bone.limits_deg) != len(bone.dof):
            continue
        grids = np.meshgrid(*[np.linspace(lo, hi, samples) for _, (lo, hi) in rot], indexing="ij")
        vals = {d: g.ravel() for (d, _), g in zip(rot, grids)}
        n = grids[0].size
        M = np.eye(3)[None].repeat(n, 0)
        for ax in ("z", "y", "x"):  # M = Rz Ry Rx over the DOFs present
            if "r" + ax in vals:
                M = M @ _rot(ax.upper(), vals["r" + ax])
        C = _axis_matrix(bone)
        R = C[None] @ M @ C.T[None]
        order = "".join(channels[bvh])
        ang = _euler(R, order)  # (n, 3)
        for i, axis in enumerate(order):
            a = np.sort(ang[:, i])
            gaps = np.diff(np.r_[a, a[0] + 360.0])
            k = int(np.argmax(gaps))  # the widest empty arc: the range is its complement
            lo, hi = a[(k + 1) % len(a)], a[k]
            if hi < lo:
                hi += 360.0
            if hi - lo > 300.0:
                continue
            if hi > 180.0 and (hi - 360.0 >= 0.0 or abs(0.5 * (lo + hi) - 360.0) < abs(0.5 * (lo + hi))):
                lo, hi = lo - 360.0, hi - 360.0  # the representation holding (or nearest) the rest angle 0
            out[f"{bvh}_{axis}rotation"] = (np.radians(lo - margin_deg), np.radians(hi + margin_deg))
    return out


def _bvh_bones(skeleton, joint_names, bone_map, skip_bones):
    """``(bone, BVH joint, rotational DOFs)`` of the bones mapped to a BVH joint with three
    rotation channels, not skipped (defaults as in :func:`bvh_limits_from_asf`)."""
    bone_map = dict(CMU_BVH_FROM_ASF if bone_map is None else bone_map)
    skip = set(NO_CAPTURED_LIMITS if skip_bones is None else skip_bones)
    channels = _rotation_channels(joint_names)
    for bname, bone in skeleton.bones.items():
        bvh = bone_map.get(bname)
        if bname not in skip and bvh is not None and len(channels.get(bvh, ())) == 3:
            yield bone, bvh, [d for d in bone.dof if d in ("rx", "ry", "rz")]


def bvh_hinges_from_asf(skeleton: AsfSkeleton, joint_names: Iterable[str], *, bone_map: Mapping[str, str] | None = None,
                        skip_bones: Iterable[str] | None = None) -> dict[str, list[float]]:
    """The BVH joints whose ASF bone turns about one axis (one rotational DOF: CMU's knees,
    elbows, toes): ``{joint: axis}``, the unit axis ``C e_d`` (``C`` the bone's ``axis``
    frame, ``d`` its DOF) in the world-aligned rest frame in which the joint's channels
    compose ``C M C^-1``. Only joints with three rotation channels; ``bone_map`` and
    ``skip_bones`` as in :func:`bvh_limits_from_asf`. :class:`pinrecon.rows.hinges.Hinges`
    holds the joints on them."""
    out = {}
    for bone, bvh, rot in _bvh_bones(skeleton, joint_names, bone_map, skip_bones):
        if len(rot) == 1:
            a = _axis_matrix(bone) @ np.eye(3)["xyz".index(rot[0][1])]
            out[bvh] = [round(float(v), 9) for v in a]
    return out


def bvh_bones_from_asf(skeleton: AsfSkeleton, joint_names: Iterable[str], *, bone_map: Mapping[str, str] | None = None,
                       skip_bones: Iterable[str] | None = None) -> dict[str, dict]:
    """The BVH joints whose ASF bone has two or three rotational DOFs (a foot, a clavicle,
    a femur, a humerus, the spine): ``{joint: {"axis": C, "dof": [...], "limits": [[lo, hi],
    ...]}}`` (``C`` the bone's ``axis`` frame as nested lists, the DOFs among ``rx ry rz``,
    their limits in degrees, or ``None`` when the file gives none). Only joints with three
    rotation channels; ``bone_map`` and ``skip_bones`` as in :func:`bvh_limits_from_asf`.
    :class:`pinrecon.rows.bones.Bones` holds the joints to them."""
    out = {}
    for bone, bvh, rot in _bvh_bones(skeleton, joint_names, bone_map, skip_bones):
        if len(rot) < 2:
            continue
        lim = dict(zip(bone.dof, bone.limits_deg)) if len(bone.limits_deg) == len(bone.dof) else None
        out[bvh] = {"axis": [[round(float(v), 12) for v in row] for row in _axis_matrix(bone)], "dof": rot,
                    "limits": None if lim is None else [[float(lim[d][0]), float(lim[d][1])] for d in rot]}
    return out
