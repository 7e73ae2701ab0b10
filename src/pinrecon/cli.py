"""The ``pinrecon`` command line. Thin: parses arguments and calls the Python API."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from .arguments import (
    add_pose_prior_argument,
    add_reconstruct_options,
    detector_options,
    figure_from_args,
    pose_prior_weights,  # noqa: F401 - part of the command line's face (workbench, tests)
    reconstruct_from_args,
    weights_kwargs,
)
from .commands import SolveProgress
from .errors import InputError, PinreconError

__all__ = ["main"]

#: what --tracks reads (docs/formats.md)
TRACKS_HELP = ("2D tracks: pinrecon tracks JSON/NPZ, an OpenPose folder of per-frame JSON (BODY_25, BODY_25B, "
               "COCO-18), COCO keypoint annotations or results JSON, AlphaPose results JSON, MMPose / RTMPose "
               "inferencer or demo JSON (COCO-17, Halpe-26/136, CrowdPose-14, H36M-17)")


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"pinrecon: warning: {message}", file=sys.stderr)


def cmd_reconstruct(args) -> int:
    outs = _outputs(args)
    progress = SolveProgress(args.quiet, args.max_iterations)
    res = reconstruct_from_args(args, callback=progress)
    progress.close()
    return _save_and_report(res, args, outs)


def _outputs(args):
    """Every file the command will write (``--out``, ``--save-figure`` and its keypoint map,
    ``--save-camera``), checked writable before the work (:class:`pinrecon.io.atomic.Outputs`)."""
    from .io.atomic import Outputs

    outs = Outputs(fields={"--out": args.out, "--save-figure": args.save_figure,
                           "--save-camera": getattr(args, "save_camera", None)})
    if args.save_figure:
        p = Path(args.save_figure)
        outs.add(p.with_name(p.stem + ".keypoints.json"), field="--save-figure")
    outs.check()
    return outs


def _save_and_report(res, args, outs) -> int:
    """Write the result (``--out``), the fitted figure (``--save-figure``) and, where the
    command has it, the camera (``--save-camera``), all or none (``outs.commit()``); then the
    summary and the files written, on stdout."""
    with outs.commit():
        res.save(args.out)
        written = [args.out]
        if args.save_figure:
            written += res.save_figure(args.save_figure)
        if getattr(args, "save_camera", None):
            written += _save_cameras(res, args.save_camera)
    print(res.summary())  # the command's output: on stdout, also with --quiet (which silences progress only)
    for path in written:
        print(f"wrote {path}")
    return 0


def cmd_fit_markers(args) -> int:
    from .io.trc import POSE2SIM_AMBIGUOUS, load_trc
    from .problem import Weights
    from .reconstruct import reconstruct_markers
    from .solver import SolverOptions
    from .tracks import Markers, load_keyframes

    outs = _outputs(args)
    markers = load_trc(args.markers, up=args.up, names="pinrecon")
    unsure = [n for n in markers.names if n in POSE2SIM_AMBIGUOUS]
    if unsure:  # said, not guessed: which point they are depends on the skeleton that wrote them
        warnings.warn(f"markers {', '.join(unsure)} not used: in Pose2Sim's files their point depends on the "
                      "skeleton (Neck is the top of the neck in HALPE_26 and BODY_25B, the shoulders' midpoint in "
                      "BODY_25); rename them in the file to use them", stacklevel=2)
        keep = [i for i, n in enumerate(markers.names) if n not in POSE2SIM_AMBIGUOUS]
        markers = Markers(markers.points[:, keep], [markers.names[i] for i in keep], markers.fps, markers.source)
    fig = figure_from_args(args, [markers])  # 'human': the bundled map carrying most of the markers' names
    kf = load_keyframes(args.keyframes) if args.keyframes else None
    progress = SolveProgress(args.quiet, args.max_iterations)
    res = reconstruct_markers(fig, markers, kf, fps_out=args.fps_out, weights=Weights(sigma_markers_m=args.sigma_m),
                              options=SolverOptions(max_iterations=args.max_iterations), callback=progress,
                              calibrate=args.calibrate)
    progress.close()
    return _save_and_report(res, args, outs)


def _save_cameras(res, path) -> list[str]:
    """``--save-camera``: the (fitted) camera as a pinrecon camera JSON; with several
    cameras, one file per camera (``<stem>_<name>.json``)."""
    path = Path(path)
    if len(res.cameras) <= 1:
        res.camera.save(path)
        return [str(path)]
    out = []
    for name, cam in zip(res.camera_names, res.cameras):
        p = path.with_name(f"{path.stem}_{name}{path.suffix or '.json'}")
        cam.save(p)
        out.append(str(p))
    return out


def cmd_demo(args) -> int:
    from .datasets import clip, source
    from .demo import run_demo
    from .io.atomic import Outputs

    outs = Outputs()
    outs.add_folder(args.out, field="--out")
    outs.check()  # before the solve; the demo reads back what it writes, so its files are not staged
    if not args.quiet:
        print(f"pinrecon demo: data from {source()}", file=sys.stderr)
    clip("walk")  # fetched (with a progress bar) before the work, or one clear error
    progress = SolveProgress(args.quiet, 100)
    if not args.quiet:
        print(f"pinrecon demo: reconstructing the bundled CMU walk into {args.out}/ (the lab setting, then your "
              "video: detector output, the generic human, no keyframes)", file=sys.stderr)
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
        if summary.video:
            print(f"and your video's (no keyframes) with:\n  pinrecon reconstruct --figure human "
                  f"--tracks {args.out}/your_video/tracks.json --camera {args.out}/your_video/camera.json "
                  f"--out {args.out}/your_video/result2.npz", file=sys.stderr)
    return 0


def _bundled_walk() -> str:
    from ._resources import bundled_clip

    return str(bundled_clip("walk"))


def cmd_plot(args) -> int:
    from .io.atomic import Outputs
    from .viz import plot_result

    outs = Outputs()
    outs.add_folder(args.out, field="--out")
    outs.check()
    result, overlays = _overlay_videos(args)  # every video readable before any drawing
    with outs.commit():
        files = plot_result(
            result,
            args.out,
            truth=args.truth,
            tracks=args.tracks,
            animation=not args.no_animation,
            truth_length_scale=args.truth_length_scale,
            truth_skip_frames=args.truth_skip_frames,
            tracks_fps=args.fps,
        )
        if overlays:
            from .tracks import load_tracks
            from .viz.overlay import write_overlay

            tracks = load_tracks(args.tracks, fps=args.fps) if args.tracks and len(overlays) == 1 else None
            files += [write_overlay(result, v, Path(args.out) / name, camera_index=i, tracks=tracks)
                      for i, (v, name) in enumerate(overlays)]
    for f in files:
        print(f)
    return 0


def _overlay_videos(args):
    """``pinrecon plot --video``: ``(result, [(video, overlay file name)])``, the videos in the
    result's camera order, each checked readable (the optional video extra); the result's path
    and no videos without ``--video``."""
    if not args.video:
        return args.result, []
    from .commands.video import per_video_names
    from .result import load_result
    from .video import video_info

    res = load_result(args.result)
    cams = [c for c in (res.cameras or [res.camera]) if c is not None]
    if len(args.video) > len(cams):
        raise InputError(f"{len(args.video)} video(s) for a result of {len(cams)} camera(s): give one per camera, "
                         "in the result's camera order", field="--video")
    for v in args.video:
        video_info(v)
    return res, list(zip(args.video, per_video_names(args.video, "overlay", ".mp4")))


def cmd_export(args) -> int:
    from .io.atomic import Outputs
    from .io.bvh_export import export_result

    html = getattr(args, "html", None)
    if not (args.bvh or args.csv or args.trc or html):
        print("pinrecon export: nothing to do: give --bvh, --csv and/or --trc", file=sys.stderr)
        return 2
    outs = Outputs(fields={"--bvh": args.bvh, "--csv": args.csv, "--trc": args.trc, "--html": html})
    outs.check()
    written = []
    with outs.commit():
        if html:
            from .workbench.html_export import export_html

            written.append(export_html(args.result, html))
        if args.bvh or args.csv or args.trc:
            written += export_result(args.result, bvh=args.bvh, csv=args.csv, ground=not args.as_reconstructed,
                                     up=args.up, units=None if args.units == "own" else args.units,
                                     facing=args.facing, trc=args.trc, trc_names=args.trc_names)
    for f in written:
        print(f)
    return 0


def cmd_edit(args) -> int:
    from .workbench.app import edit_from_args

    figure = (lambda tracks: figure_from_args(args, [tracks])) if args.figure else None
    return edit_from_args(args, figure, weights=weights_kwargs(args, ("sigma_px", "loss")))


def cmd_links(args) -> int:
    from .io.calibration import load_camera
    from .planarity import links_report
    from .tracks import load_tracks

    tracks = load_tracks(args.tracks, fps=args.fps, person=args.person, layout=args.layout)
    scale = args.scale
    if scale is None and args.camera:
        cam = load_camera(args.camera)
        scale = getattr(cam, "scale", None)
    print(links_report(tracks, scale=scale, names=args.names, all=args.all))
    return 0


def _tracks_option(r) -> None:
    r.add_argument(
        "--tracks", required=True, action="append",
        help=TRACKS_HELP + "; repeat it for several cameras (one per camera, "
        "in the cameras' order; every camera's tracks start at the same instant)",
    )


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    p = argparse.ArgumentParser(
        prog="pinrecon",
        description="Reconstruct 3D figure motion from 2D joint tracks seen by one or more cameras.",
    )
    p.add_argument("--version", action="version", version=f"pinrecon {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    from .commands import register_all

    register_all(sub)

    r = sub.add_parser("reconstruct", help="batch-reconstruct a motion from 2D tracks")
    add_reconstruct_options(r, inputs=_tracks_option)
    r.add_argument("--save-camera", metavar="FILE.json",
                   help="write the (fitted) camera as a pinrecon camera JSON, for reuse with --camera FILE.json")
    r.add_argument("--save-figure", metavar="FILE.urdf",
                   help="write the (calibrated) figure's URDF there and its keypoint map next to it "
                   "(FILE.keypoints.json), for reuse with --figure FILE.urdf --keypoints FILE.keypoints.json")
    r.add_argument("--stability", type=int, metavar="N",
                   help="solve again on N copies of the tracks with 1 %% of the detections left out at random and "
                   "report where the 3D points move by more than 30 mm (N more solves; pinrecon.stability)")
    r.add_argument("--jobs", type=int, default=None, metavar="J",
                   help="with --stability, solve J copies at once in separate processes (-1: one per CPU; "
                   "default one after another)")
    r.add_argument("--out", required=True, help="result NPZ")
    r.add_argument("--quiet", action="store_true", help="no progress output (the summary and warnings are still shown)")
    r.set_defaults(func=cmd_reconstruct)

    d = sub.add_parser("demo", help="reconstruct the bundled CMU walk and write results, plots and exports")
    d.add_argument("--out", default="pinrecon-demo", help="output folder (default: ./pinrecon-demo)")
    d.add_argument("--frames", type=int, help="use only the first N frames (quicker)")
    d.add_argument("--no-pictures", action="store_true", help="skip the plots and the animation")
    d.add_argument("--quiet", action="store_true", help="no progress output (the summary and warnings are still shown)")
    d.set_defaults(func=cmd_demo)

    pl = sub.add_parser("plot", help="draw the pictures of a result NPZ")
    pl.add_argument("result", help="result NPZ")
    pl.add_argument("--out", required=True, help="output folder")
    pl.add_argument("--truth", help="ground truth: a result NPZ or a BVH file")
    pl.add_argument("--truth-length-scale", type=float, help="metres per unit of a truth BVH (default: the result's)")
    pl.add_argument("--truth-skip-frames", type=int, default=0, help="frames to drop at the truth's start (1 for CMU)")
    pl.add_argument("--tracks", help="the 2D tracks, to draw the reprojection over them")
    pl.add_argument("--no-animation", action="store_true", help="skip the GIF")
    pl.add_argument("--fps", type=float, help="frame rate of --tracks that carry none (OpenPose folder, COCO JSON)")
    pl.add_argument("--video", nargs="+", metavar="VIDEO",
                    help="the video(s) the result was made from (one per camera, in the result's order): also write "
                    "the overlay video, the skeleton over its frames and a side view (overlay.mp4; the optional video "
                    "extra), with --tracks drawn as rings")
    pl.set_defaults(func=cmd_plot)

    e = sub.add_parser("export", help="export a result NPZ as BVH, CSV and/or TRC")
    e.add_argument("result", help="result NPZ")
    e.add_argument("--bvh", help="output BVH file")
    e.add_argument("--csv", help="output CSV file (time, root pose, joint angles in degrees)")
    e.add_argument("--trc", help="output TRC file (OpenSim's marker format: the 3D keypoints in metres)")
    e.add_argument("--trc-names", default="file", choices=["file", "pose2sim"],
                   help="TRC marker names: the figure's keypoint names (default) or Pose2Sim's (RShoulder, LKnee, "
                   "...) where they mean the same point, for Pose2Sim's OpenSim models")
    e.add_argument("--up", default="y", choices=["y", "z"], help="up axis of the exported world (default y, BVH's)")
    e.add_argument("--units", default="m", choices=["m", "cm", "mm", "own"],
                   help="BVH length unit (default m; 'own': the figure's, e.g. CMU units)")
    e.add_argument("--facing", help="axis the figure faces on the first frame, e.g. --facing=-x (default +z with y up, -y with z up; "
                   "'' keeps the heading)")
    e.add_argument("--as-reconstructed", action="store_true",
                   help="keep the reconstruction's world (default: floor at height zero, root start over the origin)")
    e.add_argument("--html", help="output HTML file: a self-contained player of the 3D motion (offline)")
    e.set_defaults(func=cmd_export)

    ed = sub.add_parser("edit", help="the workbench in the browser: look, correct with keyframes, re-solve, save")
    ed.add_argument("--figure", help="'human', a URDF file, or a BVH file (default: the --result's own figure)")
    ed.add_argument("--keypoints", help="keypoint map JSON (for 'human': coco17 or joints)")
    ed.add_argument("--length-scale", type=float, default=1.0, help="metres per BVH unit (CMU: 0.056444)")
    ed.add_argument("--lock", nargs="*", help="BVH joints to weld (zero rotation)")
    ed.add_argument("--tracks", required=True, help=TRACKS_HELP)
    detector_options(ed)
    ed.add_argument("--fps", type=float, help="frame rate of OpenPose/COCO tracks")
    ed.add_argument("--camera", help="a calibration file, or 'auto' / 'auto:orthographic' as for reconstruct "
                    "(default: the --result's own camera)")
    ed.add_argument("--image-size", type=float, nargs=2, metavar=("W", "H"), help="image size, for --camera auto")
    ed.add_argument("--fov", type=float, help="starting horizontal field of view of --camera auto, degrees")
    ed.add_argument("--keyframes", help="keyframes JSON to start from")
    ed.add_argument("--result", help="result NPZ to start from (default: solve once first)")
    ed.add_argument("--fps-out", type=float, help="reconstruction rate (integer multiple of the tracks' rate)")
    ed.add_argument("--sigma-px", type=float, help="2D noise, pixels (default 2)")
    ed.add_argument("--loss", choices=["auto", "l2", "huber", "cauchy"],
                    help="measurement loss (default auto, as for reconstruct)")
    add_pose_prior_argument(ed)
    ed.add_argument("--floor", help="feet on the ground in the whole re-solves, as for reconstruct ('auto', "
                    "'none', a plane; default: reconstruct's, on for --figure human)")
    ed.add_argument("--out", default="pinrecon-edit", help="folder for saves and exports (default ./pinrecon-edit)")
    ed.add_argument("--keyframes-out", help="where Save writes the keyframes (default OUT/keyframes.json)")
    ed.add_argument("--result-out", help="where Save writes the result (default OUT/result.npz)")
    ed.add_argument("--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1)")
    ed.add_argument("--port", type=int, default=8080, help="port (default 8080)")
    ed.add_argument("--no-browser", action="store_true", help="do not open a browser (servers)")
    ed.set_defaults(func=cmd_edit)

    fm = sub.add_parser("fit-markers", help="fit a figure to 3D markers (a TRC file: OpenSim, Pose2Sim's "
                        "triangulation), smoothing them and filling their gaps")
    fm.add_argument("--markers", required=True, help="TRC file (metres, centimetres or millimetres)")
    fm.add_argument("--up", default="y", choices=["x", "y", "z"], help="the file's up axis (default y, OpenSim's)")
    fm.add_argument("--figure", required=True, help="'human', a URDF file, or a BVH file (its skeleton)")
    fm.add_argument("--keypoints", help="keypoint map JSON, or for 'human' a bundled map (default: the map carrying "
                    "most of the markers' names, Pose2Sim's renamed: RShoulder is right_shoulder)")
    fm.add_argument("--length-scale", type=float, default=1.0, help="metres per BVH unit (CMU: 0.056444)")
    fm.add_argument("--lock", nargs="*", help="BVH joints to weld (zero rotation)")
    fm.add_argument("--limits", help="joint limits JSON, or a CMU ASF skeleton")
    fm.add_argument("--keyframes", help="keyframes JSON")
    fm.add_argument("--fps-out", type=float, help="reconstruction rate (integer multiple of the markers' rate)")
    fm.add_argument("--calibrate", choices=["none", "lengths"],
                    help="fit the figure's segment lengths to the markers too (default: lengths for 'human', "
                    "none for other figures)")
    fm.add_argument("--sigma-m", type=float, default=0.01, help="marker noise, metres (default 0.01)")
    fm.add_argument("--max-iterations", type=int, default=100)
    fm.add_argument("--save-figure", metavar="FILE.urdf", help="write the (fitted) figure's URDF and keypoint map")
    fm.add_argument("--out", required=True, help="result NPZ")
    fm.add_argument("--quiet", action="store_true", help="no progress output (the summary and warnings are still shown)")
    fm.set_defaults(func=cmd_fit_markers)

    li = sub.add_parser("links", help="discover rigid links and hinges in 2D tracks (planarity)")
    li.add_argument("tracks", help=TRACKS_HELP)
    li.add_argument("--fps", type=float, help="frame rate of OpenPose/COCO tracks")
    detector_options(li)
    li.add_argument("--quiet", action="store_true", help="no progress output (the command has none; warnings are "
                    "still shown)")
    li.add_argument("--camera", help="orthographic camera JSON, to give lengths in metres")
    li.add_argument("--scale", type=float, help="pixels per metre, to give lengths in metres")
    li.add_argument("--names", nargs="*", help="only these tracked points")
    li.add_argument("--all", action="store_true", help="list every passing triple and link")
    li.set_defaults(func=cmd_links)
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning  # also with --quiet: it silences progress only
        try:
            return args.func(args)
        except PinreconError as exc:
            print(f"pinrecon: error: {exc}", file=sys.stderr)
            return 2
        except OSError as exc:  # a file system refusal while writing (disk full ...): one line, no traceback
            where = f"{exc.filename}: " if exc.filename else ""
            print(f"pinrecon: error: {where}{exc.strerror or exc}", file=sys.stderr)
            return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
