"""Detector faults after a first solve: left/right swaps repaired, outliers reported.

A 2D detector sometimes labels a person's left limbs as right and the other way round
for a frame, and sometimes puts a point somewhere else altogether. The confidence-
weighted robust loss (``Weights.loss``, Cauchy by default when the tracks carry
confidences) keeps single bad points from dragging the solution; this stage then uses
the solution to look at every frame again:

* **Swaps** (:func:`detect_swaps`): in every observed frame both labellings of the
  left/right pairs (``left_*``/``right_*``, ``Left*``/``Right*``) are scored against the
  current estimate's projection with the measurement rows' own robust cost
  (confidence weights, ``sigma_px``, loss and scale). A frame is a swap when the swapped
  labelling is cheaper by more than ``margin`` nats. Repaired frames get their labels
  exchanged in the measurement rows (and ``problem.tracks``) and the problem is solved
  again from the current estimate (warm), twice at most.
* **Spans** (:func:`side_swap_frames`, before any solve): a detector sometimes keeps a
  person's sides the other way round for a span of frames (MediaPipe did for 33 frames of
  Pose2Sim's trial), which a solution that follows the labels cannot see. The tracks' own
  continuity can: at a span's edges every left/right pair jumps by the person's width, while
  the other labelling moves on smoothly. Each frame gets a label (kept or exchanged) by a
  dynamic programme over the clip; its cost is the pairs' capped displacement between frames
  1, 2 and 3 apart and their acceleration over three frames, so a person turning through
  side-on (where left and right cross in the image) keeps its labels: only the exchanged
  labelling makes that crossing a kink. The labelling that agrees with the detector on most
  frames is taken as right. :func:`relabel_sides` exchanges the labels of those frames. A
  lifter's 3D is judged by its own continuity with the 2D's labelling as a prior (each frame
  labelled otherwise costs :data:`PRIOR_COST`): a lifter keeps the sides of the 2D it lifted
  (MediaPipe's world landmarks keep its 2D's), so its own spans are found where its continuity
  says so clearly, but one doubtful exchange does not turn a whole tail of the clip over.
* **Outliers** (:func:`find_outliers`): observed points whose reprojection error after
  convergence exceeds ``max(5 sigma_px, median + 5 MAD-sigma)`` of all points' errors
  are reported (frame, name, error); they are left in, down-weighted by the loss.

:func:`fault_stage` runs both for the pipeline (``reconstruct``) and leaves a
:class:`FaultReport` in ``problem.reports["faults"]``; ``Result.extras`` carries
``repaired_frames``, ``outlier_frames``, ``outlier_points`` and ``outlier_error_px``.
Frames are the tracks' frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .rows.lifted import LiftedPose
from .solver import SolveResult, SolverOptions, globals_of, solve

__all__ = ["FaultReport", "detect_swaps", "fault_stage", "find_outliers", "left_right_pairs", "relabel_sides",
           "repair_swaps", "report_outliers", "side_swap_frames"]

_SIDES = (("left_", "right_"), ("Left", "Right"), ("left", "right"), ("l_", "r_"), ("L", "R"))


def left_right_pairs(names) -> list[tuple[int, int]]:
    """Index pairs (left, right) of ``names`` that differ only by their side prefix
    (``left_knee``/``right_knee``, ``LeftLeg``/``RightLeg``, ``LHipJoint``/``RHipJoint``)."""
    pos = {n: i for i, n in enumerate(names)}
    out = []
    for n, i in pos.items():
        for lo, ro in _SIDES:
            if n.startswith(lo) and ro + n[len(lo):] in pos:
                out.append((i, pos[ro + n[len(lo):]]))
                break
    return out


#: the cost of one exchange of the labels between two frames, in the person's sizes of
#: displacement (:func:`side_swap_frames`)
SWITCH_COST = 0.3
#: the cost of a frame labelled otherwise than a given labelling says (:func:`side_swap_frames`'s
#: ``prior``; the 2D's labelling for the 3D a lifter made of it), in the same units: a span of
#: its own is still found where the 3D's continuity says so clearly, never a clip's whole tail
#: turned over by one doubtful exchange (MediaPipe's 3D of Pose2Sim's camera 2 played forwards and
#: backwards to 2400 frames, without it: the last 800 frames against its 2D; bench/README.md)
PRIOR_COST = 0.05
#: the weight of the acceleration term against the displacements (:func:`side_swap_frames`):
#: at 1, fast spins seen at 20-40 frames/s had spans relabelled wrongly in 12 of 216 synthetic
#: cases (bench/bench_side_swaps.py); at 2 and 3 none, and Pose2Sim's real span still found
ACCELERATION = 2.0


def _pair_terms(points: np.ndarray, pairs) -> list[tuple[tuple[int, ...], np.ndarray]]:
    """The continuity terms of :func:`side_swap_frames`: ``(offsets, cost)`` with ``cost[t, i]``
    the capped displacement (person sizes) of every left/right pair between the frames
    ``t + offsets`` when the labels differ as pattern ``i`` says (two frames: same, exchanged;
    three frames, the acceleration: bit 1 the middle frame exchanged from the first, bit 0 the
    last)."""
    P = np.asarray(points, float)
    seen_any = np.isfinite(P[..., 0]).any(axis=1)
    if not seen_any.any():
        return []
    Q = P[seen_any]
    size = float(np.median(np.linalg.norm(np.nanmax(Q, axis=1) - np.nanmin(Q, axis=1), axis=-1)))
    if not size > 0.0:
        return []
    a, b = np.array(pairs).T
    A, B = P[:, a], P[:, b]
    seen = np.isfinite(A[..., 0]) & np.isfinite(B[..., 0])
    cap = 0.5 * size

    def total(e, ok):
        return np.where(ok, np.minimum(e, cap), 0.0).sum(axis=1) / size

    terms = []
    for k in (1, 2, 3):
        ok = seen[:-k] & seen[k:]
        same = np.linalg.norm(A[k:] - A[:-k], axis=-1) + np.linalg.norm(B[k:] - B[:-k], axis=-1)
        swapped = np.linalg.norm(A[k:] - B[:-k], axis=-1) + np.linalg.norm(B[k:] - A[:-k], axis=-1)
        terms.append(((0, k), np.stack([total(same, ok), total(swapped, ok)], axis=1)))
    ok = seen[:-2] & seen[1:-1] & seen[2:]
    acc = []
    for mid in (0, 1):
        for last in (0, 1):
            m = (B[1:-1], A[1:-1]) if mid else (A[1:-1], B[1:-1])
            n = (B[2:], A[2:]) if last else (A[2:], B[2:])
            e = sum(np.linalg.norm(n[i] - 2.0 * m[i] + (A, B)[i][:-2], axis=-1) for i in (0, 1))
            acc.append(ACCELERATION * total(e, ok))
    terms.append(((0, 1, 2), np.stack(acc, axis=1)))
    return terms


def side_swap_frames(tracks, prior=None) -> np.ndarray:
    """Frames (indices into ``tracks``) whose left/right labels are the other way round from
    the rest of the clip, judged by the tracks' continuity alone (see the module's
    docstring); empty when the names have no left/right pairs or the clip is shorter than
    four frames. The labelling that holds on most frames is taken as right.

    ``prior``: frames expected exchanged (a lifter's 3D: the frames found in the 2D it was made
    from, whose sides it keeps); then each frame labelled otherwise costs :data:`PRIOR_COST`,
    the labelling that holds on most frames is no longer the rule, and a clip shorter than four
    frames keeps the prior's frames."""
    pairs = left_right_pairs(list(tracks.names))
    T = int(tracks.points.shape[0])
    expected = None
    if prior is not None:
        expected = np.zeros(T, int)
        expected[np.asarray(prior, int)] = 1
    if not pairs:
        return np.zeros(0, int)
    terms = _pair_terms(tracks.points, pairs) if T >= 4 else []
    if not terms:  # nothing to judge by: the prior's frames, or none
        return np.zeros(0, int) if expected is None else np.flatnonzero(expected)
    # windows of four frames' labels (bits: frame t-3 .. t); every term ends at the window's last frame
    full = np.array([[(w >> (3 - i)) & 1 for i in range(4)] for w in range(16)])
    step = np.zeros((T, 16))
    for offs, cost in terms:
        span = offs[-1]
        first = full[:, 3 - span]
        if len(offs) == 2:
            pattern = (full[:, 3] != first).astype(int)
        else:
            pattern = 2 * (full[:, 3 - span + 1] != first) + (full[:, 3] != first)
        step[span:span + len(cost)] += cost[:, pattern]
    step += SWITCH_COST * (full[:, 3] != full[:, 2])
    if expected is not None:
        step += PRIOR_COST * (full[None, :, 3] != expected[:, None])
    # the first three frames: the terms inside them (those whose first frame is not before 0)
    start = np.zeros(8)
    for w in range(8):
        lab = [(w >> (2 - i)) & 1 for i in range(3)]
        for offs, cost in terms:
            span = offs[-1]
            for t in range(span, 3):
                if t - span < len(cost):
                    if len(offs) == 2:
                        start[w] += cost[t - span, int(lab[t] != lab[t - span])]
                    else:
                        start[w] += cost[t - span, 2 * int(lab[t - 1] != lab[t - 2]) + int(lab[t] != lab[t - 2])]
        start[w] += SWITCH_COST * ((lab[0] != lab[1]) + (lab[1] != lab[2]))
        if expected is not None:
            start[w] += PRIOR_COST * sum(int(lab[i] != expected[i]) for i in range(3))
    value, back = start, np.zeros((T, 8), int)
    prev_of = np.array([[(w >> 1), (w >> 1) | 4] for w in range(8)])  # the windows a window follows
    for t in range(3, T):
        cand = value[prev_of] + step[t][(prev_of << 1 & 8) | np.arange(8)[:, None]]
        pick = np.argmin(cand, axis=1)
        back[t] = prev_of[np.arange(8), pick]
        value = cand[np.arange(8), pick]
    w = int(np.argmin(value))
    labels = np.zeros(T, int)
    for t in range(T - 1, 2, -1):
        labels[t] = w & 1
        w = back[t, w]
    labels[:3] = [(w >> 2) & 1, (w >> 1) & 1, w & 1]
    if expected is None and labels.sum() > T / 2:
        labels = 1 - labels
    return np.flatnonzero(labels)


