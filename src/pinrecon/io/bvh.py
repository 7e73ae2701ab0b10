"""BVH: read any BVH file, build a pinrecon figure from its skeleton, convert its motion
to configurations, and write motion back as BVH.

Figure construction (see ``docs/formats.md``, "BVH figures"):

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
  RightShoulder, all zero in every frame; see :func:`static_joints`).
* BVH states no joint limits, so the figure has none. The URDF written for it gives
  revolute joints wide limits of +-4 pi (URDF requires a limit on revolute joints).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError, UnknownNameError
from .atomic import atomic_write_text

__all__ = [
    "BvhJoint",
    "BvhClip",
    "BvhMotion",
    "read_bvh",
    "figure_from_bvh",
    "motion_from_bvh",
    "load_bvh",
    "static_joints",
    "write_bvh",
    "euler_to_matrix",
]

_CHANNELS = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")
_WIDE_LIMIT = 4 * math.pi


@dataclass
class BvhJoint:
    """One BVH joint: name, parent index (-1 for the root), OFFSET, CHANNELS, End Sites."""

    name: str
    parent: int
    offset: np.ndarray
    channels: tuple[str, ...] = ()
    end_sites: list[np.ndarray] = field(default_factory=list)

    @property
    def rotation_channels(self) -> tuple[str, ...]:
        return tuple(c for c in self.channels if c.endswith("rotation"))

    @property
    def position_channels(self) -> tuple[str, ...]:
        return tuple(c for c in self.channels if c.endswith("position"))


@dataclass
class BvhClip:
    """A parsed BVH file: the skeleton (``joints``, file order) and the raw motion values.

    ``values`` has shape (frames, channels) in file units and degrees.
    """

    joints: list[BvhJoint]
    frame_time: float
    values: np.ndarray
    path: str | None = None

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time

    @property
    def n_frames(self) -> int:
        return self.values.shape[0]

    @property
    def names(self) -> list[str]:
        return [j.name for j in self.joints]

    def channel_columns(self) -> list[slice]:
        cols, start = [], 0
        for j in self.joints:
            cols.append(slice(start, start + len(j.channels)))
            start += len(j.channels)
        return cols

    def joint_index(self, name: str) -> int:
        for i, j in enumerate(self.joints):
            if j.name == name:
                return i
        raise UnknownNameError("BVH joint", [name], self.names, file=self.path)

    def end_site_names(self) -> list[tuple[int, str]]:
        out = []
        for i, j in enumerate(self.joints):
            for k in range(len(j.end_sites)):
                out.append((i, f"{j.name}_end" if k == 0 else f"{j.name}_end{k + 1}"))
        return out


def _tokenize(text: str):
    """Yield (token, line_number) for the hierarchy part."""
    for lineno, line in enumerate(text.splitlines(), 1):
        for tok in line.replace("{", " { ").replace("}", " } ").split():
            yield tok, lineno


def read_bvh(path: str | os.PathLike) -> BvhClip:
    """Parse a BVH file. Errors name the file, the section or joint, and the frame."""
    path = Path(path)
    try:
        text = path.read_text(errors="replace")
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except IsADirectoryError:
        raise InputError("is a directory, expected a BVH file", file=path) from None
    head, sep, motion = text.partition("MOTION")
    if not sep:
        # maybe lowercase or missing entirely
        raise InputError("no MOTION section found; not a BVH file?", file=path, field="MOTION")
    tokens = list(_tokenize(head))
    if not tokens or tokens[0][0] != "HIERARCHY":
        raise InputError("file must start with HIERARCHY", file=path, field="HIERARCHY")

    joints: list[BvhJoint] = []
    stack: list[int | None] = []  # joint index, or None inside an End Site block
    pending: str | None = None  # 'joint' or 'end' awaiting '{'
    i = 1

    def err(msg, lineno):
        return InputError(f"line {lineno}: {msg}", file=path, field="HIERARCHY")

    def numbers(k, n, lineno, what):
        vals = []
        for tok, ln in tokens[k : k + n]:
            try:
                vals.append(float(tok))
            except ValueError:
                raise err(f"{what}: expected {n} numbers, found {tok!r}", ln) from None
        if len(vals) != n:
            raise err(f"{what}: expected {n} numbers", lineno)
        return vals

    while i < len(tokens):
        tok, ln = tokens[i]
        if tok in ("ROOT", "JOINT"):
            if tok == "ROOT" and (joints or stack):
                raise err("only one ROOT is supported", ln)
            if tok == "JOINT" and (not stack or stack[-1] is None):
                raise err("JOINT outside a joint block", ln)
            if i + 1 >= len(tokens):
                raise err(f"{tok} without a name", ln)
            name = tokens[i + 1][0]
            if name in [j.name for j in joints]:
                raise err(f"duplicate joint name {name!r}", ln)
            joints.append(BvhJoint(name, stack[-1] if stack else -1, None))
            pending = "joint"
            i += 2
        elif tok == "End":
            if not stack or stack[-1] is None:
                raise err("End Site outside a joint block", ln)
            pending = "end"
            i += 2  # "End Site"
        elif tok == "{":
            if pending is None:
                raise err("unexpected '{'", ln)
            stack.append(len(joints) - 1 if pending == "joint" else None)
            if pending == "end":
                joints[stack[-2]].end_sites.append(None)
            pending = None
            i += 1
        elif tok == "}":
            if not stack:
                raise err("unbalanced '}'", ln)
            top = stack.pop()
            if top is not None and joints[top].offset is None:
                raise err(f"joint {joints[top].name!r} has no OFFSET", ln)
            if top is None and joints[stack[-1]].end_sites[-1] is None:
                raise err(f"End Site of {joints[stack[-1]].name!r} has no OFFSET", ln)
            i += 1
        elif tok == "OFFSET":
            if not stack:
                raise err("OFFSET outside a block", ln)
            vals = np.array(numbers(i + 1, 3, ln, "OFFSET"))
            if stack[-1] is None:
                joints[stack[-2]].end_sites[-1] = vals
            else:
                joints[stack[-1]].offset = vals
            i += 4
        elif tok == "CHANNELS":
            if not stack or stack[-1] is None:
                raise err("CHANNELS outside a joint block", ln)
            try:
                n = int(tokens[i + 1][0])
            except (ValueError, IndexError):
                raise err("CHANNELS needs a count", ln) from None
            chans = tuple(t for t, _ in tokens[i + 2 : i + 2 + n])
            bad = [c for c in chans if c not in _CHANNELS]
            if len(chans) != n or bad:
                raise err(
                    f"bad CHANNELS for joint {joints[stack[-1]].name!r}: {list(chans)}; "
                    f"valid channels are {list(_CHANNELS)}",
                    ln,
                )
            joints[stack[-1]].channels = chans
            i += 2 + n
        else:
            raise err(f"unexpected token {tok!r}", ln)
    if stack:
        raise InputError("unbalanced braces: hierarchy not closed", file=path, field="HIERARCHY")
    if not joints:
        raise InputError("no ROOT joint", file=path, field="HIERARCHY")

    # ---- motion
    lines = [ln for ln in motion.splitlines() if ln.strip()]
    n_frames, frame_time, k = None, None, 0
    while k < len(lines) and (n_frames is None or frame_time is None):
        s = lines[k].strip()
        if s.lower().startswith("frames:"):
            try:
                n_frames = int(s.split(":", 1)[1])
            except ValueError:
                raise InputError(f"bad 'Frames:' line {s!r}", file=path, field="Frames") from None
        elif s.lower().startswith("frame time:"):
            try:
                frame_time = float(s.split(":", 1)[1])
            except ValueError:
                raise InputError(f"bad 'Frame Time:' line {s!r}", file=path, field="Frame Time") from None
        else:
            raise InputError(f"expected 'Frames:' and 'Frame Time:', got {s!r}", file=path, field="MOTION")
        k += 1
    if n_frames is None or frame_time is None:
        raise InputError("MOTION needs 'Frames:' and 'Frame Time:'", file=path, field="MOTION")
    if not frame_time > 0:
        raise InputError(f"must be positive, got {frame_time}", file=path, field="Frame Time")
    n_ch = sum(len(j.channels) for j in joints)
    rows = lines[k:]
    if len(rows) < n_frames:
        raise InputError(
            f"header says {n_frames} frames but only {len(rows)} rows follow",
            file=path,
            field="MOTION",
            frame=len(rows),
        )
    values = np.empty((n_frames, n_ch))
    for f in range(n_frames):
        parts = rows[f].split()
        if len(parts) != n_ch:
            raise InputError(
                f"expected {n_ch} channel values, got {len(parts)}", file=path, field="MOTION", frame=f
            )
        try:
            values[f] = [float(x) for x in parts]
        except ValueError:
            raise InputError("non-numeric channel value", file=path, field="MOTION", frame=f) from None
    if not np.all(np.isfinite(values)):
        f = int(np.where(~np.all(np.isfinite(values), axis=1))[0][0])
        raise InputError("NaN or infinite channel value", file=path, field="MOTION", frame=f)
    return BvhClip(joints, frame_time, values, str(path))


# ---------------------------------------------------------------------------- rotations
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
    """Intrinsic rotation ``R = R_a1 R_a2 R_a3`` for ``axes`` like 'ZYX'; angles (..., n)."""
    angles = np.radians(np.asarray(angles_deg, float))
    R = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for k, a in enumerate(axes):
        R = R @ _axis_rotation(a, angles[..., k])
    return R


def matrix_to_euler(axes: str, R: np.ndarray) -> np.ndarray:
    """Inverse of :func:`euler_to_matrix` (degrees), for three distinct axes."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_euler(axes.upper(), degrees=True)


