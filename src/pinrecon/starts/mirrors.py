"""The solved limbs mirrored span by span, kept where the whole MAP cost falls.

The multi-hypothesis start (:mod:`.hypotheses`) chooses each limb's depth reflection from
scores it can afford per frame: each state's inverse kinematics on a base trunk, the other
limbs held. The batch solve then only refines the basin it starts in. On the bench_real
dance (bench/README.md, "Mirrored limb spans") the truth's arms put into the solved motion
and solved warm end 927 nats below the solution at 45 degrees with first and last keyframes
(PA-MPJPE 50.2 -> 26.1 mm, flipped segments 16.9 -> 8.1 %); its legs or its trunk, about 45:
the MAP cost knows the arms' reflections better than the search found them.

This stage asks the whole cost directly. A limb segment can change its reflection without a
jump only where it crosses the image plane (its end's two points on the camera ray meet), so
the candidate spans of a segment are the runs of frames between the solution's crossings,
cut also where it only comes near the plane (``near``: a local minimum of the depth ratio's
size below :data:`NEAR`, away from a crossing; :func:`crossing_spans`). The truth may cross
where the solution only dipped: on the dance's right arm (45 degrees, first and last
keyframes) the solution's upper arm came to a ratio of 0.1 at frame 88 and rose again where
the truth crossed, and the whole run, frames 1-136, mirrored both ways cost 12.5 nats more
with 77 of its 250 counted segment-frames still flipped, the run's end now wrong. For every
limb chain (:func:`~.limbs.limb_chains`: hip-knee-ankle, shoulder-elbow-wrist) and every
such span of its first segment, the chain is mirrored there with the end on the same side of
the middle point (``"first"``) or the other (``"both"``); for every span of its second
segment, the end alone (``"end"``; :func:`mirrored_points`).
A candidate is pulled to its mirrored points by 3D rows while every other tracked point is held
where it is (``sigma_m``, ``pull_iterations`` Gauss-Newton steps on the whole problem plus
those rows: pulled alone, the dance's body moved 60 cm and its arm stayed flipped), released
(``trial_iterations`` steps on the problem alone), and kept when it saves more than
``min_gain`` nats (:data:`MIN_GAIN`); later candidates start from what was kept, and the last
kept is solved to the end with the global unknowns free. The candidates are judged at the
solution's global unknowns (lengths, focal length), held: free, the mirrors traded against an
auto camera's focal length, and Pose2Sim's real trial went from 86.8 to 128.9 mm (held: 85.8).
One view only (several cameras see depth); :func:`pinrecon.reconstruct` runs it after the turn
stage on a cold start (a warm start, the workbench's, keeps the reflections it is given).

On a clip longer than ``whole_frames`` (:data:`WHOLE_FRAMES`), each candidate moves its span
and ``margin_s`` (:data:`MARGIN_S`) of the clip on either side, no more: the pull and the
release are solved on the problem cropped to those frames (:meth:`~pinrecon.problem.ReconstructionProblem.cropped`), its two
end frames on each inner side held at the solution (:data:`HOLD_SIGMA`), and the candidate is
judged by the whole clip's cost with the crop put back: a candidate costs in proportion to its
span, not to the clip, and the stage in proportion to the clip (``bench/bench_long_clip.py``).

Arms only: chains to a foot point (:func:`pinrecon.contact.foot_keypoints`) are not tried by
default. On the dance the legs held about 45 of the 927 nats; without them bench_real's dance
moved 1.6-2.1 mm (48.1 / 18.5 with first and last keyframes, 62.4 / 18.8 without, against
46.5 / 18.1 and 60.3 / 18.4) and took 18 % less time. On Pose2Sim's real balancing trial,
as 17 COCO points through its calibrated camera 1 (tests/test_your_video.py), a left-leg
span was kept because it saved 28.8 nats, and it flipped the thigh in 27 of its 59 counted
frames: PA-MPJPE 123.5 mm against 106.2 without the stage. With the arms only it is 103.2.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from itertools import pairwise

import numpy as np

from ..contact import foot_keypoints
from ..processes import Beside, forkable
from ..rows import JointKeyframes, Points3D
from ..solver import SolverOptions, costs_at, globals_of, solve
from .limbs import camera_rays, limb_chains, sphere_ray

#: nats a mirrored span must save to be kept (a likelihood ratio of e^10): with the clip's
#: own skeleton and no learned pose prior (bench_real's lab run, orthographic, where a
#: mirrored limb has exactly the same image) four wrong spans saved 1.2-7.1 nats and took
#: the flipped segments from 0 to 10.3 %; the dance's spans that helped saved 20-485
MIN_GAIN = 10.0

#: the depth ratio below which a segment's local minimum cuts its runs into shorter spans
#: (:func:`crossing_spans`): bench_real's dance, mean of 45 and 60 degrees, PA-MPJPE 48.1 ->
#: 41.7 mm with first and last keyframes and 62.4 -> 41.1 without; Pose2Sim's real trial with
#: no camera file 85.8 -> 84.2 mm, with its calibration (17 COCO points) 103.2 either way
NEAR = 0.25

#: seconds of the clip on each side of a candidate span that its solves move (the rest held);
#: a clip no longer than the span and its margins is solved whole
MARGIN_S = 1.0

#: clips of at most this many frames try every candidate on the whole clip; longer ones on the
#: crop of its span and margins. On bench_real's 591-frame spin without keyframes (mean of 45
#: and 60 degrees) the whole clip's trials gave 36.7 mm / 13.8 % and the crops 41.3-41.8 mm /
#: 14.2-15.4 % (margins of 0.5-2 s): the whole clip's trials also improve the solution away
#: from the span. Past this length their cost, which grows with the square of the clip, rules
#: them out (1000 frames: 440 of the call's 728 s, ``bench/bench_long_clip.py``)
WHOLE_FRAMES = 600

#: standard deviation (radians, metres) holding the crop's end frames at the solution
HOLD_SIGMA = 1e-5

#: the candidates' modes (:func:`mirrored_points`), indexed in ``extras["solution_mirrors"]``
MODES = ("first", "both", "end")

__all__ = ["MIN_GAIN", "MODES", "NEAR", "Mirror", "MirrorStage", "crossing_spans", "mirror_stage", "mirrored_points"]


@dataclass(frozen=True)
class Mirror:
    """A candidate tried: chain label, ``mode`` (one of :data:`MODES`), frames
    ``[first, last)``, whether it was kept, the nats it saved (negative: it cost more) and
    whether it ended turned over (its mirrored segments' depth signs opposite the solution's
    in at least half the span's frames where they have depth; a candidate that slid back
    to the solution's reflection is no alternative)."""

    chain: str
    mode: str
    first: int
    last: int
    kept: bool
    gain: float
    turned: bool = False


@dataclass
class MirrorStage:
    """The candidates :func:`mirror_stage` tried; ``to_extras`` gives
    ``Result.extras["solution_mirrors"]`` (M, 5): chain index (into ``mirror_chains``),
    mode (its index in :data:`MODES`), first frame, frame after the last, nats saved (NaN: not kept),
    ``"mirror_chains"``, the chains' labels, and ``"mirror_uncertain"`` (U, 4), the
    :meth:`uncertain` candidates: chain index, first frame, frame after the last, nats saved
    (``"mirror_uncertain_nats"``: the threshold)."""

    tried: list
    threshold: float = MIN_GAIN

    def uncertain(self) -> list[Mirror]:
        """The spans whose reflection the MAP cost does not decide: candidates not kept that
        ended turned over within ``threshold`` nats of the solution (either way), and on
        whose chain no candidate overlapping them was kept afterwards (the solution they
        were judged against changed there)."""
        out = []
        for i, m in enumerate(self.tried):
            if m.kept or not m.turned or abs(m.gain) > self.threshold:
                continue
            if not any(n.kept and n.chain == m.chain and n.first < m.last and m.first < n.last
                       for n in self.tried[i + 1 :]):
                out.append(m)
        return out

    def to_extras(self) -> dict:
        labels = sorted({m.chain for m in self.tried})
        rows = [[labels.index(m.chain), MODES.index(m.mode), m.first, m.last, m.gain if m.kept else np.nan]
                for m in self.tried]
        ties = [[labels.index(m.chain), m.first, m.last, m.gain] for m in self.uncertain()]
        return {"solution_mirrors": np.array(rows, float).reshape(-1, 5), "mirror_chains": np.array(labels, dtype=str),
                "mirror_uncertain": np.array(ties, float).reshape(-1, 4), "mirror_uncertain_nats": float(self.threshold)}


def crossing_spans(ratio, min_len: int, min_depth: float, near: float = 0.0) -> list[tuple[int, int]]:
    """Runs ``[first, last)`` of frames between a segment's crossings of the image plane:
    the sign changes of its depth ``ratio`` (its end's depth along the line of sight minus
    its start's, over its length) and, with ``near``, the local minima of ``|ratio|``
    below it (where it comes close enough to turn over) at least ``min_len`` frames from a
    crossing or an end (nearer, it is the same turn); each run at least ``min_len`` frames
    long and reaching ``min_depth`` somewhere (a segment that stays near the image plane
    looks the same either way)."""
    r = np.asarray(ratio, float)
    if not len(r):
        return []
    s = np.sign(r)
    cut = set((np.flatnonzero(s[1:] != s[:-1]) + 1).tolist()) | {0, len(r)}
    if near > 0 and len(r) > 2:
        m = np.abs(r)
        dip = (m[1:-1] <= m[:-2]) & (m[1:-1] <= m[2:]) & (m[1:-1] < near)
        crossings = np.array(sorted(cut))
        cut |= {int(d) for d in np.flatnonzero(dip) + 1 if np.min(np.abs(crossings - d)) >= min_len}
    return [(int(a), int(b)) for a, b in pairwise(sorted(cut))
            if b - a >= min_len and np.max(np.abs(r[a:b])) >= min_depth]


def mirrored_points(camera, P, mode: str) -> np.ndarray:
    """(F, n-1, 3) a chain's points ``P`` (F, n, 3) after ``1:`` mirrored in depth: the
    other point of each camera ray at the same distance from the previous point. ``"first"``:
    the middle point mirrored about the start, the end placed on its ray at its length from
    the new middle point, on the same side of it in depth as before; ``"both"``: the same,
    the end on the other side (both segments' depths reversed); ``"end"``: the end alone
    mirrored about the middle point."""
    P = np.asarray(P, float)
    out = P[:, 1:].copy()

    def other(p0, p):
        o, d = camera_rays(camera, camera.project(p))
        near, far, _ = sphere_ray(p0, o, d, np.linalg.norm(p - p0, axis=-1))
        swap = np.linalg.norm(near - p, axis=-1) > np.linalg.norm(far - p, axis=-1)
        return np.where(swap[:, None], near, far), near, far

    if mode == "end":
        out[:, -1] = other(P[:, -2], P[:, -1])[0]
        return out
    out[:, 0] = other(P[:, 0], P[:, 1])[0]
    if P.shape[1] > 2:
        o, d = camera_rays(camera, camera.project(P[:, 2]))
        near, far, _ = sphere_ray(out[:, 0], o, d, np.linalg.norm(P[:, 2] - P[:, 1], axis=-1))
        side = camera.depth(P[:, 2]) >= camera.depth(P[:, 1])
        if mode == "both":
            side = ~side
        far_side = camera.depth(far) >= camera.depth(out[:, 0])
        out[:, 1] = np.where((far_side == side)[:, None], far, near)
    return out


def _depth_ratio(camera, K, i: int, j: int) -> np.ndarray:
    """(F,) a segment's depth along the line of sight (point ``j``'s minus ``i``'s) over its
    length, from keypoints ``K`` (F, K, 3)."""
    p0, p1 = K[:, i], K[:, j]
    return (camera.depth(p1) - camera.depth(p0)) / np.maximum(np.linalg.norm(p1 - p0, axis=-1), 1e-9)


def _turned(camera, K, K_new, kp, mode: str, min_ratio: float = 0.1) -> bool:
    """Whether the segments ``mode`` mirrors (chain points ``kp``) have the depth sign
    opposite ``K``'s in ``K_new`` in at least half the frames where ``K`` gives them depth
    (``|ratio| > min_ratio``, the flip metric's count)."""
    segs = {"first": (0,), "both": (0, 1), "end": (1,)}[mode]
    opposite = counted = 0
    for s in segs:
        r0, r1 = _depth_ratio(camera, K, kp[s], kp[s + 1]), _depth_ratio(camera, K_new, kp[s], kp[s + 1])
        c = np.abs(r0) > min_ratio
        counted += int(c.sum())
        opposite += int((c & (np.sign(r1) != np.sign(r0))).sum())
    return counted > 0 and 2 * opposite >= counted


def _held_ends(figure, X, lo: int, hi: int, T: int) -> list:
    """Rows holding the two frames at each inner end of the crop ``lo .. hi - 1`` of a
    ``T``-frame clip at the solution ``X`` (T, nq), every joint (:data:`HOLD_SIGMA`): with
    them fixed, the smoothing rows the crop leaves out (those reaching outside it) do not
    change, so the candidate's cost on the whole clip is the crop's change and no more."""
    f = sorted({t for t in (lo, lo + 1) if lo > 0} | {t for t in (hi - 2, hi - 1) if hi < T})
    if not f:
        return []
    m = figure.model
    names = list(m.names[1:])
    items = [(t - lo, HOLD_SIGMA, {n: X[t, m.idx_qs[j] : m.idx_qs[j] + m.nqs[j]] for j, n in enumerate(names, 1)})
             for t in f]
    return [JointKeyframes(figure, items)]


def _spliced(problem, cur, part, lo: int, g):
    """``cur`` with frames ``lo ..`` replaced by the cropped solve ``part``'s, and its cost
    on the whole problem (the candidate judged as the clip's solution)."""
    X = np.array(cur.x, float)
    X[lo : lo + len(part.x)] = part.x
    costs = costs_at(problem, X, g)
    return replace(cur, x=X, cost=float(sum(costs.values())), costs=costs, iterations=part.iterations,
                   converged=part.converged, status=part.status, report=list(part.report))


def _seen(problem, res):
    """A solve's global unknowns, its (first) camera at them and its keypoints (T, K, 3)."""
    g = globals_of(res)
    return g, problem.cameras_at(g)[0], problem.keypoints(problem.figure.normalize(res.x), g)


def mirror_stage(problem, res, options: SolverOptions | None = None, callback=None, *, min_span_s: float = 0.3,
                 min_depth: float = 0.3, sigma_m: float = 0.02, pull_iterations: int = 15,
                 trial_iterations: int = 40, min_gain: float = MIN_GAIN, passes: int = 1, near: float = NEAR,
                 skip: Sequence[str] | None = None, observe=None, margin_s: float = MARGIN_S,
                 whole_frames: int = WHOLE_FRAMES, fork: bool | None = None):
    """The solved motion ``res`` with its limbs' spans mirrored where that lowers the MAP
    cost (module docstring); ``passes`` rounds at most, a round after one that kept
    nothing is not run; chains holding a keypoint named in ``skip`` are not tried, by
    default the figure's foot points (:func:`pinrecon.contact.foot_keypoints`: the legs
    are left to the start, module docstring). Returns the last kept candidate solved to
    the end with ``options``
    (``res`` itself when none is kept, when the problem has several views or no limb
    chains, or when the user stopped the solve); the candidates tried go to
    ``problem.reports["mirrors"]`` (:class:`MirrorStage`). ``observe``, for diagnostics
    (``bench/diagnose_mirrors.py``), is called after every candidate as
    ``observe(mirror, current, candidate)``: the :class:`Mirror`, the solve it was tried on
    and the candidate's solve (both at the solution's global unknowns). ``margin_s`` and
    ``whole_frames``: the crops of a long clip's candidates (module docstring).

    ``fork``: while a candidate is tried, the next one is tried beside it in a forked child
    (:class:`~pinrecon.processes.Beside`), as if the first is not kept (most are not; when it
    is, the child's is dropped and tried again from the kept one): the same candidates and
    result as one by one, on both CPUs. ``None``: where :func:`~pinrecon.processes.forkable`."""
    if res.status == "stopped by callback" or len(getattr(problem, "views", ())) != 1:
        return res
    fig = problem.figure
    names = list(problem.tracks.names)
    skip = set(foot_keypoints(fig) if skip is None else skip)
    chains = [c for p in limb_chains(fig, names) for c in p if not set(c.names) & skip]
    if not chains:
        return res
    options = options or SolverOptions()
    fps = float(problem.fps or 30.0)
    min_len = max(2, round(min_span_s * fps))
    trials = _Trials(problem, chains, replace(options, max_iterations=min(options.max_iterations, pull_iterations)),
                     replace(options, max_iterations=min(options.max_iterations, trial_iterations)), sigma_m,
                     max(min_len, round(margin_s * fps)), whole_frames, (min_len, min_depth, near))
    ahead = forkable(problem.n_frames) if fork is None else bool(fork)
    cur, cost, tried = res, float(res.cost), []
    for _ in range(max(1, int(passes))):
        n_kept = sum(m.kept for m in tried)
        seen = _seen(problem, cur)
        cand, pos = trials.next(_START, seen)
        while cand is not None:
            nxt, pos_nxt = trials.next(pos, seen) if ahead else (None, None)
            for c, (out, turned) in trials.tried(cur, seen, cand, nxt, callback, cost - min_gain):
                gain = cost - float(out.cost)
                keep = gain > min_gain and out.status != "stopped by callback"
                tried.append(Mirror(c.chain.label, c.mode, c.a, c.b, bool(keep), float(gain), bool(turned)))
                if observe is not None:
                    observe(tried[-1], cur, out)
                if c is nxt:
                    pos = pos_nxt
                if keep:
                    cur, cost = out, float(out.cost)
                    seen = _seen(problem, cur)
            cand, pos = trials.next(pos, seen)
        if sum(m.kept for m in tried) == n_kept:
            break
    reports = getattr(problem, "reports", None)
    if reports is not None:
        reports["mirrors"] = MirrorStage(tried, min_gain)
    if not any(m.kept for m in tried):
        return res
    return solve(problem, cur.x, options, callback, active=problem.active, g0=globals_of(cur))


@dataclass(frozen=True)
class _Candidate:
    """A limb chain mirrored in ``mode`` over frames ``[a, b)``."""

    chain: object
    mode: str
    a: int
    b: int


#: where :meth:`_Trials.next` starts: the first chain's first mode, its spans not yet cut
_START = (0, None, 0)


@dataclass
class _Trials:
    """The candidates of :func:`mirror_stage` in the order they are tried, and their trials."""

    problem: object
    chains: list
    pull_options: SolverOptions
    trial_options: SolverOptions
    sigma_m: float
    margin: int
    whole_frames: int
    spans: tuple  # crossing_spans' min_len, min_depth, near

    def __post_init__(self):
        self.modes = [(c, m) for c in self.chains for m in (MODES if c.n_segments > 1 else ("first",))]
        # every tracked point is held where it is, the chain's ends pulled to their mirrors: the
        # limb turns over, not the body round it
        self.pinned = np.unique(np.concatenate([np.asarray(self.problem.measurement.keypoints, int)]
                                               + [c.kp for c in self.chains]))

    def next(self, pos, seen):
        """``(candidate, position after it)`` from walk position ``pos`` ``(mode index, spans,
        span index)``, or ``(None, None)`` after the last: a chain's spans in a mode are cut
        where the walk enters that mode, from the solution ``seen`` then (:func:`_seen`)."""
        k, spans, s = pos
        while k < len(self.modes):
            chain, mode = self.modes[k]
            if spans is None:
                seg = 1 if mode == "end" else 0
                spans, s = crossing_spans(_depth_ratio(seen[1], seen[2], chain.kp[seg], chain.kp[seg + 1]),
                                          *self.spans), 0
            if s < len(spans):
                a, b = spans[s]
                return _Candidate(chain, mode, int(a), int(b)), (k, spans, s + 1)
            k, spans = k + 1, None
        return None, None

    def tried(self, cur, seen, cand, nxt, callback, kept_below: float):
        """``[(candidate, (solve, turned))]``: ``cand`` tried on the solution ``cur``; unless
        its cost falls below ``kept_below`` (it is kept), and where ``nxt`` is given, ``nxt``
        too, tried meanwhile in a forked child (its iterations reported to ``callback`` once
        taken; where the callback stops them, tried again here, where it is heard)."""
        side = None if nxt is None else Beside(self.trial, cur, seen, nxt, None, fork=True)
        try:
            first = self.trial(cur, seen, cand, callback)
            if side is None or float(first[0].cost) < kept_below:
                return [(cand, first[:2])]
            second = side.result()
            if callback is not None and any(callback(rep) for rep in second[2]):
                second = self.trial(cur, seen, nxt, callback)
            return [(cand, first[:2]), (nxt, second[:2])]
        finally:
            if side is not None:
                side.cancel()

    def trial(self, cur, seen, cand, callback):
        """``(solve, turned, iterations)``: ``cand`` pulled to its mirrored points from ``cur``
        and released, at the solution's global unknowns; on a long clip the span and its
        margins alone, judged on the whole clip."""
        problem, fig = self.problem, self.problem.figure
        g, camera, K = seen
        chain, mode, a, b = cand.chain, cand.mode, cand.a, cand.b
        targets = K[a:b][:, self.pinned].copy()
        moved = mirrored_points(camera, K[a:b][:, chain.kp], mode)
        for j, k in enumerate(chain.kp[1:]):
            targets[:, int(np.searchsorted(self.pinned, k))] = moved[:, j]
        held = None if g is None else np.zeros(len(g), bool)  # a mirror judged at the solution's globals
        T = problem.n_frames
        lo, hi = max(0, a - self.margin), min(T, b + self.margin)
        sub = problem.cropped(lo, hi) if T > self.whole_frames and hi - lo < T else None
        if sub is None:  # the whole clip
            lo, hi, base = 0, T, problem
        else:  # the span and its margins alone, their ends held where they are; judged on the clip
            base = sub.with_rows(_held_ends(fig, cur.x, lo, hi, T))
        pull = base.with_rows([Points3D(np.arange(a - lo, b - lo), self.pinned, targets, self.sigma_m, name="mirror")])
        pulled = solve(pull, cur.x[lo:hi], self.pull_options, callback, active=problem.active, g0=g,
                       active_globals=held)
        out = solve(base, pulled.x, self.trial_options, callback, active=problem.active, g0=g, active_globals=held)
        iterations = list(pulled.report) + list(out.report)
        if sub is not None:
            out = _spliced(problem, cur, out, lo, g)
        turned = _turned(camera, K[a:b], problem.keypoints(fig.normalize(out.x)[a:b], g), chain.kp, mode)
        return out, turned, iterations
