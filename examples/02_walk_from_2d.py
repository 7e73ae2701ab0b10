"""A real walk reconstructed from 2D tracks (DiFranco, Cham & Rehg 2001, section 5).

The bundled CMU walk (02_01, 120 fps) gives both the figure (built from the clip's own
skeleton) and the ground truth. Its 22 body keypoints are projected through an
orthographic camera 45 degrees from side-on (300 px/m) with 1 px noise; 3D point
keyframes (2 cm noise) are given every 0.25 s. ``pinrecon.reconstruct`` solves the whole
sequence at once. Prints the mean per-joint error against the clip (also with the Hips
subtracted, which removes the depth an orthographic camera cannot see) and writes a
figure-9-style joint-angle plot and a stick-figure strip (camera view and a view from
90 degrees) to the output folder.

    PYTHONPATH=src python examples/02_walk_from_2d.py [--out DIR] [--quick]

``--quick`` reconstructs the first second of the walk instead of all 2.9 s.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import pinrecon as pr
from pinrecon.synthetic import body_keypoints, bundled_motion, point_keyframes, project_tracks



def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="examples_out/02", help="folder for the pictures")
    ap.add_argument("--quick", action="store_true", help="first second of the walk only")
    args = ap.parse_args(argv)

    figure, q, fps = bundled_motion("walk")
    if args.quick:
        q = q[: round(fps)]
    names = body_keypoints(figure)
    az = np.radians(45.0)  # side-on = looking along world x; the walk goes along +z
    camera = pr.Orthographic.from_view([np.cos(az), 0, np.sin(az)], scale=300.0, center=(500.0, 500.0))
    tracks = project_tracks(figure, q, camera, names, fps=fps, noise_px=1.0, seed=1)
    keys = point_keyframes(figure, q, range(0, len(q), round(0.25 * fps)), names, seed=2)  # 2 cm

    t0 = time.perf_counter()
    result = pr.reconstruct(figure, tracks, camera, keys)
    elapsed = time.perf_counter() - t0

    idx = figure.keypoint_index(names)
    P_est, P_true = result.keypoints3d[:, idx], figure.keypoints(q)[:, idx]
    err_mm = 1000 * np.linalg.norm(P_est - P_true, axis=-1)
    rel_mm = 1000 * np.linalg.norm((P_est - P_est[:, :1]) - (P_true - P_true[:, :1]), axis=-1)
    print(f"walk: {len(q)} frames at {fps:.0f} fps, {len(names)} keypoints, {len(keys)} keyframes")
    print(f"solver: {result.solve.status}, {result.solve.iterations} iterations, {elapsed:.1f} s")
    print(f"reprojection error: {np.nanmean(result.reprojection_error_px):.2f} px")
    print(f"mean per-joint error: {err_mm.mean():.1f} mm")
    print(f"mean per-joint error, Hips aligned: {rel_mm.mean():.1f} mm")
    print(f"worst frame: {err_mm.mean(1).max():.1f} mm")

    try:
        from pinrecon.viz import plot_joint_angles, plot_stick_strip

        truth, out = pr.Result.from_motion(figure, q, fps), Path(args.out)
        flexion = ("UpLeg_Xrotation", "Leg_Xrotation", "ForeArm_Yrotation")  # hips, knees, elbows
        joints = [side + j for j in flexion for side in ("Left", "Right")]
        plot_joint_angles(result, joints, truth=truth, out=out / "joint_angles.png", ncols=2)
        plot_stick_strip(result, truth=truth, out=out / "stick_strip.png")
        print(f"wrote {out / 'joint_angles.png'} and {out / 'stick_strip.png'}")
    except ImportError as exc:  # matplotlib is the optional "viz" extra
        print(f"no pictures: {exc}")


if __name__ == "__main__":
    main()
