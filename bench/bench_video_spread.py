"""How far one number on real footage can be trusted: Pose2Sim's balancing trial, perturbed.

The README quotes one PA-MPJPE per setting for Pose2Sim's real balancing trial (camera 1,
OpenPose BODY_25B, 100 frames at 60 fps, ``pose2sim-balancing`` through pinrecon.datasets), scored
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

Beside PA-MPJPE each run prints the share of limb segments whose depth order along camera 1's
line of sight is flipped against the triangulation (``pinrecon.metrics.flip_rate``: upper arms,
forearms, thighs, shanks, frames where the triangulated depth difference exceeds a tenth of the
segment) and the MPJPE after removing the one depth offset. The triangulation is in the
calibration's world (it reprojects into camera 1 at a median 12.8 px from OpenPose's points);
the result with no camera file is in its fitted camera's, carried into camera 1's through the
camera frame both describe.

    OPENBLAS_NUM_THREADS=1 python bench/bench_video_spread.py            # 5 seeds (about 5 min)
    python bench/bench_video_spread.py --seeds 10 --drop 0.02
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take(["--seeds", "1"])

import argparse
import os
import time
import warnings
from pathlib import Path

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
REPO = Path(__file__).resolve().parents[1]

import bench_real  # bench/ is the script's folder

import pinrecon as pr
from pinrecon import datasets
from pinrecon.io.calibration import load_cameras
from pinrecon.io.trc import load_trc
from pinrecon.layouts import COCO_17
from pinrecon.metrics import flip_rate, mpjpe_depth_aligned, pa_mpjpe
from pinrecon.stability import drop_detections

TRACKS = datasets.folder("pose2sim-balancing/pose/cam01_json")
TRC = datasets.fetch("pose2sim-balancing/pose-3d/S00_P00_T01_BalancingTrial_0-100.trc")
CALIB = datasets.fetch("pose2sim-balancing/calibration/Calib_qualisys.toml")
COCO12 = list(COCO_17[5:])  # the 12 body points: shoulders, elbows, wrists, hips, knees, ankles
SEGMENTS = [(COCO12.index(a), COCO12.index(b)) for a, b in bench_real.SEGMENTS]  # its flip metric's limbs


def truth() -> np.ndarray:
    """(T, 12, 3) the triangulated body points of the TRC file (metres, in the calibration's
    world, Z up)."""
    m = load_trc(TRC, names="pinrecon")
    return m.points[:, [m.names.index(n) for n in COCO12]]


def trial():
    """Camera 1's OpenPose tracks of the trial (BODY_25B names, 60 fps) and Pose2Sim's
    calibration of camera 1."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tracks = pr.load_tracks(TRACKS, fps=60.0)
    return tracks, load_cameras(CALIB)[0].camera


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=5, help="perturbed copies per setting (seed 0, the trial as it is, "
                    "is always run too)")
    ap.add_argument("--drop", type=float, default=0.01, help="share of the observed detections removed per copy")
    a = ap.parse_args(argv)
    if a.seeds < 1:  # the summary compares the trial as it is with its perturbed copies
        ap.error(f"--seeds must be at least 1, got {a.seeds}")
    from provenance import provenance

    print(provenance())
    tracks, cam = trial()
    G = truth()
    b25b = pr.Figure.human("auto", tracks=tracks)
    coco = pr.Figure.human()
    settings = {
        "no camera file, BODY_25B map": (b25b, None, "auto", {"image_size": (1088, 1920)}),
        "calibrated, BODY_25B map": (b25b, None, cam, {}),
        "calibrated, 17 COCO points": (coco, [n for n in tracks.names if n in coco.keypoint_names], cam, {}),
    }
    print(f"\nPose2Sim's balancing trial, {a.drop:.0%} of the observed detections removed at random per seed "
          "(seed 0: as it is)\n")
    print("| setting | seed | PA-MPJPE (mm) | flips (%) | MPJPE depth-aligned (mm) | time (s) |\n"
          "|---|---:|---:|---:|---:|---:|", flush=True)
    out: dict = {}
    for label, (fig, names, camera, kw) in settings.items():
        for seed in range(a.seeds + 1):
            tr = tracks if names is None else tracks.select(names)
            tr = drop_detections(tr, a.drop, seed) if seed else tr
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = pr.reconstruct(fig, tr, camera, **kw)
            P = res.keypoints3d[:, res.figure.keypoint_index(COCO12)]
            if camera == "auto":  # its world is its fitted camera's: into camera 1's through the camera frame
                P = bench_real.in_true_world(P, res.cameras[0], cam)
            pa = pa_mpjpe(P, G)
            flips = 100.0 * flip_rate(P, G, cam, SEGMENTS)
            dz = mpjpe_depth_aligned(P, G, cam)
            out.setdefault(label, []).append((pa, flips, dz))
            print(f"| {label} | {seed} | {pa:.1f} | {flips:.1f} | {dz:.1f} | {time.perf_counter() - t0:.0f} |",
                  flush=True)
    print("\n| setting | as it is (mm) | median over the perturbed (mm) | range (mm) | within 10 mm of as it is | "
          "flips as it is / median (%) | MPJPE depth-aligned as it is / median (mm) |")
    print("|---|---:|---:|---:|---:|---|---|")
    for label, v in out.items():
        v = np.array(v)
        base, pert = v[0, 0], v[1:, 0]
        near = int(np.sum(np.abs(pert - base) <= 10.0))
        print(f"| {label} | {base:.1f} | {np.median(pert):.1f} | {pert.min():.1f}-{pert.max():.1f} | "
              f"{near} of {len(pert)} | {v[0, 1]:.1f} / {np.median(v[1:, 1]):.1f} | "
              f"{v[0, 2]:.1f} / {np.median(v[1:, 2]):.1f} |")


if __name__ == "__main__":
    main()
