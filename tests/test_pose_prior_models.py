"""Named pose priors (``Weights.pose_prior_model``): which prior a figure gets, the CMU BVH
skeleton's prior (``models/priors/cmu_bvh_pose.json``) and ``tools/fit_pose_prior.py
--figure bvh`` checked against the BVH text parsed by hand, a prior refused where it does not
fit (other joint names, another rest pose), and the command line's one-line error."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from bvh_reference import reference_clip
from conftest import checkout_module

import pinrecon as pr
from pinrecon._resources import bundled_clip, model_path
from pinrecon.cli import main
from pinrecon.errors import InputError
from pinrecon.io.bvh import load_bvh
from pinrecon.problem import Weights, posture_row
from pinrecon.rows.posture import PosePrior, prior_for
from pinrecon.synthetic import COCO_BODY_FROM_CMU, bundled_motion, project_tracks, side_camera

CMU_UNIT_M = 0.056444
CMU_STATIC = ["LHipJoint", "RHipJoint", "LeftShoulder", "RightShoulder"]


def _tool():
    return checkout_module("tools/fit_pose_prior.py")


def test_which_prior_a_figure_gets():
    walk = bundled_motion("walk")[0]
    human = pr.Figure.human()
    assert prior_for(human) == "human_pose" and prior_for(walk) is None  # "auto"
    assert prior_for(human, "none") is None
    for clip in ("walk", "run", "spin"):  # three CMU subjects (2, 9, 5), none of the prior's clips
        assert prior_for(bundled_motion(clip)[0], "cmu_bvh_pose") == "cmu_bvh_pose"
    with pytest.raises(InputError, match="does not fit figure 'human'.*LeftUpLeg"):
        prior_for(human, "cmu_bvh_pose")
    with pytest.raises(InputError, match="does not fit.*left_hip"):
        prior_for(walk, "human_pose")
    with pytest.raises(InputError, match="no pose prior 'nope'; bundled: cmu_bvh_pose, human_pose"):
        prior_for(walk, "nope")
    with pytest.raises(InputError, match="weights.pose_prior_model"):
        Weights(pose_prior_model="")


def test_a_bvh_figure_with_another_rest_pose_is_refused(tmp_path):
    """Same joint names, the left thigh's rest bone turned 40 degrees forwards: the same
    channel angles would be another pose, so the prior is refused, naming the bone."""
    text = bundled_clip("walk").read_text()
    m = re.search(r"JOINT LeftUpLeg\s*\{\s*OFFSET\s+(\S+)\s+(\S+)\s+(\S+)", text)
    o = np.array([float(v) for v in m.groups()])
    c, s = np.cos(np.radians(40.0)), np.sin(np.radians(40.0))
    turned = np.array([o[0], c * o[1] - s * o[2], s * o[1] + c * o[2]])  # about x: down -> forwards
    path = tmp_path / "turned.bvh"
    path.write_text(text[: m.start(1)] + " ".join(f"{v:.6f}" for v in turned) + text[m.end(3):])
    fig = load_bvh(path, CMU_UNIT_M, skip_frames=1, lock="static").figure
    mean_dir = np.array(json.loads(model_path("priors", "cmu_bvh_pose.json").read_text())["rest_directions"]["LeftUpLeg"])
    off = np.degrees(np.arccos(turned @ mean_dir / np.linalg.norm(turned)))
    assert off > 25.0
    with pytest.raises(InputError, match=rf"bone LeftUpLeg {off:.0f} degrees off"):
        prior_for(fig, "cmu_bvh_pose")


def test_bundled_bvh_prior_file():
    data = json.loads(model_path("priors", "cmu_bvh_pose.json").read_text())
    corr = data["correlated"]
    C = np.array(corr["covariance"])
    assert C.shape == (len(corr["joints"]),) * 2 and np.allclose(C, C.T)
    assert np.linalg.eigvalsh(C).min() > 0
    assert not any("Thumb" in n or "Finger" in n for n in data["joints"])
    assert {"LeftUpLeg_Xrotation", "RightLeg_Xrotation", "LeftArm_Zrotation"} <= set(corr["joints"])
    q = corr["distance_quantiles"]
    assert 0 < q["50"] < q["90"] < q["99"] <= q["100"]
    # the knees bend one way (BVH X rotation positive) and are bent on average in the clips
    for hinge in ("LeftLeg_Xrotation", "RightLeg_Xrotation"):
        assert data["joints"][hinge][0] > 0.2
    assert data["rest_direction_spread_deg"] < 25.0


def test_fit_tool_bvh_mode_against_the_text(tmp_path):
    """The tool's means, deviations and rest directions from the run clip, against its text."""
    src = bundled_clip("run")
    out = tmp_path / "prior.json"
    _tool().main(["--figure", "bvh", str(src), "-o", str(out), "--max-frames", "1000"])
    data = json.loads(out.read_text())
    names, _, offsets, channels, *_, V = reference_clip(src)  # the text parsed by tests/bvh_reference.py
    columns = [(n, c) for n, ch in zip(names, channels) for c in ch]
    X = np.radians(V[1:][::4])  # the T-pose frame dropped, 120 -> 30 fps
    assert data["frames"] == len(X)
    checked = 0
    for k, (joint, ch) in enumerate(columns):
        key = f"{joint}_{ch}"
        if key in data["joints"] and k >= 6:
            mean, std = data["joints"][key]
            assert mean == pytest.approx(X[:, k].mean(), abs=2e-5), key
            assert std == pytest.approx(max(X[:, k].std(), 0.05), abs=2e-5), key
            checked += 1
    assert checked >= 40
    for name, off in zip(names, offsets):
        if name in data["rest_directions"]:
            assert np.allclose(data["rest_directions"][name], off / np.linalg.norm(off), atol=2e-4), name
    assert data["rest_direction_spread_deg"] == 0.0  # one clip
    assert data["made_with"]["pinrecon"].startswith(f"pinrecon {pr.__version__}")
    assert data["made_with"]["numpy"] == np.__version__ and data["made_with"]["components"] == 1


