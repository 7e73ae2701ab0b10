"""Several cameras in one solve, against triangulating each point and smoothing.

The bundled CMU walk (02_01, 343 frames at 120 fps) is seen by two and by three
perspective cameras (f = 1200 px, 1920 x 1080, about 5 m from the middle of the walk,
1.5 m high; two cameras 90 degrees apart on one side of the walkway, the third behind
it), 1 px noise, no keyframes.

* **pinrecon**: ``reconstruct(figure, [tracks...], [cameras...])``: every camera's
  tracks are measurement rows through their own camera in the one batch solve, with
  joint limits and smoothing. Figure: the clip's own skeleton (22 body points tracked),
  or ``Figure.human()`` (other proportions: its segment lengths calibrated in the same
  solve, the default with several cameras, and uncalibrated) with 12 COCO-17 points
  tracked at the clip's joints.
* **two-stage** (what a triangulate-then-filter pipeline such as Pose2Sim does): each
  point in each frame triangulated by DLT (written here, in pixels, from the cameras'
  3 x 4 projection matrices) from the cameras that see it, points seen by fewer than two
  cameras left missing; gaps filled by cubic interpolation over time (any length; ends
  held), then a zero-phase 4th-order Butterworth low-pass, at Pose2Sim's default 6 Hz
  and at the cut-off that is best against the truth (an oracle: the best the two-stage
  pipeline could do).

With points missing in one camera: that camera loses 20 % of its points at random, the
far-side leg (left hip, knee, ankle, toe) for 0.5 s and everything for 0.125 s.
MPJPE is over all tracked points and frames, and (``missing``) over the (frame, point)
pairs that camera did not see. Flips: the share of limb segments whose depth sign is
wrong in any camera's view (:func:`pinrecon.planarity.limb_flip_rate`, the worst camera).

    OPENBLAS_NUM_THREADS=1 python bench/bench_multicam.py      (about a minute)
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take([])

import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import butter, filtfilt

import pinrecon as pr
from pinrecon.planarity import default_limbs, limb_flip_rate
from pinrecon.synthetic import body_keypoints, bundled_motion, project_tracks

#: COCO-17 body points of Figure.human() -> CMU BVH joints
COCO12_FROM_CMU = {
    "left_shoulder": "LeftArm", "right_shoulder": "RightArm", "left_elbow": "LeftForeArm",
    "right_elbow": "RightForeArm", "left_wrist": "LeftHand", "right_wrist": "RightHand",
    "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "left_knee": "LeftLeg", "right_knee": "RightLeg",
    "left_ankle": "LeftFoot", "right_ankle": "RightFoot",
}
FAR_LEG = ("LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase", "LeftToeBase_end", "left_hip", "left_knee",
           "left_ankle")


def cameras(q, azimuths_deg, distance_m=5.0, height_m=1.5):
    """Perspective cameras around the walk's middle, azimuth 0 = side-on."""
    centre = q[:, :3].mean(0)
    d = q[-1, :3] - q[0, :3]
    d[1] = 0.0
    d /= np.linalg.norm(d)
    side = np.cross([0.0, 1.0, 0.0], d)
    out = []
    for az in azimuths_deg:
        a = np.radians(az)
        eye = centre + distance_m * (np.cos(a) * side + np.sin(a) * d)
        eye[1] = height_m
        out.append(pr.Perspective.look_at(eye, centre, f_px=1200.0, center=(960.0, 540.0)))
    return out


def drop_in_camera(tracks, fps, seed=11):
    """Points missing in one camera: 20 % at random, the far leg for 0.5 s, all for 0.125 s."""
    rng = np.random.default_rng(seed)
    uv = tracks.points.copy()
    uv[rng.random(uv.shape[:2]) < 0.2] = np.nan
    leg = [i for i, n in enumerate(tracks.names) if n in FAR_LEG]
    a = int(0.8 * fps)
    uv[a : a + int(0.5 * fps), leg] = np.nan
    b = int(2.0 * fps)
    uv[b : b + int(0.125 * fps)] = np.nan
    return pr.Tracks(uv, tracks.names, tracks.fps)


