"""``pinrecon demo``: the main job on bundled data, end to end.

The bundled CMU walk (02_01) is seen through an orthographic camera 45 degrees from
side-on: its body joints become 2D tracks with 1 px noise and 3 % of the points missing,
and a few noisy 3D point keyframes (2 cm, every 0.25 s) stand in for an animator's key
poses. The motion is reconstructed with the figure built from the clip's own skeleton,
so the error against the clip is exact. Everything a user needs to repeat the run with
the CLI is written next to the outputs.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["run_demo", "DemoSummary", "PLOTTED_JOINTS"]

#: hip and knee flexion of both legs, and the elbows (DiFranco et al.'s figure 9 compares such curves)
PLOTTED_JOINTS = [
    "LeftUpLeg_Xrotation",
    "LeftLeg_Xrotation",
    "LeftForeArm_Yrotation",
    "RightUpLeg_Xrotation",
    "RightLeg_Xrotation",
    "RightForeArm_Yrotation",
]


@dataclass
class DemoSummary:
    frames: int
    fps: float
    iterations: int
    status: str
    solve_time_s: float
    total_time_s: float
    mpjpe_mm: float
    reprojection_px: float
    files: list
    note: str = ""

    def table(self) -> str:
        rows = [
            ("frames", f"{self.frames} at {self.fps:g} fps"),
            ("solver iterations", f"{self.iterations} ({self.status})"),
            ("solve time", f"{self.solve_time_s:.1f} s"),
            ("total time", f"{self.total_time_s:.1f} s (with pictures and exports)"),
            ("mean per-joint error vs the clip", f"{self.mpjpe_mm:.1f} mm"),
            ("mean reprojection error", f"{self.reprojection_px:.2f} px"),
        ]
        w = max(len(k) for k, _ in rows)
        return "\n".join(f"  {k:<{w}}  {v}" for k, v in rows)


def run_demo(out_dir="pinrecon-demo", *, frames: int | None = None, pictures: bool = True, callback=None, seed: int = 0):
    """Run the demo; returns a :class:`DemoSummary`. ``frames`` shortens the clip (tests)."""
    from . import reconstruct
    from .io.bvh import write_bvh
    from .io.csv_export import write_csv
    from .synthetic import body_keypoints, bundled_motion, point_keyframes, project_tracks, side_camera

    t0 = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figure, q_true, fps = bundled_motion("walk")
    if frames is not None:
        q_true = q_true[:frames]
    names = body_keypoints(figure)
    camera = side_camera(q_true, 45.0, scale=300.0, center=(640.0, 360.0))
    tracks = project_tracks(figure, q_true, camera, names, fps=fps, noise_px=1.0, missing=0.03, seed=seed)
    keys = point_keyframes(figure, q_true, range(0, len(q_true), int(round(0.25 * fps))), names, sigma_m=0.02, seed=seed + 1)
    # the inputs, so `pinrecon reconstruct` can repeat the run from files
    tracks.save(out / "tracks.json")
    camera.save(out / "camera.json")
    keys.save(out / "keyframes.json")

    res = reconstruct(figure, tracks, camera, keys, callback=callback)
    idx = figure.keypoint_index(names)
    err = np.linalg.norm(res.keypoints3d[:, idx] - figure.keypoints(q_true)[:, idx], axis=-1)
    files = [out / "tracks.json", out / "camera.json", out / "keyframes.json"]
    res.save(out / "result.npz")
    write_csv(out / "joint_angles.csv", res)
    write_bvh(out / "motion.bvh", figure, res.q, res.fps)
    files += [out / "result.npz", out / "joint_angles.csv", out / "motion.bvh"]
    note = ""
    if pictures:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            note = 'no pictures: matplotlib is not installed (pip install "pinrecon[viz]")'
        else:
            from .io.bvh import BvhMotion
            from .viz import plot_result

            truth = BvhMotion(figure, q_true, fps, None)
            files += plot_result(res, out, truth=truth, tracks=tracks, joints=PLOTTED_JOINTS)
    return DemoSummary(
        frames=len(q_true),
        fps=fps,
        iterations=res.solve.iterations,
        status=res.solve.status,
        solve_time_s=res.solve.time,
        total_time_s=time.perf_counter() - t0,
        mpjpe_mm=1000.0 * float(err.mean()),
        reprojection_px=float(np.nanmean(res.reprojection_error_px)),
        files=[Path(f) for f in files],
        note=note,
    )
