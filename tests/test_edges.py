"""The edges a new user meets first: where the command's output goes, what --quiet means,
the words the summary uses, --version, the top-level camera reader, the auto orthographic
camera with keyframes, the workbench's inputs and hints, the pictures' floor, the exports'
units and the links report's caveat."""

from __future__ import annotations

import numpy as np
import pytest

import pinrecon as pr
from pinrecon.cli import main


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    """40 frames of a smooth synthetic motion of the generic human through a known
    orthographic camera (scale 300 px/m), 1 px noise, point keyframes every 8 frames; the
    inputs written as files."""
    from pinrecon.synthetic import point_keyframes, project_tracks, side_camera, smooth_motion

    fig = pr.Figure.human()
    Q = smooth_motion(fig, 40, 30.0)
    cam = side_camera(Q, 45.0, scale=300.0, center=(500.0, 500.0))
    tracks = project_tracks(fig, Q, cam, fps=30.0, noise_px=1.0)
    keys = point_keyframes(fig, Q, range(0, 40, 8))
    d = tmp_path_factory.mktemp("clip")
    tracks.save(d / "tracks.json")
    cam.save(d / "camera.json")
    keys.save(d / "keyframes.json")
    return {"dir": d, "figure": fig, "Q": Q, "camera": cam, "tracks": tracks, "keyframes": keys}


@pytest.fixture(scope="module")
def solved(clip, tmp_path_factory):
    """`pinrecon reconstruct --quiet` on the clip's files: (exit code, stdout, stderr, result path)."""
    import contextlib
    import io

    d = clip["dir"]
    out, err = io.StringIO(), io.StringIO()
    path = tmp_path_factory.mktemp("out") / "r.npz"
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["reconstruct", "--figure", "human", "--tracks", str(d / "tracks.json"), "--camera",
                     str(d / "camera.json"), "--keyframes", str(d / "keyframes.json"), "--out", str(path),
                     "--quiet"])
    return code, out.getvalue(), err.getvalue(), path


def test_summary_goes_to_stdout_also_with_quiet(solved):
    code, out, err, path = solved
    assert code == 0 and path.is_file()
    assert "reprojection error" in out and f"wrote {path}" in out  # `> summary.txt` captures it
    assert "iter " not in err and "pinrecon: stage" not in err  # --quiet: no progress


def test_quiet_still_shows_warnings(clip, tmp_path, capsys):
    """A warning raised during the command reaches stderr with --quiet (it silences progress only)."""
    import warnings

    from pinrecon import cli

    def warn_then_fail(args):
        warnings.warn("the focal length is not determined", UserWarning)
        return 0

    parser = cli.build_parser()
    args = parser.parse_args(["demo", "--quiet"])
    args.func = warn_then_fail
    orig = cli.build_parser
    try:
        cli.build_parser = lambda: type("P", (), {"parse_args": lambda self, argv: args})()
        assert main(["demo", "--quiet"]) == 0
    finally:
        cli.build_parser = orig
    assert "the focal length is not determined" in capsys.readouterr().err


def test_progress_is_labelled_by_stage(clip, tmp_path, capsys):
    d = clip["dir"]
    assert main(["reconstruct", "--figure", "human", "--tracks", str(d / "tracks.json"), "--camera",
                 str(d / "camera.json"), "--keyframes", str(d / "keyframes.json"), "--out",
                 str(tmp_path / "r.npz")]) == 0
    err = capsys.readouterr().err
    stages = [ln for ln in err.splitlines() if ln.startswith("pinrecon: stage ")]
    assert [s.split()[2] for s in stages[:2]] == ["labels", "solve"] and any("feet" in s for s in stages)
    iters = [ln for ln in err.splitlines() if "iter " in ln]
    assert iters and not any(ln.startswith("iter ") for ln in iters)  # every iteration line names its stage


