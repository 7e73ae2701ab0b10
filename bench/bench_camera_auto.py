"""No calibration file: ``reconstruct(..., camera="auto")`` against the true camera.

The problem (issue 12): the bundled CMU walk (02_01, 343 frames at 120 fps) seen by a
perspective camera with f = 1100 px on a 1280 x 720 image (6 m from the middle of the
path, 45 degrees from side-on), tracked as the 12 COCO-17 body points with 2 px
Gaussian noise, reconstructed with ``Figure.human()``:

* ``true camera``: the camera that made the tracks (the reference);
* ``auto``: no camera, only the image size: principal point at the centre, focal length
  from the default 60 degree horizontal field of view (1108.5 px here), refined in the
  solve; the world is the camera's (pose is a gauge without 3D keyframes);
* ``auto, f0 = 0.7 f`` / ``1.3 f``: the same with a starting field of view that is
  30 % off in focal length (79.5 / 48.2 degrees), to show what the refinement itself
  recovers;
* ``auto:orthographic``: an orthographic camera, scale from the tracks' spread;
* with ``keyframes``: 3D point keyframes every 0.25 s (5 cm noise) in the clip's world;
  the auto camera's rotation, position and focal length then come from them.

Without keyframes the default calibration is the camera alone (lengths need 3D
information, see ``pinrecon.problem.default_calibrate``); with them, lengths too.
Accuracy computed here: PA-MPJPE (per-frame similarity alignment, Umeyama, written out
below) for every row; MPJPE only with keyframes (without them the auto camera's world
is not the clip's).

"What the data fix": the auto camera's cost profile over the focal length
(``pinrecon.starts.camera_auto.focal_profile``), a 95 % interval or "not determined".

Run: ``OPENBLAS_NUM_THREADS=1 python bench/bench_camera_auto.py`` (about 3 minutes;
``--quick`` skips the 30 %-off rows). Prints a markdown table.
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick also cuts the clips, before pinrecon is imported

QUICK = "--quick" in __import__("sys").argv and quick.take(["--every", "4"]) and __import__("sys").argv.append("--quick") is None

import argparse
import os
import time
import warnings

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

F_PX, SIZE = 1100.0, (1280, 720)


def procrustes_aligned(P, G):
    """``P`` (T, K, 3) aligned to ``G`` frame by frame by the best similarity (Umeyama)."""
    out = np.empty_like(P)
    for t in range(len(P)):
        mp, mg = P[t].mean(0), G[t].mean(0)
        X, Y = P[t] - mp, G[t] - mg
        U, S, Vt = np.linalg.svd(Y.T @ X)
        D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
        R = U @ D @ Vt
        out[t] = (np.trace(np.diag(S) @ D) / (X * X).sum()) * X @ R.T + mg
    return out


def fov_for(f_px: float) -> float:
    """Horizontal field of view (degrees) whose focal length on this image is ``f_px``."""
    return float(np.degrees(2.0 * np.arctan(SIZE[0] / 2.0 / f_px)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clip", default="walk")
    ap.add_argument("--quick", action="store_true", help="skip the rows started 30 %% off")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--every", type=int, default=1, help="keep every n-th frame (4: 30 fps) for a quicker look")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    import pinrecon as pr
    from pinrecon.starts.camera_auto import AutoCamera
    from pinrecon.synthetic import bundled_motion, coco_body_tracks, perspective_side_camera
    from pinrecon.tracks import keyframes_from_points

    bfig, q, fps = bundled_motion(args.clip)
    cam = perspective_side_camera(q, 45.0, distance_m=6.0, f_px=F_PX, center=(SIZE[0] / 2, SIZE[1] / 2))
    tracks, P = coco_body_tracks(bfig, q, cam, fps=fps, noise_px=2.0, seed=args.seed + 1)
    if args.every > 1:
        tracks, P, q, fps = pr.Tracks(tracks.points[:: args.every], list(tracks.names), fps / args.every), \
            P[:: args.every], q[:: args.every], fps / args.every
    rng = np.random.default_rng(args.seed + 2)
    kf = keyframes_from_points(list(range(0, len(q), int(round(0.25 * fps)))), P + rng.normal(0.0, 0.05, P.shape),
                               list(tracks.names), 0.05)
    names = list(tracks.names)
    cases = [
        ("true camera", cam, None),
        ("auto (60 deg)", AutoCamera(SIZE), None),
    ]
    if not args.quick:
        cases += [
            (f"auto, f0 = 0.7 f ({fov_for(0.7 * F_PX):.1f} deg)", AutoCamera(SIZE, fov_deg=fov_for(0.7 * F_PX)), None),
            (f"auto, f0 = 1.3 f ({fov_for(1.3 * F_PX):.1f} deg)", AutoCamera(SIZE, fov_deg=fov_for(1.3 * F_PX)), None),
        ]
    cases += [
        ("auto:orthographic", AutoCamera(SIZE, "orthographic"), None),
        ("true camera, keyframes", cam, kf),
        ("auto (60 deg), keyframes", AutoCamera(SIZE), kf),
        ("auto:orthographic, keyframes", AutoCamera(SIZE, "orthographic"), kf),
    ]
    rows = []
    for label, c, keys in cases:
        t = time.perf_counter()
        res = pr.reconstruct(pr.Figure.human(), tracks, c, keys)
        dt = time.perf_counter() - t
        Pe = res.keypoints3d[:, res.figure.keypoint_index(names)]
        pa = 1000 * float(np.linalg.norm(procrustes_aligned(Pe, P) - P, axis=-1).mean())
        mp = 1000 * float(np.linalg.norm(Pe - P, axis=-1).mean()) if keys is not None else float("nan")
        cal = res.calibration.get("cameras", {}).get("camera1")
        rows.append((label, res, pa, mp, cal, dt))
    print(f"\n### No calibration file: the {args.clip} ({len(q)} frames at {fps:g} fps), 12 COCO-17 points, 2 px noise, "
          f"Figure.human(), true camera f = {F_PX:g} px on {SIZE[0]} x {SIZE[1]}\n")
    print("| camera | calibrate | PA-MPJPE (mm) | vs true camera | MPJPE (mm) | focal start -> fitted (px) | "
          "focal error | what the data fix (cost profile) | reprojection (px) | time (s) |")
    print("|---|---|---:|---:|---:|---|---:|---|---:|---:|")
    ref = {False: rows[0][2], True: next(r[2] for r in rows if r[0] == "true camera, keyframes")}
    for label, res, pa, mp, cal, dt in rows:
        kfs = "keyframes" in label
        vs = f"{100 * (pa / ref[kfs] - 1):+.1f} %" if not label.startswith("true") else ""
        if cal is None:
            foc, err = "", ""
        elif cal["quantity"] == "focal_px":
            foc, err = f"{cal['start']:.0f} -> {cal['fitted']:.0f}", f"{100 * (cal['fitted'] / F_PX - 1):+.1f} %"
        else:
            foc, err = f"scale {cal['start']:.0f} -> {cal['fitted']:.0f} px/m", ""
        mps = "" if np.isnan(mp) else f"{mp:.1f}"
        rep = res.calibration.get("camera_auto", {}).get("focal")
        fix = ""
        if rep is not None:
            lo, hi = rep["interval_px"]
            costs = [c for _, c in rep["profile"]]
            low_f = rep["profile"][int(np.argmin(costs))][0]
            fix = (f"{lo:.0f}-{hi:.0f} px (95 %, the figure taken as right)" if rep["determined"] else
                   f"not determined: nothing ruled out in {lo:.0f}-{hi:.0f} px (cost moves {max(costs) - min(costs):.0f}, "
                   f"lowest at {low_f:.0f})")
        print(f"| {label} | {res.calibration.get('mode', 'none')} | {pa:.1f} | {vs} | {mps} | {foc} | {err} | {fix} | "
              f"{np.nanmean(res.reprojection_error_px):.2f} | {dt:.1f} |")


if __name__ == "__main__":
    main()