def relabel_sides(tracks, frames, lifted_frames=None):
    """A copy of ``tracks`` with every left/right pair's labels exchanged at ``frames``, and
    the lifted pose's (when the tracks carry one) at ``lifted_frames`` (default ``frames``:
    a detector's own 3D keeps the sides as its 2D does)."""
    from dataclasses import replace

    frames = np.asarray(frames, int)
    lifted_frames = frames if lifted_frames is None else np.asarray(lifted_frames, int)
    _, perm = _permutation(list(tracks.names))
    points = np.array(tracks.points, float)
    points[frames] = points[frames][:, perm]
    conf = None
    if tracks.confidence is not None:
        conf = np.array(tracks.confidence, float)
        conf[frames] = conf[frames][:, perm]
    lifted = getattr(tracks, "lifted", None)
    if lifted is not None:
        _, lperm = _permutation(list(lifted.names))
        lp, lc = np.array(lifted.points, float), np.array(lifted.confidence, float)
        f = lifted_frames
        lp[f], lc[f] = lp[f][:, lperm], lc[f][:, lperm]
        lifted = replace(lifted, points=lp, confidence=lc)
    return replace(tracks, points=points, confidence=conf, lifted=lifted)


def _rho(meas, e2):
    """The measurement rows' loss of whitened squared errors (2 rho, i.e. |r|^2 for l2)."""
    if meas.loss == "l2":
        return e2
    c2 = meas.loss_scale ** 2
    if meas.loss == "huber":
        e = np.sqrt(e2)
        return np.where(e2 <= c2, e2, 2.0 * meas.loss_scale * e - c2)
    return c2 * np.log1p(e2 / c2)


