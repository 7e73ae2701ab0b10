"""The ``pinrecon`` command line. Thin: parses arguments and calls the Python API."""

from __future__ import annotations

import argparse
import sys
import time

from .errors import PinreconError

__all__ = ["main"]


def _figure_from_args(args):
    from .figure import Figure

    spec = args.figure
    if spec == "human":
        fig = Figure.human(args.keypoints or "coco17")
    elif spec.lower().endswith(".bvh"):
        fig = Figure.from_bvh(spec, args.length_scale, lock=args.lock or ())
        if args.keypoints:
            fig = fig.with_keypoints(args.keypoints)
    else:
        fig = Figure.from_urdf(spec, args.keypoints)
    return fig


class _Progress:
    """Solver progress on stderr: a live line on a terminal, one line per 10 iterations
    (and every rejected step) when stderr is a file or a pipe."""

    def __init__(self, quiet: bool, max_iterations: int):
        self.quiet = quiet
        self.max = max_iterations
        self.t0 = time.perf_counter()
        self.tty = sys.stderr.isatty()
        self.dirty = False

    def __call__(self, rep):
        if self.quiet:
            return None
        line = (
            f"iter {rep.iteration:3d}/{self.max}  cost {rep.cost:.6g}  |dx| {rep.step_norm:.2g}  "
            f"{time.perf_counter() - self.t0:5.1f}s"
        )
        if not rep.accepted:
            line += f"  (rejected: {rep.message})"
        if self.tty:
            print("\r" + line.ljust(78), end="", file=sys.stderr, flush=True)
            self.dirty = True
        elif not rep.accepted or rep.iteration % 10 == 0 or rep.iteration == 1:
            print(line, file=sys.stderr, flush=True)
        return None

    def close(self):
        if not self.quiet and self.dirty:
            print(file=sys.stderr)
            self.dirty = False


def cmd_reconstruct(args) -> int:
    from .cameras import load_camera
    from .problem import Weights
    from .reconstruct import reconstruct
    from .solver import SolverOptions
    from .tracks import load_keyframes, load_tracks

    fig = _figure_from_args(args)
    tracks = load_tracks(args.tracks, fps=args.fps)
    cam = load_camera(args.camera)
    kf = load_keyframes(args.keyframes) if args.keyframes else None
    wkw = {k: getattr(args, k) for k in ("sigma_px", "acc_root_translation", "acc_root_rotation", "acc_joints", "sigma_limits", "loss") if getattr(args, k, None) is not None}
    opts = SolverOptions(max_iterations=args.max_iterations)
    progress = _Progress(args.quiet, args.max_iterations)
    res = reconstruct(
        fig, tracks, cam, kf, fps_out=args.fps_out, weights=Weights(**wkw), options=opts, callback=progress, seed=args.seed
    )
    progress.close()
    res.save(args.out)
    if not args.quiet:
        print(res.summary(), file=sys.stderr)
        print(f"wrote {args.out}", file=sys.stderr)
    return 0


def cmd_demo(args) -> int:
    from .demo import run_demo

    progress = _Progress(args.quiet, 100)
    if not args.quiet:
        print(f"pinrecon demo: reconstructing the bundled CMU walk into {args.out}/", file=sys.stderr)
    summary = run_demo(args.out, frames=args.frames, pictures=not args.no_pictures, callback=progress)
    progress.close()
    print(summary.table())
    if summary.note:
        print(f"pinrecon demo: {summary.note}", file=sys.stderr)
    if not args.quiet:
        print(f"\nwrote {len(summary.files)} files to {args.out}/:", file=sys.stderr)
        for f in summary.files:
            print(f"  {f.name}", file=sys.stderr)
        print(
            f"repeat the reconstruction from those files with:\n  pinrecon reconstruct --figure "
            f"{_bundled_walk()} --length-scale 0.056444 --lock LHipJoint RHipJoint LeftShoulder RightShoulder "
            f"--tracks {args.out}/tracks.json --camera {args.out}/camera.json --keyframes {args.out}/keyframes.json "
            f"--out {args.out}/result2.npz",
            file=sys.stderr,
        )
    return 0


def _bundled_walk() -> str:
    from ._resources import bundled_clip

    return str(bundled_clip("walk"))


def cmd_plot(args) -> int:
    from .viz import plot_result

    files = plot_result(
        args.result,
        args.out,
        truth=args.truth,
        tracks=args.tracks,
        animation=not args.no_animation,
        truth_length_scale=args.truth_length_scale,
        truth_skip_frames=args.truth_skip_frames,
    )
    for f in files:
        print(f)
    return 0


def cmd_export(args) -> int:
    from .io.bvh_export import export_result

    if not (args.bvh or args.csv):
        print("pinrecon export: nothing to do: give --bvh and/or --csv", file=sys.stderr)
        return 2
    for f in export_result(args.result, bvh=args.bvh, csv=args.csv):
        print(f)
    return 0


