"""The planarity seed: a start trajectory whose limbs are on the right side of each
reflective ambiguity, from 2D tracks alone (plus whatever keyframes there are).

Pipeline (:func:`seed_trajectory`; ``reconstruct(..., seed="planarity")`` calls
:func:`planarity_seed`):

1. **Reference start** - the engine's own start: keyframe poses geodesically
   interpolated and placed on the tracks (or the rest pose placed on the tracks when
   there are no keyframes).  It gives the root depth (perspective) and the keyframe
   poses.
2. **Limb fits** - every unbranched kinematic triple of tracked keypoints
   (hip-knee-ankle, shoulder-elbow-wrist, knee-ankle-toe; see
   :func:`~pinrecon.planarity.calibrate.kinematic_triples`) is fitted with
   :func:`~pinrecon.planarity.fit_planar_group` on *metric image coordinates*
   (orthographic: ``(uv - c) / s``; perspective: weak perspective, ``(uv - c) Z_t / f``
   with the reference root depth ``Z_t``).  Where the whole sequence is not planar its
   planar spans are used.  A fit is kept only if its rod lengths agree with the
   figure's segment lengths (``length_tol``, 10 %): this rejects planar
   interpretations that are geometrically possible but not the figure's.
   Each kept fit (a *unit*) gives, frame by frame and consistently over its frames,
   the depths of the triple's end points relative to its hinge, one member of the
   reflection pair.
3. **Reflections** - each unit's member is chosen by maximising
   ``sum_u s_u E_u + sum_{u<v} s_u s_v C_uv`` over the signs ``s_u``: ``E_u`` is the
   agreement of the unit's depths with the keyframes (reference poses at keyframe
   frames), ``C_uv`` the agreement between units: the correlation of the depths of a
   rod two units share (the shank in the knee and ankle triples, overlapping spans of
   one limb) and the alignment of their plane normals (the legs' and arms' planes are
   near parallel in walking and running).  Without keyframes one global reflection is
   left (the first unit keeps the fit's member).
4. **Fit** - the figure is fitted to the tracks with the engine's own rows
   (measurement, limits, smoothing, posture, keyframes) plus one *relative depth* row
   per lifted rod and frame, ``(z(p_end) - z(p_hinge) - dz) / sigma``
   (:class:`RelativeDepth`), from the reference start, by
   :func:`pinrecon.solver.solve`.  The result is the seed.

:func:`limb_flip_rate` measures what the seed is for: the share of limb segments whose
depth sign is wrong.  :func:`links_report` prints the links and hinges found in tracks
without any figure (``pinrecon links``).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..problem import Weights, make_problem
from ..rows.base import RowBlock, RowKind, State
from ..solver import SolverOptions, solve
from ..starts.rest import rest_start
from ..starts.keyframes import keyframe_start
from ..tracks import Keyframes
from .calibrate import kinematic_triples, model_lengths, track_array
from .fit_types import GroupFit
from .groups import estimate_noise_sigma, fit_planar_group
from .links import discover_links

__all__ = [
    "RelativeDepth",
    "LimbLift",
    "Seed",
    "lift_limbs",
    "seed_trajectory",
    "planarity_seed",
    "default_limbs",
    "limb_flip_rate",
    "links_report",
]


# --------------------------------------------------------------------------
# the relative-depth row kind
# --------------------------------------------------------------------------
class RelativeDepth(RowKind):
    """Rows ``r = (d . (p_b - p_a) - dz) / sigma`` with ``d`` the camera's forward axis
    in world coordinates (camera z; the same for both camera models because the
    translation cancels).  One row group per (frame, pair): ``J = d^T (J_b - J_a) / sigma``.

    Parameters
    ----------
    camera : gives ``R`` (world -> camera).
    frames : (N,) reconstruction frames.
    kp_a, kp_b : (N,) keypoint indices.
    dz_m : (N,) target depth of b minus depth of a, metres.
    sigma_m : (N,) or scalar standard deviation, metres.
    """

    name = "planarity_depth"

    def __init__(self, camera, frames, kp_a, kp_b, dz_m, sigma_m):
        self.d = np.asarray(camera.R, float)[2]
        self.frames = np.asarray(frames, dtype=int)
        self.kinematic_frames = np.unique(self.frames)
        self.kp_a = np.asarray(kp_a, dtype=int)
        self.kp_b = np.asarray(kp_b, dtype=int)
        self.dz = np.asarray(dz_m, float)
        self.inv_sigma = 1.0 / np.broadcast_to(np.asarray(sigma_m, float), self.dz.shape)

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        slots = state.slot[self.frames]
        pa = state.points[slots, self.kp_a]
        pb = state.points[slots, self.kp_b]
        r = (((pb - pa) @ self.d - self.dz) * self.inv_sigma)[:, None]
        J = None
        if jacobian:
            Ja = state.jacobians[slots, self.kp_a]  # (N, 3, nv)
            Jb = state.jacobians[slots, self.kp_b]
            J = (np.einsum("k,nkv->nv", self.d, Jb - Ja) * self.inv_sigma[:, None])[:, None, None, :]
        return RowBlock(self.frames[:, None], r, J, np.arange(state.figure.nv), self.name)


# --------------------------------------------------------------------------
# lifting limbs
# --------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class LimbLift:
    """One planar limb fit (a *unit*) with its chosen reflection.

    triple : (parent, hinge, child) keypoint names.
    span : [start, stop) track frames the fit covers.
    depths_m : (T_obs, 2) depth (camera z, metres) of the parent and of the child
        relative to the hinge, chosen member, NaN outside the fit's frames.
    normal : (3,) plane normal in camera axes of the chosen member.
    sign : +1 if the fit's own (canonical) member was kept, -1 if reflected.
    evidence : keyframe agreement ``E_u`` of the chosen member (>0 agrees).
    lengths_m : (2,) fitted rod lengths; model_lengths_m the figure's.
    fit : the :class:`~pinrecon.planarity.GroupFit` (canonical member).
    """

    triple: tuple[str, str, str]
    span: tuple[int, int]
    depths_m: np.ndarray
    normal: np.ndarray
    sign: int
    evidence: float
    lengths_m: np.ndarray
    model_lengths_m: np.ndarray
    fit: GroupFit

    @property
    def frames(self) -> np.ndarray:
        return np.flatnonzero(np.all(np.isfinite(self.depths_m), axis=1))

    def __repr__(self) -> str:
        a, j, b = self.triple
        return (
            f"LimbLift({a}-[{j}]-{b}, frames [{self.span[0]}, {self.span[1]}), sign {self.sign:+d}, "
            f"evidence {self.evidence:+.2f}, lengths ({self.lengths_m[0]:.3f}, {self.lengths_m[1]:.3f}) m "
            f"vs figure ({self.model_lengths_m[0]:.3f}, {self.model_lengths_m[1]:.3f}), "
            f"tilt {self.fit.tilt_deg:.1f} deg)"
        )


def _camera_scale(camera):
    return float(camera.scale) if hasattr(camera, "scale") else None


def _metric_points(uv: np.ndarray, camera, figure, Q_ref, factor: int, kp_idx) -> np.ndarray:
    """Image points (T, K, 2) in metres at the figure: orthographic ``(uv - c) / s``;
    perspective (weak perspective) ``(uv - c) * Z_t / f`` with ``Z_t`` the camera depth
    of the reference pose's tracked keypoints (their mean) in frame t."""
    s = _camera_scale(camera)
    if s is not None:
        return (uv - camera.center) / s
    K = camera.K
    P = figure.keypoints(Q_ref[np.arange(uv.shape[0]) * factor])[:, kp_idx]
    Z = np.maximum(camera.depth(P).mean(axis=1), 1e-6)
    f = np.array([K[0, 0], K[1, 1]])
    c = K[:2, 2]
    x = (uv - c) / f
    x[..., 0] -= K[0, 1] / K[1, 1] * x[..., 1]  # skew
    return x * Z[:, None, None]


