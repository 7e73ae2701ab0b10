"""Pose2Sim's real balancing trial, each camera alone: MediaPipe Pose's own 3D (its world
landmarks) against pinrecon with lifted-pose rows from those world landmarks (issue 41's
target: pinrecon's PA-MPJPE mean at most 0.75 x MediaPipe's, below it on every camera).

Each video (``pose2sim-balancing/videos/camNN.mp4``, 100 frames at 60 fps) through MediaPipe
Pose (``mediapipe==0.10.14``, legacy solution, ``model_complexity=1``, video mode): its 2D
landmarks (pixels), visibility and world landmarks, cached in ``--cache`` (default: the user
cache ``bench_video.py`` shares, ``<pinrecon cache>/bench_video/camNN-mediapipe0.10.14.npz``;
nothing enters the repository). The 17 COCO points become tracks (confidence =
visibility) carrying a :class:`pinrecon.lifted.Lifted` of the world landmarks (frame
``--frame``: ``"unknown"`` by default, one rotation to the camera estimated), reconstructed
by ``pinrecon.reconstruct(Figure.human(), tracks, "auto", image_size=...)`` (no calibration
file, reconstruct's defaults). Scored on the 12 body points against Pose2Sim's four-camera
triangulation (``pose-3d/*.trc``): PA-MPJPE (per-frame similarity); MPJPE depth-aligned
(pinrecon's points carried into the calibrated camera's world through the camera frame they
describe, one depth offset for the clip removed: ``pinrecon.metrics.mpjpe_depth_aligned``;
MediaPipe's world landmarks have no place, so theirs is taken in the camera's axes after
one translation for the clip); bone-length variation over the clip (the mean over the 8
limb segments of their length's standard deviation over mean, %).

This bench runs MediaPipe itself; ``pinrecon track/video`` is the user's front end.

    OMP_NUM_THREADS=1 python bench/bench_lifted_real.py --weights 0 25
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

quick.take(["--cameras", "1", "--weights", "25"], cut=False)

from bench_real import SEGMENTS, in_true_world  # noqa: E402

import pinrecon as pr  # noqa: E402
from pinrecon import datasets  # noqa: E402
from pinrecon.io.calibration import load_cameras  # noqa: E402
from pinrecon.io.trc import load_trc  # noqa: E402
from pinrecon.layouts import COCO_17, MEDIAPIPE_33  # noqa: E402
from pinrecon.lifted import Lifted  # noqa: E402
from pinrecon.metrics import mpjpe, mpjpe_depth_aligned, pa_mpjpe  # noqa: E402

#: MediaPipe Pose's 33 landmarks -> the COCO-17 names (index in MediaPipe's list)
MEDIAPIPE_COCO = {"nose": 0, "left_eye": 2, "right_eye": 5, "left_ear": 7, "right_ear": 8, "left_shoulder": 11,
                  "right_shoulder": 12, "left_elbow": 13, "right_elbow": 14, "left_wrist": 15, "right_wrist": 16,
                  "left_hip": 23, "right_hip": 24, "left_knee": 25, "right_knee": 26, "left_ankle": 27,
                  "right_ankle": 28}
COCO12 = list(COCO_17[5:])
TRIAL = "pose2sim-balancing"


def mediapipe_run(cam: int, cache: Path) -> dict:
    """MediaPipe Pose on camera ``cam``'s video: ``uv`` (T, 33, 2) pixels, ``vis`` (T, 33),
    ``world`` (T, 33, 3) metres, ``size`` (W, H), ``seconds``; NaN where no person was found.
    Cached in ``cache``."""
    path = cache / f"cam{cam:02d}-mediapipe{mp_version()}.npz"
    if path.exists():
        return dict(np.load(path))
    import cv2
    import mediapipe as mp

    video = datasets.fetch(f"{TRIAL}/videos/cam{cam:02d}.mp4")
    cap = cv2.VideoCapture(str(video))
    W, H = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    uv, vis, world = [], [], []
    t0 = time.perf_counter()
    with mp.solutions.pose.Pose(static_image_mode=False, model_complexity=1) as pose:
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            out = pose.process(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB))
            if out.pose_landmarks is None:
                uv.append(np.full((33, 2), np.nan)), vis.append(np.zeros(33)), world.append(np.full((33, 3), np.nan))
                continue
            lm, wl = out.pose_landmarks.landmark, out.pose_world_landmarks.landmark
            uv.append([[p.x * W, p.y * H] for p in lm])
            vis.append([p.visibility for p in lm])
            world.append([[p.x, p.y, p.z] for p in wl])
    res = {"uv": np.array(uv, float), "vis": np.array(vis, float), "world": np.array(world, float),
           "size": np.array([W, H]), "seconds": np.float64(time.perf_counter() - t0), "fps": np.float64(60.0),
           "names": np.array(MEDIAPIPE_33)}
    cache.mkdir(parents=True, exist_ok=True)
    np.savez(path, **res)
    return res


def mp_version() -> str:
    from pinrecon.video import MEDIAPIPE_VERSION

    return MEDIAPIPE_VERSION


def image_size(cam: int, run: dict) -> tuple[int, int]:
    """(W, H) of camera ``cam``'s video (the cache of ``bench_video.py`` does not keep it)."""
    if "size" in run:
        return tuple(int(x) for x in run["size"])
    import cv2

    cap = cv2.VideoCapture(str(datasets.fetch(f"{TRIAL}/videos/cam{cam:02d}.mp4")))
    size = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    cap.release()
    return size