def test_progress_to_a_file_shows_a_stage_of_many_short_solves_in_few_lines(capsys):
    """Written to a file or a pipe, a stage's iteration lines are its first iteration, every
    10th of each solve and every rejected step: the mirror stage's dozens of short solves do not
    print a line each. Ground truth: the lines written out here by hand."""
    from pinrecon.commands import SolveProgress
    from pinrecon.solver import IterationReport

    def rep(k, accepted=True):
        return IterationReport(k, 100.0 - k, {}, 0.1, 1e-3, 1.0, accepted, 0.0, "" if accepted else "cost rose")

    progress = SolveProgress(False, 100)
    progress.stage("mirrors")
    for n in (3, 2, 12, 4):  # four solves of the stage: 3, 2, 12 and 4 iterations
        for k in range(1, n + 1):
            progress(rep(k, accepted=not (n == 4 and k == 2)))
    progress.stage("feet")
    for k in range(1, 3):
        progress(rep(k))
    lines = [ln.split("  cost")[0] for ln in capsys.readouterr().err.splitlines()]
    assert [ln.split(" (")[0] for ln in lines] == [
        "pinrecon: stage mirrors", "mirrors: iter   1/100", "mirrors: iter  10/100", "mirrors: iter   2/100",
        "pinrecon: stage feet", "feet: iter   1/100"]


def test_summary_time_is_the_whole_runs(solved):
    res = pr.load_result(solved[3])
    run = float(res.extras["run_time_s"])
    assert run > 0
    out = solved[1]
    line = next(ln for ln in out.splitlines() if ln.startswith("solved in "))
    assert float(line.split()[2]) == pytest.approx(run, abs=0.051)


def test_summary_uses_plain_words(solved):
    out = solved[1]
    for word in ("nats", "Mahalanobis", "gauge", ".keypoints", "middle_"):
        assert word not in out, word


def test_summary_names_keypoint_segments_plainly():
    from pinrecon.result import plain_segment

    assert plain_segment("middle_pelvis.keypoints") == "pelvis keypoints"
    assert plain_segment("shoulder_width") == "shoulder width"


def test_glossary_explains_the_summary_words():
    from conftest import REPO

    text = (REPO / "docs" / "glossary.md").read_text()
    for term in ("cost", "standard deviation", "reprojection error", "PA-MPJPE", "keyframe"):
        assert term.lower() in text.lower(), term


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"pinrecon {pr.__version__}"


def test_load_camera_reads_every_calibration_format(clip):
    from conftest import data_file

    from pinrecon.io.calibration import load_cameras

    toml = data_file("pose2sim-balancing/calibration/Calib_qualisys.toml")
    every = load_cameras(toml)
    assert len(every) > 1
    cam = pr.load_camera(toml, name=every[1].name)
    np.testing.assert_allclose(cam.R, every[1].camera.R)
    with pytest.raises(pr.InputError, match="cameras"):
        pr.load_camera(toml)  # several cameras and no name: one clear error listing them
    json_cam = pr.load_camera(clip["dir"] / "camera.json")
    assert json_cam.scale == pytest.approx(300.0)


def test_auto_orthographic_camera_with_keyframes(clip):
    """Today's LinAlgError: the orthographic auto camera fitted to keyframes got the tracks'
    (T, K, 2) points in place of the keyframes' correspondences."""
    from pinrecon.starts.camera_auto import auto_camera

    cam = auto_camera(clip["tracks"], clip["figure"], (1000, 1000), "orthographic", keyframes=clip["keyframes"])
    assert cam.scale == pytest.approx(300.0, rel=0.03)  # the true camera's
    np.testing.assert_allclose(np.abs(np.sum(cam.R * clip["camera"].R, axis=1)), 1.0, atol=0.02)


def test_workbench_hint_names_a_pip_command_that_works():
    import inspect

    from pinrecon.viz import _common
    from pinrecon.workbench import app

    from pinrecon.video import frames

    for mod in (app, _common, frames):
        src = inspect.getsource(mod)
        assert "pinrecon[edit]" not in src and "pinrecon[viz]" not in src and "pinrecon[video]" not in src
    assert 'pip install ".[edit]"' in inspect.getsource(app)


def test_workbench_view_leaks_no_all_nan_warning():
    import warnings

    from pinrecon.workbench.app import view_half_px

    uv = np.full((5, 4, 2), np.nan)
    uv[2, :2] = [[0.0, 0.0], [100.0, 50.0]]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert view_half_px(uv) == pytest.approx(60.0)
        assert view_half_px(np.full((3, 2, 2), np.nan)) == 100.0