def test_fit_tool_reads_the_daz_release(tmp_path):
    """The CMU release with Daz joint names (``lShldr``, ``rShin``, ...: the salsa clips of
    subjects 60 and 61 are published so) fitted as the same motion under motionbuilder names:
    the walk's first 40 frames with its 12 joints renamed give the same joint angles."""
    tool = _tool()
    lines = bundled_clip("walk").read_text().splitlines()
    at = lines.index("MOTION")
    lines[at + 1] = "Frames: 41"
    mb = tmp_path / "mb.bvh"
    mb.write_text("\n".join(lines[: at + 3 + 41]) + "\n")
    daz = tmp_path / "daz.bvh"
    text = mb.read_text()
    for side, short in (("Left", "l"), ("Right", "r")):  # the two releases' names, from their files
        for name, other in (("Arm", "Shldr"), ("ForeArm", "ForeArm"), ("Hand", "Hand"), ("UpLeg", "Thigh"),
                            ("Leg", "Shin"), ("Foot", "Foot")):
            text = re.sub(rf"\b{side}{name}\b", short + other, text)
    daz.write_text(text)
    assert "LeftForeArm" not in text and "lForeArm" in text
    fig = pr.Figure.human()
    q_mb, err_mb = tool.fit_clip(str(mb), fig)
    q_daz, err_daz = tool.fit_clip(str(daz), fig)
    assert len(q_mb) == 10 and err_mb < 0.04  # 40 frames at 120 fps -> 30; the human fits within 4 cm
    assert np.allclose(q_daz, q_mb, atol=1e-6) and err_daz == pytest.approx(err_mb, abs=1e-6)


