"""The overlay video: the reconstruction drawn over the frames it was made from, a second view beside.

Left panel: the input video's frames with the reconstructed skeleton reprojected through the
result's (fitted) camera; right panel: the same skeleton from the side (the camera turned
90 degrees about the up axis, the floor's normal when the result has a floor; orthographic,
one fixed scale for the clip). Written with OpenCV's ``VideoWriter`` (MPEG-4 Part 2,
``mp4v``): the optional ``video`` extra.

Colours (BGR), fixed so a picture or a test can find them: the figure's left side
:data:`LEFT_BGR`, right side :data:`RIGHT_BGR`, the middle :data:`CENTRE_BGR`, the keypoints
as filled dots of :data:`JOINT_BGR`; the 2D detections (when given) as white rings.
"""

from __future__ import annotations

import mmap
import os
import queue
import threading
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_path
from ..video.frames import iter_frames, require_cv2, video_info
from ..video.progress import FrameProgress
from ._common import as_motion, second_view_camera, skeleton, skeleton_points, view_up

__all__ = ["CENTRE_BGR", "JOINT_BGR", "LEFT_BGR", "PANEL_SIDE", "RIGHT_BGR", "KeptFrames", "frame_store",
           "overlay_scale", "write_overlay"]

LEFT_BGR = (255, 140, 0)  # azure: the figure's left
RIGHT_BGR = (40, 40, 230)  # red: its right
CENTRE_BGR = (0, 220, 255)  # yellow: spine, head, hubs
JOINT_BGR = (255, 0, 255)  # magenta keypoint dots
DETECTION_BGR = (255, 255, 255)
PANEL_BGR = (40, 40, 40)


#: by default each of the overlay's two panels fits in a square of this many pixels: a
#: 1080 x 1920 portrait video gives 540 x 960 panels, a 1920 x 1080 landscape one 960 x 540
PANEL_SIDE = 960


def overlay_scale(width: int, height: int, max_height: int | None, max_width: int | None = None) -> float:
    """The factor from the input video's pixels to an overlay panel's (at most ``max_height``
    rows and ``max_width`` columns, None: no bound; never enlarged; sizes rounded to even
    numbers, as MPEG-4 wants)."""
    s = 1.0
    if max_height is not None:
        s = min(s, max_height / height)
    if max_width is not None:
        s = min(s, max_width / width)
    return s


def _even(x: float) -> int:
    return max(2, round(x / 2) * 2)


def _overlay_size(width: int, height: int, max_height: int | None, max_width: int | None) -> tuple[int, int]:
    s = overlay_scale(width, height, max_height, max_width)
    return _even(width * s), _even(height * s)


class KeptFrames:
    """A video's frames scaled to the overlay's size, kept while another pass decodes them
    (:func:`pinrecon.video.track_video`'s ``on_frame``, called with each frame once, from the
    threads that decode them: in any order), so that :func:`write_overlay` need not decode the
    video again. Frames are kept up to ``budget`` bytes (default :attr:`BUDGET`); a video with
    more lets them all go (:attr:`frames` is then None) and the overlay decodes it as usual.
    ``frames``: how many the pass will read (default the video's count, ``info.frames``;
    :meth:`~pinrecon.video.VideoInfo.frames_read`): their memory is mapped in at once, in a
    thread, before the first arrives (:func:`frame_store`).

    >>> kept = KeptFrames(video_info("clip.mp4"))                   # doctest: +SKIP
    >>> tracks = track_video("clip.mp4", on_frame=kept)              # doctest: +SKIP
    >>> write_overlay(result, "clip.mp4", "overlay.mp4", frames=kept)  # doctest: +SKIP
    """

    #: bytes of scaled frames kept at most: 345 frames of 960 x 540
    BUDGET = 512 * 2**20

    def __init__(self, info, max_height: int | None = PANEL_SIDE, budget: int | None = None,
                 max_width: int | None = PANEL_SIDE, frames: int | None = None):
        self.size = _overlay_size(info.width, info.height, max_height, max_width)
        self.budget = self.BUDGET if budget is None else int(budget)
        self._kept: dict[int, np.ndarray] | None = {}
        self._lock = threading.Lock()
        self._cv2 = require_cv2()
        n = info.frames if frames is None else frames
        W, H = self.size
        self._store, self._mapping = None, None
        if n and n * W * H * 3 > self.budget:
            self._kept = None  # more than the budget holds: nothing kept, nothing mapped
        elif n:
            def mapped():
                try:
                    self._store = frame_store(n, H, W)
                except (MemoryError, ValueError):  # the frames then get arrays of their own, as they come
                    self._store = None

            self._mapping = threading.Thread(target=mapped, name="pinrecon-kept-frames", daemon=True)
            self._mapping.start()

    @property
    def frames(self) -> list[np.ndarray] | None:
        """The frames kept, from the first on as long as none is missing; None when they were let go."""
        kept = self._kept
        if kept is None:
            return None
        out = []
        while len(out) in kept:
            out.append(kept[len(out)])
        return out

    def __call__(self, t: int, frame: np.ndarray) -> None:
        kept_so_far = self._kept  # (another thread may let them go meanwhile)
        if kept_so_far is None:
            return
        with self._lock:
            if self._mapping is not None:
                self._mapping.join()
                self._mapping = None
        if t in kept_so_far or (t + 1) * self.size[0] * self.size[1] * 3 > self.budget:
            self._kept = self._store = None  # over the budget (or a frame twice): the overlay decodes the video
            return
        W, H = self.size
        store = self._store
        into = store[t] if store is not None and t < len(store) else None
        if (W, H) != frame.shape[1::-1]:
            kept = self._cv2.resize(frame, (W, H), dst=into, interpolation=self._cv2.INTER_AREA)
        elif into is None:
            kept = frame.copy()
        else:
            into[...] = frame
            kept = into
        kept_so_far[t] = kept


