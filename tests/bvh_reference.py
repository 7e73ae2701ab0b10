"""An independent, deliberately plain BVH reader used only as ground truth in tests.

It shares no code with ``pinrecon``: it parses the text with ``str.split`` and runs
forward kinematics with SciPy rotations (intrinsic Euler angles in channel order,
local R = R_c1 R_c2 R_c3, as BVH defines them).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def reference_clip(path):
    """The file as written: (names, parents, OFFSETs (J, 3), channels per joint, end-site
    names, end-site parents, end-site OFFSETs, motion values (F, C) in file units and degrees)."""
    tokens = open(path).read().split()
    names, parents, offsets, channels = [], [], [], []
    end_names, end_parents, end_offsets = [], [], []
    stack, i = [], 0
    last_kind = None
    while tokens[i] != "MOTION":
        tok = tokens[i]
        if tok in ("ROOT", "JOINT"):
            names.append(tokens[i + 1])
            parents.append(stack[-1] if stack else -1)
            offsets.append(None)
            channels.append([])
            last_kind = "joint"
            i += 2
        elif tok == "End":
            end_names.append(names[stack[-1]] + "_end")
            end_parents.append(stack[-1])
            last_kind = "end"
            i += 2
        elif tok == "{":
            if last_kind == "joint":
                stack.append(len(names) - 1)
            else:
                stack.append(None)
            last_kind = None
            i += 1
        elif tok == "}":
            stack.pop()
            i += 1
        elif tok == "OFFSET":
            off = [float(x) for x in tokens[i + 1 : i + 4]]
            if stack and stack[-1] is None:
                end_offsets.append(off)
            else:
                offsets[stack[-1]] = off
            i += 4
        elif tok == "CHANNELS":
            n = int(tokens[i + 1])
            channels[stack[-1]] = tokens[i + 2 : i + 2 + n]
            i += 2 + n
        else:
            i += 1
    n_frames = int(tokens[i + 2])
    values = np.array([float(x) for x in tokens[i + 6 :]]).reshape(n_frames, -1)
    return names, parents, np.array(offsets), channels, end_names, end_parents, end_offsets, values


def reference_positions(path, scale=1.0):
    """Return (names, parents, positions (F, J, 3), end_names, end_positions (F, E, 3))."""
    names, parents, offsets, channels, end_names, end_parents, end_offsets, values = reference_clip(path)
    n_frames = len(values)
    offsets = offsets * scale
    J = len(names)
    R_world = np.zeros((n_frames, J, 3, 3))
    p_world = np.zeros((n_frames, J, 3))
    col = 0
    for j in range(J):
        ch = channels[j]
        block = values[:, col : col + len(ch)]
        col += len(ch)
        rot_axes = "".join(c[0].upper() for c in ch if c.endswith("rotation"))
        rot_vals = block[:, [k for k, c in enumerate(ch) if c.endswith("rotation")]]
        pos = np.zeros((n_frames, 3))
        for k, c in enumerate(ch):
            if c.endswith("position"):
                pos[:, "XYZ".index(c[0].upper())] = block[:, k] * scale
        if rot_axes:
            R_local = Rotation.from_euler(rot_axes, rot_vals, degrees=True).as_matrix()
        else:
            R_local = np.broadcast_to(np.eye(3), (n_frames, 3, 3))
        if parents[j] < 0:
            p_world[:, j] = offsets[j] + pos
            R_world[:, j] = R_local
        else:
            P = parents[j]
            # a non-root joint's position channels are in its parent's axes, like its OFFSET
            p_world[:, j] = p_world[:, P] + np.einsum("fab,fb->fa", R_world[:, P], offsets[j] + pos)
            R_world[:, j] = R_world[:, P] @ R_local
    end_p = np.zeros((n_frames, len(end_names), 3))
    for e, (P, off) in enumerate(zip(end_parents, end_offsets)):
        end_p[:, e] = p_world[:, P] + np.einsum("fab,b->fa", R_world[:, P], np.array(off) * scale)
    return names, parents, p_world, end_names, end_p