def cmd_links(args) -> int:
    from .cameras import load_camera
    from .planarity import links_report
    from .tracks import load_tracks

    tracks = load_tracks(args.tracks, fps=args.fps)
    scale = args.scale
    if scale is None and args.camera:
        cam = load_camera(args.camera)
        scale = getattr(cam, "scale", None)
    print(links_report(tracks, scale=scale, names=args.names, all=args.all))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="pinrecon",
        description="Reconstruct 3D figure motion from 2D joint tracks seen by one camera.",
    )
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("reconstruct", help="batch-reconstruct a motion from 2D tracks")
    r.add_argument("--figure", required=True, help="'human', a URDF file, or a BVH file (its skeleton)")
    r.add_argument("--keypoints", help="keypoint map JSON (for 'human': coco17 or joints)")
    r.add_argument("--length-scale", type=float, default=1.0, help="metres per BVH unit (CMU: 0.056444)")
    r.add_argument("--lock", nargs="*", help="BVH joints to weld (zero rotation)")
    r.add_argument("--tracks", required=True, help="tracks JSON/NPZ, OpenPose folder or COCO JSON")
    r.add_argument("--fps", type=float, help="frame rate of OpenPose/COCO tracks")
    r.add_argument("--camera", required=True, help="camera JSON")
    r.add_argument("--keyframes", help="keyframes JSON")
    r.add_argument("--fps-out", type=float, help="reconstruction rate (integer multiple of the tracks' rate)")
    r.add_argument("--seed", choices=["planarity"], help="start from the planarity seed")
    r.add_argument("--sigma-px", type=float, help="2D noise, pixels (default 2)")
    r.add_argument("--loss", choices=["l2", "huber", "cauchy"], help="measurement loss (default l2)")
    r.add_argument("--acc-root-translation", type=float, help="smoothing: root acceleration sd, m/s^2")
    r.add_argument("--acc-root-rotation", type=float, help="smoothing: root angular acceleration sd, rad/s^2")
    r.add_argument("--acc-joints", type=float, help="smoothing: joint acceleration sd, rad/s^2")
    r.add_argument("--sigma-limits", type=float, help="joint-limit barrier sd, rad")
    r.add_argument("--max-iterations", type=int, default=100)
    r.add_argument("--out", required=True, help="result NPZ")
    r.add_argument("--quiet", action="store_true", help="no progress output")
    r.set_defaults(func=cmd_reconstruct)

    d = sub.add_parser("demo", help="reconstruct the bundled CMU walk and write results, plots and exports")
    d.add_argument("--out", default="pinrecon-demo", help="output folder (default: ./pinrecon-demo)")
    d.add_argument("--frames", type=int, help="use only the first N frames (quicker)")
    d.add_argument("--no-pictures", action="store_true", help="skip the plots and the animation")
    d.add_argument("--quiet", action="store_true", help="no progress output")
    d.set_defaults(func=cmd_demo)

    pl = sub.add_parser("plot", help="draw the pictures of a result NPZ")
    pl.add_argument("result", help="result NPZ")
    pl.add_argument("--out", required=True, help="output folder")
    pl.add_argument("--truth", help="ground truth: a result NPZ or a BVH file")
    pl.add_argument("--truth-length-scale", type=float, help="metres per unit of a truth BVH (default: the result's)")
    pl.add_argument("--truth-skip-frames", type=int, default=0, help="frames to drop at the truth's start (1 for CMU)")
    pl.add_argument("--tracks", help="the 2D tracks, to draw the reprojection over them")
    pl.add_argument("--no-animation", action="store_true", help="skip the GIF")
    pl.set_defaults(func=cmd_plot)

    e = sub.add_parser("export", help="export a result NPZ as BVH and/or CSV")
    e.add_argument("result", help="result NPZ")
    e.add_argument("--bvh", help="output BVH file")
    e.add_argument("--csv", help="output CSV file (time, root pose, joint angles in degrees)")
    e.set_defaults(func=cmd_export)

    li = sub.add_parser("links", help="discover rigid links and hinges in 2D tracks (planarity)")
    li.add_argument("tracks", help="tracks JSON/NPZ, OpenPose folder or COCO JSON")
    li.add_argument("--fps", type=float, help="frame rate of OpenPose/COCO tracks")
    li.add_argument("--camera", help="orthographic camera JSON, to give lengths in metres")
    li.add_argument("--scale", type=float, help="pixels per metre, to give lengths in metres")
    li.add_argument("--names", nargs="*", help="only these tracked points")
    li.add_argument("--all", action="store_true", help="list every passing triple and link")
    li.set_defaults(func=cmd_links)
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except PinreconError as exc:
        print(f"pinrecon: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
