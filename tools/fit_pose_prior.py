"""Fit a pose prior (``models/priors/*.json``) to CMU motion capture.

``--figure human`` (default; ``models/priors/human_pose.json``):

Each clip's 12 COCO-17 body joint centres (shoulders, elbows, wrists, hips, knees, ankles; BVH
of the CMU motionbuilder, 3ds Max or Daz releases, told apart by their joint names),
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

``--figure bvh`` (``models/priors/cmu_bvh_pose.json``): the prior of a figure made from a BVH
file of the same skeleton layout (the CMU motionbuilder release, any subject): no fitting,
the clips' channels are that figure's joint angles. The same statistics over them, the
joints ``--skip`` names left out (default the fingers and thumbs, which the capture does not
measure), and the rest pose's bone directions (``"rest_directions"``: the mean unit OFFSET
of each bone over the clips' skeletons), by which :func:`pinrecon.rows.posture.posture_row`
refuses a figure whose joints have the same names but another rest pose.

    python tools/fit_pose_prior.py --figure bvh 01_01.bvh 03_01.bvh -o models/priors/cmu_bvh_pose.json

The clips used for the bundled priors, and why these: ``models/priors/README.md``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import re
import warnings
from pathlib import Path

import numpy as np

import pinrecon as pr
from pinrecon.io.bvh import load_bvh
from pinrecon.problem import Weights
from pinrecon.rows.posture import rest_directions

#: COCO-17 body points -> the joints of three CMU BVH releases (motionbuilder, 3ds Max, Daz)
NAMES = {
    "mb": {"left_shoulder": "LeftArm", "right_shoulder": "RightArm", "left_elbow": "LeftForeArm",
           "right_elbow": "RightForeArm", "left_wrist": "LeftHand", "right_wrist": "RightHand",
           "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "left_knee": "LeftLeg", "right_knee": "RightLeg",
           "left_ankle": "LeftFoot", "right_ankle": "RightFoot"},
    "max": {"left_shoulder": "LeftShoulder", "right_shoulder": "RightShoulder", "left_elbow": "LeftElbow",
            "right_elbow": "RightElbow", "left_wrist": "LeftWrist", "right_wrist": "RightWrist",
            "left_hip": "LeftHip", "right_hip": "RightHip", "left_knee": "LeftKnee", "right_knee": "RightKnee",
            "left_ankle": "LeftAnkle", "right_ankle": "RightAnkle"},
    "daz": {"left_shoulder": "lShldr", "right_shoulder": "rShldr", "left_elbow": "lForeArm",
            "right_elbow": "rForeArm", "left_wrist": "lHand", "right_wrist": "rHand",
            "left_hip": "lThigh", "right_hip": "rThigh", "left_knee": "lShin", "right_knee": "rShin",
            "left_ankle": "lFoot", "right_ankle": "rFoot"},
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
        res = pr.reconstruct_markers(fig, pr.Markers(P, names, m.fps / step), weights=Weights(pose_prior=None),
                                     calibrate="none")
    err = np.linalg.norm(res.keypoints3d[:, fig.keypoint_index(names)] - P, axis=-1).mean()
    return res.q, float(err)


def clip_channels(path, fps_out=30.0):
    """(figure, q at about ``fps_out``, rest directions {joint: unit OFFSET}) of a BVH clip
    whose figure is the prior's own (``--figure bvh``)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = load_bvh(path, 0.056444, skip_frames=1)
    step = max(1, round(m.fps / fps_out))
    return m.figure, m.q[::step], rest_directions(m.figure)


def made_with(a):
    """What a prior file was made with: the fitted joint angles come from this pinrecon's
    ``reconstruct_markers`` and a mixture from scikit-learn's random start, so the same
    clips give another file under another commit or version (bench/README.md, "The
    prior's own draw")."""
    bench = Path(__file__).resolve().parents[1] / "bench"
    spec = importlib.util.spec_from_file_location("provenance", bench / "provenance.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = {"pinrecon": mod.provenance(), "numpy": np.__version__, "components": a.components, "shrink": a.shrink,
           "max_frames": a.max_frames}
    if a.components > 1:
        import sklearn

        out |= {"scikit-learn": sklearn.__version__, "random_state": a.seed}
    return out


def shrunk(C, shrink):
    """``C`` shrunk towards its diagonal by ``shrink``, plus 1e-4 rad^2 on it."""
    return (1.0 - shrink) * C + shrink * np.diag(np.diag(C)) + 1e-4 * np.eye(len(C))


def rounded(C):
    return [[round(float(v), 7) for v in row] for row in C]


