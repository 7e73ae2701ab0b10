"""``pinrecon video`` on a long real video: where the time goes and how much memory it takes.

Pose2Sim's balancing trial is 100 frames a camera; a user's video is often ten or a hundred
times longer. Here camera ``--cam``'s video (1080 x 1920, 60 fps) is played forwards and
backwards until it is ``--frames`` frames long (a continuous motion: frame ``i`` shows the
trial's frame ``i mod 200`` or ``199 - i mod 200``), written to a temporary folder with
OpenCV, and ``pinrecon video LONG --out DIR --quiet`` runs on it in a process of its own, as a
user runs it (default options, ``--camera auto``). Printed: the command's own seconds end to
end and per part (detector, reconstruct, exports, overlay, plots), the reconstruct call's
stages (:attr:`pinrecon.Result.stages`), the largest resident set of the command and the
processes it started (``getrusage(RUSAGE_CHILDREN).ru_maxrss``), and PA-MPJPE of the 12 COCO
body points against Pose2Sim's four-camera triangulation played the same way, beside
MediaPipe's own world landmarks of the same frames.

    OMP_NUM_THREADS=1 python bench/bench_video_long.py                  # 1200 frames, camera 1
    python bench/bench_video_long.py --frames 2400 --cam 2
"""

from __future__ import annotations

import quick

QUICK = quick.take(["--frames", "200"], cut=False)

import argparse
import resource
import tempfile
from pathlib import Path

import numpy as np
from bench_video import COCO12, TRIAL, run_command, truth

import pinrecon as pr
from pinrecon import datasets
from pinrecon.metrics import pa_mpjpe
from pinrecon.tracks import load_tracks
from pinrecon.video import require_cv2

PART = r"pinrecon video: (\d+) frames in ([\d.]+) s end to end \(([\d.]+) frames/s: (.*)\)"


def played_back_and_forth(n: int, period: int) -> np.ndarray:
    """Frame ``i`` of the long video shows frame ``played[i]`` of the trial (``period`` frames)."""
    k = np.arange(n) % (2 * period)
    return np.where(k < period, k, 2 * period - 1 - k)


def write_long(video: Path, out: Path, n: int) -> np.ndarray:
    """``video`` played forwards and backwards to ``n`` frames, written to ``out``; returns the
    source frame of each."""
    cv2 = require_cv2()
    cap = cv2.VideoCapture(str(video))
    fps, frames = cap.get(cv2.CAP_PROP_FPS), []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(f)
    cap.release()
    order = played_back_and_forth(n, len(frames))
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    for i in order:
        writer.write(frames[i])
    writer.release()
    return order


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cam", type=int, default=1, choices=[1, 2, 3, 4], help="the trial's camera")
    ap.add_argument("--frames", type=int, default=1200, help="frames of the long video")
    a = ap.parse_args(argv)
    from provenance import provenance

    print(provenance())
    print(f"command: OMP_NUM_THREADS=1 python bench/bench_video_long.py --cam {a.cam} --frames {a.frames}"
          + (" --quick" if QUICK else ""))
    video = datasets.fetch(f"{TRIAL}/videos/cam{a.cam:02d}.mp4")
    G = truth()
    with tempfile.TemporaryDirectory() as d:
        long_video, out = Path(d) / f"cam{a.cam:02d}_long.mp4", Path(d) / "out"
        order = write_long(video, long_video, a.frames)
        line = run_command(long_video, out, PART)
        rss_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        res = pr.load_result(out / "result.npz")
        tracks = load_tracks(out / "tracks.json")
    T = int(line[1])
    GT = G[order[:T]]
    P = res.keypoints3d[:, res.figure.keypoint_index(COCO12)]
    W = tracks.lifted.select(COCO12).points
    ok = np.isfinite(GT).all(axis=(1, 2))
    print(f"\nPose2Sim's camera {a.cam} played forwards and backwards to {T} frames ({T / tracks.fps:.0f} s at "
          f"{tracks.fps:.0f} fps, 1080 x 1920), `pinrecon video` with its default options\n")
    print("| frames | seconds end to end | frames/s | parts (s) | largest resident set (MB) | PA-MPJPE pinrecon / "
          "MediaPipe (mm) |")
    print("|---:|---:|---:|---|---:|---|")
    print(f"| {T} | {float(line[2]):.1f} | {float(line[3]):.1f} | {line[4]} | {rss_mb:.0f} | "
          f"{pa_mpjpe(P[ok], GT[ok]):.1f} / {pa_mpjpe(W[ok], GT[ok]):.1f} |")
    print("\nthe reconstruct call's stages\n")
    print("| stage | seconds | what changed |")
    print("|---|---:|---|")
    for s in res.stages:
        print(f"| {s.name} | {s.seconds:.2f} | {s.changed} |")


if __name__ == "__main__":
    main()