def _fit_units(figure, x_m, names, *, length_tol, sigma, seed, triples=None):
    """Fit the limb triples; return (accepted units, rejected [(triple, reason)])."""
    if triples is None:
        triples = [t for t, limb in kinematic_triples(figure, names) if limb]
    units, rejected = [], []
    pos = {n: i for i, n in enumerate(names)}
    for tri in triples:
        x = x_m[:, [pos[n] for n in tri]]
        f = fit_planar_group(x, hinge=1, sigma=sigma, seed=seed)
        Lm, _ = model_lengths(figure, [(tri[0], tri[1]), (tri[1], tri[2])])
        cands = [f] if (f.planar and f.degeneracy in (None, "plane_parallel_to_image")) else list(f.span_fits)
        if not cands:
            rejected.append((tri, f"not planar ({f.reason})"))
            continue
        for g in cands:
            if not (g.planar and g.degeneracy is None and g.n_frames >= 4):
                rejected.append((tri, f"fit not usable ({g.reason})"))
                continue
            rel = np.abs(g.lengths / Lm - 1.0)
            if np.any(rel > length_tol):
                why = f"rod lengths {np.round(g.lengths, 3)} m differ from the figure's {np.round(Lm, 3)} m"
                rejected.append((tri, why))
                continue
            used = np.flatnonzero(g.used)
            units.append((tri, g, (int(used[0]), int(used[-1]) + 1), Lm))
    return units, rejected


