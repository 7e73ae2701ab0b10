"""Issue 10's "Done when": no keyframes needed, detector faults survived.

The bundled CMU walk (02_01), run (09_01) and dance (05_11, sideways steps and a double
pirouette) are tracked as a detector would: the 12 COCO-17 body points (shoulders,
elbows, wrists, hips, knees, ankles = the CMU joints LeftArm, LeftForeArm, LeftHand,
LeftUpLeg, LeftLeg, LeftFoot and their right twins) through a perspective camera
(f = 1200 px, 1920 x 1080, 6 m from the middle of the path) 45 and 60 degrees from
side-on, with exactly the issue's faults (``pinrecon.synthetic.detector_faults``): 2 px
noise, 2 % of the points thrown 20-80 px away with lower confidence (0.2-0.6 against
0.6-1.0), 1 % of the frames with every left/right label pair exchanged, 3 % of the
points missing, confidences given. They are reconstructed with ``Figure.human()``
(anatomical limits, ``docs/limits.md``), calibrated when ``reconstruct`` takes
``calibrate=`` (the mode is printed), with 3D point keyframes (5 cm noise) on the first
and last frame, or none, or (``--keyframes N``) on N frames evenly spaced from the first to
the last; from the engine's default start and from the multi-hypothesis start
(``seed="hypotheses"``).

Columns (``pinrecon.metrics``, against the clip's own joints): PA-MPJPE (per-frame
similarity alignment), flipped limb segments (upper arms, forearms, thighs, shanks whose
depth order along the line of sight is wrong, frames where the true depth difference
exceeds 10 % of the length), MPJPE after removing the one constant depth offset, the
root (mid-hip) trajectory error after that offset, plain MPJPE; the mean over the camera
angles, and the worst angle's flips.

The lab case: the clip's own skeleton (with the CMU ASF joint limits read onto it,
``project-test-data/cmu-asf_01.asf`` through pinrecon.datasets), an orthographic camera 45 degrees from side-on, its 22
body joints with 1 px noise, 3D keyframes (2 cm) on the first and last frame.

    OPENBLAS_NUM_THREADS=1 python bench/bench_real.py            # everything (about 30 min on one core)
    OPENBLAS_NUM_THREADS=1 python bench/bench_real.py --quick    # walk only, 45 degrees, 150 frames
    python bench/bench_real.py --clips walk --angles 45 60 --starts hypotheses
    python bench/bench_real.py --clips spin --starts auto --no-lab --copies 3   # the dance over copies

Thresholds of the issue (checked in the last column): first and last keyframes PA-MPJPE
<= 40 mm and flips <= 5 %; no keyframes <= 50 mm and <= 8 %; lab case flips <= 2 %.
"""

from __future__ import annotations

import argparse
import inspect
import os
import time
import warnings
from pathlib import Path

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pinrecon as pr
from pinrecon import datasets
from pinrecon import metrics
from pinrecon.result import uncertain_limb_spans
from pinrecon.stability import drop_detections
from pinrecon.synthetic import (
    COCO_BODY_FROM_CMU,
    body_keypoints,
    bundled_motion,
    coco_body_tracks,
    detector_faults,
    perspective_side_camera,
    point_keyframes,
    project_tracks,
    side_camera,
)
from pinrecon.tracks import keyframes_from_points

ASF = datasets.fetch("project-test-data/cmu-asf_01.asf")
SEGMENTS = [("left_shoulder", "left_elbow"), ("left_elbow", "left_wrist"), ("right_shoulder", "right_elbow"),
            ("right_elbow", "right_wrist"), ("left_hip", "left_knee"), ("left_knee", "left_ankle"),
            ("right_hip", "right_knee"), ("right_knee", "right_ankle")]
LIMITS = {"first+last": (40.0, 5.0), "none": (50.0, 8.0)}


def within_limits(keyframes: str, pa: float, flips: float) -> str:
    """``"yes"`` / ``"no"`` against the issue's limits for that keyframe setting, ``"-"``
    for a setting the issue sets none for."""
    if keyframes not in LIMITS:
        return "-"
    pa_max, fl_max = LIMITS[keyframes]
    return "yes" if pa <= pa_max and flips <= fl_max else "no"


