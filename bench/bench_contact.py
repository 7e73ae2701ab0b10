"""Feet on the ground: foot skating, penetration and floating, with and without the contact rows.

The bundled CMU walk, run and dance (05_11, sideways steps and a pirouette), taken at 60 fps
(every other frame), are seen by an orthographic camera 45 degrees from side-on with 1 px
noise, in two settings:

* **lab**: the figure built from the clip's own skeleton, its 22 body points tracked,
  3D point keyframes (2 cm noise) every 0.25 s; foot points: both ankles (``*Foot``),
  toe joints and toe ends.
* **generic figure**: ``Figure.human()`` (example-robot-data, other proportions), 12
  COCO-17 body points (shoulders, elbows, wrists, hips, knees, ankles) tracked at the
  clip's joints, 3D keyframes of those 12 points on the first and last frame only; foot
  points: the ankles.

Each is reconstructed without (``reconstruct``) and with the floor and contact rows
(``reconstruct(..., floor="auto", contact="auto")``: floor and contacts estimated from
the motion itself). Scored against the clip:

* the true floor and the planted foot points' true contact frames are taken from the clip
  itself (:func:`pinrecon.contact.estimate_floor` and :func:`~pinrecon.contact.detect_contacts`
  on the clip's own foot points: within 3 cm of the point's lowest level and slower than
  15 cm/s, smoothed over 50 ms, until above 5 cm or faster than 25 cm/s);
* skating: mean horizontal speed of a reconstructed foot point over the true contact frames
  (frames t, t + 1 both in contact); the clip's own foot points skate 7.4 (walk), 12.6 (run)
  and 6.7 cm/s (dance) by this measure over the same frames (``clip itself`` in the table):
  its joint centres creep 1-3 cm over a stance as the foot rolls, jitter by about 1 mm
  from frame to frame, and move 15-25 cm/s in the first and last frames counted;
* penetration: depth of a reconstructed foot point below the lowest height the true point
  ever reaches above the true floor, mean over all frames and foot points and largest;
* floating: height of a reconstructed foot point above the true one during true contacts;
* MPJPE over the tracked points.

    OPENBLAS_NUM_THREADS=1 python bench/bench_contact.py [--clips walk run spin] [--cases lab generic]

``--real``: Pose2Sim's real balancing trial instead, each of its four phone videos alone through
the default path (``Figure.human()``, the auto camera, MediaPipe's tracks and 3D cues as
bench_video caches them), against its four-camera triangulation: the contacts the feet stage
found against those pinrecon's own detection finds on the triangulated ankles (a level floor,
Z up in the calibration's world, through their low heights; ankle-only thresholds), the angle between
the floor it estimated and the calibration's up (carried into each true camera's frame), and
PA-MPJPE with the feet stage and without it (``floor="none"``).

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python bench/bench_contact.py --real
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take(["--clips", "walk", "--cases", "lab"])

import argparse
import sys
import time

import numpy as np

import pinrecon as pr
from pinrecon.contact import ContactSettings, detect_contacts, estimate_floor, foot_keypoints, foot_metrics
from pinrecon.synthetic import body_keypoints, bundled_motion, point_keyframes, project_tracks, side_camera

#: COCO-17 body points of Figure.human() -> CMU BVH joints
COCO12_FROM_CMU = {
    "left_shoulder": "LeftArm", "right_shoulder": "RightArm", "left_elbow": "LeftForeArm",
    "right_elbow": "RightForeArm", "left_wrist": "LeftHand", "right_wrist": "RightHand",
    "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "left_knee": "LeftLeg", "right_knee": "RightLeg",
    "left_ankle": "LeftFoot", "right_ankle": "RightFoot",
}


#: contact detection on the clip itself (the true contact frames)
TRUTH_SETTINGS = ContactSettings(speed_on_mps=0.15, speed_off_mps=0.25, smooth_s=0.05)


def truth_feet(fig, q, fps, names):
    """The clip's own floor, contacts, foot heights (T, F) and clearances (F,)."""
    P = fig.keypoints(q)
    feet = P[:, fig.keypoint_index(names)]
    floor = estimate_floor(feet, p_upper=q[:, :3], fps=fps)
    contact = detect_contacts(feet, floor, fps, TRUTH_SETTINGS)
    h = floor.height(feet)
    return floor, contact, h, h.min(axis=0)


