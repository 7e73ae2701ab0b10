"""The multi-hypothesis start: every limb's depth reflections enumerated, scored with the
MAP terms that tell them apart, and a consistent path chosen over time.

DiFranco, Cham & Rehg (section 3) note that a kinematic model restricted to 2D data has
isolated candidate solutions, one per combination of reflections of its links, and name
a multiple-hypothesis smoother as the way past keyframes ("future work"). This start is
that smoother, made tractable by the figure's structure (geometry in :mod:`.limbs`):

1. **Base.** The problem solved briefly (``base_options``) from the engine's own start
   (keyframe poses, or the rest pose placed on the tracks). Its trunk has a reflection of
   its own: hips and shoulders are nearly planar, and a planar quadrilateral has two
   poses with one image (the Necker reversal; perspective and the trunk's bend break the
   tie only weakly). The trunk-flipped base (:func:`~.limbs.torso_flip`, solved as
   briefly) is a second base.
2. **Hypotheses.** The tracks are cleaned (isolated outliers and swapped labels removed
   by a running median, gaps filled, noise smoothed: :func:`~.limbs.clean_tracks`). Every
   limb chain (hip-knee-ankle, shoulder-elbow-wrist, then knee-ankle-toe pieces where
   tracked: :func:`~.limbs.limb_chains`) has, in every frame, two positions for each
   segment's end on its camera ray at the segment's length from its start (the
   sphere-ray intersections: the depth reflection, exact under perspective; the length is
   the 99th percentile of the segment's projected length, which is its true length
   whenever it crosses the image plane). Two segments give four states. Each state's
   directions, with the figure's own lengths, are turned into a pose by a batch inverse
   kinematics (3D targets, joint limits, posture prior; all frames and limbs at once, one
   solve per state; a state a frame did not reach is solved again from its neighbours'
   and the other states' poses).
3. **Scores.** A state's cost in a frame is what the MAP terms say of its pose: the joint
   limits it has to violate (knees and elbows bend one way), how far it has to stay from
   its ray to respect them (across the ray as reprojection at ``weights.sigma_px``, along
   it at ``sigma_pull_m``), the posture prior and, where a 3D keyframe is given, the
   keyframe, and the lifted-pose rows (:mod:`pinrecon.rows.lifted`) of the
   chain's bones. The posture prior scores ``0.5 |r|^2`` of its rows: for the generic human's
   robust prior those are reweighted, ``0.5 m^2 / (1 + m^2 / k^2)`` at a Mahalanobis
   distance ``m`` under the Cauchy loss, bounded by ``k^2 / 2``: a pose unlike the
   prior's clips is not ranked against another unlike them (scored with the loss itself,
   the bench_real dance was 7 mm worse on the mean of four runs). Between frames, the
   smoothing prior: changing a segment's reflection from one frame to the next costs its
   depth jump (measured from the local minimum of its depth, so free where the segment
   crosses the image plane, dear elsewhere).
4. **Path.** Dynamic programming over frames (sub-sampled to ``rate_hz``) picks the
   cheapest path per limb; forward and backward passes give every state's min-marginal
   cost. The limb's joints follow the chosen states' poses (interpolated in between).
   With ``acc_weight`` the path also pays each segment's depth acceleration over three
   frames, so a limb bouncing off the image plane costs what the smoothing prior charges
   (second-order dynamic programming, :mod:`.paths`; off by default, measured mixed).
5. **Splice.** The trunk's reflection may change within a clip (a turn, a pirouette: the
   trunk passes edge-on to the camera, where both reflections look alike). The two
   solved trunk candidates are spliced per frame (:func:`splice_path`): dynamic
   programming over each frame's share of their MAP cost, a switch costing the distance
   between their keypoints there (so it happens where they nearly coincide).
6. **Choice.** Every candidate (limbs on the base, limbs on the flipped trunk, their
   splice, the base alone unless ``guard_base=False``, and with keyframes the planarity
   seed) is solved ``final_options`` long with the whole problem; the lowest MAP cost is the
   start.
7. **Turns.** Where the chosen start's root turns fast (a pirouette), it is wound a whole
   turn either way and kept where the MAP cost falls (:mod:`.turns`): a turn taken the
   wrong way round, or a spurious one, is the trunk's own discrete ambiguity over time.

Measured in ``bench/bench_real.py`` (README there).

**Report.** Per limb and *span* (a run of frames with one chosen state), the cost gap
between the two best hypotheses: the cost of the best path that holds the whole span in
another state (the rest free) minus the best path's (:func:`span_gaps`), in nats
(whitened squared residuals / 2, the solver's cost units); per frame, the gap between
the best and second-best min-marginal. A small gap means the data, limits and prior barely prefer the
chosen reflection there: that is where a keyframe helps. :func:`hypotheses_start` leaves
the :class:`HypothesisReport` in ``problem.reports["hypotheses"]``; the pipeline puts
:meth:`HypothesisReport.to_extras` in ``Result.extras`` and the summary names the
uncertain spans.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import minimum_filter1d

from ..problem import ReconstructionProblem, posture_row, rest_pose
from ..processes import Beside, forkable
from ..rows import JointLimits, Points3D, Posture, State
from ..rows.lifted import LiftedPose
from ..solver import SolverOptions, solve
from .keyframes import keyframe_start
from .limbs import (
    camera_rays,
    clean_tracks,
    image_lengths,
    limb_chains,
    ray_point_at_depth,
    sphere_ray,
    torso_flip,
    trunk_keypoints,
)
from .paths import min_sum_path, span_gaps
from .rest import rest_start
from .turns import turns_array, wind_turns

__all__ = ["BASE_OPTIONS", "UNCERTAIN_GAP", "HypothesisReport", "Span", "base_solve", "frame_costs", "hypotheses_start",
           "min_sum_path", "search_hypotheses", "span_gaps", "splice_path"]

#: spans whose cost gap is below this many nats (a likelihood ratio under e^2 = 7.4) are
#: reported as uncertain; on the detector-like walk of bench_real 12 of 14 spans above it
#: had their limb on the right side in most frames, against 13 of 29 below it
UNCERTAIN_GAP = 2.0

#: the base's brief solve (step 1 of the module docstring)
BASE_OPTIONS = SolverOptions(max_iterations=30, ftol=1e-3)


# ----------------------------------------------------------------------------- report
@dataclass(frozen=True)
class Span:
    """A run of frames [start, stop) (reconstruction frames) over which limb ``chain``
    keeps one state; ``gap`` the cost (nats) of the best other hypothesis there."""

    chain: str
    start: int
    stop: int
    state: int
    gap: float


@dataclass
class HypothesisReport:
    """What the multi-hypothesis search chose and how sure it is.

    chains : the limb labels ("left_hip-left_knee-left_ankle" ...).
    states : (T, n_chains) chosen state per frame (bit k set: segment k's end on the far
        side of its start; -1 for frames not decided).
    gaps : (T, n_chains) per-frame cost gap (nats) between the two best hypotheses.
    spans : the :class:`Span` list.
    fps, factor : the reconstruction grid (frame / fps = seconds; tracks frame = frame / factor).
    threshold : spans with ``gap`` below it are uncertain.
    """

    chains: list[str]
    states: np.ndarray
    gaps: np.ndarray
    spans: list[Span] = field(default_factory=list)
    fps: float = 1.0
    factor: int = 1
    threshold: float = UNCERTAIN_GAP
    q_base: np.ndarray | None = None
    torso_gap: float = float("nan")
    torso_flipped: bool = False
    cost: float = float("nan")
    alternatives: dict = field(default_factory=dict)
    kept_base: bool = False
    chosen: str = "limbs"
    trunk_switches: list = field(default_factory=list)
    turns: list = field(default_factory=list)  # the fast turns tried (pinrecon.starts.turns.Turn)

    def uncertain_spans(self) -> list[Span]:
        return [s for s in self.spans if s.gap < self.threshold]

    def to_extras(self) -> dict:
        """Arrays for ``Result.extras`` (saved in the result NPZ)."""
        idx = {c: i for i, c in enumerate(self.chains)}
        arr = np.array([[idx[s.chain], s.start, s.stop, s.state, s.gap] for s in self.spans], float).reshape(-1, 5)
        return {
            "hypothesis_chains": np.array(self.chains, dtype=str),
            "hypothesis_spans": arr,
            "hypothesis_gaps": self.gaps,
            "hypothesis_threshold": np.float64(self.threshold),
            "hypothesis_chosen": np.array(self.chosen),
            "hypothesis_turns": turns_array(self.turns),
        }


# ----------------------------------------------------------------------------- search
def base_solve(problem, options: SolverOptions | None = None) -> np.ndarray:
    """The search's base before it is normalised (``search_hypotheses(problem, base=...)``
    takes it): the problem solved briefly (``options``, by default :data:`BASE_OPTIONS`) from
    the engine's own start, the keyframes' poses or the rest pose placed on the tracks."""
    kf = problem.keyframes is not None and len(problem.keyframes)
    Q = keyframe_start(problem) if kf else rest_start(problem)
    Q = problem.figure.clamp(Q, margin=1e-3)
    return solve(problem, Q, options or BASE_OPTIONS, active=problem.active).x


def _base_trajectory(problem, options):
    return problem.figure.normalize(base_solve(problem, options))


def _state_bits(n_seg):
    return np.array([[(h >> k) & 1 for k in range(n_seg)] for h in range(2 ** n_seg)], bool)


def _directions(chains, roots, uv, camera, lengths):
    """Unit segment directions (F, H, S, 3) of every state of every chain (list): the
    sphere-ray points of each segment's end from its start, the chain starting at
    ``roots[i]`` (F, 3)."""
    out = []
    for c, p0, L in zip(chains, roots, lengths):
        o, d = camera_rays(camera, uv[:, c.kp])  # (F, S+1, 3)
        F, H = len(p0), c.n_states
        pts = np.empty((F, H, c.n_segments + 1, 3))
        pts[:, :, 0] = p0[:, None]
        bits = _state_bits(c.n_segments)
        for k in range(c.n_segments):
            near, far, _ = sphere_ray(pts[:, :, k], o[:, None, k + 1], d[:, None, k + 1], L[k])
            pts[:, :, k + 1] = np.where(bits[None, :, k, None], far, near)
        seg = np.diff(pts, axis=2)
        out.append(seg / np.maximum(np.linalg.norm(seg, axis=-1, keepdims=True), 1e-12))
    return out


def _keyframe_targets(problem, T):
    """(T, K, 3) 3D point keyframes on the reconstruction grid (NaN elsewhere), sigma (T,)."""
    fig = problem.figure
    P = np.full((T, fig.K, 3), np.nan)
    sig = np.full(T, np.inf)
    for k in problem.keyframes or ():
        if k.points is None:
            continue
        f = int(k.frame) * problem.factor
        for n, x in k.points.items():
            P[f, fig.keypoint_index([n])[0]] = x
        sig[f] = min(sig[f], float(k.sigma))
    return P, sig


@dataclass
class _Scores:
    Q: list  # per state: (F, nq) IK poses at the scored frames
    unary: list  # per chain: (F, H)
    dirs: list  # per chain: (F, H, S, 3) segment directions of the IK poses


def _chain_targets(chains, D, P_root, h):
    """(F, M, 3) IK targets of state ``h`` (each chain's own ``h mod n_states``): the
    chain rebuilt from its start with the figure's lengths along the state's directions."""
    tg = []
    for c, Dc, p0 in zip(chains, D, P_root):
        hh = h % c.n_states
        p = p0
        for k in range(c.n_segments):
            p = p + c.lengths_m[k] * Dc[:, hh, k]
            tg.append(p)
    return np.stack(tg, axis=1)


def _ik(fig, Q_start, kps, targets, active, w, sigma_pull_m, options):
    """Batch inverse kinematics, every frame on its own: 3D targets, limits, posture."""
    F = len(Q_start)
    rows = [Points3D(np.arange(F), kps, targets, sigma_pull_m, name="hypothesis"),
            JointLimits(fig, F, w.sigma_limits), _posture(fig, F, w, active)]
    return fig.normalize(solve(ReconstructionProblem(fig, F, rows), Q_start, options, active=active).x)


def _posture(fig, F, w, active):
    """The problem's posture prior (the generic human's pose prior), else a weak rest pose."""
    return posture_row(fig, F, w, active) or Posture(fig, F, rest_pose(fig), 3.0, active)


def _misfit(fig, Q, chains, kps, targets):
    """(F, n_chains) distance (m) of the chains' ends from their targets."""
    P = fig.keypoints(Q)[:, kps]
    d = np.linalg.norm(P - targets, axis=-1)
    out, col = [], 0
    for c in chains:
        out.append(d[:, col : col + c.n_segments].sum(1))
        col += c.n_segments
    return np.stack(out, 1)


