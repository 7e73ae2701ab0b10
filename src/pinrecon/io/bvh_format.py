"""The BVH file format itself: parse a file into its skeleton and raw channel values,
and write a skeleton and channel values back as BVH text. No figures here.

:mod:`pinrecon.io.bvh` turns a parsed file into a figure and configurations (and back);
:mod:`pinrecon.figure_bvh` converts a parsed skeleton into URDF text and keypoints.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError, UnknownNameError
from .atomic import atomic_write_text
from .jsonfile import read_text

__all__ = ["BvhJoint", "BvhClip", "read_bvh", "static_joints", "write_bvh_text"]

_CHANNELS = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")

#: the largest BVH number accepted (offsets, positions, angles in degrees)
MAX_VALUE = 1e9
#: the frame times accepted, seconds
FRAME_TIME_RANGE = (1e-6, 1e3)


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
    text = read_text(path, errors="replace")
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
            if not abs(vals[-1]) <= MAX_VALUE:
                raise err(f"{what}: {tok!r} is not a length (finite, at most {MAX_VALUE:g})", ln)
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
            if pending == "end" and (not stack or stack[-1] is None):
                raise err("End Site outside a joint block", ln)
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
    if not FRAME_TIME_RANGE[0] <= frame_time <= FRAME_TIME_RANGE[1]:
        raise InputError(f"must be in [{FRAME_TIME_RANGE[0]:g}, {FRAME_TIME_RANGE[1]:g}] seconds, got {frame_time}",
                         file=path, field="Frame Time")
    if n_frames < 0:
        raise InputError(f"must be a number of frames, got {n_frames}", file=path, field="Frames")
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
    if np.any(np.abs(values) > MAX_VALUE):
        f = int(np.where(np.any(np.abs(values) > MAX_VALUE, axis=1))[0][0])
        raise InputError(f"a channel value beyond +-{MAX_VALUE:g}", file=path, field="MOTION", frame=f)
    return BvhClip(joints, frame_time, values, str(path))


def static_joints(clip: BvhClip, tol_deg: float = 1e-9) -> list[str]:
    """Non-root joints whose channels are zero in every frame (candidates for ``lock``)."""
    out = []
    for j, cols in zip(clip.joints[1:], clip.channel_columns()[1:]):
        block = clip.values[:, cols]
        if block.size and np.all(np.abs(block) <= tol_deg):
            out.append(j.name)
    return out


# ---------------------------------------------------------------------------- writing
def _fmt(x: float) -> str:
    s = f"{x:.9f}"
    return s[1:] if s == "-0.000000000" else s




def write_bvh_text(
    path: str | os.PathLike, joints: list[BvhJoint], values: np.ndarray, unit: float, fps: float
) -> None:
    """Write a BVH file atomically from a skeleton and its channel values.

    ``joints`` in file order (parents before children), OFFSETs and End Sites in metres;
    ``values`` (frames, channels) already in file units and degrees; ``unit`` metres per
    file unit (OFFSETs are divided by it). Numbers get 9 decimals.
    """
    values = np.asarray(values, float)
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
    lines.append(f"Frames: {values.shape[0]}")
    lines.append(f"Frame Time: {1.0 / fps:.10f}")
    for row in values:
        lines.append(" ".join(f"{x:.9f}" for x in row))
    atomic_write_text(path, "\n".join(lines) + "\n")