def score(P_feet, truth, fps):
    floor, contact, h_true, clear = truth
    m = foot_metrics(P_feet, floor, contact, fps, clearance_m=clear, contact_height_m=h_true)
    return m


#: frames of the 120 fps clips kept (2: 60 fps)
STEP = 2


def setting(clip, case):
    """(figure, tracks, camera, keyframes, truth points (T, N, 3), their names, truth foot
    data, foot point names on the reconstructed figure)."""
    cfig, q, fps = bundled_motion(clip)
    q, fps = q[::STEP], fps / STEP
    cam = side_camera(q, 45.0)
    if case == "lab":
        names = body_keypoints(cfig)
        tracks = project_tracks(cfig, q, cam, names, fps=fps, noise_px=1.0, seed=1)
        keys = point_keyframes(cfig, q, range(0, len(q), int(0.25 * fps)), names, sigma_m=0.02, seed=2)
        feet = foot_keypoints(cfig, names)
        truth_pts = cfig.keypoints(q)[:, cfig.keypoint_index(names)]
        return cfig, tracks, cam, keys, truth_pts, names, truth_feet(cfig, q, fps, feet), feet, fps
    fig = pr.Figure.human()
    names = list(COCO12_FROM_CMU)
    cmu = [COCO12_FROM_CMU[n] for n in names]
    truth_pts = cfig.keypoints(q)[:, cfig.keypoint_index(cmu)]
    rng = np.random.default_rng(3)
    uv = cam.project(truth_pts) + rng.normal(0.0, 1.0, truth_pts.shape[:2] + (2,))
    tracks = pr.Tracks(uv, names, fps)
    noisy = truth_pts + rng.normal(0.0, 0.02, truth_pts.shape)
    keys = pr.tracks.keyframes_from_points([0, len(q) - 1], noisy, names, 0.02)
    feet = ["left_ankle", "right_ankle"]
    return fig, tracks, cam, keys, truth_pts, names, truth_feet(cfig, q, fps, ["LeftFoot", "RightFoot"]), feet, fps


def run(clip, case, rows):
    fig, tracks, cam, keys, truth_pts, names, truth, feet, fps = setting(clip, case)
    idx = fig.keypoint_index(names)
    fidx = fig.keypoint_index(feet)
    cfig, q, _ = bundled_motion(clip)
    cmu_feet = feet if case == "lab" else ["LeftFoot", "RightFoot"]
    m = score(cfig.keypoints(q[::STEP])[:, cfig.keypoint_index(cmu_feet)], truth, fps)
    rows.append((clip, case, "clip itself", m, 0.0, int(truth[1].sum()), 0.0))
    for label, kw in (("without", {"floor": "none"}), ("with floor + contact rows", {"floor": "auto", "contact": "auto"})):
        t0 = time.perf_counter()
        res = pr.reconstruct(fig, tracks, cam, keys, **kw)
        dt = time.perf_counter() - t0
        P = res.keypoints3d
        mpjpe = 1000 * np.linalg.norm(P[:, idx] - truth_pts, axis=-1).mean()
        m = score(P[:, fidx], truth, fps)
        rows.append((clip, case, label, m, mpjpe, int(truth[1].sum()), dt))
        print(f"  {clip:5s} {case:8s} {label:26s} skating {100 * m['skating_mps']:6.2f} cm/s  "
              f"penetration {1000 * m['penetration_m']:5.1f} / {1000 * m['penetration_max_m']:5.1f} mm  "
              f"floating {1000 * m['floating_m']:5.1f} mm  MPJPE {mpjpe:6.1f} mm  {dt:5.1f} s", flush=True)


