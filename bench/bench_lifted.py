"""What the lifted-pose rows (pinrecon.rows.lifted) are worth, and the default of Weights.lifted.

The bundled CMU walk (02_01), run (09_01) and dance (05_11) as bench_real's detector case
(``tracked_case``: the 12 COCO-17 body points through a perspective camera 45 degrees
from side-on, 2 px noise, 2 % outliers, 1 % swapped frames, 3 % missing, confidences),
reconstructed with ``Figure.human()``, no keyframes, the true camera, reconstruct's
defaults; the tracks carry a *simulated lifter* (:func:`simulated_lifter`): the true
points in the camera's axes (``Lifted.frame == "camera"``, or turned by a fixed unknown
rotation with ``--frame unknown``), scaled by 1.7 and shifted (a lifter's size and
origin are its own), with ``--noise-cm`` Gaussian noise per point and, on a share
``--flip-share`` of each limb's frames, the limb mirrored in depth through its root (the
shoulder or the hip: upper and lower segment together, the lifter's own 180-degree
error) over spans of 10-40 frames; confidences 0.6-1.0, 0.3-0.6 on the mirrored spans.

Columns: PA-MPJPE (mm), flipped limb segments (%, bench_real's measure), the lifter's own
flips and PA-MPJPE against the truth, and the time. ``lifted 0`` is the run without the
rows (the tracks are the same).

    OPENBLAS_NUM_THREADS=1 python bench/bench_lifted.py                      # walk, run, dance; 150 frames
    python bench/bench_lifted.py --clips walk --weights 0 25 --frames 100    # quicker
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

quick.take(["--clips", "walk", "--weights", "0", "25", "--frames", "60"])

from bench_real import SEGMENTS, score, tracked_case  # noqa: E402  (bench/ is the script's folder)

import pinrecon as pr  # noqa: E402
from pinrecon import metrics  # noqa: E402
from pinrecon.lifted import Lifted  # noqa: E402
from pinrecon.synthetic import bundled_motion  # noqa: E402

LIMBS = [("left_shoulder", ["left_elbow", "left_wrist"]), ("right_shoulder", ["right_elbow", "right_wrist"]),
         ("left_hip", ["left_knee", "left_ankle"]), ("right_hip", ["right_knee", "right_ankle"])]


def simulated_lifter(P_world, camera, names, *, noise_m=0.03, flip_share=0.1, frame="camera", seed=0,
                     span=(10, 40)):
    """A lifter's output for true points ``P_world`` (T, K, 3) seen by ``camera``: camera
    axes (or, ``frame="unknown"``, turned by a fixed rotation), scaled by 1.7 and shifted,
    ``noise_m`` noise, each limb of :data:`LIMBS` mirrored in depth through its root on
    about ``flip_share`` of the frames (spans of ``span`` frames). Returns the
    :class:`Lifted` and the (T, 4) bool mask of the mirrored limb-frames."""
    rng = np.random.default_rng(seed)
    T = len(P_world)
    X = np.asarray(P_world, float) @ np.asarray(camera.R, float).T  # camera axes (translation irrelevant)
    conf = rng.uniform(0.6, 1.0, X.shape[:2])
    flipped = np.zeros((T, len(LIMBS)), bool)
    for li, (root, kids) in enumerate(LIMBS):
        if root not in names:
            continue
        r, ks = names.index(root), [names.index(k) for k in kids if k in names]
        n_spans = int(np.ceil(flip_share * T / np.mean(span)))
        for _ in range(n_spans if flip_share > 0 else 0):
            n = int(rng.integers(*span))
            a = int(rng.integers(0, max(T - n, 1)))
            flipped[a:a + n, li] = True
        f = flipped[:, li]
        X[np.ix_(f, ks, [2])] = 2.0 * X[f, r, None, 2:3] - X[np.ix_(f, ks, [2])]
        conf[np.ix_(f, ks)] = rng.uniform(0.3, 0.6, (int(f.sum()), len(ks)))
    X = 1.7 * X + np.array([0.3, -0.2, 4.0]) + rng.normal(0.0, noise_m * 1.7, X.shape)
    if frame == "unknown":
        from scipy.spatial.transform import Rotation

        X = X @ Rotation.from_rotvec([0.4, 2.5, -0.3]).as_matrix().T
    return Lifted(X, list(names), conf, frame, "simulated"), flipped


def lifter_scores(lifted, P_true, camera):
    """The lifter alone against the truth: PA-MPJPE (mm) and flipped segments (%)."""
    names = lifted.names
    X = lifted.points
    if lifted.frame == "camera":  # back in world axes for the depth measure
        X = X @ np.asarray(camera.R, float)
    else:  # unknown axes: the best one rotation onto the truth
        Xc, Pc = X - X.mean(1, keepdims=True), P_true - P_true.mean(1, keepdims=True)
        U, _, Vt = np.linalg.svd(np.einsum("tki,tkj->ij", Pc, Xc))
        X = X @ (U @ np.diag([1, 1, np.sign(np.linalg.det(U @ Vt))]) @ Vt).T
    segs = [(names.index(a), names.index(b)) for a, b in SEGMENTS]
    X = X * (np.linalg.norm(P_true - P_true.mean(1, keepdims=True)) / np.linalg.norm(X - X.mean(1, keepdims=True)))
    return metrics.pa_mpjpe(X, P_true), 100.0 * metrics.flip_rate(X, P_true, camera, segs)


def weights_of(weight, a) -> pr.Weights:
    """``Weights.lifted = weight`` and ``--lifted-lengths`` when given."""
    return pr.Weights(lifted=weight) if a.lifted_lengths == "default" else pr.Weights(
        lifted=weight, lifted_lengths=None if a.lifted_lengths == "none" else float(a.lifted_lengths))


def run(clip, weight, a):
    fig, q, fps = bundled_motion(clip)
    q = q[: a.frames] if a.frames else q
    tracks, cam, _, P, _ = tracked_case(fig, q, fps, a.angle, "none", seed=int(a.angle))
    lifted, _ = simulated_lifter(P, cam, list(tracks.names), noise_m=a.noise_cm / 100.0, flip_share=a.flip_share,
                                 frame=a.frame, seed=a.seed)
    tracks = pr.Tracks(tracks.points, tracks.names, tracks.fps, tracks.confidence, lifted=lifted)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct(pr.Figure.human(), tracks, cam, weights=weights_of(weight, a))
    dt = time.perf_counter() - t0
    P_est = res.keypoints3d[:, res.figure.keypoint_index(tracks.names)]
    out = score(P_est, P, cam, list(tracks.names))
    out["time"] = dt
    out["lifter_pa"], out["lifter_flips"] = lifter_scores(lifted, P, cam)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clips", nargs="*", default=["walk", "run", "spin"])
    ap.add_argument("--weights", nargs="*", type=float, default=[0.0, 5.0, 25.0, 100.0])
    ap.add_argument("--frames", type=int, default=150)
    ap.add_argument("--angle", type=float, default=45.0)
    ap.add_argument("--noise-cm", type=float, default=3.0)
    ap.add_argument("--flip-share", type=float, default=0.1)
    ap.add_argument("--lifted-lengths", default="default",
                    metavar="SIGMA|none", help="Weights.lifted_lengths (default: Weights' own)")
    ap.add_argument("--frame", choices=["camera", "unknown"], default="camera")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    from provenance import provenance

    print(provenance())
    print("python bench/bench_lifted.py " + " ".join(argv if argv is not None else sys.argv[1:]))
    print(f"\nWeights.lifted_lengths {pr.Weights().lifted_lengths if a.lifted_lengths == 'default' else a.lifted_lengths}"
          f"; lifter: frame {a.frame!r}, noise {a.noise_cm:g} cm, limbs mirrored on {100 * a.flip_share:g} % of "
          f"their frames; {a.frames} frames, camera {a.angle:g} degrees from side-on, no keyframes\n")
    print("| clip | Weights.lifted | PA-MPJPE (mm) | flips (%) | MPJPE depth-aligned (mm) | lifter PA-MPJPE (mm) "
          "| lifter flips (%) | time (s) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for clip in a.clips:
        for w in a.weights:
            m = run(clip, w, a)
            print(f"| {clip} | {w:g} | {m['pa']:.1f} | {m['flips']:.1f} | {m['dz']:.1f} | {m['lifter_pa']:.1f} "
                  f"| {m['lifter_flips']:.1f} | {m['time']:.0f} |", flush=True)


if __name__ == "__main__":
    main()
