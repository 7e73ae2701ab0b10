"""The stage ``labels``: spans of frames whose left and right a detector kept the other way
round, found from the tracks' continuity (:func:`pinrecon.faults.side_swap_frames`).

Synthetic: the bundled walk (02_01), run (09_01) and dances 05_02 and 05_11 (fast spins), all
frames, sub-sampled to 60, 40 and 20 frames/s, as bench_real's detector case (12 COCO-17 points,
perspective camera at 0, 45 and 90 degrees from side-on, 2 px noise, 2 % outliers, 1 % of the
frames swapped, 3 % missing) with seeds 1-3; each case once as it is and once with a span of 20
frames (at most a third of the clip: the labelling on most frames is taken as right) swapped
from a third of the clip. A case is right when the frames found are exactly the
swapped ones. Rows per weight of the acceleration term (:data:`pinrecon.faults.ACCELERATION`).

Real: Pose2Sim's balancing trial, MediaPipe Pose on each video (cached by bench_video.py) and
OpenPose's detections, against the four-camera triangulation projected through each camera's
calibration: a frame is swapped where the detector's labels lie nearer the other side's
projected points by more than 30 px (frames where neither labelling is plain are not counted).

    OMP_NUM_THREADS=1 python bench/bench_side_swaps.py
"""

from __future__ import annotations

import quick

QUICK = quick.take(cut=False)

import sys
import time
import warnings

import numpy as np
from bench_real import tracked_case

import pinrecon as pr
from pinrecon import datasets, faults
from pinrecon.io.calibration import load_cameras
from pinrecon.io.trc import load_trc
from pinrecon.layouts import COCO_17
from pinrecon.synthetic import bundled_motion

COCO12 = list(COCO_17[5:])
TRIAL = "pose2sim-balancing"


def synthetic(weights, clips, steps, azimuths, seeds) -> None:
    print("| acceleration weight | cases | right | with a 20-frame span: right | frames missed | frames found wrongly |")
    print("|---:|---:|---:|---:|---:|---:|")
    motions = {c: bundled_motion(c) for c in clips}
    default = faults.ACCELERATION
    for w in weights:
        faults.ACCELERATION = w
        n = right = right_span = missed = wrong = 0
        for clip in clips:
            fig, q, fps = motions[clip]
            for step in steps:
                for az in azimuths:
                    for seed in seeds:
                        tracks, _, _, _, log = tracked_case(fig, q[::step], fps / step, az, "none", seed=seed)
                        single = set(log["swapped_frames"].tolist())
                        T = tracks.T
                        span = [t for t in range(T // 3, T // 3 + min(20, T // 3)) if t not in single]
                        for frames, truth in ((None, single), (span, single ^ set(span))):
                            tr = tracks if frames is None else _swapped(tracks, frames)
                            found = set(faults.side_swap_frames(tr).tolist())
                            ok = found == truth
                            n += frames is None
                            right += ok and frames is None
                            right_span += ok and frames is not None
                            missed += len(truth - found)
                            wrong += len(found - truth)
        print(f"| {w:g} | {n} | {right} | {right_span} | {missed} | {wrong} |", flush=True)
    faults.ACCELERATION = default


def _swapped(tracks, frames):
    uv, conf = np.array(tracks.points), np.array(tracks.confidence)
    for a, b in faults.left_right_pairs(tracks.names):
        uv[np.ix_(frames, [a, b])] = uv[np.ix_(frames, [b, a])]
        conf[np.ix_(frames, [a, b])] = conf[np.ix_(frames, [b, a])]
    return pr.Tracks(uv, tracks.names, tracks.fps, conf)


def real() -> None:
    import bench_video

    m = load_trc(datasets.fetch(f"{TRIAL}/pose-3d/S00_P00_T01_BalancingTrial_0-100.trc"), names="pinrecon")
    G = m.points[:, [m.names.index(c) for c in COCO12]]
    cams = load_cameras(datasets.fetch(f"{TRIAL}/calibration/Calib_qualisys.toml"))
    perm = np.arange(12)
    for a, b in faults.left_right_pairs(COCO12):
        perm[a], perm[b] = b, a
    print("\n| detector | camera | swapped frames (triangulation) | found | missed | found wrongly | not plain | ms |")
    print("|---|---|---|---|---:|---:|---:|---:|")
    for c in range(1, 5):
        uvG = cams[c - 1].camera.project(G)
        video = datasets.fetch(f"{TRIAL}/videos/cam{c:02d}.mp4")
        mp, _ = bench_video.tracked(video, False)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            op = pr.load_tracks(datasets.folder(f"{TRIAL}/pose/cam{c:02d}_json"), fps=60.0)
        for name, tr in (("MediaPipe", mp), ("OpenPose", op)):
            tr = tr.select(COCO12)
            n = min(tr.T, len(G))
            uv = tr.points[:n]
            kept = np.nanmean(np.linalg.norm(uv - uvG[:n], axis=-1), axis=1)
            other = np.nanmean(np.linalg.norm(uv[:, perm] - uvG[:n], axis=-1), axis=1)
            plain = np.abs(kept - other) > 30.0
            truth = np.flatnonzero(plain & (other < kept))
            t0 = time.perf_counter()
            found = faults.side_swap_frames(tr)
            ms = 1000 * (time.perf_counter() - t0)
            f_plain = np.intersect1d(found, np.flatnonzero(plain))
            print(f"| {name} | cam{c:02d} | {_ranges(truth) or '-'} | {_ranges(found) or '-'} "
                  f"| {len(np.setdiff1d(truth, f_plain))} | {len(np.setdiff1d(f_plain, truth))} "
                  f"| {int((~plain).sum())} | {ms:.1f} |", flush=True)


def _ranges(f) -> str:
    from pinrecon.result import spans_text

    return spans_text(f)


def main() -> None:
    from provenance import provenance

    print(provenance())
    print("command: OMP_NUM_THREADS=1 python bench/bench_side_swaps.py" + (" --quick" if QUICK else ""))
    print("\nsynthetic detector tracks (see the docstring): a case is right when exactly its swapped frames are found\n")
    if QUICK:
        synthetic([2.0], ["spin"], [6], [90.0], [1])
        return
    synthetic([1.0, 2.0, 3.0], ["walk", "run", "dance", "spin"], [2, 3, 6], [0.0, 45.0, 90.0], [1, 2, 3])
    real()


if __name__ == "__main__":
    sys.exit(main())