# ---------------------------------------------------------------------------- figure
def _link_name(j: BvhJoint) -> str:
    return j.name


def figure_from_bvh(clip: BvhClip, length_scale: float = 1.0, *, lock: Iterable[str] = ()):
    """Build a :class:`pinrecon.Figure` from a BVH skeleton (see the module docstring).

    Parameters
    ----------
    clip : parsed BVH (:func:`read_bvh`).
    length_scale : metres per file unit (CMU files: 0.056444).
    lock : BVH joint names whose channels are welded at zero (fixed joints), or
        ``"static"`` for every joint :func:`static_joints` finds.
    """
    import yourdfpy

    from ..figure import Figure, Keypoint

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

    links = [yourdfpy.Link(name=clip.joints[0].name)]
    ujoints = []
    keypoints = []
    for idx, j in enumerate(clip.joints):
        if idx > 0:
            parent_link = _link_name(clip.joints[j.parent])
            offset = np.asarray(j.offset, float) * length_scale
            chain = [] if j.name in lock else list(j.position_channels) + list(j.rotation_channels)
            if not chain:
                origin = np.eye(4)
                origin[:3, 3] = offset
                ujoints.append(
                    yourdfpy.Joint(f"{j.name}_weld", "fixed", parent_link, j.name, origin=origin)
                )
                links.append(yourdfpy.Link(name=j.name))
            else:
                prev = parent_link
                for c_i, ch in enumerate(chain):
                    child = j.name if c_i == len(chain) - 1 else f"{j.name}__{ch}"
                    origin = np.eye(4)
                    if c_i == 0:
                        origin[:3, 3] = offset
                    axis = np.eye(3)["XYZ".index(ch[0])]
                    if ch.endswith("rotation"):
                        jt = "revolute"
                        limit = yourdfpy.Limit(effort=0.0, velocity=0.0, lower=-_WIDE_LIMIT, upper=_WIDE_LIMIT)
                    else:
                        jt = "prismatic"
                        limit = yourdfpy.Limit(effort=0.0, velocity=0.0, lower=-1e3, upper=1e3)
                    ujoints.append(
                        yourdfpy.Joint(f"{j.name}_{ch}", jt, prev, child, origin=origin, axis=axis, limit=limit)
                    )
                    links.append(yourdfpy.Link(name=child))
                    prev = child
        keypoints.append(Keypoint(j.name, _link_name(j)))
    for i, end_name in clip.end_site_names():
        j = clip.joints[i]
        k = int(end_name[len(j.name) + 4 :] or 1) - 1
        keypoints.append(Keypoint(end_name, _link_name(j), tuple(np.asarray(j.end_sites[k]) * length_scale)))

    robot_name = Path(clip.path).stem if clip.path else "bvh_figure"
    robot = yourdfpy.Robot(name=robot_name, links=links, joints=ujoints)
    # str without an XML declaration (yourdfpy's write_xml_string returns declared bytes)
    from lxml import etree

    urdf = yourdfpy.URDF(robot, build_scene_graph=False, load_meshes=False)
    xml = etree.tostring(urdf.write_xml(), encoding="unicode", pretty_print=True)
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
    return Figure.from_urdf_string(
        xml, keypoints, root="free", name=robot_name, source=clip.path, limits={}, meta=meta
    )