def _score_states(problem, chains, frames, Q_base, D, options, sigma_pull_m, sigma_lat_m, retries=2, reach_m=0.02):
    """IK every state of the chains at ``frames`` (one batch solve per state, all chains
    at once) and score each frame. A state a frame's IK did not reach (ends farther than
    ``reach_m`` from the targets) is solved again from the closest of its solutions at
    neighbouring frames and the other states' solutions at that frame (``retries``
    rounds): a pose far from the base is often only reachable from a nearby pose."""
    fig, w = problem.figure, problem.weights
    F = len(frames)
    Qb = Q_base[frames]
    H = max(c.n_states for c in chains)
    active = np.zeros(fig.nv, bool)
    for c in chains:
        active |= c.v_mask
    kps = np.concatenate([c.kp[1:] for c in chains])
    P_root = [fig.keypoints(Qb)[:, c.kp[0]] for c in chains]
    tgs = [_chain_targets(chains, D, P_root, h) for h in range(H)]
    qidx = [_q_of(fig, c.v_mask) for c in chains]
    Qs = [_ik(fig, Qb, kps, tgs[h], active, w, sigma_pull_m, options) for h in range(H)]
    mis = [_misfit(fig, Qs[h], chains, kps, tgs[h]) for h in range(H)]
    for _ in range(retries):
        changed = False
        for h in range(H):
            bad = mis[h] > reach_m  # (F, n_chains)
            rows = np.flatnonzero(bad.any(1))
            if not len(rows):
                continue
            start = Qs[h][rows].copy()
            best = mis[h][rows].copy()
            # candidates: other states at the same frame, this state at the nearest reached frames
            cands = [Qs[g][rows] for g in range(H) if g != h]
            for ci in range(len(chains)):
                ok = np.flatnonzero(~bad[:, ci])
                if len(ok):
                    near = ok[np.argmin(np.abs(ok[None, :] - rows[:, None]), axis=1)]
                    cands.append(np.where(np.isin(np.arange(fig.nq), qidx[ci])[None], Qs[h][near], Qs[h][rows]))
            for Qc in cands:
                m = _misfit(fig, Qc, chains, kps, tgs[h][rows])
                for ci in range(len(chains)):
                    take = m[:, ci] < best[:, ci]
                    start[np.ix_(take, qidx[ci])] = Qc[np.ix_(take, qidx[ci])]
                    best[take, ci] = m[take, ci]
            Qn = _ik(fig, start, kps, tgs[h][rows], active, w, sigma_pull_m, options)
            mn = _misfit(fig, Qn, chains, kps, tgs[h][rows])
            for ci in range(len(chains)):
                take = mn[:, ci] < mis[h][rows, ci] - 1e-6
                if take.any():
                    changed = True
                    Qs[h][np.ix_(rows[take], qidx[ci])] = Qn[np.ix_(take, qidx[ci])]
                    mis[h][rows[take], ci] = mn[take, ci]
        if not changed:
            break
    K_kf, sig_kf = _keyframe_targets(problem, len(Q_base))
    K_kf, sig_kf = K_kf[frames], sig_kf[frames]
    fwd = np.asarray(problem.camera.R, float)[2]
    limits = JointLimits(fig, F, w.sigma_limits)
    posture = _posture(fig, F, w, active)
    no_frames = np.zeros(0, int)  # the posture row reads Q only
    # a lifter's bone directions (rows.lifted), the rotation to its axes read at the base
    lifted = [r for r in problem.rows if isinstance(r, LiftedPose)]
    base = problem.state(Q_base, jacobian=False) if lifted else None
    lifted = [(r, r.rotation(base)) for r in lifted]
    unary = [np.zeros((F, c.n_states)) for c in chains]
    dirs = [np.zeros((F, c.n_states, c.n_segments, 3)) for c in chains]
    for h in range(H):
        Q = Qs[h]
        P = fig.keypoints(Q)
        st = ReconstructionProblem(fig, F, [limits, posture]).state(Q, jacobian=False)
        r_lim = limits.evaluate(st, False).r
        col = 0
        for ci, c in enumerate(chains):
            M = c.n_segments
            if h >= c.n_states:
                col += M
                continue
            miss = P[:, c.kp[1:]] - tgs[h][:, col : col + M]
            depth = miss @ fwd
            lat = miss - depth[..., None] * fwd
            cost = 0.5 * (np.sum(lat ** 2, axis=(1, 2)) / sigma_lat_m ** 2 + np.sum(depth ** 2, axis=1) / sigma_pull_m ** 2)
            cost += 0.5 * np.sum(r_lim[:, c.v_mask[limits.cols]] ** 2, axis=1)
            # the posture prior of this chain's state with the other chains at the base: the
            # generic human's prior couples joints, so its cost is not a sum over chains
            Qm = Qb.copy()
            Qm[:, qidx[ci]] = Q[:, qidx[ci]]
            cost += 0.5 * np.sum(posture.evaluate(State(fig, Qm, no_frames, False), False).r ** 2, axis=1)
            kf_rel = K_kf[:, c.kp[1:]] - K_kf[:, c.kp[:1]]
            e = np.where(np.isfinite(kf_rel), P[:, c.kp[1:]] - P[:, c.kp[:1]] - np.nan_to_num(kf_rel), 0.0)
            has = np.isfinite(sig_kf)
            cost[has] += 0.5 * np.sum(e[has] ** 2, axis=(1, 2)) / sig_kf[has] ** 2
            for row, R in lifted:
                cost += row.bone_costs(P, frames, R)[:, np.isin(row.bones, c.kp).all(axis=1)].sum(axis=1)
            unary[ci][:, h] = cost
            seg = np.diff(P[:, c.kp], axis=1)
            dirs[ci][:, h] = seg / np.maximum(np.linalg.norm(seg, axis=-1, keepdims=True), 1e-12)
            col += M
    return _Scores(Qs, unary, dirs)


