"""Lifted-pose rows: a learned per-frame 3D estimate of the figure (a lifter's output,
:class:`pinrecon.lifted.Lifted`) as a robust prior on the directions of its bones.

A *bone* is a pair of keypoints ``(a, b)`` along the skeleton (shoulder-elbow,
elbow-wrist, hip-knee, knee-ankle, the shoulders, the hips, each side's shoulder-hip, ...:
:func:`lifted_bones`). In frame ``t`` the figure's bone direction in world axes is

    d = (p_b - p_a) / |p_b - p_a|,

the lifter's is ``l = (L_b - L_a) / |L_b - L_a|`` in its own axes, and the row is

    e = d - R_world_lifter l            (3 entries; |e| = 2 sin(angle / 2), the chord)

whitened by ``sqrt(w c_ab)``, ``w`` the row kind's weight (``Weights.lifted``: the inverse
variance of a bone's chord; 25 is a standard deviation of 0.2, about 11 degrees) and
``c_ab = min(c_a, c_b)`` the lifter's confidences. Unit directions make the rows free of
the lifter's size and translation (a lifter's metres are seldom the figure's); a robust
loss on ``|e|`` (Cauchy or Huber, scale ``loss_scale`` in chord units, the same for every
weight) lets the image and the other rows outvote a bone the lifter got wrong (a limb
mirrored in depth: ``|e| = 2 sin(elevation)``). The loss is applied as iteratively
reweighted rows, ``r = sqrt(w c rho'(|e|^2)) e``, as :class:`~.measurement.Measurement2D`
does, so ``J^T r`` is the exact gradient of ``0.5 w c rho(|e|^2)``.

**The lifter's axes.** ``Lifted.frame == "camera"``: the lifter's axes are the camera's
(OpenCV: x right, y down, z forward), so ``R_world_lifter = R_cam_world^T`` of the view's
camera, known. ``"unknown"``: one rotation for the whole clip, estimated. It is *profiled
out*: at every evaluation ``R`` is the weighted Procrustes (Wahba) rotation that minimises
the rows' cost at the current poses, ``R = U diag(1, 1, det(U V^T)) V^T`` with ``U S V^T =
sum_tb omega d l^T`` (``omega = w c rho'`` re-solved a few times for the robust loss), so
the rows are a function of the poses alone. Why this and not a global unknown of the
Schur complement: the rotation has a closed form given the poses, and profiling it keeps
every solve of the pipeline (starts, stages, windows, solves without globals) consistent
without adding a global to the problem; the gradient is exact (the envelope theorem: the
cost is stationary in ``R`` at its optimum), and the Gauss-Newton matrix drops only
``dR/dq_t``, a coupling of order ``1/T`` per frame through the one rotation shared by all
frames (Kaufman's variable-projection approximation). The solver's step test reads the
profiled cost, so an accepted step lowers it. Rotation, not reflection: the lifter's
handedness is kept, which is what tells a limb from its mirror image.

The derivative (``docs/derivations.md``, lifted-pose rows): ``dd/dv = (I - d d^T) / |p_b -
p_a| (J_b - J_a)`` with ``J_k`` the keypoint Jacobian; with the figure's proportions as
global unknowns the same projection of ``dp_b/dg - dp_a/dg``. It lies in the plane normal to
``d``, so a bone's block holds two rows, ``U^T r`` for ``U`` a basis of that plane: the same
``J^T J`` and ``J^T r`` as the three rows of ``r``; ``r``'s part along ``d`` has no derivative
and counts in the cost and in ``RowBlock.group_cost``.
"""

from __future__ import annotations

import copy

import numpy as np

from .base import RowBlock, RowKind, State, crop_aligned, supported_columns

__all__ = [
    "DISAGREEMENT_DEG",
    "EXTRA_BONES",
    "LENGTH_BONES",
    "LiftedLengths",
    "LiftedPose",
    "disagreement_extras",
    "disagreement_spans",
    "lifted_bones",
    "lifted_lengths_row",
    "lifted_rows",
    "procrustes_rotation",
]

#: bones across the skeleton's tree (the tree's own bones come from the keypoint map's parents)
EXTRA_BONES = (
    ("left_shoulder", "right_shoulder"), ("left_hip", "right_hip"), ("left_shoulder", "left_hip"),
    ("right_shoulder", "right_hip"), ("left_ear", "right_ear"), ("left_shoulder", "right_hip"),
    ("right_shoulder", "left_hip"), ("neck", "nose"), ("left_ankle", "left_heel"), ("right_ankle", "right_heel"),
    ("left_ankle", "left_big_toe"), ("right_ankle", "right_big_toe"),
)