def _views(problem):
    """(tracks, measurement rows, factor) of every camera of the problem."""
    views = getattr(problem, "views", None)
    if views:
        return [(v.tracks, v.measurement, max(int(v.factor), 1)) for v in views if v.measurement is not None]
    if problem.measurement is None or problem.tracks is None:
        return []
    return [(problem.tracks, problem.measurement, max(int(problem.factor), 1))]


def _measured(problem, meas, Q, g=None):
    """Projections (N, M, 2) of the measured keypoints at the measurement frames."""
    state = problem.state(Q, jacobian=False) if g is None else problem.state(Q, jacobian=False, g=g)
    P = state.points[state.slot[meas.frames]][:, meas.keypoints]
    camera = meas.camera_at(state) if hasattr(meas, "camera_at") else meas.camera
    return camera.project(P)


def _permutation(names):
    pairs = left_right_pairs(names)
    perm = np.arange(len(names))
    if pairs:
        a, b = np.array(pairs).T
        perm[a], perm[b] = b, a
    return pairs, perm


def detect_swaps(problem, Q, *, margin: float = 4.0, g=None, view: int = 0):
    """Frames whose left/right labels are swapped, judged against the estimate ``Q``.

    Returns ``(rows, gain)``: indices into the camera ``view``'s measurement frames of the
    frames where exchanging every left/right pair lowers the frame's robust measurement
    cost by more than ``margin`` nats, and that gain (nats) for each."""
    views = _views(problem)
    if view >= len(views):
        return np.zeros(0, int), np.zeros(0)
    tracks, meas, _ = views[view]
    pairs, perm = _permutation(list(tracks.names))
    if not pairs or not len(meas.frames):
        return np.zeros(0, int), np.zeros(0)
    uv_hat = _measured(problem, meas, Q, g)
    sw = meas.sqrt_w  # (N, M): sqrt(confidence) / sigma, 0 where missing

    def cost(uv_obs, s):
        e2 = np.sum((uv_hat - uv_obs) ** 2, axis=-1) * s**2
        return 0.5 * np.sum(np.where(s > 0, _rho(meas, e2), 0.0), axis=1)

    a, b = np.array(pairs).T
    both = (sw[:, a] > 0) & (sw[:, b] > 0)
    gain = cost(meas.uv_filled, sw) - cost(meas.uv_filled[:, perm], sw[:, perm])
    rows = np.flatnonzero((gain > margin) & both.any(axis=1))
    return rows, gain[rows]