def tracks_of(run: dict, frame: str) -> pr.Tracks:
    """The 17 COCO points of a MediaPipe run as tracks (confidence = visibility) carrying its
    world landmarks as the lifted pose."""
    idx = list(MEDIAPIPE_COCO.values())
    names = list(MEDIAPIPE_COCO)
    conf = np.clip(run["vis"][:, idx], 0.0, 1.0)
    lifted = Lifted(run["world"][:, idx], names, conf, frame, "mediapipe")
    return pr.Tracks(run["uv"][:, idx], names, 60.0, conf, source="mediapipe", lifted=lifted)


def truth() -> np.ndarray:
    m = load_trc(datasets.fetch(f"{TRIAL}/pose-3d/S00_P00_T01_BalancingTrial_0-100.trc"), names="pinrecon")
    return m.points[:, [m.names.index(n) for n in COCO12]]


def bone_variation(P) -> float:
    """Mean over the limb segments of std/mean of their length over the clip, percent."""
    segs = [(COCO12.index(a), COCO12.index(b)) for a, b in SEGMENTS]
    L = np.stack([np.linalg.norm(P[:, b] - P[:, a], axis=-1) for a, b in segs], axis=1)
    return 100.0 * float(np.mean(L.std(axis=0) / L.mean(axis=0)))


def translated(P, G) -> float:
    """MPJPE (mm) after the one translation that best moves ``P`` onto ``G``."""
    return mpjpe(P + (G - P).mean(axis=(0, 1)), G)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cameras", nargs="*", type=int, default=[1, 2, 3, 4])
    ap.add_argument("--weights", nargs="*", type=float, default=[0.0, 25.0])
    ap.add_argument("--lifted-lengths", default="default",
                    metavar="SIGMA|none", help="Weights.lifted_lengths (default: Weights' own)")
    ap.add_argument("--frame", choices=["camera", "unknown"], default="unknown")
    ap.add_argument("--cache", type=Path, default=datasets.cache_dir() / "bench_video")
    a = ap.parse_args(argv)
    from provenance import provenance

    print(provenance())
    print("python bench/bench_lifted_real.py " + " ".join(argv if argv is not None else sys.argv[1:]))
    G = truth()
    calib = load_cameras(datasets.fetch(f"{TRIAL}/calibration/Calib_qualisys.toml"))
    print(f"\nPose2Sim's balancing trial, each camera alone; lifted frame {a.frame!r}; Weights.lifted_lengths "
          f"{pr.Weights().lifted_lengths if a.lifted_lengths == 'default' else a.lifted_lengths}\n")
    print("| camera | MediaPipe PA-MPJPE (mm) | MediaPipe MPJPE translated (mm) | MediaPipe bone variation (%) "
          "| Weights.lifted | pinrecon PA-MPJPE (mm) | pinrecon / MediaPipe | pinrecon MPJPE depth-aligned (mm) "
          "| pinrecon bone variation (%) | MediaPipe (s) | pinrecon (s) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    table: dict = {}
    for cam in a.cameras:
        run = mediapipe_run(cam, a.cache)
        tracks = tracks_of(run, a.frame)
        world = run["world"][:, [MEDIAPIPE_COCO[n] for n in COCO12]]
        ok = np.isfinite(world).all(axis=(1, 2))
        mp_pa = pa_mpjpe(world[ok], G[ok])
        true_cam = calib[cam - 1].camera
        mp_tr = translated((world[ok] - true_cam.t) @ true_cam.R, G[ok])  # camera axes, in the calibrated world
        for w in a.weights:
            weights = pr.Weights(lifted=w) if a.lifted_lengths == "default" else pr.Weights(
                lifted=w, lifted_lengths=None if a.lifted_lengths == "none" else float(a.lifted_lengths))
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = pr.reconstruct(pr.Figure.human(), tracks, "auto", image_size=image_size(cam, run),
                                     weights=weights)
            dt = time.perf_counter() - t0
            P = res.keypoints3d[:, res.figure.keypoint_index(COCO12)]
            pa = pa_mpjpe(P[ok], G[ok])
            depth = mpjpe_depth_aligned(in_true_world(P, res.cameras[0], true_cam)[ok], G[ok], true_cam)
            table.setdefault(w, []).append((pa, mp_pa))
            print(f"| cam{cam:02d} | {mp_pa:.1f} | {mp_tr:.1f} | {bone_variation(world[ok]):.1f} | {w:g} | {pa:.1f} "
                  f"| {pa / mp_pa:.2f} | {depth:.1f} | {bone_variation(P):.1f} | {float(run['seconds']):.1f} "
                  f"| {dt:.0f} |", flush=True)
    print("\n| Weights.lifted | pinrecon mean (mm) | MediaPipe mean (mm) | ratio | below MediaPipe on every camera |")
    print("|---:|---:|---:|---:|---|")
    for w, v in table.items():
        v = np.array(v)
        print(f"| {w:g} | {v[:, 0].mean():.1f} | {v[:, 1].mean():.1f} | {v[:, 0].mean() / v[:, 1].mean():.2f} "
              f"| {'yes' if np.all(v[:, 0] < v[:, 1]) else 'no'} |")


if __name__ == "__main__":
    main()