def test_the_bvh_prior_row_and_its_distance_by_hand():
    fig, q, _ = bundled_motion("walk")
    q = q[:60:4]
    data = json.loads(model_path("priors", "cmu_bvh_pose.json").read_text())
    row = posture_row(fig, len(q), Weights(pose_prior_model="cmu_bvh_pose"))
    assert isinstance(row, PosePrior) and row.quantiles["99"] == data["correlated"]["distance_quantiles"]["99"]
    assert type(posture_row(fig, len(q), Weights())).__name__ == "Posture"  # off by default: the rest pose
    assert posture_row(fig, len(q), Weights(pose_prior_model="cmu_bvh_pose", pose_prior=None)).__class__ is not PosePrior
    # the distance by hand: the correlated joints' Mahalanobis distance from the mean
    m = fig.model
    jid = {m.names[j]: j for j in range(1, m.njoints)}
    idx = [m.idx_qs[jid[n]] for n in data["correlated"]["joints"]]
    mu = np.array([data["joints"][n][0] for n in data["correlated"]["joints"]])
    D = q[:, idx] - mu
    d = np.sqrt(np.einsum("ti,ij,tj->t", D, np.linalg.inv(np.array(data["correlated"]["covariance"])), D))
    assert np.allclose(row.distances(q), d, rtol=1e-6)
    # subject 2's walk is a pose the prior knows (its clips hold other subjects' walks)
    assert np.median(d) < data["correlated"]["distance_quantiles"]["99"]


def test_cli_pose_prior_model(tmp_path, capsys):
    """A BVH figure solved with the CMU BVH prior; the human refuses it in one line."""
    fig, q, fps = bundled_motion("walk")
    q = q[:48:2]
    cam = side_camera(q, 45.0)
    names = ["LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot", "LeftArm", "LeftForeArm",
             "LeftHand", "RightArm", "RightForeArm", "RightHand"]
    tracks = project_tracks(fig, q, cam, names, fps=fps / 2, noise_px=1.0, seed=3)
    tracks.save(tmp_path / "tracks.json")
    coco = {v: k for k, v in COCO_BODY_FROM_CMU.items()}
    pr.Tracks(tracks.points, [coco[n] for n in names], tracks.fps).save(tmp_path / "coco.json")
    cam.save(tmp_path / "cam.json")
    base = ["reconstruct", "--camera", str(tmp_path / "cam.json"), "--pose-prior-model", "cmu_bvh_pose", "--quiet"]
    bvh = ["--figure", str(bundled_clip("walk")), "--length-scale", str(CMU_UNIT_M), "--lock", *CMU_STATIC,
           "--tracks", str(tmp_path / "tracks.json")]
    assert main(base + bvh + ["--out", str(tmp_path / "r.npz")]) == 0
    assert "--pose-prior-model" not in capsys.readouterr().err
    res = pr.load_result(tmp_path / "r.npz")
    assert len(res.extras["prior_distance"]) == len(q)  # the prior's check ran, with this prior
    assert float(res.extras["prior_distance_limit"]) == pytest.approx(
        json.loads(model_path("priors", "cmu_bvh_pose.json").read_text())["correlated"]["distance_quantiles"]["99"])
    capsys.readouterr()
    # without it, the summary says that it fits (the human's summary does not)
    assert main(["reconstruct", "--camera", str(tmp_path / "cam.json"), *bvh, "--out", str(tmp_path / "r0.npz")]) == 0
    assert "but 'cmu_bvh_pose' fits this figure" in capsys.readouterr().out  # the summary, on stdout
    assert "but 'cmu_bvh_pose' fits this figure" in pr.load_result(tmp_path / "r0.npz").summary()
    assert "fits this figure" not in pr.load_result(tmp_path / "r.npz").summary()
    human = ["--figure", "human", "--tracks", str(tmp_path / "coco.json")]
    assert main(base + human + ["--out", str(tmp_path / "h.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "weights.pose_prior_model" in err[0] and "does not fit figure 'human'" in err[0]
    assert not (tmp_path / "h.npz").exists()
