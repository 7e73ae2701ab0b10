"""pinrecon.stability: the solve again on copies of the tracks with a few detections left out.

Ground truth here: the copies are remade by hand (the same seeds), solved with
``pinrecon.reconstruct`` and compared with ``alignment.pa_mpjpe_mm`` (Umeyama written out in
the tests, not ``pinrecon.metrics``). The real instability is in tests/test_your_video.py
(Pose2Sim's trial, scored against its four-camera triangulation)."""

from __future__ import annotations

import numpy as np
import pytest
from alignment import pa_mpjpe_mm

import pinrecon as pr
from pinrecon.result import stability_lines, unstable_spans
from pinrecon.stability import Stability, drop_detections, stability


def test_drop_detections_removes_that_share_of_the_observed_points(coco_walk):
    _, plain, _, _ = coco_walk
    rng = np.random.default_rng(0)
    tracks = pr.Tracks(plain.points, plain.names, plain.fps, rng.uniform(0.3, 1.0, plain.points.shape[:2]))
    n_obs = int(tracks.observed.sum())
    copy = drop_detections(tracks, 0.05, seed=3)
    gone = tracks.observed & ~copy.observed
    assert int(gone.sum()) == round(0.05 * n_obs) and not (copy.observed & ~tracks.observed).any()
    assert np.all(copy.confidence[gone] == 0) and np.isnan(copy.points[gone]).all()
    kept = copy.observed
    np.testing.assert_array_equal(copy.points[kept], tracks.points[kept])
    np.testing.assert_array_equal(copy.confidence[kept], tracks.confidence[kept])
    assert copy.names == tracks.names and copy.fps == tracks.fps
    np.testing.assert_array_equal(drop_detections(tracks, 0.05, seed=3).observed, copy.observed)  # seeded
    assert (drop_detections(tracks, 0.05, seed=4).observed != copy.observed).any()
    bare = drop_detections(plain, 0.05, seed=3)  # no confidences: the same points, none made up
    assert bare.confidence is None and np.array_equal(bare.observed, copy.observed)


def test_a_well_determined_walk_is_stable_and_the_distances_are_right(coco_walk, human):
    """The walk with 5 cm keyframes every 0.25 s: every copy stays within a few mm. Each
    copy's distance is checked by solving the same copy here and aligning it by hand."""
    cam, tracks, _, keys = coco_walk
    res = pr.reconstruct(human, tracks, cam, keys)
    s = stability(human, tracks, cam, keys, result=res, runs=2, random_seed=5)
    assert s.spread_mm.shape == (2, len(res.times)) and s.keypoint_spread_mm.shape == (len(res.times), 12)
    assert s.names == list(tracks.names) and s.seeds == (5, 6)
    idx = res.figure.keypoint_index(list(tracks.names))
    for k, seed in enumerate(s.seeds):
        again = pr.reconstruct(human, drop_detections(tracks, 0.01, seed), cam, keys)
        expected = pa_mpjpe_mm(again.keypoints3d[:, idx], res.keypoints3d[:, idx])
        assert float(s.spread_mm[k].mean()) == pytest.approx(expected, rel=1e-6, abs=1e-6)
    assert s.spread_mm.max() < 10.0, s.spread_mm.max()
    extras = s.to_extras()
    assert unstable_spans(extras) == []
    assert stability_lines(extras, res.fps)[1] == "  every frame within 30 mm in every copy"


def test_unstable_spans_and_their_summary_lines():
    """Spans from hand-made spreads: frames 3-5 over 30 mm in copy 0, frames 8-9 in both."""
    spread = np.zeros((2, 12))
    spread[0, 3:6] = 45.0
    spread[:, 8:10] = [[31.0, 33.0], [60.0, 20.0]]
    per_point = np.zeros((12, 3))
    per_point[3:6, 1] = [50.0, 90.0, 70.0]
    per_point[8:10, 2] = [120.0, 80.0]
    s = Stability(0.01, (0, 1), spread, per_point, ["a", "b", "c"], 30.0, 10.0)
    assert unstable_spans(s.to_extras()) == [(3, 6, "b", 90.0, 1), (8, 10, "c", 120.0, 2)]
    lines = s.summary().splitlines()
    assert lines[0].startswith("stability: solved again on 2 copies of the tracks with 1 % of the detections left out: "
                               "mean difference from this result 16.6, 6.7 mm")
    assert lines[1].startswith("  5 of 12 frames differ by more than 30 mm in some copy")
    assert lines[2] == "  frames 8-9 (0.80-0.90 s): 2 of 2 copies, most at c (120 mm)"
    assert lines[3] == "  frames 3-5 (0.30-0.50 s): 1 of 2 copies, most at b (90 mm)"