def test_workbench_takes_the_results_figure_and_camera(clip, solved, monkeypatch, capsys):
    from pinrecon.workbench import app

    seen = {}
    monkeypatch.setattr(app, "serve", lambda session, **kw: seen.setdefault("s", session))
    res = pr.load_result(solved[3])
    d = clip["dir"]
    assert main(["edit", "--tracks", str(d / "tracks.json"), "--result", str(solved[3]), "--no-browser"]) == 0
    s = seen.pop("s")
    assert s.figure.nv == res.figure.nv
    np.testing.assert_allclose(s.figure.keypoints(res.q[:1]), res.keypoints3d[:1], atol=1e-9)  # fitted lengths
    assert s.camera.scale == pytest.approx(res.camera.scale)
    capsys.readouterr()
    assert main(["edit", "--figure", "human", "--tracks", str(d / "tracks.json"), "--result", str(solved[3]),
                 "--no-browser"]) == 0
    assert "overrides the result's own figure" in capsys.readouterr().err


def test_workbench_accepts_camera_auto_with_reconstructs_defaults(clip, monkeypatch):
    from pinrecon.workbench import app

    seen = {}
    monkeypatch.setattr(app, "serve", lambda session, **kw: seen.setdefault("s", session))
    d = clip["dir"]
    assert main(["edit", "--figure", "human", "--tracks", str(d / "tracks.json"), "--keyframes",
                 str(d / "keyframes.json"), "--camera", "auto:orthographic", "--image-size", "1000", "1000",
                 "--floor", "none", "--no-browser"]) == 0
    s = seen["s"]
    assert s.camera.scale == pytest.approx(300.0, rel=0.03)  # the fitted camera, as reconstruct's
    assert s.weights.loss == pr.Weights().loss  # reconstruct's default loss


def test_stick_strip_floor_is_level_and_heights_are_above_it(clip):
    """A floor tilted against the world axes: the second view is levelled on it, so the floor
    is a horizontal line and the axis says heights above it."""
    pytest.importorskip("matplotlib")
    from pinrecon.floor import Floor
    from pinrecon.viz._common import floor_segment, height_ticks, new_figure, second_view_camera, view_up

    n = np.array([0.0, np.cos(0.2), np.sin(0.2)])
    floor = Floor(n, -0.1)
    feet = type("Feet", (), {"floor": floor})()
    cam = clip["camera"]
    up = view_up(cam, feet)
    view = second_view_camera(cam, None, up)
    seg = floor_segment(view, floor, np.zeros(3), 1.0)
    assert seg[0, 1] == pytest.approx(seg[1, 1], abs=1e-9)  # a level line
    fig = new_figure((3, 3))
    ax = fig.subplots()
    ax.set_ylim(1.0, -2.0)
    assert height_ticks(ax, floor, up) == "height above the floor"
    # a point on the floor reads height 0 and one 0.5 m above it 0.5 on the axis' scale
    v, label = ax.get_yticks()[0], float(ax.get_yticklabels()[0].get_text())
    p = np.array([0.3, 0.0, 0.0])
    p = p - floor.height(p) * n
    for above in (0.0, 0.5):
        v_p = view.project((p + above * n)[None])[0, 1]
        assert label + (v - v_p) == pytest.approx(above, abs=1e-9)
    assert height_ticks(ax, floor, np.array([0.0, 0.0, 1.0])) == "height"  # not level: no claim


def test_second_view_stands_on_the_floor_when_the_camera_is_rolled():
    """A video filmed sideways: the auto camera's world is the camera's (+Y its up), and the
    floor's normal, pointing up to the body, lies nearly along X, a little below the camera's
    horizon (as Pose2Sim's cam01 turned 90 degrees). The second view's up is the floor's
    normal, so a head 1.5 m above the feet is drawn above them (it was drawn below: the normal
    was turned to the camera's up side)."""
    from pinrecon.cameras import Orthographic
    from pinrecon.floor import Floor
    from pinrecon.viz._common import second_view_camera, view_up

    cam = Orthographic.from_view([0.0, 0.0, 1.0], (0.0, 1.0, 0.0), scale=1.0)
    for side in (-1.0, 1.0):  # rolled either way
        n = np.array([side, -0.4, -0.3]) / np.linalg.norm([side, -0.4, -0.3])
        feet = type("Feet", (), {"floor": Floor(n, -1.0)})()
        np.testing.assert_allclose(view_up(cam, feet), n)
        view = second_view_camera(cam, None, view_up(cam, feet))
        p_feet = np.array([0.2, 0.1, 3.0])
        v_feet, v_head = view.project(np.array([p_feet, p_feet + 1.5 * n]))[:, 1]
        assert v_feet - v_head == pytest.approx(1.5, abs=1e-9)  # image rows grow downwards


