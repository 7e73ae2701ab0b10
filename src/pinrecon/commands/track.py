"""``pinrecon track VIDEO --out tracks.json``: MediaPipe Pose over a video, to a tracks file.

The file (pinrecon's tracks JSON, or NPZ for ``.npz``; ``docs/formats.md``) carries the 33
landmarks in pixels, their visibility as ``confidence`` and MediaPipe's 3D world landmarks
as the ``lifted`` block, so ``pinrecon reconstruct --tracks tracks.json`` uses all three.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from ..errors import InputError

__all__ = ["add_video_options", "check_video_options", "check_writable", "cmd_track", "register"]


def check_writable(path: str | os.PathLike, *, folder: bool = False) -> Path:
    """Fail early, before any work, when ``path`` (a file, or with ``folder`` a folder whose
    files will be written) cannot be written: one :class:`~pinrecon.errors.InputError`
    naming it. Creates missing folders."""
    path = Path(path)
    target = path if folder else path.parent
    if path.is_dir() and not folder:
        raise InputError("is a folder: give a file name", file=path, field="--out")
    if folder and path.exists() and not path.is_dir():
        raise InputError("exists and is not a folder", file=path, field="--out")
    try:
        target.mkdir(parents=True, exist_ok=True)
        probe = target / f".pinrecon-write-test-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise InputError(f"cannot write there ({exc.strerror or exc})", file=target, field="--out") from None
    return path


FPS_HELP = "the video's frame rate, when its file stores none or a wrong one"

#: the error of a video in which MediaPipe found nobody
NOBODY = ("MediaPipe found no person in any frame (it finds one who fills much of its image: a small "
          "person in a wide shot is missed; --crop X Y W H runs it on the part of the frame they move in)")


def add_video_options(p, *, fps: bool = True) -> None:
    """The detector's options, shared by ``track`` and ``video`` (``fps=False``: the parser
    has ``--fps`` already)."""
    if fps:
        p.add_argument("--fps", type=float, help=FPS_HELP)
    p.add_argument("--max-frames", type=int, metavar="N", help="only the first N frames")
    p.add_argument("--crop", type=int, nargs=4, metavar=("X", "Y", "W", "H"),
                   help="run the detector on this part of each frame only (pixels: left, top, width, height): "
                   "MediaPipe finds a person who fills much of its image and misses a small one in a wide shot; "
                   "the tracks stay in the whole frame's pixels")
    p.add_argument("--model-complexity", type=int, choices=(0, 1, 2), default=1,
                   help="MediaPipe Pose's model: 1 full (the default: in MediaPipe's wheel, offline), 0 lite or "
                   "2 heavy (MediaPipe downloads those on first use)")


def check_video_options(args) -> None:
    """``--max-frames`` and ``--fps`` in range, else one InputError (``--crop`` is checked
    against each video's frame: :func:`pinrecon.video.crop_box`)."""
    if args.max_frames is not None and args.max_frames < 1:
        raise InputError(f"must be at least 1, got {args.max_frames}", field="--max-frames")
    if args.fps is not None and not 0 < args.fps < 1e4:
        raise InputError(f"must be a frame rate in (0, 10000), got {args.fps}", field="--fps")


def cmd_track(args) -> int:
    from ..video import crop_box, require_mediapipe, track_video, video_info

    check_video_options(args)
    require_mediapipe()
    check_writable(args.out)
    if Path(args.out).suffix.lower() not in (".json", ".npz"):
        raise InputError("the tracks file is .json or .npz", file=args.out, field="--out")
    info = video_info(args.video, fps=args.fps)
    crop_box(args.crop, info, field="--crop")
    t0 = time.perf_counter()
    tracks = track_video(args.video, fps=args.fps, max_frames=args.max_frames,
                         model_complexity=args.model_complexity, progress=not args.quiet, info=info,
                         crop=args.crop)
    dt = time.perf_counter() - t0
    tracks.save(args.out)
    seen = int(tracks.observed.any(axis=1).sum())
    if not seen:  # said also with --quiet: the file holds no point
        print(f"pinrecon track: warning: {NOBODY}", file=sys.stderr)
    if not args.quiet:
        print(f"pinrecon track: {tracks.T} frames of {info.width} x {info.height} at {tracks.fps:g} fps in {dt:.1f} s "
              f"({tracks.T / max(dt, 1e-9):.1f} frames/s); a person in {seen} of them", file=sys.stderr)
        print(f"wrote {args.out}", file=sys.stderr)
    return 0


def register(sub) -> None:
    p = sub.add_parser("track", help="MediaPipe Pose over a video: 2D landmarks, visibility and MediaPipe's 3D "
                       "to a tracks file (the optional 'video' extra)")
    p.add_argument("video", help="video file (anything OpenCV reads: MP4, MOV, AVI ...)")
    p.add_argument("--out", required=True, help="tracks file to write: .json or .npz (docs/formats.md)")
    add_video_options(p)
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=cmd_track)
