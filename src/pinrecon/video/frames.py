"""Video files through OpenCV: what a video is (size, rate, length) and its frames, one by one.

OpenCV (``cv2``) is the optional ``video`` extra's (``pip install ".[video]"`` from a checkout);
without it :func:`require_cv2` raises :class:`MissingVideoExtraError`, one line naming the
extra. A file OpenCV cannot decode, or one without frames, is one
:class:`~pinrecon.errors.InputError` naming the file.
"""

from __future__ import annotations

import os
import queue
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, PinreconError

__all__ = ["EXTRA_HINT", "MIN_CROP", "MissingVideoExtraError", "VideoInfo", "crop_box", "iter_frames", "require_cv2",
           "video_info"]

EXTRA_HINT = 'from a pinrecon checkout, pip install ".[video]"'


class MissingVideoExtraError(PinreconError, ImportError):
    """A package of the optional ``video`` extra (OpenCV, MediaPipe) is not installed."""


def require_cv2():
    """The ``cv2`` module, or :class:`MissingVideoExtraError` naming the extra."""
    try:
        import cv2
    except ImportError as exc:
        raise MissingVideoExtraError(f"reading and writing video needs OpenCV ({exc}): {EXTRA_HINT}") from None
    return cv2


@dataclass(frozen=True)
class VideoInfo:
    """A video's file, frame rate, frame size in pixels and frame count (as its container says;
    :func:`iter_frames` yields what decodes)."""

    path: str
    fps: float
    width: int
    height: int
    frames: int

    @property
    def image_size(self) -> tuple[int, int]:
        """``(width, height)`` in pixels, as ``--image-size`` takes it."""
        return self.width, self.height

    def frames_read(self, max_frames: int | None = None) -> int:
        """How many frames a pass of at most ``max_frames`` reads, as the container says: its
        count (0: it says none) up to ``max_frames``, or ``max_frames`` when it says none."""
        return self.frames if max_frames is None else min(self.frames or max_frames, max_frames)


def _open(path):
    cv2 = require_cv2()
    path = Path(path)
    if not path.exists():
        raise InputError("file not found", file=path)
    if path.is_dir():
        raise InputError("is a folder, not a video file", file=path)
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        cap.release()
        raise InputError("not a video OpenCV can read (an MP4, MOV, AVI ... file)", file=path)
    return cv2, cap


def video_info(path: str | os.PathLike, *, fps: float | None = None) -> VideoInfo:
    """Size, rate and length of the video at ``path``; ``fps`` replaces a container's missing
    or wrong rate. A file that is not a readable video, has no frame, or stores no rate (and
    ``fps`` is not given) raises :class:`~pinrecon.errors.InputError`."""
    cv2, cap = _open(path)
    try:
        ok, frame = cap.read()
        if not ok or frame is None:
            raise InputError("not a video OpenCV can read: no frame decodes", file=path)
        rate = float(cap.get(cv2.CAP_PROP_FPS) or 0.0) if fps is None else float(fps)
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    finally:
        cap.release()
    if not (np.isfinite(rate) and 0 < rate < 1e4):
        raise InputError(f"the video stores no usable frame rate ({rate:g}): give it (--fps)", file=path, field="fps")
    h, w = frame.shape[:2]
    return VideoInfo(str(path), rate, int(w), int(h), count)


#: a crop's least width and height in pixels
MIN_CROP = 16


def crop_box(crop, info: VideoInfo, *, field: str = "crop") -> tuple[int, int, int, int]:
    """``(x, y, w, h)`` of ``crop`` (the whole frame when None) inside the frame of the video
    ``info`` describes, at least :data:`MIN_CROP` pixels wide and high; else one
    :class:`~pinrecon.errors.InputError` naming the video and ``field``."""
    if crop is None:
        return 0, 0, info.width, info.height
    x, y, w, h = (int(v) for v in crop)
    if min(x, y) < 0 or min(w, h) < MIN_CROP:
        raise InputError(f"needs X, Y >= 0 and W, H >= {MIN_CROP} pixels, got {x} {y} {w} {h}", file=info.path,
                         field=field)
    if x + w > info.width or y + h > info.height:
        raise InputError(f"{x} {y} {w} {h} reaches outside the {info.width} x {info.height} frame", file=info.path,
                         field=field)
    return x, y, w, h


def iter_frames(path: str | os.PathLike, max_frames: int | None = None, *, ahead: int = 0,
                prepare: Callable[[int, np.ndarray], object] | None = None, start: int = 0) -> Iterator:
    """The video's frames in order, each an (H, W, 3) uint8 BGR array (OpenCV's order),
    at most ``max_frames`` (counted from the video's first frame). ``start``: the frames before
    frame ``start`` are decoded and dropped (no seek: the frame numbers are the decoder's own
    count, whatever the container's timestamps say). ``ahead`` > 0: a thread decodes up to that
    many frames ahead of the caller (OpenCV lets go of the GIL while it decodes, so the decoding
    runs beside the caller's own work on the frames). ``prepare(t, frame)``: what is yielded
    instead of frame ``t``, computed in that thread (with ``ahead`` > 0) as the frames decode, in
    order: work on the frames that lets go of the GIL (OpenCV's colour conversions, resizing)
    then runs beside the caller's."""
    _, cap = _open(path)
    frames_read = _read(cap, max_frames, start)
    if prepare is not None:
        frames_read = (prepare(t, frame) for t, frame in enumerate(frames_read, start=start))
    if ahead <= 0:
        try:
            yield from frames_read
        finally:
            cap.release()
        return
    frames: queue.Queue = queue.Queue(maxsize=ahead)
    stop = threading.Event()

    def reader():
        try:
            for frame in frames_read:
                while not stop.is_set():
                    try:
                        frames.put(frame, timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if stop.is_set():
                    return
            frames.put(_END)
        except BaseException as exc:  # noqa: BLE001 - raised again in the caller's thread
            frames.put(exc)
        finally:
            cap.release()

    thread = threading.Thread(target=reader, name="pinrecon-frames", daemon=True)
    thread.start()
    try:
        while True:
            item = frames.get()
            if item is _END:
                return
            if isinstance(item, BaseException):
                raise item
            yield item
    finally:  # the caller stopped early (or the frames ended): the reader stops and lets the file go
        stop.set()
        while thread.is_alive():
            try:
                frames.get(timeout=0.1)
            except queue.Empty:
                pass
        thread.join()


_END = object()


def _read(cap, max_frames: int | None, start: int = 0) -> Iterator[np.ndarray]:
    n = 0
    while n < start and (max_frames is None or n < max_frames):
        if not cap.grab():  # decoded, not converted to an image
            return
        n += 1
    while max_frames is None or n < max_frames:
        ok, frame = cap.read()
        if not ok:
            break
        yield frame
        n += 1
