"""Issue 42: pinrecon's own lifter (``pinrecon.lifter``), scored honestly: by models that never
saw the scored clip's subject.

Folds (made by the same tool, kept outside the repository, in ``--folds``):

* ``no5``: ``python tools/train_lifter.py --hold-out 5 --out FOLDS/fold_no5.npz`` scores the
  dances 05_02 (``dance``) and 05_11 (``spin``): subject 5 (all 20 of its iClone trials, the
  same captures as the mocap files) is out of its training data.
* ``no2_9``: ``--hold-out 2 9 --out FOLDS/fold_no2_9.npz`` scores the walk 02_01 and the run
  09_01.
* ``shipped``: ``models/lifter/lifter.npz`` (``--hold-out 2 9``, the default: the same training
  as fold ``no2_9``) scores Pose2Sim's trial.

Each fold's weights file records its held-out subjects; the bench refuses a fold that saw the
clip's subject. Tracks: ``bench_real.tracked_case`` (the issue's user-grade detector case:
COCO-17 body points, perspective camera 45 and 60 degrees from side-on, 2 px noise, 2 %
outliers, 1 % left/right swaps, 3 % missing, no keyframes). The lifter alone is given the
true camera (its intrinsics: the user's calibration) and its root-relative output is put at the
true hips' midpoint: PA-MPJPE (per-frame similarity), MPJPE with the lifter's size matched to
the clip's mean limb length, and the share of flipped limb segments (``pinrecon.metrics.flip_rate``,
bench_real's segments). Inference time per 1000 frames (one thread).

Pose2Sim's real balancing trial: each camera's OpenPose detections (BODY_25B, 100 frames at
60 fps) lifted with that camera's calibration (and with no camera), scored against Pose2Sim's
four-camera triangulation (PA-MPJPE, flips along that camera's line of sight), shipped weights
(nobody of that trial is in CMU's data).

``--map`` also runs ``pinrecon.reconstruct`` (``Figure.human()``, the true camera, no keyframes; ``--keyframes
first+last``: 3D point keyframes on the first and last frames)
on the CMU cases: the path without the lifter (``lifter="none"``) and the default path with the
fold's lifter (``lifter=FILE``, :func:`pinrecon.lifter.attach_lifter`: its rows from the start
while the default pose prior holds, at ``Weights.own_lifter``; at ``Weights.lifted`` once the
prior switches), the lifter alone beside them; and on Pose2Sim's trial, each camera with the
auto camera, with and without the shipped lifter (slow: up to minutes a run; ``--clips`` and
``--angles`` choose). One draw of the detector's faults varies the flips by a few points
(``--seeds``: the mean over several draws, the flips' range beside).

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python bench/bench_lifter.py
    python bench/bench_lifter.py --folds ~/.cache/pinrecon/lifter-folds --map
    python bench/bench_lifter.py --map --clips walk run --no-pose2sim --seeds 45 60 1 2 3 4
"""

from __future__ import annotations

import quick

QUICK = quick.take(["--angles", "45", "--no-pose2sim"], cut=False)

import argparse
import os
import time
import warnings
from pathlib import Path

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import bench_real  # bench/ is the script's folder

import pinrecon as pr
from pinrecon import datasets, metrics
from pinrecon.lifter import BODY, LIMB_LENGTH_M, attach_lifter, lift, load_lifter
from pinrecon.synthetic import bundled_motion

REPO = Path(__file__).resolve().parents[1]
SUBJECT = {"walk": 2, "run": 9, "spin": 5, "dance": 5}
CLIP_NAME = {"walk": "02_01 walk", "run": "09_01 run", "spin": "05_11 dance", "dance": "05_02 dance"}
FOLDS = {"no5": ["spin", "dance"], "no2_9": ["walk", "run"], "shipped": []}
TARGETS = {"walk": (30.0, 5.0), "run": (30.0, 5.0), "spin": (40.0, None), "dance": (40.0, None)}
TRC = "pose2sim-balancing/pose-3d/S00_P00_T01_BalancingTrial_0-100.trc"
CALIB = "pose2sim-balancing/calibration/Calib_qualisys.toml"
#: the OpenPose detections' image (width, height; the phones held upright), which their files do not store
OPENPOSE_IMAGE = (1088, 1920)