def _canonical(f: GroupFit):
    n = np.asarray(f.normal, float)
    D = np.asarray(f.depths, float)
    if n[2] < 0:  # same plane, same member: only orient the normal with n_z >= 0
        n = -n
    return D, n


def _rod_series(tri, D):
    """{(start, end) name pair sorted: depth of end minus start (T,)} for a unit."""
    a, j, b = tri
    out = {}
    for name, z in ((a, D[:, 0]), (b, D[:, 1])):
        key = (j, name) if j < name else (name, j)
        out[key] = z if key == (j, name) else -z
    return out


def _choose_signs(E: np.ndarray, C: np.ndarray) -> np.ndarray:
    """argmax_s sum s_u E_u + sum_{u<v} s_u s_v C_uv over s in {-1, 1}^U (exhaustive for
    U <= 14, else iterated conditional modes from several starts); s_0 = +1 breaks
    the global reflection when nothing else does."""
    U = len(E)
    if U == 0:
        return np.zeros(0, int)

    def J(s):
        return float(s @ E + 0.5 * s @ C @ s)

    if U <= 14:
        S = np.array(list(itertools.product((1, -1), repeat=U)))
        vals = S @ E + 0.5 * np.einsum("su,uv,sv->s", S, C, S)
        best = np.flatnonzero(vals >= vals.max() - 1e-12 * max(1.0, abs(vals.max())))
        # ties (no keyframe evidence): prefer the one keeping unit 0's own member
        pick = [k for k in best if S[k, 0] == 1]
        return S[pick[0] if pick else best[0]].astype(int)
    starts = [np.ones(U), np.where(E >= 0, 1.0, -1.0)]
    best_s, best_v = None, -np.inf
    for s in starts:
        s = s.copy()
        for _ in range(100):
            changed = False
            for u in range(U):
                field_u = E[u] + C[u] @ s - C[u, u] * s[u]
                new = 1.0 if field_u >= 0 else -1.0
                if new != s[u]:
                    s[u], changed = new, True
            if not changed:
                break
        v = J(s)
        if v > best_v:
            best_s, best_v = s, v
    return best_s.astype(int)


