"""Turns: how many times the trunk turns through a fast turn, decided by the MAP cost.

One camera sees a turning trunk's facing only up to its depth reflection, frame by frame.
Through a fast turn (a pirouette, a spin on the spot) a solve started from a poor guess can
take the turn the wrong way round, unwind it halfway, or add a whole turn that is not there:
nearly every frame still fits the image, and what is wrong is the *winding*, a discrete
ambiguity like a limb's reflection that no small step of Gauss-Newton crosses. On
``bench_real``'s dance (05_11) without keyframes the start's trunk spun a spurious whole turn
in a sixth of a second (frames 95-115 at 120 fps) where the dancer barely turned, and took
the pirouette (392 degrees in 100 frames) forwards and back; its MAP cost was 1100-2700 nats
above the same trajectory wound right.

:func:`wind_turns` finds the windows in which the root turns faster than ``rate_dps`` about
the figure's up axis (the root's local axis whose world direction stays put over the clip,
:func:`turn_axis`), winds the trajectory by one whole turn either way there
(:func:`wind`: the root rotated about that axis by ``2 pi s(t)``, ``s`` a smoothstep from 0
before the window to 1 after it, so that nothing outside the window changes), solves each
candidate warm and keeps it when the whole MAP cost falls.

A 3D keyframe inside a fast window fixes the facing at its frame, not how many turns lie
between it and its neighbours, so the window is cut there (:func:`split_at`) and each piece
is wound on its own: a whole turn over a piece leaves its ends as they were. Winding the
whole window instead turns the keyframe's frame with it (half a turn at the window's
middle), and the MAP cost refuses it. On ``bench_real``'s dance with keyframes on frames
0, 197, 393 and 590 (197 in the middle of the double pirouette) the pirouette had a whole
turn too few on both sides of 197; cut there, the one before it is wound (1000-1100 nats
cheaper), and PA-MPJPE goes from 66.1 to 56.0 mm at 45 degrees and 75.3 to 45.9 mm at 60
(flips 18.8 -> 15.6 and 30.9 -> 17.8 %); before the cut these four keyframes did worse
than the first and last alone (55.1 and 50.0 mm).

The start's turns are decided before the whole problem is solved, and the keyframe start
(denser keyframes) has no turn step at all: it interpolates the root between keyframes, a
whole turn short wherever the figure turns more than half a turn between two of them.
:func:`turn_stage` therefore winds the *solved* motion as well (the pipeline runs it right
after the solve, candidates solved warm with the global unknowns free, at most 40
iterations each, a kept one solved to the end), in the windows where the solution's
heading turns back against its net turn (:func:`turned_back`: a turn too few between two
keyframes follows the images round and comes back to meet the next keyframe). On the
dance with four keyframes at 45 degrees it winds the piece after frame 197 that the start
left (1361 nats cheaper): 56.0 -> 37.5 mm, 15.6 -> 11.1 % flips; with six (the keyframe
start) it winds the pirouette's pieces: 78.8 -> 50.2 mm, 23.5 -> 17.1 % (bench/README.md,
"The dance with more keyframes").
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import pairwise

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.spatial.transform import Rotation

from ..contact import true_runs
from ..processes import Beside, forkable
from ..solver import SolverOptions, globals_of, solve

__all__ = ["Turn", "TurnStage", "fast_turn_windows", "split_at", "turn_angle", "turn_axis", "turn_stage", "turned_back",
           "turns_array", "wind", "wind_turns"]


@dataclass
class Turn:
    """A window tried: frames ``[first, last)``; ``turns`` the winding kept (+1, -1 about
    the up axis, or 0: left as it was); ``gain`` the MAP cost it saved (nats, 0 if none)."""

    first: int
    last: int
    turns: int
    gain: float


def turns_array(turns) -> np.ndarray:
    """(W, 4) :class:`Turn` rows for ``Result.extras``: first frame, frame after the last,
    the turns kept (0: none), the nats saved."""
    return np.array([[t.first, t.last, t.turns, t.gain] for t in turns], float).reshape(-1, 4)


def _root_rotations(Q) -> np.ndarray:
    """(T, 3, 3) the free-flyer root's rotation matrices (x y z w quaternions in ``Q[:, 3:7]``)."""
    return Rotation.from_quat(np.asarray(Q, float)[:, 3:7]).as_matrix()


def turn_axis(Q, min_resultant: float = 0.7) -> tuple[int, np.ndarray] | None:
    """The root's local axis that stays put in the world over ``Q`` (the body's up, about
    which it turns): ``(local axis index, world direction)``, the axis whose world
    directions have the longest mean resultant (a pelvis leaning 25 degrees that spins
    about the vertical has 0.9, and its mean direction is the vertical); None if even that
    is shorter than ``min_resultant`` (the figure tumbles: no up axis to wind about)."""
    R = _root_rotations(Q)
    means = R.mean(axis=0)  # (3, 3): column j the mean world direction of local axis j
    lengths = np.linalg.norm(means, axis=0)
    j = int(np.argmax(lengths))
    if lengths[j] < min_resultant:
        return None
    return j, means[:, j] / lengths[j]