def repair_swaps(problem, rows, *, view: int = 0) -> None:
    """Exchange the left/right labels of the camera ``view``'s measurement rows ``rows``
    in place (the measurement rows and that camera's tracks), and of the lifted pose of
    the same image when the tracks carry one (its rows, :meth:`pinrecon.rows.lifted.
    LiftedPose.swap_sides`, and ``tracks.lifted``): a detector that labels a person's sides
    the other way round in 2D does so in its 3D too."""
    rows = np.asarray(rows, int)
    if not len(rows):
        return
    tracks, meas, factor = _views(problem)[view]
    _, perm = _permutation(list(tracks.names))
    for attr in ("uv_px", "uv_filled", "sqrt_w", "observed"):
        arr = getattr(meas, attr)
        arr[rows] = arr[rows][:, perm]
    fr = meas.frames[rows] // factor
    tracks.points[fr] = tracks.points[fr][:, perm]
    if tracks.confidence is not None:
        tracks.confidence[fr] = tracks.confidence[fr][:, perm]
    lifted = getattr(tracks, "lifted", None)
    if lifted is not None:
        _, lperm = _permutation(list(lifted.names))
        lifted.points[fr] = lifted.points[fr][:, lperm]
        lifted.confidence[fr] = lifted.confidence[fr][:, lperm]
    name = _view_name(problem, view)
    figure_names = list(problem.figure.keypoint_names)
    _, kperm = _permutation(figure_names)
    for row in getattr(problem, "rows", ()):
        if isinstance(row, LiftedPose) and row.view == name:
            row.swap_sides(meas.frames[rows], kperm)


def _view_name(problem, view: int):
    """The name of the camera ``view`` of :func:`_views` (None for a problem without views)."""
    views = [v for v in (getattr(problem, "views", None) or ()) if v.measurement is not None]
    return views[view].name if view < len(views) else None


def find_outliers(problem, Q, *, threshold_px: float | None = None, g=None, view: int = 0):
    """Observed points far from the estimate's projection after convergence (camera ``view``).

    Returns ``(frames, names, error_px, threshold_px)``: tracks frames, point names and
    reprojection errors (pixels) of the points whose error exceeds the threshold
    (default ``max(5 sigma_px, median + 5 * 1.4826 MAD)`` over all observed points)."""
    views = _views(problem)
    if view >= len(views) or not len(views[view][1].frames):
        return np.zeros(0, int), np.zeros(0, str), np.zeros(0), float("nan")
    tracks, meas, factor = views[view]
    err = np.linalg.norm(_measured(problem, meas, Q, g) - meas.uv_px, axis=-1)
    ok = meas.observed & np.isfinite(err)
    e = err[ok]
    if threshold_px is None:
        med = float(np.median(e)) if e.size else 0.0
        mad = float(np.median(np.abs(e - med))) if e.size else 0.0
        threshold_px = max(5.0 * meas.sigma_px, med + 5.0 * 1.4826 * mad)
    n, m = np.nonzero(ok & (err > threshold_px))
    names = np.array([tracks.names[k] for k in m], dtype=str)
    return meas.frames[n] // factor, names, err[n, m], float(threshold_px)


