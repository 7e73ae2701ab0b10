"""Accuracy of the engine on the bundled CMU walk, in the settings of tests/test_reconstruct.py.

The walk (02_01) is reconstructed with the figure built from its own skeleton; 22 body
joints are tracked in 2D with 1 px noise and keyed with 3D points (2 cm noise). Prints a
markdown table: mean per-joint position error (MPJPE), the share of limb segments whose
depth sign is flipped (pinrecon.planarity.limb_flip_rate), iterations and time.

    OPENBLAS_NUM_THREADS=1 python bench/bench_accuracy.py
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take([])

import time

import numpy as np

import pinrecon as pr
from pinrecon.planarity import limb_flip_rate
from pinrecon.synthetic import body_keypoints, bundled_motion, noisy_markers, point_keyframes, project_tracks, side_camera


def main():
    fig, q, fps = bundled_motion("walk")
    names = body_keypoints(fig)
    idx = fig.keypoint_index(names)
    truth = fig.keypoints(q)[:, idx]
    every = range(0, len(q), int(0.25 * fps))
    rows = []

    def run(label, tracks, cam, keys, q_true=q, **kw):
        t = time.perf_counter()
        res = pr.reconstruct(fig, tracks, cam, keys, **kw)
        dt = time.perf_counter() - t
        P = res.keypoints3d[:, idx]
        T = fig.keypoints(q_true)[:, idx]
        err = 1000 * np.linalg.norm(P - T, axis=-1).mean()
        flips = limb_flip_rate(fig, res.q, q_true, cam)
        rows.append((label, err, flips, res.solve.iterations, dt))

    cam = side_camera(q, 45.0)
    tr = project_tracks(fig, q, cam, names, fps=fps, noise_px=1.0, seed=1)
    run("orthographic, keyframes every 0.25 s", tr, cam, point_keyframes(fig, q, every, names, sigma_m=0.02, seed=2))
    cam35 = side_camera(q, 35.0)
    tr_gap = project_tracks(fig, q, cam35, names, fps=fps, noise_px=1.0, missing=0.2, gaps=[(150, 160)], seed=3)
    run("+ 20 % points missing and a 10-frame gap", tr_gap, cam35, point_keyframes(fig, q, every, names, sigma_m=0.02, seed=4))
    n = ((len(q) - 1) // 4) * 4 + 1
    cam50 = side_camera(q[:n], 50.0)
    tr30 = project_tracks(fig, q[:n:4], cam50, names, fps=fps / 4, noise_px=1.0, seed=5)
    keys30 = point_keyframes(fig, q[:n:4], range(0, len(q[:n:4]), int(0.25 * fps / 4)), names, sigma_m=0.02, seed=6)
    run("observed at 30 fps, reconstructed at 120 fps (all frames scored)", tr30, cam50, keys30, q_true=q[:n], fps_out=fps)
    centre = q[:, :3].mean(0)
    d = q[-1, :3] - q[0, :3]
    d[1] = 0
    d /= np.linalg.norm(d)
    side = np.cross([0.0, 1.0, 0.0], d)
    eye = centre + 5.0 * (np.cos(np.radians(40)) * side - np.sin(np.radians(40)) * d) + np.array([0, 0.5, 0])
    camp = pr.Perspective.look_at(eye, centre, f_px=1200.0, center=(960.0, 540.0))
    trp = project_tracks(fig, q, camp, names, fps=fps, noise_px=1.0, seed=7)
    run("perspective camera 5 m away", trp, camp, point_keyframes(fig, q, every, names, sigma_m=0.02, seed=8))
    for az in (30.0, 45.0, 60.0):
        c = side_camera(q, az)
        t_ = project_tracks(fig, q, c, names, fps=fps, noise_px=1.0, seed=int(az))
        run(f"keyframes on the first and last frame only ({az:.0f} deg)", t_, c,
            point_keyframes(fig, q, [0, len(q) - 1], names, sigma_m=0.02, seed=int(az) + 1))

    print("| walk, 343 frames at 120 fps | MPJPE (mm) | limbs with flipped depth sign | iterations | time (s) |")
    print("|---|---:|---:|---:|---:|")
    for label, err, flips, its, dt in rows:
        print(f"| {label} | {err:.1f} | {100 * flips:.1f} % | {its} | {dt:.1f} |")

    markers = noisy_markers(fig, q, names, fps=fps, noise_m=0.01, missing=0.1, gaps=[(200, 215)], seed=9)
    t = time.perf_counter()
    res = pr.reconstruct_markers(fig, markers)
    dt = time.perf_counter() - t
    raw = 1000 * np.nanmean(np.linalg.norm(markers.points - truth, axis=-1))
    fit = 1000 * np.linalg.norm(res.keypoints3d[:, idx] - truth, axis=-1)
    print(
        f"\n3D mode: markers with 1 cm noise, 10 % dropped and a 15-frame gap: raw markers {raw:.1f} mm, "
        f"fitted figure {fit.mean():.1f} mm ({fit[200:215].mean():.1f} mm inside the gap), "
        f"{res.solve.iterations} iterations, {dt:.1f} s."
    )


if __name__ == "__main__":
    main()
