"""The ``pinrecon`` command line. Thin: parses arguments and calls the Python API."""

from __future__ import annotations

import argparse
import sys
import time
import warnings

from .errors import PinreconError

__all__ = ["main"]


def _figure_from_args(args, tracks=None):
    from pathlib import Path

    from .errors import InputError
    from .figure import Figure
    from .layouts import human_keypoint_maps

    spec = args.figure
    if spec == "human":
        fig = Figure.human(args.keypoints) if args.keypoints else Figure.human("auto", tracks=tracks or [])
    elif spec.lower().endswith(".bvh") or spec.lower().endswith(".urdf") or Path(spec).is_file():
        if args.keypoints and not Path(args.keypoints).is_file():
            raise InputError(
                f"no such keypoint-map file {args.keypoints!r} (the bundled maps "
                f"{', '.join(human_keypoint_maps())} are for --figure human)",
                field="--keypoints",
            )
        if spec.lower().endswith(".bvh"):
            fig = Figure.from_bvh(spec, args.length_scale, lock=args.lock or ())
            if args.keypoints:
                fig = fig.with_keypoints(args.keypoints)
        else:
            fig = Figure.from_urdf(spec, args.keypoints)
    else:
        hint = " (did you mean 'human'?)" if spec.lower() == "human" else ""
        raise InputError(
            f"{spec!r} is not 'human' and no such file{hint}: valid choices are 'human', a URDF file (.urdf) "
            "or a BVH file (.bvh)",
            field="--figure",
        )
    if getattr(args, "limits", None):
        fig = fig.with_limits(args.limits)
    return fig


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"pinrecon: warning: {message}", file=sys.stderr)


