"""The generic human's joints in anatomical words (``left_knee_Z`` -> ``left knee flexion/extension``),
for pictures and summaries."""

from __future__ import annotations

import re

__all__ = ["HUMAN_MOVEMENTS", "joint_title"]

#: the generic human's (``Figure.human()``) joint axes as movements: at rest its Z axes are
#: the body's left-right axis, X its front-back axis and Y the vertical (checked in
#: tests/test_edges.py against the figure's own geometry)
HUMAN_MOVEMENTS = {
    "Z": "flexion/extension",
    "X": {"": "abduction/adduction", "ankle": "inversion/eversion", "wrist": "radial/ulnar deviation",
          "clavicle_joint": "elevation/depression", "lumbar": "lateral bending", "thoracic": "lateral bending",
          "cervical": "lateral bending"},
    "Y": {"": "internal/external rotation", "elbow": "pronation/supination", "lumbar": "axial rotation",
          "thoracic": "axial rotation", "cervical": "axial rotation"},
}


def joint_title(figure, name: str) -> str:
    """A joint-angle panel's title: the anatomical movement where the generic human's joint
    is known (``left_knee_Z`` -> ``left knee flexion/extension``), else the joint's name."""
    m = re.fullmatch(r"(left|right|middle)_(\w+?)_([XYZ])", name)
    if m is None or getattr(figure, "name", "") != "human":
        return name
    side, part, axis = m.groups()
    moves = HUMAN_MOVEMENTS[axis]
    move = moves if isinstance(moves, str) else moves.get(part, moves[""])
    where = part.replace("_joint", "").replace("_", " ")
    return f"{'' if side == 'middle' else side + ' '}{where} {move}"