def _depth_acceleration(z, lengths, dt, sigma):
    """(N-2, H, H, H) the smoothing prior's cost of three consecutive states of a chain
    from its segments' signed depths ``z`` (N, H, S), metres: the depth acceleration of
    each segment's end against ``sigma`` (rad/s^2) times its length, integrated over ``dt``."""
    d2 = z[:-2, :, None, None] - 2.0 * z[1:-1, None, :, None] + z[2:, None, None, :]
    return 0.5 * np.sum((d2 / (dt * dt * sigma * np.asarray(lengths))) ** 2, axis=-1) * dt


def _limb_search(problem, Q_base, uv, passes, sub_frames, step, switch_sigma, ik_options, sigma_pull_m, acc_weight=0.0):
    """The limb hypotheses on one base trajectory: returns (Q, labels, states, gaps, spans)."""
    fig, cam = problem.figure, problem.camera
    fps = float(problem.fps or 30.0)
    T = len(Q_base)
    t_all = np.arange(T)
    window = max(1, int(round(0.15 * fps / step)))
    Q = Q_base.copy()
    labels, all_states, all_gaps, spans = [], [], [], []
    for chains in passes:
        P_cur = fig.keypoints(Q)
        z = cam.depth(P_cur)
        roots, lengths = [], []
        for c in chains:
            roots.append(ray_point_at_depth(cam, uv[sub_frames, c.kp[0]], z[sub_frames, c.kp[0]]))
            d_proj = image_lengths(cam, uv, z, c.kp)  # (T, S) projected lengths, metres
            lengths.append(np.clip(np.percentile(d_proj, 99, axis=0), 0.6 * c.lengths_m, 1.5 * c.lengths_m))
        D = _directions(chains, roots, uv[sub_frames], cam, lengths)
        sc = _score_states(problem, chains, sub_frames, Q, D, ik_options, sigma_pull_m, _lateral_sigma_m(problem, P_cur))
        for ci, c in enumerate(chains):
            U = sc.unary[ci] * step
            N, H = U.shape
            # switching a segment's reflection between frames costs its depth jump: free
            # where the two reflections meet (the segment crosses the image plane)
            half = np.abs(np.einsum("nhsk,k->nhs", D[ci], cam.R[2])) * lengths[ci]  # (N, H, S) |dz| per state
            # measured from its local minimum: a length error keeps the reflections from
            # meeting at a crossing, but the crossing is still where |dz| is smallest
            half = half - minimum_filter1d(half, size=2 * window + 1, axis=0, mode="nearest")
            bits = _state_bits(c.n_segments)
            flip = bits[:, None, :] != bits[None, :, :]  # (H, H, S)
            jump = np.minimum(half[:-1, :, None, :], half[1:, None, :, :])  # (N-1, H, H, S)
            trans = 0.5 * np.sum(flip[None] * (jump / (switch_sigma * lengths[ci])) ** 2, axis=-1)
            acc = None
            if acc_weight > 0:
                acc = acc_weight * _depth_acceleration(np.where(bits[None], half, -half), lengths[ci], step / fps,
                                                       problem.weights.acc_joints)
            path, marg = min_sum_path(U, trans, acc)
            chosen = np.take_along_axis(marg, path[:, None], axis=1)[:, 0]
            other = np.where(np.arange(H)[None, :] == path[:, None], np.inf, marg).min(axis=1)
            frame_of = np.append(sub_frames, T)
            qi = _q_of(fig, c.v_mask)
            Qc = _continuous(fig, qi, np.stack([sc.Q[path[i]][i, qi] for i in range(N)]))  # (N, n) chosen values
            for k, iq in enumerate(qi):
                Q[:, iq] = np.interp(t_all, sub_frames, Qc[:, k])
            nearest = np.clip(np.searchsorted(sub_frames, t_all - 0.5 * step), 0, N - 1)
            states = path[nearest]
            gaps = np.interp(t_all, sub_frames, other - chosen)
            labels.append(c.label)
            all_states.append(states)
            all_gaps.append(gaps)
            spans += [Span(c.label, int(frame_of[a]), int(frame_of[b]) if b < N else T, h, g)
                      for a, b, h, g in span_gaps(U, trans, path, acc)]
    return fig.clamp(Q, margin=1e-3), labels, all_states, all_gaps, spans


