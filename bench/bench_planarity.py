"""Does the planarity seed help when keyframes are scarce?

For the bundled walk and run clips: 2D tracks of the 22 body keypoints through an
orthographic camera (side-on = looking along world X; the clips go along +Z, Y up)
``--azimuth`` degrees from side-on, 300 px/m, 1 px noise; 3D point keyframes on the
first and last frame only (2 cm). The batch solve (``pinrecon.reconstruct``, default
weights and solver options) starts once from the engine's default start (keyframe poses
interpolated, placed on the tracks) and once from ``seed="planarity"``.

Columns: mean per-joint error against the clip (absolute, and root-aligned: the Hips
keypoint subtracted, which removes the depth an orthographic view cannot see), share of
limb segments (thigh, shank, upper arm, forearm) with a flipped depth sign
(:func:`pinrecon.planarity.limb_flip_rate`), solver iterations and wall time (for the
seed: seeding fit + batch solve).

    python bench/bench_planarity.py [--clips walk run] [--azimuth 30 45 60] [--threads 1]

Prints a markdown table (about 5 minutes on one core). "(seed alone)" rows score the
seed trajectory itself, before the batch solve.
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take(["--clips", "walk", "--azimuth", "45"])

import argparse
import os
import sys
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", nargs="+", default=["walk", "run"])
    ap.add_argument("--azimuth", nargs="+", type=float, default=[30.0, 45.0, 60.0], help="degrees from side-on")
    ap.add_argument("--scale", type=float, default=300.0, help="pixels per metre")
    ap.add_argument("--noise", type=float, default=1.0, help="pixel noise")
    ap.add_argument("--seed", type=int, default=0, help="noise seed")
    ap.add_argument(
        "--threads",
        type=int,
        default=1,
        help="BLAS threads (default 1: the banded solves are small, and oversubscribed "
        "BLAS threads on a busy machine made one solve 60x slower)",
    )
    args = ap.parse_args(argv)
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(args.threads)

    import numpy as np

    import pinrecon as pr
    from pinrecon.planarity import limb_flip_rate, seed_trajectory
    from pinrecon.synthetic import body_keypoints, bundled_motion, point_keyframes, project_tracks

    limbs = [
        (s + a, s + b)
        for s in ("Left", "Right")
        for a, b in (("UpLeg", "Leg"), ("Leg", "Foot"), ("Arm", "ForeArm"), ("ForeArm", "Hand"))
    ]
    rows = []
    for clip in args.clips:
        fig, q, fps = bundled_motion(clip)
        names = body_keypoints(fig)
        idx = fig.keypoint_index(names)
        P = fig.keypoints(q)[:, idx]
        T = len(q)
        for az_deg in args.azimuth:
            az = np.radians(az_deg)
            cam = pr.Orthographic.from_view([np.cos(az), 0.0, np.sin(az)], scale=args.scale, center=(500.0, 500.0))
            tracks = project_tracks(fig, q, cam, names, fps=fps, noise_px=args.noise, seed=args.seed)
            kf = point_keyframes(fig, q, [0, T - 1], names, sigma_m=0.02, seed=args.seed)

            def score(Q):
                Pe = fig.keypoints(Q)[:, idx]
                err = 1000 * np.linalg.norm(Pe - P, axis=-1).mean()
                rel = 1000 * np.linalg.norm((Pe - Pe[:, :1]) - (P - P[:, :1]), axis=-1).mean()
                return err, rel, limb_flip_rate(fig, Q, q, cam, limbs)

            t0 = time.perf_counter()
            res = pr.reconstruct(fig, tracks, cam, kf)
            t_def = time.perf_counter() - t0
            rows.append((clip, az_deg, "default", *score(res.q), f"{res.solve.iterations}", t_def, res.solve.status))
            # the seed, timed apart from the batch solve (same as reconstruct(..., seed="planarity"))
            t0 = time.perf_counter()
            sd = seed_trajectory(fig, tracks, cam, kf)
            t_seed = time.perf_counter() - t0
            t0 = time.perf_counter()
            res = pr.reconstruct(fig, tracks, cam, kf, init=sd.q)
            t_solve = time.perf_counter() - t0
            it_seed = sd.solve.iterations if sd.solve is not None else 0
            rows.append(
                (clip, az_deg, "planarity seed", *score(res.q), f"{it_seed} + {res.solve.iterations}",
                 t_seed + t_solve, res.solve.status)
            )
            rows.append((clip, az_deg, "(seed alone)", *score(sd.q), f"{it_seed}", t_seed, ""))
            print(f"done {clip} {az_deg:g} deg", file=sys.stderr, flush=True)

    print(
        "| clip | view | start | MPJPE (mm) | root-aligned MPJPE (mm) | limb flip rate | iterations "
        "| time (s) | solver status |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for clip, az, start, err, rel, flip, its, t, status in rows:
        print(f"| {clip} | {az:g} deg | {start} | {err:.1f} | {rel:.1f} | {flip:.3f} | {its} | {t:.1f} | {status} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
