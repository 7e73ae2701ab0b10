"""Calibration: the generic human fitted to the subject (segment lengths, focal length).

The problem (issue 9): a bundled CMU clip (walk 02_01, run 09_01, dance 05_11 "sideways
steps, pirouette") seen by a perspective camera (f = 1100 px, 1280 x 720, 6 m from the
middle of the path, 45 degrees from side-on), tracked as the 12 COCO-17 body points
(shoulders, elbows, wrists, hips, knees, ankles = the CMU joints LeftArm, LeftForeArm,
LeftHand, LeftUpLeg, LeftLeg, LeftFoot and their right twins) with 2 px Gaussian noise;
3D point keyframes of the same 12 points (the CMU joint positions, 5 cm noise, sigma
5 cm) every 0.25 s, or on the first and last frame only. Reconstructed with
``Figure.human()`` (COCO-17 map), whose proportions differ from the subject's (its
forearm is 52 % longer than this walker's): ``pinrecon.reconstruct(..., calibrate=...)``.

Rows:
* ``none``: motion only (the figure as given);
* ``lengths``: the segment scale factors as unknowns (the default for the human);
* ``lengths+camera, f0 = 0.7 f``: also the focal length, started 30 % short (1.3: long).
  ``reconstruct`` starts a calibrated camera's focal length from the keyframes (closed
  form, ``camera_scale_from_keyframes``); the row marked *refined only* skips that and
  starts the solve at 0.7 f (``make_problem`` + ``initial_trajectory`` + ``solve``);
* ``lengths, first+last keyframes``: keyframes on the first and last frame only.

Accuracy is computed here, independently of pinrecon: MPJPE (mean distance of the 12
points to the clip's joints), PA-MPJPE (the same after a per-frame similarity alignment,
Umeyama's closed form written out below) and each segment's length error: the mean over
frames of the distance between its two points, estimated against the clip's own (left
and right twins averaged; hip and shoulder width between the twins).

Run: ``OPENBLAS_NUM_THREADS=1 python bench/bench_calibration.py`` (about 5 minutes;
``--clips walk`` for the walk alone, about a minute). Prints markdown tables.
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take(["--clips", "walk"])

import argparse
import os
import time
import warnings

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

CLIPS = {"walk": "walk", "run": "run", "dance": "spin"}  # bundled names (spin = CMU 05_11, a dance)
SEGMENTS = {
    "thigh": [("left_hip", "left_knee"), ("right_hip", "right_knee")],
    "shank": [("left_knee", "left_ankle"), ("right_knee", "right_ankle")],
    "upper arm": [("left_shoulder", "left_elbow"), ("right_shoulder", "right_elbow")],
    "forearm": [("left_elbow", "left_wrist"), ("right_elbow", "right_wrist")],
    "hip width": [("left_hip", "right_hip")],
    "shoulder width": [("left_shoulder", "right_shoulder")],
}
F_PX, SIZE = 1100.0, (1280, 720)


def procrustes_aligned(P, G):
    """``P`` (T, K, 3) aligned to ``G`` frame by frame by the similarity (rotation,
    translation, scale) minimising the squared distance (Umeyama 1991)."""
    out = np.empty_like(P)
    for t in range(len(P)):
        mp, mg = P[t].mean(0), G[t].mean(0)
        X, Y = P[t] - mp, G[t] - mg
        U, S, Vt = np.linalg.svd(Y.T @ X)  # cov(G, P) = U S V^T
        D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
        R = U @ D @ Vt
        s = np.trace(np.diag(S) @ D) / (X * X).sum()
        out[t] = s * X @ R.T + mg
    return out


def segment_lengths(P, names):
    """Mean over frames of each segment's length (twins averaged), metres."""
    idx = {n: i for i, n in enumerate(names)}
    return {s: float(np.mean([np.linalg.norm(P[:, idx[a]] - P[:, idx[b]], axis=-1).mean() for a, b in pairs]))
            for s, pairs in SEGMENTS.items()}


def scene(clip, seed=0):
    import pinrecon as pr
    from pinrecon.synthetic import bundled_motion, coco_body_tracks, perspective_side_camera
    from pinrecon.tracks import keyframes_from_points

    bfig, q, fps = bundled_motion(CLIPS[clip])
    cam = perspective_side_camera(q, 45.0, distance_m=6.0, f_px=F_PX, center=(SIZE[0] / 2, SIZE[1] / 2))
    tracks, P = coco_body_tracks(bfig, q, cam, fps=fps, noise_px=2.0, seed=seed + 1)
    rng = np.random.default_rng(seed + 2)
    noisy = P + rng.normal(0.0, 0.05, P.shape)
    step = int(round(0.25 * fps))
    every = keyframes_from_points(list(range(0, len(q), step)), noisy, list(tracks.names), 0.05)
    ends = keyframes_from_points([0, len(q) - 1], noisy, list(tracks.names), 0.05)
    uv = tracks.points
    inside = float(np.mean((uv[..., 0] >= 0) & (uv[..., 0] < SIZE[0]) & (uv[..., 1] >= 0) & (uv[..., 1] < SIZE[1])))
    return pr, cam, tracks, P, every, ends, inside