#: a bone whose solved direction is further than this from the lifter's (degrees) disagrees
DISAGREEMENT_DEG = 45.0


def lifted_bones(figure, names) -> list[tuple[str, str]]:
    """The bones ``(a, b)`` among ``names`` (keypoints the figure and the lifter share): each
    keypoint with its parent keypoint in the figure's map (elbow-shoulder, wrist-elbow, ...),
    then :data:`EXTRA_BONES`; a pair of coincident keypoints is left out."""
    have = [n for n in names if n in figure.keypoint_names]
    out = []
    parents = figure.parents_of_keypoints
    for n in have:
        p = parents[figure.keypoint_names.index(n)]
        if p is not None and figure.keypoint_names[p] in have:
            out.append((figure.keypoint_names[p], n))
    seen = {frozenset(b) for b in out}
    out += [(a, b) for a, b in EXTRA_BONES if a in have and b in have and frozenset((a, b)) not in seen]
    P = figure.keypoints(figure.neutral()[None])[0]
    return [(a, b) for a, b in out
            if np.linalg.norm(P[figure.keypoint_names.index(a)] - P[figure.keypoint_names.index(b)]) > 1e-6]


def procrustes_rotation(D: np.ndarray, L: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The rotation ``R`` (3, 3) minimising ``sum w |D - R L|^2`` over paired unit vectors
    ``D``, ``L`` (..., 3) with weights ``w`` (...) (Wahba's problem, by SVD)."""
    M = np.einsum("n,ni,nj->ij", np.ravel(w), np.reshape(D, (-1, 3)), np.reshape(L, (-1, 3)))
    U, _, Vt = np.linalg.svd(M)
    S = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    return U @ S @ Vt


class LiftedPose(RowKind):
    """Rows pulling the figure's bone directions to a lifter's, frame by frame.

    Parameters
    ----------
    frames : (N,) reconstruction frames with a lifted pose.
    bones : (B, 2) figure keypoint indices ``(a, b)`` of each bone.
    directions : (N, B, 3) the lifter's unit bone directions in its own axes, NaN where missing.
    confidence : (N, B) per bone (0 where missing).
    R_world_lifter : (3, 3) the lifter's axes in world axes (``"camera"`` frame:
        ``camera.R.T``), or ``None``: estimated from the poses at every evaluation
        (the module docstring).
    weight : inverse variance of a bone's chord ``|d - R l|`` (``Weights.lifted``).
    loss : ``"cauchy"``, ``"huber"`` or ``"l2"``; ``loss_scale`` its scale in chord units.
    irls : Procrustes re-solves with the robust weights (an estimated rotation only).
    names : (B,) labels of the bones (``"left_elbow-left_wrist"``), for reports.
    view : the name of the camera whose image was lifted (:class:`pinrecon.problem.View`).
    """

    name = "lifted"

    def __init__(self, frames, bones, directions, confidence, R_world_lifter=None, weight=25.0, loss="cauchy",
                 loss_scale=0.5, irls=3, names=None, view=None):
        self.frames = np.asarray(frames, dtype=int)
        self.kinematic_frames = self.frames
        self.bones = np.asarray(bones, dtype=int).reshape(-1, 2)
        L = np.asarray(directions, float)
        c = np.asarray(confidence, float)
        ok = np.all(np.isfinite(L), axis=-1) & (c > 0)
        self.observed = ok
        self.L = np.where(ok[..., None], L, 0.0)
        self.w = np.where(ok, c, 0.0) * float(weight)
        self.R_fixed = None if R_world_lifter is None else np.asarray(R_world_lifter, float)
        if loss not in ("l2", "huber", "cauchy"):
            raise ValueError(f"loss must be 'l2', 'huber' or 'cauchy', got {loss!r}")
        self.loss, self.loss_scale, self.irls = loss, float(loss_scale), int(irls)
        self.names = list(names) if names is not None else [f"{a}-{b}" for a, b in self.bones]
        self.keypoints = np.unique(self.bones)
        self.view = view

    def crop(self, lo: int, hi: int) -> LiftedPose | None:
        """Cropped when the lifter's axes are known (``R_world_lifter``); an estimated
        rotation is the whole clip's, so those rows are not cropped (``None``)."""
        if self.R_fixed is None:
            return None
        return crop_aligned(self, lo, hi, ("observed", "L", "w"))

    def crop_at(self, lo: int, hi: int, state: State) -> LiftedPose:
        """:meth:`crop` with the rotation held at the one the whole clip's ``state`` gives (an
        estimated rotation is the whole clip's: a part of the clip alone would estimate its own)."""
        held = copy.copy(self)
        held.R_fixed = self.rotation(state)
        return crop_aligned(held, lo, hi, ("observed", "L", "w"))

    def swap_sides(self, frames, perm) -> None:
        """Exchange the lifter's left and right labels at the reconstruction frames
        ``frames`` in place, as the fault stage does the detector's (:mod:`pinrecon.faults`):
        ``perm`` (K,) maps each figure keypoint to its other side's (itself when it has
        none). A bone ``(a, b)`` takes the lifter's direction of ``(perm a, perm b)``
        (reversed when that bone is stored as ``(perm b, perm a)``; no row when the lifter
        has no such bone)."""
        perm = np.asarray(perm, int)
        index = {(int(a), int(b)): j for j, (a, b) in enumerate(self.bones)}
        src, sign = np.full(len(self.bones), -1), np.ones(len(self.bones))
        for j, (a, b) in enumerate(self.bones):
            pa, pb = int(perm[a]), int(perm[b])
            if (pa, pb) in index:
                src[j] = index[(pa, pb)]
            elif (pb, pa) in index:
                src[j], sign[j] = index[(pb, pa)], -1.0
        n = np.flatnonzero(np.isin(self.frames, np.asarray(frames, int)))
        if not len(n):
            return
        ok = src >= 0
        take = np.where(ok, src, 0)
        self.L[n] = np.where(ok[:, None], self.L[n][:, take] * sign[:, None], 0.0)
        self.w[n] = np.where(ok, self.w[n][:, take], 0.0)
        self.observed[n] = ok & self.observed[n][:, take]

    # -- pieces ---------------------------------------------------------------------------
    def _robust(self, s):
        """``(rho(s), rho'(s))`` of the squared chord ``s`` (``rho(s) = s`` for l2)."""
        c2 = self.loss_scale**2
        if self.loss == "l2":
            return s, np.ones_like(s)
        if self.loss == "huber":
            e = np.sqrt(s)
            inside = e <= self.loss_scale
            return (np.where(inside, s, 2.0 * self.loss_scale * e - c2),
                    np.where(inside, 1.0, self.loss_scale / np.maximum(e, 1e-300)))
        return c2 * np.log1p(s / c2), 1.0 / (1.0 + s / c2)

    def directions(self, state: State):
        """``(d, length)``: the figure's unit bone directions (N, B, 3) in world axes and the
        bones' lengths (N, B) at the state."""
        P = state.points[state.slot[self.frames]]
        v = P[:, self.bones[:, 1]] - P[:, self.bones[:, 0]]
        n = np.maximum(np.linalg.norm(v, axis=-1), 1e-12)
        return v / n[..., None], n

    def rotation(self, state: State, d=None) -> np.ndarray:
        """``R_world_lifter`` at the state: the fixed one, or the profiled Procrustes one."""
        if self.R_fixed is not None:
            return self.R_fixed
        if d is None:
            d = self.directions(state)[0]
        R = procrustes_rotation(d, self.L, self.w)
        for _ in range(self.irls if self.loss != "l2" else 0):
            s = np.sum((d - self.L @ R.T) ** 2, axis=-1)
            R, R_old = procrustes_rotation(d, self.L, self.w * self._robust(s)[1]), R
            if np.abs(R - R_old).max() < 1e-13:
                break
        return R

    def angles_deg(self, state: State) -> np.ndarray:
        """(N, B) angle between the figure's bone and the lifter's (degrees), NaN where missing."""
        d, _ = self.directions(state)
        e = np.linalg.norm(d - self.L @ self.rotation(state, d).T, axis=-1)
        return np.where(self.observed, np.degrees(2.0 * np.arcsin(np.clip(e / 2.0, 0.0, 1.0))), np.nan)

    def bone_costs(self, P, frames, R) -> np.ndarray:
        """(F, B) each bone's cost ``0.5 w c rho(|e|^2)`` for keypoints ``P`` (F, K, 3) at the
        reconstruction frames ``frames`` (F,), the rotation ``R`` held (0 where no lifted pose):
        what a search over discrete hypotheses (:mod:`pinrecon.starts.hypotheses`) adds."""
        frames = np.asarray(frames, dtype=int)
        pos = np.clip(np.searchsorted(self.frames, frames), 0, max(len(self.frames) - 1, 0))
        have = (self.frames[pos] == frames) if len(self.frames) else np.zeros(len(frames), bool)
        v = P[:, self.bones[:, 1]] - P[:, self.bones[:, 0]]
        d = v / np.maximum(np.linalg.norm(v, axis=-1), 1e-12)[..., None]
        s = np.sum((d - self.L[pos] @ np.asarray(R).T) ** 2, axis=-1)
        return np.where(have[:, None], 0.5 * self.w[pos] * self._robust(s)[0], 0.0)

    # -- rows -----------------------------------------------------------------------------
    def evaluate(self, state: State, jacobian: bool = True, R=None) -> RowBlock:
        d, length = self.directions(state)
        R = self.rotation(state, d) if R is None else R
        e = d - self.L @ R.T  # (N, B, 3)
        s = np.sum(e * e, axis=-1)
        rho, drho = self._robust(s)
        scale = np.sqrt(self.w * drho)  # (N, B)
        # two rows per bone, e's components across d (U: an orthonormal basis of the plane
        # normal to d): dd/dv lies in that plane, so J^T J and J^T r are those of the three
        # rows of e; e's part along d (|e|^2 / 2) has no derivative and stays in the cost
        U = _normal_basis(d)  # (N, B, 3, 2)
        N, B = e.shape[:2]
        r = (np.einsum("nbij,nbi->nbj", U, e) * scale[..., None]).reshape(N, 2 * B)
        cost = 0.5 * float(np.sum(self.w * rho))
        J = Jg = gcols = None
        cols = np.arange(state.figure.nv)
        if jacobian:
            slots = state.slot[self.frames]
            A = U.swapaxes(-1, -2) * (scale / length)[..., None, None]  # (N, B, 2, 3)
            kps = np.r_[self.bones[:, 1], self.bones[:, 0]]
            AA = np.concatenate([A, -A], axis=1)
            cols = supported_columns(state.figure, self.keypoints)
            Jp = state.point_jacobians(slots, kps, AA, None, cols)  # (N, 2B, 2, c)
            J = (Jp[:, :B] + Jp[:, B:]).reshape(N, 1, 2 * B, -1)
            if state.has_global_points:
                Gp = state.global_point_jacobians(slots, kps, AA)
                Jg, gcols = (Gp[:, :B] + Gp[:, B:]).reshape(N, 2 * B, -1), state.proportion_cols
        return RowBlock(self.frames[:, None], r, J, cols, self.name, cost_value=cost, Jg=Jg, gcols=gcols,
                        group_cost=0.5 * np.sum(self.w * drho * s, axis=1))


def _normal_basis(d: np.ndarray) -> np.ndarray:
    """(..., 3, 2) two orthonormal vectors normal to each unit vector ``d`` (..., 3), without
    a branch (Duff et al. 2017, "Building an orthonormal basis, revisited")."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    sg = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sg + z)
    b = x * y * a
    out = np.empty(d.shape + (2,))
    out[..., 0, 0], out[..., 1, 0], out[..., 2, 0] = 1.0 + sg * x * x * a, sg * b, -sg * x
    out[..., 0, 1], out[..., 1, 1], out[..., 2, 1] = b, sg + y * y * a, -y
    return out


#: bones whose length the figure keeps over the clip (nearly: the sides cross the spine), for
#: the lifter's proportions (:class:`LiftedLengths`)
LENGTH_BONES = (
    ("left_shoulder", "left_elbow"), ("right_shoulder", "right_elbow"), ("left_elbow", "left_wrist"),
    ("right_elbow", "right_wrist"), ("left_hip", "left_knee"), ("right_hip", "right_knee"), ("left_knee", "left_ankle"),
    ("right_knee", "right_ankle"), ("left_shoulder", "right_shoulder"), ("left_hip", "right_hip"),
    ("left_shoulder", "left_hip"), ("right_shoulder", "right_hip"),
)


class LiftedLengths(RowKind):
    """Rows pulling the figure's proportions to a lifter's: per frame, the figure's log bone
    lengths about their mean over the bones, against the lifter's median (over the clip)
    log lengths about theirs,

        r_tb = sqrt(w) (lambda_tb - mean_b' lambda_tb' - (m_b - mean_b' m_b')),
        lambda_tb = log |p_b - p_a|,  m_b = median_t log |L_tb - L_ta|,

    free of the lifter's size like the direction rows. ``weight`` is the inverse variance of
    one frame's log length, divided by the number of frames (so the clip weighs as one
    measurement of the proportions whatever its length). The derivative: ``d lambda_b =
    d_b^T (dp_b - dp_a) / |p_b - p_a|`` (``d_b`` the unit bone), centred over the bones.

    Parameters
    ----------
    frames : (N,) reconstruction frames.
    bones : (B, 2) figure keypoint indices.
    log_lengths : (B,) the lifter's median log lengths (any units).
    weight : per-frame weight (the whole clip: ``weight * N``).
    """

    name = "lifted_lengths"

    def __init__(self, frames, bones, log_lengths, weight):
        self.frames = np.asarray(frames, dtype=int)
        self.kinematic_frames = self.frames
        self.bones = np.asarray(bones, dtype=int).reshape(-1, 2)
        m = np.asarray(log_lengths, float)
        self.target = m - m.mean()
        self.weight = float(weight)
        self.keypoints = np.unique(self.bones)

    def crop(self, lo: int, hi: int) -> LiftedLengths:
        return crop_aligned(self, lo, hi)

    def log_lengths(self, state: State) -> np.ndarray:
        """(N, B) the figure's log bone lengths at the state."""
        P = state.points[state.slot[self.frames]]
        return np.log(np.maximum(np.linalg.norm(P[:, self.bones[:, 1]] - P[:, self.bones[:, 0]], axis=-1), 1e-12))

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        P = state.points[state.slot[self.frames]]
        v = P[:, self.bones[:, 1]] - P[:, self.bones[:, 0]]
        n = np.maximum(np.linalg.norm(v, axis=-1), 1e-12)
        lam = np.log(n)
        sw = np.sqrt(self.weight)
        r = sw * (lam - lam.mean(axis=1, keepdims=True) - self.target)
        B = r.shape[1]
        J = Jg = gcols = None
        cols = np.arange(state.figure.nv)
        if jacobian:
            C = sw * (np.eye(B) - 1.0 / B)  # the centring over the bones
            A = (v / (n * n)[..., None])[:, :, None, :]  # d lambda / d (p_b - p_a): (N, B, 1, 3)
            kps = np.r_[self.bones[:, 1], self.bones[:, 0]]
            AA = np.concatenate([A, -A], axis=1)
            cols = supported_columns(state.figure, self.keypoints)
            Jp = state.point_jacobians(state.slot[self.frames], kps, AA, None, cols)[:, :, 0]  # (N, 2B, c)
            J = np.einsum("ij,njc->nic", C, Jp[:, :B] + Jp[:, B:])[:, None]
            if state.has_global_points:
                Gp = state.global_point_jacobians(state.slot[self.frames], kps, AA)[:, :, 0]
                Jg, gcols = np.einsum("ij,njc->nic", C, Gp[:, :B] + Gp[:, B:]), state.proportion_cols
        return RowBlock(self.frames[:, None], r, J, cols, self.name, Jg=Jg, gcols=gcols)


def lifted_lengths_row(figure, lifted, frames, sigma: float) -> LiftedLengths | None:
    """The :class:`LiftedLengths` row of a lifted pose (names the figure's) on the
    reconstruction frames ``frames`` (one per lifted frame), with the standard deviation
    ``sigma`` of the clip's log length ratios; ``None`` with fewer than 3 bones observed in
    at least half the frames."""
    pairs, logs = [], []
    for a, b in LENGTH_BONES:
        if a not in lifted.names or b not in lifted.names or a not in figure.keypoint_names:
            continue
        ia, ib = lifted.names.index(a), lifted.names.index(b)
        ok = (lifted.confidence[:, ia] > 0) & (lifted.confidence[:, ib] > 0)
        n = np.linalg.norm(lifted.points[:, ib] - lifted.points[:, ia], axis=-1)
        ok &= np.isfinite(n) & (n > 1e-9)
        if ok.sum() < max(1, len(n) // 2):
            continue
        pairs.append((figure.keypoint_names.index(a), figure.keypoint_names.index(b)))
        logs.append(float(np.median(np.log(n[ok]))))
    if len(pairs) < 3 or not len(frames):
        return None
    return LiftedLengths(frames, pairs, logs, 1.0 / (sigma**2 * len(frames)))


def lifted_rows(figure, views, weights) -> list[LiftedPose]:
    """One :class:`LiftedPose` per view whose tracks carry a lifted pose (``view.tracks.
    lifted``, names already the figure's), on the reconstruction grid (tracks frame ``i`` is
    frame ``i * view.factor``); none when ``weights.lifted`` is 0 or ``None``. ``"camera"``
    lifters are read in the view's camera axes, ``"unknown"`` ones get their rotation
    estimated. The points a lifter's 3D is not taken for (:data:`pinrecon.lifted.UNUSED_CUES`:
    MediaPipe's feet) make no bone."""
    w = getattr(weights, "lifted", None)
    if not w:
        return []
    out = []
    for v in views:
        lifted = getattr(v.tracks, "lifted", None)
        if lifted is None:
            continue
        lifted = lifted.cues()
        pairs = lifted_bones(figure, [n for n in lifted.names if np.any(lifted.confidence[:, lifted.names.index(n)] > 0)])
        if not pairs:
            continue
        ia = [lifted.names.index(a) for a, _ in pairs]
        ib = [lifted.names.index(b) for _, b in pairs]
        vec = lifted.points[:, ib] - lifted.points[:, ia]
        n = np.linalg.norm(vec, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            L = np.where((n > 1e-9)[..., None], vec / n[..., None], np.nan)
        conf = np.minimum(lifted.confidence[:, ia], lifted.confidence[:, ib])
        rows = np.flatnonzero((np.isfinite(L).all(-1) & (conf > 0)).any(axis=1))
        if not len(rows):
            continue
        R = np.asarray(v.camera.R, float).T if lifted.frame == "camera" else None
        bones = np.array([[figure.keypoint_names.index(a), figure.keypoint_names.index(b)] for a, b in pairs])
        sigma_len = getattr(weights, "lifted_lengths", None)
        if sigma_len:
            row = lifted_lengths_row(figure, lifted, rows * v.factor, sigma_len)
            if row is not None:
                out.append(row)
        out.append(LiftedPose(rows * v.factor, bones, L[rows], conf[rows], R, weight=w, loss=weights.lifted_loss,
                              loss_scale=weights.lifted_loss_scale, names=[f"{a}-{b}" for a, b in pairs],
                              view=v.name))
    return out


def disagreement_extras(rows, state: State, n_frames: int, threshold_deg: float = DISAGREEMENT_DEG) -> dict:
    """What the lifted rows say of a solution, as result extras (empty without them):
    ``lifted_disagreement_deg`` (T, B) the angle between each solved bone and the lifter's
    (the largest over views; NaN without a lifted pose), ``lifted_frame_deg`` (T,) its
    per-frame median over the bones, ``lifted_bones`` (B,) their labels,
    ``lifted_rotation`` (V, 3, 3) each view's ``R_world_lifter``, ``lifted_spans`` (S, 4)
    (bone, first frame, frame after the last, largest angle) of the runs over
    ``lifted_threshold_deg``."""
    rows = [r for r in rows if isinstance(r, LiftedPose)]
    if not rows:
        return {}
    names = []
    for r in rows:
        names += [n for n in r.names if n not in names]
    ang = np.full((n_frames, len(names)), np.nan)
    for r in rows:
        a = r.angles_deg(state)
        idx = [names.index(n) for n in r.names]
        cur = ang[np.ix_(r.frames, idx)]
        ang[np.ix_(r.frames, idx)] = np.where(np.isnan(cur) | (a > cur), a, cur)
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            frame = np.nanmedian(ang, axis=1)
    return {
        "lifted_disagreement_deg": ang,
        "lifted_frame_deg": frame,
        "lifted_bones": np.array(names),
        "lifted_rotation": np.stack([r.rotation(state) for r in rows]),
        "lifted_threshold_deg": np.float64(threshold_deg),
        "lifted_spans": disagreement_spans(ang, threshold_deg),
    }


def disagreement_spans(ang: np.ndarray, threshold_deg: float = DISAGREEMENT_DEG) -> np.ndarray:
    """(S, 4) runs of frames where a bone's angle to the lifter's exceeds ``threshold_deg``:
    (bone index, first frame, frame after the last, largest angle in degrees)."""
    out = []
    for b in range(ang.shape[1]):
        over = np.flatnonzero(np.nan_to_num(ang[:, b], nan=0.0) > threshold_deg)
        if not len(over):
            continue
        for run in np.split(over, np.flatnonzero(np.diff(over) > 1) + 1):
            out.append((b, run[0], run[-1] + 1, float(np.nanmax(ang[run, b]))))
    return np.array(out, float).reshape(-1, 4)
