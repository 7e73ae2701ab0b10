"""TRC marker files (pinrecon.io.trc, ``pinrecon export --trc``).

Ground truth: numbers typed in here from Pose2Sim's trial file (its first and last rows),
files written out by hand in the tests, and distances between points, which no change of
axes alters."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import data_path

import pinrecon as pr
from pinrecon.cli import main
from pinrecon.io.trc import load_trc, write_trc

REPO = Path(__file__).resolve().parents[1]
TRIAL = data_path("pose2sim-balancing/pose-3d/S00_P00_T01_BalancingTrial_0-100.trc")


def test_pose2sims_trial_reads_as_written_in_metres_with_z_up():
    m = load_trc(TRIAL)
    assert m.points.shape == (100, 21, 3) and m.fps == 60.0 and not np.isnan(m.points).any()
    assert m.names[:3] == ["RHip", "RKnee", "RAnkle"] and m.names[-1] == "LWrist"
    # frame 1, RHip in the file (X, Y, Z; Y up): -0.06497214796810755 0.9015045550714222 -1.4005886926185436
    np.testing.assert_allclose(m.points[0, 0], [-1.4005886926185436, -0.06497214796810755, 0.9015045550714222],
                               rtol=0, atol=1e-15)
    assert m.points[:, m.names.index("Head"), 2].min() > m.points[:, m.names.index("RAnkle"), 2].max()  # Z is up


def test_pinrecon_names_are_the_ones_every_skeleton_shares():
    m = load_trc(TRIAL, names="pinrecon")
    assert {"left_shoulder", "right_knee", "left_big_toe", "right_heel", "nose"} <= set(m.names)
    assert {"Neck", "Head"} <= set(m.names)  # the top of the neck or the shoulders' midpoint: not guessed
    fig = pr.Figure.human("body25b")
    assert len(set(m.names) & set(fig.keypoint_names)) == 19  # 12 body points, 6 foot points and the nose
    np.testing.assert_array_equal(m.points, load_trc(TRIAL).points)


@pytest.mark.parametrize("up", ["x", "y", "z"])
def test_written_files_read_back(tmp_path, up):
    rng = np.random.default_rng(0)
    P = rng.normal(size=(7, 3, 3))
    P[2, 1] = np.nan  # a missing marker
    m = pr.Markers(P, ["right_shoulder", "Neck", "stick_tip"], 30.0)
    out = write_trc(tmp_path / "m.trc", m, up=up, names="pose2sim")
    back = load_trc(out, up=up, names="pinrecon")
    assert back.names == m.names and back.fps == 30.0
    np.testing.assert_allclose(back.points, P, rtol=0, atol=1e-6)  # six decimals of a metre
    assert np.isnan(back.points[2, 1]).all() and np.isfinite(np.delete(back.points.reshape(-1, 3), 7, 0)).all()
    raw = load_trc(out, up=up)
    assert raw.names == ["RShoulder", "Neck", "stick_tip"]
    text = out.read_text().splitlines()
    up_col = "xyz".index(up)
    assert float(text[6].split("\t")[2 + up_col]) == pytest.approx(P[0, 0, 2], abs=1e-6)  # Z goes to the file's up


def test_millimetres_and_gaps_as_another_program_writes_them(tmp_path):
    f = tmp_path / "mm.trc"
    f.write_text("PathFileType\t4\t(X/Y/Z)\tmm.trc\n"
                 "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
                 "100\t100\t2\t2\tmm\t100\t1\t2\n"
                 "Frame#\tTime\tA\t\t\tB\t\t\n"
                 "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
                 "1\t0.00\t1000\t2000\t3000\t\t\t\n"
                 "2\t0.01\t10\t20\t30\tNaN\tNaN\tNaN\n")
    m = load_trc(f, up="z")
    np.testing.assert_allclose(m.points[:, 0], [[1.0, 2.0, 3.0], [0.01, 0.02, 0.03]])
    assert np.isnan(m.points[:, 1]).all() and m.fps == 100.0


def _trc_text(units="m", frames="2", row2="2\t0.1\t0\t0\t0"):
    return ("PathFileType\t4\t(X/Y/Z)\tx.trc\n"
            "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
            f"10\t10\t{frames}\t1\t{units}\t10\t1\t2\n"
            "Frame#\tTime\tA\t\t\n\t\tX1\tY1\tZ1\n"
            f"1\t0.0\t0\t0\t0\n{row2}\n")


@pytest.mark.parametrize(("text", "field", "frame", "words"), [
    ("hello\n" * 6, "PathFileType", None, "not a TRC file"),
    (_trc_text(units="inch"), "Units", None, "unknown unit 'inch'"),
    (_trc_text(frames="3"), "NumFrames", None, "NumFrames says 3, the file has 2"),
    (_trc_text(frames="two"), "NumFrames", None, "not a number"),
    (_trc_text(row2="2\t0.1\t0\tabc\t0"), "coordinates", 1, "'abc' (line 7, marker 'A')"),
])
def test_bad_files_get_one_clear_error(tmp_path, text, field, frame, words):
    f = tmp_path / "x.trc"
    f.write_text(text)
    with pytest.raises(pr.InputError) as e:
        load_trc(f)
    assert e.value.field == field and e.value.frame == frame and words in str(e.value) and str(f) in str(e.value)


def test_a_bad_name_writes_nothing(tmp_path):
    m = pr.Markers(np.zeros((2, 1, 3)), ["a\tb"], 10.0)
    with pytest.raises(pr.InputError, match="without tabs"):
        write_trc(tmp_path / "m.trc", m)
    assert not (tmp_path / "m.trc").exists()


def test_export_writes_the_keypoints_for_opensim(tmp_path):
    """``pinrecon export --trc``: the result's 3D keypoints in the export's world (Y up in the
    file), the same distances between them, Pose2Sim's names on request."""
    fig = pr.Figure.human()
    T = 5
    q = np.repeat(fig.neutral()[None], T, axis=0)
    q[:, 0] = np.linspace(0.0, 0.4, T)  # walks 0.4 m along x
    res = pr.Result.from_motion(fig, q, fps=25.0)
    res.save(tmp_path / "r.npz")
    assert main(["export", str(tmp_path / "r.npz"), "--trc", str(tmp_path / "m.trc"), "--trc-names", "pose2sim"]) == 0
    back = load_trc(tmp_path / "m.trc", names="pinrecon")
    names = fig.distinct_keypoint_names
    assert back.names == names and back.points.shape == (T, len(names), 3)
    P = res.keypoints3d[:, fig.keypoint_index(names)]
    def d(X):
        return np.linalg.norm(X[:, :, None] - X[:, None, :], axis=-1)

    np.testing.assert_allclose(d(back.points), d(P), atol=2e-6)
    rows = (tmp_path / "m.trc").read_text().splitlines()
    assert "RShoulder" in rows[3].split("\t")
    head, ankle = names.index("nose"), names.index("left_ankle")
    y = [float(v) for v in rows[6].split("\t")[2:]][1::3]  # the file's Y column of frame 1
    assert y[head] - y[ankle] > 1.2  # standing, Y up


