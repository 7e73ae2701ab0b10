"""Long clips in bounded memory: the batch solve over overlapping windows of frames.

The batch solve's memory is linear in the number of frames (the band of ``J^T J``, its
factor and the Jacobians: about 70 KB a frame for the human, see ``bench/bench_engine.py``),
so an hour of motion does not fit. :func:`solve_windowed` solves the same problem window
by window, in order:

* windows of ``window`` frames (reconstruction frames) overlap by ``overlap`` frames;
  each is a problem of its own, built from the clip's inputs restricted to its frames
  (:func:`pinrecon.problem.make_problem`: the tracks of every camera, the keyframes that
  fall in it, the same weights and calibration mode);
* each window starts from the same start as the batch solve, computed on the window's
  data (or from a given start trajectory), except for the frames it shares with the
  previous window, which start warm from that window's solution;
* its solution is stitched on: inside the overlap the two solutions are blended
  geodesically (``pin.interpolate``), the weight of the new one going from 0 to 1 over
  the middle half of the overlap, away from both windows' ends where a window knows least;
* global unknowns (a calibration) are solved once on a leading stretch of the clip
  (:data:`CALIBRATION_FRAMES`, or the first window if longer; :func:`solve_lead`, whose poses
  :func:`pinrecon.reconstruct` also judges the pose prior on, making the broader prior's
  stretch meanwhile in a forked child where a CPU is spare), then held in every window
  (:func:`pinrecon.reconstruct` measures one camera's limb lengths from the tracks of its
  first frames before, as the batch solve does on the clip);
  which of the fitted lengths that stretch's data fix
  (:func:`pinrecon.identifiability.proportions_identifiability`) is the result's
  ``identifiability`` attribute;
* the turn stage (:func:`pinrecon.starts.turns.turn_stage`: the solution's fast turns
  wound), the mirror stage where asked (:func:`pinrecon.starts.mirrors.mirror_stage`: limb
  spans mirrored where the MAP cost falls) and the fault stage (:func:`pinrecon.faults.fault_stage`: left/right swaps
  repaired, outliers) run in every window, as after the batch solve; their reports are
  merged, frames shifted to the clip's.

Both cores: with ``n_jobs`` (:func:`pinrecon.reconstruct` asks for every core) the windows are
split into as many runs of consecutive windows, each solved in a worker process (forked where
the platform can fork; one after another elsewhere), the first window of each run starting
cold; the runs are stitched as consecutive windows are. The callback's reports come back over
a queue (its stop stops every worker). Each worker holds one window's problem and solver
buffers at a time, so memory does not grow with the clip (the inputs and the output
trajectory, a few hundred bytes a frame, do).
On clips that fit in memory the windowed answer is within 1 mm (mean per-joint) of the
batch one (``tests/test_windowed.py``, ``bench/bench_engine.py``).

:func:`pinrecon.reconstruct` windows by itself past :data:`AUTO_WINDOW_FRAMES` frames,
or when given ``window=N`` (``window=0``: never); ``pinrecon reconstruct --window N``.
Progress: the callback gets every window's :class:`~pinrecon.solver.IterationReport`\\ s
and, when it has a ``window`` method, a :class:`WindowReport` after each window.
"""

from __future__ import annotations

import ctypes
import functools
import gc
import math
import multiprocessing
import queue as queue_module
import time
import warnings
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field, replace

import numpy as np

from .errors import InputError
from .faults import FaultReport, fault_stage
from .identifiability import proportions_identifiability
from .prior_yield import adapt_prior as adapt_to_keyframes
from .prior_yield import decided_by_keyframes, pose_prior_row, with_pose_prior
from .problem import make_problem
from .processes import may_fork, n_processes, usable_cpus
from .solver import SolveResult, SolverOptions, costs_at, solve
from .starts import initial_trajectory, searches
from .starts.hypotheses import hypotheses_start
from .starts.mirrors import MirrorStage, mirror_stage
from .starts.turns import TurnStage, turn_stage
from .tracks import Keyframes
from .unfamiliar import JudgedWhile, judged_at_base

__all__ = [
    "AUTO_WINDOW_FRAMES",
    "DEFAULT_OVERLAP",
    "DEFAULT_WINDOW",
    "Lead",
    "WindowReport",
    "lead_base",
    "solve_lead",
    "solve_windowed",
    "window_plan",
    "windowed_length",
]

