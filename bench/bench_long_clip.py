"""A 10-minute clip through the default monocular path: time and peak memory (issue 43: 18,000
frames at 30 fps in under 2 GB of peak RSS, at the rate of the short clips).

The clip: the bundled walk (02_01), run (09_01) and dances 05_02 and 05_11, each sub-sampled to
30 frames/s and made into bench_real's detector case (12 COCO-17 points, a perspective camera 45
degrees from side-on, 2 px noise, 2 % outliers, 1 % left/right swaps, 3 % missing; a new seed
each time round), one after the other until ``--frames`` frames. Where one clip ends and the
next begins the person jumps (another place, another pose): the clip tests the long path, not
a motion. ``pinrecon.reconstruct(Figure.human(), tracks, "auto", image_size=(1920, 1080))``
with its defaults (past 10,000 frames: windows of 2000 frames, ``pinrecon.windowed``, solved
in worker processes on every core), no lifted cues (``--cues``: a simulated lifter's, as
bench_stages' cue rows: the path of ``pinrecon video``). Printed: frames/s (wall clock, and CPU of
this process and its workers), the peak resident memory (``ru_maxrss``) of this process and of
its largest worker, and the PA-MPJPE (per frame) against the truth.

    OMP_NUM_THREADS=1 python bench/bench_long_clip.py               # 18,000 frames
    OMP_NUM_THREADS=1 python bench/bench_long_clip.py --frames 3000
    OMP_NUM_THREADS=1 python bench/bench_long_clip.py --frames 2400 --window 800   # four windows
    OMP_NUM_THREADS=1 python bench/bench_long_clip.py --cues        # with lifted cues
"""

from __future__ import annotations

import quick

QUICK = quick.take(["--frames", "120"], cut=False)

import argparse
import resource
import time
import warnings

import numpy as np
from bench_lifted import simulated_lifter
from bench_real import tracked_case

import pinrecon as pr
from pinrecon.layouts import COCO_17
from pinrecon.lifted import Lifted
from pinrecon.metrics import pa_mpjpe
from pinrecon.synthetic import bundled_motion
from pinrecon.windowed import usable_cpus

COCO12 = list(COCO_17[5:])
CLIPS = ("walk", "run", "dance", "spin")


def long_case(n_frames: int, fps: float = 30.0, cues: bool = False):
    """(tracks, true points (T, 12, 3)) of ``n_frames`` frames, the clips one after another;
    ``cues``: with bench_lifted's simulated lifter (camera axes, 3 cm noise, limbs mirrored on
    10 % of the frames), as bench_stages' cue rows."""
    motions = [bundled_motion(c) for c in CLIPS]
    points, conf, truth, lifted, seed = [], [], [], [], 0
    names = None
    while sum(len(p) for p in points) < n_frames:
        for fig, q, clip_fps in motions:
            step = max(1, round(clip_fps / fps))
            tracks, cam, _, P, _ = tracked_case(fig, q[::step], clip_fps / step, 45.0, "none", seed=seed)
            names = list(tracks.names)
            points.append(tracks.points)
            conf.append(tracks.confidence)
            truth.append(P)
            if cues:
                lifted.append(simulated_lifter(P, cam, names, seed=seed)[0])
            seed += 1
    T = n_frames
    cue = None
    if cues:
        cue = Lifted(np.concatenate([x.points for x in lifted])[:T], names,
                     np.concatenate([x.confidence for x in lifted])[:T], "camera", "simulated")
    tracks = pr.Tracks(np.concatenate(points)[:T], names, fps, np.concatenate(conf)[:T], lifted=cue)
    order = [names.index(n) for n in COCO12]
    return tracks, np.concatenate(truth)[:T][:, order]


class _Windows:
    """Prints each window as it is solved (a solve's callback; iteration reports are ignored)."""

    def __init__(self, t0: float):
        self.t0 = t0

    def __call__(self, report) -> bool:
        return False

    def window(self, report) -> None:
        print(f"  {report} (at {time.perf_counter() - self.t0:.0f} s)", flush=True)


def _cpu() -> float:
    """CPU seconds of this process and of its finished worker processes (the windows' workers)."""
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=18000)
    ap.add_argument("--window", type=int, default=None,
                    help="frames per window (default: reconstruct's, windows past 10,000 frames; 0: one batch)")
    ap.add_argument("--cues", action="store_true",
                    help="the tracks carry a simulated lifter's 3D (the path of `pinrecon video`)")
    a = ap.parse_args(argv)
    from provenance import provenance

    print(provenance())
    print(f"command: OMP_NUM_THREADS=1 python bench/bench_long_clip.py --frames {a.frames}"
          + (f" --window {a.window}" if a.window is not None else "") + (" --cues" if a.cues else ""))
    tracks, P = long_case(a.frames, cues=a.cues)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    kids0 = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024  # git's, for the provenance
    t0, c0 = time.perf_counter(), _cpu()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct(pr.Figure.human(), tracks, "auto", image_size=(1920, 1080), window=a.window,
                             callback=_Windows(t0),
                             progress=lambda name: print(f"  stage {name} at {time.perf_counter() - t0:.0f} s, peak RSS "
                                                         f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f}"
                                                         " MB", flush=True))
    wall, cpu = time.perf_counter() - t0, _cpu() - c0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    worker = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    worker = worker if worker > kids0 else 0.0  # no window worker larger than the provenance's git
    X = res.keypoints3d[:, res.figure.keypoint_index(COCO12)]
    cues = "a simulated lifter's 3D cues" if a.cues else "no lifted cues"
    print(f"\n{a.frames} frames at 30 fps ({a.frames / 1800:.1f} min), the default monocular path, {cues}\n")
    print("| frames | frames/s (wall / CPU) | peak RSS (MB) | largest worker's peak RSS (MB) | RSS before the call (MB) | "
          "PA-MPJPE (mm) | stages |")
    print("|---:|---:|---:|---:|---:|---:|---|")
    print(f"| {a.frames} | {a.frames / wall:.1f} / {a.frames / cpu:.1f} | {peak:.0f} | {worker:.0f} | {rss0:.0f} | "
          f"{pa_mpjpe(X, P):.1f} "
          f"| {', '.join(s.name for s in res.stages)} |")
    print("\nstages: " + "; ".join(f"{s.name} {s.seconds:.0f} s" for s in res.stages))
    n = usable_cpus() if worker else 0  # the windows' workers: one per core
    print(f"\ntargets (issue 43): peak RSS under 2 GB: {'met' if peak + n * worker < 2048 else 'NOT met'} (this "
          f"process and {n} workers at their peaks: {peak + n * worker:.0f} MB); "
          f"300 frames/s: {'met' if a.frames / wall >= 300 else 'NOT met'}")


if __name__ == "__main__":
    main()