def static_joints(clip: BvhClip, tol_deg: float = 1e-9) -> list[str]:
    """Non-root joints whose channels are zero in every frame (candidates for ``lock``)."""
    out = []
    for j, cols in zip(clip.joints[1:], clip.channel_columns()[1:]):
        block = clip.values[:, cols]
        if block.size and np.all(np.abs(block) <= tol_deg):
            out.append(j.name)
    return out


def motion_from_bvh(figure, clip: BvhClip) -> np.ndarray:
    """The clip's motion as configurations (frames, nq) of ``figure`` (built from ``clip``).

    Keypoint positions of the result reproduce the BVH joint positions exactly (up to
    floating point). Locked joints must be zero in every frame.
    """
    meta = figure.meta.get("bvh")
    if meta is None or meta["names"] != clip.names:
        raise InputError("figure was not built from this BVH skeleton", file=clip.path, field="figure")
    scale = meta["length_scale"]
    lock = set(meta["lock"])
    F = clip.n_frames
    Q = np.tile(figure.neutral(), (F, 1))
    cols = clip.channel_columns()
    root = clip.joints[0]
    block = clip.values[:, cols[0]]
    pos = np.tile(np.asarray(root.offset, float), (F, 1))
    rot_axes, rot_idx = "", []
    for k, ch in enumerate(root.channels):
        if ch.endswith("position"):
            pos[:, "XYZ".index(ch[0])] += block[:, k]
        else:
            rot_axes += ch[0]
            rot_idx.append(k)
    R = euler_to_matrix(rot_axes, block[:, rot_idx]) if rot_axes else np.broadcast_to(np.eye(3), (F, 3, 3))
    Q[:, :3] = pos * scale
    Q[:, 3:7] = _matrix_to_quat_xyzw(R)
    for j, c in zip(clip.joints[1:], cols[1:]):
        block = clip.values[:, c]
        if j.name in lock:
            bad = np.where(np.any(np.abs(block) > 1e-9, axis=1))[0]
            if bad.size:
                raise InputError(
                    f"joint {j.name!r} is locked but its channels are non-zero",
                    file=clip.path,
                    field=j.name,
                    frame=int(bad[0]),
                )
            continue
        for k, ch in enumerate(j.channels):
            qs, _ = figure.joint_slices(f"{j.name}_{ch}")
            Q[:, qs.start] = np.radians(block[:, k]) if ch.endswith("rotation") else block[:, k] * scale
    return Q