def test_stability_extras_survive_save_and_load(tmp_path, coco_walk, human):
    cam, tracks, _, _ = coco_walk
    short = pr.Tracks(tracks.points[:40], tracks.names, tracks.fps)
    res = pr.reconstruct(human, short, cam, None, floor="none")
    spread = np.full((1, len(res.times)), 5.0)
    spread[0, 10:20] = 80.0
    s = Stability(0.01, (0,), spread, np.full((len(res.times), 12), 9.0), list(tracks.names), 30.0, res.fps)
    res.extras.update(s.to_extras())
    res.save(tmp_path / "r.npz")
    back = pr.load_result(tmp_path / "r.npz")
    assert unstable_spans(back.extras) == unstable_spans(res.extras) == [(10, 20, tracks.names[0], 9.0, 1)]
    assert "stability: solved again on 1 copies" in back.summary()


def test_the_copies_do_not_repeat_the_results_warnings(coco_walk, human):
    """Tracks with a point the figure lacks: the result warns once; the copies stay quiet."""
    import warnings

    cam, tracks, _, _ = coco_walk
    pts = np.concatenate([tracks.points[:30], tracks.points[:30, :1]], axis=1)
    extra = pr.Tracks(pts, [*tracks.names, "left_big_toe"], tracks.fps)
    with pytest.warns(UserWarning, match="not on the figure"):
        res = pr.reconstruct(human, extra, cam, floor="none")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = stability(human, extra, cam, result=res, runs=1, floor="none")
    assert s.names == list(tracks.names)  # the points the figure has


def test_copies_solved_in_processes_give_the_same_numbers_in_the_same_order(coco_walk, human):
    """``n_jobs=2``: the copies solved in two processes give each copy's spread as the
    one-after-another path does (checked against hand-solved copies above), copy by copy."""
    cam, tracks, _, _ = coco_walk
    short = pr.Tracks(tracks.points[:40], tracks.names, tracks.fps)
    res = pr.reconstruct(human, short, cam, None, floor="none")
    one = stability(human, short, cam, result=res, runs=2, random_seed=3, floor="none")
    two = stability(human, short, cam, result=res, runs=2, random_seed=3, n_jobs=2, floor="none")
    assert not np.allclose(one.spread_mm[0], one.spread_mm[1])  # so that an exchange of copies would show
    np.testing.assert_allclose(two.spread_mm, one.spread_mm, rtol=0, atol=1e-6)
    np.testing.assert_allclose(two.keypoint_spread_mm, one.keypoint_spread_mm, rtol=0, atol=1e-6)
    assert two.seeds == one.seeds == (3, 4)


def test_a_callback_that_cannot_go_to_another_process_is_refused(coco_walk, human):
    cam, tracks, _, _ = coco_walk
    short = pr.Tracks(tracks.points[:20], tracks.names, tracks.fps)
    res = pr.reconstruct(human, short, cam, None, floor="none", options=pr.SolverOptions(max_iterations=1))
    with pytest.raises(pr.InputError, match="n_jobs=1, or a callback defined at module level") as e:
        stability(human, short, cam, result=res, runs=2, n_jobs=2, floor="none", callback=lambda report: False)
    assert e.value.field == "n_jobs"


@pytest.mark.parametrize(("kw", "field"), [({"runs": 0}, "runs"), ({"runs": 1.5}, "runs"), ({"drop": 0.0}, "drop"),
                                           ({"drop": 0.6}, "drop"), ({"drop": "a lot"}, "drop"),
                                           ({"threshold_mm": -1.0}, "threshold_mm"), ({"threshold_mm": None}, "threshold_mm"),
                                           ({"init": np.zeros((3, 3))}, "init"), ({"n_jobs": 0}, "n_jobs"),
                                           ({"n_jobs": -2}, "n_jobs"), ({"n_jobs": 1.5}, "n_jobs"),
                                           ({"n_jobs": True}, "n_jobs")])
def test_bad_arguments_are_refused_before_any_solve(kw, field, coco_walk, human):
    cam, tracks, _, _ = coco_walk
    with pytest.raises(pr.InputError) as e:
        stability(human, tracks, cam, result=object(), **kw)
    assert e.value.field == field
