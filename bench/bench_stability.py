"""What ``--stability N`` is worth: does it point at the frames that are wrong?

bench_real's detector cases (12 COCO-17 points with the issue's faults, perspective camera
45 or 60 degrees from side-on, ``Figure.human()`` calibrated, first and last keyframes or
none) are reconstructed, then checked with :func:`pinrecon.stability.stability` (``--runs``
copies with 1 % of the detections left out). Against the clip's own joints:

* the copies' mean distance from the result (mm, per-frame similarity alignment);
* the share of frames the check calls unstable (a copy over 30 mm);
* the per-frame PA-MPJPE inside and outside those frames (a useful check has the error
  inside);
* the share of the flipped limb segment-frames that fall in unstable frames, beside the
  share the result's own warnings already cover (bench_real's "flipped segments flagged":
  uncertain reflection spans, ties of the mirror stage, poses unlike the prior's clips).

    OPENBLAS_NUM_THREADS=1 python bench/bench_stability.py                 # walk, run, dance (about 25 min)
    python bench/bench_stability.py --cases walk:none:45 run:none:60 --runs 3 --jobs 2

``--timing``: what ``n_jobs`` (CLI ``--jobs``) saves. The check of each case timed one copy
after another and with ``--jobs`` processes, in turn (A B A B ..., ``--repeats`` pairs), the
medians and the median of the pairs' ratios; the two give the same spreads (to 1e-6 mm, checked
here on every pair).
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take(["--cases", "walk:none:45", "--runs", "1"])

import argparse
import os
import time
import warnings

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from bench_real import SEGMENTS, detector_case, flag_mask

import pinrecon as pr
from pinrecon import metrics
from pinrecon.result import unstable_spans
from pinrecon.stability import stability

CASES = ["walk:none:45", "walk:first+last:60", "run:none:60", "run:first+last:45", "spin:none:45",
         "spin:first+last:60"]


def solved_case(clip: str, keyframes: str, angle: float):
    """bench_real's detector case and its solve: ``(tracks, camera, keyframes, true points,
    figure, result, solve seconds)``."""
    tracks, cam, keys, P, _ = detector_case(clip, angle, keyframes, None, seed=int(angle))
    fig = pr.Figure.human()
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct(fig, tracks, cam, keys, calibrate="lengths")
    return tracks, cam, keys, P, fig, res, time.perf_counter() - t0


def run(clip: str, keyframes: str, angle: float, runs: int, jobs: int | None = None) -> dict:
    tracks, cam, keys, P, fig, res, t_solve = solved_case(clip, keyframes, angle)
    names = list(tracks.names)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check = stability(fig, tracks, cam, keys, result=res, runs=runs, calibrate="lengths", n_jobs=jobs)
    t_check = time.perf_counter() - t0
    P_est = res.keypoints3d[:, res.figure.keypoint_index(names)]
    flip, count = metrics.flipped_segments(P_est, P, cam, [(names.index(a), names.index(b)) for a, b in SEGMENTS])
    unstable = np.zeros(len(P), bool)
    for a, b, *_ in unstable_spans(check.to_extras()):
        unstable[a:b] = True
    err = 1000.0 * np.linalg.norm(metrics.procrustes(P_est, P) - P, axis=-1).mean(axis=1)
    flags = flag_mask(res.extras, len(P))
    n_flip = max(int(flip.sum()), 1)
    return {"pa": metrics.pa_mpjpe(P_est, P), "flips": 100.0 * flip.sum() / max(int(count.sum()), 1),
            "spreads": check.spread_mm.mean(axis=1), "unstable": 100.0 * unstable.mean(),
            "err_in": float(err[unstable].mean()) if unstable.any() else float("nan"),
            "err_out": float(err[~unstable].mean()) if (~unstable).any() else float("nan"),
            "flips_in": 100.0 * int((flip & unstable[:, None]).sum()) / n_flip,
            "flags": 100.0 * int((flip & flags).sum()) / n_flip,
            "both": 100.0 * int((flip & (unstable[:, None] | flags)).sum()) / n_flip,
            "t_solve": t_solve, "t_check": t_check}


def timing(clip: str, keyframes: str, angle: float, runs: int, jobs: int, repeats: int) -> dict:
    """The check's wall time one copy after another and in ``jobs`` processes, in turn."""
    tracks, cam, keys, _, fig, res, _ = solved_case(clip, keyframes, angle)
    times = {1: [], jobs: []}
    for _ in range(repeats):
        got = {}
        for n in (1, jobs):
            t0 = time.perf_counter()
            got[n] = stability(fig, tracks, cam, keys, result=res, runs=runs, calibrate="lengths", n_jobs=n)
            times[n].append(time.perf_counter() - t0)
        gap = float(np.abs(got[1].spread_mm - got[jobs].spread_mm).max())
        if gap > 1e-6:
            raise SystemExit(f"n_jobs={jobs} gave other spreads than one after another ({gap:.3g} mm)")
    ratio = np.array(times[1]) / np.array(times[jobs])
    return {"serial": float(np.median(times[1])), "parallel": float(np.median(times[jobs])),
            "ratio": float(np.median(ratio)), "lo": float(ratio.min()), "hi": float(ratio.max())}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", nargs="*", default=CASES, help="clip:keyframes:angle (clips walk, run, spin)")
    ap.add_argument("--runs", type=int, default=3, help="copies per check (default 3)")
    ap.add_argument("--jobs", type=int, default=None, help="processes per check (n_jobs; default one after another)")
    ap.add_argument("--timing", action="store_true", help="time the check with 1 and --jobs processes instead")
    ap.add_argument("--repeats", type=int, default=3, help="with --timing: pairs of runs per case (default 3)")
    a = ap.parse_args(argv)
    from provenance import provenance

    print(provenance())
    if a.timing:
        jobs = a.jobs or os.cpu_count() or 1
        print(f"\n--stability {a.runs}: the check's wall time one copy after another and in {jobs} processes "
              f"({os.cpu_count()} CPUs; {a.repeats} pairs, medians)\n")
        print(f"| clip | keyframes | angle | one after another (s) | n_jobs={jobs} (s) | ratio (min-max) |")
        print("|---|---|---:|---:|---:|---|", flush=True)
        for case in a.cases:
            clip, kf, angle = case.split(":")
            r = timing(clip, kf, float(angle), a.runs, jobs, a.repeats)
            print(f"| {clip} | {kf} | {float(angle):.0f} | {r['serial']:.1f} | {r['parallel']:.1f} "
                  f"| {r['ratio']:.2f} ({r['lo']:.2f}-{r['hi']:.2f}) |", flush=True)
        return
    print(f"\n--stability {a.runs} on bench_real's detector cases (1 % of the detections left out per copy)\n")
    print("| clip | keyframes | angle | PA-MPJPE (mm) | flips (%) | copies from the result (mm) | unstable frames (%) "
          "| PA-MPJPE in / out of them (mm) | flipped segments in them (%) | flagged by the result (%) "
          "| by either (%) | solve / check (s) |")
    print("|---|---|---:|---:|---:|---|---:|---|---:|---:|---:|---|", flush=True)
    for case in a.cases:
        clip, kf, angle = case.split(":")
        r = run(clip, kf, float(angle), a.runs, a.jobs)
        spreads = ", ".join(f"{v:.1f}" for v in r["spreads"])
        print(f"| {clip} | {kf} | {float(angle):.0f} | {r['pa']:.1f} | {r['flips']:.1f} | {spreads} | {r['unstable']:.0f} "
              f"| {r['err_in']:.1f} / {r['err_out']:.1f} | {r['flips_in']:.0f} | {r['flags']:.0f} | {r['both']:.0f} "
              f"| {r['t_solve']:.0f} / {r['t_check']:.0f} |", flush=True)


if __name__ == "__main__":
    main()
