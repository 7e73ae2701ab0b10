"""A figure's proportions as unknowns: log scale factors on its segments.

A *segment* is a URDF joint whose origin has a translation (the bone from its parent
link's origin to its child link's origin: the human's ``left_knee_Z`` is the thigh), or
the offsets of the keypoints attached to one frame (``middle_head.keypoints``: the face
points on the head). Both are read from the Pinocchio model: every URDF joint, fixed or
movable, is a frame whose ``parentFrame`` is its parent link, and its local origin is
``placement(parent link)^-1 * placement(joint)``.

Segments are gathered in *groups* that share one factor ``s = exp(theta)``: by default
one group per bone with left/right twins merged (:func:`mirror_name` pairs ``left``/
``right``, ``Left``/``Right``, ``l_``/``r_``, ``_l``/``_r`` and ``LHip``/``RHip`` names),
and for the human figure the named groups of :data:`HUMAN_GROUPS` (thigh, shank, foot,
upper arm, forearm, pelvis width, shoulder width, trunk, neck, head, hand).

Scaling segment u (parent link ``a``, local translation ``t_u``) by ``s`` moves every
point below it by ``R_world(a) t_u ds``, so with the log parametrisation

    d p_k / d theta_g = sum over segments u of group g on the path of keypoint k of
                        R_world(a_u) (s_u t_u),

and for a keypoint offset ``o_k`` in frame ``f`` scaled by its frame's factor,
``R_world(f) (s o_k)``. :meth:`Proportions.kinematics` returns the keypoints, their
Jacobians w.r.t. the configuration tangent and these derivatives for a trajectory,
vectorised over frames (NumPy forward kinematics for free-flyer, revolute and prismatic
joints; Pinocchio frame by frame for other joint types). :meth:`Proportions.calibrated_figure` writes the factors
into a new :class:`~pinrecon.figure.Figure` (URDF origins and keypoint offsets scaled),
whose forward kinematics equals that of the scaled model.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .errors import InputError, UnknownNameError
from .figure import Figure, Keypoint
from .figure_files import scale_urdf_origins
from .kinematics import (
    joint_kinds,
    joint_kinematics,
    keypoint_jacobians_from_world,
    point_kinematics,
    rows_of,
)

__all__ = ["HUMAN_GROUPS", "KEYPOINT_SEGMENT_SUFFIX", "FactorDerivatives", "Proportions", "Segment", "mirror_name"]

KEYPOINT_SEGMENT_SUFFIX = ".keypoints"

#: Named segment groups of ``Figure.human()`` (segments absent from a figure are skipped).
HUMAN_GROUPS: dict[str, list[str]] = {
    "pelvis_width": ["left_hip_Z", "right_hip_Z"],
    "thigh": ["left_knee_Z", "right_knee_Z"],
    "shank": ["left_ankle_Z", "right_ankle_Z"],
    "foot": ["left_foot.keypoints", "right_foot.keypoints"],
    "trunk": ["middle_thoracic_Z", "left_clavicle_joint_X", "right_clavicle_joint_X"],
    "shoulder_width": ["left_shoulder_Z", "right_shoulder_Z"],
    "upper_arm": ["left_elbow_Z", "right_elbow_Z"],
    "forearm": ["left_wrist_Z", "right_wrist_Z"],
    "hand": ["left_hand.keypoints", "right_hand.keypoints"],
    "neck": ["middle_cervical_Z"],
    "head": ["middle_head.keypoints"],
}
_HUMAN_SIGNATURE = ("left_knee_Z", "right_knee_Z", "left_wrist_Z", "middle_thoracic_Z")

_SWAP = {"left": "right", "right": "left", "Left": "Right", "Right": "Left", "LEFT": "RIGHT", "RIGHT": "LEFT"}


def _swap_case(token: str, other: str) -> str:
    if token.isupper():
        return other.upper()
    return other.capitalize() if token[0].isupper() else other.lower()


def mirror_name(name: str) -> tuple[str, str] | None:
    """``(other side's name, side-free stem)`` of a left/right name, or ``None``.

    Recognised: ``left``/``right`` anywhere (any case), ``l_``/``r_`` (or ``.``, ``-``)
    prefixes, ``_l``/``_r`` (``.L``/``.R``) suffixes and ``L``/``R`` before a capital
    (``LHipJoint``). The stem drops the side token (``left_knee_Z`` -> ``knee_Z``).
    """
    m = re.search(r"left|right", name, flags=re.IGNORECASE)
    if m:
        tok = m.group(0)
        other = _swap_case(tok, "right" if tok.lower() == "left" else "left")
        stem = (name[: m.start()] + name[m.end() :]).strip("_.- ") or name
        stem = re.sub(r"[_.\-]{2,}", "_", stem)
        return name[: m.start()] + other + name[m.end() :], stem
    m = re.match(r"^([lLrR])([_.\-])(.+)$", name)
    if m:
        side = {"l": "r", "r": "l", "L": "R", "R": "L"}[m.group(1)]
        return side + m.group(2) + m.group(3), m.group(3)
    m = re.match(r"^(.+)([_.\-])([lLrR])$", name)
    if m:
        side = {"l": "r", "r": "l", "L": "R", "R": "L"}[m.group(3)]
        return m.group(1) + m.group(2) + side, m.group(1)
    m = re.match(r"^([LR])([A-Z].*)$", name)
    if m:
        return ("R" if m.group(1) == "L" else "L") + m.group(2), m.group(2)
    return None


@dataclass(frozen=True)
class Segment:
    """One scalable translation of a figure.

    name : the URDF joint's name, or ``<frame>.keypoints`` for keypoint offsets.
    kind : ``"joint"`` (movable URDF joint), ``"fixed"`` (fixed URDF joint) or ``"keypoints"``.
    frame : Pinocchio frame id (the joint's frame, or the keypoints' frame).
    translation : (3,) local translation at factor 1 in the parent link's axes (metres);
        for keypoint segments the mean offset norm is its ``length_m``.
    length_m : the segment's length at factor 1.
    """

    name: str
    kind: str
    frame: int
    translation: np.ndarray
    length_m: float


class _Scaled:
    """The model and keypoint data of one log-factor vector (cached by Proportions)."""

    def __init__(self, model, kp_joint, kp_p_joint, anchor_w, end_w, data, placements):
        self.model, self.data, self.placements = model, data, placements
        self.kp_joint, self.kp_p_joint = kp_joint, kp_p_joint
        self.anchor_w, self.end_w = anchor_w, end_w


class FactorDerivatives:
    """d p_k / d theta (T, K, 3, n) of the scaled figure along a trajectory, kept as its
    factors: ``V[t, b] = R_world(a_b) (s_b t_b)`` (T, B, 3) for every scaled bone, the
    constant map ``C`` (B, K n) from bones to (keypoint, group) and the scaled end offsets
    ``d_end[t, e]`` (T, E, 3) of the keypoints ``ends`` in groups ``end_groups``:

        d p_k / d theta_g = sum_b V[t, b] C[b, k, g]  (+ d_end[t, e] when k = ends[e], g = end_groups[e])

    :meth:`projected` applies a constant matrix ``A`` (a camera's ``d uv / d X``, a floor
    normal) to ``V`` before the product with ``C`` (r rows instead of 3, only the selected
    keypoints' columns); :meth:`full` forms the whole array once."""

    def __init__(self, T, K, n, V, C, ends, end_groups, d_end):
        self.T, self.K, self.n = T, K, n
        self.V, self.C = V, C
        self.ends, self.end_groups, self.d_end = ends, end_groups, d_end
        self._full = None

    def full(self) -> np.ndarray:
        """(T, K, 3, n), formed on the first call."""
        if self._full is None:
            T, K, n = self.T, self.K, self.n
            dp = np.zeros((T, 3, K * n))
            if self.V is not None:  # one matrix product for all frames (a batched matmul of T small ones is slower)
                dp = (self.V.transpose(0, 2, 1).reshape(T * 3, -1) @ self.C).reshape(T, 3, K * n)
            dp = dp.reshape(T, 3, K, n).transpose(0, 2, 1, 3)  # a view: (T, K, 3, n) strides over (T, 3, K, n)
            if len(self.ends):
                dp[:, self.ends, :, self.end_groups] += self.d_end.transpose(1, 0, 2)
            self._full = dp
        return self._full

    def projected(self, rows, keypoints, A, out=None) -> np.ndarray:
        """(N, M, r, n): ``A d p_k / d theta`` at trajectory rows ``rows`` (N,) for
        ``keypoints`` (M,), ``A`` an (r, 3) matrix or per-point (N, M, r, 3) matrices;
        written into ``out`` when given."""
        A = np.asarray(A, float)
        kps = np.asarray(keypoints, dtype=int)
        if A.ndim != 2 or self._full is not None:
            return np.matmul(A, np.take(rows_of(self.full(), rows), kps, axis=1), out=out)
        N, M, r, n = len(rows), len(kps), A.shape[0], self.n
        if out is None:
            out = np.empty((N, M, r, n))
        if self.V is None:
            out[...] = 0.0
        else:
            B = self.V.shape[1]
            VA = np.matmul(rows_of(self.V, rows), A.T)  # (N, B, r)
            Ck = self.C.reshape(B, self.K, n)[:, kps].reshape(B, M * n)
            X = VA.transpose(0, 2, 1).reshape(N * r, B) @ Ck
            out[...] = X.reshape(N, r, M, n).transpose(0, 2, 1, 3)
        if len(self.ends):
            pos = {int(e): i for i, e in enumerate(self.ends)}
            m_idx = [m for m, k in enumerate(kps) if int(k) in pos]
            if m_idx:
                e_idx = [pos[int(kps[m])] for m in m_idx]
                D = np.matmul(rows_of(self.d_end, rows)[:, e_idx], A.T)  # (N, E', r)
                out[:, m_idx, :, self.end_groups[e_idx]] += D.transpose(1, 0, 2)
        return out


class Proportions:
    """Log scale factors on groups of a figure's segments.

    Parameters
    ----------
    figure : the generic figure (factor 1 everywhere).
    groups : ``{group name: [segment names]}``; every segment in at most one group.
        Segments in no group keep factor 1. See :attr:`segments` for the names.

    Attributes
    ----------
    names : the n group names, in parameter order (``theta[i]`` is ``log`` of group i's factor).
    segments : every scalable segment of the figure (:class:`Segment`).
    """

    def __init__(self, figure: Figure, groups: Mapping[str, Sequence[str]]):
        self.figure = figure
        model = figure.model
        self._model = model
        frames = model.frames
        nf = len(frames)
        self._P0 = [pin.SE3(f.placement) for f in frames]
        self._type_joint = np.array([f.type == pin.FrameType.JOINT for f in frames])
        self._parent = np.array([f.parentFrame for f in frames], dtype=int)
        self._pjoint = np.array([f.parentJoint for f in frames], dtype=int)
        if np.any(self._parent[1:] >= np.arange(1, nf)):
            raise InputError("the model's frames are not ordered parent before child", field="figure")
        # a frame's origin relative to its parent frame (None: not chained, kept as is)
        self._local: list[pin.SE3 | None] = [None] * nf
        for i in range(1, nf):
            f, pi = frames[i], self._parent[i]
            if self._type_joint[i]:
                if self._pjoint[pi] == model.parents[f.parentJoint]:
                    self._local[i] = self._P0[pi].actInv(model.jointPlacements[f.parentJoint])
            elif self._pjoint[pi] == f.parentJoint:
                self._local[i] = self._P0[pi].actInv(self._P0[i])
        segments = []
        for i in range(1, nf):
            L = self._local[i]
            if L is None or frames[i].type not in (pin.FrameType.JOINT, pin.FrameType.FIXED_JOINT):
                continue
            if np.linalg.norm(L.translation) > 1e-12:
                kind = "joint" if self._type_joint[i] else "fixed"
                t = np.array(L.translation)
                segments.append(Segment(frames[i].name, kind, i, t, float(np.linalg.norm(t))))
        kps = figure.keypoints_def
        self._kp_frame = np.array([model.getFrameId(k.frame) for k in kps], dtype=int)
        self._kp_offset = np.array([k.offset for k in kps], float).reshape(-1, 3)
        by_frame: dict[int, list[int]] = {}
        for k in range(len(kps)):
            if np.linalg.norm(self._kp_offset[k]) > 1e-12:
                by_frame.setdefault(int(self._kp_frame[k]), []).append(k)
        for fid, ks in sorted(by_frame.items()):
            length = float(np.mean(np.linalg.norm(self._kp_offset[ks], axis=1)))
            segments.append(Segment(frames[fid].name + KEYPOINT_SEGMENT_SUFFIX, "keypoints", fid, np.zeros(3), length))
        self.segments = segments
        self._seg_index = {s.name: u for u, s in enumerate(segments)}
        # groups
        seg_group = np.full(len(segments), -1, dtype=int)
        names = []
        for gname, members in groups.items():
            members = list(members)
            unknown = [m for m in members if m not in self._seg_index]
            if unknown:
                raise UnknownNameError("segment", unknown, list(self._seg_index), field=f"groups.{gname}")
            if not members:
                raise InputError("a group needs at least one segment", field=f"groups.{gname}")
            for m in members:
                u = self._seg_index[m]
                if seg_group[u] >= 0:
                    raise InputError(f"segment {m!r} is in two groups ({names[seg_group[u]]!r}, {gname!r})",
                                     field="groups")
                seg_group[u] = len(names)
            names.append(str(gname))
        self.names = names
        self.n = len(names)
        self._seg_group = seg_group
        # structure for the derivatives: joint/fixed segments act through their parent
        # link (anchor joint); keypoint segments through the keypoints' own joint
        self._bone = np.array([u for u, s in enumerate(segments) if s.kind != "keypoints" and seg_group[u] >= 0], int)
        self._anchor = np.array([self._pjoint[self._parent[segments[u].frame]] for u in self._bone], dtype=int)
        K = len(kps)
        chains = []
        for k in range(K):
            chain, i = set(), int(self._kp_frame[k])
            while i > 0:
                chain.add(i)
                i = int(self._parent[i])
            chains.append(chain)
        # C[k, b, g]: bone b is on keypoint k's path and in group g
        C = np.zeros((K, len(self._bone), self.n))
        for b, u in enumerate(self._bone):
            for k in range(K):
                if segments[u].frame in chains[k]:
                    C[k, b, seg_group[u]] = 1.0
        self._C = C.transpose(1, 0, 2).reshape(len(self._bone), K * self.n)
        self._kp_end_group = np.full(K, -1, dtype=int)
        for u, s in enumerate(segments):
            if s.kind == "keypoints" and seg_group[u] >= 0:
                self._kp_end_group[by_frame[s.frame]] = seg_group[u]
        self._kp_joint = self._pjoint[self._kp_frame]
        self._joints = np.unique(np.concatenate([self._kp_joint, self._anchor]).astype(int))
        slot = {int(j): i for i, j in enumerate(self._joints)}
        self._kp_slot = np.array([slot[int(j)] for j in self._kp_joint], dtype=int)
        self._anchor_slot = np.array([slot[int(j)] for j in self._anchor], dtype=int)
        mask = np.zeros((K, model.nv), dtype=bool)
        for k, j in enumerate(self._kp_joint):
            for s in model.supports[int(j)]:
                if s > 0:
                    mask[k, model.idx_vs[s] : model.idx_vs[s] + model.nvs[s]] = True
        self._kp_mask = mask
        self._kinds = joint_kinds(model)
        self._cache_key: bytes | None = None
        self._cache: _Scaled | None = None
        self._work: pin.Model | None = None
        self._work_data = None

    # ------------------------------------------------------------------ building
    @classmethod
    def bones(cls, figure: Figure, *, symmetric: bool = True) -> Proportions:
        """One factor per segment, left/right twins sharing one when ``symmetric``."""
        return cls(figure, _bone_groups([s.name for s in cls(figure, {}).segments], symmetric))

    @classmethod
    def human(cls, figure: Figure, *, symmetric: bool = True) -> Proportions:
        """The named groups of :data:`HUMAN_GROUPS` for the human figure, and one
        (symmetric) group per remaining segment."""
        seg = [s.name for s in cls(figure, {}).segments]
        groups = {g: [m for m in members if m in seg] for g, members in HUMAN_GROUPS.items()}
        groups = {g: m for g, m in groups.items() if m}
        used = {m for ms in groups.values() for m in ms}
        for g, ms in _bone_groups([s for s in seg if s not in used], symmetric).items():
            groups[g if g not in groups else g + "_bone"] = ms
        return cls(figure, groups)

    @classmethod
    def default(cls, figure: Figure) -> Proportions:
        """:meth:`human` for the human figure (recognised by its joint names), else
        :meth:`bones` (symmetric)."""
        seg = {s.name for s in cls(figure, {}).segments}
        if all(n in seg for n in _HUMAN_SIGNATURE):
            return cls.human(figure)
        return cls.bones(figure)

    # ------------------------------------------------------------------ factors
    def check(self, log_factors) -> np.ndarray:
        theta = np.asarray(log_factors, float)
        if theta.shape != (self.n,) or not np.all(np.isfinite(theta)):
            raise InputError(f"expected {self.n} finite log factors, got shape {theta.shape}", field="log_factors")
        return theta

    def segment_factors(self, log_factors) -> dict[str, float]:
        """Segment name -> factor (1 for segments in no group)."""
        theta = self.check(log_factors)
        return {s.name: float(np.exp(theta[g])) if g >= 0 else 1.0 for s, g in zip(self.segments, self._seg_group)}

    def factors(self, log_factors) -> dict[str, float]:
        """Group name -> factor ``exp(theta)``."""
        theta = self.check(log_factors)
        return {n: float(np.exp(t)) for n, t in zip(self.names, theta)}

    def pair_groups(self, pairs, tol: float = 0.05) -> np.ndarray:
        """For keypoint index pairs ``pairs`` (P, 2): the group whose factor alone scales
        the pair's distance (``d log |p_a - p_b| / d theta`` is 1 for it and 0 for the
        others, within ``tol``, and the distance is the same in the neutral pose and in a
        bent one: a rigid segment, e.g. hip-knee for the thigh), else -1. Measured at the
        figure as given, by central differences of :meth:`keypoints`."""
        pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
        fig = self.figure
        q0 = fig.neutral()
        lo, hi = fig.lower_v, fig.upper_v
        v = np.where(np.isfinite(lo) & np.isfinite(hi), 0.3 * (hi - lo), 0.5)
        rng = np.random.default_rng(0)
        q1 = fig.clamp(fig.integrate(q0, v * rng.uniform(-1.0, 1.0, fig.nv)))
        Q = np.stack([q0, q1])
        def dist(theta):
            P = self.keypoints(theta, Q)
            return np.linalg.norm(P[:, pairs[:, 0]] - P[:, pairs[:, 1]], axis=-1)  # (2, P)
        d0 = dist(np.zeros(self.n))
        eps = 1e-4
        D = np.stack([(np.log(dist(eps * e)[0]) - np.log(dist(-eps * e)[0])) / (2 * eps) for e in np.eye(self.n)], axis=1)
        out = np.full(len(pairs), -1)
        for i in range(len(pairs)):
            g = int(np.argmax(D[i])) if self.n else -1
            rigid = d0[0, i] > 0 and abs(d0[1, i] - d0[0, i]) <= 1e-6 * d0[0, i]
            if g >= 0 and rigid and abs(D[i, g] - 1.0) <= tol and np.sum(np.abs(np.delete(D[i], g))) <= tol:
                out[i] = g
        return out

    def members(self, group: str) -> list[str]:
        if group not in self.names:
            raise UnknownNameError("group", [group], self.names, field="group")
        g = self.names.index(group)
        return [s.name for s, gg in zip(self.segments, self._seg_group) if gg == g]

    def lengths_m(self, log_factors=None) -> dict[str, float]:
        """Group name -> mean length (metres) of its segments at these factors."""
        theta = np.zeros(self.n) if log_factors is None else self.check(log_factors)
        out = {}
        for g, name in enumerate(self.names):
            lengths = [s.length_m for s, gg in zip(self.segments, self._seg_group) if gg == g]
            out[name] = float(np.exp(theta[g]) * np.mean(lengths))
        return out

    def log_factors_for_lengths(self, lengths_m: Mapping[str, float], log_factors=None) -> np.ndarray:
        """Log factors giving groups the mean lengths ``lengths_m`` (others unchanged):
        how a measured segment length (e.g. from planarity) starts its factor."""
        theta = np.zeros(self.n) if log_factors is None else self.check(log_factors).copy()
        nominal = self.lengths_m()
        for name, length in lengths_m.items():
            if name not in nominal:
                raise UnknownNameError("group", [name], self.names, field="lengths_m")
            if not (np.isfinite(length) and length > 0):
                raise InputError(f"must be a positive length, got {length!r}", field=f"lengths_m.{name}")
            theta[self.names.index(name)] = np.log(length / nominal[name])
        return theta

    # ------------------------------------------------------------------ the scaled model
    def _scaled(self, theta: np.ndarray) -> _Scaled:
        key = theta.tobytes()
        if key == self._cache_key:
            return self._cache
        grouped = self._seg_group >= 0
        seg_s = np.ones(len(self._seg_group))
        seg_s[grouped] = np.exp(theta[self._seg_group[grouped]])  # ungrouped segments (all, with no group) stay
        frame_s = np.ones(len(self._P0))
        end_s = np.ones(len(self._P0))
        for s, f in zip(self.segments, seg_s):
            (end_s if s.kind == "keypoints" else frame_s)[s.frame] = f
        if self._work is None:  # one working model and its data, rewritten for each factor vector
            self._work = pin.Model(self._model)
            self._work_data = self._work.createData()
        model = self._work
        P = list(self._P0)
        for i in range(1, len(P)):
            L = self._local[i]
            if L is None:
                continue
            if frame_s[i] != 1.0:
                L = pin.SE3(L.rotation, L.translation * frame_s[i])
            if self._type_joint[i]:
                model.jointPlacements[int(self._pjoint[i])] = P[self._parent[i]] * L
            else:  # a frame: its placement is written only into copies (``model()``)
                P[i] = P[self._parent[i]] * L
        offsets = self._kp_offset * end_s[self._kp_frame][:, None]
        kp_p = np.array([P[f].act(o) for f, o in zip(self._kp_frame, offsets)]).reshape(-1, 3)
        anchor_w = np.array(
            [P[self._parent[self.segments[u].frame]].rotation @ (seg_s[u] * self.segments[u].translation)
             for u in self._bone]
        ).reshape(-1, 3)
        end_w = np.array([P[f].rotation @ o for f, o in zip(self._kp_frame, offsets)]).reshape(-1, 3)
        end_w[self._kp_end_group < 0] = 0.0
        self._cache_key = key
        self._cache = _Scaled(model, self._kp_joint, kp_p, anchor_w, end_w, self._work_data, P)
        return self._cache

    def model(self, log_factors) -> pin.Model:
        """A copy of the Pinocchio model with the factors applied (joint and frame placements)."""
        sc = self._scaled(self.check(log_factors))
        model = pin.Model(sc.model)
        for i in range(1, len(sc.placements)):
            if self._local[i] is not None and not self._type_joint[i]:
                fr = model.frames[i]
                fr.placement = sc.placements[i]
                model.frames[i] = fr
        return model

    def _poses(self, sc: _Scaled, Q: np.ndarray, jacobian: bool):
        """World rotations (T, U, 3, 3) and origins (T, U, 3) of the joints ``self._joints``
        and the WORLD joint Jacobian (T, 6, nv) of the scaled model
        (:func:`pinrecon.kinematics.joint_kinematics`: vectorised over frames when every
        joint is a free flyer, a revolute or a prismatic joint, else frame by frame)."""
        return joint_kinematics(sc.model, sc.data, self._kinds, Q, self._joints, jacobian)

    def _check_q(self, Q):
        Q = np.asarray(Q, float)
        if Q.ndim != 2 or Q.shape[1] != self._model.nq:
            raise InputError(f"expected a trajectory (T, {self._model.nq}), got shape {Q.shape}", field="q")
        return Q

    def keypoints(self, log_factors, Q) -> np.ndarray:
        """(T, K, 3) keypoints of the scaled figure along the trajectory Q (T, nq)."""
        sc = self._scaled(self.check(log_factors))
        P, _ = point_kinematics(sc.model, sc.data, self._kinds, self._check_q(Q), self._joints, self._kp_slot,
                                sc.kp_p_joint, False)  # formed in chunks of frames
        return P

    def world_kinematics(self, log_factors, Q, full: bool = True):
        """Keypoints (T, K, 3), the WORLD joint Jacobian (T, 6, nv) and d p / d theta
        (T, K, 3, n) of the scaled figure along Q (T, nq); the keypoint Jacobians are
        :func:`pinrecon.kinematics.keypoint_jacobians_from_world` of the first two with the
        figure's ``keypoint_support`` (scaling changes no joint's support). With
        ``full=False`` the last is a :class:`FactorDerivatives` (the derivatives kept as
        their factors, projected or formed on demand)."""
        sc = self._scaled(self.check(log_factors))
        Q = self._check_q(Q)
        R, pj, Jw = self._poses(sc, Q, True)
        T, K = Q.shape[0], len(self._kp_joint)
        Rk = R[:, self._kp_slot]
        p = np.einsum("tkab,kb->tka", Rk, sc.kp_p_joint) + pj[:, self._kp_slot]
        V = np.einsum("tbxy,by->tbx", R[:, self._anchor_slot], sc.anchor_w) if len(self._bone) else None  # (T, B, 3)
        ends = np.where(self._kp_end_group >= 0)[0]
        d_end = np.einsum("tkxy,ky->tkx", Rk[:, ends], sc.end_w[ends]) if len(ends) else None  # (T, E, 3)
        dp = FactorDerivatives(T, K, self.n, V, self._C, ends, self._kp_end_group[ends], d_end)
        return p, Jw, (dp.full() if full else dp)

    def kinematics(self, log_factors, Q):
        """Keypoints (T, K, 3), d p / d v (T, K, 3, nv) and d p / d theta (T, K, 3, n) of
        the scaled figure along Q (T, nq)."""
        p, Jw, dp = self.world_kinematics(log_factors, Q)
        return p, keypoint_jacobians_from_world(p, Jw, self._kp_mask), dp

    # ------------------------------------------------------------------ the calibrated figure
    def calibrated_figure(self, log_factors, *, name: str | None = None) -> Figure:
        """A new :class:`Figure` with the factors written in: URDF joint origins and
        keypoint offsets scaled (the URDF text is edited; a figure without URDF gets the
        edited Pinocchio model). Its forward kinematics equals :meth:`keypoints`."""
        theta = self.check(log_factors)
        fig = self.figure
        seg_f = self.segment_factors(theta)
        end_s = {s.frame: seg_f[s.name] for s in self.segments if s.kind == "keypoints"}
        kps = [
            Keypoint(k.name, k.frame, tuple(float(x) for x in end_s.get(int(f), 1.0) * np.asarray(k.offset, float)))
            for k, f in zip(fig.keypoints_def, self._kp_frame)
        ]
        meta = {k: v for k, v in fig.meta.items() if not str(k).startswith("_")}
        meta["proportions"] = {"factors": self.factors(theta), "segment_factors": seg_f}
        if isinstance(meta.get("bvh"), Mapping):
            meta["bvh"] = self._bvh_meta(meta["bvh"], seg_f)
        limits = fig.limits_dict()
        if fig.urdf_xml is not None:
            joint_f = {s.name: seg_f[s.name] for s in self.segments if s.kind != "keypoints" and seg_f[s.name] != 1.0}
            xml = scale_urdf_origins(fig.urdf_xml, joint_f)
            return Figure.from_urdf_string(
                xml, kps, root="free" if fig.floating else "fixed", name=name or fig.name, source=None,
                limits=limits, meta=meta,
            )
        return Figure(self.model(theta), kps, name=name or fig.name, urdf_xml=None, limits=limits,
                      source=None, floating=fig.floating, meta=meta)

    def _bvh_meta(self, bvh: Mapping, seg_f: Mapping[str, float]) -> dict:
        """A BVH figure's skeleton description (``meta["bvh"]``) with the factors applied:
        each BVH joint's OFFSET lives in the first URDF joint of its chain (named
        ``<joint>_<channel>`` or ``<joint>_weld``), its end sites in its link's keypoints."""
        out = dict(bvh)
        by_name = {s.name: s for s in self.segments}
        offsets = [list(map(float, o)) for o in bvh.get("offsets", [])]
        for i, name in enumerate(bvh.get("names", [])):
            o = np.asarray(offsets[i], float) if i < len(offsets) else np.zeros(3)
            cands = [s for n, s in by_name.items() if s.kind != "keypoints" and n.startswith(f"{name}_")
                     and np.allclose(s.translation, o, rtol=1e-9, atol=1e-12)]
            if i > 0 and len(cands) == 1:
                offsets[i] = list(map(float, o * seg_f[cands[0].name]))
        if offsets:
            out["offsets"] = offsets
        if "end_sites" in bvh:
            out["end_sites"] = [
                [list(map(float, np.asarray(e, float) * seg_f.get(name + KEYPOINT_SEGMENT_SUFFIX, 1.0))) for e in ends]
                for name, ends in zip(bvh.get("names", []), bvh["end_sites"])
            ]
        return out

    def __repr__(self) -> str:
        return f"Proportions({self.figure.name!r}, {self.n} groups: {', '.join(self.names)})"


def _bone_groups(segment_names: Sequence[str], symmetric: bool) -> dict[str, list[str]]:
    """One group per segment; with ``symmetric`` left/right twins share one, paired by
    :func:`mirror_name` on the full name, else on the name without its last ``_token``
    (a BVH joint welded on one side only: ``LeftLeg_weld`` with ``RightLeg_Zrotation``)."""
    names = list(segment_names)
    pairs: list[tuple[str, str, str]] = []
    if symmetric:
        present = set(names)
        done: set[str] = set()
        for name in names:
            m = mirror_name(name)
            if name not in done and m and m[0] in present and m[0] not in done and m[0] != name:
                pairs.append((name, m[0], m[1]))
                done.update((name, m[0]))
        rest = [n for n in names if n not in done]
        base = {}
        for n in rest:
            base.setdefault(n.rsplit("_", 1)[0] if "_" in n else n, []).append(n)
        unique = {b: ns[0] for b, ns in base.items() if len(ns) == 1}
        for b, n in unique.items():
            m = mirror_name(b)
            if n not in done and m and m[0] in unique and unique[m[0]] not in done and m[0] != b:
                pairs.append((n, unique[m[0]], m[1]))
                done.update((n, unique[m[0]]))
    partner = {a: (b, stem) for a, b, stem in pairs}
    paired = {b for _, b, _ in pairs}
    groups: dict[str, list[str]] = {}
    for name in names:
        if name in paired:
            continue
        if name in partner:
            other, stem = partner[name]
            gname = stem if stem not in groups and stem not in names else name
            groups[gname] = [name, other]
        else:
            groups[name] = [name]
    return groups