def lift_limbs(
    figure,
    tracks,
    camera,
    keyframes=None,
    *,
    Q_ref: np.ndarray | None = None,
    factor: int = 1,
    length_tol: float = 0.10,
    sigma: float | None = None,
    seed: int | None = 0,
    keyframe_sigma_m: float | None = None,
) -> tuple[list[LimbLift], list]:
    """Fit the figure's planar limbs in ``tracks`` and choose each one's reflection.

    Parameters
    ----------
    figure, tracks, camera : as for :func:`pinrecon.reconstruct` (track names not on the
        figure are ignored).
    keyframes : optional :class:`~pinrecon.Keyframes`; their poses (``Q_ref`` at the
        keyframe frames) decide the reflections where they can.
    Q_ref : (T_out, nq) reference start (default: the engine's start).  Needed for the
        keyframe poses and, with a perspective camera, the root depth.
    factor : reconstruction frames per track frame (``fps_out / fps``).
    length_tol : a fit whose rod lengths differ from the figure's by more than this
        fraction is rejected.
    sigma : image noise for the fits (metric units); None estimates it.
    keyframe_sigma_m : standard deviation of a keyframe depth difference (default
        ``sqrt(2)`` times the keyframes' own sigma).

    Returns
    -------
    (lifts, rejected) : the :class:`LimbLift` units, and ``(triple, reason)`` for the
    triples or spans that were not used.
    """
    names = [n for n in tracks.names if n in figure.keypoint_names]
    if not names:
        raise InputError(
            f"the tracks and the figure share no keypoint name; figure keypoints: {figure.keypoint_names[:60]}",
            field="names",
        )
    uv = track_array(tracks, names)
    kp_idx = figure.keypoint_index(names)
    if Q_ref is None:
        Q_ref = _reference_start(_seed_problem(figure, tracks.select(names), camera, keyframes, factor, None))
    x_m = _metric_points(uv, camera, figure, Q_ref, factor, kp_idx)
    raw, rejected = _fit_units(figure, x_m, names, length_tol=length_tol, sigma=sigma, seed=seed)
    U = len(raw)
    if U == 0:
        return [], rejected
    Ds, ns, rods = [], [], []
    for tri, g, _, _ in raw:
        D, n = _canonical(g)
        Ds.append(D)
        ns.append(n)
        rods.append(_rod_series(tri, D))
    # keyframe evidence
    E = np.zeros(U)
    kf_frames = sorted({int(k.frame) for k in (keyframes or ())})
    if kf_frames:
        ks = keyframe_sigma_m
        if ks is None:
            ks = np.sqrt(2.0) * float(np.median([k.sigma for k in keyframes if k.points is not None] or [0.02]))
        P_kf = figure.keypoints(Q_ref[np.array(kf_frames) * factor])
        z_kf = camera.depth(P_kf)  # (F, K)
        for u, (tri, g, span, Lm) in enumerate(raw):
            a, j, b = figure.keypoint_index(list(tri))
            for fi, f in enumerate(kf_frames):
                if not (0 <= f < Ds[u].shape[0]) or not np.all(np.isfinite(Ds[u][f])):
                    continue
                for k, (end, L) in enumerate(((a, Lm[0]), (b, Lm[1]))):
                    dz_kf = z_kf[fi, end] - z_kf[fi, j]
                    dz = Ds[u][f, k]
                    conf = min(1.0, abs(dz) / (0.1 * L))
                    E[u] += np.clip(dz_kf / ks, -3.0, 3.0) / 3.0 * np.sign(dz) * conf
    # agreement between units
    C = np.zeros((U, U))
    for u, v in itertools.combinations(range(U), 2):
        c = 0.0
        for key in set(rods[u]) & set(rods[v]):
            zu, zv = rods[u][key], rods[v][key]
            ok = np.isfinite(zu) & np.isfinite(zv)
            den = np.sqrt(np.sum(zu[ok] ** 2) * np.sum(zv[ok] ** 2))
            if ok.sum() >= 3 and den > 0:
                c += 2.0 * float(np.sum(zu[ok] * zv[ok]) / den)
        c += float(ns[u][0] * ns[v][0] + ns[u][1] * ns[v][1])
        C[u, v] = C[v, u] = c
    s = _choose_signs(E, C)
    lifts = []
    for u, (tri, g, span, Lm) in enumerate(raw):
        n = ns[u] if s[u] > 0 else ns[u] * np.array([-1.0, -1.0, 1.0])
        lifts.append(
            LimbLift(
                triple=tri,
                span=span,
                depths_m=s[u] * Ds[u],
                normal=n,
                sign=int(s[u]),
                evidence=float(s[u] * E[u]),
                lengths_m=np.asarray(g.lengths, float),
                model_lengths_m=np.asarray(Lm, float),
                fit=g,
            )
        )
    return lifts, rejected


# --------------------------------------------------------------------------
# the seed
# --------------------------------------------------------------------------
def _seed_problem(figure, tracks, camera, keyframes, factor, weights):
    """The engine's problem for these inputs (names already restricted to the figure)."""
    return make_problem(figure, tracks, camera, keyframes, factor=factor, weights=weights, keypoints=tracks.names)


def _reference_start(problem):
    """The engine's own start (what ``reconstruct`` starts from without a seed)."""
    start = keyframe_start if problem.keyframes is not None and len(problem.keyframes) else rest_start
    return problem.figure.clamp(start(problem), margin=1e-3)