def search_hypotheses(
    problem: ReconstructionProblem,
    *,
    base: np.ndarray | None = None,
    base_options: SolverOptions | None = None,
    ik_options: SolverOptions | None = None,
    final_options: SolverOptions | None = None,
    rate_hz: float = 30.0,
    switch_sigma: float = 0.25,
    sigma_pull_m: float = 0.05,
    torso: bool = True,
    planarity: bool = True,
    threshold: float = UNCERTAIN_GAP,
    splice_sigma_m: float = 0.05,
    acc_weight: float = 0.0,
    turns: bool = True,
    guard_base: bool = True,
) -> tuple[np.ndarray, HypothesisReport]:
    """The multi-hypothesis start and its report (see the module docstring).

    Parameters
    ----------
    problem : a :class:`ReconstructionProblem` built from 2D tracks (``make_problem``).
    base : the base trajectory (default: the problem solved briefly from the engine's own
        start, ``base_options``: 30 iterations, ``ftol`` 1e-3).
    ik_options : options of the per-state inverse kinematics (15 iterations).
    final_options : the solve that scores each trunk hypothesis with the whole MAP cost
        (40 iterations, ``ftol`` 1e-4); the start is the winner's solution.
    rate_hz : the dynamic programming runs on frames sub-sampled to about this rate.
    switch_sigma : the smoothing between frames: a segment whose reflection changes from
        one frame to the next pays ``0.5 (|dz| / (switch_sigma L))^2``, ``|dz|`` the depth
        of its end from its start (half the jump), ``L`` its length: free where it crosses
        the image plane, dear elsewhere.
    acc_weight : with a positive weight the path also pays, times it, the smoothing prior's
        cost of each segment's depth *acceleration* over three sub-sampled frames
        (``weights.acc_joints`` times the segment's length as its standard deviation): a
        limb that bounces off the image plane instead of crossing it pays for the kink
        (second-order dynamic programming, :mod:`.paths`). Off by default: on bench_real
        (weight 1) it changed the walk and the run with first and last keyframes by under
        0.1 mm, the run without keyframes from 28.8 / 5.5 to 31.2 / 6.1 (PA-MPJPE mm /
        flips %, mean of 45 and 60 degrees), the dance by -16 to +10 mm on three runs (within
        its run-to-run spread); on the lab run it found a MAP cost 25 nats *below* the solve
        started from the truth, with 22 % of the limb segments flipped (bench/README.md).
    sigma_pull_m : how hard the inverse kinematics holds a state's depth (metres).
    torso : also try the trunk's reflection (:func:`~pinrecon.starts.limbs.torso_flip`).
    planarity : with keyframes, the planarity seed (:mod:`pinrecon.planarity.seed`) competes
        too. Every candidate (limbs on the base, limbs on the flipped trunk, the base alone,
        the planarity seed) is solved ``final_options`` long and the lowest MAP cost wins
        (``report.chosen``, ``report.alternatives``).
    threshold : spans with a smaller cost gap (nats) are reported uncertain.
    turns : the chosen start wound through its fast turns (:func:`~pinrecon.starts.turns.
        wind_turns`: a whole turn more or less about the body's up axis where the root turns
        faster than 300 degrees per second, kept when the MAP cost falls; ``report.turns``).
    guard_base : the base alone competes, solved as long as the candidates; False: it does not
        (the solve stage's choice where pinrecon's lifter joined from the start, bench/README.md).
    splice_sigma_m : the splice's switch between the trunk candidates at frame t costs
        ``0.5 sum_k |p_k^A(t) - p_k^B(t)|^2 / splice_sigma_m^2`` (0: no splice). The
        spliced candidate's frames from the flipped trunk are ``report.trunk_switches``
        apart when it wins.

    Returns
    -------
    (Q0 (T, nq), :class:`HypothesisReport`)
    """
    fig, cam = problem.figure, problem.camera
    T = problem.n_frames
    base_options = base_options or BASE_OPTIONS
    ik_options = ik_options or SolverOptions(max_iterations=15, ftol=1e-4)
    final_options = final_options or SolverOptions(max_iterations=40, ftol=1e-4)
    Q_base = _base_trajectory(problem, base_options) if base is None else fig.normalize(np.asarray(base, float))
    names = list(problem.tracks.names) if problem.tracks is not None else []
    passes = limb_chains(fig, names) if names else []
    fps = float(problem.fps or 30.0)
    if not passes or cam is None:
        return Q_base, HypothesisReport([], np.zeros((T, 0), int), np.zeros((T, 0)), [], fps, problem.factor,
                                        threshold, Q_base)
    step = max(1, int(round(fps / rate_hz)))
    sub_frames = np.arange(0, T, step)
    if sub_frames[-1] != T - 1:
        sub_frames = np.append(sub_frames, T - 1)
    uv = clean_tracks(problem, Q_base)
    trunk = trunk_keypoints(fig, names, passes)

    # candidates are compared with the global unknowns (calibration) held at their start:
    # freed, they fit a wrong reflection as well as the right one (bench_real: the walk's
    # flips with first and last keyframes went from 31 to 47 %)
    def candidate(Qb, name: str, flip: bool = False):
        """The limbs searched on the base ``Qb`` (``flip``: its trunk reflected and solved
        first), then the whole MAP solved from them: ``(cost, Q, labels, states, gaps, spans,
        base, name)``."""
        if flip:
            Qb = fig.normalize(solve(problem, fig.clamp(torso_flip(fig, Qb, cam, trunk), 1e-3), base_options,
                                     active=problem.active).x)
        Q0, labels, states, gaps, spans = _limb_search(problem, Qb, uv, passes, sub_frames, step, switch_sigma,
                                                       ik_options, sigma_pull_m, acc_weight)
        res = solve(problem, Q0, final_options, active=problem.active)
        return res.cost, fig.normalize(res.x), labels, states, gaps, spans, Qb, name

    def solved_long(Qs):
        return solve(problem, fig.clamp(Qs, 1e-3), final_options, active=problem.active)

    flipped = None
    if torso and fig.floating and len(trunk) >= 3:  # the flipped trunk's search in a child meanwhile, where it may
        flipped = Beside(candidate, Q_base, "trunk flipped", True, fork=forkable(T))
    try:
        results = [candidate(Q_base, "limbs")]
        base_long = solved_long(Q_base) if guard_base else None  # made here while the child searches
        results += [flipped.result()] if flipped is not None else []
    finally:
        if flipped is not None:
            flipped.cancel()
    switches = []
    if len(results) == 2 and splice_sigma_m > 0:
        QA, QB = results[0][1], results[1][1]
        path = splice_path(frame_costs(problem, QA), frame_costs(problem, QB), problem.keypoints(QA),
                           problem.keypoints(QB), splice_sigma_m)
        if 0 < path.sum() < T:
            res = solve(problem, fig.clamp(np.where(path[:, None] == 1, QB, QA), 1e-3), final_options,
                        active=problem.active)
            k = 0 if results[0][0] <= results[1][0] else 1  # the limbs' report of the better trunk
            results.append((res.cost, fig.normalize(res.x), *results[k][2:7], "trunk spliced"))
            switches = (np.flatnonzero(np.diff(path)) + 1).tolist()
    order = np.argsort([r[0] for r in results])
    cost, Q, labels, states, gaps, spans, Qb, won = results[order[0]]
    report = HypothesisReport(labels, np.stack(states, 1), np.stack(gaps, 1), spans, fps, problem.factor,
                              threshold, Qb)
    if len(results) > 1:
        report.torso_gap = float(results[order[1]][0] - cost)
        report.torso_flipped = won == "trunk flipped"
        report.trunk_switches = switches if won == "trunk spliced" else []
    # the search only proposes starts: it must not lose to the base solved as long (guard_base), nor,
    # with keyframes, to the planarity seed (which decides whole planar spans from them)
    others = [("base", Q_base)] if guard_base else []
    if planarity and problem.keyframes is not None and len(problem.keyframes):
        seed = _planarity_seed(problem)
        if seed is not None:
            others.append(("planarity", seed))
    report.cost = float(cost)
    for label, Qs in others:
        ref = base_long if label == "base" else solved_long(Qs)
        report.alternatives[label] = float(ref.cost)
        if ref.cost < cost:
            cost, Q, won = ref.cost, fig.normalize(ref.x), label
    report.kept_base = won == "base"
    report.chosen = won
    if turns:
        Q, report.turns = wind_turns(problem, Q, final_options, cost=cost)
    return fig.clamp(Q, margin=1e-3), report