def calibration_mode() -> str | None:
    """``"lengths"`` when :func:`pinrecon.reconstruct` can calibrate, else ``None``."""
    return "lengths" if "calibrate" in inspect.signature(pr.reconstruct).parameters else None


def score(P_est, P_true, camera, names):
    segs = [(names.index(a), names.index(b)) for a, b in SEGMENTS if a in names and b in names]
    hips = [names.index(n) for n in names if n.endswith(("hip", "UpLeg"))][:2]
    return {
        "pa": metrics.pa_mpjpe(P_est, P_true),
        "flips": 100.0 * metrics.flip_rate(P_est, P_true, camera, segs),
        "dz": metrics.mpjpe_depth_aligned(P_est, P_true, camera),
        "root": metrics.root_error(P_est, P_true, camera, hips),
        "mpjpe": metrics.mpjpe(P_est, P_true),
    }


def flag_mask(extras, T: int) -> np.ndarray:
    """(T, S) bool: the limb segment-frames (``SEGMENTS``) a result's own warnings flag: its
    limb's reflection span is uncertain (the hypothesis search, or a mirror the mirror stage
    found as cheap) or the pose there is unlike the pose prior's clips
    (``pinrecon.unfamiliar``)."""
    unf = np.zeros(T, bool)
    for a, b in np.asarray(extras.get("prior_unfamiliar_spans", np.zeros((0, 2))), int).reshape(-1, 2):
        unf[a:b] = True
    out = np.repeat(unf[:, None], len(SEGMENTS), axis=1)
    for chain, s0, s1 in uncertain_limb_spans(extras):
        for k, (a, b) in enumerate(SEGMENTS):
            if {a, b} <= set(chain.split("-")):
                out[s0:s1, k] = True
    return out


def flagged(extras, P_est, P_true, camera, names):
    """How the result's own warnings cover its errors: (share of the flipped limb-segment
    frames that fall in a frame the result flags (:func:`flag_mask`), share of frames
    flagged), percent."""
    flip, _ = metrics.flipped_segments(P_est, P_true, camera, [(names.index(a), names.index(b)) for a, b in SEGMENTS])
    mask = flag_mask(extras, len(P_true))
    return 100.0 * int((flip & mask).sum()) / max(int(flip.sum()), 1), 100.0 * float(mask.any(axis=1).mean())


def detector_case(clip, azimuth, keyframes, frames=None, seed=0):
    fig, q, fps = bundled_motion(clip)
    return tracked_case(fig, q[:frames] if frames else q, fps, azimuth, keyframes, seed)


def tracked_case(fig, q, fps, azimuth, keyframes, seed=0, joints=None):
    """A motion (``fig``, ``q`` at ``fps``) as the issue's detector case: the 12 COCO-17 body
    points (``joints``: COCO name -> the figure's joint, default the CMU motionbuilder
    release's) through the perspective camera ``azimuth`` degrees from side-on, the issue's
    faults, point keyframes (5 cm) per ``keyframes``. Returns (tracks, camera, keyframes or
    None, true points (T, 12, 3), the faults' log)."""
    cam = perspective_side_camera(q, azimuth)
    clean, P = coco_body_tracks(fig, q, cam, fps=fps, joints=joints)
    tracks, log = detector_faults(clean, seed=seed)
    keys = None
    if keyframes == "first+last" or keyframes.isdigit():
        n = 2 if keyframes == "first+last" else int(keyframes)
        kf_frames = np.unique(np.round(np.linspace(0, len(q) - 1, n)).astype(int)).tolist()
        rng = np.random.default_rng(seed + 7)
        keys = keyframes_from_points(kf_frames, P + rng.normal(0.0, 0.05, P.shape), clean.names, 0.05)
    return tracks, cam, keys, P, log