@dataclass
class Seed:
    """Result of :func:`seed_trajectory`.

    q : (T_out, nq) the seed trajectory.
    q_reference : (T_out, nq) the engine's own start it was fitted from.
    lifts : the :class:`LimbLift` units used; rejected : ``(triple, reason)``.
    solve : the solver's result of the seeding fit (None if nothing was lifted).
    """

    q: np.ndarray
    q_reference: np.ndarray
    lifts: list
    rejected: list
    solve: object = None
    rows: list = field(default_factory=list)

    def summary(self) -> str:
        lines = [f"planarity seed: {len(self.lifts)} planar limb fits used, {len(self.rejected)} rejected"]
        lines += [f"  {lf!r}" for lf in self.lifts]
        lines += [f"  rejected {'-'.join(t)}: {why}" for t, why in self.rejected]
        if self.solve is not None:
            s = self.solve
            lines.append(f"  seeding fit: {s.status} after {s.iterations} iterations, {s.time:.2f} s")
        return "\n".join(lines)


def seed_trajectory(
    figure,
    tracks,
    camera,
    keyframes=None,
    *,
    factor: int = 1,
    weights=None,
    options=None,
    depth_sigma_m: float = 0.03,
    length_tol: float = 0.10,
    seed: int | None = 0,
) -> Seed:
    """The planarity seed with everything that went into it (see the module docstring).

    Parameters
    ----------
    figure, tracks, camera, keyframes, factor, weights : as :func:`pinrecon.reconstruct`
        receives them (``factor = fps_out / fps``; ``weights`` a
        :class:`~pinrecon.problem.Weights`).
    options : :class:`~pinrecon.solver.SolverOptions` of the seeding fit (default 12
        iterations, ``ftol=1e-3``: it only has to land in the right basin; the batch
        solve refines it).
    depth_sigma_m : standard deviation of a lifted relative depth (floor; a fit with a
        larger residual gets ``3 rms``).
    length_tol : see :func:`lift_limbs`.

    Returns
    -------
    Seed
    """
    weights = weights or Weights()
    if keyframes is not None and not isinstance(keyframes, Keyframes):
        keyframes = Keyframes(list(keyframes))
    names = [n for n in tracks.names if n in figure.keypoint_names]
    if not names:
        raise InputError(
            f"the tracks and the figure share no keypoint name; figure keypoints: {figure.keypoint_names[:60]}",
            field="names",
        )
    sub = tracks.select(names)
    if keyframes is not None:
        keyframes.validate(figure, sub.T)
    problem = _seed_problem(figure, sub, camera, keyframes, factor, weights)
    Q_ref = _reference_start(problem)
    lifts, rejected = lift_limbs(
        figure, sub, camera, keyframes, Q_ref=Q_ref, factor=factor, length_tol=length_tol, seed=seed
    )
    if not lifts:
        return Seed(Q_ref, Q_ref, lifts, rejected)
    frames, ka, kb, dz, sig = [], [], [], [], []
    for lf in lifts:
        a, j, b = figure.keypoint_index(list(lf.triple))
        fr = lf.frames
        s_u = max(depth_sigma_m, 3.0 * float(lf.fit.rms))
        for k, end in enumerate((a, b)):
            frames.append(fr * factor)
            ka.append(np.full(fr.size, j))
            kb.append(np.full(fr.size, end))
            dz.append(lf.depths_m[fr, k])
            sig.append(np.full(fr.size, s_u))
    depth_rows = RelativeDepth(
        camera, np.concatenate(frames), np.concatenate(ka), np.concatenate(kb), np.concatenate(dz), np.concatenate(sig)
    )
    problem = problem.with_rows([depth_rows])
    res = solve(problem, Q_ref, options or SolverOptions(max_iterations=12, ftol=1e-3), active=problem.active)
    Q = figure.normalize(res.x)
    if hasattr(camera, "scale") and figure.floating and keyframes is not None and len(keyframes):
        Q = _depth_gauge(Q, Q_ref, camera, sorted({int(k.frame) * factor for k in keyframes}))
    Q = figure.clamp(Q, margin=1e-3)
    return Seed(Q, Q_ref, lifts, rejected, res, problem.rows)


def _depth_gauge(Q, Q_ref, camera, key_frames):
    """Orthographic views do not see the root's depth: only the keyframes and the
    smoothing prior hold it, so the seeding fit leaves it wherever its iterations
    drifted.  Put it back on the straight line between the keyframes' root depths
    (constant velocity along the line of sight; held constant outside).  Moving the
    whole figure along the line of sight changes no projection and no relative depth."""
    d = np.asarray(camera.R, float)[2]
    T = Q.shape[0]
    kf = np.asarray(key_frames, dtype=int)
    z_key = Q_ref[kf, :3] @ d
    z_want = np.interp(np.arange(T), kf, z_key)
    Q = Q.copy()
    Q[:, :3] += (z_want - Q[:, :3] @ d)[:, None] * d[None, :]
    return Q