def _refined_only(pr, tracks, cam0, keyframes, calibrate):
    """The batch solve from the given focal length (no closed-form start): keypoints
    (T, K, 3) of the calibrated figure, the fitted camera, the solve."""
    from pinrecon.problem import make_problem
    from pinrecon.solver import solve
    from pinrecon.starts import initial_trajectory

    problem = make_problem(pr.Figure.human(), tracks, cam0, keyframes, calibrate=calibrate)
    res = solve(problem, initial_trajectory(problem, "auto"), active=problem.active, g0=problem.g0)
    return problem.keypoints(problem.figure.normalize(res.x), res.g), problem.cameras_at(res.g)[0], res


def run_case(pr, cam, tracks, P, keyframes, calibrate, focal_start=1.0, refined_only=False):
    K = cam.K.copy()
    K[:2, :2] *= focal_start
    cam0 = pr.Perspective(K, cam.R, cam.t)
    names = list(tracks.names)
    t = time.perf_counter()
    if refined_only:
        P_all, camera, solved = _refined_only(pr, tracks, cam0, keyframes, calibrate)
        Pe = P_all[:, pr.Figure.human().keypoint_index(names)]
    else:
        res = pr.reconstruct(pr.Figure.human(), tracks, cam0, keyframes, calibrate=calibrate)
        camera, solved = res.camera, res.solve
        Pe = res.keypoints3d[:, res.figure.keypoint_index(names)]
    dt = time.perf_counter() - t
    est, true = segment_lengths(Pe, names), segment_lengths(P, names)
    err = {s: 100.0 * (est[s] / true[s] - 1.0) for s in SEGMENTS}
    return {
        "mpjpe": 1000 * float(np.linalg.norm(Pe - P, axis=-1).mean()),
        "pa": 1000 * float(np.linalg.norm(procrustes_aligned(Pe, P) - P, axis=-1).mean()),
        "seg": err,
        "seg_mean": float(np.mean(np.abs(list(err.values())))),
        "focal": float(camera.K[0, 0]),
        "time": dt,
        "iterations": solved.iterations,
        "status": solved.status,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", nargs="*", default=list(CLIPS), choices=list(CLIPS))
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    from provenance import provenance

    print(provenance())
    warnings.simplefilter("ignore")
    cases = [
        ("none", "every", "none", 1.0),
        ("lengths", "every", "lengths", 1.0),
        ("lengths+camera, f0 = 0.7 f", "every", "lengths+camera", 0.7),
        ("lengths+camera, f0 = 1.3 f", "every", "lengths+camera", 1.3),
        ("lengths+camera, f0 = 0.7 f, refined only", "every", "lengths+camera", 0.7),
        ("none, first+last keyframes", "ends", "none", 1.0),
        ("lengths, first+last keyframes", "ends", "lengths", 1.0),
    ]
    rows = []
    for clip in args.clips:
        pr, cam, tracks, P, every, ends, inside = scene(clip, args.seed)
        for label, kf, mode, f0 in cases:
            r = run_case(pr, cam, tracks, P, every if kf == "every" else ends, mode, f0, "refined" in label)
            rows.append((clip, label, r, inside))
    print(f"\n### Calibration: Figure.human() fitted to CMU subjects (12 COCO-17 points, 2 px noise, "
          f"perspective f = {F_PX:g} px, keyframes 5 cm)\n")
    print("| clip | calibrate | MPJPE (mm) | PA-MPJPE (mm) | mean segment length error | focal (px) | iterations | "
          "time (s) |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for clip, label, r, _ in rows:
        print(f"| {clip} | {label} | {r['mpjpe']:.1f} | {r['pa']:.1f} | {r['seg_mean']:.1f} % | {r['focal']:.0f} | "
              f"{r['iterations']} | {r['time']:.1f} |")
    print("\n### Segment length errors (estimated / true - 1)\n")
    print("| clip | calibrate | " + " | ".join(SEGMENTS) + " |")
    print("|---|---|" + "---:|" * len(SEGMENTS))
    for clip, label, r, _ in rows:
        print(f"| {clip} | {label} | " + " | ".join(f"{r['seg'][s]:+.1f} %" for s in SEGMENTS) + " |")
    print()
    for clip in args.clips:
        base = next(r for c, lab, r, _ in rows if c == clip and lab == "lengths")
        for c, lab, r, inside in rows:
            if c == clip and lab.startswith("lengths+camera"):
                print(f"- {clip}, {lab}: focal {r['focal']:.0f} px ({100 * (r['focal'] / F_PX - 1):+.1f} %), MPJPE "
                      f"{100 * (r['mpjpe'] / base['mpjpe'] - 1):+.1f} % and PA-MPJPE {100 * (r['pa'] / base['pa'] - 1):+.1f} "
                      "% against the known camera.")
        print(f"- {clip}: {100 * inside:.0f} % of the tracked points inside the {SIZE[0]} x {SIZE[1]} image.")


if __name__ == "__main__":
    main()
