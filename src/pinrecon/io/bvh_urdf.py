"""BVH export of figures that did not come from a BVH file (URDF figures such as
:meth:`pinrecon.Figure.human`): their skeleton and channel values.

:func:`pinrecon.io.bvh.write_bvh` calls :func:`urdf_figure_to_bvh` for such figures.
The conversion:

* **Hierarchy = kinematic tree.** The BVH ROOT is the free flyer (6 channels
  ``Xposition Yposition Zposition Zrotation Yrotation Xrotation``, the world pose of the
  root joint) or, for a fixed-base figure, the base link at the world origin (same 6
  channels, constant zeros).
* **One BVH joint per anatomical joint.** A chain of Pinocchio joints with zero
  translation between them (the human's ``left_hip_Z``, ``left_hip_X``, ``left_hip_Y``)
  becomes one BVH joint when every joint of the chain but the last has exactly one child
  and carries no keypoint away from its origin. Its OFFSET is the translation of the
  chain's first joint placement; its 3 rotation channels are Euler angles of the chain's
  local rotation ``R_place1 R_motion1 R_place2 R_motion2 ...`` (exact: any rotation
  matrix is reproduced). The Euler order follows the chain's own axes when they are
  coordinate axes (``left_hip`` Z, X, Y -> ``Zrotation Xrotation Yrotation``, so channel
  values are the joint angles in degrees up to sign), otherwise ZYX. Chains with a
  translational degree of freedom (prismatic joints) get ``Xposition Yposition
  Zposition`` channels first (BVH's ``T(offset + p) R``). Angles are made continuous over
  time (no 360 degree jumps, the equivalent Euler triple is picked when it is closer),
  which animation tools interpolate well.
* **Names.** A BVH joint is named after the link that ends its chain
  (``left_upperleg``), or after the keypoint at its origin when exactly one keypoint
  sits there (``left_hip`` for COCO-17). Name clashes get a ``_joint`` suffix.
* **Every keypoint is reproduced.** Keypoints that are not alone at a joint origin
  become extra BVH joints named exactly as the keypoint, with ``CHANNELS 0`` and OFFSET =
  the keypoint's position in its joint frame. Reading the written file back with
  :func:`pinrecon.io.bvh.load_bvh` gives keypoints with the same names and positions.
* **End Sites.** Every leaf joint gets an End Site (BVH tools expect one): zero for the
  keypoint joints; for a leaf body, its centre of mass when the URDF has inertias, else
  half its bone continued.

Units: joint OFFSETs are returned in metres and the values in file units (``length_scale``
metres per unit; default 1.0, the file is in metres) and degrees.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..errors import InputError
from ..rotations import continuous_euler, matrix_to_euler
from .bvh_format import BvhJoint

__all__ = ["urdf_figure_to_bvh"]

_TOL = 1e-9
_ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")
_BAD_NAME = re.compile(r"[\s{}]")


# ---------------------------------------------------------------------------- skeleton plan
@dataclass
class _Node:
    """A BVH joint of the plan: a chain of Pinocchio joints, or a keypoint marker."""

    name: str
    parent: int  # index in the plan, -1 for the root
    offset_m: np.ndarray
    chain: list[int] = field(default_factory=list)  # Pinocchio joint ids (empty: keypoint)
    order: str = "ZYX"
    translational: bool = False
    end_sites: list[np.ndarray] = field(default_factory=list)
    kp_named: int | None = None  # the keypoint this chain joint is named after

    @property
    def last(self) -> int:
        return self.chain[-1]


def _joint_dofs(model: pin.Model):
    """Per joint: (translational?, [signed principal axis letters of its rotation dofs])."""
    data = model.createData()
    pin.computeJointJacobians(model, data, pin.neutral(model))
    trans, axes = {}, {}
    for j in range(1, model.njoints):
        J = pin.getJointJacobian(model, data, j, pin.LOCAL)
        cols = J[:, model.idx_vs[j] : model.idx_vs[j] + model.nvs[j]]
        trans[j] = bool(np.abs(cols[:3]).max() > _TOL) if cols.size else False
        letters = []
        for c in cols.T:
            w = c[3:]
            k = int(np.argmax(np.abs(w)))
            pure = np.linalg.norm(c[:3]) < _TOL and np.linalg.norm(w) - abs(w[k]) < 1e-9
            if pure and abs(abs(w[k]) - 1) < 1e-9:
                letters.append("XYZ"[k])
            else:
                letters.append("?")
        axes[j] = letters
    return trans, axes


def _euler_order(chain: list[int], axes: dict[int, list[str]], model: pin.Model) -> str:
    """The chain's own axis order if it is a sequence of distinct coordinate axes with
    identity placement rotations, completed with the missing axes; else ZYX."""
    letters = []
    for j in chain:
        if not np.allclose(model.jointPlacements[j].rotation, np.eye(3), atol=1e-12):
            return "ZYX"
        letters += axes[j]
    if "?" in letters or len(set(letters)) != len(letters) or len(letters) > 3:
        return "ZYX"
    return "".join(letters) + "".join(a for a in "ZYX" if a not in letters)


def _keypoints_by_joint(figure):
    """Per keypoint: (joint id, position in that joint's frame, metres)."""
    model = figure.model
    out = []
    for kp in figure.keypoints_def:
        frame = model.frames[model.getFrameId(kp.frame)]
        p_joint = np.asarray(frame.placement.act(np.asarray(kp.offset, float)))
        out.append((int(frame.parentJoint), p_joint))
    return out


def _body_name(model: pin.Model, joint: int) -> str:
    """The link that a joint moves (its first BODY frame), else the joint's name."""
    for f in model.frames:
        if f.parentJoint == joint and f.type == pin.FrameType.BODY:
            return f.name
    return model.names[joint] if joint > 0 else "root"


def _clean_name(name: str, what: str) -> str:
    if _BAD_NAME.search(name) or not name:
        new = _BAD_NAME.sub("_", name) or "unnamed"
        warnings.warn(
            f"BVH names cannot contain spaces or braces: {what} {name!r} written as {new!r}", stacklevel=4
        )
        return new
    return name


def _plan(figure) -> list[_Node]:
    """BVH joints (DFS pre-order, parents before children) for ``figure``."""
    model = figure.model
    floating = bool(figure.floating)
    root_joint = 1 if floating else 0
    children: dict[int, list[int]] = {j: [] for j in range(model.njoints)}
    for j in range(1, model.njoints):
        children[model.parents[j]].append(j)
    trans, axes = _joint_dofs(model)

    kps = _keypoints_by_joint(figure)
    on_joint: dict[int, list[int]] = {}
    for i, (j, _) in enumerate(kps):
        on_joint.setdefault(j, []).append(i)
    if floating:
        stray = [figure.keypoint_names[i] for i in on_joint.get(0, [])]
        if stray:
            raise InputError(
                f"keypoints {stray} are fixed in the world frame, not on the figure; "
                "a BVH file cannot carry them",
                field="keypoints",
            )

    def off_origin(j):
        return [i for i in on_joint.get(j, []) if np.linalg.norm(kps[i][1]) > _TOL]

    def chain_from(j):
        chain = [j]
        while True:
            last = chain[-1]
            kids = children[last]
            if len(kids) != 1 or off_origin(last):
                return chain
            nxt = kids[0]
            if np.linalg.norm(model.jointPlacements[nxt].translation) > _TOL:
                return chain
            chain.append(nxt)

    nodes: list[_Node] = []
    kp_nodes: list[tuple[int, int]] = []  # (node index of the keypoint joint, keypoint index)

    def add_group(chain, parent):
        first = chain[0]
        node = _Node(
            name="",
            parent=parent,
            offset_m=np.array(model.jointPlacements[first].translation if parent >= 0 else np.zeros(3), float),
            chain=chain,
            order="ZYX" if parent < 0 else _euler_order(chain, axes, model),
            translational=any(trans.get(j, False) for j in chain) if parent >= 0 else True,
        )
        idx = len(nodes)
        nodes.append(node)
        # keypoints of this chain: at the common origin (any chain joint) or away from it (last)
        here = [i for j in chain for i in on_joint.get(j, [])]
        at_origin = [i for i in here if np.linalg.norm(kps[i][1]) <= _TOL]
        node.kp_named = at_origin[0] if len(at_origin) == 1 else None
        if node.kp_named is not None:
            node.name = figure.keypoint_names[node.kp_named]
        else:
            node.name = _body_name(model, chain[-1])
        for c in children[chain[-1]]:
            add_group(chain_from(c), idx)
        for i in here:
            if i != node.kp_named:
                kp_nodes.append((len(nodes), i))
                nodes.append(_Node(figure.keypoint_names[i], idx, np.array(kps[i][1], float)))
        return idx

    add_group([root_joint], -1)

    # names: keypoint names are exact; joint names must not clash with them or each other
    kp_names = {figure.keypoint_names[i] for _, i in kp_nodes} | {
        n.name for n in nodes if n.chain and n.kp_named is not None
    }
    used: set[str] = set()
    for n in nodes:
        if not n.chain or n.kp_named is not None:
            n.name = _clean_name(n.name, "keypoint")
            used.add(n.name)
    for n in nodes:
        if n.chain and n.kp_named is None:
            base = _clean_name(n.name, "link")
            name = base if base not in kp_names and base not in used else f"{base}_joint"
            k = 2
            while name in used or name in kp_names:
                name = f"{base}_joint{k}"
                k += 1
            n.name = name
            used.add(name)
    if len(used) != len(nodes):
        raise InputError("keypoint names collide after cleaning; rename them", field="keypoints")

    # end sites for leaves
    has_child = {n.parent for n in nodes}
    for idx, n in enumerate(nodes):
        if idx in has_child:
            continue
        if not n.chain:
            n.end_sites = [np.zeros(3)]
            continue
        inertia = model.inertias[n.last]
        if inertia.mass > 0 and np.linalg.norm(inertia.lever) > 1e-6:
            n.end_sites = [np.array(inertia.lever, float)]
        else:
            # continue the bone: the offset, expressed in the chain's frame at rest
            R_rest = np.eye(3)
            for j in n.chain:
                R_rest = R_rest @ model.jointPlacements[j].rotation
            n.end_sites = [0.5 * (R_rest.T @ n.offset_m)]
    return nodes


# ---------------------------------------------------------------------------- conversion
def urdf_figure_to_bvh(figure, q: np.ndarray, length_scale: float = 1.0):
    """BVH skeleton and channel values of motion ``q`` (frames, nq) of a URDF figure.

    Parameters
    ----------
    figure : a :class:`pinrecon.Figure` (free-flyer or fixed root).
    q : (frames, nq) configurations (a single (nq,) configuration is one frame).
    length_scale : metres per file unit (1.0: the file is in metres; 0.01: centimetres).

    Returns
    -------
    joints : list of :class:`~pinrecon.io.bvh.BvhJoint` in file (depth-first) order,
        OFFSETs and End Sites in metres.
    values : (frames, channels) channel values, file units and degrees.
    unit : ``length_scale``.

    See the module docstring for the mapping; it is exact (keypoints read back with
    :func:`pinrecon.io.bvh.load_bvh` match ``figure.keypoints(q)`` to rounding).
    """
    unit = float(length_scale)
    if not (unit > 0 and math.isfinite(unit)):
        raise InputError(f"must be a positive number, got {length_scale}", field="length_scale")
    q = figure.check_q(q)
    if q.ndim == 1:
        q = q[None]
    if q.ndim != 2:
        raise InputError(f"expected q of shape (frames, {figure.nq}), got {q.shape}", field="q")
    if not np.all(np.isfinite(q)):
        f = int(np.where(~np.all(np.isfinite(q), axis=1))[0][0])
        raise InputError("NaN or infinite configuration", field="q", frame=f)
    model, data = figure.model, figure.model.createData()
    nodes = _plan(figure)
    F = q.shape[0]

    # world poses of every joint, per frame
    oMi = np.empty((F, model.njoints, 4, 4))
    for f in range(F):
        pin.forwardKinematics(model, data, q[f])
        for j in range(model.njoints):
            oMi[f, j] = data.oMi[j].homogeneous

    joints: list[BvhJoint] = []
    cols = []
    for n in nodes:
        if not n.chain:
            joints.append(BvhJoint(n.name, n.parent, n.offset_m, (), list(n.end_sites)))
            continue
        if n.parent < 0:
            M = oMi[:, n.last]
            channels = _ROOT_CHANNELS
            pos = M[:, :3, 3] / unit
            rot = continuous_euler(matrix_to_euler("ZYX", M[:, :3, :3]))
            cols.append(np.concatenate([pos, rot], axis=1))
        else:
            parent_last = nodes[n.parent].last
            P = oMi[:, parent_last]
            M_local = np.linalg.inv(P) @ oMi[:, n.last]
            rot = continuous_euler(matrix_to_euler(n.order, M_local[:, :3, :3]))
            channels = tuple(f"{a}rotation" for a in n.order)
            if n.translational:
                channels = ("Xposition", "Yposition", "Zposition") + channels
                pos = (M_local[:, :3, 3] - n.offset_m) / unit
                cols.append(np.concatenate([pos, rot], axis=1))
            else:
                cols.append(rot)
        joints.append(BvhJoint(n.name, n.parent, n.offset_m, channels, list(n.end_sites)))
    values = np.concatenate(cols, axis=1) if cols else np.zeros((F, 0))
    return joints, values, unit