class _Progress:
    """Solver progress on stderr: a live line on a terminal, one line per 10 iterations
    (and every rejected step) when stderr is a file or a pipe."""

    def __init__(self, quiet: bool, max_iterations: int):
        self.quiet = quiet
        self.max = max_iterations
        self.t0 = time.perf_counter()
        self.tty = sys.stderr.isatty()
        self.dirty = False
        self.label = ""

    def stage(self, name: str):
        """A stage of :func:`pinrecon.reconstruct` starts (:mod:`pinrecon.stages`): one labelled line."""
        if self.quiet:
            return
        self.close()
        print(f"pinrecon: stage {name} ({time.perf_counter() - self.t0:.1f}s)", file=sys.stderr, flush=True)
        self.label = f"{name}: "

    def __call__(self, rep):
        if self.quiet:
            return None
        line = (
            f"{self.label}iter {rep.iteration:3d}/{self.max}  cost {rep.cost:.6g}  |dx| {rep.step_norm:.2g}  "
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

    def window(self, rep):
        """One solved window of a long clip (:class:`pinrecon.windowed.WindowReport`), with
        the time left at the pace so far."""
        if self.quiet:
            return
        elapsed = time.perf_counter() - self.t0
        left = elapsed / rep.index * (rep.count - rep.index)
        print(("\r" if self.tty else "") + f"{rep}  (elapsed {elapsed:.0f}s, about {left:.0f}s left)".ljust(78),
              file=sys.stderr, flush=True)
        self.dirty = False

    def close(self):
        if not self.quiet and self.dirty:
            print(file=sys.stderr)
            self.dirty = False


def _cameras_for_tracks(camera_files, tracks_files):
    """The cameras of every ``--camera`` file, in order (a file's cameras in the file's
    order), one per ``--tracks``; a mismatch is one clear error listing them."""
    from .errors import InputError
    from .io.calibration import load_cameras

    cams = [c for path in camera_files for c in load_cameras(path)]
    if len(cams) != len(tracks_files):
        listed = ", ".join(f"{c.name!r}" for c in cams)
        raise InputError(
            f"{len(tracks_files)} --tracks but the --camera files hold {len(cams)} cameras ({listed}): give one "
            "--tracks per camera, in this order",
            field="--camera",
        )
    return cams


def cmd_reconstruct(args) -> int:
    from .problem import Weights
    from .reconstruct import reconstruct
    from .solver import SolverOptions
    from .tracks import load_keyframes, load_tracks

    if args.stability is not None and args.stability < 1:
        from .errors import InputError

        raise InputError(f"must be a number of solves, at least 1; got {args.stability}", field="--stability")
    auto = _auto_camera_from_args(args)
    cams = [auto] if auto is not None else _cameras_for_tracks(args.camera, args.tracks)
    tracks = [load_tracks(path, fps=args.fps, person=args.person, layout=args.layout) for path in args.tracks]
    if args.lifted:
        tracks = _with_lifted(tracks, args)
    fig = _figure_from_args(args, tracks)
    if len(tracks) == 1:  # one camera: plain arguments, as the Python API takes them
        tracks, cam = tracks[0], cams[0]
    else:
        cam = cams
    kf = load_keyframes(args.keyframes) if args.keyframes else None
    wkw = _weights_kwargs(args, ("sigma_px", "acc_root_translation", "acc_root_rotation", "acc_joints", "sigma_limits",
                                 "loss"))
    opts = SolverOptions(max_iterations=args.max_iterations)
    progress = _Progress(args.quiet, args.max_iterations)
    kw = {"fps_out": args.fps_out, "weights": Weights(**wkw), "options": opts, "seed": args.seed,
          "calibrate": args.calibrate, "window": args.window, **_feet_from_args(args)}
    res = reconstruct(fig, tracks, cam, kf, callback=progress, skip=args.skip, progress=progress.stage, **kw)
    progress.close()
    if args.stability:
        from .stability import stability

        if not args.quiet:
            print(f"pinrecon: solving again on {args.stability} copies of the tracks with 1 % of the detections "
                  "left out (--stability)", file=sys.stderr)
        res.extras.update(stability(fig, tracks, cam, kf, result=res, runs=args.stability, n_jobs=args.jobs,
                                    **kw).to_extras())
    return _save_and_report(res, args)


def _with_lifted(tracks, args) -> list:
    """The tracks with the 3D cues of ``--lifted`` (one file per ``--tracks``, in order) attached."""
    from dataclasses import replace

    from .errors import InputError
    from .lifted import load_lifted

    if len(args.lifted) != len(tracks):
        raise InputError(f"{len(args.lifted)} --lifted for {len(tracks)} --tracks: give one per --tracks, in order",
                         field="--lifted")
    out = []
    for cam, (t, path) in enumerate(zip(tracks, args.lifted)):
        lf = load_lifted(path, fmt=args.lifted_format, layout=args.lifted_layout, frames=t.T, frame=args.lifted_frame)
        out.append(replace(t, lifted=replace(lf, camera=cam)))
    return out


def _save_and_report(res, args) -> int:
    """Write the result (``--out``), the fitted figure (``--save-figure``) and, where the
    command has it, the camera (``--save-camera``); then the summary and the files written,
    unless ``--quiet``."""
    res.save(args.out)
    written = [args.out]
    if args.save_figure:
        written += res.save_figure(args.save_figure)
    if getattr(args, "save_camera", None):
        written += _save_cameras(res, args.save_camera)
    if not args.quiet:
        print(res.summary(), file=sys.stderr)
        for path in written:
            print(f"wrote {path}", file=sys.stderr)
    return 0


def cmd_fit_markers(args) -> int:
    from .io.trc import POSE2SIM_AMBIGUOUS, load_trc
    from .problem import Weights
    from .reconstruct import reconstruct_markers
    from .solver import SolverOptions
    from .tracks import Markers, load_keyframes

    markers = load_trc(args.markers, up=args.up, names="pinrecon")
    unsure = [n for n in markers.names if n in POSE2SIM_AMBIGUOUS]
    if unsure:  # said, not guessed: which point they are depends on the skeleton that wrote them
        warnings.warn(f"markers {', '.join(unsure)} not used: in Pose2Sim's files their point depends on the "
                      "skeleton (Neck is the top of the neck in HALPE_26 and BODY_25B, the shoulders' midpoint in "
                      "BODY_25); rename them in the file to use them", stacklevel=2)
        keep = [i for i, n in enumerate(markers.names) if n not in POSE2SIM_AMBIGUOUS]
        markers = Markers(markers.points[:, keep], [markers.names[i] for i in keep], markers.fps, markers.source)
    fig = _figure_from_args(args, [markers])  # 'human': the bundled map carrying most of the markers' names
    kf = load_keyframes(args.keyframes) if args.keyframes else None
    progress = _Progress(args.quiet, args.max_iterations)
    res = reconstruct_markers(fig, markers, kf, fps_out=args.fps_out, weights=Weights(sigma_markers_m=args.sigma_m),
                              options=SolverOptions(max_iterations=args.max_iterations), callback=progress,
                              calibrate=args.calibrate)
    progress.close()
    return _save_and_report(res, args)


def _auto_camera_from_args(args):
    """The :class:`~pinrecon.starts.camera_auto.AutoCamera` of ``--camera auto`` (or
    ``auto:orthographic``), ``None`` for camera files; auto with several --tracks, or
    --image-size/--fov without auto, is one clear error."""
    from .errors import InputError
    from .starts.camera_auto import DEFAULT_FOV_DEG, AutoCamera

    specs = [c for c in args.camera if c.split(":")[0] == "auto"]
    if not specs:
        if args.image_size is not None or args.fov is not None:
            raise InputError("--image-size and --fov are for --camera auto", field="--camera")
        return None
    if len(args.camera) != 1 or len(args.tracks) != 1:
        raise InputError("--camera auto is for one --tracks and no other --camera", field="--camera")
    proj = specs[0].split(":", 1)[1] if ":" in specs[0] else "perspective"
    return AutoCamera(args.image_size, proj, DEFAULT_FOV_DEG if args.fov is None else args.fov)


def _save_cameras(res, path) -> list[str]:
    """``--save-camera``: the (fitted) camera as a pinrecon camera JSON; with several
    cameras, one file per camera (``<stem>_<name>.json``)."""
    from pathlib import Path

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


def _feet_from_args(args) -> dict:
    """``floor`` and ``contact`` for :func:`pinrecon.reconstruct` from ``--floor`` / ``--contact``."""
    floor, contact = getattr(args, "floor", None), getattr(args, "contact", None)
    if contact not in (None, "auto", "none"):
        from .io.jsonfile import read_json

        contact = read_json(contact)
        if not isinstance(contact, dict):
            from .errors import InputError

            raise InputError("expected an object {foot keypoint: [[first, last], ...]}", file=args.contact)
    elif contact == "none":
        contact = False
    return {"floor": floor, "contact": contact}


def cmd_demo(args) -> int:
    from .datasets import clip, source
    from .demo import run_demo

    if not args.quiet:
        print(f"pinrecon demo: data from {source()}", file=sys.stderr)
    clip("walk")  # fetched (with a progress bar) before the work, or one clear error
    progress = _Progress(args.quiet, 100)
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
    from .viz import plot_result

    files = plot_result(
        args.result,
        args.out,
        truth=args.truth,
        tracks=args.tracks,
        animation=not args.no_animation,
        truth_length_scale=args.truth_length_scale,
        truth_skip_frames=args.truth_skip_frames,
        tracks_fps=args.fps,
    )
    for f in files:
        print(f)
    return 0


def cmd_export(args) -> int:
    from .io.bvh_export import export_result

    if getattr(args, "html", None):
        from .workbench.html_export import export_html

        print(export_html(args.result, args.html))
        if not (args.bvh or args.csv or args.trc):
            return 0
    if not (args.bvh or args.csv or args.trc):
        print("pinrecon export: nothing to do: give --bvh, --csv and/or --trc", file=sys.stderr)
        return 2
    for f in export_result(args.result, bvh=args.bvh, csv=args.csv, ground=not args.as_reconstructed, up=args.up,
                           units=None if args.units == "own" else args.units, facing=args.facing, trc=args.trc,
                           trc_names=args.trc_names):
        print(f)
    return 0


def cmd_edit(args) -> int:
    from .workbench.app import edit_from_args

    return edit_from_args(args, _figure_from_args(args) if args.figure else None,
                          weights=_weights_kwargs(args, ("sigma_px", "loss")))


def cmd_links(args) -> int:
    from .cameras import load_camera
    from .planarity import links_report
    from .tracks import load_tracks

    tracks = load_tracks(args.tracks, fps=args.fps, person=args.person, layout=args.layout)
    scale = args.scale
    if scale is None and args.camera:
        cam = load_camera(args.camera)
        scale = getattr(cam, "scale", None)
    print(links_report(tracks, scale=scale, names=args.names, all=args.all))
    return 0


def _detector_options(parser) -> None:
    from .layouts import LAYOUTS

    parser.add_argument(
        "--layout",
        help="the detector's point layout: " + ", ".join(LAYOUTS) + " (default: from the file, or by geometry)",
    )
    parser.add_argument(
        "--person",
        help="who to follow in detector output with several people: an index in the first frame with people, "
        "a box x1,y1,x2,y2 around them in the first frame they appear, or 'largest' (each frame's most "
        "prominent person, no following); default: the most prominent person of the first frame",
    )


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="pinrecon",
        description="Reconstruct 3D figure motion from 2D joint tracks seen by one or more cameras.",
    )
    sub = p.add_subparsers(dest="command", required=True)
    from .commands import register_all

    register_all(sub)

    r = sub.add_parser("reconstruct", help="batch-reconstruct a motion from 2D tracks")
    r.add_argument("--figure", required=True, help="'human', a URDF file, or a BVH file (its skeleton)")
    r.add_argument(
        "--keypoints",
        help="keypoint map JSON, or for 'human' a bundled map: coco17, body25, body25b, halpe26, joints "
        "(default: the map of the tracks' detector layout)",
    )
    r.add_argument("--length-scale", type=float, default=1.0, help="metres per BVH unit (CMU: 0.056444)")
    r.add_argument("--lock", nargs="*", help="BVH joints to weld (zero rotation)")
    r.add_argument(
        "--tracks", required=True, action="append",
        help="tracks JSON/NPZ, OpenPose folder or COCO JSON; repeat it for several cameras (one per camera, "
        "in the cameras' order; every camera's tracks start at the same instant)",
    )
    r.add_argument("--fps", type=float, help="frame rate of OpenPose/COCO tracks")
    _detector_options(r)
    r.add_argument(
        "--camera", required=True, action="append",
        help="camera or calibration file: pinrecon camera JSON, Pose2Sim/Sports2D TOML, OpenCV YAML/XML/JSON; "
        "repeat it for several cameras. Cameras pair with --tracks in order: a file holding several cameras "
        "(a Pose2Sim TOML) gives them in the file's order, so give its cameras' --tracks in that order. "
        "'auto' (one --tracks, no calibration): a perspective camera with the principal point at the image "
        "centre (--image-size), the focal length from a 60 degree field of view (--fov) refined in the solve, "
        "the world placed at the camera unless point keyframes give its pose; 'auto:orthographic' likewise",
    )
    r.add_argument("--image-size", type=float, nargs=2, metavar=("W", "H"),
                   help="image width and height in pixels, for --camera auto")
    r.add_argument("--fov", type=float, help="starting horizontal field of view of --camera auto, degrees (default 60)")
    r.add_argument("--save-camera", metavar="FILE.json",
                   help="write the (fitted) camera as a pinrecon camera JSON, for reuse with --camera FILE.json")
    r.add_argument("--keyframes", help="keyframes JSON")
    r.add_argument("--lifted", action="append", metavar="FILE",
                   help="a lifter's 3D output of the same frames, as learned 3D cues: MotionBERT / VideoPose3D .npy, "
                   "MMPose 3D JSON (docs/formats.md, section 11); one per --tracks, in order")
    r.add_argument("--lifted-format", choices=["npy", "motionbert", "videopose3d", "mmpose3d"],
                   help="format of --lifted (default: from the suffix)")
    r.add_argument("--lifted-layout", help="joint order of --lifted (default h36m17)")
    r.add_argument("--lifted-frame", choices=["camera", "unknown"],
                   help="axes of --lifted: 'camera' (the lifters' own output) or 'unknown' (turned into other axes)")
    r.add_argument("--fps-out", type=float, help="reconstruction rate (integer multiple of the tracks' rate)")
    r.add_argument("--seed", choices=["auto", "rest", "keyframes", "planarity", "hypotheses"],
                   help="the start (default auto: the multi-hypothesis start when keyframes are absent or sparse, "
                   "the keyframe start when they are dense)")
    r.add_argument("--limits", help="joint limits to apply to the figure: a limits JSON, or a CMU ASF skeleton "
                   "(its limits onto a CMU BVH figure)")
    r.add_argument("--sigma-px", type=float, help="2D noise, pixels (default 2)")
    r.add_argument("--loss", choices=["auto", "l2", "huber", "cauchy"],
                   help="measurement loss (default auto: cauchy when the tracks carry confidences, else l2)")
    r.add_argument("--acc-root-translation", type=float, help="smoothing: root acceleration sd, m/s^2")
    r.add_argument("--acc-root-rotation", type=float, help="smoothing: root angular acceleration sd, rad/s^2")
    r.add_argument("--acc-joints", type=float, help="smoothing: joint acceleration sd, rad/s^2")
    r.add_argument("--sigma-limits", type=float, help="joint-limit barrier sd, rad")
    add_pose_prior_argument(r)
    r.add_argument("--max-iterations", type=int, default=100)
    r.add_argument("--skip", nargs="+", default=(), metavar="STAGE",
                   help="switch stages off by name: prior, turns, mirrors, faults, focal, feet (the start and the "
                   "solve always run; the summary lists every stage with its time and what it changed)")
    r.add_argument("--window", type=int, help="solve in overlapping windows of this many frames, in bounded memory "
                   "(default: windows of 2000 frames past 10000 frames; 0: one batch solve)")
    r.add_argument("--floor", help="feet on the ground: 'auto' (estimated under the feet; the default for "
                   "--figure human with a tracked ankle), 'none' (off), 'y=0' / 'z=0', or "
                   "'nx,ny,nz,d' (the plane n.p = d, n up); adds the contact rows (see --contact)")
    r.add_argument("--contact", help="foot contacts: 'auto' (from low height and speed; the default with --floor), "
                   "'none' (only keep feet above the floor), or a JSON file {foot keypoint: [[first, last], ...]} "
                   "of tracks frames")
    r.add_argument(
        "--calibrate", choices=["none", "lengths", "camera", "lengths+camera"],
        help="unknowns besides the motion: the figure's segment lengths (scale factors, 10 %% prior), the camera's "
        "focal length (or orthographic scale), or both (default: lengths for --figure human with 3D point "
        "keyframes or one given camera, the limb lengths then measured from the tracks first; else none; "
        "plus camera with --camera auto)",
    )
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
    pl.add_argument("--fps", type=float, help="frame rate of --tracks that carry none (OpenPose folder, COCO JSON)")
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
    ed.add_argument("--tracks", required=True, help="tracks JSON/NPZ, OpenPose folder or COCO JSON")
    ed.add_argument("--fps", type=float, help="frame rate of OpenPose/COCO tracks")
    ed.add_argument("--camera", required=True, help="camera JSON")
    ed.add_argument("--keyframes", help="keyframes JSON to start from")
    ed.add_argument("--result", help="result NPZ to start from (default: solve once first)")
    ed.add_argument("--fps-out", type=float, help="reconstruction rate (integer multiple of the tracks' rate)")
    ed.add_argument("--sigma-px", type=float, help="2D noise, pixels (default 2)")
    ed.add_argument("--loss", choices=["l2", "huber", "cauchy"], help="measurement loss (default l2)")
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
    fm.add_argument("--quiet", action="store_true", help="no progress output")
    fm.set_defaults(func=cmd_fit_markers)

    li = sub.add_parser("links", help="discover rigid links and hinges in 2D tracks (planarity)")
    li.add_argument("tracks", help="tracks JSON/NPZ, OpenPose folder or COCO JSON")
    li.add_argument("--fps", type=float, help="frame rate of OpenPose/COCO tracks")
    _detector_options(li)
    li.add_argument("--quiet", action="store_true", help="no warnings")
    li.add_argument("--camera", help="orthographic camera JSON, to give lengths in metres")
    li.add_argument("--scale", type=float, help="pixels per metre, to give lengths in metres")
    li.add_argument("--names", nargs="*", help="only these tracked points")
    li.add_argument("--all", action="store_true", help="list every passing triple and link")
    li.set_defaults(func=cmd_links)
    return p


