"""The broader prior's switch on motion capture it was not fitted to: single Gaussian against mixture.

``reconstruct`` solves a clip again with the generic human's broader pose prior
(``human_pose_mixture``) when the default (``human_pose``) does not know enough of its frames'
poses: more than half, or a fifth with one camera and no keyframes (``pinrecon.unfamiliar.
switch_share``). This bench measures what that choice is worth on clips of any CMU BVH release
(motionbuilder, 3ds Max or Daz joint names, as ``tools/fit_pose_prior.py`` reads them), so that
clips the mixture was not fitted to can judge it (CMU's salsa, subjects 60 and 61, in the Daz
release: bench/README.md). Each clip is taken at 30 fps (its first ``--frames``), seen as
bench_real's detector case (the 12 COCO-17 body points through a perspective camera 6 m away,
``--angles`` from side-on; the issue's faults: ``pinrecon.synthetic.detector_faults``; 3D point
keyframes with 5 cm of noise on the first and last frame, or none) and solved with
``Figure.human()`` (calibrated lengths) under each prior named, then by default (``auto``, which
says whether it switched and at what share of the main solve's frames).

    OPENBLAS_NUM_THREADS=1 python bench/bench_switch.py 60_01_scaled.bvh 61_01_scaled.bvh --scale 1
    python bench/bench_switch.py clip.bvh --keyframes none first+last --priors human_pose auto
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take(["--frames", "60", "--angles", "45", "--priors", "auto"])
if QUICK:  # the clip: the dance pinrecon fetches
    from pinrecon import datasets as _datasets

    __import__("sys").argv.insert(1, str(_datasets.clip("dance")))

import argparse
import json
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tools"))

from bench_real import score, tracked_case  # bench/ is the script's folder
from fit_pose_prior import NAMES  # the CMU releases' joint names

import pinrecon as pr
from pinrecon.io.bvh import load_bvh


def release(figure) -> dict:
    """The COCO-17 -> joint table of the CMU release whose 12 joints the figure has."""
    have = set(figure.keypoint_names)
    for table in NAMES.values():
        if set(table.values()) <= have:
            return table
    raise SystemExit(f"none of the CMU releases' joint names ({', '.join(NAMES)}) are all in this file")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("bvh", nargs="+", type=Path, help="CMU BVH clips (any release)")
    ap.add_argument("--scale", type=float, default=0.056444, help="BVH units to metres (0.056444: CMU's "
                    "releases as published; 1 for files already in metres, such as the *_scaled.bvh copies)")
    ap.add_argument("--frames", type=int, default=600, help="the first N frames at 30 fps")
    ap.add_argument("--angles", type=float, nargs="+", default=[45.0, 60.0])
    ap.add_argument("--keyframes", nargs="+", default=["none"], choices=["none", "first+last"])
    ap.add_argument("--priors", nargs="+", default=["human_pose", "human_pose_mixture", "auto"])
    ap.add_argument("--json", action="store_true", help="one JSON line per run instead of the table")
    a = ap.parse_args(argv)
    from provenance import provenance

    print(provenance())
    print("\n| clip | keyframes | angle | prior | PA-MPJPE (mm) | flips (%) | frames unfamiliar to the default (%) | "
          "switched | time (s) |\n|---|---|---:|---|---:|---:|---:|---|---:|", flush=True)
    for path in a.bvh:
        m = load_bvh(path, a.scale, skip_frames=1, lock="static")
        step = max(1, round(m.fps / 30.0))
        q, fps, joints = m.q[::step][: a.frames], m.fps / step, release(m.figure)
        for kf in a.keyframes:
            for az in a.angles:
                tracks, cam, keys, P, _ = tracked_case(m.figure, q, fps, az, kf, seed=int(az), joints=joints)
                for prior in a.priors:
                    t0 = time.perf_counter()
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        r = pr.reconstruct(pr.Figure.human(), tracks, cam, keys, calibrate="lengths",
                                           weights=pr.Weights(pose_prior_model=prior))
                    dt = time.perf_counter() - t0
                    s = score(r.keypoints3d[:, r.figure.keypoint_index(list(tracks.names))], P, cam, list(tracks.names))
                    d = np.asarray(r.extras["prior_distance"], float)
                    share = 100.0 * float(np.mean(d > float(r.extras["prior_distance_limit"])))
                    judged = str(r.extras.get("prior_distance_model", prior))  # a switched result: by the default
                    share = share if judged in ("human_pose", "auto") else float("nan")
                    switched = ("-" if prior != "auto" else
                                f"yes, at {100 * float(r.extras['prior_default_unfamiliar']):.0f} %"
                                if "prior_model" in r.extras else "no")
                    row = {"clip": path.name, "keyframes": kf, "angle": az, "prior": prior, "pa": s["pa"],
                           "flips": s["flips"], "unfamiliar": share, "switched": switched, "time": dt}
                    if a.json:
                        print(json.dumps(row), flush=True)
                    else:
                        print(f"| {path.name} | {kf} | {az:g} | {prior} | {s['pa']:.1f} | {s['flips']:.1f} | "
                              f"{'-' if np.isnan(share) else f'{share:.0f}'} | {switched} | {dt:.0f} |", flush=True)


if __name__ == "__main__":
    main()
