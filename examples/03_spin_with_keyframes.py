"""A double pirouette reconstructed from 2D tracks and a few keyframes.

As in the skating sequence of DiFranco, Cham & Rehg (2001, section 5: 8 keyframes, some
of them approximate). The bundled CMU 05_11 dance clip turns about 720 degrees in 2 s
(frames 140-380 at 120 fps, up to ~600 degrees per second). Its 22 body keypoints are
seen by an orthographic camera (300 px/m, 1 px noise). Nine 3D point keyframes, 0.25 s
apart: the first, middle and last accurate (2 cm), the six others approximate (5 cm).
Prints the largest turn between keyframes, the total turn of the clip and of the
reconstruction, the error against the clip, and writes two stick-figure strips (camera
view and a view from 90 degrees, truth in grey).

Keyframes must stay well under half a turn apart: the start is interpolated between
keyframe poses the short way round, and the orthographic tracks hardly tell which way
the figure turns (its image is nearly that of its mirror image in depth turning the
other way). Try ``--keyframes 8`` (up to ~175 degrees between keyframes): the
reconstruction turns back instead of on between two of them and loses a whole turn.

    PYTHONPATH=src python examples/03_spin_with_keyframes.py [--out DIR] [--quick] [--keyframes N]

``--quick`` uses 30 fps tracks (every 4th frame) instead of 120 fps.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import pinrecon as pr
from pinrecon.synthetic import body_keypoints, bundled_motion, point_keyframes, project_tracks
from pinrecon.tracks import Keyframes



def heading_deg(q):
    """The root's heading about the vertical (world y), unwrapped over the frames."""
    forward = Rotation.from_quat(q[:, 3:7]).apply([0.0, 0.0, 1.0])  # quaternion (x, y, z, w)
    return np.degrees(np.unwrap(np.arctan2(forward[:, 0], forward[:, 2])))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="examples_out/03", help="folder for the pictures")
    ap.add_argument("--quick", action="store_true", help="30 fps tracks instead of 120 fps")
    ap.add_argument("--keyframes", type=int, default=9, help="number of evenly spaced keyframes")
    args = ap.parse_args(argv)

    figure, q, fps = bundled_motion("spin")
    step = 4 if args.quick else 1
    q, fps = q[140:381:step], fps / step  # the double pirouette
    T, names = len(q), body_keypoints(figure)
    camera = pr.Orthographic.from_view([1.0, 0.0, 1.0], scale=300.0, center=(500.0, 500.0))
    tracks = project_tracks(figure, q, camera, names, fps=fps, noise_px=1.0, seed=1)

    frames = np.linspace(0, T - 1, args.keyframes).round().astype(int)
    sure = frames[[0, len(frames) // 2, -1]]  # first, middle, last: accurate
    rough = np.setdiff1d(frames, sure)  # the others: approximate
    keys = Keyframes(
        list(point_keyframes(figure, q, sure, names, sigma_m=0.02, seed=2))
        + list(point_keyframes(figure, q, rough, names, sigma_m=0.05, seed=3))
    )

    t0 = time.perf_counter()
    result = pr.reconstruct(figure, tracks, camera, keys)
    elapsed = time.perf_counter() - t0

    idx = figure.keypoint_index(names)
    P_est, P_true = result.keypoints3d[:, idx], figure.keypoints(q)[:, idx]
    err_mm = 1000 * np.linalg.norm(P_est - P_true, axis=-1)
    rel_mm = 1000 * np.linalg.norm((P_est - P_est[:, :1]) - (P_true - P_true[:, :1]), axis=-1)
    print(f"spin: {T} frames at {fps:.0f} fps, {len(names)} keypoints")
    print(f"keyframes at frames {frames.tolist()}: accurate {sure.tolist()}, approximate {rough.tolist()}")
    turn_deg = np.abs(np.diff(heading_deg(q[frames]))).max()
    print(f"largest turn between keyframes: {turn_deg:.0f} deg")
    print(f"solver: {result.solve.status}, {result.solve.iterations} iterations, {elapsed:.1f} s")
    turns = [heading_deg(x)[-1] - heading_deg(x)[0] for x in (q, result.q)]
    print(f"total turn: clip {abs(turns[0]):.0f} deg, reconstruction {abs(turns[1]):.0f} deg")
    print(f"reprojection error: {np.nanmean(result.reprojection_error_px):.2f} px")
    print(f"mean per-joint error: {err_mm.mean():.1f} mm")
    print(f"mean per-joint error, Hips aligned: {rel_mm.mean():.1f} mm")
    print(f"worst frame: {err_mm.mean(1).max():.1f} mm")

    try:
        from pinrecon.viz import plot_stick_strip

        truth, out = pr.Result.from_motion(figure, q, fps), Path(args.out)
        shown = np.linspace(0, T - 1, 12).round().astype(int)
        for k, strip in enumerate((shown[:6], shown[6:]), 1):
            plot_stick_strip(result, strip, truth=truth, out=out / f"stick_strip_{k}.png")
        print(f"wrote {out / 'stick_strip_1.png'} and {out / 'stick_strip_2.png'}")
    except ImportError as exc:  # matplotlib is the optional "viz" extra
        print(f"no pictures: {exc}")


if __name__ == "__main__":
    main()
