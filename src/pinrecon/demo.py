"""``pinrecon demo``: the main job on bundled data, end to end, twice.

**Your video** (``OUT/your_video/``): the bundled CMU walk (02_01) as a user would have
it: its first 1.5 s filmed through a perspective camera 45 degrees from side-on,
run through a 2D detector (the 12 COCO-17 body points with 2 px noise, 2 % of the
points thrown 20-80 px away at low confidence, 1 % of the frames with left and right
swapped, 3 % missing: :func:`pinrecon.synthetic.detector_faults`), reconstructed with the
generic ``Figure.human()`` and no keyframe at all: the default path (the multi-hypothesis
start, the robust loss, swap repair; the limb lengths measured from the tracks start the
calibration, since one view alone cannot tell a limb's length from its depth).

**The lab setting** (``OUT/``): the same walk through an orthographic camera, its body
joints with 1 px noise and 3 % missing, a few noisy 3D point keyframes (2 cm, every
0.25 s) standing in for an animator's key poses, reconstructed with the figure built
from the clip's own skeleton. Its result, pictures and exports are written, with
everything a user needs to repeat the run with the CLI.

Both are scored against the clip (MPJPE, PA-MPJPE, flipped limb segments:
:mod:`pinrecon.metrics`) and printed side by side.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["PLOTTED_JOINTS", "DemoSummary", "run_demo"]

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
    lab_scores: dict = field(default_factory=dict)
    video: dict = field(default_factory=dict)

    def table(self) -> str:
        v, lab = self.video, self.lab_scores
        head = ("", "your video", "lab setting")
        rows = [
            ("input", "COCO-17 detector output", "clip joints, 1 px"),
            ("figure", "Figure.human()" + (" calibrated" if v.get("calibrated") else ""), "the clip's own skeleton"),
            ("camera", "perspective, 45 deg", "orthographic, 45 deg"),
            ("keyframes", "none", "every 0.25 s"),
            ("frames", f"{v.get('frames', 0)} at {v.get('fps', 0):g} fps", f"{self.frames} at {self.fps:g} fps"),
            ("solve time", f"{v.get('time_s', float('nan')):.1f} s", f"{self.solve_time_s:.1f} s"),
            ("MPJPE vs the clip", f"{v.get('mpjpe', float('nan')):.1f} mm", f"{self.mpjpe_mm:.1f} mm"),
            ("PA-MPJPE", f"{v.get('pa', float('nan')):.1f} mm", f"{lab.get('pa', float('nan')):.1f} mm"),
            ("MPJPE, depth offset removed", f"{v.get('dz', float('nan')):.1f} mm", f"{lab.get('dz', float('nan')):.1f} mm"),
            ("limb segments flipped", f"{v.get('flips', float('nan')):.1f} %", f"{lab.get('flips', float('nan')):.1f} %"),
            ("left/right swaps repaired", f"{v.get('repaired', 0)} of {v.get('swapped', 0)} injected", "-"),
            ("outliers reported", f"{v.get('outliers', 0)} ({v.get('injected', 0)} injected)", "-"),
            ("uncertain limb spans", f"{v.get('uncertain', 0)} of {v.get('spans', 0)}", "-"),
            ("poses unlike the pose prior", f"{v.get('unfamiliar', 0)} of {v.get('frames', 0)} frames", "-"),
            ("lengths the data fix", f"{v.get('fixed', 0)} of {v.get('groups', 0)}, size "
             + ("fixed" if v.get("size_fixed") else "not fixed"), "- (the clip's own)"),
            ("mean reprojection error", f"{v.get('reprojection_px', float('nan')):.2f} px", f"{self.reprojection_px:.2f} px"),
        ]
        w = max(len(r[0]) for r in rows)
        w1 = max(len(r[1]) for r in rows + [head])
        lines = [f"  {head[0]:<{w}}  {head[1]:<{w1}}  {head[2]}"]
        lines += [f"  {k:<{w}}  {a:<{w1}}  {b}" for k, a, b in rows]
        lines.append(f"  total time {self.total_time_s:.1f} s (with pictures and exports)")
        return "\n".join(lines)


def run_video(out_dir, *, frames: int | None = None, seed: int = 0, callback=None) -> dict:
    """The user's path (module docstring): writes ``out_dir/{tracks.json, camera.json,
    result.npz}`` and returns its scores against the clip."""
    from . import metrics
    from .figure import Figure
    from .reconstruct import reconstruct
    from .result import hypothesis_spans, unfamiliar_frames
    from .synthetic import (
        bundled_motion,
        coco_body_tracks,
        detector_faults,
        perspective_side_camera,
    )

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    clip, q, fps = bundled_motion("walk")
    q = q[: min(frames or 180, 180)]  # the first 1.5 s (at 120 fps: 30 fps loses more than it saves here)
    camera = perspective_side_camera(q, 45.0)
    clean, P = coco_body_tracks(clip, q, camera, fps=fps)
    tracks, log = detector_faults(clean, seed=seed)
    tracks.save(out / "tracks.json")
    camera.save(out / "camera.json")
    human = Figure.human()
    t0 = time.perf_counter()
    res = reconstruct(human, tracks, camera, callback=callback)
    dt = time.perf_counter() - t0
    res.save(out / "result.npz")
    names = tracks.names
    Pe = res.keypoints3d[:, res.figure.keypoint_index(names)]
    segs = [(names.index(a), names.index(b)) for a, b in _SEGMENTS]
    x = res.extras
    _, spans, thr = hypothesis_spans(x)
    d, lim, _ = unfamiliar_frames(x)
    return {
        "frames": len(q), "fps": fps, "time_s": dt,
        "calibrated": bool(res.calibration) and res.calibration.get("mode", "none") != "none",
        "mpjpe": metrics.mpjpe(Pe, P), "pa": metrics.pa_mpjpe(Pe, P), "dz": metrics.mpjpe_depth_aligned(Pe, P, camera),
        "flips": 100.0 * metrics.flip_rate(Pe, P, camera, segs),
        "repaired": len(set(np.asarray(x.get("repaired_frames", [])).tolist())
                        & set(np.asarray(log["swapped_frames"]).tolist())),
        "swapped": len(log["swapped_frames"]), "outliers": len(x.get("outlier_frames", [])),
        "injected": len(log["outliers"]), "spans": len(spans), "uncertain": int(np.sum(spans[:, 4] < thr)),
        "unfamiliar": int(np.sum(d > lim)),
        **_lengths_fixed(res.calibration),
        "reprojection_px": float(np.nanmean(res.reprojection_error_px)),
        "files": [out / "tracks.json", out / "camera.json", out / "result.npz"],
    }


def _lengths_fixed(calibration: dict) -> dict:
    """How many fitted length groups, and whether the size, the data fix
    (:func:`pinrecon.identifiability.proportions_identifiability`)."""
    ident = (calibration or {}).get("identifiability") or {}
    groups = list(ident.get("ratios", {}))
    return {"groups": len(groups), "fixed": len(groups) - len(ident.get("undetermined", [])),
            "size_fixed": bool(ident.get("size_determined", False))}


#: COCO-17 limb segments scored for flips (upper arms, forearms, thighs, shanks)
_SEGMENTS = [("left_shoulder", "left_elbow"), ("left_elbow", "left_wrist"), ("right_shoulder", "right_elbow"),
             ("right_elbow", "right_wrist"), ("left_hip", "left_knee"), ("left_knee", "left_ankle"),
             ("right_hip", "right_knee"), ("right_knee", "right_ankle")]


def run_demo(out_dir="pinrecon-demo", *, frames: int | None = None, pictures: bool = True, callback=None, seed: int = 0,
             video: bool = True):
    """Run the demo; returns a :class:`DemoSummary`. ``frames`` shortens the clip (tests);
    ``video=False`` skips the user's path (:func:`run_video`)."""
    from . import reconstruct
    from .io.bvh import write_bvh
    from .io.csv_export import write_csv
    from .synthetic import (
        body_keypoints,
        bundled_motion,
        point_keyframes,
        project_tracks,
        side_camera,
    )

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
    from . import metrics
    from .synthetic import COCO_BODY_FROM_CMU

    P_lab, T_lab = res.keypoints3d[:, idx], figure.keypoints(q_true)[:, idx]
    cmu = {v: k for k, v in COCO_BODY_FROM_CMU.items()}
    coco_names = [cmu.get(n, n) for n in names]
    segs = [(coco_names.index(a), coco_names.index(b)) for a, b in _SEGMENTS]
    lab_scores = {"pa": metrics.pa_mpjpe(P_lab, T_lab), "dz": metrics.mpjpe_depth_aligned(P_lab, T_lab, camera),
                  "flips": 100.0 * metrics.flip_rate(P_lab, T_lab, camera, segs)}
    vid = run_video(out / "your_video", frames=frames, seed=seed) if video else {}
    files = [out / "tracks.json", out / "camera.json", out / "keyframes.json"]
    res.save(out / "result.npz")
    write_csv(out / "joint_angles.csv", res)
    write_bvh(out / "motion.bvh", figure, res.q, res.fps, unit="m")  # metres, as every export
    files += [out / "result.npz", out / "joint_angles.csv", out / "motion.bvh"]
    note = ""
    if pictures:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            note = 'no pictures: matplotlib is not installed (from a pinrecon checkout: pip install ".[viz]")'
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
        files=[Path(f) for f in files] + list(vid.pop("files", [])),
        note=note,
        lab_scores=lab_scores,
        video=vid,
    )