def real_trial() -> None:
    """``--real``: the feet stage on Pose2Sim's trial, each camera alone (module docstring)."""
    import bench_stages
    import bench_video

    from pinrecon.contact import FootContact, detection_settings
    from pinrecon.floor import Floor

    G = bench_video.truth()  # (T, 12, 3), the calibration's world (Z up)
    names = bench_stages.COCO12
    ankles = ["left_ankle", "right_ankle"]
    feet = G[:, [names.index(n) for n in ankles]]
    floor = Floor(np.array([0.0, 0.0, 1.0]), float(np.nanquantile(feet[..., 2], 0.05)) - ContactSettings().ankle_height_m)
    true_c = detect_contacts(feet, floor, 60.0, detection_settings(ankles, ContactSettings()))
    print(f"Pose2Sim's balancing trial, {len(G)} frames; the triangulated ankles' contact frames: "
          f"{int(true_c[:, 0].sum())} left, {int(true_c[:, 1].sum())} right\n")
    print("| camera | contacts found left / right | correct | false | missed | recall | precision | "
          "floor normal to the calibration's up (deg) | PA-MPJPE with / without the feet stage (mm) |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---|")
    for cam in (1, 2, 3, 4):
        case = bench_stages.real_case(cam, True)
        true_cam = case[3]
        pa = {label: bench_stages.run(case, **kw) for label, kw in (("with", {}), ("without", {"floor": "none"}))}
        res = pa["with"]["result"]
        fc = FootContact.from_extras(res.extras)
        found = np.asarray(fc.contact, bool)[:, [list(fc.names).index(n) for n in ankles]]
        n_cam = np.asarray(res.cameras[0].R, float) @ np.asarray(fc.floor.normal, float)
        up_cam = np.asarray(true_cam.R, float) @ floor.normal
        angle = float(np.degrees(np.arccos(min(1.0, abs(float(n_cam @ up_cam)) / np.linalg.norm(n_cam)))))
        tp, fp, fn = int((found & true_c).sum()), int((found & ~true_c).sum()), int((~found & true_c).sum())
        precision = f"{tp / (tp + fp):.2f}" if tp + fp else "-"
        print(f"| cam{cam:02d} | {int(found[:, 0].sum())} / {int(found[:, 1].sum())} | {tp} | {fp} | {fn} | "
              f"{tp / max(1, tp + fn):.2f} | {precision} | {angle:.1f} | {pa['with']['pa']:.1f} / {pa['without']['pa']:.1f} |",
              flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--clips", nargs="*", default=["walk", "run", "spin"])
    ap.add_argument("--cases", nargs="*", default=["lab", "generic"])
    ap.add_argument("--real", action="store_true", help="Pose2Sim's real trial instead (module docstring)")
    a = ap.parse_args()
    from provenance import provenance

    print(provenance())
    print("command: python bench/bench_contact.py " + " ".join(sys.argv[1:]))
    if a.real:
        real_trial()
        return
    rows = []
    for case in a.cases:
        for clip in a.clips:
            run(clip, case, rows)
    print("\n| clip | case | rows | skating (cm/s) | penetration mean / max (mm) | floating (mm) | MPJPE (mm) | "
          "true contacts | time (s) |")
    print("|---|---|---|---:|---:|---:|---:|---:|---:|")
    for clip, case, label, m, mpjpe, nc, dt in rows:
        err, sec = (f"{mpjpe:.1f}", f"{dt:.1f}") if label != "clip itself" else ("-", "-")
        print(f"| {clip} | {case} | {label} | {100 * m['skating_mps']:.2f} | {1000 * m['penetration_m']:.1f} / "
              f"{1000 * m['penetration_max_m']:.1f} | {1000 * m['floating_m']:.1f} | {err} | {nc} | {sec} |")


if __name__ == "__main__":
    main()