@dataclass
class FaultReport:
    """What :func:`fault_stage` found: ``repaired_frames`` (tracks frames whose left and
    right labels were exchanged), ``swap_gain`` (nats each repair saved), and the
    outliers (``outlier_frames``, ``outlier_points``, ``outlier_error_px``, above
    ``outlier_threshold_px``)."""

    repaired_frames: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    swap_gain: np.ndarray = field(default_factory=lambda: np.zeros(0))
    outlier_frames: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    outlier_points: np.ndarray = field(default_factory=lambda: np.zeros(0, str))
    outlier_error_px: np.ndarray = field(default_factory=lambda: np.zeros(0))
    outlier_threshold_px: float = float("nan")

    prefix: str = ""

    def to_extras(self) -> dict:
        """Arrays for ``Result.extras`` (keys prefixed with ``<camera>_`` for a second camera)."""
        out = {
            "repaired_frames": np.asarray(self.repaired_frames, int),
            "outlier_frames": np.asarray(self.outlier_frames, int),
            "outlier_points": np.asarray(self.outlier_points, dtype=str),
            "outlier_error_px": np.asarray(self.outlier_error_px, float),
            "outlier_threshold_px": np.float64(self.outlier_threshold_px),
        }
        return {self.prefix + k: v for k, v in out.items()}


def fault_stage(problem, res: SolveResult, options: SolverOptions | None = None, callback=None, *,
                rounds: int = 2, margin: float = 4.0) -> SolveResult:
    """Repair left/right swaps against the solution ``res`` (every camera) and solve again
    warm (up to ``rounds`` times while new swaps are found), then report outliers. The
    :class:`FaultReport` goes to ``problem.reports["faults"]`` (when the problem has
    ``reports``; frames of the first camera, the others' in ``"faults_<camera>"``).
    Returns the final solve."""
    views = _views(problem)
    if not views:
        return res
    g = globals_of(res)
    toggled = [np.zeros(len(m.frames), bool) for _, m, _ in views]  # a frame swapped twice is back
    gain_of = [np.zeros(len(m.frames)) for _, m, _ in views]
    for _ in range(rounds):
        found = False
        for v in range(len(views)):
            rows, gain = detect_swaps(problem, res.x, margin=margin, g=g, view=v)
            if len(rows):
                repair_swaps(problem, rows, view=v)
                toggled[v][rows] ^= True
                gain_of[v][rows] += gain
                found = True
        if not found:
            break
        res = solve(problem, res.x, options, callback, active=problem.active, g0=g)
        g = globals_of(res)
    reports = getattr(problem, "reports", None)
    names = _camera_names(problem, len(views))
    for v, (_, meas, factor) in enumerate(views):
        rows = np.flatnonzero(toggled[v])
        report = FaultReport(meas.frames[rows] // factor, gain_of[v][rows], prefix="" if v == 0 else f"{names[v]}_")
        _set_outliers(report, problem, res.x, g, v)
        if reports is not None:
            reports[_report_key(v, names)] = report
    return res


def report_outliers(problem, res: SolveResult) -> None:
    """Find the outliers again against solve ``res`` and put them in the fault reports
    :func:`fault_stage` left in ``problem.reports``: for a solve after the fault stage
    (an auto camera's focal length carried down its valley restarts it), whose points
    are not where the fault stage's were."""
    views, reports = _views(problem), getattr(problem, "reports", None)
    if not views or reports is None:
        return
    g = globals_of(res)
    names = _camera_names(problem, len(views))
    for v in range(len(views)):
        report = reports.get(_report_key(v, names))
        if report is not None:
            _set_outliers(report, problem, res.x, g, v)


def _camera_names(problem, n: int) -> list[str]:
    return getattr(problem, "camera_names", None) or [f"camera{v + 1}" for v in range(n)]


def _report_key(view: int, names: list[str]) -> str:
    """Where camera ``view``'s :class:`FaultReport` goes in ``problem.reports``."""
    return "faults" if view == 0 else f"faults_{names[view]}"


def _set_outliers(report: FaultReport, problem, Q, g, view: int) -> None:
    (report.outlier_frames, report.outlier_points, report.outlier_error_px,
     report.outlier_threshold_px) = find_outliers(problem, Q, g=g, view=view)