def _pose_prior(text: str):
    if text.strip().lower() in ("none", "off"):
        return None
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number or 'none', got {text!r}") from None
    if not 0 < v < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive number or 'none', got {text!r}")
    return v


def add_pose_prior_argument(parser) -> None:
    parser.add_argument("--pose-prior", type=_pose_prior, default=argparse.SUPPRESS, metavar="SCALE|none",
                        help="the generic human's pose prior from motion capture (a joint Gaussian): its "
                        "standard deviations times SCALE (default 2), or none (a weak rest-pose prior, as "
                        "other figures)")
    parser.add_argument("--pose-prior-loss", choices=("huber", "cauchy"), default=argparse.SUPPRESS,
                        help="the pose prior's robust loss beyond a Mahalanobis distance of 2 (huber, the "
                        "default) or 3 (cauchy: better for motion unlike walking and running, such as dance, "
                        "with a given camera; worse for --camera auto's focal length)")
    parser.add_argument("--pose-prior-model", default=argparse.SUPPRESS, metavar="NAME|FILE",
                        help="which learned pose prior: auto (the default: the generic human's for --figure human, "
                        "solved again with its broader mixture when it does not know more than half of the "
                        "poses, a fifth with one camera and no keyframes; none for other figures), none, a "
                        "bundled one (human_pose: the human's, kept whatever the clip; human_pose_mixture: its "
                        "mixture of Gaussians over more clips; "
                        "cmu_bvh_pose: a figure made from a CMU BVH file, for detector tracks) or a JSON file "
                        "made by tools/fit_pose_prior.py")


