"""The trunk's winding through fast turns (pinrecon.starts.turns), against motions whose
answer is known: each rotation below is written out here with SciPy, not taken from the
module."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import pinrecon as pr
from pinrecon.problem import make_problem
from pinrecon.solver import SolverOptions, solve
from pinrecon.starts.turns import (
    fast_turn_windows,
    split_at,
    turn_angle,
    turn_axis,
    wind,
    wind_turns,
)
from pinrecon.synthetic import (
    COCO_BODY_FROM_CMU,
    human_walk,
    perspective_side_camera,
    project_tracks,
)

NAMES = list(COCO_BODY_FROM_CMU)


def _spun(Q, first, last, turns, up=(0.0, 1.0, 0.0)):
    """Q with ``turns`` whole turns about world ``up`` added between ``first`` and ``last``
    along a smoothstep, written out independently of :func:`wind`."""
    Q = np.array(Q, float)
    for t in range(len(Q)):
        s = min(max((t - first) / (last - first), 0.0), 1.0)
        s = s * s * (3 - 2 * s)
        R = Rotation.from_rotvec(2 * np.pi * turns * s * np.asarray(up)) * Rotation.from_quat(Q[t, 3:7])
        Q[t, 3:7] = R.as_quat()
    return Q


def _walk_problem(T):
    """The human walking T frames at 30 fps, seen 50 degrees from side-on at 5 m with 1 px
    noise: the figure, the truth, the camera, the problem and short solver options."""
    fig = pr.Figure.human()
    _, Q = human_walk(T, 30.0)
    cam = perspective_side_camera(Q, 50.0, distance_m=5.0)
    tracks = project_tracks(fig, Q, cam, NAMES, fps=30.0, noise_px=1.0, seed=3)
    return fig, Q, cam, make_problem(fig, tracks, cam), SolverOptions(max_iterations=40, ftol=1e-4)


def _angle_deg(Qa, Qb):
    return np.degrees((Rotation.from_quat(Qa[:, 3:7]).inv() * Rotation.from_quat(Qb[:, 3:7])).magnitude())


def test_wind_is_a_whole_turn_inside_the_window_and_nothing_outside():
    _, Q = human_walk(40, 30.0)
    up = np.array([0.0, 1.0, 0.0])
    W = wind(Q, up, 10, 30, 1)
    assert np.all(_angle_deg(W, _spun(Q, 10, 30, 1)) < 1e-6)
    d = _angle_deg(W, Q)
    assert np.all(d[:11] < 1e-6) and np.all(d[30:] < 1e-6)
    assert d[20] == pytest.approx(180.0, abs=1e-6)  # halfway through the smoothstep: half a turn
    assert np.allclose(W[:, :3], Q[:, :3]) and np.allclose(W[:, 7:], Q[:, 7:])  # the root's place, the joints


def test_turn_axis_and_fast_windows_of_a_spin():
    _, Q = human_walk(120, 60.0)
    S = _spun(Q, 40, 70, -1)  # a whole turn in half a second: 720 degrees/s at its mean
    axis, up = turn_axis(S)
    # the human's local y is up (this walk's pelvis leans forward 25 degrees, hence the slack)
    assert axis == 1 and np.degrees(np.arccos(up @ np.array([0.0, 1.0, 0.0]))) < 30.0
    a = turn_angle(S, axis, up)
    assert np.degrees(abs(a[-1] - a[0])) == pytest.approx(360.0, abs=25.0)  # the walk itself turns a little
    ws = fast_turn_windows(a, 60.0, rate_dps=300.0, margin_s=0.1)
    assert len(ws) == 1
    (lo, hi), = ws
    assert 34 <= lo <= 48 and 62 <= hi <= 76  # the spin's fast middle, 6 frames (0.1 s) either side
    assert fast_turn_windows(turn_angle(Q, axis, up), 60.0) == []  # the walk alone: no fast turn


def test_turn_axis_refuses_a_tumbling_figure():
    _, Q = human_walk(60, 30.0)
    Q = Q.copy()
    rot = Rotation.from_rotvec(np.outer(np.linspace(0, 2 * np.pi, 60, endpoint=False), [1.0, 0.0, 0.0]))
    Q[:, 3:7] = (rot * Rotation.from_quat(Q[:, 3:7])).as_quat()  # somersaults: every axis sweeps around
    Q2 = Q.copy()
    rot2 = Rotation.from_rotvec(np.outer(np.linspace(0, 2 * np.pi, 60, endpoint=False), [0.0, 0.0, 1.0]))
    Q2[:, 3:7] = (rot2 * Rotation.from_quat(Q[:, 3:7])).as_quat()
    assert turn_axis(Q2) is None


def test_a_spurious_turn_is_wound_out():
    """A walk seen from 50 degrees; the start has a whole turn the walker never made (a sixth
    of a second, as the dance's start had in frames 95-115): wound out, the start's root is
    back within a few degrees of the truth's everywhere, and the report says so."""
    fig = pr.Figure.human()
    _, Q = human_walk(60, 30.0)
    cam = perspective_side_camera(Q, 50.0, distance_m=5.0)
    tracks = project_tracks(fig, Q, cam, NAMES, fps=30.0, noise_px=1.0, seed=3)
    problem = make_problem(fig, tracks, cam)
    start = _spun(Q, 25, 31, 1)
    assert _angle_deg(start, Q).max() > 170.0
    out, report = wind_turns(problem, start)
    assert [(t.turns, t.first <= 26 and t.last >= 30) for t in report] == [(-1, True)]
    assert report[0].gain > 100.0
    # as close as the same solve started from the truth itself (one view, no keyframes:
    # its root settles tens of degrees off, the same in every frame), not a turn apart
    direct = solve(problem, fig.clamp(Q, 1e-3), SolverOptions(max_iterations=40, ftol=1e-4), active=problem.active)
    assert np.abs(_angle_deg(out, Q) - _angle_deg(fig.normalize(direct.x), Q)).max() < 5.0
    assert _angle_deg(out, Q).max() < 60.0


def test_the_turn_the_other_way_solved_beside_is_the_one_solved_here(monkeypatch, spy_beside):
    """Each window's two windings do not depend on each other: where a CPU is spare the turn
    the other way is solved in a forked child meanwhile (``pinrecon.processes.Beside``). The
    same start and report to the digit as solved here, and it was the child's."""
    from pinrecon.starts import turns

    fig = pr.Figure.human()
    _, Q = human_walk(60, 30.0)
    cam = perspective_side_camera(Q, 50.0, distance_m=5.0)
    problem = make_problem(fig, project_tracks(fig, Q, cam, NAMES, fps=30.0, noise_px=1.0, seed=3), cam)
    start = _spun(Q, 25, 31, 1)
    forked = spy_beside(turns)
    out = {}
    for beside in (False, True):
        monkeypatch.setattr(turns, "forkable", lambda frames=None, b=beside: b)
        out[beside] = wind_turns(problem, start)
    assert set(forked[: len(forked) // 2]) == {False} and set(forked[len(forked) // 2:]) == {True}
    assert np.array_equal(out[False][0], out[True][0]) and out[False][1] == out[True][1]
    assert out[True][1][0].turns == -1  # the turn the other way (the child's) was the one kept


def test_turned_back_is_the_drawdown_against_the_net_turn():
    from pinrecon.starts.turns import turned_back

    assert turned_back(np.radians([0.0, 90.0, 180.0, 360.0])) == 0.0  # a steady turn
    assert turned_back(np.radians([0.0, -90.0, -360.0])) == 0.0  # the other way
    assert np.isclose(np.degrees(turned_back(np.radians([0.0, 100.0, 40.0, 120.0]))), 60.0)
    assert np.isclose(np.degrees(turned_back(np.radians([0.0, -50.0, 30.0, -80.0]))), 80.0)  # -50 back to +30
    assert turned_back(np.zeros(1)) == 0.0


def test_windows_are_cut_at_keyframes():
    assert split_at([(10, 50), (60, 80)], [0, 30, 49, 70, 100]) == [(10, 30), (30, 50), (60, 70), (70, 80)]
    assert split_at([(10, 50)], [11, 200]) == [(11, 50)]  # a piece under 3 frames is dropped
    assert split_at([(10, 50)], []) == [(10, 50)]


def test_winding_the_pieces_leaves_every_keyframe_pose_as_it_was():
    """A fast window with a keyframe inside: wound whole, the keyframe's frame turns with it
    (half a turn at the window's middle); wound piece by piece, every keyframe frame keeps
    its orientation (angles from SciPy)."""
    _, Q = human_walk(60, 30.0)
    up = np.array([0.0, 1.0, 0.0])
    assert _angle_deg(wind(Q, up, 20, 36, 1), Q)[28] > 170.0
    for a, b in split_at([(20, 36)], [28, 33]):
        for k in (1, -1):
            moved = _angle_deg(wind(Q, up, a, b, k), Q)
            assert moved[[20, 28, 33, 36]].max() < 1e-6
            assert moved[a:b].max() > 90.0 or b - a < 6


def test_the_report_and_the_summary_say_what_was_wound():
    from types import SimpleNamespace

    from pinrecon.starts.hypotheses import HypothesisReport
    from pinrecon.starts.turns import Turn

    rep = HypothesisReport([], np.zeros((10, 0), int), np.zeros((10, 0)), turns=[Turn(2, 8, -1, 812.4), Turn(8, 10, 0, 0.0)])
    ex = rep.to_extras()
    assert ex["hypothesis_turns"].tolist() == [[2.0, 8.0, -1.0, 812.4], [8.0, 10.0, 0.0, 0.0]]
    lines = pr.Result.faults_summary(SimpleNamespace(extras=ex, fps=30.0, figure=None))
    wound = [s for s in lines if s.startswith("trunk turned")]
    assert wound == [("trunk turned -1 whole turn in frames 2-7 (0.07-0.23 s), cost 812 lower (a fast turn the "
                      "start took the wrong way round; pinrecon.starts.turns)")]
    assert "hypothesis_turns" in HypothesisReport([], np.zeros((1, 0), int), np.zeros((1, 0))).to_extras()


def test_the_solved_motion_is_wound_too():
    """turn_stage: a solution that kept a whole turn the walker never made (the start's
    turns are decided before the whole problem is solved) is wound out after the solve, the
    global unknowns free as in the solve; the result's extras and summary say so."""
    from types import SimpleNamespace

    from pinrecon.starts.turns import turn_stage

    fig, Q, _, problem, options = _walk_problem(60)
    spun = solve(problem, fig.clamp(_spun(Q, 25, 31, 1), 1e-3), options, active=problem.active)
    assert _angle_deg(fig.normalize(spun.x), Q).max() > 90.0  # the solve alone keeps (most of) the turn
    # by default only windows that turn back against their net turn are tried (a turn too few
    # between keyframes); this spurious turn is one way, so it is left to the start's winding
    assert turn_stage(problem, spun, options) is spun
    out = turn_stage(problem, spun, options, min_back_deg=None)  # every window
    assert out.cost < spun.cost - 100.0
    direct = solve(problem, fig.clamp(Q, 1e-3), options, active=problem.active)
    assert np.abs(_angle_deg(fig.normalize(out.x), Q) - _angle_deg(fig.normalize(direct.x), Q)).max() < 5.0
    ex = problem.reports["turns"].to_extras()
    rows = ex["solution_turns"]
    assert rows.shape[1] == 4 and list(rows[rows[:, 2] != 0][:, 2]) == [-1.0]
    lines = pr.Result.faults_summary(SimpleNamespace(extras=ex, fps=30.0, figure=None))
    assert any(s.startswith("trunk turned -1 whole turn") and "turn_stage" in s for s in lines)
    # a solution without a fast turn is returned as it is, and so is a solve the user stopped
    assert turn_stage(problem, direct, options) is direct
    stopped = replace(spun, status="stopped by callback")
    assert turn_stage(problem, stopped, options) is stopped


def test_each_window_of_a_long_clip_is_wound_too(monkeypatch):
    """The windowed solve (long clips) runs the turn stage in every window, as the batch
    pipeline does after its solve: a spurious whole turn in the second window's start is
    wound out, and the report names it in the clip's frames, not the window's."""
    from functools import partial

    from pinrecon import windowed
    from pinrecon.starts.turns import turn_stage

    fig, Q, _, problem, options = _walk_problem(120)
    start = fig.clamp(_spun(Q, 90, 96, 1), 1e-3)  # windows (0, 79) and (40, 119): the turn in the second only
    # every fast window tried: the default's filter (tested above) leaves a one-way turn to the start
    monkeypatch.setattr(windowed, "turn_stage", partial(turn_stage, min_back_deg=None))
    kept = windowed.solve_windowed(problem, start, options, window=80, turns=False, faults=False)
    assert "windowed (2 windows" in kept.status and "turns" not in problem.reports
    assert _angle_deg(fig.normalize(kept.x), Q)[88:100].max() > 90.0  # the window's solve alone keeps it
    wound = windowed.solve_windowed(problem, start, options, window=80, faults=False)
    direct = windowed.solve_windowed(problem, fig.clamp(Q, 1e-3), options, window=80, turns=False, faults=False)
    assert np.abs(_angle_deg(fig.normalize(wound.x), Q) - _angle_deg(fig.normalize(direct.x), Q)).max() < 5.0
    assert wound.cost < kept.cost - 100.0
    rows = problem.reports["turns"].to_extras()["solution_turns"]
    turned = rows[rows[:, 2] != 0]
    assert len(turned) == 1 and turned[0, 2] == -1.0
    assert 40 <= turned[0, 0] <= 90 and 96 <= turned[0, 1] <= 120  # the clip's frames