def frame_costs(problem, Q) -> np.ndarray:
    """(T,) each frame's share of ``0.5 |r|^2`` over the problem's rows at ``Q`` (globals at
    their start): a row over s frames gives each 1 / s (robust rows: their reweighted
    residuals)."""
    c = np.zeros(problem.n_frames)
    for b in problem.evaluate(Q, False):
        for blk in b if isinstance(b, (list, tuple)) else [b]:
            if blk is None or not blk.r.size or not blk.frames.size:
                continue
            e = blk.group_cost if blk.group_cost is not None else \
                0.5 * (np.asarray(blk.r).reshape(len(blk.frames), -1) ** 2).sum(1)
            e = e / blk.frames.shape[1]
            for i in range(blk.frames.shape[1]):
                np.add.at(c, blk.frames[:, i], e)
    return c


def splice_path(cost_a, cost_b, P_a, P_b, sigma_m: float) -> np.ndarray:
    """(T,) 0/1 per frame: which of two trajectories to follow, the path of least
    ``sum_t cost[t, h_t]`` plus ``0.5 |P_a(t) - P_b(t)|^2 / sigma_m^2`` (summed over
    keypoints, the mean of frames t and t + 1) at each switch between t and t + 1.
    ``cost_a``, ``cost_b`` (T,) per-frame costs (:func:`frame_costs`), ``P_a``, ``P_b``
    (T, K, 3) keypoints."""
    jump = 0.5 * ((np.asarray(P_a) - np.asarray(P_b)) ** 2).sum(axis=(1, 2)) / sigma_m**2
    trans = np.zeros((len(jump) - 1, 2, 2))
    trans[:, 0, 1] = trans[:, 1, 0] = 0.5 * (jump[:-1] + jump[1:])
    return min_sum_path(np.stack([cost_a, cost_b], 1), trans)[0]