def test_links_report_says_when_its_fits_are_not_trustworthy(clip):
    from pinrecon.planarity import links_report

    names = ["left_hip", "left_knee", "left_ankle", "right_hip", "right_knee", "right_ankle"]
    fig, Q, cam = clip["figure"], clip["Q"], clip["camera"]
    from pinrecon.synthetic import project_tracks

    clean = links_report(project_tracks(fig, Q, cam, names, fps=30.0, noise_px=0.5, seed=3))
    noisy = links_report(project_tracks(fig, Q, cam, names, fps=30.0, noise_px=5.0, seed=3))
    assert "NOT TRUSTWORTHY" not in clean and "assume" in clean
    assert "NOT TRUSTWORTHY" in noisy


def test_joint_angle_panels_are_named_anatomically(human):
    """The names follow the human's joint axes at rest: Z along the hips' left-right line
    (flexion), X front-back (abduction), Y vertical (rotation), measured here from the
    figure's own keypoints."""
    import pinocchio as pin

    from pinrecon.anatomy import joint_title

    assert joint_title(human, "left_knee_Z") == "left knee flexion/extension"
    assert joint_title(human, "right_hip_X") == "right hip abduction/adduction"
    assert joint_title(human, "left_elbow_Y") == "left elbow pronation/supination"
    assert joint_title(human, "middle_thoracic_Y") == "thoracic axial rotation"
    assert joint_title(type("F", (), {"name": "cmu"})(), "left_knee_Z") == "left_knee_Z"  # other figures: as named
    m, d = human.model, human.model.createData()
    q = pin.neutral(m)
    pin.forwardKinematics(m, d, q)
    P = human.keypoints(q[None])[0]
    k = human.keypoint_names.index
    lateral = P[k("right_hip")] - P[k("left_hip")]
    lateral /= np.linalg.norm(lateral)
    for joint in ("left_knee_Z", "right_hip_Z", "left_hip_X", "left_elbow_Y", "right_shoulder_X"):
        j = m.getJointId(joint)
        short = m.joints[j].shortname()
        a = np.asarray(m.joints[j].extract().axis).ravel() if "Unaligned" in short else np.eye(3)["XYZ".index(short[-1])]
        w = d.oMi[j].rotation @ a
        along = abs(float(w @ lateral))
        assert (along > 0.99) == joint.endswith("_Z"), joint


def test_workbench_page_is_titled_pinrecon():
    """The page's title is "pinrecon", not viser's "Viser": fetched over HTTP from a server
    made as the workbench makes it."""
    pytest.importorskip("viser")
    import socket
    import urllib.request

    import viser

    from pinrecon.workbench.app import page_title

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with page_title("pinrecon"):
        server = viser.ViserServer(host="127.0.0.1", port=port, verbose=False)
    try:
        html = urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=30).read().decode("utf-8", "replace")
    finally:
        server.stop()
    assert "<title>pinrecon</title>" in html and "<title>Viser</title>" not in html


def test_tracks_help_names_every_detector_format():
    from pinrecon.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    text = sub.choices["reconstruct"].format_help()
    for fmt in ("OpenPose", "COCO", "AlphaPose", "MMPose", "RTMPose", "Halpe"):
        assert fmt in text, fmt


def test_demo_bvh_is_in_metres(tmp_path):
    """The demo's BVH is in metres like every export (it was in CMU units, 26 units tall)."""
    from pinrecon.demo import run_demo
    from pinrecon.io.bvh import load_bvh

    run_demo(tmp_path, frames=30, pictures=False, video=False)
    back = load_bvh(tmp_path / "motion.bvh", 1.0)
    P = back.figure.keypoints(back.q)
    height_m = float(np.max(np.ptp(P[0], axis=0)))
    assert 1.4 < height_m < 2.1  # a person, in metres
