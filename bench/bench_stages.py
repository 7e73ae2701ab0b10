"""What every stage of ``pinrecon.reconstruct`` (``pinrecon.stages.STAGES``) costs and earns on the
default monocular path: one camera, ``Figure.human()``, the auto camera, detector-like tracks, no
keyframes, reconstruct's defaults.

Clips: the bundled CMU walk (02_01), run (09_01) and dances 05_02 (``dance``) and 05_11
(``spin``) as bench_real's detector case (``tracked_case``: 12 COCO-17 body points through a
perspective camera 45 degrees from side-on, 2 px noise, 2 % outliers, 1 % swapped frames, 3 %
missing), first ``--frames`` frames, reconstructed with ``camera="auto"`` (1920 x 1080); and
Pose2Sim's real balancing trial (``real``: camera ``--cam``'s MediaPipe tracks, 100 frames, cached
by bench_video.py in ``<pinrecon cache>/bench_video/``). Each clip with lifted cues (``cues``:
synthetic clips carry bench_lifted's simulated lifter, 3 cm noise, limbs mirrored on 10 % of
their frames; the real trial MediaPipe's own world landmarks) and without (``none``).

Per clip and cue: the ``reconstruct`` call's frames/s (wall clock, and per CPU second of this
one-threaded process and the children it forks beside it, ``pinrecon.processes``: on a shared
machine the second is the one to compare), PA-MPJPE (mm) and flipped limb segments
(%, bench_real's measure), and per stage its time and what the result scores with that stage
alone switched off (``skip=(stage,)``; a stage that changed nothing is not run again: skipping
it gives the same result). ``--variants`` adds whole-path variants: ``rest`` (the rest-pose
start instead of the multi-hypothesis one), ``nolengths`` (no limb lengths from the tracks).

    OMP_NUM_THREADS=1 nice python bench/bench_stages.py                       # about 30 min
    python bench/bench_stages.py --clips real walk --cues cues --no-ablate    # the speed only
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

quick.take(["--clips", "walk", "--frames", "40", "--cues", "cues", "--no-ablate"])

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402
from bench_lifted import simulated_lifter  # noqa: E402
from bench_real import SEGMENTS, in_true_world, tracked_case  # noqa: E402

import pinrecon as pr  # noqa: E402
from pinrecon import datasets, metrics  # noqa: E402
from pinrecon.layouts import COCO_17  # noqa: E402
from pinrecon.stages import STAGES  # noqa: E402
from pinrecon.synthetic import bundled_motion  # noqa: E402

COCO12 = list(COCO_17[5:])
TRIAL = "pose2sim-balancing"
NAMES = {"walk": "walk 02_01", "run": "run 09_01", "dance": "dance 05_02", "spin": "dance 05_11", "real": "Pose2Sim"}


def synthetic_case(clip: str, frames: int, cues: bool):
    """(tracks, image size, true points (T, 12, 3), true camera) of a bundled clip."""
    fig, q, fps = bundled_motion(clip)
    q = q[:frames] if frames else q
    tracks, cam, _, P, _ = tracked_case(fig, q, fps, 45.0, "none", seed=45)
    lifted = simulated_lifter(P, cam, list(tracks.names))[0] if cues else None
    tracks = pr.Tracks(tracks.points, tracks.names, tracks.fps, tracks.confidence, lifted=lifted)
    order = [list(tracks.names).index(n) for n in COCO12]
    return tracks, (1920, 1080), P[:, order], cam


def real_case(cam: int, cues: bool):
    """Pose2Sim's trial seen by camera ``cam``: MediaPipe's tracks (cached by bench_video.py)."""
    import bench_video

    from pinrecon.io.calibration import load_cameras

    video = datasets.fetch(f"{TRIAL}/videos/cam{cam:02d}.mp4")
    tr, _ = bench_video.tracked(video, False)
    if not cues:
        tr = pr.Tracks(tr.points, tr.names, tr.fps, tr.confidence, tr.source, tr.layout)
    import cv2

    cap = cv2.VideoCapture(str(video))
    size = (int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
    cap.release()
    true_cam = load_cameras(datasets.fetch(f"{TRIAL}/calibration/Calib_qualisys.toml"))[cam - 1].camera
    return tr, size, bench_video.truth(), true_cam


def _cpu() -> float:
    """CPU seconds of this process and of its children that have ended (the solves forked beside it)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def run(case, **kwargs) -> dict:
    tracks, size, P_true, cam = case
    t0, c0 = time.perf_counter(), _cpu()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct(pr.Figure.human(), tracks, "auto", image_size=size, **kwargs)
    dt, cpu = time.perf_counter() - t0, _cpu() - c0
    P = in_true_world(res.keypoints3d[:, res.figure.keypoint_index(COCO12)], res.cameras[0], cam)
    ok = np.isfinite(P_true).all(axis=(1, 2))
    segs = [(COCO12.index(a), COCO12.index(b)) for a, b in SEGMENTS]
    return {"fps": tracks.T / dt, "cpu_fps": tracks.T / cpu, "time": dt, "pa": metrics.pa_mpjpe(P[ok], P_true[ok]),
            "flips": 100.0 * metrics.flip_rate(P[ok], P_true[ok], cam, segs), "stages": res.stages, "result": res}