def _weights_kwargs(args, names) -> dict:
    """The :class:`~pinrecon.Weights` keywords the command line gave: ``names`` (those not
    None) and the pose-prior flags (:func:`pose_prior_weights`)."""
    out = {k: getattr(args, k) for k in names if getattr(args, k, None) is not None}
    out.update(pose_prior_weights(args))
    return out


def pose_prior_weights(args) -> dict:
    """The :class:`~pinrecon.Weights` keywords of ``--pose-prior``, ``--pose-prior-loss`` and
    ``--pose-prior-model`` (those given)."""
    out = {"pose_prior": args.pose_prior} if hasattr(args, "pose_prior") else {}
    if hasattr(args, "pose_prior_model"):
        out["pose_prior_model"] = args.pose_prior_model
    if hasattr(args, "pose_prior_loss"):
        out.update(pose_prior_loss=args.pose_prior_loss, pose_prior_k=3.0 if args.pose_prior_loss == "cauchy" else 2.0)
    return out


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    with warnings.catch_warnings():
        if getattr(args, "quiet", False):
            warnings.simplefilter("ignore")
        else:
            warnings.showwarning = _show_warning
        try:
            return args.func(args)
        except PinreconError as exc:
            print(f"pinrecon: error: {exc}", file=sys.stderr)
            return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
