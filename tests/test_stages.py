"""The pipeline as named stages (``pinrecon.stages``): every stage reported, each one switched
off alone still gives a valid result, and the reports round-trip through the result file."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import pinrecon as pr
from pinrecon.errors import InputError
from pinrecon.metrics import pa_mpjpe
from pinrecon.stages import STAGES


@pytest.fixture(scope="module")
def short_walk(coco_walk):
    """One second of the detector walk (60 frames at 30 fps), no keyframes, auto camera."""
    _cam, tracks, P, _kf = coco_walk
    return tracks.frames(0, 30), P[:30]


def _solve(short_walk, human, **kw):
    tracks, _ = short_walk
    return pr.reconstruct(human, tracks, "auto", image_size=(1280, 720), **kw)


@pytest.fixture(scope="module")
def full(short_walk, human):
    return _solve(short_walk, human)


def test_every_stage_is_reported_in_order(full):
    assert [s.name for s in full.stages] == list(STAGES)
    labels, solve = full.stages[:2]
    assert labels.name == "labels" and np.isnan(labels.cost_before) and np.isnan(labels.cost_after)  # nothing solved yet
    assert solve.ran and solve.seconds > 0
    assert solve.cost_after <= solve.cost_before
    # from the solve on, the MAP cost a stage leaves is the next one's start, and the last one's is the result's
    for a, b in zip(full.stages[1:], full.stages[2:]):
        assert b.cost_before == pytest.approx(a.cost_after)
    assert full.stages[-1].cost_after == pytest.approx(full.solve.cost)
    text = full.summary()
    assert "stages (" in text and all(f"  {n}" in text for n in STAGES)


@pytest.mark.parametrize("stage", [n for n in STAGES if n != "solve"])
def test_each_stage_switched_off_alone_gives_a_valid_result(short_walk, human, full, stage):
    _, P = short_walk
    res = _solve(short_walk, human, skip=(stage,))
    rep = {s.name: s for s in res.stages}
    assert rep[stage].changed == "skipped: switched off" and rep[stage].seconds == 0.0
    assert np.all(np.isfinite(res.q)) and np.all(np.isfinite(res.keypoints3d))
    assert np.nanmean(res.reprojection_error_px) < 6.0  # 2 px detector noise
    kp = res.figure.keypoint_index(list(short_walk[0].names))
    err = pa_mpjpe(res.keypoints3d[:, kp], P)  # mm
    assert err < 60.0, f"without {stage}: PA-MPJPE {err:.1f} mm"


def test_stage_reports_round_trip_through_the_result_file(full, tmp_path):
    path = tmp_path / "r.npz"
    full.save(path)
    back = pr.load_result(path)
    np.testing.assert_equal([s.to_dict() for s in back.stages], [s.to_dict() for s in full.stages])  # NaN == NaN


def test_unknown_stage_is_refused_with_the_valid_names(short_walk, human):
    with pytest.raises(InputError, match="unknown stage.*'mirror'.*prior, yield, turns, mirrors, faults, focal, feet"):
        _solve(short_walk, human, skip=("mirror",))
    with pytest.raises(InputError, match="'solve'"):
        _solve(short_walk, human, skip=("solve",))


def test_progress_names_the_stages_that_run(short_walk, human):
    seen = []
    _solve(short_walk, human, skip=("feet",), progress=seen.append)
    assert seen == [n for n in STAGES if n != "feet"]


def test_cli_skip_and_labelled_stage_lines(short_walk, tmp_path, capsys):
    from pinrecon.cli import main

    tracks, _ = short_walk
    tracks.save(tmp_path / "t.json")
    out = tmp_path / "r.npz"
    assert main(["reconstruct", "--figure", "human", "--tracks", str(tmp_path / "t.json"), "--camera", "auto",
                 "--image-size", "1280", "720", "--skip", "turns", "feet", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "pinrecon: stage solve" in err and "pinrecon: stage turns" not in err
    rep = {s.name: s.changed for s in pr.load_result(out).stages}
    assert rep["turns"] == rep["feet"] == "skipped: switched off"
    assert main(["reconstruct", "--figure", "human", "--tracks", str(tmp_path / "t.json"), "--camera", "auto",
                 "--image-size", "1280", "720", "--skip", "solve", "--out", str(tmp_path / "x.npz")]) == 2
    assert not (tmp_path / "x.npz").exists()


@pytest.fixture(scope="module")
def cued_walk(coco_walk):
    """The short walk whose tracks carry a lifter's 3D: the true points in the camera's axes,
    scaled and shifted (a lifter's size and origin are its own), 3 cm noise."""
    from pinrecon.lifted import Lifted

    cam, tracks, P, _kf = coco_walk
    tr = tracks.frames(0, 30)
    X = 1.7 * (P[:30] @ np.asarray(cam.R).T) + np.random.default_rng(4).normal(0.0, 0.05, P[:30].shape)
    tr.lifted = Lifted(X, list(tr.names), np.ones(X.shape[:2]), "camera", "truth")
    return tr, P[:30]


def test_with_lifted_cues_one_start_and_no_mirror_or_turn_stage(cued_walk, human, monkeypatch):
    from pinrecon import stages as stages_module

    turned = []
    monkeypatch.setattr(stages_module, "turn_stage", lambda *a, **k: turned.append(1))
    res = _solve(cued_walk, human)
    rep = {s.name: s.changed for s in res.stages}
    assert rep["mirrors"].startswith("skipped")
    assert rep["turns"].startswith("skipped") and turned == []
    assert "hypothesis_chains" not in res.extras  # the lifted start, not the search
    kp = res.figure.keypoint_index(list(cued_walk[0].names))
    assert pa_mpjpe(res.keypoints3d[:, kp], cued_walk[1]) < 40.0


@pytest.mark.parametrize("stage", ["prior", "faults", "focal", "feet"])
def test_with_lifted_cues_each_stage_switched_off_alone_gives_a_valid_result(cued_walk, human, stage):
    res = _solve(cued_walk, human, skip=(stage,))
    assert {s.name: s.changed for s in res.stages}[stage] == "skipped: switched off"
    assert np.all(np.isfinite(res.q)) and np.nanmean(res.reprojection_error_px) < 6.0
    kp = res.figure.keypoint_index(list(cued_walk[0].names))
    assert pa_mpjpe(res.keypoints3d[:, kp], cued_walk[1]) < 60.0


def test_with_lifted_cues_the_priors_switch_solves_from_the_same_start(cued_walk, human, monkeypatch):
    """The lifted start turns only the root, which no pose prior sees: when the prior switches,
    the clip is solved again from the first solve's start and measured lengths instead of
    running them again (one start and one start on the measured lengths, not two of each).
    Ground truth: the true walk, and the lengths the first solve measured."""
    import sys

    from pinrecon import stages as stages_module

    reconstruct_module = sys.modules["pinrecon.reconstruct"]  # the package's name is the function's

    starts = []
    for module in (stages_module, reconstruct_module):  # the stage's start, and the start on the measured lengths
        real = module.initial_trajectory
        monkeypatch.setattr(module, "initial_trajectory", lambda *a, _real=real, **k: starts.append(1) or _real(*a, **k))
    monkeypatch.setattr(reconstruct_module, "switch_share", lambda *a: -1.0)  # every clip switches
    monkeypatch.setattr(stages_module, "forkable", lambda *a: False)  # every start here, where it is counted
    measured = []
    real_remade = stages_module._remade
    monkeypatch.setattr(stages_module, "_remade",
                        lambda p, m, *a: measured.append(m.measured_lengths) or real_remade(p, m, *a))
    res = _solve(cued_walk, human)
    rep = {s.name: s.changed for s in res.stages}
    assert rep["prior"].startswith("pose prior human_pose -> human_pose_mixture")
    assert len(starts) == 2 and len(measured) == 1
    assert res.calibration["lengths_from_tracks"] == measured[0] and len(measured[0]) == 4
    kp = res.figure.keypoint_index(list(cued_walk[0].names))
    assert pa_mpjpe(res.keypoints3d[:, kp], cued_walk[1]) < 40.0


# without cues (short_walk, 7 s: the search's start made afresh in the child) in CI only
@pytest.mark.parametrize("clip", ["cued_walk", pytest.param("short_walk", marks=pytest.mark.slow)])
def test_the_switched_solve_made_beside_is_the_one_made_after(clip, human, monkeypatch, request):
    """Where a CPU is spare, a child makes the switched prior's solve while the first solve runs
    (with the tracks' cues both start from the same lifted start; without them pinrecon's lifter
    joins and the child makes its start afresh): the result is the one the prior stage makes
    after the first solve, to the last digit (its extras too: the start's reports, the measured
    lengths), the stage's solve is not made again here, and the callback hears the switched
    solve's iterations all the same. Ground truth: the same call with no child."""
    from pinrecon import stages as stages_module

    walk = request.getfixturevalue(clip)

    reconstruct_module = sys.modules["pinrecon.reconstruct"]
    monkeypatch.setattr(reconstruct_module, "switch_share", lambda *a: -1.0)  # every clip switches
    monkeypatch.setattr(stages_module, "_judged_base", lambda run: None)  # judged after its first solve
    real = stages_module.solve
    out = {}
    for spare in (False, True):
        monkeypatch.setattr(stages_module, "forkable", lambda *a, spare=spare: spare)
        calls, heard = [], []
        monkeypatch.setattr(stages_module, "solve", lambda *a, calls=calls, **k: calls.append(1) or real(*a, **k))
        res = _solve(walk, human, callback=lambda rep, heard=heard: heard.append(rep.iteration) and False)
        out[spare] = res, len(calls), heard
    (serial, n_serial, heard_serial), (beside, n_beside, heard_beside) = out[False], out[True]
    assert {s.name: s.changed for s in beside.stages}["prior"].startswith("pose prior human_pose -> human_pose_mixture")
    np.testing.assert_array_equal(beside.q, serial.q)
    assert sorted(beside.extras) == sorted(serial.extras)
    for key, value in serial.extras.items():
        if key != "run_time_s":  # the clock's
            np.testing.assert_array_equal(beside.extras[key], value, err_msg=key)
    assert beside.calibration["lengths_from_tracks"] == serial.calibration["lengths_from_tracks"]
    assert ("hypothesis_chains" in serial.extras) == (clip == "short_walk")  # the search's report, without cues
    assert beside.solve.cost == serial.solve.cost
    assert (n_serial, n_beside) == (2, 1)  # the first solve and the switched one; the first alone
    assert heard_beside == heard_serial


@pytest.mark.parametrize("share", [1.0, 0.0])
def test_the_switch_judged_at_the_search_base(share, short_walk, human):
    """Without cues the prior's switch is judged first at the multi-hypothesis search's base
    solve (``EARLY_SWITCH``). Where the default prior does not know those poses (share 1 here) the
    clip is solved with the broader prior at once: no first solve, no child beside it, and the
    result of switching after the first solve to the last digit. Where it knows them (share 0) no
    switched solve is made beside the first in case the clip switches, and the result is the one
    made with that child. Ground truth: the same call judged after its first solve only."""
    from pinrecon import stages as stages_module

    reconstruct_module = sys.modules["pinrecon.reconstruct"]
    real_solve, real_beside, real_judged = stages_module.solve, stages_module.Beside, stages_module.judged_at_base

    def run(early):
        calls, children = [], []
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(stages_module, "forkable", lambda *a: True)
            if share:
                mp.setattr(reconstruct_module, "switch_share", lambda *a: -1.0)  # the first solve's judge switches too
            if early:
                mp.setattr(stages_module, "judged_at_base", lambda problem: (real_judged(problem)[0], share))  # the base's
            else:
                mp.setattr(stages_module, "_judged_base", lambda run: None)
            mp.setattr(stages_module, "solve", lambda *a, **k: calls.append(1) or real_solve(*a, **k))
            mp.setattr(stages_module, "Beside", lambda *a, **k: children.append(1) or real_beside(*a, **k))
            return _solve(short_walk, human), len(calls), len(children)

    out = {early: run(early) for early in (False, True)}
    (late, n_late, kids_late), (res, n_early, kids_early) = out[False], out[True]
    np.testing.assert_array_equal(res.q, late.q)
    assert res.solve.cost == late.solve.cost
    prior = {s.name: s.changed for s in res.stages}["prior"]
    if share:
        assert prior.startswith("pose prior human_pose -> human_pose_mixture (100 % of the poses unfamiliar at the")
        assert bool(res.extras["prior_switch_early"]) and "prior_switch_early" not in late.extras
        assert str(res.extras["prior_model"]) == "human_pose_mixture" == str(late.extras["prior_model"])
        assert (n_late, n_early) == (1, 1)  # here: the first solve (the switched one made beside), or the switched one
        assert (kids_late, kids_early) == (1, 0)
    else:
        assert prior == "skipped: nothing to do" and "prior_model" not in res.extras
        assert (kids_late, kids_early) == (1, 0)  # the switched solve made beside in case: not any more
    for key, value in late.extras.items():
        if key not in ("run_time_s", "prior_default_unfamiliar", "prior_switch_early"):
            np.testing.assert_array_equal(res.extras[key], value, err_msg=key)


@pytest.mark.parametrize("switch", [True, False])
def test_the_switch_judged_while_the_first_solve_runs(switch, cued_walk, human):
    """From ``JUDGED_FROM_ITERATION`` on, the first solve's poses are judged after each step
    (``EARLY_SWITCH``'s multiples). Far beyond the switch's share (forced here: a share of -1)
    the first solve stops there and the clip switches: the result of the solve run to the end and
    judged then, to the last digit. Far under it (the walk's poses, all familiar) the switched
    solve made beside is dropped while the first one runs, not at the prior stage, and the
    result is the same. Ground truth: the same call with the judging moved past any iteration."""
    from pinrecon import stages as stages_module
    from pinrecon import unfamiliar

    reconstruct_module = sys.modules["pinrecon.reconstruct"]
    real_beside = stages_module.Beside

    def run(judged_from):
        dropped, stage = [], []

        def beside(*a, **k):
            child = real_beside(*a, **k)
            cancel = child.cancel
            child.cancel = lambda: dropped.append(stage[-1]) or cancel()
            return child

        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(stages_module, "forkable", lambda *a: True)
            mp.setattr(unfamiliar, "JUDGED_FROM_ITERATION", judged_from)
            mp.setattr(stages_module, "Beside", beside)
            if switch:
                mp.setattr(reconstruct_module, "switch_share", lambda *a: -1.0)
            return _solve(cued_walk, human, progress=stage.append), dropped

    (late, dropped_late), (res, dropped) = run(10**9), run(6)
    np.testing.assert_array_equal(res.q, late.q)
    assert res.solve.cost == late.solve.cost
    for key, value in late.extras.items():
        if key not in ("run_time_s", "prior_default_unfamiliar"):
            np.testing.assert_array_equal(res.extras[key], value, err_msg=key)
    first, first_late = ({s.name: s.changed for s in r.stages}["solve"] for r in (res, late))
    late_iterations = int(first_late.split(": ")[-1].split()[0])
    assert late_iterations > 6  # the judging stops it earlier
    if switch:
        assert first.endswith(": 6 iterations, stopped: 0 % of the poses unfamiliar (the prior's switch)")
        assert int(res.extras["prior_switch_iteration"]) == 6 and "prior_switch_iteration" not in late.extras
        assert str(res.extras["prior_model"]) == "human_pose_mixture" == str(late.extras["prior_model"])
        assert "0 % of the frames' poses 6 iterations into the first solve: solved again" in res.summary()
        assert dropped == dropped_late == []  # the switched solve made beside is taken
    else:
        assert first == first_late and "prior_model" not in res.extras
        assert dropped_late == ["prior"] and dropped == ["solve"]


def test_each_warning_is_said_once_though_the_stages_make_the_problem_again(cued_walk, human, monkeypatch):
    """The stages make the problem again (the lengths measured from the tracks, the prior's switch):
    its note on points the figure does not carry is said once, not once per problem. Ground
    truth: the problem made three times or more in the call, each time saying it."""
    import warnings

    from pinrecon import problem as problem_module

    reconstruct_module = sys.modules["pinrecon.reconstruct"]
    monkeypatch.setattr(reconstruct_module, "switch_share", lambda *a: -1.0)  # the prior switches: made again
    tracks, _ = cued_walk
    extra = np.concatenate([tracks.points, tracks.points[:, :1] + 5.0], axis=1)
    odd = pr.Tracks(extra, [*tracks.names, "left_pinky_tip"], tracks.fps, lifted=tracks.lifted)
    made = []
    real_check = problem_module.warnings.warn
    monkeypatch.setattr(problem_module.warnings, "warn", lambda msg, *a, **k: made.append(str(msg)) or real_check(
        msg, *a, **k))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = pr.reconstruct(human, odd, "auto", image_size=(1280, 720))
    notes = [str(w.message) for w in caught if "points not on the figure" in str(w.message)]
    assert str(res.extras["prior_model"]) == "human_pose_mixture"
    assert sum("points not on the figure" in m for m in made) >= 3
    assert notes == [made[0]] and "left_pinky_tip" in notes[0]


def test_a_callback_that_stops_the_switched_solve_is_obeyed_beside(cued_walk, human, monkeypatch):
    """A callback that stops the switched solve at its first iteration: the solve made beside
    is not taken (it ran to the end), the stage solves it here and stops where the callback
    says, as without a child. Ground truth: the same call with no child."""
    from pinrecon import stages as stages_module

    reconstruct_module = sys.modules["pinrecon.reconstruct"]
    monkeypatch.setattr(reconstruct_module, "switch_share", lambda *a: -1.0)
    out = {}
    for spare in (False, True):
        monkeypatch.setattr(stages_module, "forkable", lambda *a, spare=spare: spare)
        stage, stopped = [], []
        res = _solve(cued_walk, human, progress=stage.append,
                     callback=lambda rep, stage=stage, stopped=stopped: stage[-1] == "prior" and not stopped.append(1))
        out[spare] = res, len(stopped)
    (serial, n_serial), (beside, n_beside) = out[False], out[True]
    prior = [{s.name: s for s in r.stages}["prior"] for r in (serial, beside)]
    assert prior[0].changed.startswith("pose prior") and prior[1].changed == prior[0].changed
    assert prior[1].cost_after == prior[0].cost_after
    assert (n_serial, n_beside) == (1, 2)  # stopped at the first iteration; beside, at the first replayed, then here
    np.testing.assert_array_equal(beside.q, serial.q)
