"""MediaPipe Pose on a video: 2D landmarks, their visibility and MediaPipe's own 3D, as Tracks.

MediaPipe's legacy Pose solution (``mediapipe==0.10.14``; BlazePose GHUM, the full model
``model_complexity=1`` ships inside the wheel and runs offline) follows one person through
the frames. Per frame and landmark (33, :data:`pinrecon.layouts.MEDIAPIPE_33`):

* ``pose_landmarks``: x, y normalised by the image's width and height -> pixels (x W, y H);
* ``visibility``: the model's likelihood that the landmark is visible -> the confidence;
* ``pose_world_landmarks``: metres, origin at the hips' midpoint, y down, z toward the
  camera negative (MediaPipe's convention) -> :class:`pinrecon.lifted.Lifted` with
  ``frame="unknown"``: measured on Pose2Sim's balancing trial against its four-camera
  triangulation (``bench/bench_video.py``), their axes are not the camera's, by a rotation
  that changes with the pose (see ``docs/formats.md``).

A frame where MediaPipe finds nobody is missing (NaN, confidence 0) in both.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import types
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from ..layouts import MEDIAPIPE_33
from ..lifted import Lifted
from ..processes import usable_cpus
from ..tracks import Tracks
from .frames import (
    EXTRA_HINT,
    MissingVideoExtraError,
    crop_box,
    iter_frames,
    require_cv2,
    video_info,
)
from .progress import FrameProgress

if TYPE_CHECKING:
    from .frames import VideoInfo

__all__ = ["MAX_DETECTOR_THREADS", "MEDIAPIPE_VERSION", "SPLIT_FRAMES", "WARM_FRAMES", "MediaPipePose",
           "detector_threads", "require_mediapipe", "track_parts", "track_video"]

#: the MediaPipe release whose legacy Pose solution this reads (its model is in the wheel)
MEDIAPIPE_VERSION = "0.10.14"


def require_mediapipe() -> None:
    """Check, without importing it (a second), that MediaPipe is installed; else
    :class:`~pinrecon.video.MissingVideoExtraError` naming the extra. For commands that
    check their inputs before any work."""
    import importlib.util

    try:
        found = importlib.util.find_spec("mediapipe") is not None
    except (ImportError, ValueError):  # a module set to None in sys.modules
        found = False
    if not found:
        raise MissingVideoExtraError(f"tracking a video needs MediaPipe {MEDIAPIPE_VERSION}: {EXTRA_HINT}")


class _Deferred(types.ModuleType):
    """A stand-in for a module while another package is imported: any attribute asked of it
    later comes from the real module, imported then."""

    def __getattr__(self, attr):
        import importlib

        if sys.modules.get(self.__name__) is self:  # still standing in: the real one is not importable now
            raise AttributeError(attr)
        return getattr(importlib.import_module(self.__name__), attr)


#: modules MediaPipe's package imports and its Pose solution never uses: matplotlib.pyplot, for its
#: drawing helpers (0.3 s on the critical path of ``pinrecon video``, whose plots are drawn in
#: another process). Not its Tasks API (0.08 s): ``mediapipe.tasks`` is bound to it by name, and a
#: stand-in would lose that binding once the real one is imported
UNUSED_BY_POSE = ("matplotlib", "matplotlib.pyplot")


@contextlib.contextmanager
def _deferred(names=UNUSED_BY_POSE):
    """While MediaPipe is imported, the modules ``names`` not imported yet are stand-ins
    (:class:`_Deferred`); they leave ``sys.modules`` after, so the next import of one is the real
    one, and what MediaPipe kept of them asks the real one when used."""
    names = [n for n in names if n not in sys.modules]
    for name in names:
        sys.modules[name] = _Deferred(name)
    try:
        yield
    finally:
        for name in names:
            if isinstance(sys.modules.get(name), _Deferred):
                del sys.modules[name]


def _import_mediapipe():
    # MediaPipe's C++ logs (glog, TensorFlow Lite) go to stderr unless told otherwise
    os.environ.setdefault("GLOG_minloglevel", "2")
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            with _deferred():
                import mediapipe as mp
        except ImportError as exc:
            raise MissingVideoExtraError(
                f"tracking a video needs MediaPipe {MEDIAPIPE_VERSION} ({exc}): {EXTRA_HINT}") from None
    solutions = getattr(mp, "solutions", None)
    if solutions is None or not hasattr(solutions, "pose"):
        raise MissingVideoExtraError(
            f"this MediaPipe ({getattr(mp, '__version__', '?')}) has no legacy Pose solution "
            f"(mp.solutions.pose): install MediaPipe {MEDIAPIPE_VERSION}: {EXTRA_HINT}")
    return mp


#: at most this many threads for the detector's networks by default (two halve its time a frame
#: on 1080 x 1920 video nearly: bench/README.md, bench_video)
MAX_DETECTOR_THREADS = 4


def detector_threads(share: int = 1) -> int:
    """The threads MediaPipe's networks run on by default: the CPUs this process may use
    (:func:`~pinrecon.processes.usable_cpus`), divided among ``share`` detectors running at
    once, at least 1 and at most :data:`MAX_DETECTOR_THREADS`; ``PINRECON_DETECTOR_THREADS=N``
    in the environment sets it (where other processes of the caller's already use the cores), up
    to those CPUs: more threads than CPUs wait on each other (with a third thread on two CPUs the
    detector ran 20 times slower), so a larger count is said and lowered to them."""
    given = os.environ.get("PINRECON_DETECTOR_THREADS", "").strip()
    if given:
        if not given.isdigit() or int(given) < 1:
            raise InputError(f"must be a whole number of threads, at least 1; got {given!r}",
                             field="PINRECON_DETECTOR_THREADS")
        cpus = usable_cpus()
        if int(given) > cpus:
            warnings.warn(f"PINRECON_DETECTOR_THREADS={given} is more than the {cpus} CPU(s) this process may use: "
                          f"the detector runs on {cpus} (more threads than CPUs wait on each other)", stacklevel=2)
            return cpus
        return int(given)
    return max(1, min(MAX_DETECTOR_THREADS, usable_cpus() // max(1, int(share))))


def _pose_class(mp, threads: int):
    """MediaPipe's legacy Pose whose inference calculators run XNNPACK on ``threads`` threads
    (the legacy solution has no such argument; its graph's options are set as it builds them)."""
    from mediapipe.calculators.tensor import inference_calculator_pb2

    ext = inference_calculator_pb2.InferenceCalculatorOptions.ext

    class Pose(mp.solutions.pose.Pose):
        def _modify_calculator_options(self, config, params):
            super()._modify_calculator_options(config, params)
            for node in config.node:
                if node.calculator.startswith("InferenceCalculator") and node.options.HasExtension(ext):
                    delegate = node.options.Extensions[ext].delegate
                    if delegate.HasField("xnnpack"):
                        delegate.xnnpack.num_threads = threads

    return Pose


@contextlib.contextmanager
def _quiet_native_stderr():
    """MediaPipe's native code prints notes (TensorFlow Lite's delegate, glog lines that
    ignore ``GLOG_minloglevel``) straight to file descriptor 2, from its own threads and a
    moment after the call that caused them: hide them while MediaPipe works. Yields a text
    stream to the real stderr (for a progress bar)."""
    try:
        fd = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):  # a replaced stderr (pytest's capture)
        fd = 2
    sys.stderr.flush()
    try:
        saved = os.dup(fd)
        null = os.open(os.devnull, os.O_WRONLY)
    except OSError:  # pragma: no cover - no descriptors to spare
        yield sys.stderr
        return
    visible = os.fdopen(os.dup(saved), "w", buffering=1)
    try:
        os.dup2(null, fd)
        yield visible
    finally:
        visible.flush()
        os.dup2(saved, fd)
        os.close(saved)
        os.close(null)
        visible.close()


class MediaPipePose:
    """One MediaPipe Pose tracker over consecutive frames: ``detect(frame_bgr)`` ->
    ``(uv_px (33, 2), visibility (33,), p_world_m (33, 3))``, NaN and 0 where nobody is found.

    ``model_complexity``: 1 (full, the default: the model in MediaPipe's wheel), 0 (lite) or
    2 (heavy): MediaPipe downloads those on first use. ``threads``: the CPU threads each of its
    two networks runs on (TensorFlow Lite's XNNPACK; the same landmarks with any number); None,
    :func:`detector_threads`. Close it (or use ``with``) to free the graph."""

    def __init__(self, model_complexity: int = 1, *, static_image_mode: bool = False, threads: int | None = None):
        mp = _import_mediapipe()
        self.cv2 = require_cv2()
        self.threads = detector_threads() if threads is None else int(threads)
        if self.threads < 1:
            raise ValueError(f"threads must be at least 1, got {threads}")
        with warnings.catch_warnings(), _quiet_native_stderr():
            warnings.simplefilter("ignore")
            self._pose = _pose_class(mp, self.threads)(static_image_mode=static_image_mode,
                                                       model_complexity=model_complexity)
        self._started = False

    def detect(self, frame_bgr: np.ndarray):
        return self.detect_rgb(self.cv2.cvtColor(frame_bgr, self.cv2.COLOR_BGR2RGB))

    def detect_rgb(self, rgb: np.ndarray):
        """:meth:`detect` of a frame already in RGB order (what MediaPipe reads)."""
        h, w = rgb.shape[:2]
        with warnings.catch_warnings(), (contextlib.nullcontext() if self._started else _quiet_native_stderr()):
            warnings.simplefilter("ignore")  # protobuf's deprecation notes, per frame
            res = self._pose.process(rgb)
        self._started = True
        n = len(MEDIAPIPE_33)
        if res.pose_landmarks is None:
            return np.full((n, 2), np.nan), np.zeros(n), np.full((n, 3), np.nan)
        lm = res.pose_landmarks.landmark
        uv = np.array([(p.x * w, p.y * h) for p in lm], float)
        vis = np.clip(np.array([p.visibility for p in lm], float), 0.0, 1.0)
        if res.pose_world_landmarks is not None:
            world = np.array([(p.x, p.y, p.z) for p in res.pose_world_landmarks.landmark], float)
        else:  # pragma: no cover - MediaPipe gives both or neither
            world = np.full((n, 3), np.nan)
        return uv, vis, world

    def close(self):
        self._pose.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


#: a video of at least this many frames is tracked in two parts, each by a MediaPipe graph of its
#: own, at once where two CPUs are free: XNNPACK's threads on one graph wait on each other, two
#: graphs on a thread each use the CPUs better (600 frames of 1080 x 1920: 10.8 -> 9.1 s; on a
#: shorter video the second graph's start and the frames it decodes to reach its part eat the
#: gain: bench/README.md, bench_video_long). The parts depend on the frame count alone, not on
#: the CPUs, so the landmarks are the same on every machine
SPLIT_FRAMES = 600
#: the second part's tracker starts this many frames before the frames it gives (dropped: its
#: region of interest and MediaPipe's smoothing settle on them)
WARM_FRAMES = 8


def track_parts(total: int) -> list[tuple[int, int, int]]:
    """The parts :func:`track_video` tracks a video of ``total`` frames in (0: the count is
    unknown): ``(start, first kept, end)`` each, frames ``[start, end)`` run through one
    tracker and ``[first kept, end)`` kept (the last part reads on to where the video ends),
    the two parts about as long as each other."""
    if total < SPLIT_FRAMES:
        return [(0, 0, total)]
    mid = (total + WARM_FRAMES) // 2
    return [(0, 0, mid), (mid - WARM_FRAMES, mid, total)]


def track_video(
    path: str | os.PathLike,
    *,
    fps: float | None = None,
    max_frames: int | None = None,
    model_complexity: int = 1,
    progress: bool = False,
    on_frame: Callable[[int, np.ndarray], None] | None = None,
    info: VideoInfo | None = None,
    crop: tuple[int, int, int, int] | None = None,
    threads: int | None = None,
) -> Tracks:
    """Run MediaPipe Pose over the video at ``path``: :class:`~pinrecon.Tracks` of its 33
    landmarks in pixels (layout ``"mediapipe33"``, confidence = visibility, ``fps`` the
    video's unless given) with ``lifted`` = MediaPipe's world landmarks
    (:class:`~pinrecon.lifted.Lifted`, metres, ``frame="unknown"``, ``source="mediapipe"``).

    ``max_frames`` stops early; ``progress`` draws a bar over the frames on stderr;
    ``on_frame(t, frame_bgr)`` sees each decoded frame once, in the thread that decodes it (to
    reuse the decode: it must not hold the GIL long); a video of :data:`SPLIT_FRAMES` frames or
    more is tracked in two parts at once (:func:`track_parts`), so ``t`` comes in order within
    each part only. ``info``: the video's :func:`~pinrecon.video.video_info` (with the same
    ``fps``) when the caller has it, which saves opening the file once more. ``crop`` ``(x, y,
    w, h)``: the detector sees that part of each frame only (:func:`~pinrecon.video.crop_box`)
    (MediaPipe misses a person who fills little of its image); the landmarks are in the whole
    frame's pixels all the same. ``threads``: the detector's (:class:`MediaPipePose`; None, every
    CPU this process may use, up to :data:`MAX_DETECTOR_THREADS`), shared by the parts' trackers
    (with one, the parts run one after the other: the same landmarks). A file that is not a
    video raises :class:`~pinrecon.errors.InputError`; a missing extra
    :class:`~pinrecon.video.MissingVideoExtraError`.
    """
    info = video_info(path, fps=fps) if info is None else info
    total = info.frames_read(max_frames)
    name = os.path.basename(str(path))
    cv2 = require_cv2()
    x0, y0, cw, ch = crop_box(crop, info)
    parts = track_parts(total)

    def prepare(t, frame, first):  # in the decoding thread, beside the detector (both let go of the GIL)
        if on_frame is not None and t >= first:
            on_frame(t, frame)
        return cv2.cvtColor(frame[y0:y0 + ch, x0:x0 + cw], cv2.COLOR_BGR2RGB)

    threads = detector_threads() if threads is None else threads  # said before MediaPipe's notes are hidden
    at_once = len(parts) > 1 and threads >= len(parts)
    each = max(1, threads // len(parts)) if at_once else threads
    found: list[list] = [[] for _ in parts]
    stop = threading.Event()
    with _quiet_native_stderr() as stderr, contextlib.ExitStack() as graphs, \
            FrameProgress(total, f"track {name}", enabled=progress, file=stderr) as bar:
        poses = [graphs.enter_context(MediaPipePose(model_complexity, threads=each)) for _ in parts]

        def track(i):  # part i through its own tracker
            start, first, end = parts[i]
            frames = iter_frames(path, max_frames if i == len(parts) - 1 else end, ahead=4, start=start,
                                 prepare=lambda t, f: prepare(t, f, first))
            try:
                for t, rgb in enumerate(frames, start=start):
                    if stop.is_set():
                        return
                    detected = poses[i].detect_rgb(rgb)
                    if t >= first:
                        found[i].append(detected)
                        bar.update()
            finally:
                frames.close()

        if at_once:
            _in_threads(track, len(parts), stop)
        else:
            for i in range(len(parts)):
                track(i)
    rows = found[0]
    for (_, first, _), more in zip(parts[1:], found[1:]):
        if len(rows) == first:  # (a video shorter than its container says may end in the first part)
            rows = rows + more
    names = list(MEDIAPIPE_33)
    n = len(names)
    uv = np.array([r[0] for r in rows]).reshape(-1, n, 2) + [x0, y0]  # the whole frame's pixels
    vis = np.array([r[1] for r in rows]).reshape(-1, n)
    lifted = Lifted(np.array([r[2] for r in rows]).reshape(-1, n, 3), names, vis, frame="unknown",
                    source="mediapipe")
    return Tracks(uv, names, info.fps, lifted.confidence.copy(), str(path), "mediapipe33", lifted)


def _in_threads(work: Callable[[int], None], n: int, stop: threading.Event) -> None:
    """``work(i)`` for ``i < n``: the first here, the others each in a thread of its own; the
    first error (or an interrupt) here sets ``stop`` for the others, and an error of theirs is
    raised here once every thread has ended."""
    errors: list[BaseException] = []

    def run(i):
        try:
            work(i)
        except BaseException as exc:  # noqa: BLE001 - raised again in the caller's thread
            errors.append(exc)
            stop.set()

    others = [threading.Thread(target=run, args=(i,), name=f"pinrecon-track-{i}", daemon=True) for i in range(1, n)]
    for th in others:
        th.start()
    try:
        work(0)
    except BaseException:
        stop.set()
        raise
    finally:
        for th in others:
            th.join()
    if errors:
        raise errors[0]