# ----------------------------------------------------------------------------- two-stage
def dlt(cams, uv_list):
    """Per point DLT: homogeneous least squares on ``u P_3 - P_1``, ``v P_3 - P_2`` of every
    camera that sees the point (pixels; 3 x 4 matrices ``K [R | t]``). (T, K, 3), NaN
    where fewer than two cameras see the point."""
    T, K = uv_list[0].shape[:2]
    rows = np.zeros((T, K, 2 * len(cams), 4))
    n = np.zeros((T, K), int)
    for c, (cam, uv) in enumerate(zip(cams, uv_list)):
        Pm = cam.K @ np.c_[cam.R, cam.t]
        ok = np.all(np.isfinite(uv), axis=-1)
        u = np.where(ok, uv[..., 0], 0.0)[..., None]
        v = np.where(ok, uv[..., 1], 0.0)[..., None]
        rows[:, :, 2 * c] = np.where(ok[..., None], u * Pm[2] - Pm[0], 0.0)
        rows[:, :, 2 * c + 1] = np.where(ok[..., None], v * Pm[2] - Pm[1], 0.0)
        n += ok
    _, _, Vt = np.linalg.svd(rows)
    X = Vt[..., -1, :]
    out = X[..., :3] / X[..., 3:4]
    out[n < 2] = np.nan
    return out


def fill_and_filter(X, fps, cutoff_hz):
    """Gaps filled by cubic interpolation over time (ends held), then a zero-phase
    4th-order Butterworth low-pass."""
    T = X.shape[0]
    t = np.arange(T)
    Y = X.copy()
    for k in range(X.shape[1]):
        for a in range(3):
            x = X[:, k, a]
            ok = np.isfinite(x)
            if ok.all():
                continue
            f = CubicSpline(t[ok], x[ok])
            y = f(t)
            y[t < t[ok][0]] = x[ok][0]
            y[t > t[ok][-1]] = x[ok][-1]
            Y[:, k, a] = y
    b, a = butter(4, cutoff_hz / (0.5 * fps))
    return filtfilt(b, a, Y, axis=0)


def point_flips(fig, P_est, P_true, names, cam):
    """limb_flip_rate's definition on points (for the two-stage output)."""
    limbs = [sg for sg in default_limbs(fig) if sg[0] in names and sg[1] in names]
    a = [names.index(sg[0]) for sg in limbs]
    b = [names.index(sg[1]) for sg in limbs]
    dz_e = cam.depth(P_est[:, b]) - cam.depth(P_est[:, a])
    dz_t = cam.depth(P_true[:, b]) - cam.depth(P_true[:, a])
    L = np.linalg.norm(P_true[:, b] - P_true[:, a], axis=-1)
    count = np.abs(dz_t) > 0.1 * L
    return float((count & (np.sign(dz_e) != np.sign(dz_t))).sum() / max(count.sum(), 1))


