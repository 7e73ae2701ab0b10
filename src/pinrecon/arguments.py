"""The reconstruction's command-line arguments, shared by ``pinrecon reconstruct`` and the
commands that run the same reconstruction on many inputs (``pinrecon batch``).

:func:`add_reconstruct_options` adds the options to a parser; :func:`reconstruct_from_args`
runs the reconstruction those options (an ``argparse.Namespace``) describe and returns the
:class:`~pinrecon.Result`; the ``*_from_args`` helpers turn single options into the Python
API's arguments. Nothing here writes a file.
"""

from __future__ import annotations

import argparse
import sys

__all__ = ["add_reconstruct_options", "reconstruct_from_args", "figure_from_args", "cameras_for_tracks",
           "auto_camera_from_args", "feet_from_args", "detector_options", "add_pose_prior_argument",
           "weights_kwargs", "pose_prior_weights"]

#: the Weights keywords of reconstruct's options (those given)
WEIGHT_OPTIONS = ("sigma_px", "acc_root_translation", "acc_root_rotation", "acc_joints", "sigma_limits", "loss")


def add_reconstruct_options(r, *, inputs=None, camera_required: bool = True, figure_required: bool = True) -> None:
    """Add ``pinrecon reconstruct``'s options (figure, camera, detector, weights, solver,
    feet, calibration) to the parser ``r``; ``inputs(r)``, when given, adds the input options
    after ``--lock`` (``--tracks`` for reconstruct). ``camera_required=False`` for commands
    that take the camera (or the figure) elsewhere too (a batch manifest)."""
    r.add_argument("--figure", required=figure_required, help="'human', a URDF file, or a BVH file (its skeleton)")
    r.add_argument(
        "--keypoints",
        help="keypoint map JSON, or for 'human' a bundled map: coco17, body25, body25b, halpe26, joints "
        "(default: the map of the tracks' detector layout)",
    )
    r.add_argument("--length-scale", type=float, default=1.0, help="metres per BVH unit (CMU: 0.056444)")
    r.add_argument("--lock", nargs="*", help="BVH joints to weld (zero rotation)")
    if inputs is not None:
        inputs(r)
    r.add_argument("--fps", type=float, help="frame rate of OpenPose/COCO tracks")
    detector_options(r)
    r.add_argument(
        "--camera", required=camera_required, action="append",
        help="camera or calibration file: pinrecon camera JSON, Pose2Sim/Sports2D TOML, OpenCV YAML/XML/JSON; "
        "repeat it for several cameras. Cameras pair with --tracks in order: a file holding several cameras "
        "(a Pose2Sim TOML) gives them in the file's order, so give its cameras' --tracks in that order. "
        "'auto' (one --tracks, no calibration): a perspective camera with the principal point at the image "
        "centre (--image-size), the focal length from a 60 degree field of view (--fov) refined in the solve, "
        "the world placed at the camera unless point keyframes give its pose; 'auto:orthographic' likewise",
    )
    r.add_argument("--camera-name", nargs="+", metavar="NAME",
                   help="use only these cameras of the --camera files, in this order (e.g. cam_01 of a Pose2Sim "
                   "Calib.toml, for that camera's --tracks)")
    r.add_argument("--image-size", type=float, nargs=2, metavar=("W", "H"),
                   help="image width and height in pixels, for --camera auto")
    r.add_argument("--fov", type=float, help="starting horizontal field of view of --camera auto, degrees (default 60)")
    r.add_argument("--keyframes", help="keyframes JSON")
    if inputs is not None:  # tracks files in: a lifter's 3D of the same frames may come beside them
        r.add_argument("--lifted", action="append", metavar="FILE",
                       help="a lifter's 3D output of the same frames, as learned 3D cues: MotionBERT / VideoPose3D "
                       ".npy, MMPose 3D JSON (docs/formats.md, section 11); one per --tracks, in order")
        r.add_argument("--lifted-format", choices=["npy", "motionbert", "videopose3d", "mmpose3d"],
                       help="format of --lifted (default: from the suffix)")
        r.add_argument("--lifted-layout", help="joint order of --lifted (default h36m17)")
        r.add_argument("--lifted-frame", choices=["camera", "unknown"],
                       help="axes of --lifted: 'camera' (the lifters' own output) or 'unknown' (turned into other "
                       "axes)")
    r.add_argument("--lifter", metavar="auto|none|FILE",
                   help="pinrecon's own 2D-to-3D lifter as learned 3D cues (lifted-pose rows) for one camera's "
                   "tracks that carry none: 'auto' (the shipped weights, for --figure human with the COCO-17 body "
                   "points), 'none', or a weights file (tools/train_lifter.py); default: "
                   "pinrecon.lifter.DEFAULT_LIFTER (docs/lifted.md)")
    r.add_argument("--own-lifter-weight", type=_non_negative, metavar="W",
                   help="weight of pinrecon's own lifter's rows from the start, while the default pose prior holds "
                   "(default 3, Weights.own_lifter; with the broader prior they take --lifted-weight); 0: the "
                   "lifter only where the prior switches")
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
    r.add_argument("--lifted-weight", type=_non_negative, metavar="W",
                   help="weight of the lifted-pose rows when the tracks carry a lifter's 3D (a video's MediaPipe "
                   "world landmarks, --lifted): the inverse variance of a bone's unit-direction chord (default 25, "
                   "docs/lifted.md); 0 turns them off")
    add_pose_prior_argument(r)
    r.add_argument("--max-iterations", type=int, default=100)
    r.add_argument("--skip", nargs="+", default=(), metavar="STAGE",
                   help="switch stages off by name: labels, prior, yield, turns, mirrors, faults, focal, feet (the start and the "
                   "solve always run; the summary lists every stage with its time and what it changed)")
    r.add_argument("--window", type=int, help="solve in overlapping windows of this many frames, in bounded memory "
                   "and on every core (default: windows of 2000 frames past 10000 frames; 0: one batch solve)")
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