def test_the_generic_human_fitted_to_pose2sims_triangulation():
    """Pose2Sim's four-camera triangulation of its balancing trial, its 13 COCO-17 points:
    ``reconstruct_markers`` with ``Figure.human()`` fits the figure's lengths to them by
    default (mean distance 17.7 mm measured) where the generic proportions leave 34.8 mm."""
    import warnings

    m = load_trc(TRIAL, names="pinrecon")
    fig = pr.Figure.human()
    names = [n for n in m.names if n in fig.keypoint_names]
    assert len(names) == 13
    G = m.points[:, [m.names.index(n) for n in names]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the points the figure lacks (toes, heels, neck, head)
        fitted = pr.reconstruct_markers(fig, m)
        held = pr.reconstruct_markers(fig, m, calibrate="none")
    d = {k: 1000.0 * np.linalg.norm(r.keypoints3d[:, r.figure.keypoint_index(names)] - G, axis=-1).mean()
         for k, r in (("fitted", fitted), ("held", held))}
    assert d["fitted"] < 20.0 and d["held"] > 30.0, d
    assert fitted.calibration["factors"]["thigh"] == pytest.approx(0.94, abs=0.03)  # a shorter subject's thighs


def test_fit_markers_command_writes_a_result_and_says_what_it_left_out(tmp_path, capsys):
    """``pinrecon fit-markers``: Pose2Sim's TRC in, the generic human fitted (its lengths too),
    a result NPZ that exports; Pose2Sim's Neck and Head left out with a warning, not guessed."""
    out = tmp_path / "r.npz"
    assert main(["fit-markers", "--markers", str(TRIAL), "--figure", "human", "--out", str(out)]) == 0
    cap = capsys.readouterr()
    assert "markers Neck, Head not used" in cap.err  # a warning, on stderr
    err = cap.out  # the summary, on stdout
    assert "reprojection error" not in err
    assert "poses unlike the pose prior" not in err  # 3D markers measure the depths the prior would guess
    # 13 COCO points fix neither the trunk against the spine's bend nor the neck against the head
    assert "NOT fixed by the data alone: trunk, shoulder width, neck, head" in err
    res = pr.load_result(out)
    assert res.calibration["identifiability"]["undetermined"][:4] == ["trunk", "shoulder_width", "neck", "head"]
    m = load_trc(TRIAL, names="pinrecon")
    names = ["left_shoulder", "right_knee", "left_big_toe", "right_heel"]
    d = res.keypoints3d[:, res.figure.keypoint_index(names)] - m.points[:, [m.names.index(n) for n in names]]
    assert 1000 * np.linalg.norm(d, axis=-1).mean() < 30.0
    assert res.calibration["mode"] == "lengths"
    assert main(["export", str(out), "--bvh", str(tmp_path / "m.bvh")]) == 0
