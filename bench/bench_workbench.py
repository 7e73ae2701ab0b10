"""Workbench re-solve times: one correction, then the warm-start re-solve.

The problem: the example-robot-data human figure (nv = 42, COCO-17 keypoints) walking
(`pinrecon.synthetic.human_walk`), 30 fps, orthographic camera 45 degrees from side-on,
1 px noise, 3D point keyframes (2 cm) every 2 s; solved once from scratch (what
`pinrecon reconstruct` does), then corrected in a `pinrecon.workbench.Session`:

* flip: the right shank's depth flipped at the middle frame (a partial point keyframe, the
  warm start flipped over the excursion);
* joint: the right elbow bent by 0.3 rad at the middle frame (a joint keyframe);

then `Session.solve()`: the window around the edit first (edges held on the current
motion), then the whole sequence from there (the same problem `pinrecon reconstruct`
solves). "whole only" re-solves the whole sequence directly from the edited warm start.
The page shows the window's result as soon as it is done.

Run: ``OPENBLAS_NUM_THREADS=1 python bench/bench_workbench.py`` (about a minute;
``--frames 300 1000``). Prints a markdown table.
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take(["--frames", "60"])

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pinrecon as pr
from pinrecon import synthetic as syn
from pinrecon.workbench import Session


def case(n_frames, floor=None):
    fig, Q = syn.human_walk(n_frames, 30.0)
    cam = syn.side_camera(Q, 45.0)
    tracks = syn.project_tracks(fig, Q, cam, fps=30.0, noise_px=1.0, seed=1)
    keys = syn.point_keyframes(fig, Q, sorted(set(range(0, n_frames, 60)) | {n_frames - 1}), sigma_m=0.02)
    t0 = time.perf_counter()
    start = pr.reconstruct(fig, tracks, cam, keys, floor=floor)
    return fig, cam, tracks, keys, start, time.perf_counter() - t0


def edit(session, kind, frame):
    if kind == "flip":
        session.flip(frame, "right_knee>right_ankle")
    else:
        session.set_joint(frame, "right_elbow_Z", session.joint_value(frame, "right_elbow_Z") + 0.3)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, nargs="+", default=[300, 1000])
    ap.add_argument("--floor", default=None, help="as for reconstruct: the default (None: the feet on the ground "
                    "for the human, in the first solve and the whole re-solves) or 'none'")
    args = ap.parse_args()
    rows = []
    for n in args.frames:
        fig, cam, tracks, keys, start, t_cold = case(n, args.floor)
        for kind in ("flip", "joint"):
            s = Session(fig, tracks, cam, keys, result=start, floor=args.floor)
            edit(s, kind, n // 2)
            rep = s.solve()
            s2 = Session(fig, tracks, cam, keys, result=start, floor=args.floor)
            edit(s2, kind, n // 2)
            rep2 = s2.solve(window=False)
            w = f"{rep.window[0]}-{rep.window[1]}" if rep.window else "-"
            rows.append((n, kind, w, rep.window_time, rep.window_iterations, rep.full_time, rep.full_iterations,
                         rep.time, rep2.full_time, rep2.full_iterations, t_cold))
            print(f"{n} frames, {kind}: {rep}", flush=True)
    print()
    print("| frames | edit | window | window solve (s) | it | then whole (s) | it | total (s) | whole only (s) | it |"
          " first solve from scratch (s) |")
    print("|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n, kind, w, tw, iw, tf, itf, tt, t2, it2, tc in rows:
        print(f"| {n} | {kind} | {w} | {tw:.2f} | {iw} | {tf:.2f} | {itf} | {tt:.2f} | {t2:.2f} | {it2} | {tc:.1f} |")


if __name__ == "__main__":
    main()