def _matrix_to_quat_xyzw(R: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    quat = Rotation.from_matrix(R).as_quat()  # (x, y, z, w), canonical w >= 0 not enforced
    return quat


@dataclass
class BvhMotion:
    """A BVH file loaded as a figure and its motion: ``q`` (frames, nq) at ``fps``."""

    figure: object
    q: np.ndarray
    fps: float
    clip: BvhClip

    @property
    def times(self) -> np.ndarray:
        return np.arange(self.q.shape[0]) / self.fps

    def keypoints(self) -> np.ndarray:
        return self.figure.keypoints(self.q)


def load_bvh(
    path: str | os.PathLike,
    length_scale: float = 1.0,
    *,
    lock: Iterable[str] | str = (),
    skip_frames: int = 0,
) -> BvhMotion:
    """Read a BVH file into a figure and its motion.

    Parameters
    ----------
    length_scale : metres per file unit (CMU: 0.056444).
    lock : joints to weld (must be zero in every frame), or ``"static"`` to lock every
        joint that :func:`static_joints` finds.
    skip_frames : frames to drop at the start (1 for the CMU T-pose frame of cgspeed files).
    """
    clip = read_bvh(path)
    if isinstance(lock, str):
        if lock != "static":
            raise InputError(f"lock must be a list of joint names or 'static', got {lock!r}", field="lock")
        lock = static_joints(clip)
    if skip_frames:
        clip = BvhClip(clip.joints, clip.frame_time, clip.values[skip_frames:], clip.path)
    figure = figure_from_bvh(clip, length_scale, lock=lock)
    return BvhMotion(figure, motion_from_bvh(figure, clip), clip.fps, clip)


# ---------------------------------------------------------------------------- writing
def _fmt(x: float) -> str:
    s = f"{x:.9f}"
    return s[1:] if s == "-0.000000000" else s


def write_bvh(path: str | os.PathLike, figure, q: np.ndarray, fps: float) -> None:
    """Write motion ``q`` (frames, nq) of ``figure`` as BVH, atomically.

    A figure built from a BVH writes back with its original joint names, channel orders,
    offsets and end sites, in its own length unit. Other figures are converted by
    :func:`pinrecon.io.bvh_export.urdf_figure_to_bvh`. Values are written with 9 decimals
    so positions survive the round trip to well below 1e-6 m.
    """
    q = np.asarray(q, float)
    if q.ndim != 2 or q.shape[1] != figure.nq:
        raise InputError(f"expected q of shape (frames, {figure.nq}), got {q.shape}", file=path, field="q")
    if not (fps > 0):
        raise InputError(f"must be positive, got {fps}", file=path, field="fps")
    bad = np.where(~np.all(np.isfinite(q), axis=1))[0]
    if bad.size:
        raise InputError("NaN or infinite configuration value", file=path, field="q", frame=int(bad[0]))
    if "bvh" in figure.meta:
        joints, values, unit = _bvh_skeleton_and_values(figure, q)
    else:
        from .bvh_export import urdf_figure_to_bvh

        joints, values, unit = urdf_figure_to_bvh(figure, q)
    lines = ["HIERARCHY"]
    children: dict[int, list[int]] = {}
    for i, j in enumerate(joints):
        children.setdefault(j.parent, []).append(i)

    def emit(i, depth):
        j = joints[i]
        ind = "\t" * depth
        lines.append(f"{ind}{'ROOT' if j.parent < 0 else 'JOINT'} {j.name}")
        lines.append(f"{ind}{{")
        lines.append(f"{ind}\tOFFSET {' '.join(_fmt(x / unit) for x in j.offset)}")
        lines.append(f"{ind}\tCHANNELS {len(j.channels)} {' '.join(j.channels)}")
        for c in children.get(i, []):
            emit(c, depth + 1)
        for e in j.end_sites:
            lines.append(f"{ind}\tEnd Site")
            lines.append(f"{ind}\t{{")
            lines.append(f"{ind}\t\tOFFSET {' '.join(_fmt(x / unit) for x in e)}")
            lines.append(f"{ind}\t}}")
        lines.append(f"{ind}}}")

    emit(children[-1][0], 0)
    lines.append("MOTION")
    lines.append(f"Frames: {q.shape[0]}")
    lines.append(f"Frame Time: {1.0 / fps:.10f}")
    for row in values:
        lines.append(" ".join(f"{x:.9f}" for x in row))
    atomic_write_text(path, "\n".join(lines) + "\n")


def _bvh_skeleton_and_values(figure, q):
    """Joints (offsets in metres) and channel values (file units/degrees) for a BVH figure."""
    meta = figure.meta["bvh"]
    unit = meta["length_scale"]
    lock = set(meta["lock"])
    joints = [
        BvhJoint(n, p, np.asarray(o), tuple(c), [np.asarray(e) for e in es])
        for n, p, o, c, es in zip(meta["names"], meta["parents"], meta["offsets"], meta["channels"], meta["end_sites"])
    ]
    F = q.shape[0]
    cols = []
    root = joints[0]
    R = np.array([_quat_xyzw_to_matrix(x) for x in q[:, 3:7]])
    pos = q[:, :3] / unit - root.offset / unit
    rot_axes = "".join(c[0] for c in root.channels if c.endswith("rotation"))
    if rot_axes and len(rot_axes) != 3:
        raise InputError("root rotation channels must be three distinct axes to export", field="channels")
    if rot_axes:
        from .bvh_export import continuous_euler

        eul = continuous_euler(matrix_to_euler(rot_axes, R))  # no 360-degree jumps when turning
    else:
        eul = np.zeros((F, 0))
    ri = 0
    block = np.zeros((F, len(root.channels)))
    for k, ch in enumerate(root.channels):
        if ch.endswith("position"):
            block[:, k] = pos[:, "XYZ".index(ch[0])]
        else:
            block[:, k] = eul[:, ri]
            ri += 1
    cols.append(block)
    for j in joints[1:]:
        block = np.zeros((F, len(j.channels)))
        if j.name not in lock:
            for k, ch in enumerate(j.channels):
                qs, _ = figure.joint_slices(f"{j.name}_{ch}")
                v = q[:, qs.start]
                block[:, k] = np.degrees(v) if ch.endswith("rotation") else v / unit
        cols.append(block)
    return joints, np.concatenate(cols, axis=1), unit


def _quat_xyzw_to_matrix(quat):
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(quat).as_matrix()