def mixture(X, k, shrink, seed=0):
    """({"weights", "means", "covariances"}, means, covariances): a mixture of ``k`` full
    Gaussians fitted to ``X`` (frames, joints) by scikit-learn, each covariance shrunk."""
    try:
        from sklearn.mixture import GaussianMixture
    except ImportError:
        raise SystemExit("--components above 1 needs scikit-learn: pip install scikit-learn") from None
    g = GaussianMixture(k, covariance_type="full", reg_covar=1e-4, n_init=3, random_state=seed).fit(X)
    covs = [shrunk(c, shrink) for c in g.covariances_]
    return ({"weights": [round(float(w), 6) for w in g.weights_], "means": [[round(float(v), 6) for v in mu] for mu in g.means_],
             "covariances": [rounded(c) for c in covs]}, list(g.means_), covs)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("bvh", nargs="+")
    ap.add_argument("--figure", choices=("human", "bvh"), default="human",
                    help="human: Figure.human(), the clips' joint centres fitted; bvh: the clips' own skeleton layout")
    ap.add_argument("-o", "--out", default=None, help="default models/priors/human_pose.json or cmu_bvh_pose.json")
    ap.add_argument("--min-std", type=float, default=0.05)
    ap.add_argument("--skip", default=None,
                    help="regular expression of joints left out (human: default the elbows' flexion, elbow_Z: its "
                    "mean depends on the activity, and with it a 2 s walk's forearm was calibrated 16 %% long; bvh: "
                    "default the fingers and thumbs, Thumb|Finger)")
    ap.add_argument("--shrink", type=float, default=0.1,
                    help="weight of the diagonal in the covariance (0: the sample covariance, 1: independent joints)")
    ap.add_argument("--max-frames", type=int, default=150,
                    help="frames kept per clip, evenly spaced, so that every clip weighs about the same")
    ap.add_argument("--components", type=int, default=1,
                    help="Gaussians of the correlated joints: 1, one Gaussian; more, a mixture fitted by "
                    "scikit-learn's GaussianMixture (full covariances, each shrunk as --shrink says), scored "
                    "per frame by its least-cost component (pinrecon.rows.posture.PosePrior)")
    ap.add_argument("--seed", type=int, default=0, help="the mixture fit's random state")
    a = ap.parse_args(argv)
    bvh_mode = a.figure == "bvh"
    a.out = a.out or f"models/priors/{'cmu_bvh_pose' if bvh_mode else 'human_pose'}.json"
    a.skip = (r"Thumb|Finger" if bvh_mode else "elbow_Z") if a.skip is None else a.skip
    fig = None if bvh_mode else pr.Figure.human()
    qs, clips, dirs = [], [], []
    for path in a.bvh:
        if bvh_mode:
            f, q, d = clip_channels(path)
            if fig is not None and list(f.model.names) != list(fig.model.names):
                raise SystemExit(f"{path}: joints differ from {a.bvh[0]}'s: --figure bvh needs one skeleton layout")
            fig = fig or f
            dirs.append(d)
        else:
            q, err = fit_clip(path, fig)
        q = q[np.unique(np.linspace(0, len(q) - 1, min(len(q), a.max_frames)).round().astype(int))]
        qs.append(q)
        clips.append({"file": Path(path).name, "frames": len(q)} if bvh_mode else
                     {"file": Path(path).name, "frames": len(q), "fit_error_mm": round(1000 * err, 1)})
        print(f"{path}: {len(q)} frames kept (of the clip at 30 fps)" +
              ("" if bvh_mode else f", markers fitted to {1000 * err:.1f} mm"))
    m = fig.model
    Q = np.concatenate(qs)
    joints, moving = {}, []
    for jid in range(1, m.njoints):
        if m.nqs[jid] == 1 and m.nvs[jid] == 1 and not (a.skip and re.search(a.skip, m.names[jid])):
            x = Q[:, m.idx_qs[jid]]
            joints[m.names[jid]] = [round(float(x.mean()), 5), round(max(float(x.std()), a.min_std), 5)]
            if x.std() > a.min_std:
                moving.append(jid)
    X = Q[:, [m.idx_qs[j] for j in moving]]
    C = shrunk(np.cov(X, rowvar=False, bias=True), a.shrink)
    corr = {"joints": [m.names[j] for j in moving], "shrink": a.shrink, "covariance": rounded(C)}
    means, covs = [X.mean(axis=0)], [C]
    if a.components > 1:
        corr["mixture"], means, covs = mixture(X, a.components, a.shrink, a.seed)
    # how far the clips' own frames lie from the mean (of a mixture: the nearest component's;
    # Mahalanobis distance, standard deviations): the yardstick of a pose the prior does not
    # know (pinrecon.unfamiliar)
    dist = np.min([np.sqrt(np.einsum("ij,ij->i", (X - mu) @ np.linalg.inv(c), X - mu)) for mu, c in zip(means, covs)],
                  axis=0)
    corr["distance_quantiles"] = {str(p): round(float(np.percentile(dist, p)), 3) for p in (50, 90, 99, 100)}
    out = {"figure": "BVH, CMU motionbuilder layout" if bvh_mode else "Figure.human()", "units": "rad", "joints": joints,
           "correlated": corr,
           "clips": clips, "frames": len(Q), "min_std_rad": a.min_std, "skipped": a.skip,
           "made_by": "tools/fit_pose_prior.py" + (" --figure bvh" if bvh_mode else ""), "made_with": made_with(a)}
    if bvh_mode:
        mean_dir = {n: np.mean([d[n] for d in dirs], axis=0) for n in dirs[0]}
        out["rest_directions"] = {n: [round(float(x), 4) for x in v / np.linalg.norm(v)] for n, v in mean_dir.items()}
        spread = max(np.degrees(np.arccos(np.clip(d[n] @ (v / np.linalg.norm(v)), -1, 1)))
                     for d in dirs for n, v in mean_dir.items())
        out["rest_direction_spread_deg"] = round(float(spread), 1)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {a.out}: {len(joints)} joints, {len(Q)} frames")


if __name__ == "__main__":
    main()
