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
    """One line per iteration on stderr (the CLI's progress display)."""

    def __init__(self, quiet: bool, max_iterations: int):
        self.quiet = quiet
        self.max = max_iterations
        self.t0 = time.perf_counter()

    def __call__(self, rep):
        if self.quiet:
            return None
        width = 24
        done = int(width * min(rep.iteration, self.max) / self.max)
        bar = "#" * done + "." * (width - done)
        flag = "" if rep.accepted else f"  (rejected: {rep.message})"
        print(
            f"\r[{bar}] iter {rep.iteration:3d}  cost {rep.cost:.6g}  |dx| {rep.step_norm:.2g}  "
            f"{time.perf_counter() - self.t0:5.1f}s{flag}",
            file=sys.stderr,
            end="\n" if not rep.accepted else "",
            flush=True,
        )
        return None

    def close(self):
        if not self.quiet:
            print(file=sys.stderr)


def cmd_reconstruct(args) -> int:
    from .cameras import load_camera
    from .reconstruct import Weights, reconstruct
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