def reconstruct_from_args(args, callback=None):
    """The reconstruction ``pinrecon reconstruct`` runs for the options ``args`` (a
    namespace of :func:`add_reconstruct_options`, ``args.tracks`` a list of tracks files,
    ``args.camera`` a list of camera files or ``["auto"]``): loads the inputs, builds the
    figure, solves (``callback``: the solver's per-iteration callback; its ``stage(name)``
    method, when it has one, hears each stage start), and, with
    ``args.stability``, the stability runs. Returns the :class:`~pinrecon.Result`."""
    from .errors import InputError
    from .problem import Weights
    from .reconstruct import reconstruct
    from .solver import SolverOptions
    from .tracks import load_keyframes, load_tracks

    stability_runs = getattr(args, "stability", None)
    if stability_runs is not None and stability_runs < 1:
        raise InputError(f"must be a number of solves, at least 1; got {stability_runs}", field="--stability")
    auto = auto_camera_from_args(args)
    cams = [auto] if auto is not None else cameras_for_tracks(args.camera, args.tracks, getattr(args, "camera_name", None))
    tracks = [load_tracks(path, fps=args.fps, person=args.person, layout=args.layout) for path in args.tracks]
    if getattr(args, "lifted", None):
        tracks = with_lifted(tracks, args)
    fig = figure_from_args(args, tracks)
    if len(tracks) == 1:  # one camera: plain arguments, as the Python API takes them
        tracks, cam = tracks[0], cams[0]
    else:
        cam = cams
    kf = load_keyframes(args.keyframes) if args.keyframes else None
    opts = SolverOptions(max_iterations=args.max_iterations)
    kw = {"fps_out": args.fps_out, "weights": Weights(**weights_kwargs(args, WEIGHT_OPTIONS)), "options": opts,
          "seed": args.seed, "calibrate": args.calibrate, "window": args.window, **feet_from_args(args),
          **({"lifter": args.lifter} if getattr(args, "lifter", None) is not None else {})}
    res = reconstruct(fig, tracks, cam, kf, callback=callback, skip=getattr(args, "skip", ()),
                      progress=getattr(callback, "stage", None), **kw)
    if stability_runs:
        from .stability import stability

        if hasattr(callback, "close"):  # end a live progress line before saying more
            callback.close()
        if not getattr(args, "quiet", False):
            print(f"pinrecon: solving again on {stability_runs} copies of the tracks with 1 % of the detections "
                  "left out (--stability)", file=sys.stderr)
        res.extras.update(stability(fig, tracks, cam, kf, result=res, runs=stability_runs,
                                    n_jobs=getattr(args, "jobs", None), **kw).to_extras())
    return res


def with_lifted(tracks, args) -> list:
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


def figure_from_args(args, tracks=None):
    """The :class:`~pinrecon.Figure` of ``--figure`` (``human``, a URDF or a BVH file) with
    ``--keypoints``, ``--length-scale``, ``--lock`` and ``--limits``; ``tracks`` pick the
    human's keypoint map when ``--keypoints`` is not given."""
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


def cameras_for_tracks(camera_files, tracks_files, names=None, *, given: str = "--tracks", field: str = "--camera"):
    """The cameras of every ``--camera`` file, in order (a file's cameras in the file's
    order), or those called ``names`` (``--camera-name``) in that order, one per ``--tracks``;
    a mismatch is one clear error listing them (``given``: what the caller calls the inputs,
    ``field``: the option it names)."""
    from .errors import InputError, UnknownNameError
    from .io.calibration import load_cameras

    cams = [c for path in camera_files for c in load_cameras(path)]
    if names:
        by_name = {c.name: c for c in cams}
        missing = [n for n in names if n not in by_name]
        if missing:
            raise UnknownNameError("camera", missing, list(by_name), field="--camera-name")
        cams = [by_name[n] for n in names]
    if len(cams) != len(tracks_files):
        listed = ", ".join(f"{c.name!r}" for c in cams)
        one = "--tracks" if given == "--tracks" else given.rstrip("s")
        pick = "" if names else " (or name the cameras they were filmed by: --camera-name)"
        raise InputError(
            f"{len(tracks_files)} {given} but the {'calibration holds' if field == '--calibration' else '--camera files hold'} "
            f"{len(cams)} cameras ({listed}): give one "
            f"{one} per camera, in this order{pick}",
            field=field,
        )
    return cams


def auto_camera_from_args(args):
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


def feet_from_args(args) -> dict:
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


def detector_options(parser) -> None:
    """Add ``--layout`` and ``--person`` (detector output) to ``parser``."""
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


def _non_negative(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (v >= 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"must be 0 or a positive number, got {text!r}")
    return v


def add_pose_prior_argument(parser) -> None:
    """Add ``--pose-prior``, ``--pose-prior-loss`` and ``--pose-prior-model`` to ``parser``."""
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


def weights_kwargs(args, names) -> dict:
    """The :class:`~pinrecon.Weights` keywords the command line gave: ``names`` (those not
    None), ``--lifted-weight``, ``--own-lifter-weight`` and the pose-prior flags
    (:func:`pose_prior_weights`)."""
    out = {k: getattr(args, k) for k in names if getattr(args, k, None) is not None}
    if getattr(args, "lifted_weight", None) is not None:  # --lifted-weight (--lifted is a file)
        out["lifted"] = args.lifted_weight
    if getattr(args, "own_lifter_weight", None) is not None:
        out["own_lifter"] = args.own_lifter_weight or None  # 0: the lifter only at the prior's switch
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