#: clips longer than this many reconstruction frames are solved in windows by default
AUTO_WINDOW_FRAMES = 10_000
#: frames per window when windowing is automatic
DEFAULT_WINDOW = 2_000
#: frames two consecutive windows share (at most a third of the window)
DEFAULT_OVERLAP = 200
#: frames of the leading stretch whose solve gives the global unknowns (a calibration)
CALIBRATION_FRAMES = 2_000


@dataclass
class WindowReport:
    """One solved window: its index (from 1) of ``count``, its frames ``[first, last]``
    (reconstruction frames, inclusive), iterations, final cost, status and CPU seconds."""

    index: int
    count: int
    first: int
    last: int
    iterations: int
    cost: float
    status: str
    seconds: float

    def __str__(self) -> str:
        return (f"window {self.index}/{self.count}  frames {self.first}-{self.last}  {self.iterations} iterations  "
                f"cost {self.cost:.6g}  {self.status}  {self.seconds:.1f}s")


def windowed_length(n_frames: int, window: int | None) -> int | None:
    """The window length :func:`pinrecon.reconstruct` uses for ``n_frames`` frames:
    ``window`` when given (``0``: ``None``, the batch solve), else
    :data:`DEFAULT_WINDOW` past :data:`AUTO_WINDOW_FRAMES` frames, else ``None``."""
    if window is None:
        return DEFAULT_WINDOW if n_frames > AUTO_WINDOW_FRAMES else None
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 0:
        raise InputError(f"must be a number of frames (0: no windows), got {window!r}", field="window")
    if window == 0 or window >= n_frames:
        return None
    return window