def planarity_seed(figure, tracks, camera, keyframes=None, *, factor: int = 1, weights=None, **kwargs) -> np.ndarray:
    """Start trajectory (T_out, nq) for :func:`pinrecon.reconstruct` (``seed="planarity"``).

    Every planar limb's hinge plane and depth sign come from its fit over the tracks,
    consistently over time, with the reflections chosen to agree with the keyframes and
    with each other (one global reflection is left without keyframes).  See
    :func:`seed_trajectory` for the parameters and a result with diagnostics.
    """
    return seed_trajectory(figure, tracks, camera, keyframes, factor=factor, weights=weights, **kwargs).q


# --------------------------------------------------------------------------
# evaluation
# --------------------------------------------------------------------------
def default_limbs(figure, names: Sequence[str] | None = None, min_fraction: float = 0.25) -> list[tuple[str, str]]:
    """The rods of the figure's unbranched limb triples among ``names`` (default: the
    distinct keypoints), without those shorter than ``min_fraction`` of the longest
    (toes, head ends): thigh, shank, foot, upper arm, forearm for a human."""
    names = list(figure.distinct_keypoint_names if names is None else names)
    segs = []
    for (a, j, b), limb in kinematic_triples(figure, names):
        if limb:
            for sg in ((a, j), (j, b)):
                if sg not in segs:
                    segs.append(sg)
    if not segs:
        return []
    L, _ = model_lengths(figure, segs)
    return [sg for sg, l in zip(segs, L) if l >= min_fraction * L.max()]


def limb_flip_rate(
    figure,
    q_est: np.ndarray,
    q_true: np.ndarray,
    camera,
    limbs: Sequence[tuple[str, str]] | None = None,
    *,
    min_fraction: float = 0.1,
    per_limb: bool = False,
):
    """Share of limb segments whose depth sign is wrong.

    For each limb segment (parent keypoint -> child keypoint) and frame, the depth sign
    (camera z of the child minus the parent) of ``q_est`` is compared with ``q_true``;
    only frames where the true ``|depth difference|`` exceeds ``min_fraction`` of the
    segment's true length count.  Returns flipped / counted (NaN if nothing counts), or
    ``(rate, {limb: (flipped, counted)})`` with ``per_limb``.

    ``limbs`` defaults to :func:`default_limbs`.  Both trajectories must have the same
    length; ``q_true`` is evaluated with the same figure.
    """
    q_est, q_true = np.asarray(q_est, float), np.asarray(q_true, float)
    if q_est.shape != q_true.shape:
        raise InputError(f"q_est {q_est.shape} and q_true {q_true.shape} must have the same shape", field="q_est")
    limbs = default_limbs(figure) if limbs is None else [tuple(sg) for sg in limbs]
    if not limbs:
        return (float("nan"), {}) if per_limb else float("nan")
    a = figure.keypoint_index([sg[0] for sg in limbs])
    b = figure.keypoint_index([sg[1] for sg in limbs])
    Pe, Pt = figure.keypoints(q_est), figure.keypoints(q_true)
    dz_e = camera.depth(Pe[:, b]) - camera.depth(Pe[:, a])
    dz_t = camera.depth(Pt[:, b]) - camera.depth(Pt[:, a])
    L = np.linalg.norm(Pt[:, b] - Pt[:, a], axis=-1)
    count = np.abs(dz_t) > min_fraction * L
    flip = count & (np.sign(dz_e) != np.sign(dz_t))
    n = int(count.sum())
    rate = float(flip.sum() / n) if n else float("nan")
    if per_limb:
        return rate, {sg: (int(flip[:, k].sum()), int(count[:, k].sum())) for k, sg in enumerate(limbs)}
    return rate


# --------------------------------------------------------------------------
# links report (pinrecon links TRACKS)
# --------------------------------------------------------------------------
#: image noise (px) above which the planarity test's threshold, which grows with the noise,
#: passes triples of points that are not joined on the body (docs/planarity.md, section 7)
TRUSTED_NOISE_PX = 2.0