def _start(start, keys):
    """The start ``reconstruct`` runs: "previous" is the default before issue 10, "auto"
    today's default (``pinrecon.starts.auto_start``: the multi-hypothesis start without
    keyframes or with sparse ones, the keyframe start with denser ones)."""
    if start == "previous":
        return "keyframes" if keys is not None else "rest"
    if start == "auto":
        return "auto"
    return start


_CACHE: dict = {}


def _feet(floor):
    """``reconstruct``'s floor keyword for ``--floor``: nothing for "default" (its own default:
    the feet on the ground for the generic human), else the value ("auto", "none")."""
    return {} if floor in (None, "default") else {"floor": floor}


def run_detector(clip, azimuth, keyframes, start, mode, frames=None, figure="human", prior="auto", floor="default",
                 camera="true", copy=None):
    """One detector row's run; ``copy`` (a seed) solves a copy of its tracks with 1 % of the
    detections left out instead (``pinrecon.stability.drop_detections``)."""
    key = (clip, azimuth, keyframes, _start(start, keyframes if keyframes != "none" else None), mode, frames, figure,
           prior, floor, camera, copy)
    if key not in _CACHE:
        _CACHE[key] = _run_detector(clip, azimuth, keyframes, start, mode, frames, figure, prior, floor, camera, copy)
    return _CACHE[key]


def in_true_world(P_est, fitted, true):
    """Points of a result whose world is its fitted camera's (the auto camera) carried into
    the true camera's world through the camera frame both describe (what the camera sees)."""
    return (fitted.camera_points(P_est) - true.t) @ true.R


def _run_detector(clip, azimuth, keyframes, start, mode, frames=None, figure="human", prior="auto", floor="default",
                  camera="true", copy=None):
    tracks, cam, keys, P, log = detector_case(clip, azimuth, keyframes, frames, seed=int(azimuth))
    if copy is not None:
        tracks = drop_detections(tracks, 0.01, int(copy))
    coco = list(tracks.names)
    if figure == "own":  # the clip's own skeleton: the same tracks under the CMU joint names
        fig = bundled_motion(clip)[0].with_limits(ASF)
        ren = [COCO_BODY_FROM_CMU[n] for n in coco]
        tracks = pr.Tracks(tracks.points, ren, tracks.fps, tracks.confidence)
        if keys is not None:
            keys = pr.Keyframes([type(k)(k.frame, k.sigma, points={COCO_BODY_FROM_CMU[n]: x for n, x in k.points.items()})
                                 for k in keys])
    else:
        fig = pr.Figure.human()
    kw = {"calibrate": mode if figure == "human" else "none"} if mode else {}
    if camera == "auto":  # no camera file: the image size only; calibrate takes reconstruct's default (+ camera)
        kw = {"image_size": (1920, 1080)} if figure == "human" else {"image_size": (1920, 1080), "calibrate": "camera"}
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct(fig, tracks, "auto" if camera == "auto" else cam, keys, seed=_start(start, keys),
                             weights=pr.Weights(pose_prior_model=prior), **kw, **_feet(floor))
    dt = time.perf_counter() - t0
    P_est = res.keypoints3d[:, res.figure.keypoint_index(tracks.names)]
    if camera == "auto" and keys is None:  # its world is the fitted camera's; with keyframes the clip's
        P_est = in_true_world(P_est, res.cameras[0], cam)
    out = score(P_est, P, cam, coco)
    out["flips_flagged"], out["frames_flagged"] = flagged(res.extras, P_est, P, cam, coco)
    swapped = set(np.asarray(log["swapped_frames"]).tolist())
    repaired = set(np.asarray(res.extras.get("repaired_frames", [])).tolist())
    out["focal"] = float(res.cameras[0].K[0, 0]) if camera == "auto" else float("nan")
    out.update(time=dt, swaps_found=len(swapped & repaired), swaps=len(swapped), false_repairs=len(repaired - swapped),
               outliers=len(res.extras.get("outlier_frames", [])), injected=len(log["outliers"]))
    return out


