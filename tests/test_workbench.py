"""The workbench's server logic through its Python API (pinrecon.workbench.Session):
flips, point and joint keyframes, undo/redo, warm-start re-solve, save/reload, exports,
the HTML player. Ground truth is the synthetic motion of tests/workbench_case.py."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from workbench_case import (
    FLIP_FRAME,
    FLOOR,
    GAP,
    SEGMENT,
    WEIGHTS,
    all_flips,
    flipped_frames,
    make_case,
)

import pinrecon as pr
from pinrecon.cli import main
from pinrecon.workbench import Session, export_html, segments
from pinrecon.workbench.edits import flip_span, mirror_segment


@pytest.fixture(scope="module")
def case():
    return make_case()


@pytest.fixture(scope="module")
def start(case):
    """The batch solve of the case (what `pinrecon reconstruct` gives): the right shank
    is flipped inside the marker drop-out."""
    fig, Q, cam, tracks, keys = case
    return pr.reconstruct(fig, tracks, cam, keys, weights=WEIGHTS, floor=FLOOR)


@pytest.fixture(scope="module")
def fixed(case, start, tmp_path_factory):
    """One flip at frame 30, one re-solve, saved."""
    fig, Q, cam, tracks, keys = case
    s = Session(fig, tracks, cam, keys, result=start, weights=WEIGHTS, floor=FLOOR)
    before = s.q
    key = s.flip(FLIP_FRAME, SEGMENT)
    warm = s.q
    report = s.solve()
    out = tmp_path_factory.mktemp("wb")
    s.save(out / "keyframes.json", out / "result.npz")
    return s, before, warm, key, report, out


def test_the_case_has_one_wrongly_flipped_limb(case, start):
    fig, Q, cam, tracks, keys = case
    flips = all_flips(fig, cam, start.keypoints3d, Q)
    assert set(flips) == {SEGMENT}
    frames = flipped_frames(fig, cam, start.keypoints3d, Q, "right_knee", "right_ankle")
    assert len(frames) >= 15 and GAP[0] <= frames.min() and frames.max() <= GAP[1]
    assert FLIP_FRAME in frames


def test_resolving_without_the_flip_keeps_it_flipped(case, start):
    # the wrong side is a local minimum: a warm re-solve alone does not leave it
    fig, Q, cam, tracks, keys = case
    s = Session(fig, tracks, cam, keys, result=start, weights=WEIGHTS, floor=FLOOR)
    s.set_joint(FLIP_FRAME, "left_elbow_Z", s.joint_value(FLIP_FRAME, "left_elbow_Z"))  # a no-op edit
    s.solve()
    assert len(flipped_frames(fig, cam, s.keypoints3d, Q, "right_knee", "right_ankle")) >= 15


def test_flip_makes_a_partial_keyframe_of_the_mirrored_limb(case, start, fixed):
    fig, Q, cam, tracks, keys = case
    s, before, warm, key, report, out = fixed
    assert key.frame == FLIP_FRAME and set(key.points) == {"right_knee", "right_ankle"}
    P = fig.keypoints(before[FLIP_FRAME])
    knee, ankle = (P[list(fig.keypoint_names).index(n)] for n in ("right_knee", "right_ankle"))
    view = cam.R[2]
    # the knee stays; the ankle's image does not move; its depth behind/in front of the knee flips
    np.testing.assert_allclose(key.points["right_knee"], knee, atol=1e-12)
    np.testing.assert_allclose(cam.project(key.points["right_ankle"]), cam.project(ankle), atol=1e-9)
    assert (key.points["right_ankle"] - knee) @ view == pytest.approx(-((ankle - knee) @ view), abs=1e-12)
    # the warm start is flipped over the excursion around frame 30 (up to the nearest minima
    # of the depth difference), not only at frame 30: 23 wrong frames before, 7 after
    wrong_warm = flipped_frames(fig, cam, fig.keypoints(warm), Q, "right_knee", "right_ankle")
    assert len(wrong_warm) <= 8 and not np.any((wrong_warm >= 22) & (wrong_warm <= 40))


def test_flip_and_resolve_fixes_the_limb(case, fixed):
    fig, Q, cam, tracks, keys = case
    s, before, warm, key, report, out = fixed
    assert len(flipped_frames(fig, cam, s.keypoints3d, Q, "right_knee", "right_ankle")) == 0
    assert all_flips(fig, cam, s.keypoints3d, Q) == {}
    assert not s.needs_solve
    # the motion inside the drop-out is now right: mean error of the ankle there
    a, b = GAP
    err = np.linalg.norm(s.keypoints3d[a : b + 1] - fig.keypoints(Q[a : b + 1]), axis=-1)
    err_before = np.linalg.norm(fig.keypoints(before[a : b + 1]) - fig.keypoints(Q[a : b + 1]), axis=-1)
    ankle = list(fig.keypoint_names).index("right_ankle")
    print(f"right ankle error in the drop-out: {err_before[:, ankle].mean():.3f} m -> {err[:, ankle].mean():.3f} m")
    assert err[:, ankle].mean() < 0.4 * err_before[:, ankle].mean()
    # a window around the edit was solved first, then the whole
    assert report.window is not None and report.window[0] <= FLIP_FRAME <= report.window[1]
    assert report.full_iterations >= 1


def test_saved_keyframes_reproduce_the_result_through_the_command(case, fixed, tmp_path):
    fig, Q, cam, tracks, keys = case
    s, *_, out = fixed
    tracks.save(tmp_path / "tracks.json")
    cam.save(tmp_path / "camera.json")
    code = main(["reconstruct", "--figure", "human", "--calibrate", "none", "--pose-prior", "none", "--floor", "none", "--tracks", str(tmp_path / "tracks.json"), "--camera",
                 str(tmp_path / "camera.json"), "--keyframes", str(out / "keyframes.json"), "--out",
                 str(tmp_path / "again.npz"), "--quiet"])
    assert code == 0
    again = pr.load_result(tmp_path / "again.npz")
    d = np.linalg.norm(again.keypoints3d - s.keypoints3d, axis=-1)
    print(f"cold solve from the saved keyframes vs the workbench: max {1000 * d.max():.2f} mm, mean {1000 * d.mean():.3f} mm")
    assert d.max() < 0.005 and d.mean() < 0.001
    assert all_flips(fig, cam, again.keypoints3d, Q) == {}


def test_whole_resolve_puts_the_feet_down_as_reconstruct_does(case, start):
    """Without ``floor`` the session takes reconstruct's default (the generic human: feet on
    the ground) for the whole solve; ``floor="none"`` (the case's setting) leaves it out."""
    fig, Q, cam, tracks, keys = case
    s = Session(fig, tracks, cam, keys, result=start, weights=WEIGHTS)
    s.solve(window=False)
    m = s.result().foot_metrics()
    assert m is not None and m["contact_frames"] > 0.2 * len(Q)
    assert "floor:" in s.result().summary()
    off = Session(fig, tracks, cam, keys, result=start, weights=WEIGHTS, floor=FLOOR)
    off.solve(window=False)
    assert off.result().foot_metrics() is None


def test_reload_gives_the_same_state(case, fixed):
    fig, Q, cam, tracks, keys = case
    s, *_, out = fixed
    r = Session(fig, tracks, cam, pr.load_keyframes(out / "keyframes.json"), result=pr.load_result(out / "result.npz"), weights=WEIGHTS, floor=FLOOR)
    np.testing.assert_allclose(r.q, s.q, atol=1e-12)
    assert r.keyframes.to_dict() == json.loads((out / "keyframes.json").read_text())
    assert len(r.keyframes) == len(keys) + 1
    np.testing.assert_allclose(r.reprojection_px()[1], s.reprojection_px()[1], atol=1e-9, equal_nan=True)


def test_undo_redo_steps_through_edits_and_solves(case, start):
    fig, Q, cam, tracks, keys = case
    s = Session(fig, tracks, cam, keys, result=start, weights=WEIGHTS, floor=FLOOR)
    q0, n0 = s.q, len(s.keyframes)
    assert not s.can_undo and s.undo() is False
    s.flip(FLIP_FRAME, SEGMENT)
    q1 = s.q
    s.delete_keyframe(0)
    assert len(s.keyframes) == n0
    assert s.undo() and len(s.keyframes) == n0 + 1 and s.q is q1
    assert s.undo() and len(s.keyframes) == n0 and np.array_equal(s.q, q0) and not s.needs_solve
    assert s.redo() and s.q is q1 and s.needs_solve and s.dirty_frames[0] <= FLIP_FRAME <= s.dirty_frames[1]
    s.solve()
    solved = s.q
    assert s.undo() and s.q is q1 and s.needs_solve
    assert s.redo() and s.q is solved and not s.needs_solve
    s.flip(10, "left_elbow>left_wrist")
    assert not s.can_redo  # a new edit forgets the redo branch
    assert s.history[-1] == "flip left_elbow>left_wrist at 10"


def test_point_keyframe_moves_the_keypoint(case, start):
    fig, Q, cam, tracks, keys = case
    s = Session(fig, tracks, cam, keys, result=start, weights=WEIGHTS, floor=FLOOR)
    i = list(fig.keypoint_names).index("left_wrist")
    p = s.keypoints3d[60, i]
    target = p + 0.15 * cam.R[2]  # 15 cm deeper along the camera axis: the image does not see it
    key = s.set_point(60, "left_wrist", target)
    assert "left_wrist" in key.points and key.frame == 60
    # merged into the keyframe already at frame 60 (which keyed the wrist elsewhere)
    assert sum(k.frame == 60 and k.points is not None and "left_wrist" in k.points for k in s.keyframes) == 1
    assert np.linalg.norm(s.keypoints3d[60, i] - target) < 0.01  # the warm start reaches it
    s.solve()
    depth = (s.keypoints3d[60, i] - p) @ cam.R[2]
    assert 0.07 < depth < 0.16


def test_joint_keyframe_sets_the_angle(case, start):
    fig, Q, cam, tracks, keys = case
    s = Session(fig, tracks, cam, keys, result=start, weights=WEIGHTS, floor=FLOOR)
    v0 = s.joint_value(70, "right_elbow_Z")
    key = s.set_joint(70, "right_elbow_Z", v0 + 0.3)
    assert float(key.joints["right_elbow_Z"]) == pytest.approx(v0 + 0.3)
    assert s.joint_value(70, "right_elbow_Z") == pytest.approx(v0 + 0.3)
    assert abs(s.joint_value(65, "right_elbow_Z") - v0 - 0.3) < 0.3  # spread over the neighbours
    s.move_keyframe(len(s.keyframes) - 1, 72)
    assert s.keyframes[len(s.keyframes) - 1].frame == 72


def test_bad_edits_raise_typed_errors(case, start):
    fig, Q, cam, tracks, keys = case
    s = Session(fig, tracks, cam, keys, result=start, weights=WEIGHTS, floor=FLOOR)
    with pytest.raises(pr.InputError, match="right_knee>right_ankle"):
        s.flip(10, "tail>tip")
    with pytest.raises(pr.InputError, match="frame 500"):
        s.flip(500, SEGMENT)
    with pytest.raises(pr.InputError, match="not a 1-dof joint"):
        s.set_joint(10, "root_joint", 0.0)
    with pytest.raises(pr.UnknownNameError):
        s.set_point(10, "tail", [0, 0, 0])
    with pytest.raises(pr.InputError, match="no keyframe 99"):
        s.delete_keyframe(99)
    with pytest.raises(pr.InputError, match="result.q"):
        Session(fig, tracks, cam, keys, result=pr.Result.from_motion(fig, Q[:10], 30.0), weights=WEIGHTS, floor=FLOOR)


def test_mirror_and_span_geometry():
    cam = pr.Orthographic.from_view([0.6, 0.0, 0.8], scale=100.0)
    rng = np.random.default_rng(3)
    P = rng.normal(size=(4, 3))  # root 0, child 1, below 2 and 3
    z = cam.R[2]
    for whole in (False, True):
        M = mirror_segment(cam, P, 0, 1, [2, 3], whole_limb=whole)
        np.testing.assert_allclose(cam.project(M), cam.project(P), atol=1e-9)  # the image never moves
        assert (M[1] - P[0]) @ z == pytest.approx(-(P[1] - P[0]) @ z)
        np.testing.assert_allclose(M[0], P[0])
        if whole:  # the points below are reflected about the root too
            np.testing.assert_allclose((M[2:] - P[0]) @ z, -((P[2:] - P[0]) @ z))
        else:  # they keep their depth relative to the child
            np.testing.assert_allclose((M[2:] - M[1]) @ z, (P[2:] - P[1]) @ z)
    # one excursion: depth difference +,+,+(peak),+,+(local min),+,- ...
    dz = np.array([-1, 1, 2, 3, 2, 1, 1.5, 2, -1, -2], float)
    traj = np.zeros((10, 2, 3))
    traj[:, 1] = dz[:, None] * z
    assert flip_span(cam, traj, 0, 1, 3) == (1, 5)
    assert flip_span(cam, traj, 0, 1, 7) == (5, 7)


def test_segments_of_the_human(case):
    fig = case[0]
    names = [s.name for s in segments(fig)]
    assert "right_knee>right_ankle" in names and "left_shoulder>left_elbow" in names
    hip = next(s for s in segments(fig) if s.name == "left_hip>left_knee")
    assert hip.below == ("left_ankle",)


def test_html_player_is_self_contained_and_carries_the_motion(case, fixed, tmp_path):
    fig, Q, cam, tracks, keys = case
    s, *_, out = fixed
    code = main(["export", str(out / "result.npz"), "--html", str(tmp_path / "m.html")])
    assert code == 0
    text = (tmp_path / "m.html").read_text()
    assert not re.search(r"(src|href)\s*=\s*[\"']?(https?:)?//", text)  # nothing fetched
    assert "<script src" not in text and "import(" not in text
    data = json.loads(re.search(r'<script id="data" type="application/json">(.*?)</script>', text, re.S).group(1))
    assert (data["T"], data["K"]) == s.keypoints3d.shape[:2]
    P = np.array(data["P"]).reshape(data["T"], data["K"], 3) / 1000.0
    np.testing.assert_allclose(P, s.keypoints3d, atol=0.0006)
    assert len(data["edges"]) >= 16
    # from the session: the keyframes are marked on the player's timeline
    s.export(html=tmp_path / "k.html")
    data2 = json.loads(re.search(r'application/json">(.*?)</script>', (tmp_path / "k.html").read_text(), re.S).group(1))
    assert data2["keyframes"] == sorted({k.frame for k in s.keyframes})
    path = export_html(out / "result.npz", tmp_path / "n.html", title="walk")
    assert "<title>walk</title>" in path.read_text()


def test_exports_bvh_and_csv(fixed, tmp_path):
    s = fixed[0]
    files = s.export(bvh=tmp_path / "m.bvh", csv=tmp_path / "m.csv")
    assert [f.name for f in files] == ["m.bvh", "m.csv"]
    assert (tmp_path / "m.bvh").read_text().startswith("HIERARCHY")
    assert len((tmp_path / "m.csv").read_text().splitlines()) == s.n_frames + 1


def test_uncertain_spans_come_from_the_result_and_are_drawn(case, start):
    """The hypothesis search's uncertain spans (gap below its threshold) are read from the
    result's extras and drawn as a purple strip on the timeline; decided spans are not."""
    from dataclasses import replace

    from pinrecon.workbench.panels import UNCERTAIN_RGB, timeline
    from pinrecon.workbench.session import UNFAMILIAR

    fig, Q, cam, tracks, keys = case
    extras = dict(start.extras)
    extras.update(
        hypothesis_chains=np.array(["left_hip-left_knee-left_ankle", "right_hip-right_knee-right_ankle"]),
        # chain, start, stop, state, gap: one uncertain span (gap 0.5 < 2), one decided (gap 9)
        hypothesis_spans=np.array([[1.0, 20.0, 45.0, 1.0, 0.5], [0.0, 60.0, 90.0, 0.0, 9.0]]),
        hypothesis_threshold=np.float64(2.0),
    )
    for k in ("prior_distance", "prior_distance_limit", "prior_unfamiliar_spans"):
        extras.pop(k, None)
    s = Session(fig, tracks, cam, keys, result=replace(start, extras=extras), weights=WEIGHTS, floor=FLOOR)
    assert s.uncertain_spans() == [(20, 45, "right_hip-right_knee-right_ankle")]
    assert Session(fig, tracks, cam, keys, result=replace(start, extras={}), weights=WEIGHTS, floor=FLOOR).uncertain_spans() == []
    # poses the pose prior does not know are uncertain for every limb
    both = Session(fig, tracks, cam, keys, weights=WEIGHTS, floor=FLOOR,
                   result=replace(start, extras={**extras, "prior_unfamiliar_spans": np.array([[50, 58]])}))
    assert both.uncertain_spans() == [(20, 45, "right_hip-right_knee-right_ankle"), (50, 58, UNFAMILIAR)]
    W, H = 480, 90
    img = timeline(np.ones(s.n_frames), 0, uncertain=[(a, b) for a, b, _ in s.uncertain_spans()], size=(W, H))
    row = img[H - 17]
    purple = np.all(row == UNCERTAIN_RGB, axis=-1)

    def x(t):  # the timeline's frame -> pixel map, written out
        return 8 + (W - 16) * t / (s.n_frames - 1)

    cols = np.flatnonzero(purple)
    assert cols.min() == pytest.approx(x(20), abs=1.0) and cols.max() == pytest.approx(x(44), abs=1.0)
    assert not purple[int(x(70))]


def test_unstable_frames_of_a_stability_check_are_uncertain_spans(case, start):
    """A result of ``reconstruct --stability N`` opened in the workbench: the runs of frames
    its copies moved by more than the threshold join the uncertain spans, named by the
    keypoint that moved most."""
    from dataclasses import replace

    from pinrecon.stability import Stability
    from pinrecon.workbench.session import UNSTABLE

    fig, Q, cam, tracks, keys = case
    T = len(start.times)
    spread = np.zeros((2, T))
    spread[1, 10:25] = 55.0
    per_point = np.zeros((T, 2))
    per_point[10:25, 1] = 140.0
    check = Stability(0.02, (0, 1), spread, per_point, ["left_wrist", "right_wrist"], 30.0, start.fps)
    s = Session(fig, tracks, cam, keys, weights=WEIGHTS, floor=FLOOR,
                result=replace(start, extras=check.to_extras()))
    assert s.uncertain_spans() == [(10, 25, f"{UNSTABLE}: right_wrist moved up to 140 mm with 2 % of the detections "
                                            "left out")]