def _planarity_seed(problem):
    """The planarity seed's trajectory when it lifted any limb, else None."""
    from ..planarity.seed import seed_trajectory

    sd = seed_trajectory(problem.figure, problem.tracks, problem.camera, problem.keyframes, factor=problem.factor,
                         weights=problem.weights)
    return sd.q if sd.lifts else None


def _continuous(figure, qi, X):
    """Joint values (N, n) at q indices ``qi`` made continuous over time: each revolute
    angle unwrapped (independent inverse kinematics may land 2 pi apart) and shifted by
    2 pi where that brings it inside its limits."""
    X = np.unwrap(X, axis=0)
    m = figure.model
    lo = np.full(len(qi), -np.inf)
    hi = np.full(len(qi), np.inf)
    for k, iq in enumerate(qi):
        jid = int(np.flatnonzero(np.asarray(m.idx_qs) == iq)[0])
        iv = m.idx_vs[jid]
        lo[k], hi[k] = figure.lower_v[iv], figure.upper_v[iv]
    for shift in (2 * np.pi, -2 * np.pi):
        Y = X + shift
        better = ((X < lo) | (X > hi)) & (Y >= lo) & (Y <= hi)
        X = np.where(better, Y, X)
    return X


def _lateral_sigma_m(problem, P):
    """The image noise (``weights.sigma_px``) in metres at the figure."""
    cam, s_px = problem.camera, problem.weights.sigma_px
    if hasattr(cam, "scale"):
        return s_px / cam.scale
    z = float(np.median(cam.depth(P)))
    return s_px * z / float(np.mean([cam.K[0, 0], cam.K[1, 1]]))


def _q_of(figure, v_mask):
    """q indices of the 1-dof joints among tangent entries ``v_mask`` (others: none)."""
    m = figure.model
    out = []
    for jid in range(1, m.njoints):
        if m.nqs[jid] == 1 and m.nvs[jid] == 1 and v_mask[m.idx_vs[jid]]:
            out.append(m.idx_qs[jid])
    return np.array(out, int)


def hypotheses_start(problem: ReconstructionProblem, base: np.ndarray | None = None,
                     guard_base: bool = True) -> np.ndarray:
    """The multi-hypothesis start (``seed="hypotheses"``); its :class:`HypothesisReport`
    is left in ``problem.reports["hypotheses"]``. ``base``: the search's base when already
    solved (:func:`base_solve` of ``problem``); ``guard_base``: as :func:`search_hypotheses`."""
    Q0, report = search_hypotheses(problem, base=base, guard_base=guard_base)
    reports = getattr(problem, "reports", None)
    if reports is not None:
        reports["hypotheses"] = report
    return Q0
