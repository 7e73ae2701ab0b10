"""Acclaim motion (AMC, the CMU motion-capture database's original format) on its ASF
skeleton, read as a pinrecon figure and motion the same way as a BVH clip.

:func:`load_amc` is the one call: ``load_amc(asf, amc)`` returns a
:class:`pinrecon.io.bvh.BvhMotion` (``figure``, ``q`` (frames, nq), ``fps``, ``clip``), so
forward kinematics, keypoints, BVH/CSV/TRC exports and everything else that takes a BVH
motion take it unchanged. ``pinrecon.datasets.cmu("01_01")`` gives the two files.

How the skeleton becomes a BVH-like clip (:func:`amc_clip`):

* The ASF ``root`` becomes the BVH root at the ``:root`` ``position``, with channels
  ``Xposition Yposition Zposition Zrotation Yrotation Xrotation``. Every bone becomes a
  BVH joint at the bone's start (the end of its parent bone), named as the bone (or, with
  ``names="bvh"``, as the joint of CMU's MotionBuilder-friendly BVH release carrying its
  rotation: :data:`pinrecon.io.asf.CMU_BVH_FROM_ASF`, root ``Hips``). Its OFFSET is the
  parent bone's vector ``direction * length`` (zero under the root); a bone without
  children ends in an End Site at its own vector.
* A bone with rotational DOFs gets ``Zrotation Yrotation Xrotation`` channels; a bone
  without DOFs is welded (no channels).
* Motion, per frame (Acclaim's convention, as CMU's files use it): a bone's rotation in
  the world-aligned rest frame is ``C M C^-1``, ``C`` from its ``axis`` (the three angles
  applied in the axis order: ``XYZ`` is ``Rz Ry Rx``) and ``M`` from its DOF values
  applied in the DOF order (``rx ry rz`` is ``Rz Ry Rx``). The root's translation is
  ``position + (TX, TY, TZ)`` and its rotation ``M`` from its R values applied in the
  ``:root`` ``order``. Each rotation is written as the channels' ZYX Euler angles (made
  continuous over frames), so the figure's forward kinematics reproduce the ASF/AMC
  joint positions to floating point.

Units: lengths and the root translation are in the ASF's units; ``length_scale`` (metres
per unit) defaults to CMU's convention, ``0.0254 / length`` (the ASF ``:units length`` is
a multiplier on inches: CMU's 0.45 gives 0.056444 m). Angles are in degrees unless the
ASF says ``angle rad`` (or the AMC ``:RADIANS``). AMC stores no frame rate: ``fps``
defaults to CMU's 120.

Not read: a ``:root`` ``orientation`` other than zero, bones with translation or length
DOFs (``tx``, ``ty``, ``tz``, ``l``); both are refused with an ``InputError``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, UnknownNameError
from ..rotations import continuous_euler, euler_to_matrix, matrix_to_euler
from .asf import CMU_BVH_FROM_ASF, AsfSkeleton, read_asf
from .bvh import BvhMotion, figure_from_bvh, motion_from_bvh
from .bvh_format import BvhClip, BvhJoint

__all__ = ["AmcMotion", "read_amc", "amc_clip", "load_amc", "CMU_FPS", "asf_length_scale"]

CMU_FPS = 120.0
_ROT = ("rx", "ry", "rz")
_ROOT_DOF = ("TX", "TY", "TZ", "RX", "RY", "RZ")


@dataclass
class AmcMotion:
    """A parsed AMC file: per bone (``"root"`` included) its DOF values over the frames,
    ``values[bone]`` (frames, n DOF) in the file's order and units; ``frame_numbers`` as
    written in the file; ``radians`` when the file (or its ASF) gives angles in radians."""

    values: dict
    frame_numbers: list
    radians: bool
    source: str | None = None

    @property
    def n_frames(self) -> int:
        return len(self.frame_numbers)


def _dof(skeleton: AsfSkeleton) -> dict[str, tuple[str, ...]]:
    """Every bone's DOFs in the AMC's value order (the root's from ``:root order``)."""
    order = tuple(skeleton.root.get("order", _ROOT_DOF))
    bad = [d for d in order if d not in _ROOT_DOF]
    if bad or len(set(order)) != len(order):
        raise InputError(f"root order must list distinct values among {list(_ROOT_DOF)}, got {list(order)}",
                         file=skeleton.source, field="root.order")
    out = {"root": order}
    for name, bone in skeleton.bones.items():
        other = [d for d in bone.dof if d not in _ROT]
        if other:
            raise InputError(f"bone {name!r} has DOF {other}: only rotations (rx, ry, rz) are read",
                             file=skeleton.source, field=f"bonedata.{name}.dof")
        out[name] = tuple(bone.dof)
    return out


def read_amc(path: str | os.PathLike, skeleton: AsfSkeleton) -> AmcMotion:
    """Parse an AMC file against its ASF skeleton (:func:`pinrecon.io.asf.read_asf`).

    Errors (an :class:`~pinrecon.errors.InputError` naming the file, the bone as field and
    the frame, counted from 0 in file order): a bone the skeleton lacks (the valid names are
    listed), a bone given twice or missing in a frame, a value count other than the bone's
    DOF count, a non-numeric or non-finite value, values before the first frame number.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except (IsADirectoryError, UnicodeDecodeError):
        raise InputError("not a text AMC file", file=path) from None
    dofs = _dof(skeleton)
    radians = str(skeleton.units.get("angle", "deg")).lower().startswith("rad")
    rows: dict[str, list] = {b: [] for b in dofs}
    numbers: list[int] = []
    seen: set[str] = set()

    def close_frame():
        if not numbers:
            return
        missing = [b for b in dofs if dofs[b] and b not in seen]
        if missing:
            raise InputError(f"bone(s) {missing} missing (frame number {numbers[-1]} in the file)", file=path,
                             field=missing[0], frame=len(numbers) - 1)
        for b in dofs:
            if not dofs[b] and b not in seen:
                rows[b].append(())

    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith(":"):
            key = line.upper()
            if key.startswith(":RADIANS"):
                radians = True
            elif key.startswith(":DEGREES"):
                radians = False
            continue
        tokens = line.split()
        if len(tokens) == 1 and tokens[0].isdigit():
            close_frame()
            numbers.append(int(tokens[0]))
            seen = set()
            continue
        bone, vals = tokens[0], tokens[1:]
        frame = len(numbers) - 1 if numbers else None
        if not numbers:
            raise InputError(f"line {lineno}: values before the first frame number", file=path, field=bone)
        where = f"(line {lineno}, frame number {numbers[-1]} in the file)"
        if bone not in dofs:
            raise UnknownNameError("ASF bone", [bone], list(dofs), file=path, field=bone, frame=frame)
        if bone in seen:
            raise InputError(f"bone given twice in one frame {where}", file=path, field=bone, frame=frame)
        if len(vals) != len(dofs[bone]):
            raise InputError(f"expected {len(dofs[bone])} values ({' '.join(dofs[bone]) or 'no DOF'}), got "
                             f"{len(vals)} {where}", file=path, field=bone, frame=frame)
        try:
            nums = tuple(float(v) for v in vals)
        except ValueError:
            raise InputError(f"non-numeric value in {' '.join(vals)!r} {where}", file=path, field=bone,
                             frame=frame) from None
        if not all(map(math.isfinite, nums)):
            raise InputError(f"NaN or infinite value in {' '.join(vals)!r} {where}", file=path, field=bone,
                             frame=frame)
        rows[bone].append(nums)
        seen.add(bone)
    close_frame()
    if not numbers:
        raise InputError("no frames (a frame starts with its number on a line of its own)", file=path)
    values = {b: np.array(r, float).reshape(len(numbers), len(dofs[b])) for b, r in rows.items()}
    return AmcMotion(values, numbers, radians, str(path))


def asf_length_scale(skeleton: AsfSkeleton) -> float:
    """Metres per ASF length unit by CMU's convention: ``0.0254 / length`` (inches times
    the ``:units length`` multiplier; 1.0 when the file gives none)."""
    try:
        mult = float(skeleton.units.get("length", 1.0))
    except ValueError:
        raise InputError(f"must be a number, got {skeleton.units['length']!r}", file=skeleton.source,
                         field="units.length") from None
    if not (mult > 0 and np.isfinite(mult)):
        raise InputError(f"must be a positive number, got {mult}", file=skeleton.source, field="units.length")
    return 0.0254 / mult


def _axes_matrix(axes: str, angles_deg: np.ndarray) -> np.ndarray:
    """Rotations about ``axes`` applied in that order (first axis first): ``XYZ`` with
    angles ``(a, b, c)`` is ``Rz(c) Ry(b) Rx(a)``; angles (..., n) degrees."""
    angles_deg = np.asarray(angles_deg, float)
    if not axes:
        return np.broadcast_to(np.eye(3), angles_deg.shape[:-1] + (3, 3)).copy()
    return euler_to_matrix(axes[::-1], angles_deg[..., ::-1])


def _children(skeleton: AsfSkeleton) -> dict[str, list[str]]:
    kids: dict[str, list[str]] = {}
    seen: set[str] = set()
    for parent, children in skeleton.hierarchy.items():
        if parent != "root" and parent not in skeleton.bones:
            raise UnknownNameError("ASF bone", [parent], list(skeleton.bones), file=skeleton.source,
                                   field="hierarchy")
        for c in children:
            if c not in skeleton.bones:
                raise UnknownNameError("ASF bone", [c], list(skeleton.bones), file=skeleton.source,
                                       field=f"hierarchy.{parent}")
            if c in seen:
                raise InputError(f"bone {c!r} has two parents (or is its own ancestor)", file=skeleton.source,
                                 field=f"hierarchy.{parent}")
            seen.add(c)
        kids[parent] = list(children)
    if "root" not in kids:
        raise InputError("the hierarchy has no 'root' line", file=skeleton.source, field="hierarchy")
    # every bone reached from the root once: a cycle never reaches it
    reached, stack = set(), list(kids["root"])
    while stack:
        b = stack.pop()
        if b not in reached:
            reached.add(b)
            stack.extend(kids.get(b, []))
    cut = sorted(seen - reached)
    if cut:
        raise InputError(f"bone(s) {cut} not reached from the root (a cycle in the hierarchy)",
                         file=skeleton.source, field="hierarchy")
    return kids


def _axis_order(order: str, file, field) -> str:
    if len(order) != 3 or set(order) - set("XYZ"):
        raise InputError(f"expected three of X, Y, Z (like XYZ), got {order!r}", file=file, field=field)
    return order


def amc_clip(skeleton: AsfSkeleton, motion: AmcMotion, *, fps: float = CMU_FPS, names: str = "asf") -> BvhClip:
    """The skeleton and motion as a parsed BVH clip (see the module docstring), in ASF
    length units and degrees. ``names``: ``"asf"`` (bone names, root ``root``) or ``"bvh"``
    (CMU's MotionBuilder-friendly BVH names, :data:`pinrecon.io.asf.CMU_BVH_FROM_ASF`)."""
    if names not in ("asf", "bvh"):
        raise InputError(f"names must be 'asf' or 'bvh', got {names!r}", field="names")
    if not (fps > 0 and np.isfinite(fps)):
        raise InputError(f"must be a positive number, got {fps!r}", field="fps")
    rename = (lambda b: b) if names == "asf" else (lambda b: "Hips" if b == "root" else CMU_BVH_FROM_ASF.get(b, b))
    if any(abs(a) > 0 for a in skeleton.root.get("orientation", (0.0, 0.0, 0.0))):
        raise InputError("a root orientation other than 0 0 0 is not read", file=skeleton.source,
                         field="root.orientation")
    kids = _children(skeleton)
    dofs = _dof(skeleton)
    F = motion.n_frames
    to_deg = np.degrees if motion.radians else (lambda x: x)

    # the root: position + translation, rotation M from its R values in their order
    order = dofs["root"]
    rv = motion.values["root"]
    pos = np.zeros((F, 3))
    r_axes, r_idx = "", []
    for k, d in enumerate(order):
        if d[0] == "T":
            pos[:, "XYZ".index(d[1])] = rv[:, k]
        else:
            r_axes += d[1]
            r_idx.append(k)
    R = _axes_matrix(r_axes, to_deg(rv[:, r_idx]))
    joints = [BvhJoint(rename("root"), -1, np.array(skeleton.root.get("position", (0.0, 0.0, 0.0)), float),
                       ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"))]
    columns = [np.concatenate([pos, continuous_euler(matrix_to_euler("ZYX", R))], axis=1)]

    def vector(b):
        bone = skeleton.bones[b]
        return np.asarray(bone.direction, float) * float(bone.length)

    bone_R = []
    stack = [(c, 0, np.zeros(3)) for c in reversed(kids["root"])]
    while stack:
        b, parent, offset = stack.pop()
        bone = skeleton.bones[b]
        me = len(joints)
        chans = ("Zrotation", "Yrotation", "Xrotation") if dofs[b] else ()
        joints.append(BvhJoint(rename(b), parent, offset, chans))
        if dofs[b]:
            C = _axes_matrix(_axis_order(bone.axis_order, skeleton.source, f"bonedata.{b}.axis"),
                             np.asarray(bone.axis_deg, float))
            M = _axes_matrix("".join(d[1].upper() for d in dofs[b]), to_deg(motion.values[b]))
            bone_R.append(C[None] @ M @ C.T[None])
        children = kids.get(b, [])
        if not children:
            joints[me].end_sites.append(vector(b))
        stack.extend((c, me, vector(b)) for c in reversed(children))
    if bone_R:  # (F, bones, 3) ZYX angles, each bone made continuous over the frames
        angles = continuous_euler(matrix_to_euler("ZYX", np.stack(bone_R, axis=1).reshape(-1, 3, 3)).reshape(F, -1, 3))
        columns.append(angles.reshape(F, -1))
    values = np.concatenate(columns, axis=1)
    return BvhClip(joints, 1.0 / float(fps), values, motion.source)


def load_amc(
    asf: str | os.PathLike,
    amc: str | os.PathLike,
    length_scale: float | None = None,
    *,
    fps: float = CMU_FPS,
    names: str = "asf",
    lock: Iterable[str] | str = (),
) -> BvhMotion:
    """Read an ASF skeleton and its AMC motion into a figure and its motion.

    Parameters
    ----------
    asf, amc : the two files (``pinrecon.datasets.cmu("01_01")`` gives both).
    length_scale : metres per ASF length unit (default :func:`asf_length_scale`: CMU's
        0.056444 m for ``:units length 0.45``).
    fps : frames per second (AMC stores none; CMU captured at 120).
    names : ``"asf"`` (joints and keypoints named as the bones, root ``root``, leaves'
        ends ``<bone>_end``) or ``"bvh"`` (as CMU's MotionBuilder-friendly BVH release, so
        its keypoint maps and ``Figure.with_limits(asf)`` apply).
    lock : joints to weld (zero in every frame), or ``"static"``, as :func:`pinrecon.io.bvh.load_bvh`.

    Returns a :class:`pinrecon.io.bvh.BvhMotion`: ``figure``, ``q`` (frames, nq), ``fps``,
    ``clip`` (the BVH-like clip, :func:`amc_clip`).
    """
    skeleton = read_asf(asf)
    motion = read_amc(amc, skeleton)
    scale = asf_length_scale(skeleton) if length_scale is None else length_scale
    clip = amc_clip(skeleton, motion, fps=fps, names=names)
    figure = figure_from_bvh(clip, scale, lock=lock)
    return BvhMotion(figure, motion_from_bvh(figure, clip), clip.fps, clip)