# ----------------------------------------------------------------------------- cases
def case(label, fig, names, truth, q_true, cams, tracks, fps, rows, *, lossy=None, **kw):
    """pinrecon and the two-stage pipeline on one setting; ``lossy``: the index of the
    camera with missing points (scored apart). Flips from ``q_true`` when given, else
    from the points."""
    idx = fig.keypoint_index(names)
    miss = ~tracks[lossy].observed if lossy is not None else None
    flips_q = q_true is not None
    t0 = time.perf_counter()
    res = pr.reconstruct(fig, tracks, cams, **kw)
    dt = time.perf_counter() - t0
    e = 1000 * np.linalg.norm(res.keypoints3d[:, idx] - truth, axis=-1)
    if flips_q:
        fl = max(limb_flip_rate(fig, res.q, q_true, c) for c in cams)
    else:
        fl = max(point_flips_named(fig, res.keypoints3d[:, idx], truth, names, c) for c in cams)
    rows.append((label, "pinrecon (one solve)", e.mean(), e[miss].mean() if miss is not None else None, fl,
                 f"{res.solve.iterations} it, {dt:.1f} s"))
    X = dlt(cams, [t.points for t in tracks])
    tri = 1000 * np.linalg.norm(X - truth, axis=-1)
    rows.append((label, "DLT alone (points seen by >= 2 cameras)", np.nanmean(tri),
                 np.nanmean(tri[miss]) if miss is not None and np.isfinite(tri[miss]).any() else None, None,
                 f"{100 * np.isnan(tri).mean():.1f} % not triangulated"))
    best = None
    for hz in (3.0, 4.0, 6.0, 8.0, 10.0, 12.0, 16.0):
        Y = fill_and_filter(X, fps, hz)
        e2 = 1000 * np.linalg.norm(Y - truth, axis=-1)
        if hz == 6.0:
            six = (e2, Y)
        if best is None or e2.mean() < best[0].mean():
            best = (e2, Y, hz)
    variants = [("6 Hz (Pose2Sim's default)", six), (f"{best[2]:g} Hz (the best cut-off)", best[:2])]
    if best[2] == 6.0:
        variants = [("6 Hz (Pose2Sim's default, also the best cut-off)", six)]
    for tag, (e2, Y) in variants:
        fl2 = max(point_flips_named(fig, Y, truth, names, c) for c in cams)
        rows.append((label, f"DLT + fill + Butterworth {tag}", e2.mean(), e2[miss].mean() if miss is not None else None,
                     fl2, ""))
    print(f"  {label}: pinrecon {e.mean():.1f} mm, two-stage {six[0].mean():.1f} / {best[0].mean():.1f} mm", flush=True)


def point_flips_named(fig, P_est, P_true, names, cam):
    limb_names = {n for sg in default_limbs(fig) for n in sg}
    if not limb_names & set(names):
        return float("nan")
    return point_flips(fig, P_est, P_true, names, cam)


def main():
    fig, q, fps = bundled_motion("walk")
    names = body_keypoints(fig)
    truth = fig.keypoints(q)[:, fig.keypoint_index(names)]
    rows = []
    for n_cam, az in ((2, (45.0, -45.0)), (3, (45.0, -45.0, 180.0))):
        cams = cameras(q, az)
        tracks = [project_tracks(fig, q, c, names, fps=fps, noise_px=1.0, seed=10 + i) for i, c in enumerate(cams)]
        case(f"{n_cam} cameras", fig, names, truth, q, cams, tracks, fps, rows)
        tracks_m = list(tracks)
        j = 1
        tracks_m[j] = drop_in_camera(tracks[j], fps)
        case(f"{n_cam} cameras, points missing in camera 2", fig, names, truth, q, cams, tracks_m, fps, rows,
             lossy=j)

    human = pr.Figure.human()
    hnames = list(COCO12_FROM_CMU)
    htruth = fig.keypoints(q)[:, fig.keypoint_index([COCO12_FROM_CMU[n] for n in hnames])]
    cams = cameras(q, (45.0, -45.0, 180.0))
    rng = np.random.default_rng(5)
    htracks = [pr.Tracks(c.project(htruth) + rng.normal(0.0, 1.0, htruth.shape[:2] + (2,)), hnames, fps)
               for c in cams]
    case("Figure.human(), 12 COCO-17 points, 3 cameras, lengths calibrated (the default)", human, hnames, htruth,
         None, cams, htracks, fps, rows)
    case("Figure.human(), 12 COCO-17 points, 3 cameras, uncalibrated (calibrate='none')", human, hnames, htruth,
         None, cams, htracks, fps, rows, calibrate="none")

    print("\n| walk, 343 frames at 120 fps, 1 px noise, no keyframes | method | MPJPE (mm) | "
          "MPJPE where camera 2 misses the point (mm) | limbs with flipped depth sign | notes |")
    print("|---|---|---:|---:|---:|---|")
    for label, method, err, err_miss, fl, note in rows:
        em = "" if err_miss is None else f"{err_miss:.1f}"
        f = "" if fl is None else f"{100 * fl:.1f} %"
        print(f"| {label} | {method} | {err:.1f} | {em} | {f} | {note} |")


if __name__ == "__main__":
    main()
