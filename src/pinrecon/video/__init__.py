"""Video in: frames through OpenCV, MediaPipe Pose per frame, :class:`~pinrecon.Tracks` out.

The optional ``video`` extra (``pip install ".[video]"`` from a checkout: MediaPipe 0.10.14, OpenCV,
tqdm)::

    from pinrecon.video import track_video
    tracks = track_video("clip.mp4", progress=True)   # 33 landmarks in pixels, visibility,
    tracks.lifted                                     # and MediaPipe's 3D (pinrecon.lifted.Lifted)
    tracks.save("tracks.json")

``pinrecon track VIDEO`` and ``pinrecon video VIDEO... --out DIR`` (which also reconstructs
and writes the exports and the overlay video, :func:`pinrecon.viz.overlay.write_overlay`)
call these. Without the extra, the functions raise :class:`MissingVideoExtraError` naming it.
"""

from .frames import (
    EXTRA_HINT,
    MIN_CROP,
    MissingVideoExtraError,
    VideoInfo,
    crop_box,
    iter_frames,
    require_cv2,
    video_info,
)
from .mediapipe_pose import (
    MAX_DETECTOR_THREADS,
    MEDIAPIPE_VERSION,
    SPLIT_FRAMES,
    MediaPipePose,
    detector_threads,
    require_mediapipe,
    track_parts,
    track_video,
)
from .progress import FrameProgress

__all__ = [
    "EXTRA_HINT",
    "MAX_DETECTOR_THREADS",
    "MEDIAPIPE_VERSION",
    "MIN_CROP",
    "SPLIT_FRAMES",
    "FrameProgress",
    "MediaPipePose",
    "MissingVideoExtraError",
    "VideoInfo",
    "crop_box",
    "detector_threads",
    "iter_frames",
    "require_cv2",
    "require_mediapipe",
    "track_parts",
    "track_video",
    "video_info",
]