def openpose_tracks(cam: int):
    """Pose2Sim's OpenPose BODY_25B detections of phone ``cam`` (1-4), 60 frames/s."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return pr.load_tracks(datasets.folder(f"pose2sim-balancing/pose/cam0{cam}_json"), fps=60.0)


def fold_path(folds: Path, fold: str) -> Path:
    return REPO / "models" / "lifter" / "lifter.npz" if fold == "shipped" else folds / f"fold_{fold}.npz"


def in_world(lifted_cam, P_true, camera):
    """Lifted points (T, K, 3) in camera axes, root-relative, placed at the true hips' midpoint
    and carried into the camera's world."""
    hips = [BODY.index("left_hip"), BODY.index("right_hip")]
    root_cam = camera.camera_points(P_true[:, hips].mean(1))
    return (lifted_cam + root_cam[:, None] - camera.t) @ camera.R


def mean_limb(P):
    return float(np.mean([np.linalg.norm(P[:, BODY.index(a)] - P[:, BODY.index(b)], axis=-1).mean()
                          for a, b in bench_real.SEGMENTS]))


def score_lifted(L, P_true, camera):
    """PA-MPJPE, size-matched root-aligned MPJPE (mm) and flips (%) of a lifted clip."""
    pts = L.select(list(BODY)).points * (mean_limb(P_true) / LIMB_LENGTH_M)
    P = in_world(pts, P_true, camera)
    segs = [(BODY.index(a), BODY.index(b)) for a, b in bench_real.SEGMENTS]
    return {"pa": metrics.pa_mpjpe(P, P_true), "mpjpe": metrics.mpjpe(P, P_true),
            "flips": 100.0 * metrics.flip_rate(P, P_true, camera, segs)}


def cmu_case(clip, azimuth, keyframes="none", seed=None):
    """The case's tracks, camera, true points and keyframes; ``seed`` draws the detector's faults
    (default the angle's own, ``int(azimuth)``: the single-seed tables)."""
    fig, q, fps = bundled_motion(clip)
    tracks, cam, keys, P, _ = bench_real.tracked_case(fig, q, fps, azimuth, keyframes,
                                                      seed=int(azimuth) if seed is None else int(seed))
    order = [list(tracks.names).index(n) for n in BODY]
    return tracks, cam, P[:, order], keys


def run_map(tracks, cam, P_true, lifter="none", weight=None, from_start=False, **kw):
    """``pinrecon.reconstruct`` (``Figure.human()``, no keyframes) of the case with ``lifter``
    (``"none"``: the path without the lifter; a weights file: its lifted-pose rows, at ``weight``,
    joining with the broader prior as ``lifter="auto"`` does, or with ``from_start`` in every solve)."""
    tr = pr.Tracks(tracks.points, tracks.names, tracks.fps, tracks.confidence)
    if from_start and lifter != "none":  # the rows in every solve, not only with the broader prior
        tr, lifter = attach_lifter(pr.Figure.human(), tr, cam, lifter), "none"
    w = pr.Weights() if weight is None else pr.Weights(lifted=weight)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct(pr.Figure.human(), tr, cam, lifter=lifter, weights=w, **kw)
    dt = time.perf_counter() - t0
    P = res.keypoints3d[:, res.figure.keypoint_index(list(BODY))]
    segs = [(BODY.index(a), BODY.index(b)) for a, b in bench_real.SEGMENTS]
    if isinstance(cam, str):
        return P, res, dt
    return {"pa": metrics.pa_mpjpe(P, P_true), "flips": 100.0 * metrics.flip_rate(P, P_true, cam, segs), "time": dt,
            "lifted": "lifted_bones" in res.extras}