def turn_angle(Q, axis: int, up) -> np.ndarray:
    """(T,) the root's heading about world direction ``up`` (radians, unwrapped): the angle
    of its next local axis after ``axis``, projected on the plane normal to ``up``."""
    R = _root_rotations(Q)
    up = np.asarray(up, float)
    v = R[:, :, (axis + 1) % 3]
    v = v - (v @ up)[:, None] * up
    a = np.cross(up, [1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.cross(up, [0.0, 0.0, 1.0])
    a /= np.linalg.norm(a)
    b = np.cross(up, a)
    return np.unwrap(np.arctan2(v @ b, v @ a))


def fast_turn_windows(angle, fps: float, rate_dps: float = 300.0, margin_s: float = 0.1,
                      smooth_s: float = 0.05) -> list[tuple[int, int]]:
    """Frame windows ``[a, b)`` where the heading ``angle`` (T,) turns faster than
    ``rate_dps`` degrees per second (averaged over ``smooth_s``), widened by ``margin_s``
    either side and merged where they overlap."""
    angle = np.asarray(angle, float)
    T = len(angle)
    if T < 3:
        return []
    rate = np.degrees(np.abs(np.gradient(angle))) * float(fps)
    rate = uniform_filter1d(rate, max(1, round(smooth_s * fps)))
    fast = rate > rate_dps
    m = round(margin_s * fps)
    out: list[tuple[int, int]] = []
    for a, b in true_runs(fast):
        a, b = max(0, int(a) - m), min(T, int(b) + m)
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], b)
        else:
            out.append((a, b))
    return out


def split_at(windows, frames, min_frames: int = 3) -> list[tuple[int, int]]:
    """``windows`` ``[a, b)`` cut at every frame of ``frames`` inside them, pieces shorter
    than ``min_frames`` dropped: a whole turn wound over a piece leaves the orientation at
    its ends as it was, so a keyframe at a cut keeps its pose while the turns on either
    side of it are decided apart (a keyframe in the middle of a pirouette fixes the
    facing there, not how many turns lie between it and its neighbours)."""
    cuts = np.asarray(sorted({int(f) for f in frames}), int)
    out = []
    for a, b in windows:
        inner = cuts[(cuts > a) & (cuts < b - 1)]
        edges = [a, *inner.tolist(), b]
        out += [(p, q) for p, q in pairwise(edges) if q - p >= min_frames]
    return out


def wind(Q, up, first: int, last: int, turns: int) -> np.ndarray:
    """``Q`` with its root turned ``turns`` whole turns more about world direction ``up``
    (through the root's own position) between frames ``first`` and ``last``: the extra
    angle ``2 pi turns s(t)`` rises from 0 to its full value along a smoothstep ``s`` over
    the window, and a whole turn is no turn at all outside it."""
    Q = np.array(Q, float)
    t = np.arange(len(Q))
    s = np.clip((t - first) / max(last - first, 1), 0.0, 1.0)
    s = s * s * (3.0 - 2.0 * s)
    extra = Rotation.from_rotvec(np.outer(2.0 * np.pi * turns * s, np.asarray(up, float)))
    Q[:, 3:7] = (extra * Rotation.from_quat(Q[:, 3:7])).as_quat()
    return Q


def _windows(problem, Q, rate_dps, margin_s, min_back_deg=None):
    """(up axis, fast-turn windows cut at the keyframes) of ``Q``, or None; with
    ``min_back_deg`` only the windows in which the heading turns back against its own net
    turn by more than that (:func:`turned_back`)."""
    if not problem.figure.floating or problem.n_frames < 3:
        return None
    found = turn_axis(Q)
    if found is None:
        return None
    axis, up = found
    angle = turn_angle(Q, axis, up)
    windows = fast_turn_windows(angle, float(problem.fps or 30.0), rate_dps, margin_s)
    windows = split_at(windows, [int(k.frame) * problem.factor for k in (problem.keyframes or ())])
    if min_back_deg is not None:
        windows = [(a, b) for a, b in windows if turned_back(angle[a:b]) > np.radians(min_back_deg)]
    return (up, windows) if windows else None


def turned_back(angle) -> float:
    """How far (radians) a heading ``angle`` (n,) turns back against its net turn over the
    window (the largest drawdown along the net direction; 0 for a steady turn either way)."""
    angle = np.asarray(angle, float)
    if len(angle) < 2:
        return 0.0
    x = angle if angle[-1] >= angle[0] else -angle
    return float(np.max(np.maximum.accumulate(x) - x))


