"""Cameras as they come: a camera for tracks that have no calibration file, and the
focal length (or scale) started from the keyframes.

**The auto camera** (:func:`auto_camera`, ``reconstruct(..., camera="auto")``, CLI
``--camera auto``). One view of a moving figure does not fix everything about the
camera that filmed it, so the unknowns that are not observable are fixed by convention
(the gauge) and the observable ones are estimated:

* *Perspective* (the default): square pixels, no skew, the principal point at the image
  centre ``(W/2, H/2)``, no lens distortion, and the focal length from a default
  horizontal field of view :data:`DEFAULT_FOV_DEG` (60 degrees, a phone or webcam:
  ``f = W / 2 / tan(30 deg) = 0.866 W``); the focal length is then refined in the
  batch solve as a global unknown (:class:`~pinrecon.rows.CameraScale`).
* *Orthographic*: the scale (pixels per metre) from the tracks' spread against the
  figure's size, the image centre as the world origin's image; the scale is refined
  the same way.
* *Pose*: without 3D keyframes the camera's placement in the world is a pure gauge: the
  world is the camera's (optical centre at the origin, looking along world +Z, image
  up = world +Y). Where the subject stands (depth, heading) is estimated by the start
  from the tracks and the figure's size. The camera's height and tilt above the floor
  are not observable from joint tracks alone; ``pinrecon export`` levels the motion on
  the floor under the feet afterwards. With point keyframes (3D positions in a world of
  the user's) the camera's rotation, position and focal length are estimated from the
  keyframes and the tracks at those frames (:func:`camera_from_keyframes`: a direct
  linear transform refined on the reprojection error), or, where they cannot fix the
  focal length, the rotation and position alone at the default focal length
  (:func:`camera_pose_from_keyframes`); :func:`pinrecon.reconstruct`
  then refines the pose with the tracks of every frame, as six more globals of the batch
  solve (``docs/globals.md``, section 4).

What stays unobservable (``docs/globals.md``, section 4): with neither keyframes nor a
known figure size, overall size against distance (perspective) or scale
(orthographic): the prior on the figure's proportions (or the figure as given) fixes
it; and focal length against distance is only weakly observable, through the
perspective within the figure (its depth extent against its distance).
:func:`focal_profile` measures it after each auto solve (the MAP cost profiled over the
focal length) and :func:`check_focal` warns (:class:`FocalLengthWarning`) when the
tracks do not fix it; on issue 12's CMU walk without keyframes they do not.

The geometry of cameras from keyframes lives in :mod:`pinrecon.starts.camera_keyframes`
(its functions are importable from here too).

**Focal length from keyframes** (:func:`camera_scale_from_keyframes`): a given camera
whose focal length (or scale) is to be calibrated starts from the least-squares value
that best projects the point keyframes onto the tracks at the keyed frames (closed
form), so the batch solve starts near it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..cameras import Orthographic, Perspective, look_at_rotation
from ..errors import InputError
from ..processes import Beside, forkable
from .camera_keyframes import (
    PROFILE_THRESHOLD,
    camera_from_keyframes,
    camera_pose_from_keyframes,
    camera_scale_from_keyframes,
    keyframe_correspondences,
    keyframe_focal_interval,
    orthographic_from_keyframes,
)

__all__ = [
    "DEFAULT_FOV_DEG",
    "AutoCamera",
    "FocalLengthWarning",
    "FocalReport",
    "auto_camera",
    "camera_from_keyframes",
    "camera_pose_from_keyframes",
    "camera_scale_from_keyframes",
    "check_focal",
    "doubt_focal",
    "fitted_focal",
    "focal_profile",
    "image_size_of",
    "implausible_focal",
    "keyframe_correspondences",
    "keyframe_focal_interval",
    "orthographic_from_keyframes",
    "placed_by_keyframes",
    "profile_interval",
    "settle_focal",
    "stretch_depth",
]

#: default horizontal field of view of the auto perspective camera, degrees
DEFAULT_FOV_DEG = 60.0

#: the auto camera's rotation world -> camera: looking along world +Z, world +Y up
R_AUTO = look_at_rotation((0.0, 0.0, 1.0), (0.0, 1.0, 0.0))


@dataclass(frozen=True)
class AutoCamera:
    """A camera to be estimated (``reconstruct(..., camera=AutoCamera(...))``; the string
    ``"auto"`` is ``AutoCamera()``).

    image_size : (W, H) pixels; default: the tracks' own (``tracks.image_size``), else an
        error asking for it.
    projection : ``"perspective"`` or ``"orthographic"``.
    fov_deg : the perspective camera's starting horizontal field of view, degrees.
    """

    image_size: tuple[float, float] | None = None
    projection: str = "perspective"
    fov_deg: float = DEFAULT_FOV_DEG

    def __post_init__(self):
        if self.projection not in ("perspective", "orthographic"):
            raise InputError(f"must be 'perspective' or 'orthographic', got {self.projection!r}", field="projection")
        if not (isinstance(self.fov_deg, (int, float)) and 1.0 <= float(self.fov_deg) <= 170.0):
            raise InputError(f"must be a field of view in degrees between 1 and 170, got {self.fov_deg!r}",
                             field="fov_deg")
        if self.image_size is not None:
            object.__setattr__(self, "image_size", _check_size(self.image_size))

    @classmethod
    def parse(cls, spec, **kw) -> AutoCamera | None:
        """``AutoCamera`` for ``"auto"``, ``"auto:perspective"``, ``"auto:orthographic"`` or
        an ``AutoCamera``; ``None`` for anything else (a real camera)."""
        if isinstance(spec, AutoCamera):
            return spec
        if isinstance(spec, str) and spec.split(":")[0] == "auto":
            proj = spec.split(":", 1)[1] if ":" in spec else kw.pop("projection", "perspective")
            return cls(projection=proj, **kw)
        return None


def _check_size(size) -> tuple[float, float]:
    try:
        w, h = (float(v) for v in size)
    except (TypeError, ValueError):
        raise InputError(f"must be two numbers W H (pixels), got {size!r}", field="image_size") from None
    if not (np.isfinite(w) and np.isfinite(h) and w >= 16 and h >= 16):
        raise InputError(f"must be two positive sizes W H of at least 16 px, got {size!r}", field="image_size")
    return (w, h)


def image_size_of(tracks, image_size=None) -> tuple[float, float]:
    """``image_size`` if given, else the tracks' own ``image_size`` attribute when they
    carry one; otherwise a clear error (the principal point is the image centre)."""
    if image_size is not None:
        return _check_size(image_size)
    own = getattr(tracks, "image_size", None)
    if own is not None:
        return _check_size(own)
    raise InputError(
        "the auto camera needs the image size (its centre is the principal point) and these tracks do not "
        "carry one: pass image_size=(W, H) (CLI: --image-size W H)",
        file=getattr(tracks, "source", None),
        field="image_size",
    )


#: log focal length steps of the profile, outwards from the fitted value (0.1: about 10 %)
PROFILE_STEPS = (0.1, 0.3, 0.6)


def placed_by_keyframes(camera) -> bool:
    """Whether :func:`auto_camera` placed ``camera`` in the keyframes' world, rather than
    returning the gauge camera (rotation ``R_AUTO``, at the origin: the world is then the
    camera's)."""
    R = np.asarray(camera.R, float)
    if isinstance(camera, Perspective):
        return not (np.array_equal(R, R_AUTO) and not np.any(np.asarray(camera.t, float)))
    return not np.array_equal(R, R_AUTO)


def _figure_height_m(figure, names: Sequence[str]) -> float:
    """Extent (metres) of the figure's rest pose over the named keypoints (its largest
    axis-aligned spread): the size the tracks' spread is compared with."""
    from ..problem import rest_pose

    P = figure.keypoints(rest_pose(figure))[figure.keypoint_index(list(names))]
    return float(np.ptp(P, axis=0).max())


def auto_camera(tracks, figure=None, image_size=None, projection: str = "perspective", *,
                fov_deg: float = DEFAULT_FOV_DEG, keyframes=None):
    """A starting camera for ``tracks`` without a calibration (see the module docstring).

    ``image_size`` (W, H) defaults to the tracks' own. Perspective: principal point at
    the image centre, focal length ``W / 2 / tan(fov_deg / 2)``, at the world origin
    looking along +Z (Y up); with 6 or more point-keyframe correspondences that fix the
    focal length (its profile bounded on both sides: :func:`keyframe_focal_interval`),
    rotation, position and focal length from them (:func:`camera_from_keyframes`); else,
    with 4 or more, rotation and position at that focal length
    (:func:`camera_pose_from_keyframes`). :func:`placed_by_keyframes` tells the cases apart. Orthographic:
    the same rotation, the scale from the tracks' median per-frame spread against the
    ``figure``'s rest-pose extent over the tracked points (keyframes, when given, fit the
    scale and centre; :func:`camera_scale_from_keyframes`), the image centre as the
    world origin's image.
    """
    spec = AutoCamera(image_size, projection, fov_deg)
    W, H = image_size_of(tracks, spec.image_size)
    centre = np.array([W / 2.0, H / 2.0])
    X, uv = keyframe_correspondences(tracks, keyframes)
    if spec.projection == "perspective":
        f = (W / 2.0) / np.tan(np.radians(spec.fov_deg) / 2.0)
        cam = camera_from_keyframes(X, uv, (W, H), f) if len(X) >= 6 else None
        if cam is not None and all(keyframe_focal_interval(X, uv, cam)[1]):
            return cam  # the keyframes fix the focal length as well as the pose
        if len(X) >= 4:  # they place the camera at the default focal length (the solve refines both)
            posed = camera_pose_from_keyframes(X, uv, (W, H), f, rotations=() if cam is None else (cam.R,))
            if posed is not None:
                return posed
        K = np.array([[f, 0.0, centre[0]], [0.0, f, centre[1]], [0.0, 0.0, 1.0]])
        return Perspective(K, R_AUTO, np.zeros(3))
    if figure is None:
        raise InputError("the orthographic auto camera needs the figure (its size sets the scale)", field="figure")
    names = [n for n in tracks.names if n in figure.keypoint_names]
    if not names:
        raise InputError("the tracks share no point with the figure", file=getattr(tracks, "source", None),
                         field="names")
    tracked_px = tracks.select(names).points  # (T, K, 2); uv stays the keyframes' correspondences
    seen = np.isfinite(tracked_px[..., 0]).sum(axis=1) >= 2
    spread_px = float("nan")
    if seen.any():
        spread = np.nanmax(tracked_px[seen], axis=1) - np.nanmin(tracked_px[seen], axis=1)  # (T', 2)
        spread_px = float(np.median(spread.max(axis=1)))
    size_m = _figure_height_m(figure, names)
    if not (np.isfinite(spread_px) and spread_px > 0 and size_m > 0):
        raise InputError("the tracks have no frame with two or more points to size the camera",
                         file=getattr(tracks, "source", None), field="points")
    if len(X) >= 4:
        cam = orthographic_from_keyframes(X, uv)
        if cam is not None:
            return cam
    return Orthographic(R_AUTO, spread_px / size_m, centre)


# ----------------------------------------------------------------------------- how well the data fix f
class FocalLengthWarning(UserWarning):
    """The tracks do not determine the auto camera's focal length (see :func:`focal_profile`),
    or it ended where no camera without a fisheye lens is (:func:`implausible_focal`)."""


#: focal lengths, in image diagonals, of the widest and the longest lens an auto camera's fit is
#: taken from without a warning: fields of view of about 127 and 8 degrees across the diagonal
FOCAL_DIAGONALS = (0.25, 6.0)


def implausible_focal(f_px: float, image_size) -> str | None:
    """What is wrong with a fitted focal length ``f_px`` for an image of ``image_size`` (W, H)
    pixels when it lies outside :data:`FOCAL_DIAGONALS`, else None. A fit that wide means
    the solve bent the figure's depths and lengths to a camera no phone or camcorder has (on
    the bench's fast spin, 239 px for 1920 x 1080 with a forearm measured at half the
    figure's)."""
    diag = float(np.hypot(*image_size))
    lo, hi = FOCAL_DIAGONALS
    if lo * diag <= f_px <= hi * diag:
        return None
    fov = float(np.degrees(2.0 * np.arctan(diag / 2.0 / f_px)))
    return (f"the auto camera's focal length ended at {f_px:.0f} px, {f_px / diag:.2f} image diagonals (a field of "
            f"view of {fov:.0f} degrees across the image): {'wider than any lens but a fisheye' if f_px < lo * diag else 'longer than a telephoto'}; "
            "the solution is likely degenerate (depths and limb lengths bent to fit). Give the field of view "
            "(--fov), a calibrated camera (--camera FILE) or 3D keyframes")


@dataclass
class FocalReport:
    """How well a solve's tracks fix the auto camera's focal length.

    focal_px : the fitted focal length (the solve's); start_px : where it started.
    profile : ``(focal_px, cost)`` pairs, the MAP cost with the focal length held at each
        value and everything else re-solved (``cost`` at ``focal_px`` is the solve's).
    interval_px : (low, high): determined, the focal lengths whose profiled cost stays
        within ``threshold`` of the lowest; not determined, the whole tested range (nothing
        in it is ruled out; ``bounded`` False). See :func:`profile_interval`.
    depth_ratio : the root's largest over smallest depth from the camera (a number
        that does not depend on f): how far the subject walks towards or away from it.
    determined : the interval lies within ``tolerance`` of ``focal_px`` on both sides.
    """

    focal_px: float
    start_px: float
    profile: list
    interval_px: tuple
    bounded: tuple
    depth_ratio: float
    determined: bool
    tolerance: float
    threshold: float = PROFILE_THRESHOLD
    #: with the camera placed by point keyframes and held there (a solve that does not refine its
    #: pose, :func:`pinrecon.reconstruct._pose_unknown`): their own profile
    #: (:func:`keyframe_focal_interval`, ``{"interval_px", "bounded", "points", "frames"}``): the
    #: interval is then the envelope of both, and not determined when theirs is too wide. With its
    #: pose refined by the solve, the solve's profile (the pose re-solved at every focal length,
    #: the keyframe rows in the cost) says it alone, unless it ends outside the keyframes' own
    #: interval (bounded on both sides, by more than ``tolerance``): then ``keyframes`` holds theirs
    #: with ``"excludes_fit": True``, the interval is theirs and the focal length not determined
    #: (the solve's profile valley is the pose prior's, :func:`doubt_focal`)
    keyframes: dict | None = None
    #: ``(lo, hi)``: the profile was taken on frames ``lo .. hi - 1`` alone (a long clip's
    #: stretch, :func:`settle_focal`'s ``profile_frames``), None: on the whole clip
    frames: tuple | None = None

    def message(self) -> str:
        lo, hi = self.interval_px
        if self.keyframes is not None and self.keyframes.get("excludes_fit"):
            k = self.keyframes
            return (f"the focal length is NOT determined: the point keyframes alone ({k['points']} points on "
                    f"{k['frames']} frames, their reprojection profile) put it at {lo:.0f}-{hi:.0f} px (95 %), and the "
                    f"solve with the tracks moved it to {self.focal_px:.0f} px, outside that: one view fixes it only "
                    "through the pose prior, which has pulled it away from the keyframes (as it does where the poses "
                    "are unlike its clips). Give a calibrated camera (--camera FILE) or more 3D keyframes, spread over "
                    "the clip and in depth, for a metric focal length")
        if self.keyframes is not None and self.determined:
            return (f"focal length {self.focal_px:.0f} px (started at {self.start_px:.0f} px), {lo:.0f} to {hi:.0f} px "
                    "at 95 % (the MAP cost profile, and the point keyframes' own, which place the camera)")
        if self.keyframes is not None:
            k = self.keyframes
            return (f"the focal length is NOT determined: the point keyframes ({k['points']} points on "
                    f"{k['frames']} frames) place the camera and fix its focal length, which trades off against its "
                    f"distance, only to {lo:.0f}-{hi:.0f} px" + ("" if all(self.bounded) else " or beyond")
                    + f" (95 %, their reprojection profile); the fit, {self.focal_px:.0f} px, keeps the camera where "
                    "they put it. Give a calibrated camera (--camera FILE) or point keyframes on more frames")
        costs = [c for _, c in self.profile]
        low_f = self.profile[int(np.argmin(costs))][0]
        along = "the clip" if self.frames is None else \
            f"frames {self.frames[0]}-{self.frames[1] - 1}, where the profile was taken (a long clip's stretch)"
        tail = (f"; the subject's depth changes by a factor {self.depth_ratio:.2f} along {along}"
                + (" (hardly at all: nothing ties f to the depths)" if self.depth_ratio < 1.1 else ""))
        if self.determined:
            return (f"focal length {self.focal_px:.0f} px (started at {self.start_px:.0f} px), "
                    f"{lo:.0f} to {hi:.0f} px at 95 % (MAP cost profile){tail}")
        return (f"the focal length is NOT determined by these tracks: fitted {self.focal_px:.0f} px (started at "
                f"{self.start_px:.0f} px) but the MAP cost profile rules out nothing from {lo:.0f} to {hi:.0f} px "
                f"(it moves by {max(costs) - min(costs):.1f} over that range, lowest at {low_f:.0f} px, and is not "
                f"one valley {self.threshold:g} deep within {100 * self.tolerance:.0f} % of the fit){tail}. "
                "Give a calibrated camera (--camera FILE) or 3D keyframes (on more frames, if some are given) for a "
                "metric focal length")

    def to_dict(self) -> dict:
        return {"focal_px": self.focal_px, "start_px": self.start_px,
                "profile": [[float(f), float(c)] for f, c in self.profile],
                "interval_px": [float(v) for v in self.interval_px], "bounded": [bool(b) for b in self.bounded],
                "depth_ratio": self.depth_ratio, "determined": self.determined, "tolerance": self.tolerance,
                "threshold": self.threshold, "message": self.message(),
                **({"keyframes": self.keyframes} if self.keyframes is not None else {}),
                **({"frames": [int(f) for f in self.frames]} if self.frames is not None else {})}


def stretch_depth(Q, camera, k: float) -> np.ndarray:
    """``Q`` with its root moved along the camera's depth axis by the factor ``k`` about
    the optical centre (``z_cam -> k z_cam``, ``x_cam`` and ``y_cam`` kept): what a focal
    length ``k`` times longer does to a reconstruction that keeps the image scale
    ``f / z`` of every frame."""
    out = np.array(Q, float)
    p_cam = camera.camera_points(out[:, :3])
    p_cam[:, 2] *= k
    out[:, :3] = (p_cam - np.asarray(camera.t, float)) @ np.asarray(camera.R, float)
    return out


def focal_profile(problem, res, *, steps: Sequence[float] = PROFILE_STEPS, tolerance: float = 0.1,
                  threshold: float = PROFILE_THRESHOLD, options=None) -> FocalReport | None:
    """The profile of the MAP cost over the focal length of ``problem``'s (first, perspective)
    camera around the solution ``res``, and the :class:`FocalReport` it gives.

    For each log step ``d`` in ``+-steps`` (outwards, each from its neighbour's solution),
    the focal length is held at ``fitted * exp(d)`` and the trajectory (and any other
    global, e.g. the proportions) re-solved warm from the neighbour's solution with the
    root's depth stretched by the same factor (:func:`stretch_depth`: the image scale of
    every frame kept), so every point of the profile lies on the same branch of poses.
    ``None`` when the problem does not calibrate a perspective camera.

    What fixes f (``docs/globals.md``, section 4): with the figure's size known, each
    frame's image scale fixes ``z / f`` and the lateral and vertical positions in metres,
    whatever f; only the depths scale with f. So f is seen only where the figure's 3D
    shape meets its depth: the perspective within the figure (parts nearer the camera look
    larger), and the depth its limbs span by foreshortening (a limb's image length against
    its 3D length) against the distance its root travels in depth. Both are weak: a limb
    tilted 17 degrees out of the image plane gains 11 % depth for a 1 % longer limb, so
    the generic figure's proportions bias f by more than 10 %; a subject who keeps his
    distance (``depth_ratio`` near 1) gives no travel at all. The profile measures what
    the data say instead of assuming it; the interval is reported, not a guess.
    """
    solves = _profile_solves(problem, res, steps, options)
    if solves is None:
        return None
    return _report(problem, res, solves, threshold, tolerance)


def _focal_of(problem, res):
    """(intrinsics, fitted g) of the solve's auto focal length, or None."""
    from ..solver import globals_of

    views = getattr(problem, "views", None) or []
    g = globals_of(res)
    if not views or g is None:
        return None
    intr = views[0].measurement.intrinsics if views[0].measurement is not None else None
    if intr is None or intr.name != "log_focal":
        return None
    return intr, np.array(g, float)


def fitted_focal(problem, res) -> float | None:
    """The auto camera's focal length (px) in the solve ``res`` of ``problem``, or None when the
    focal length is not one of its unknowns."""
    of = _focal_of(problem, res)
    return None if of is None else float(of[0].value(of[1]))


def _profile_solves(problem, res, steps, options):
    """The profile's solves: ``[(focal_px, cost, Q, g)]``, the fit first; None without an
    auto focal length. The longer focal lengths are solved in a child process beside the
    shorter ones where one can be forked (:class:`~pinrecon.processes.Beside`)."""
    of = _focal_of(problem, res)
    if of is None:
        return None
    intr, g_fit = of
    first = [(intr.value(g_fit), float(res.cost), np.asarray(res.x, float), g_fit)]
    with Beside(_profile_side, problem, res, intr, g_fit, steps, options, 1.0, fork=forkable(problem.n_frames)) as longer:
        shorter = _profile_side(problem, res, intr, g_fit, steps, options, -1.0)
        return first + longer.result() + shorter


def profile_stretch(problem, res, n: int | None, options=None, frames: tuple | None = None):
    """``(problem, solve, (lo, hi))`` of a long clip's stretch of ``n`` frames for the focal
    length's profile: the frames ``lo .. hi - 1`` (``frames``, or those where the root's depth
    from the camera changes most, by its largest over smallest depth), cropped with every
    estimated lifter rotation held at the whole clip's (:meth:`~pinrecon.problem.
    ReconstructionProblem.cropped`) and solved from the clip's solution there. None for a clip
    of at most ``n`` frames, with keyframes (they place the camera over the whole clip), or
    when the stretch cannot be cropped."""
    from ..solver import solve

    T, of = problem.n_frames, _focal_of(problem, res)
    if n is None or T <= n or of is None or len(getattr(problem, "keyframes", None) or ()):
        return None
    intr, g_fit = of
    if frames is None:
        z = intr.camera(g_fit).depth(np.asarray(res.x, float)[:, :3])
        z = np.where(z > 1e-6, z, np.nan)
        starts = sorted({*range(0, T - n + 1, max(1, n // 4)), T - n})
        spread = [np.nanmax(z[a:a + n]) / np.nanmin(z[a:a + n]) if np.isfinite(z[a:a + n]).any() else 0.0
                  for a in starts]
        first = starts[int(np.argmax(spread))]
        frames = (first, first + n)
    lo, hi = frames
    part = problem.cropped(lo, hi, problem.state(res.x, False, g=g_fit))
    if part is None:
        return None
    return part, solve(part, np.asarray(res.x, float)[lo:hi], options, active=part.active, g0=g_fit), (lo, hi)


def _profile_side(problem, res, intr, g_fit, steps, options, sign: float):
    """The profile's solves on one side of the fit (``sign`` 1: longer focal lengths), each
    from the one before it."""
    from ..solver import solve

    col = intr.col
    f_fit = intr.value(g_fit)
    cam_fit = intr.camera(g_fit)
    frozen = np.ones(len(g_fit), bool)
    frozen[col] = False
    out = []
    Q, gg, last = np.array(res.x, float), g_fit.copy(), 0.0
    for d in sorted(steps):
        gg = gg.copy()
        gg[col] = g_fit[col] + sign * d
        Q = stretch_depth(Q, cam_fit, float(np.exp(sign * d - last)))
        r = solve(problem, Q, options, active=problem.active, g0=gg, active_globals=frozen)
        Q, last = r.x, sign * d
        if r.g is not None and len(r.g):
            gg = np.array(r.g, float)
        out.append((float(f_fit * np.exp(sign * d)), float(r.cost), Q, gg))
    return out


def _report(problem, res, solves, threshold, tolerance) -> FocalReport:
    intr, g_fit = _focal_of(problem, res)
    f_fit = intr.value(g_fit)
    cam_fit = intr.camera(g_fit)
    points = [(f, c) for f, c, _, _ in solves]
    interval, bounded, determined = profile_interval(points, f_fit, threshold=threshold, tolerance=tolerance)
    z = cam_fit.depth(np.asarray(res.x, float)[:, :3])
    z = z[z > 1e-6]
    ratio = float(z.max() / z.min()) if len(z) else 1.0
    return FocalReport(float(f_fit), float(intr.value(np.zeros_like(g_fit))), sorted(points), interval, bounded,
                       ratio, determined, float(tolerance), float(threshold))


def profile_interval(points, f_fit: float, *, threshold: float = PROFILE_THRESHOLD, tolerance: float = 0.1):
    """``(interval_px, bounded, determined)`` from a cost profile ``points`` ((focal_px,
    cost) pairs, the fitted ``f_fit`` among them).

    The profile *determines* f when it is one valley (falling, then rising) whose lowest
    point is the fit, not at either end, and rises by more than ``threshold`` at the
    tested values next to the fit on both sides, which lie within ``tolerance`` (at
    least a log step of 0.1) of it. Then the interval is where the parabola in log f
    through the lowest point and its two neighbours crosses ``lowest + threshold``: the
    statistical uncertainty of the MAP (the model, e.g. the figure's proportions, taken as
    right; a wrong model can bias f by more than the interval says).
    Otherwise nothing in the tested range is ruled out: a profile that jumps between
    branches of poses, or rises less than ``threshold`` across the tested range, or keeps
    falling past its end cannot put f anywhere, and the interval is the whole tested
    range (``bounded`` False on both sides)."""
    pts = sorted((float(f), float(c)) for f, c in points)
    f_arr = np.array([p[0] for p in pts])
    c_arr = np.array([p[1] for p in pts])
    i0 = int(np.argmin(np.abs(np.log(f_arr / f_fit))))
    best = int(np.argmin(c_arr))
    unimodal = bool(np.all(np.diff(c_arr[: best + 1]) <= 0) and np.all(np.diff(c_arr[best:]) >= 0))
    level = c_arr[best] + threshold
    near = 0 < best < len(f_arr) - 1 and best == i0
    close = near and f_arr[best - 1] >= f_fit / np.exp(max(tolerance, 0.1) + 1e-9) \
        and f_arr[best + 1] <= f_fit * np.exp(max(tolerance, 0.1) + 1e-9)
    determined = bool(unimodal and close and c_arr[best - 1] > level and c_arr[best + 1] > level)
    if not determined:
        return (float(f_arr[0]), float(f_arr[-1])), (False, False), False

    # the parabola in log f through the lowest point and its two neighbours (exact for a
    # quadratic profile; a chord would cut the valley narrower than it is)
    x = np.log(f_arr[best - 1: best + 2] / f_arr[best])
    a2, a1, a0 = np.polyfit(x, c_arr[best - 1: best + 2], 2)
    disc = np.sqrt(a1 * a1 - 4.0 * a2 * (a0 - level))
    roots = np.sort([(-a1 - disc) / (2.0 * a2), (-a1 + disc) / (2.0 * a2)])

    def cross(i):
        return float(f_arr[best] * np.exp(roots[i]))

    return (cross(0), cross(1)), (True, True), True


def doubt_focal(auto: dict | None, unfamiliar_share: float, *, limit: float = 0.5,
                broader: str | None = None) -> dict | None:
    """The auto camera's description ``auto`` with its focal report marked NOT determined
    (and a :class:`FocalLengthWarning`) when more than ``limit`` of the frames' poses are
    unlike the pose prior's clips (``unfamiliar_share``, :mod:`pinrecon.unfamiliar`): one
    view fixes the focal length only through the prior (the valley of its cost profile is
    the prior's), which there extrapolates. Pose2Sim's real balancing trial, every frame
    unlike the prior, fitted 960 px "927-987 at 95 %" against its calibration's 1681 px.
    With ``broader``, the share is the default prior's, and the clip was solved again with
    that broader prior (:func:`pinrecon.unfamiliar.broader_prior`), whose valley is no surer:
    bench_real's dance (05_11, first and last keyframes at 60 degrees, no camera file) fitted
    1528 px "1525-1688 px at 95 %" against a true 1200.
    Unchanged when the focal length was not determined anyway, or point keyframes fixed it."""
    focal = (auto or {}).get("focal")
    if not isinstance(focal, dict) or not focal.get("determined") or focal.get("keyframes") or \
            not unfamiliar_share > limit:
        return auto
    lo, hi = focal["interval_px"]
    keyed = str(auto.get("pose", "")).startswith("from the point keyframes")
    why = (f"the default pose prior did not know {100 * unfamiliar_share:.0f} % of the frames' poses (the clip was "
           f"solved with the broader {broader}, a fallback no surer of them)" if broader else
           f"{100 * unfamiliar_share:.0f} % of the frames' poses are unlike its clips")
    msg = (f"the focal length is NOT determined: one view fixes it only through the pose prior, and {why}; "
           f"fitted {focal['focal_px']:.0f} px, which the MAP cost profile put at {lo:.0f}-{hi:.0f} px (95 %) taking the "
           f"prior as right. Give a calibrated camera (--camera FILE) or "
           f"{'more 3D keyframes, spread over the clip and in depth,' if keyed else '3D keyframes'}"
           " for a metric focal length")
    import warnings

    warnings.warn(msg, FocalLengthWarning, stacklevel=3)
    return {**auto, "focal": {**focal, "determined": False, "message": msg,
                              "unfamiliar_share": float(unfamiliar_share)}}


def check_focal(problem, res, auto: dict | None, **kw) -> dict | None:
    """The auto camera's description ``auto`` with ``"focal"``, the :class:`FocalReport`
    of :func:`focal_profile` as plain data, when the auto camera is perspective and its
    focal length was a global of the solve ``res``; warns
    (:class:`FocalLengthWarning`) when the tracks do not determine it. The solve is left
    where it is (:func:`settle_focal` with no round; ``kw``: its profile's arguments)."""
    return settle_focal(problem, res, auto, rounds=0, **kw)[1]


def settle_focal(problem, res, auto: dict | None, *, options=None, rounds: int = 3, min_gain: float = 0.5,
                 steps: Sequence[float] = PROFILE_STEPS, tolerance: float = 0.1,
                 threshold: float = PROFILE_THRESHOLD, undetermined_range: tuple[float, float] | None = None,
                 final_profile: bool = True, profile_frames: int | None = None):
    """``(res, auto)``: the solve carried to the bottom of its focal length's cost profile,
    and :func:`check_focal`'s description of it.

    The focal length and every frame's depth move together along a long shallow valley
    of the MAP cost (:func:`stretch_depth`), and Gauss-Newton stops part-way down it (the
    walk of ``bench/bench_camera_auto.py`` started 30 % long stopped at +27 % with the cost
    16 nats lower at +4 %). The profile of :func:`focal_profile` walks that valley; where
    one of its points is more than ``min_gain`` nats lower than the solve, the solve starts
    again from the lowest with the focal length free (at most ``rounds`` times). The
    report is the last profile's (``threshold``, ``tolerance``: :func:`profile_interval`).
    ``undetermined_range`` ``(lo, hi)`` px: when the first profile is no valley (the focal
    length NOT determined), the solve moves only to its points inside that range (a valley
    that does not determine the focal length says nothing against a plausible one).
    ``final_profile`` False: after the last move the report is made from the profile points
    already solved and the moved solve, instead of profiling again around it (the same
    function of the focal length, sampled less densely there: it says "determined" only
    where those points show the valley). ``profile_frames``: a clip longer than that is profiled
    on its stretch of that many frames where the subject's depth changes most
    (:func:`profile_stretch`), the move solved on the whole clip (the report says which frames)."""
    if not auto or auto.get("projection") != "perspective":
        return res, auto
    from ..solver import solve

    part, part_res, frames = profile_stretch(problem, res, profile_frames, options) or (problem, res, None)
    solves = _profile_solves(part, part_res, steps, options)
    if solves is None:
        return res, auto
    lo, hi = 0.0, np.inf
    if undetermined_range is not None and not _report(part, part_res, solves, threshold, tolerance).determined:
        lo, hi = undetermined_range
    for k in range(rounds):
        f, cost, Q, g = min([x for x in solves if lo <= x[0] <= hi] or solves[:1], key=lambda s: s[1])
        if cost >= part_res.cost - min_gain:
            break
        if frames is not None:  # the whole clip carried to that focal length
            intr, g_fit = _focal_of(problem, res)
            Q = stretch_depth(res.x, intr.camera(g_fit), f / intr.value(g_fit))
            g = np.where(np.arange(len(g_fit)) == intr.col, g[intr.col], g_fit)
        res = solve(problem, Q, options, active=problem.active, g0=g)
        part, part_res = (problem, res) if frames is None else \
            profile_stretch(problem, res, profile_frames, options, frames)[:2]
        if k == rounds - 1 and not final_profile:
            intr, g_fit = _focal_of(part, part_res)
            solves = [(intr.value(g_fit), float(part_res.cost), np.asarray(part_res.x, float), g_fit), *solves]
        else:
            solves = _profile_solves(part, part_res, steps, options)
    rep = _report(part, part_res, solves, threshold, tolerance)
    if frames is not None:  # the whole clip's focal length; its profile the stretch's
        intr, g_fit = _focal_of(problem, res)
        rep = dataclasses.replace(rep, focal_px=float(intr.value(g_fit)), frames=tuple(int(v) for v in frames))
    kf = auto.get("keyframe_focal")
    placed = _focal_of(problem, res)[0].pose_col is None  # held where the keyframes put it, not refined
    if kf is not None and placed and rep.determined:  # the camera's placement by the keyframes is uncertain too
        (lo, hi), (klo, khi) = rep.interval_px, kf["interval_px"]
        wide = not (all(kf["bounded"]) and klo >= rep.focal_px / (1.0 + tolerance) and khi <= rep.focal_px * (1.0 + tolerance))
        rep = dataclasses.replace(rep, interval_px=(klo, khi) if wide else (min(lo, klo), max(hi, khi)),
                                  bounded=tuple(kf["bounded"]) if wide else rep.bounded, determined=not wide,
                                  keyframes=kf)
    elif kf is not None and all(kf["bounded"]) and not placed and not \
            kf["interval_px"][0] / (1.0 + tolerance) <= rep.focal_px <= kf["interval_px"][1] * (1.0 + tolerance):
        # the solve refined the camera's pose and left the keyframes' own interval: it is the
        # tracks' (the prior's) focal length, not theirs
        rep = dataclasses.replace(rep, interval_px=tuple(kf["interval_px"]), bounded=(True, True), determined=False,
                                  keyframes={**kf, "excludes_fit": True})
    import warnings

    if not rep.determined:
        warnings.warn(rep.message(), FocalLengthWarning, stacklevel=3)
    odd = implausible_focal(rep.focal_px, auto["image_size"]) if auto.get("image_size") else None
    if odd:
        warnings.warn(odd, FocalLengthWarning, stacklevel=3)
    return res, {**auto, "focal": rep.to_dict()}
