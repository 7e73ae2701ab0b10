"""pinrecon: reconstruct the 3D motion of an articulated figure from 2D joint tracks.

Quick use::

    import pinrecon
    fig = pinrecon.Figure.human()                      # or Figure.from_urdf / from_bvh
    tracks = pinrecon.load_tracks("tracks.json")
    cam = pinrecon.load_camera("camera.json")          # or Calib.toml, name="cam01"
    result = pinrecon.reconstruct(fig, tracks, cam, pinrecon.load_keyframes("keys.json"))
    result.save("result.npz")
"""

from .cameras import Orthographic, Perspective
from .errors import InputError, PinreconError, UnknownNameError
from .figure import Figure, Keypoint, load_keypoint_map
from .io.calibration import load_camera, load_cameras
from .problem import Weights
from .reconstruct import reconstruct, reconstruct_markers
from .result import Result, load_result
from .solver import SolverOptions
from .tracks import Keyframe, Keyframes, Markers, Tracks, load_keyframes, load_tracks

__version__ = "0.1.0"

__all__ = [
    "Figure",
    "Keypoint",
    "load_keypoint_map",
    "Orthographic",
    "Perspective",
    "load_camera",
    "load_cameras",
    "Tracks",
    "Markers",
    "Keyframe",
    "Keyframes",
    "load_tracks",
    "load_keyframes",
    "reconstruct",
    "reconstruct_markers",
    "Result",
    "load_result",
    "Weights",
    "SolverOptions",
    "PinreconError",
    "InputError",
    "UnknownNameError",
]