def run_lab(clip, start, frames=None, prior="auto", floor="default"):
    fig, q, fps = bundled_motion(clip)
    if frames:
        q = q[:frames]
    fig = fig.with_limits(ASF)
    names = body_keypoints(fig)
    cam = side_camera(q, 45.0)
    tracks = project_tracks(fig, q, cam, names, fps=fps, noise_px=1.0, seed=11)
    keys = point_keyframes(fig, q, [0, len(q) - 1], names, sigma_m=0.02, seed=12)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct(fig, tracks, cam, keys, seed=_start(start, keys), weights=pr.Weights(pose_prior_model=prior),
                             **_feet(floor))
    dt = time.perf_counter() - t0
    coco = {v: k for k, v in COCO_BODY_FROM_CMU.items()}
    idx = fig.keypoint_index(names)
    P_est, P_true = res.keypoints3d[:, idx], fig.keypoints(q)[:, idx]
    out = score(P_est, P_true, cam, [coco.get(n, n) for n in names])
    out["time"] = dt
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clips", nargs="*", default=["walk", "run", "spin"])
    ap.add_argument("--angles", nargs="*", type=float, default=[45.0, 60.0])
    ap.add_argument("--keyframes", nargs="*", default=["first+last", "none"],
                    help="first+last, none, or a number N: N keyframes evenly spaced from the first frame to "
                    "the last (the issue's limits are checked for first+last and none only)")
    ap.add_argument("--starts", nargs="*", default=["previous", "auto", "hypotheses"],
                    help="starts to compare; 'previous' is the default before issue 10 (the keyframe start "
                    "with keyframes, else the rest start); 'auto' today's (the multi-hypothesis start without "
                    "keyframes, the keyframe start with them); runs that are the same are run once")
    ap.add_argument("--lab-starts", nargs="*", default=["auto", "planarity", "hypotheses"])
    ap.add_argument("--frames", type=int, help="only the first N frames of each clip")
    ap.add_argument("--no-lab", action="store_true")
    ap.add_argument("--quick", action="store_true", help="walk, 45 degrees, 150 frames")
    ap.add_argument("--figure", choices=["human", "own"], default="human",
                    help="Figure.human() (default) or the clip's own skeleton (with the ASF limits)")
    ap.add_argument("--uncalibrated", action="store_true", help="calibrate='none' even where reconstruct can")
    ap.add_argument("--pose-prior-model", default="auto",
                    help="Weights.pose_prior_model for every row, the lab case's too (cmu_bvh_pose: the CMU BVH "
                    "skeleton's prior, with --figure own)")
    ap.add_argument("--floor", choices=["default", "auto", "none"], default="default",
                    help="the feet stage for every row, the lab case's too: reconstruct's default (on for the "
                    "generic human), 'auto' (on for any figure) or 'none' (off)")
    ap.add_argument("--copies", type=int, default=0, metavar="K",
                    help="also solve every detector row on K copies of its tracks with 1 %% of the detections left "
                    "out (seeds 0..K-1) and print a table of the mean and range over the copies: a row of a clip the "
                    "model does not decide is one draw (bench/README.md, \"What --stability N is worth\")")
    ap.add_argument("--camera", choices=["true", "auto"], default="true",
                    help="the camera that made the tracks (default) or none: camera='auto' with the image size "
                    "(1920 x 1080; the detector rows only; the fitted focal length is printed, true 1200 px)")
    a = ap.parse_args(argv)
    if a.quick:
        a.clips, a.angles, a.frames = ["walk"], [45.0], a.frames or 150
    from provenance import provenance

    print(provenance())
    mode = calibration_mode()
    if a.uncalibrated and mode:
        mode = "none"
    what = "the clip's own skeleton (ASF limits)" if a.figure == "own" else "Figure.human()"
    what += f", pose prior {a.pose_prior_model!r}, floor {a.floor!r}, camera {a.camera!r}"
    cal = mode not in (None, "none") and a.figure == "human"  # the own skeleton is the subject's: never calibrated
    print(f"mode: {what}, {'calibrated (calibrate=' + repr(mode) + ')' if cal else 'uncalibrated'}"
          f" (reconstruct {'takes' if calibration_mode() else 'does not take'} calibrate=)")
    print()
    print("| clip | keyframes | start | PA-MPJPE (mm) | flips (%) | worst angle flips (%) | MPJPE depth-aligned (mm) "
          "| root error (mm) | MPJPE (mm) | swaps found | false repairs | outliers reported / injected "
          "| flipped segments flagged (%) | frames flagged (%) | time (s) | within the issue's limits |")
    print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    def detector_rows(clip, kf, start, copies=(None,)):
        """The runs of one table row: every angle, as run (``None``) or on each copy's seed."""
        return [run_detector(clip, az, kf, start, mode, a.frames, a.figure, a.pose_prior_model, a.floor, a.camera,
                             copy=c) for az in a.angles for c in copies]

    for clip in a.clips:
        for kf in a.keyframes:
            for start in a.starts:
                rows = detector_rows(clip, kf, start)
                m = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}
                worst = max(r["flips"] for r in rows)
                ok = within_limits(kf, m["pa"], m["flips"])
                print(f"| {clip} | {kf} | {start} | {m['pa']:.1f} | {m['flips']:.1f} | {worst:.1f} | {m['dz']:.1f} "
                      f"| {m['root']:.1f} | {m['mpjpe']:.1f} | {sum(r['swaps_found'] for r in rows)}/"
                      f"{sum(r['swaps'] for r in rows)} | {sum(r['false_repairs'] for r in rows)} "
                      f"| {sum(r['outliers'] for r in rows)}/{sum(r['injected'] for r in rows)} "
                      f"| {m['flips_flagged']:.0f} | {m['frames_flagged']:.0f} | {m['time']:.0f} "
                      f"| {ok} |" + (" focal " + ", ".join(f"{r['focal']:.0f}" for r in rows) + " px"
                                     if a.camera == "auto" else ""), flush=True)
    if a.copies > 0:
        print(f"\nover {a.copies} copies per angle with 1 % of the detections left out (PA-MPJPE mm / flips %; the "
              "issue's limits checked on the means)\n")
        print("| clip | keyframes | start | as run | mean over the copies | PA-MPJPE range | flips range "
              "| within the issue's limits over the copies |")
        print("|---|---|---|---:|---:|---:|---:|---|")
        for clip in a.clips:
            for kf in a.keyframes:
                for start in a.starts:
                    base = detector_rows(clip, kf, start)
                    rows = detector_rows(clip, kf, start, range(a.copies))
                    pa, fl = (np.array([r[k] for r in rows]) for k in ("pa", "flips"))
                    ok = within_limits(kf, pa.mean(), fl.mean())
                    print(f"| {clip} | {kf} | {start} | {np.mean([r['pa'] for r in base]):.1f} / "
                          f"{np.mean([r['flips'] for r in base]):.1f} | {pa.mean():.1f} / {fl.mean():.1f} "
                          f"| {pa.min():.1f}-{pa.max():.1f} | {fl.min():.1f}-{fl.max():.1f} | {ok} |", flush=True)
    if a.no_lab:
        return
    print()
    print("| lab case (own skeleton + ASF limits, orthographic 45 deg, 22 joints, 1 px, first+last keyframes) "
          "| start | PA-MPJPE (mm) | flips (%) | MPJPE depth-aligned (mm) | MPJPE (mm) | time (s) | flips <= 2 % |")
    print("|---|---|---:|---:|---:|---:|---:|---|")
    for clip in [c for c in a.clips if c in ("walk", "run")]:
        for start in a.lab_starts:
            r = run_lab(clip, start, a.frames, a.pose_prior_model, a.floor)
            print(f"| {clip} | {start} | {r['pa']:.1f} | {r['flips']:.1f} | {r['dz']:.1f} | {r['mpjpe']:.1f} "
                  f"| {r['time']:.0f} | {'yes' if r['flips'] <= 2.0 else 'no'} |", flush=True)


if __name__ == "__main__":
    main()
