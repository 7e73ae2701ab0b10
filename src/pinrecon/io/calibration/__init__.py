"""Camera calibration files as other tools write them: Pose2Sim / Sports2D TOML, OpenCV
FileStorage YAML / XML / JSON and plain OpenCV-style JSON or YAML, and pinrecon's own
camera JSON. ``load_cameras(path)`` reads every camera of a file, ``load_camera(path,
name=None)`` one camera. The formats and conventions are in :mod:`.readers` and
``docs/formats.md`` section 5.1; :mod:`.opencv_storage` parses OpenCV's FileStorage text.
"""

from .readers import (
    SUPPORTED_FORMATS,
    CalibratedCamera,
    load_camera,
    load_cameras,
    rodrigues_to_matrix,
)

__all__ = [
    "CalibratedCamera",
    "load_cameras",
    "load_camera",
    "rodrigues_to_matrix",
    "SUPPORTED_FORMATS",
]
