"""``pinrecon video VIDEO... --out DIR``: from video files to 3D motion, exports and an overlay video.

One call runs, per video, MediaPipe Pose (``pinrecon track``: 2D landmarks, visibility, its
3D world landmarks as lifted cues), then one reconstruction of the generic human (``--figure``
and every option of ``pinrecon reconstruct``: the same code, :mod:`pinrecon.arguments`), with
a camera estimated from the video (``--camera auto``, the default) or a calibration
(``--calibration Calib.toml``: several videos are several cameras of one solve, in the
file's camera order). Into ``DIR``: ``tracks.json`` (``tracks_<video>.json`` per video with
several), ``result.npz``, ``motion.bvh``, ``motion.csv``, ``motion.trc``, ``plots/`` and
``overlay.mp4`` (``overlay_<video>.mp4``): the skeleton drawn over the input frames with a
side view beside (the plots are drawn by ``pinrecon plot`` in a second process meanwhile).
Every output is checked writable and every video readable before the work starts.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
import warnings
from pathlib import Path

from ..errors import InputError
from . import SolveProgress
from .track import FPS_HELP, NOBODY, add_video_options, check_video_options, check_writable

__all__ = ["cmd_video", "per_video_names", "register", "run_video"]


def per_video_names(videos: list[str], stem: str, suffix: str) -> list[str]:
    """One output file name per video: ``stem + suffix`` for one video, ``stem_<its file's
    stem> + suffix`` for several (numbered ``stem_<i>_<its stem>`` when two share a stem)."""
    if len(videos) == 1:
        return [stem + suffix]
    stems = [Path(v).stem for v in videos]
    if len(set(stems)) != len(stems):
        stems = [f"{i + 1}_{s}" for i, s in enumerate(stems)]
    return [f"{stem}_{s}{suffix}" for s in stems]


def _outputs(out: Path, videos: list[str]) -> dict:
    return {
        "tracks": [out / n for n in per_video_names(videos, "tracks", ".json")],
        "overlay": [out / n for n in per_video_names(videos, "overlay", ".mp4")],
        "result": out / "result.npz",
        "bvh": out / "motion.bvh",
        "csv": out / "motion.csv",
        "trc": out / "motion.trc",
        "plots": out / "plots",
    }


class _Plots:
    """The plots of a saved result, drawn by ``pinrecon plot`` in a new process (Python, not a
    fork: the detector's and OpenCV's threads make forking unsafe). The process is started
    (:meth:`start`) once the detector is done and imports pinrecon and matplotlib while the
    reconstruction leaves a CPU idle; it waits for :meth:`go` (the result saved) and draws while
    the caller writes the overlay; :meth:`result` waits for it and returns the files. Where
    that process cannot run or fails (a worker of a pool, one CPU, several videos' tracks, an
    error), the plots are drawn in :meth:`result` itself, which then raises any error as it
    would have."""

    #: what the process runs: the imports, then ``pinrecon plot`` once told to go (nothing when
    #: its input closes first: the command failed); once it returned (its pictures written, their
    #: names printed) the process ends at once, without the interpreter's teardown (0.1 s with
    #: matplotlib loaded, which the caller would wait for)
    CODE = ("import os, signal, sys; "
            "signal.signal(signal.SIGINT, signal.default_int_handler); "  # heard even if ignored here
            "sys.path.append({here!r}); from pinrecon.cli import main; import pinrecon.viz.plots; "
            "import matplotlib.pyplot; code = main() if sys.stdin.readline() == 'go\\n' else 0; "
            "sys.stdout.flush(); sys.stderr.flush(); "
            "os._exit(0 if code is None else code if isinstance(code, int) else 1)")

    def __init__(self, result_path: Path, folder: Path, tracks_paths: list[Path]):
        import importlib.util
        import multiprocessing as mp

        from ..processes import usable_cpus

        self.folder, self.proc, self.seconds, self.t0 = folder, None, None, time.perf_counter()
        self.going, self._command, self._watcher = False, None, None
        if len(tracks_paths) != 1 or mp.parent_process() is not None or usable_cpus() < 2 \
                or importlib.util.find_spec("matplotlib") is None:  # no viz extra: said by result()
            return
        self._command = (result_path, folder, tracks_paths)

    def start(self) -> None:
        """Start the process (once the detector is done: its imports then use the CPU the
        reconstruction leaves idle, not the one decoding the video)."""
        import os
        import subprocess

        if self._command is None or self.proc is not None:
            return
        result_path, folder, tracks_paths = self._command
        here = str(Path(__file__).resolve().parents[2])  # where this pinrecon was imported from, searched last
        try:
            self.proc = subprocess.Popen([sys.executable, "-c", self.CODE.format(here=here), "plot", str(result_path),
                                          "--out", str(folder), "--tracks", str(tracks_paths[0]), "--no-animation"],
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                         text=True, env={**os.environ, "MPLBACKEND": "Agg"})
        except OSError:
            self.proc = None

    def go(self) -> None:
        """The result and tracks are saved: draw them."""
        self.t0 = time.perf_counter()
        if self.proc is None:
            return
        try:
            self.proc.stdin.write("go\n")
            self.proc.stdin.flush()  # communicate() closes it
            self.going = True
        except OSError:  # the process has ended: result() draws here
            return
        import threading

        self._watcher = threading.Thread(target=self._watch, name="pinrecon-plots", daemon=True)
        self._watcher.start()

    def _watch(self) -> None:
        """When the process ends (its pictures drawn): :attr:`seconds`, though :meth:`result` is
        called later (after the overlay)."""
        self.proc.wait()
        self.seconds = time.perf_counter() - self.t0

    def stop(self) -> None:
        """Stop the process (the caller failed): before :meth:`go` it ends without drawing;
        after, interrupted, it removes what it had staged (``pinrecon plot`` writes its folder
        whole or not at all)."""
        import os
        import signal
        import subprocess

        if self.proc is None or self.proc.poll() is not None:
            return
        if self.going:
            self.proc.send_signal(signal.SIGINT if os.name == "posix" else signal.SIGTERM)
        try:
            self.proc.communicate(timeout=10)  # closes its input: a process not told to go ends
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.communicate()

    def result(self, res, tracks) -> list[Path]:
        if self.proc is not None and not self.going:
            self.stop()
        if self.proc is not None and self.going:
            out, _ = self.proc.communicate()
            if self._watcher is not None:
                self._watcher.join(5.0)
            if self.seconds is None:
                self.seconds = time.perf_counter() - self.t0
            if self.proc.returncode == 0:
                return [Path(line) for line in out.splitlines() if line.strip()]
        from ..viz import plot_result

        return plot_result(res, self.folder, tracks=tracks if len(tracks) > 1 else tracks[0], animation=False)


def _overlay_bounds(args) -> dict:
    """The overlay panels' bounds: ``--overlay-height`` rows, or by default each panel within
    :data:`pinrecon.viz.overlay.PANEL_SIDE` pixels square."""
    from ..viz.overlay import PANEL_SIDE

    if args.overlay_height is None:
        return {"max_height": PANEL_SIDE, "max_width": PANEL_SIDE}
    return {"max_height": args.overlay_height, "max_width": None}


def _write_overlays(res, args, paths, tracks, kept) -> tuple[list[Path], float]:
    """Each video's overlay (``paths``, in the videos' order) and the seconds they took
    (``kept``: each video's frames kept by the detector's pass, or None)."""
    from ..viz.overlay import write_overlay

    t0 = time.perf_counter()
    out = [write_overlay(res, video, paths[i], camera_index=i, tracks=tracks[i], **_overlay_bounds(args),
                         progress=not args.quiet, frames=kept[i]) for i, video in enumerate(args.videos)]
    return out, time.perf_counter() - t0


def run_video(args, tracked=None) -> dict:
    """The work of ``pinrecon video`` for its parsed ``args``; returns ``{"files": [...],
    "frames": n, "seconds": s, "result": Result, "tracks": [Tracks per video], "stages":
    {name: seconds}}``. ``tracked``:
    one :class:`~pinrecon.Tracks` per video from an earlier :func:`pinrecon.video.track_video`
    (a benchmark's cache), used instead of running the detector again."""
    from ..video import crop_box, require_mediapipe, video_info

    check_video_options(args)
    if args.overlay_height is not None and args.overlay_height < 16:
        raise InputError(f"must be at least 16 pixels, got {args.overlay_height}", field="--overlay-height")
    if tracked is None:
        require_mediapipe()
    if args.calibration:
        if args.camera:
            raise InputError("give --calibration or --camera, not both", field="--calibration")
        args.camera = [args.calibration]
    if not args.camera:
        args.camera = ["auto"]
    auto = any(c.split(":")[0] == "auto" for c in args.camera)
    if auto and len(args.videos) > 1:
        raise InputError(f"{len(args.videos)} videos need their cameras' calibration (--calibration Calib.toml, one "
                         "camera per video in the file's order); --camera auto is for one video", field="--calibration")
    infos = [video_info(v, fps=args.fps) for v in args.videos]  # every video readable before any work
    if args.crop is not None and len(args.videos) > 1:
        raise InputError("--crop is one video's (its frame's pixels): give it with one video", field="--crop")
    for info in infos:
        crop_box(args.crop, info, field="--crop")
    if not auto:  # as many cameras as videos before any work
        from ..arguments import cameras_for_tracks

        cameras_for_tracks(args.camera, args.videos, args.camera_name, given="videos",
                           field="--calibration" if args.calibration else "--camera")
    if args.figure != "human":  # a BVH or URDF figure names MediaPipe's points, before the detector runs
        from ..arguments import figure_from_args
        from ..layouts import MEDIAPIPE_33, shared_point_names

        shared_point_names(MEDIAPIPE_33, figure_from_args(args).keypoint_names, what="MediaPipe landmarks",
                           source=args.keypoints or args.figure)
    out = check_writable(args.out, folder=True)
    files = _outputs(out, args.videos)
    stages: dict[str, float] = {}
    t_start = time.perf_counter()
    # started once the detector is done (it imports while the reconstruction runs); it draws once the result is saved
    plots = None if args.no_plots else _Plots(files["result"], files["plots"], files["tracks"])
    try:
        return _run(args, infos, files, stages, t_start, plots, auto, tracked)
    except BaseException:
        if plots is not None:
            plots.stop()
        raise


def _run(args, infos, files, stages, t_start, plots, auto, tracked) -> dict:
    """:func:`run_video` from the detector on (``plots``: the :class:`_Plots`, started here once the
    detector is done, or None)."""
    from ..arguments import reconstruct_from_args
    from ..layouts import MEDIAPIPE_OFF_MAP
    from ..video import track_video

    tracks, kept = [], [None] * len(args.videos)
    for i, (video, info) in enumerate(zip(args.videos, infos)):
        t0 = time.perf_counter()
        if tracked is not None:
            tr = tracked[i]
        else:
            if not args.no_overlay:  # the overlay's frames kept as the detector decodes them (short videos)
                from ..viz.overlay import KeptFrames

                kept[i] = KeptFrames(info, budget=KeptFrames.BUDGET // len(args.videos),
                                     frames=info.frames_read(args.max_frames), **_overlay_bounds(args))
            tr = track_video(video, fps=args.fps, max_frames=args.max_frames, model_complexity=args.model_complexity,
                             progress=not args.quiet, on_frame=kept[i], info=info, crop=args.crop)
        tr.lifted.camera = i
        tr.save(files["tracks"][i])
        tracks.append(tr)
        stages[f"track {Path(video).name}"] = time.perf_counter() - t0
        if not tr.observed.any():
            raise InputError(NOBODY, file=video)
    if plots is not None:
        plots.start()

    t0 = time.perf_counter()
    args.tracks = [str(p) for p in files["tracks"]]
    if auto and args.image_size is None:
        args.image_size = [float(infos[0].width), float(infos[0].height)]
    args.fps = None
    with warnings.catch_warnings():  # warnings are said also with --quiet (it silences progress only)
        # MediaPipe's eye and mouth corners and hand points are on no figure: said in docs/video.md, not on
        # every run
        off_map = f"tracks points not on the figure are ignored: {list(MEDIAPIPE_OFF_MAP)}"
        warnings.filterwarnings("ignore", message=re.escape(off_map) + "$")
        progress = SolveProgress(args.quiet, args.max_iterations)
        res = reconstruct_from_args(args, callback=progress)
        progress.close()
    res.save(files["result"])
    written = [files["tracks"], [files["result"]]]
    stages["reconstruct"] = time.perf_counter() - t0

    if plots is not None:  # drawn by `pinrecon plot` in the other process while the exports and overlay are written
        plots.go()
    t0 = time.perf_counter()
    from ..io.bvh_export import export_result

    written.append(export_result(files["result"], bvh=files["bvh"], csv=files["csv"], trc=files["trc"]))
    stages["exports"] = time.perf_counter() - t0

    if not args.no_overlay:
        paths, stages["overlay"] = _write_overlays(res, args, files["overlay"], tracks, kept)
        written.append(paths)
    if plots is not None:
        t0 = time.perf_counter()
        try:
            written.append(plots.result(res, tracks))
        except ImportError as exc:  # the viz extra (matplotlib) is optional
            print(f"pinrecon video: no plots ({exc})", file=sys.stderr)
        stages["plots"] = plots.seconds or time.perf_counter() - t0
    seconds = time.perf_counter() - t_start
    return {"files": [Path(f) for group in written for f in group], "frames": tracks[0].T, "seconds": seconds,
            "result": res, "tracks": tracks, "stages": stages}


def cmd_video(args) -> int:
    run = run_video(args)
    print(run["result"].summary())  # the command's output, on stdout (also with --quiet: no progress only)
    n, s = run["frames"], run["seconds"]
    where = ", ".join(f"{k} {v:.1f} s" for k, v in run["stages"].items())
    print(f"pinrecon video: {n} frames in {s:.1f} s end to end ({n / max(s, 1e-9):.1f} frames/s: {where})")
    for f in run["files"]:
        print(f"wrote {f}")
    return 0


def register(sub) -> None:
    from ..arguments import add_reconstruct_options

    p = sub.add_parser("video", help="from video files to 3D motion: track (MediaPipe Pose), reconstruct, and write "
                       "the result, BVH, CSV, TRC, plots and an overlay video (the optional 'video' extra)")
    p.add_argument("videos", nargs="+", metavar="VIDEO",
                   help="video file(s); several need --calibration (one camera per video, in the file's order)")
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument("--calibration", metavar="CALIB.toml",
                   help="the cameras' calibration (Pose2Sim/Sports2D TOML, OpenCV YAML/XML/JSON, pinrecon camera "
                   "JSON): one camera per video, in order; default --camera auto (one video)")
    add_video_options(p, fps=False)
    add_reconstruct_options(p, camera_required=False)
    for action in p._actions:  # argparse keeps its options there: the figure defaults to the generic human here
        if action.dest == "figure":
            action.required, action.default = False, "human"
            action.help = "'human' (the default), a URDF file, or a BVH file (its skeleton)"
        elif action.dest == "fps":
            action.help = FPS_HELP
        elif action.dest in ("layout", "person"):  # a tracks file's options: MediaPipe follows one person
            action.help = argparse.SUPPRESS
    p.add_argument("--overlay-height", type=int, default=None, metavar="PX",
                   help="height of the overlay video in pixels (the input scaled down to it); default: each of its "
                   "two panels within 960 x 960 (a 1080 x 1920 video gives 1080 x 960, a 1920 x 1080 one 1920 x 540)")
    p.add_argument("--no-overlay", action="store_true", help="skip the overlay video")
    p.add_argument("--no-plots", action="store_true", help="skip the plots")
    p.add_argument("--quiet", action="store_true", help="no progress output (the summary and warnings are still "
                   "shown)")
    p.set_defaults(func=cmd_video)
