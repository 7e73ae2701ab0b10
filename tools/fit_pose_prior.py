"""Fit the generic human's pose prior (``models/priors/human_pose.json``) to CMU motion capture.

Each clip's 12 COCO-17 body joint centres (shoulders, elbows, wrists, hips, knees, ankles),
taken at 30 fps (at most ``--max-frames`` evenly spaced frames of each) and scaled so that the median hip-knee-ankle length is the human figure's,
are fitted by ``pinrecon.reconstruct_markers`` with ``Figure.human()`` (its anatomical
limits; the rest-pose posture prior, not this one); the prior is the mean and standard
deviation of every 1-dof joint angle over all fitted frames (the standard deviation at
least ``--min-std`` rad), except the joints ``--skip`` names (the elbows' flexion), which
keep the weak rest-pose prior; and the covariance of the joints that move (standard
deviation above ``--min-std``), shrunk towards its diagonal by ``--shrink`` (Ledoit-Wolf
style, with 1e-4 rad^2 added on the diagonal) so that about a thousand frames give a well
conditioned matrix: how the joints move together (a walking thigh swings forwards with the
knee bent, not sideways), which tells the reflections of a limb apart where each joint's
own range does not.

    python tools/fit_pose_prior.py cmu-mb_01_01.bvh cmu-max_131_03.bvh -o models/priors/human_pose.json

The clips used for the bundled prior, and why these: ``models/priors/README.md``.
"""

from __future__ import annotations

import argparse
import json
import re
import warnings
from pathlib import Path

import numpy as np

import pinrecon as pr
from pinrecon.io.bvh import load_bvh
from pinrecon.problem import Weights

#: COCO-17 body points -> the joints of the two CMU BVH releases (motionbuilder, 3ds Max)
NAMES = {
    "mb": {"left_shoulder": "LeftArm", "right_shoulder": "RightArm", "left_elbow": "LeftForeArm",
           "right_elbow": "RightForeArm", "left_wrist": "LeftHand", "right_wrist": "RightHand",
           "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "left_knee": "LeftLeg", "right_knee": "RightLeg",
           "left_ankle": "LeftFoot", "right_ankle": "RightFoot"},
    "max": {"left_shoulder": "LeftShoulder", "right_shoulder": "RightShoulder", "left_elbow": "LeftElbow",
            "right_elbow": "RightElbow", "left_wrist": "LeftWrist", "right_wrist": "RightWrist",
            "left_hip": "LeftHip", "right_hip": "RightHip", "left_knee": "LeftKnee", "right_knee": "RightKnee",
            "left_ankle": "LeftAnkle", "right_ankle": "RightAnkle"},
}


def leg_length(P, names):
    i = {n: k for k, n in enumerate(names)}
    return float(np.median(sum(np.linalg.norm(P[:, i[f"{s}_{a}"]] - P[:, i[f"{s}_{b}"]], axis=-1)
                               for s in ("left", "right") for a, b in (("hip", "knee"), ("knee", "ankle"))) / 2))


def fit_clip(path, fig, fps_out=30.0):
    m = load_bvh(path, 0.056444, skip_frames=1, lock="static")
    joints = set(m.figure.keypoint_names)
    table = next(t for t in NAMES.values() if set(t.values()) <= joints)
    names = list(table)
    step = max(1, int(round(m.fps / fps_out)))
    q = m.q[::step]
    P = m.figure.keypoints(q)[:, m.figure.keypoint_index([table[n] for n in names])]
    rest = fig.keypoints(fig.neutral()[None])[:, fig.keypoint_index(names)]
    P = P * (leg_length(rest, names) / leg_length(P, names))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct_markers(fig, pr.Markers(P, names, m.fps / step), weights=Weights(pose_prior=None))
    err = np.linalg.norm(res.keypoints3d[:, fig.keypoint_index(names)] - P, axis=-1).mean()
    return res.q, float(err)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("bvh", nargs="+")
    ap.add_argument("-o", "--out", default="models/priors/human_pose.json")
    ap.add_argument("--min-std", type=float, default=0.05)
    ap.add_argument("--skip", default="elbow_Z",
                    help="regular expression of joints left out (default the elbows' flexion: its mean depends on "
                    "the activity, and with it a 2 s walk's forearm was calibrated 16 %% long)")
    ap.add_argument("--shrink", type=float, default=0.1,
                    help="weight of the diagonal in the covariance (0: the sample covariance, 1: independent joints)")
    ap.add_argument("--max-frames", type=int, default=150,
                    help="frames kept per clip, evenly spaced, so that every clip weighs about the same")
    a = ap.parse_args(argv)
    fig = pr.Figure.human()
    m = fig.model
    qs, clips = [], []
    for path in a.bvh:
        q, err = fit_clip(path, fig)
        q = q[np.unique(np.linspace(0, len(q) - 1, min(len(q), a.max_frames)).round().astype(int))]
        qs.append(q)
        clips.append({"file": Path(path).name, "frames": len(q), "fit_error_mm": round(1000 * err, 1)})
        print(f"{path}: {len(q)} frames kept (of the clip at 30 fps), markers fitted to {1000 * err:.1f} mm")
    Q = np.concatenate(qs)
    joints, moving = {}, []
    for jid in range(1, m.njoints):
        if m.nqs[jid] == 1 and m.nvs[jid] == 1 and not (a.skip and re.search(a.skip, m.names[jid])):
            x = Q[:, m.idx_qs[jid]]
            joints[m.names[jid]] = [round(float(x.mean()), 5), round(max(float(x.std()), a.min_std), 5)]
            if x.std() > a.min_std:
                moving.append(jid)
    X = Q[:, [m.idx_qs[j] for j in moving]]
    C = np.cov(X, rowvar=False, bias=True)
    C = (1.0 - a.shrink) * C + a.shrink * np.diag(np.diag(C)) + 1e-4 * np.eye(len(moving))
    # how far the clips' own frames lie from the mean (Mahalanobis distance, standard
    # deviations): the yardstick of a pose the prior does not know (pinrecon.unfamiliar)
    D = X - X.mean(axis=0)
    dist = np.sqrt(np.einsum("ij,ij->i", D @ np.linalg.inv(C), D))
    out = {"figure": "Figure.human()", "units": "rad", "joints": joints,
           "correlated": {"joints": [m.names[j] for j in moving], "shrink": a.shrink,
                          "covariance": [[round(float(v), 7) for v in row] for row in C],
                          "distance_quantiles": {str(p): round(float(np.percentile(dist, p)), 3)
                                                 for p in (50, 90, 99, 100)}},
           "clips": clips, "frames": int(len(Q)), "min_std_rad": a.min_std, "skipped": a.skip,
           "made_by": "tools/fit_pose_prior.py"}
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {a.out}: {len(joints)} joints, {len(Q)} frames")


if __name__ == "__main__":
    main()