def frame_store(n: int, height: int, width: int) -> np.ndarray:
    """An (n, height, width, 3) uint8 array whose memory is mapped in at once (Linux's
    ``MAP_POPULATE``: one call, not a page fault per 4 KiB page as the frames fill it, on the CPU
    the detector shares); a plain ``np.empty`` elsewhere."""
    size = n * height * width * 3
    populate = getattr(mmap, "MAP_POPULATE", None)
    if populate is None or size == 0:
        return np.empty((n, height, width, 3), np.uint8)
    try:
        m = mmap.mmap(-1, size, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS | populate)
    except OSError:  # pragma: no cover - no memory to map at once
        return np.empty((n, height, width, 3), np.uint8)
    return np.frombuffer(m, np.uint8).reshape(n, height, width, 3)


class _Encoder:
    """OpenCV's ``VideoWriter`` (``mp4v``) at ``path``, fed from a thread of its own: :meth:`write`
    hands a frame over (a few may wait) and returns, so the encoding, which lets go of the GIL,
    runs beside the caller's decoding and drawing; each frame is written from one of a few
    buffers (:meth:`canvas`) the caller fills and does not touch again. Leaving the block waits
    for every frame and releases the writer, raising what the thread raised (a refused file:
    :class:`~pinrecon.errors.InputError` naming ``named``)."""

    AHEAD = 4

    def __init__(self, cv2, path, fps: float, size: tuple[int, int], named):
        self.writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)
        if not self.writer.isOpened():
            raise InputError("OpenCV cannot write an MPEG-4 video there", file=named)
        W, H = size
        self.todo: queue.Queue = queue.Queue(maxsize=self.AHEAD)
        self.free: queue.Queue = queue.Queue()
        for _ in range(self.AHEAD + 2):
            self.free.put(np.empty((H, W, 3), np.uint8))
        self.failed: BaseException | None = None
        self.thread = threading.Thread(target=self._run, name="pinrecon-overlay-encoder", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while (frame := self.todo.get()) is not None:
            if self.failed is None:
                try:
                    self.writer.write(frame)
                except BaseException as exc:  # noqa: BLE001 - raised again in the caller's thread
                    self.failed = exc
            self.free.put(frame)

    def canvas(self) -> np.ndarray:
        """A buffer to draw the next frame into (once the thread is done with it)."""
        if self.failed is not None:
            raise self.failed
        return self.free.get()

    def write(self, frame: np.ndarray) -> None:
        self.todo.put(frame)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.todo.put(None)
        self.thread.join()
        self.writer.release()
        if self.failed is not None and exc[0] is None:
            raise self.failed


def write_overlay(
    result,
    video: str | os.PathLike,
    out_path: str | os.PathLike,
    *,
    camera_index: int = 0,
    tracks=None,
    max_height: int | None = PANEL_SIDE,
    max_width: int | None = PANEL_SIDE,
    second_view: float | None = None,
    progress: bool = False,
    frames: KeptFrames | None = None,
) -> Path:
    """Write the overlay video of ``result`` over ``video`` to ``out_path`` (``.mp4``).

    ``result`` : a :class:`~pinrecon.Result` (or a result NPZ path); ``camera_index`` picks
    which of its cameras filmed ``video`` (several-camera solves). ``tracks`` : that camera's
    :class:`~pinrecon.Tracks`, drawn as white rings. The video's frame ``t`` shows the result
    at the nearest time ``t / fps``; the overlay stops at the result's last frame (or the
    tracks' last). ``max_height``, ``max_width`` : each panel's largest size in pixels (the
    input is scaled down to fit, never up; ``None``: no bound; by default both
    :data:`PANEL_SIDE`). ``second_view`` : the side panel's angle about the up axis, degrees
    (default 90). ``frames``: the video's frames kept by :class:`KeptFrames` while the
    detector read it (the same sizes); used
    instead of decoding the video again when it holds every frame drawn. Returns the path written
    (atomically); the file holds one frame per input frame, ``2 W x H`` pixels after scaling.
    A frame the result saw no 2D point on (``result.observed_frames``: its motion carried by the
    smoothing, the limits and the prior) says so in both panels.
    """
    cv2 = require_cv2()
    if isinstance(result, (str, os.PathLike)):
        from ..result import load_result

        result = load_result(result)
    motion = as_motion(result)
    cams = list(getattr(result, "cameras", None) or [getattr(result, "camera", None)])
    if not 0 <= camera_index < len(cams) or cams[camera_index] is None:
        raise InputError(f"the result has {len(cams)} camera(s); no camera {camera_index}", field="camera_index")
    cam = cams[camera_index]
    info = video_info(video)
    W, H = _overlay_size(info.width, info.height, max_height, max_width)
    sx, sy = W / info.width, H / info.height

    sk = skeleton(motion.figure)
    P = skeleton_points(motion, sk, np.arange(len(motion.times)))  # (T, K + hubs, 3)
    uv_cam = cam.project(P) * [sx, sy]
    side = second_view_camera(cam, second_view, view_up(cam, motion.feet))  # levelled on the floor, as the plots
    uv_side = side.project(P)
    ok = np.all(np.isfinite(uv_side), axis=2)
    lo, hi = np.nanmin(uv_side[ok], axis=0), np.nanmax(uv_side[ok], axis=0)
    span = max(float(np.max(hi - lo)), 1e-6)
    zoom = 0.85 * min(W, H) / span
    uv_side = (uv_side - (lo + hi) / 2) * zoom + [W / 2, H / 2]
    colours = [LEFT_BGR if c == "L" else RIGHT_BGR if c == "R" else CENTRE_BGR for c in sk.side]
    seen = getattr(result, "observed_frames", None)
    seen = np.ones(len(motion.times), bool) if seen is None or len(seen) != len(motion.times) else np.asarray(seen)
    thick = max(2, round(H / 240))
    radius = max(3, round(H / 160))
    det = None
    if tracks is not None:
        det = np.asarray(tracks.points, float) * [sx, sy]
        det_ok = tracks.observed

    def draw(img, uv):
        pts = np.round(uv).astype(int)
        good = np.all(np.isfinite(uv), axis=1)
        for (a, b), col in zip(sk.edges, colours):
            if good[a] and good[b]:
                cv2.line(img, tuple(pts[a]), tuple(pts[b]), col, thick, cv2.LINE_AA)
        for k in range(sk.K):
            if good[k]:
                cv2.circle(img, tuple(pts[k]), radius, JOINT_BGR, -1, cv2.LINE_AA)

    def label(img, text):  # a line of text at a panel's top left
        cv2.putText(img, text, (10, 10 + 2 * radius + 10), cv2.FONT_HERSHEY_SIMPLEX, max(0.4, H / 1600),
                    (230, 230, 230), 1, cv2.LINE_AA)

    out_path = Path(out_path)
    # the frames the result covers (a --max-frames run stops there), or the tracks' frames
    n_frames = int(np.floor(motion.times[-1] * info.fps + 0.5)) + 1 if tracks is None else tracks.T
    if info.frames:
        n_frames = min(n_frames, info.frames)
    blank = np.full((H, W, 3), PANEL_BGR, np.uint8)  # copied whole: a fill by a colour triple costs 2 ms a frame
    right = np.empty((H, W, 3), np.uint8)  # the side panel, reused frame after frame
    kept = frames.frames if frames is not None and frames.size == (W, H) else None
    if kept is not None and len(kept) >= n_frames:
        source, owned = kept[:n_frames], False  # kept for others too: drawn on a copy
    else:  # decoded again and scaled in the decoding thread: frames of their own
        scale = (W, H) != (info.width, info.height)
        source = iter_frames(video, n_frames, ahead=4, prepare=(lambda t, frame: cv2.resize(
            frame, (W, H), interpolation=cv2.INTER_AREA)) if scale else None)
        owned = scale
    with atomic_path(out_path) as tmp, _Encoder(cv2, tmp, info.fps, (2 * W, H), out_path) as encoder, \
            FrameProgress(n_frames, f"overlay {out_path.name}", enabled=progress) as bar:
        for t, frame in enumerate(source):
            f = motion.frame_at(t / info.fps)
            if frame.shape[1::-1] != (W, H):
                left = cv2.resize(frame, (W, H), interpolation=cv2.INTER_AREA)
            else:
                left = frame if owned else frame.copy()
            if det is not None and t < len(det):
                for k in np.flatnonzero(det_ok[t]):
                    cv2.circle(left, tuple(np.round(det[t, k]).astype(int)), radius + 2, DETECTION_BGR, 1, cv2.LINE_AA)
            draw(left, uv_cam[f])
            np.copyto(right, blank)
            draw(right, uv_side[f])
            label(right, f"side view  t={motion.times[f]:.2f}s" + ("" if seen[f] else "  NOT OBSERVED"))
            if not seen[f]:  # no 2D point: the motion here is the solve's guess
                label(left, "not observed: the motion is carried by the smoothing")
            encoder.write(np.concatenate([left, right], axis=1, out=encoder.canvas()))
            bar.update()
    return out_path