def window_plan(n_frames: int, window: int, overlap: int, unit: int = 1) -> list[tuple[int, int]]:
    """Windows ``(first, last)`` (inclusive) covering frames ``0 .. n_frames - 1``: each
    ``window`` frames long (rounded down to a multiple of ``unit``, the cameras' frame
    step, plus one), starting on multiples of ``unit``, as few as let consecutive ones
    share at least ``overlap`` frames, spread evenly; the last one ends on the last frame."""
    last = n_frames - 1
    span = max(unit, (window - 1) // unit * unit)
    if span >= last:
        return [(0, last)]
    stride = max(unit, (span - overlap) // unit * unit)
    count = math.ceil((last - span) / stride) + 1
    starts = [round(k * (last - span) / (count - 1) / unit) * unit for k in range(count)]
    return [(a, min(a + span, last)) if k < count - 1 else (starts[-1], last) for k, a in enumerate(starts)]


@dataclass
class Lead:
    """The leading stretch of a clip solved in windows (the module docstring): its problem
    (None when it has nothing to solve), its solution ``x``, the globals solved on it and what
    its data fix of them, the pose prior adapted to its keyframes (held in every window), and
    its problem's reports (e.g. the start's, carried to the clip's problem)."""

    problem: object = None
    x: np.ndarray | None = None
    g_solved: np.ndarray | None = None
    identified: object = None
    held_prior: object = None
    reports: dict = field(default_factory=dict)
    judged: object = None  # the prior's switch judged while it was solved (solve_lead's limit)


def _plan(problem, window: int, overlap: int | None):
    """``(plan, overlap, unit)`` of :func:`solve_windowed`."""
    window = int(window)
    if window < 3:
        raise InputError(f"a window needs at least 3 frames, got {window}", field="window")
    overlap = min(DEFAULT_OVERLAP if overlap is None else int(overlap), window // 3)
    unit = math.lcm(*[int(v.factor) for v in problem.views])
    return window_plan(problem.n_frames, max(window, 2 * unit + 1), overlap, unit), overlap, unit


def _lead_problem(problem, window: int, overlap: int | None):
    plan, _, unit = _plan(problem, window, overlap)
    stretch = (min(problem.n_frames - 1, max(plan[0][1], CALIBRATION_FRAMES - 1)) // unit) * unit
    return _window_problem(problem, 0, stretch, free_globals=True, g_held=None), stretch


def lead_base(problem, start="auto", *, window: int = DEFAULT_WINDOW, overlap: int | None = None):
    """``(base, share)``: the leading stretch's multi-hypothesis search base
    and the share of its poses the problem's pose prior does not know
    (:func:`pinrecon.unfamiliar.judged_at_base`; :func:`solve_lead` takes the base); None where
    ``start`` (``"auto"`` only) starts the stretch otherwise (lifted cues, several cameras, dense keyframes)."""
    if not (isinstance(start, str) and start == "auto"):
        return None
    wp, _ = _lead_problem(problem, window, overlap)
    return judged_at_base(wp) if searches(wp) else None


def solve_lead(problem, start="auto", options: SolverOptions | None = None, callback=None, *,
               window: int = DEFAULT_WINDOW, overlap: int | None = None, adapt_prior: bool = False,
               judge: bool = False, base: np.ndarray | None = None, limit: float | None = None,
               on_keep: Callable[[], None] | None = None) -> Lead:
    """The leading stretch of :func:`solve_windowed` (its first :data:`CALIBRATION_FRAMES`
    frames, or the first window if longer): started, its pose prior adapted (``adapt_prior``),
    and solved with its globals free where ``problem`` has globals or ``judge`` asks for its
    poses (:func:`pinrecon.reconstruct` judges the pose prior on them). An empty :class:`Lead`
    when there is nothing to do. ``base``: its search's base already solved (:func:`lead_base`).
    ``limit``: the prior's switch judged while it is solved, at that share
    (:class:`~pinrecon.unfamiliar.JudgedWhile` with ``on_keep``, ``Lead.judged``): far beyond it
    the solve stops there, unfinished."""
    if problem.g0 is None and not adapt_prior and not judge:
        return Lead()
    wp, stretch = _lead_problem(problem, window, overlap)
    if base is not None:
        start = functools.partial(hypotheses_start, base=base)
    q0 = initial_trajectory(wp, start) if isinstance(start, str) or callable(start) else \
        np.array(np.asarray(start, float)[: stretch + 1])
    lead = Lead(wp)
    if adapt_prior:  # the pose prior adapted to it, then held in every window
        wp = lead.problem = adapt_to_keyframes(wp, q0, wp.g0, keyframes=True)[0]
        lead.held_prior = pose_prior_row(wp) if decided_by_keyframes(wp) else None
    if problem.g0 is not None or judge:  # the globals solved on it, then held in every window
        lead.judged = None if limit is None else JudgedWhile(wp, limit, on_keep)
        res = solve(wp, q0, options, callback, active=wp.active, g0=wp.g0, stop_when=lead.judged)
        lead.x = res.x
        if problem.g0 is not None:
            lead.g_solved = res.g if res.g is not None else wp.g0
            lead.identified = proportions_identifiability(wp, res.x, lead.g_solved)  # what this stretch's data fix
    lead.reports = lead.problem.reports
    return lead


def solve_windowed(problem, start="auto", options: SolverOptions | None = None, callback=None, *,
                   window: int = DEFAULT_WINDOW, overlap: int | None = None, faults: bool = True,
                   turns: bool = True, mirrors: bool = False, adapt_prior: bool = False,
                   n_jobs: int | None = None, lead: Lead | None = None) -> SolveResult:
    """Solve ``problem`` (a :class:`~pinrecon.problem.ReconstructionProblem` from
    :func:`~pinrecon.problem.make_problem`) window by window; see the module docstring.

    ``start``: a start's name (:func:`pinrecon.starts.initial_trajectory`) used in every
    window, or a (T, nq) start trajectory. ``overlap`` defaults to
    :data:`DEFAULT_OVERLAP` (at most a third of the window). ``turns``, ``mirrors`` and
    ``faults``: the turn, mirror and fault stages in every window (``problem.reports["turns"]``,
    ``["mirrors"]`` and ``["faults"]``, merged over the windows; :func:`pinrecon.reconstruct`
    asks for the mirror stage where it would run it after a batch solve). ``adapt_prior``: each
    window's pose prior adapted to its start, the keyframes' poses (:func:`pinrecon.prior_yield.
    adapt_prior`, as the batch solve's stage ``yield`` does at a dense-keyframe start). Returns a
    :class:`~pinrecon.solver.SolveResult` for the whole clip: the stitched trajectory,
    the whole problem's cost there, the iterations of all windows, and the globals
    solved on the leading stretch. ``n_jobs``: worker processes for the windows (scikit-learn's
    convention: ``None`` or 1 here, one after another; -1 every CPU; at most one per window).
    ``lead``: the leading stretch already solved (:func:`solve_lead` of the same arguments).
    """
    t0 = time.perf_counter()
    views = problem.views
    if not views:
        raise InputError("the windowed solve needs a problem built from tracks (make_problem)", field="window")
    T = problem.n_frames
    window = int(window)
    plan, overlap, _ = _plan(problem, window, overlap)
    X = np.empty((T, problem.figure.nq))
    if lead is None:
        lead = solve_lead(problem, start, options, callback, window=window, overlap=overlap, adapt_prior=adapt_prior)
    g_solved, identified, held_prior = lead.g_solved, lead.identified, lead.held_prior
    if g_solved is not None:
        for key, rep in lead.reports.items():  # e.g. the hypotheses start's report
            problem.reports.setdefault(key, rep)
    reports, iterations, statuses, fault_reports, tried, mirrored = [], 0, [], [[] for _ in views], {}, {}
    user_window = getattr(callback, "window", None)
    done_until = -1  # the last frame written to X
    stopped = False
    setup = _Setup(problem, start, options, g_solved, held_prior, turns, mirrors, faults)
    jobs = _jobs(n_jobs, len(plan))
    solved = None
    if jobs > 1:
        try:
            solved = _solve_groups(setup, plan, jobs, callback, user_window)
        except BrokenProcessPool:
            warnings.warn("a worker process solving the windows died (out of memory?): the windows are solved again, "
                          "one after another", RuntimeWarning, stacklevel=2)
    if solved is None:
        solved = _solve_run(setup, plan, list(range(len(plan))), callback,
                            None if user_window is None else lambda out: user_window(_window_report(out, len(plan))))
    for out in solved:
        a, e = out.first, out.last
        for t in out.turns:  # a window tried twice (overlap): once
            tried.setdefault((t.first + a, t.last + a), replace(t, first=t.first + a, last=t.last + a))
        for m in out.mirrors:
            mirrored.setdefault((m.chain, m.mode, m.first + a, m.last + a), replace(m, first=m.first + a, last=m.last + a))
        for v, rep in out.faults:
            fault_reports[v].append((a // views[v].factor, rep))
        for key, rep in out.reports.items():  # the first window's (e.g. the hypotheses start's report)
            problem.reports.setdefault(key, rep)
        _stitch(problem.figure, X, out.x, a, done_until)
        done_until = e
        iterations += out.iterations
        statuses.append(out.status)
        reports.extend(out.report)
        if out.status == "stopped by callback":
            stopped = True
            X[e + 1 :] = X[e]  # not solved: the last solved pose held
            break
    if tried:  # the windows in which the turn stage tried a winding
        problem.reports["turns"] = TurnStage(list(tried.values()))
    if mirrored:
        problem.reports["mirrors"] = MirrorStage(list(mirrored.values()))
    for v, items in enumerate(fault_reports):
        if items:
            key = "faults" if v == 0 else f"faults_{problem.camera_names[v]}"
            problem.reports[key] = _merge_faults(items, prefix="" if v == 0 else f"{problem.camera_names[v]}_")
    g_final = g_solved if g_solved is not None else problem.g0
    costs = costs_at(problem, X, g_final)
    status = "stopped by callback" if stopped else (
        f"windowed ({len(plan)} windows of {window} frames, overlap {overlap}): "
        + ", ".join(f"{s} x{statuses.count(s)}" for s in sorted(set(statuses))))
    out = SolveResult(X, float(sum(costs.values())), costs, iterations,
                      not stopped and all(s in ("ftol", "xtol", "gtol") for s in statuses), status, reports,
                      time.perf_counter() - t0, float("nan"))
    out.g = g_final
    out.identifiability = identified
    return out


@dataclass
class _Setup:
    """What every window's solve shares (sent once to each worker process)."""

    problem: object
    start: object
    options: object
    g_solved: object
    held_prior: object
    turns: bool
    mirrors: bool
    faults: bool


@dataclass
class _Solved:
    """One window's solve: its frames, solution and the stages' reports (frames the window's)."""

    index: int
    first: int
    last: int
    x: np.ndarray
    iterations: int
    cost: float
    status: str
    report: list
    seconds: float
    turns: list
    mirrors: list
    faults: list  # (view, FaultReport)
    reports: dict  # the first window's problem reports (e.g. the start's)


def _solve_window(s: _Setup, k: int, a: int, e: int, warm, callback) -> _Solved:
    """Window ``k``, frames ``a .. e``: its start (``warm``: the solution of the frames it shares
    with the previous window, or None), the solve and the windows' stages."""
    c_w = time.process_time()
    problem = s.problem
    wp = _window_problem(problem, a, e, free_globals=False, g_held=s.g_solved)
    if isinstance(s.start, str):
        q0 = initial_trajectory(wp, s.start)
    else:
        q0 = np.array(np.asarray(s.start, float)[a : e + 1])
    if s.held_prior is not None:
        wp = with_pose_prior(wp, s.held_prior)
    if warm is not None:
        q0[: len(warm)] = warm
    res = solve(wp, q0, s.options, callback, active=wp.active)
    turns, mirrors, faults = [], [], []
    if s.turns:
        res = turn_stage(wp, res, s.options, callback)
        turns = list(getattr(wp.reports.pop("turns", None), "turns", []))
    if s.mirrors:
        res = mirror_stage(wp, res, s.options, callback)
        mirrors = list(getattr(wp.reports.pop("mirrors", None), "tried", []))
    if s.faults:
        res = fault_stage(wp, res, s.options, callback)
        faults = [(v, wp.reports[name]) for v, name in enumerate(["faults"] + [f"faults_{n}" for n in wp.camera_names[1:]])
                  if name in wp.reports]
    first = {key: rep for key, rep in wp.reports.items() if not key.startswith("faults")} if k == 0 else {}
    return _Solved(k, a, e, res.x, res.iterations, res.cost, res.status, res.report, time.process_time() - c_w,
                   turns, mirrors, faults, first)


def _window_report(out: _Solved, count: int) -> WindowReport:
    return WindowReport(out.index + 1, count, out.first, out.last, out.iterations, out.cost, out.status, out.seconds)


def _jobs(n_jobs, n_windows: int) -> int:
    """Worker processes for ``n_windows`` windows (:func:`n_processes`, the CPUs this process
    may use); one where processes cannot be forked (a process started afresh imports the
    caller's script again, which a script without a ``__main__`` guard does not survive), and in
    a process that is itself a worker (``pinrecon batch``'s, Dask's: their pool already uses the
    cores)."""
    jobs = n_processes(n_jobs, n_windows, usable_cpus())
    return jobs if may_fork() else 1


def _solve_groups(s: _Setup, plan, jobs: int, callback, user_window) -> list[_Solved]:
    """The windows in ``jobs`` runs of consecutive windows, each run in a process of its own
    (the first window of a run starts cold); the callback's reports come over a queue, and
    the callback stopping one solve stops them all. Returns the windows in order, up to the
    first one stopped."""
    global _INHERITED
    runs = [r.tolist() for r in np.array_split(np.arange(len(plan)), jobs)]
    ctx = multiprocessing.get_context("fork")  # the caller's script is not run again (see _jobs)
    _INHERITED = s  # the workers are forked at the first submit: they find the setup here, not pickled to them
    _trim_heap()
    with ctx.Manager() as manager, ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
        said, halt = manager.Queue(), manager.Event()
        try:
            futures = [pool.submit(_worker_run, plan, run, callback is not None, said, halt) for run in runs]
        finally:
            _INHERITED = None
        while True:
            try:
                kind, item = said.get(timeout=0.2)
            except queue_module.Empty:
                if all(f.done() for f in futures):
                    break
                continue
            if kind == "iteration" and callback(item):
                halt.set()
            elif kind == "window" and user_window is not None:
                user_window(item)
        done = sorted((out for f in futures for out in f.result()), key=lambda o: o.index)
    solved = []
    for k, out in enumerate(done):
        if out.index != k:  # a run stopped before this window: the windows after the gap are not kept
            break
        solved.append(out)
        if out.status == "stopped by callback":
            break
    return solved


def _solve_run(s: _Setup, plan, run, callback, on_window) -> list[_Solved]:
    """Windows ``run`` (consecutive indices into ``plan``) one after another, each starting warm
    on the frames it shares with the one before (the run's first cold); ``on_window(solved)``
    after each. Stops after a window the callback stopped."""
    figure = s.problem.figure
    X = np.empty((s.problem.n_frames, figure.nq))
    solved, done_until = [], -1
    for k in run:
        a, e = plan[k]
        out = _solve_window(s, k, a, e, X[a : done_until + 1] if done_until >= a else None, callback)
        _stitch(figure, X, out.x, a, done_until)
        done_until = e
        solved.append(out)
        if on_window is not None:
            on_window(out)
        if out.status == "stopped by callback":
            break
    return solved


def _trim_heap() -> None:
    """Give the memory this process has freed back to the system (glibc's ``malloc_trim``)
    before the workers are forked, so that they do not start with it; elsewhere nothing."""
    gc.collect()
    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError, TypeError):  # not glibc
        pass


#: the windows' setup, set while their worker processes are forked (they inherit it: a whole
#: clip's problem pickled to every worker was a second copy of it in each)
_INHERITED: _Setup | None = None


def _worker_run(plan, run, forward: bool, said, halt) -> list[_Solved]:
    """:func:`_solve_run` in a worker process, on the setup it inherited (:data:`_INHERITED`):
    the iteration reports (``forward``) and the window reports go to the queue ``said``; the
    event ``halt`` stops the solve."""
    s = _INHERITED

    def callback(report):
        if forward:
            said.put(("iteration", report))
        return halt.is_set()

    return _solve_run(s, plan, run, callback, lambda out: said.put(("window", _window_report(out, len(plan)))))

def _window_problem(problem, a: int, e: int, *, free_globals: bool, g_held):
    """The problem of reconstruction frames ``a .. e`` (inclusive): every camera's tracks,
    the keyframes in range (frames shifted), the same weights and calibration mode."""
    views = problem.views
    tracks = [v.tracks.frames(a // v.factor, e // v.factor + 1) for v in views]
    cams = [v.camera for v in views]
    keys = None
    if problem.keyframes is not None:
        f0 = views[0].factor
        lo, hi = a // f0, e // f0
        keys = Keyframes([replace(k, frame=k.frame - lo) for k in problem.keyframes if lo <= k.frame <= hi],
                         source=getattr(problem.keyframes, "source", None))
    props = problem.proportions
    n_p = 0 if props is None else props.n
    log0 = None if problem.g0 is None or props is None else problem.g0[:n_p]
    wp = make_problem(
        problem.figure, tracks[0] if len(views) == 1 else tracks, cams[0] if len(views) == 1 else cams, keys,
        fps_out=problem.fps, weights=problem.weights, calibrate=problem.calibrate, proportions=props,
        log_factors0=log0,
    )
    if wp.n_frames != e - a + 1:
        raise InputError(f"window {a}-{e} has {wp.n_frames} frames: the cameras' frame steps do not divide it",
                         field="window")
    if problem.g0 is not None and wp.g0 is not None:
        wp.g0 = np.array(problem.g0 if free_globals or g_held is None else g_held, float)
    return wp


def _stitch(figure, X: np.ndarray, Xw: np.ndarray, a: int, done_until: int) -> None:
    """Write window solution ``Xw`` (frames ``a ..``) into ``X``: frames after
    ``done_until`` as they are, the shared ones blended from X's (the previous window's)
    to ``Xw``'s over the middle half of the overlap."""
    n = len(Xw)
    shared = done_until - a + 1 if done_until >= a else 0
    if shared > 0:
        u = (np.arange(shared) + 0.5) / shared
        w = np.clip((u - 0.25) / 0.5, 0.0, 1.0)
        for i in range(shared):
            if w[i] >= 1.0:
                X[a + i] = Xw[i]
            elif w[i] > 0.0:
                X[a + i] = figure.interpolate(X[a + i], Xw[i], float(w[i]))
    X[a + shared : a + n] = Xw[shared:]


def _merge_faults(items, prefix: str) -> FaultReport:
    """One :class:`~pinrecon.faults.FaultReport` from per-window ones ``(first tracks
    frame, report)``: frames shifted to the clip, a frame reported twice (in an overlap)
    counted once."""
    seen_rep, seen_out = set(), set()
    rf, sg, of, op, oe, th = [], [], [], [], [], []
    for off, r in items:
        for f, gain in zip(np.asarray(r.repaired_frames, int) + off, np.asarray(r.swap_gain, float)):
            if int(f) not in seen_rep:
                seen_rep.add(int(f))
                rf.append(int(f))
                sg.append(float(gain))
        for f, p, err in zip(np.asarray(r.outlier_frames, int) + off, np.asarray(r.outlier_points, dtype=str),
                             np.asarray(r.outlier_error_px, float)):
            if (int(f), str(p)) not in seen_out:
                seen_out.add((int(f), str(p)))
                of.append(int(f))
                op.append(str(p))
                oe.append(float(err))
        th.append(float(r.outlier_threshold_px))
    finite = [x for x in th if np.isfinite(x)]
    return FaultReport(np.array(rf, int), np.array(sg, float), np.array(of, int), np.array(op, dtype=str),
                       np.array(oe, float), float(np.median(finite)) if finite else float("nan"), prefix=prefix)
