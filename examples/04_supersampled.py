"""Super-sampled reconstruction: 30 fps tracks in, 120 fps motion out.

DiFranco, Cham & Rehg (2001) solve for the motion on a finer time grid than the video:
frames without an observation are held by the smoothing prior (constant velocity) and
the joint limits. Here the bundled CMU walk (120 fps) is observed at 30 fps (every 4th
frame, orthographic camera 50 degrees from side-on, 1 px noise, point keyframes every
0.25 s), reconstructed with ``reconstruct(..., fps_out=120)`` and scored against the clip
on every 120 fps frame: the observed ones and the three in between each pair.
Writes a joint-angle plot of the 120 fps result over the clip.

    PYTHONPATH=src python examples/04_supersampled.py [--out DIR] [--quick]

``--quick`` uses the first second of the walk.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import pinrecon as pr
from pinrecon.synthetic import body_keypoints, bundled_motion, point_keyframes, project_tracks

FACTOR = 4  # 120 fps out for 30 fps in



def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="examples_out/04", help="folder for the picture")
    ap.add_argument("--quick", action="store_true", help="first second of the walk only")
    args = ap.parse_args(argv)

    figure, q, fps = bundled_motion("walk")
    if args.quick:
        q = q[: round(fps) + 1]
    q = q[: (len(q) - 1) // FACTOR * FACTOR + 1]  # the 120 fps frames the 30 fps ones span
    names = body_keypoints(figure)
    az = np.radians(50.0)
    camera = pr.Orthographic.from_view([np.cos(az), 0, np.sin(az)], scale=300.0, center=(500.0, 500.0))
    q_video, fps_video = q[::FACTOR], fps / FACTOR
    tracks = project_tracks(figure, q_video, camera, names, fps=fps_video, noise_px=1.0, seed=5)
    key_frames = range(0, len(q_video), round(0.25 * fps_video))
    keys = point_keyframes(figure, q_video, key_frames, names, seed=6)

    t0 = time.perf_counter()
    result = pr.reconstruct(figure, tracks, camera, keys, fps_out=fps)
    elapsed = time.perf_counter() - t0

    idx = figure.keypoint_index(names)
    err_mm = 1000 * np.linalg.norm(result.keypoints3d[:, idx] - figure.keypoints(q)[:, idx], axis=-1)
    err_mm = err_mm.mean(axis=1)  # per frame
    seen = result.observed_frames
    print(f"tracks: {tracks.T} frames at {tracks.fps:.0f} fps -> "
          f"result: {len(result.q)} frames at {result.fps:.0f} fps")
    print(f"solver: {result.solve.status}, {result.solve.iterations} iterations, {elapsed:.1f} s")
    print(f"reprojection error: {np.nanmean(result.reprojection_error_px):.2f} px")
    print(f"mean per-joint error, all {len(err_mm)} frames: {err_mm.mean():.1f} mm")
    print(f"mean per-joint error, {seen.sum()} observed frames: {err_mm[seen].mean():.1f} mm")
    print(f"mean per-joint error, {(~seen).sum()} frames in between: {err_mm[~seen].mean():.1f} mm")

    try:
        from pinrecon.viz import plot_joint_angles

        legs = ["LeftUpLeg_Xrotation", "LeftLeg_Xrotation", "RightUpLeg_Xrotation", "RightLeg_Xrotation"]
        path = Path(args.out) / "joint_angles_120fps.png"
        truth = pr.Result.from_motion(figure, q, fps)
        plot_joint_angles(result, legs, truth=truth, out=path, labels=("120 fps result", "clip"))
        print(f"wrote {path}")
    except ImportError as exc:  # matplotlib is the optional "viz" extra
        print(f"no pictures: {exc}")


if __name__ == "__main__":
    main()