def trust_lines(noise_px: float) -> list[str]:
    """What :func:`links_report` says about how far its fits can be trusted: always the
    assumptions, and a NOT TRUSTWORTHY line when the image noise is above
    :data:`TRUSTED_NOISE_PX` (detector output of real footage)."""
    out = []
    if not noise_px <= TRUSTED_NOISE_PX:
        out.append(f"NOT TRUSTWORTHY: image noise ~{noise_px:.3g} px is above {TRUSTED_NOISE_PX:g} px, where the test "
                   "passes many triples of points that are not joined on the body; read the hinges below as "
                   "candidates, not findings")
    out.append("the fits assume a far camera (orthographic) and joints that turn about fixed axes over the clip; a "
               "hinge between points that are not neighbours on the body passed by chance")
    return out


def links_report(
    tracks, *, scale: float | None = None, names: Sequence[str] | None = None, all: bool = False, **kwargs
) -> str:
    """Text report of the rigid links and hinges found in 2D tracks, no figure needed.

    Runs :func:`~pinrecon.planarity.discover_links` on the tracked points ``names``
    (default: all).  For each point it prints the passing hinged triple *with the
    shortest rods* that has the point as its hinge (end -[hinge]- end, both rod
    lengths, plane normal in camera axes x right / y down / z forward, tilt from the
    image plane, fit score rms/threshold), then each point's shortest passing link.
    Short arcs of real motion make many long "rods" pass (docs/planarity.md, section 7):
    a real limb joins near neighbours, so the shortest passing rods are the ones to
    read; ``all=True`` lists every triple and link instead.  With ``scale`` (pixels per
    metre, orthographic) lengths are also given in metres.  ``kwargs`` go to
    :func:`discover_links` (``sigma``, ``model_tol``, ``max_triples``...).
    """
    names = list(tracks.names if names is None else names)
    x = track_array(tracks, names)
    if scale is not None and not (np.isfinite(float(scale)) and float(scale) > 0):
        raise InputError(f"must be a positive number (pixels per metre), got {scale!r}", field="scale")
    g = discover_links(x, names=names, **kwargs)
    sig = estimate_noise_sigma(x)

    def length(v):
        return f"{v:.2f} px" + (f" ({v / float(scale):.3f} m)" if scale else "")

    def normal(f):
        n = f.normal
        return f"({n[0]:+.3f}, {n[1]:+.3f}, {n[2]:+.3f})" if np.all(np.isfinite(n)) else "undetermined"

    triples = sorted(g.triples, key=lambda t: (max(t.lengths), t.fit.score))
    links = sorted(g.links, key=lambda ln: (ln.length, ln.fit.score))
    if not all:
        seen: set[int] = set()
        shown = []
        for tr in triples:
            if tr.hinge not in seen:
                seen.add(tr.hinge)
                shown.append(tr)
        triples = sorted(shown, key=lambda t: t.fit.score)
        seen, shown = set(), []
        for ln in links:
            i, j = ln.points
            if i not in seen or j not in seen:
                seen.update((i, j))
                shown.append(ln)
        links = shown
    lines = [
        f"{len(names)} points, {tracks.T} frames at {tracks.fps:g} fps; image noise ~{sig:.3g} px"
        + (f"; scale {float(scale):g} px/m" if scale else ""),
        *trust_lines(sig),
        f"{len(g.triples)} hinged triples and {len(g.links)} links pass the planarity test"
        + ("" if all else " (shown: per hinge the triple with the shortest rods; per point its shortest link)"),
        "normals: camera axes (x right, y down, z forward), one member of the reflection pair; "
        "score = fit rms / threshold (<= 1 passes)",
        "",
        "hinges:",
    ]
    for tr in triples:
        i, h, k = (names[p] for p in tr.points)
        lines.append(
            f"  {i} -[{h}]- {k}: |{h}-{i}| {length(tr.lengths[0])}, |{h}-{k}| {length(tr.lengths[1])}, "
            f"normal {normal(tr.fit)}, tilt {tr.fit.tilt_deg:.1f} deg, score {tr.fit.score:.2f}"
            + (" [rigid triangle]" if tr.rigid_triangle else "")
        )
    if not triples:
        lines.append("  (none)")
    lines += ["", "links:"]
    for ln in links:
        i, j = (names[p] for p in ln.points)
        lines.append(
            f"  {i} -- {j}: {length(ln.length)}, normal {normal(ln.fit)}, tilt {ln.fit.tilt_deg:.1f} deg, "
            f"score {ln.fit.score:.2f}"
        )
    if not links:
        lines.append("  (none)")
    return "\n".join(lines)