def time_per_1000(model, tracks, cam, repeat=3) -> float:
    """CPU seconds (this process, one thread) per 1000 frames of :func:`lift`, best of ``repeat``
    (CPU time, not wall time: the bench machine is shared)."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.process_time()
        lift(tracks, cam, model=model)
        best = min(best, time.process_time() - t0)
    return 1000.0 * best / tracks.T


def pose2sim_rows(model):
    from pinrecon.io.calibration import load_cameras
    from pinrecon.io.trc import load_trc

    m = load_trc(datasets.fetch(TRC), names="pinrecon")
    G = m.points[:, [m.names.index(n) for n in BODY]]
    cams = load_cameras(datasets.fetch(CALIB))
    rows = []
    for k in range(4):
        tracks = openpose_tracks(k + 1)
        cam = cams[k].camera
        for label, given in (("calibration", cam), ("no camera", None)):
            r = score_lifted(lift(tracks, given, model=model), G, cam)
            rows.append((f"cam0{k + 1}", label, r))
    return rows


def pose2sim_map_rows(path, weight=None, cameras=(1, 2, 3, 4), calibrated=False):
    """Each camera's OpenPose tracks through ``reconstruct`` with the auto camera
    (``Figure.human("auto", tracks=...)``, BODY_25B map, image 1088 x 1920), or with
    ``calibrated`` the calibration file's camera as ``pinrecon reconstruct --camera FILE`` passes
    it: without the lifter and with the lifter at ``path``; PA-MPJPE and flips against the
    triangulation."""
    from pinrecon.io.calibration import load_cameras
    from pinrecon.io.trc import load_trc

    m = load_trc(datasets.fetch(TRC), names="pinrecon")
    G = m.points[:, [m.names.index(n) for n in BODY]]
    cams = load_cameras(datasets.fetch(CALIB))
    segs = [(BODY.index(a), BODY.index(b)) for a, b in bench_real.SEGMENTS]
    rows = []
    for k in cameras:
        tracks = openpose_tracks(k)
        cam = cams[k - 1].camera
        out = {}
        for label, lifter in (("default", "none"), ("lifter", str(path))):
            w = pr.Weights() if weight is None or lifter == "none" else pr.Weights(lifted=weight)
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                given = {"camera": cams[k - 1]} if calibrated else {"camera": "auto", "image_size": OPENPOSE_IMAGE}
                res = pr.reconstruct(pr.Figure.human("auto", tracks=tracks), tracks, lifter=lifter, weights=w, **given)
            P = bench_real.in_true_world(res.keypoints3d[:, res.figure.keypoint_index(list(BODY))], res.cameras[0], cam)
            out[label] = {"pa": metrics.pa_mpjpe(P, G), "flips": 100.0 * metrics.flip_rate(P, G, cam, segs),
                          "time": time.perf_counter() - t0}
        rows.append((f"cam0{k}", out))
        print(f"| cam0{k} | {out['default']['pa']:.1f} | {out['default']['flips']:.1f} | {out['default']['time']:.0f} "
              f"| {out['lifter']['pa']:.1f} | {out['lifter']['flips']:.1f} | {out['lifter']['time']:.0f} |", flush=True)
    return rows


def map_case(a, model, fold, case):
    """``(alone, without, with)`` on one case ``(tracks, camera, P, keyframes)``: the fold's
    lifter alone, the MAP without the lifter and with it (as ``--weight``, ``--from-start``,
    ``--seed`` say)."""
    tracks, cam, P, keys = case
    alone = score_lifted(lift(tracks, cam, model=model), P, cam)
    d = run_map(tracks, cam, P, keyframes=keys)  # lifter="none"
    w = run_map(tracks, cam, P, str(fold_path(a.folds, fold)), a.weight, a.from_start, keyframes=keys,
                **({"seed": a.seed} if a.seed else {}))
    assert not d["lifted"]
    return alone, d, w


def map_seeds(a, model, fold, clip, az):
    """One table row of ``--map --seeds``: the lifter alone, the MAP without it and with it, each
    the mean over the seeds' draws of the detector's faults, the flips' range beside."""
    rows = [map_case(a, model, fold, cmu_case(clip, az, a.keyframes, seed)) for seed in a.seeds]

    def cell(k):
        pa, fl = [r[k]["pa"] for r in rows], [r[k]["flips"] for r in rows]
        return f"{np.mean(pa):.1f} / {np.mean(fl):.1f} ({min(fl):.1f}-{max(fl):.1f})"

    pa_t, fl_t = TARGETS[clip]
    w_pa, w_fl = np.mean([r[2]["pa"] for r in rows]), np.mean([r[2]["flips"] for r in rows])
    met = " | -" if fl_t is None else f" | {'yes' if w_pa <= pa_t and w_fl <= fl_t else 'no'}"  # dances: vs today's
    print(f"| {CLIP_NAME[clip]} | {az:.0f} | {fold} | {cell(0)} | {cell(1)} | {cell(2)} "
          f"| {np.mean([r[1]['time'] for r in rows]):.1f} / {np.mean([r[2]['time'] for r in rows]):.1f}{met} |",
          flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--folds", type=Path, default=datasets.cache_dir() / "lifter-folds",
                    help="folder of fold_no5.npz and fold_no2_9.npz (made by tools/train_lifter.py --hold-out)")
    ap.add_argument("--angles", nargs="*", type=float, default=[45.0, 60.0])
    ap.add_argument("--map", action="store_true", help="also reconstruct (slow)")
    ap.add_argument("--no-pose2sim", action="store_true")
    ap.add_argument("--clips", nargs="*", default=list(SUBJECT), choices=list(SUBJECT),
                    help="CMU cases to score (default all: walk, run, spin, dance)")
    ap.add_argument("--from-start", action="store_true",
                    help="the MAP + lifter column with the lifter's rows in every solve (default: as reconstruct's "
                    "default, joining with the broader prior where the default prior does not know the clip)")
    ap.add_argument("--keyframes", default="none", choices=["none", "first+last"],
                    help="the CMU cases' 3D point keyframes (5 cm; default none, the issue's main case)")
    ap.add_argument("--weight", type=float, help="Weights.lifted of the MAP with the lifter (default: Weights' own)")
    ap.add_argument("--calibrated", action="store_true",
                    help="with --map: Pose2Sim's trial with its calibration file's cameras instead of the auto camera")
    ap.add_argument("--seeds", nargs="+", type=int, metavar="S",
                    help="with --map: the CMU cases' detector faults drawn with each of these seeds, the MAP scored "
                    "as the mean over them and the range of the flips (default: one draw, the angle's own seed)")
    ap.add_argument("--seed", help="the start of the MAP with the lifter (reconstruct's seed=; default its own: with "
                    "--from-start the lifted start)")
    a = ap.parse_args(argv)
    from provenance import provenance

    print(provenance())
    print("command: python bench/bench_lifter.py " + " ".join(argv if argv is not None else os.sys.argv[1:]))
    models = {}
    for fold in FOLDS:
        p = fold_path(a.folds, fold)
        if not p.exists():
            how = "" if fold == "shipped" else f"--hold-out {fold[2:].replace('_', ' ')} --out {p}"
            print(f"fold {fold}: {p} missing; make it with: python tools/train_lifter.py {how}")
            continue
        models[fold] = load_lifter(p)
        meta = models[fold].meta
        print(f"fold {fold}: {p.name}, held out subjects {meta.get('held_out_subjects')}, commit "
              f"{str(meta.get('commit'))[:12]}, {meta.get('args', {}).get('steps')} steps, "
              f"{meta.get('train_seconds')} s")
    print("\nThe lifter alone (true camera's intrinsics; root put at the true hips' midpoint), no keyframes, "
          "mean over the angles\n")
    print("| clip | fold (subjects held out) | PA-MPJPE (mm) | MPJPE size-matched (mm) | flips (%) | worst angle flips (%) "
          "| issue target PA / flips | CPU ms per 1000 frames |")
    print("|---|---|---:|---:|---:|---:|---|---:|")
    cases = {}
    for fold, clips in FOLDS.items():
        if fold not in models:
            continue
        held = set(models[fold].meta.get("held_out_subjects", []))
        for clip in [c for c in clips if c in a.clips]:
            if SUBJECT[clip] not in held:
                print(f"| {CLIP_NAME[clip]} | {fold} | fold saw subject {SUBJECT[clip]}: not scored | | | | | |")
                continue
            rows = []
            for az in a.angles:
                key = (clip, az)
                if key not in cases:
                    cases[key] = cmu_case(clip, az, a.keyframes)
                tracks, cam, P, _ = cases[key]
                r = score_lifted(lift(tracks, cam, model=models[fold]), P, cam)
                r["ms"] = time_per_1000(models[fold], tracks, cam)
                rows.append(r)
            m = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}
            pa_t, fl_t = TARGETS[clip]
            target = f"<= {pa_t:.0f} mm / " + (f"<= {fl_t:.0f} %" if fl_t else "half of the MAP's")
            print(f"| {CLIP_NAME[clip]} | {fold} ({', '.join(map(str, sorted(held)))}) | {m['pa']:.1f} | {m['mpjpe']:.1f} "
                  f"| {m['flips']:.1f} | {max(r['flips'] for r in rows):.1f} | {target} | {1000 * m['ms']:.0f} |",
                  flush=True)
    if a.map:
        kf = "no keyframes" if a.keyframes == "none" else "point keyframes (5 cm) on the first and last frames"
        print(f"\nThe MAP (pinrecon.reconstruct, Figure.human(), the true camera, {kf}): without the lifter "
              "(lifter='none') and with the fold's lifter (lifter=FILE: its lifted-pose rows"
              + (f", Weights.lifted {a.weight:g}" if a.weight is not None else "")
              + (", in every solve" if a.from_start else ", as by default: from the start while the default prior "
                 "holds, joining again with the broader prior")
              + (f", start {a.seed!r}" if a.seed else "")
              + "); the lifter alone beside them\n")
        if a.seeds:
            print(f"Each cell the mean over {len(a.seeds)} draws of the detector's faults (seeds "
                  f"{', '.join(map(str, a.seeds))}), the flips' range in brackets; 'met': the MAP with the lifter "
                  "within the issue's PA-MPJPE and flips on the means\n")
        print("| clip | angle | fold | lifter alone PA-MPJPE (mm) / flips (%) | MAP without the lifter PA-MPJPE (mm) "
              "/ flips (%) | MAP with the lifter PA-MPJPE (mm) / flips (%) | time without / with (s) |"
              + (" met |" if a.seeds else ""))
        print("|---|---:|---|---|---|---|---|" + ("---|" if a.seeds else ""))
        for fold, clips in FOLDS.items():
            if fold == "shipped" or fold not in models:
                continue
            for clip in [c for c in clips if c in a.clips]:
                for az in a.angles:
                    if a.seeds:
                        map_seeds(a, models[fold], fold, clip, az)
                        continue
                    case = cases.get((clip, az)) or cmu_case(clip, az, a.keyframes)
                    alone, d, w = map_case(a, models[fold], fold, case)
                    print(f"| {CLIP_NAME[clip]} | {az:.0f} | {fold} | {alone['pa']:.1f} / {alone['flips']:.1f} "
                          f"| {d['pa']:.1f} / {d['flips']:.1f} | {w['pa']:.1f} / {w['flips']:.1f} "
                          f"| {d['time']:.0f} / {w['time']:.0f} |", flush=True)
    if not a.no_pose2sim and "shipped" in models:
        print("\nPose2Sim's balancing trial (OpenPose BODY_25B, 100 frames), the shipped lifter alone, against the "
              "four-camera triangulation (issue target: PA-MPJPE mean <= 70 mm)\n")
        print("| camera | lifter given | PA-MPJPE (mm) | MPJPE size-matched (mm) | flips (%) |")
        print("|---|---|---:|---:|---:|")
        rows = pose2sim_rows(models["shipped"])
        for cam, label, r in rows:
            print(f"| {cam} | {label} | {r['pa']:.1f} | {r['mpjpe']:.1f} | {r['flips']:.1f} |")
        for label in ("calibration", "no camera"):
            v = [r["pa"] for _, lab, r in rows if lab == label]
            print(f"| mean | {label} | {np.mean(v):.1f} | | |")
        if a.map:
            cam_said = "the calibration file's camera" if a.calibrated else "auto camera"
            print(f"\nThe same trial through reconstruct ({cam_said}, Figure.human('auto', tracks=...): the BODY_25B "
                  "map), without the lifter and with the shipped lifter (the default; issue target: mean <= 70 mm)\n")
            print("| camera | without PA-MPJPE (mm) | without flips (%) | without time (s) | with lifter PA-MPJPE (mm) "
                  "| with lifter flips (%) | with lifter time (s) |")
            print("|---|---:|---:|---:|---:|---:|---:|")
            rows = pose2sim_map_rows(fold_path(a.folds, "shipped"), a.weight, calibrated=a.calibrated)
            print(f"| mean | {np.mean([r['default']['pa'] for _, r in rows]):.1f} | | "
                  f"| {np.mean([r['lifter']['pa'] for _, r in rows]):.1f} | | |")


if __name__ == "__main__":
    main()