def changed(report) -> bool:
    return not str(report.changed).startswith(("skipped", "nothing kept", "focal length at the bottom"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clips", nargs="*", default=["walk", "run", "dance", "spin", "real"])
    ap.add_argument("--frames", type=int, default=150, help="frames of the synthetic clips (0: all)")
    ap.add_argument("--cam", type=int, default=1, help="the real trial's camera (1-4)")
    ap.add_argument("--cues", nargs="*", choices=["cues", "none"], default=["cues", "none"])
    ap.add_argument("--no-ablate", dest="ablate", action="store_false", help="no runs with a stage switched off")
    ap.add_argument("--variants", nargs="*", choices=["rest", "nolengths"], default=[])
    a = ap.parse_args(argv)
    from provenance import provenance

    print(provenance())
    print("command: python bench/bench_stages.py " + " ".join(argv if argv is not None else sys.argv[1:]))
    print(f"\nthe default monocular path (Figure.human(), camera 'auto', no keyframes); synthetic clips "
          f"{a.frames or 'all'} frames; real: Pose2Sim camera {a.cam}\n")
    names = list(STAGES)
    print("| clip | lifted cues | frames/s (wall / CPU) | PA-MPJPE (mm) | flips (%) | "
          + " | ".join(f"{n}: s / PA off / flips off" for n in names) + " |")
    print("|---|---|---:|---:|---:|" + "---|" * len(names), flush=True)
    for clip in a.clips:
        for cue in a.cues:
            case = real_case(a.cam, cue == "cues") if clip == "real" else synthetic_case(clip, a.frames, cue == "cues")
            base = run(case)
            cells = []
            for rep in base["stages"]:
                if rep.name == "solve" or not a.ablate or not changed(rep):
                    off = "" if rep.name == "solve" else (" / =" if changed(rep) is False else " / -")
                    cells.append(f"{rep.seconds:.1f}{off}")
                    continue
                m = run(case, skip=(rep.name,))
                cells.append(f"{rep.seconds:.1f} / {m['pa']:.1f} / {m['flips']:.1f}")
            print(f"| {NAMES[clip]} | {cue} | {base['fps']:.1f} / {base['cpu_fps']:.1f} | {base['pa']:.1f} | {base['flips']:.1f} | "
                  + " | ".join(cells) + " |", flush=True)
            for v in a.variants:
                kw = {"seed": "rest"} if v == "rest" else {"lengths_from_tracks": False}
                m = run(case, **kw)
                print(f"| {NAMES[clip]} ({v}) | {cue} | {m['fps']:.1f} / {m['cpu_fps']:.1f} | {m['pa']:.1f} | {m['flips']:.1f} | "
                      + " | ".join(f"{r.seconds:.1f}" for r in m["stages"]) + " |", flush=True)
    print("\n'=': the stage changed nothing (switched off, the result is the same); "
          "'-': not run again (--no-ablate)")


if __name__ == "__main__":
    main()
