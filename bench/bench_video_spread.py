"""How far one number on real footage can be trusted: Pose2Sim's balancing trial, perturbed.

The README quotes one PA-MPJPE per setting for Pose2Sim's real balancing trial (camera 1,
OpenPose BODY_25B, 100 frames at 60 fps, ``examples/data/pose2sim_balancing``), scored
against Pose2Sim's own triangulation from all four calibrated cameras. A monocular solve
of motion the pose prior does not know can land in different basins after small changes of
its input, so this runs each setting on the trial as it is and on copies with a small share
of the observed detections removed at random (``--drop``, default 1 %: a detector's missed
points), several seeds, and prints each run, then per setting the median, the range and
how many runs stayed within 10 mm of the unperturbed one (the copies are
``pinrecon.stability.drop_detections``'s, which ``--stability`` solves again on a user's clip).

Settings: no camera file (``camera="auto"``, the image size, ``Figure.human("auto",
tracks=...)``: BODY_25B's map), Pose2Sim's calibration of camera 1 with the BODY_25B map,
and the same calibration with the 17 COCO points only (what a COCO-17 detector gives).

    OPENBLAS_NUM_THREADS=1 python bench/bench_video_spread.py            # 5 seeds (about 5 min)
    python bench/bench_video_spread.py --seeds 10 --drop 0.02
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from pathlib import Path

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
REPO = Path(__file__).resolve().parents[1]

import pinrecon as pr
from pinrecon.io.calibration import load_cameras
from pinrecon.io.trc import load_trc
from pinrecon.layouts import COCO_17
from pinrecon.metrics import pa_mpjpe
from pinrecon.stability import drop_detections

FOLDER = REPO / "examples" / "data" / "pose2sim_balancing"
TRC = FOLDER / "S00_P00_T01_BalancingTrial_0-100.trc"
CALIB = REPO / "tests" / "data" / "calibration" / "pose2sim" / "Calib_qualisys.toml"
COCO12 = list(COCO_17[5:])  # the 12 body points: shoulders, elbows, wrists, hips, knees, ankles


def truth() -> np.ndarray:
    """(T, 12, 3) the triangulated body points of the TRC file (metres, Z up)."""
    m = load_trc(TRC, names="pinrecon")
    return m.points[:, [m.names.index(n) for n in COCO12]]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=5, help="perturbed copies per setting (seed 0, the trial as it is, "
                    "is always run too)")
    ap.add_argument("--drop", type=float, default=0.01, help="share of the observed detections removed per copy")
    a = ap.parse_args(argv)
    from provenance import provenance

    print(provenance())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tracks = pr.load_tracks(FOLDER / "cam01_json", fps=60.0)
    G = truth()
    cam = load_cameras(CALIB)[0].camera
    b25b = pr.Figure.human("auto", tracks=tracks)
    coco = pr.Figure.human()
    settings = {
        "no camera file, BODY_25B map": (b25b, None, "auto", {"image_size": (1088, 1920)}, G),
        "calibrated, BODY_25B map": (b25b, None, cam, {}, G[:, :, [2, 0, 1]]),
        "calibrated, 17 COCO points": (coco, [n for n in tracks.names if n in coco.keypoint_names], cam, {},
                                       G[:, :, [2, 0, 1]]),
    }
    print(f"\nPose2Sim's balancing trial, {a.drop:.0%} of the observed detections removed at random per seed "
          "(seed 0: as it is)\n")
    print("| setting | seed | PA-MPJPE (mm) | time (s) |\n|---|---:|---:|---:|", flush=True)
    out: dict = {}
    for label, (fig, names, camera, kw, GG) in settings.items():
        for seed in range(a.seeds + 1):
            tr = tracks if names is None else tracks.select(names)
            tr = drop_detections(tr, a.drop, seed) if seed else tr
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = pr.reconstruct(fig, tr, camera, **kw)
            P = res.keypoints3d[:, res.figure.keypoint_index(COCO12)]
            pa = pa_mpjpe(P, GG)
            out.setdefault(label, []).append(pa)
            print(f"| {label} | {seed} | {pa:.1f} | {time.perf_counter() - t0:.0f} |", flush=True)
    print("\n| setting | as it is (mm) | median over the perturbed (mm) | range (mm) | within 10 mm of as it is |")
    print("|---|---:|---:|---:|---:|")
    for label, v in out.items():
        base, pert = v[0], np.array(v[1:])
        near = int(np.sum(np.abs(pert - base) <= 10.0))
        print(f"| {label} | {base:.1f} | {np.median(pert):.1f} | {pert.min():.1f}-{pert.max():.1f} | "
              f"{near} of {len(pert)} |")


if __name__ == "__main__":
    main()