def _wind_windows(problem, Q, cost, up, windows, solve_one, min_gain, beside: bool = False):
    """Each window wound a whole turn either way from the current best and solved
    (``solve_one(Q) -> SolveResult``); the cheaper kept when it saves more than
    ``min_gain``. ``beside``: the turn the other way solved in a child forked meanwhile
    where a CPU is spare (:class:`~pinrecon.processes.Beside`; ``solve_one`` calls nobody
    back). Returns (the last kept SolveResult or None, a :class:`Turn` per window)."""
    fig = problem.figure
    kept, report = None, []
    fork = beside and forkable(problem.n_frames)
    for a, b in windows:
        best, best_k = None, 0
        starts = [fig.clamp(fig.normalize(wind(Q, up, a, b, k)), 1e-3) for k in (1, -1)]
        with Beside(solve_one, starts[1], fork=fork) as other:
            solved = [solve_one(starts[0]), other.result()]
        for k, res in zip((1, -1), solved):
            if res.cost < (cost if best is None else best.cost) - min_gain:
                best, best_k = res, k
        report.append(Turn(a, b, best_k, cost - float(best.cost) if best is not None else 0.0))
        if best is not None:
            kept, Q, cost = best, fig.normalize(best.x), float(best.cost)
    return kept, report


def wind_turns(problem, Q, options: SolverOptions | None = None, *, cost: float | None = None,
               rate_dps: float = 300.0, margin_s: float = 0.1,
               min_gain: float = 1.0) -> tuple[np.ndarray, list[Turn]]:
    """``Q`` wound right through its fast turns (module docstring): for each window of
    :func:`fast_turn_windows` of the root's heading, ``Q`` wound a whole turn either way
    and solved warm (``options``, the global unknowns held at their start); the cheaper is
    kept when it saves more than ``min_gain`` nats. A window is cut at the problem's
    keyframes inside it (:func:`split_at`) and each piece wound on its own. ``cost``: ``Q``'s
    MAP cost when ``Q`` is already a solution with ``options`` (else it is solved first).
    Returns (the trajectory, solved if a winding was kept, else ``Q`` itself; a
    :class:`Turn` per window)."""
    fig = problem.figure
    found = _windows(problem, Q, rate_dps, margin_s)
    if found is None:
        return Q, []
    options = options or SolverOptions(max_iterations=40, ftol=1e-4)
    if cost is None:
        cur = solve(problem, fig.clamp(Q, 1e-3), options, active=problem.active)
        Q, cost = fig.normalize(cur.x), float(cur.cost)
    kept, report = _wind_windows(problem, Q, cost, *found,
                                 lambda X: solve(problem, X, options, active=problem.active), min_gain, beside=True)
    return (Q if kept is None else fig.normalize(kept.x)), report


@dataclass
class TurnStage:
    """The windows :func:`turn_stage` tried on the solved motion; ``to_extras`` gives
    ``Result.extras["solution_turns"]`` (W, 4): first frame, frame after the last, the
    turns kept (0: none), the nats saved."""

    turns: list

    def to_extras(self) -> dict:
        return {"solution_turns": turns_array(self.turns)}


def turn_stage(problem, res, options: SolverOptions | None = None, callback=None, *, rate_dps: float = 300.0,
               margin_s: float = 0.1, min_gain: float = 1.0, trial_iterations: int = 40,
               min_back_deg: float = 15.0):
    """The solved motion ``res`` (a :class:`~pinrecon.solver.SolveResult`) wound through its
    fast turns as :func:`wind_turns` winds a start, each candidate solved warm with
    ``options`` and the global unknowns free from the solution's, as the solve itself had
    them (the fault stage's way). A start's turns are decided before the whole problem is
    solved; the solution's heading can still hold a turn too few where a keyframe or a
    second solve put it (bench/README.md, "The dance with more keyframes"). Only the windows
    in which the solution turns back against its own net turn by more than ``min_back_deg``
    are tried (:func:`turned_back`): a turn too few between two keyframes shows as a heading
    that follows the images round and comes back to meet the next keyframe, where a pirouette
    solved right turns one way (the lab dance, a keyframe every quarter second, has 8 such
    pieces and none turning back; trying them all took its solve from 1.2 to 20.8 s);
    ``min_back_deg=None`` tries every window. Each candidate is solved at most
    ``trial_iterations`` long; a winding kept is then solved to the end with ``options``.
    Returns that solve (``res`` itself when no winding saves ``min_gain`` nats); the windows
    tried go to ``problem.reports["turns"]`` (:class:`TurnStage`)."""
    fig = problem.figure
    if res.status == "stopped by callback":  # the user stopped the solve: not to be resumed here
        return res
    Q = fig.normalize(res.x)
    found = _windows(problem, Q, rate_dps, margin_s, min_back_deg)
    if found is None:
        return res
    def warm(r, X, opts):  # solved from X with r's global unknowns as the start of theirs
        g = globals_of(r)
        return solve(problem, X, opts, callback, active=problem.active, g0=g)

    options = options or SolverOptions()
    trial = replace(options, max_iterations=min(options.max_iterations, trial_iterations))
    kept, report = _wind_windows(problem, Q, float(res.cost), *found, lambda X: warm(res, X, trial), min_gain)
    reports = getattr(problem, "reports", None)
    if reports is not None:
        reports["turns"] = TurnStage(report)
    return res if kept is None else warm(kept, kept.x, options)  # a kept winding solved to the end
