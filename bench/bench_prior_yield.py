"""The pose prior yields to strong data (``pinrecon.prior_yield``, the stage ``yield``).

Rows, each scored against the true motion (keypoint MPJPE, mm, in the clip's world: these
cases have 3D keyframes or a lifted pose that fix the depth):

* ``walk, engine``: bench_engine's problem (``synthetic.human_walk``, one orthographic view
  45 degrees from side-on, 1 px, 3D point keyframes every 8 frames at 2 cm) with
  ``calibrate="none"``, solved from the keyframes' start: the problem as ``make_problem`` builds it
  (the prior held), against ``build_problem``'s (the prior adapted to the keyframes' start, as
  reconstruct's ``solve`` stage does) and the solve without a prior;
* ``walk, reconstruct``: the same inputs through ``reconstruct`` (its defaults: the limbs'
  lengths calibrated, the start the keyframes' poses, the prior adapted to them first);
* ``random motion``: test_prior_switch's clip no prior knows (40 frames, perspective,
  keyframes every 10 frames), through ``reconstruct``;
* ``no keyframes``: bench_real's detector cases (walk, run, dance; 12 COCO-17 points, 2 px,
  outliers, swaps, missing points, perspective 45 degrees, no keyframes), PA-MPJPE and
  flipped limb segments: the prior is what decides the depths there and must not yield.

Columns: the default prior with the stage ``yield`` switched off, with it on, and without a
pose prior; time of the run with the stage on.

    OPENBLAS_NUM_THREADS=1 python bench/bench_prior_yield.py
    python bench/bench_prior_yield.py --quick
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

quick.take(["--frames", "64", "--clips", "walk", "--detector-frames", "60"])

from bench_real import score, tracked_case  # noqa: E402
from provenance import provenance  # noqa: E402

import pinrecon as pr  # noqa: E402
from pinrecon.prior_yield import prior_conflict  # noqa: E402
from pinrecon.problem import make_problem  # noqa: E402
from pinrecon.reconstruct import build_problem  # noqa: E402
from pinrecon.solver import solve  # noqa: E402
from pinrecon.starts import initial_trajectory  # noqa: E402
from pinrecon.synthetic import (  # noqa: E402
    COCO_BODY_FROM_CMU,
    bundled_motion,
    human_walk,
    point_keyframes,
    project_tracks,
    side_camera,
    smooth_motion,
)
from pinrecon.tracks import keyframes_from_points  # noqa: E402

NO_PRIOR = pr.Weights(pose_prior=None)


def _mm(P, T):
    return 1000.0 * float(np.linalg.norm(P - T, axis=-1).mean())


def _quiet(fn, *a, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*a, **kw)


def walk(n):
    fig, q = human_walk(n, 30.0)
    cam = side_camera(q, 45.0, scale=300.0, center=(640, 360))
    tracks = project_tracks(fig, q, cam, fps=30.0, noise_px=1.0, seed=1)
    keys = point_keyframes(fig, q, range(0, n, 8), sigma_m=0.02, seed=2)
    return fig, q, cam, tracks, keys


def engine_row(n):
    fig, q, cam, tracks, keys = walk(n)
    truth = fig.keypoints(q)
    held = make_problem(fig, tracks, cam, keys, calibrate="none")
    res = solve(held, initial_trajectory(held, "auto"), active=held.active)
    t0 = time.perf_counter()
    s = build_problem(fig, tracks, cam, keys, calibrate="none")
    out = solve(s.problem, s.q0, active=s.active)
    dt = time.perf_counter() - t0
    conflict = prior_conflict(held, s.q0)
    f = build_problem(fig, tracks, cam, keys, calibrate="none", weights=NO_PRIOR)
    free = solve(f.problem, f.q0, active=f.active)
    return (f"walk, engine ({n} frames)", _mm(fig.keypoints(res.x), truth), _mm(fig.keypoints(out.x), truth),
            _mm(fig.keypoints(free.x), truth), dt, ", ".join(conflict.conflicting))


def reconstruct_row(label, fig, tracks, cam, keys, truth, names=None, **kw):
    def err(r):
        P = r.keypoints3d if names is None else r.keypoints3d[:, r.figure.keypoint_index(names)]
        return _mm(P, truth)

    off = _quiet(pr.reconstruct, fig, tracks, cam, keys, skip=("yield", "feet"), **kw)
    t0 = time.perf_counter()
    on = _quiet(pr.reconstruct, fig, tracks, cam, keys, skip=("feet",), **kw)
    dt = time.perf_counter() - t0
    free = _quiet(pr.reconstruct, fig, tracks, cam, keys, skip=("feet",), weights=NO_PRIOR, **kw)
    joints = ", ".join(str(j) for j in on.extras.get("prior_conflict_joints", ()))
    return label, err(off), err(on), err(free), dt, joints


def random_motion():
    names = list(COCO_BODY_FROM_CMU)
    fig = pr.Figure.human()
    Q = smooth_motion(fig, 40, 30.0, seed=3, amplitude=0.3)
    cam = pr.Perspective.look_at([2.0, 0.9, 4.5], [0.5, 0.0, 0.0], f_px=1000.0, center=(960.0, 540.0))
    P = fig.keypoints(Q)[:, fig.keypoint_index(names)]
    uv = cam.project(P) + np.random.default_rng(0).normal(0.0, 1.0, P.shape[:2] + (2,))
    keys = keyframes_from_points(range(0, 40, 10), P, names, 0.02)
    tracks = pr.Tracks(uv, names, 30.0, np.full(uv.shape[:2], 0.9))
    return reconstruct_row("random motion (40 frames, keyframes every 10)", fig, tracks, cam, keys, P, names,
                           calibrate="none", floor="none")


def detector_rows(clips, frames):
    out = []
    for clip in clips:
        fig, q, fps = bundled_motion(clip)
        q = q[:frames] if frames else q
        tracks, cam, _, P, _ = tracked_case(fig, q, fps, 45, "none", seed=45)
        row = []
        for kw in ({"skip": ("yield",)}, {}, {"weights": NO_PRIOR}):
            t0 = time.perf_counter()
            res = _quiet(pr.reconstruct, pr.Figure.human(), tracks, cam, **kw)
            dt = time.perf_counter() - t0
            s = score(res.keypoints3d[:, res.figure.keypoint_index(tracks.names)], P, cam, list(tracks.names))
            row.append((s["pa"], s["flips"], dt, res))
        yielded = next(s.changed for s in row[1][3].stages if s.name == "yield")
        out.append((clip, row, yielded))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=300, help="frames of the synthetic walk")
    ap.add_argument("--clips", nargs="*", default=["walk", "run", "dance"], help="bench_real's detector clips")
    ap.add_argument("--detector-frames", type=int, default=150)
    a = ap.parse_args(argv)
    print(provenance())
    print(f"command: python bench/bench_prior_yield.py {' '.join(sys.argv[1:])}\n")
    print("| case | default prior, yield off (mm) | yield on (mm) | no pose prior (mm) | time, yield on (s) | "
          "joints the data disagreed with |")
    print("|---|---:|---:|---:|---:|---|")
    rows = [engine_row(a.frames)]
    fig, q, cam, tracks, keys = walk(a.frames)
    rows.append(reconstruct_row(f"walk, reconstruct ({a.frames} frames)", fig, tracks, cam, keys, fig.keypoints(q)))
    rows.append(random_motion())
    for label, off, on, free, dt, joints in rows:
        print(f"| {label} | {off:.1f} | **{on:.1f}** | {free:.1f} | {dt:.1f} | {joints} |", flush=True)
    if a.clips:
        print("\nNo keyframes (bench_real's detector case, 45 degrees, "
              f"{a.detector_frames} frames): PA-MPJPE (mm) / flipped limb segments (%)\n")
        print("| clip | yield off | yield on | no pose prior | time, yield on (s) | the stage said |")
        print("|---|---:|---:|---:|---:|---|")
        for clip, row, said in detector_rows(a.clips, a.detector_frames):
            cells = " | ".join(f"{pa:.1f} / {fl:.1f}" for pa, fl, _, _ in row)
            print(f"| {clip} | {cells} | {row[1][2]:.1f} | {said} |", flush=True)


if __name__ == "__main__":
    main()
