"""Pose2Sim's real balancing trial through every default route at once: the means to judge a
change to the default path by (issue 43).

A change to a start, a stopping rule or a stage moves each camera of the real trial by several
millimetres either way (bench/README.md, bench_stages: "Measured, not adopted"), and a change
that keeps every synthetic score can still move one camera of one route (the focal profile's
early stop, camera 2 through ``pinrecon video`` only). This bench runs the default path (the
generic human, ``camera="auto"``, no keyframes) on each of the four phones alone, by the three
routes a user takes:

* ``video``: MediaPipe's tracks and world landmarks through ``pinrecon video``'s code
  (:func:`pinrecon.commands.video.run_video`, default options; the detections cached by
  bench_video.py, which runs MediaPipe where the cache is empty);
* ``mediapipe-2d``: the same tracks without the world landmarks (pinrecon's own lifter joins);
* ``openpose``: Pose2Sim's OpenPose BODY_25B detections of the same frames (the lifter joins),
  as bench_lifter.py reads them;

and prints each run's PA-MPJPE and flipped limb segments against the four-camera triangulation
(12 COCO body points, bench_real's segments) and the ``reconstruct`` call's seconds, then the
means per route and over every run. To compare two commits, run it with the other checkout's
``src`` first on ``PYTHONPATH`` and compare the means.

    OMP_NUM_THREADS=1 python bench/bench_real_panel.py            # about 2 min
    PYTHONPATH=/path/to/other/checkout/src OMP_NUM_THREADS=1 python bench/bench_real_panel.py
    OMP_NUM_THREADS=1 python bench/bench_real_panel.py --skip mirrors   # a stage switched off everywhere
"""

from __future__ import annotations

import quick  # bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take(["--cams", "1"], cut=False)

import argparse
import os
import tempfile
import warnings

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import bench_lifter  # bench/ is the script's folder
import bench_real
import bench_stages
import bench_video

import pinrecon as pr
from pinrecon import datasets, metrics
from pinrecon.cli import build_parser
from pinrecon.commands.video import run_video
from pinrecon.io.calibration import load_cameras

COCO12 = bench_video.COCO12
ROUTES = ("video", "mediapipe-2d", "openpose")


def solved(route: str, cam: int, skip: tuple[str, ...] = ()):
    """The default path's :class:`~pinrecon.result.Result` of camera ``cam`` by ``route``, the
    stages ``skip`` switched off."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if route == "openpose":
            tracks = bench_lifter.openpose_tracks(cam)
            return pr.reconstruct(pr.Figure.human("auto", tracks=tracks), tracks, "auto",
                                  image_size=bench_lifter.OPENPOSE_IMAGE, skip=skip)
        if route == "mediapipe-2d":  # bench_stages' real case without cues: the tracks, the image size
            bare, size = bench_stages.real_case(cam, False)[:2]
            return pr.reconstruct(pr.Figure.human(), bare, "auto", image_size=size, skip=skip)
        video = datasets.fetch(f"{bench_video.TRIAL}/videos/cam{cam:02d}.mp4")
        with tempfile.TemporaryDirectory() as out:
            args = build_parser().parse_args(["video", str(video), "--out", out, "--quiet"]
                                             + (["--skip", *skip] if skip else []))
            return run_video(args, tracked=[bench_video.tracked(video, False)[0]])["result"]


def score(res, G: np.ndarray, camera) -> tuple[float, float, float]:
    """(PA-MPJPE mm, flipped limb segments %, the call's seconds) of a result against the truth."""
    P = bench_real.in_true_world(res.keypoints3d[:, res.figure.keypoint_index(COCO12)], res.cameras[0], camera)
    return (metrics.pa_mpjpe(P, G), 100.0 * metrics.flip_rate(P, G, camera, bench_video.BONES),
            float(res.extras["run_time_s"]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cams", type=int, nargs="*", default=[1, 2, 3, 4], help="which phones (1-4)")
    ap.add_argument("--routes", nargs="*", choices=ROUTES, default=list(ROUTES))
    ap.add_argument("--skip", nargs="*", default=[], metavar="STAGE",
                    help="stages to switch off in every run (pinrecon.stages.STAGES; default none)")
    a = ap.parse_args(argv)
    from provenance import provenance

    print(provenance())
    print("command: OMP_NUM_THREADS=1 python bench/bench_real_panel.py"
          + (f" --cams {' '.join(map(str, a.cams))}" if a.cams != [1, 2, 3, 4] else "")
          + (f" --routes {' '.join(a.routes)}" if a.routes != list(ROUTES) else "")
          + (f" --skip {' '.join(a.skip)}" if a.skip else ""))
    G = bench_video.truth()
    cams = load_cameras(datasets.fetch(f"{bench_video.TRIAL}/calibration/Calib_qualisys.toml"))
    print("\nPose2Sim's balancing trial, each phone alone, the default path (Figure.human(), camera 'auto', no "
          f"keyframes{'; stages switched off: ' + ', '.join(a.skip) if a.skip else ''}), against the four-camera "
          "triangulation; PA-MPJPE (mm) / flipped limb segments (%) / the reconstruct call (s)\n")
    print("| camera | " + " | ".join(a.routes) + " |")
    print("|---|" + "---|" * len(a.routes), flush=True)
    table = np.full((len(a.cams), len(a.routes), 3), np.nan)
    for i, c in enumerate(a.cams):
        for j, route in enumerate(a.routes):
            table[i, j] = score(solved(route, c, tuple(a.skip)), G, cams[c - 1].camera)
        print(f"| cam{c:02d} | " + " | ".join(f"{p:.1f} / {f:.1f} / {s:.1f}" for p, f, s in table[i]) + " |",
              flush=True)
    m = table.mean(axis=0)
    print("| mean | " + " | ".join(f"**{p:.1f}** / {f:.1f} / {s:.1f}" for p, f, s in m) + " |")
    print(f"\nover all {table.shape[0] * table.shape[1]} runs: PA-MPJPE {table[..., 0].mean():.1f} mm, flips "
          f"{table[..., 1].mean():.1f} %, {table[..., 2].sum():.0f} s of reconstruct calls")


if __name__ == "__main__":
    main()
