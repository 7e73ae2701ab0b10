"""The problem layer: rows built from the inputs, on the reconstruction's time grid.

DiFranco, Cham & Rehg's MAP estimate (eq. 5) is a sum of row kinds over the whole
trajectory: 2D measurements, joint-limit barriers, constant-velocity smoothing, a weak
posture prior and keyframes (joint-space or 3D points). :func:`make_problem` validates
tracks, camera and keyframes, matches the tracks' names to the figure, and builds those
rows on a grid ``factor`` times finer than the tracks' (super-sampled frames carry no
observation). The :class:`ReconstructionProblem` it returns is what the solver
minimises and what every start (:mod:`pinrecon.starts`) reads its inputs from.

Data flows one way: this module imports the figure, tracks and row kinds; the starts,
the pipeline (:mod:`pinrecon.reconstruct`) and the planarity seed import it.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from .cameras import Perspective
from .errors import InputError, UnknownNameError
from .figure_files import load_keypoint_map
from .layouts import human_keypoint_map, human_map_for_names, shared_point_names
from .proportions import Proportions
from .rows import (
    CameraScale,
    GlobalPrior,
    JointKeyframes,
    JointLimits,
    Measurement2D,
    Points3D,
    Smoothing,
    State,
    smoothing_sigmas,
)
from .rows.bones import skeleton_rows
from .rows.lifted import lifted_rows
from .rows.posture import posture_row, rest_pose
from .tracks import Keyframe, Keyframes, Markers, Tracks
from .views import camera_views, upsample_factor, view_grid
from .weights import Weights

__all__ = [
    "CALIBRATE_MODES", "ReconstructionProblem", "View", "Weights", "camera_views", "check_calibrate",
    "default_calibrate", "has_point_keyframes", "keyframe_rows", "make_marker_problem", "make_problem",
    "measurement_rows", "observable_mask", "prior_rows", "resolved_loss", "rest_pose", "shared_keypoints",
    "upsample_factor", "view_grid",
]

#: what :func:`make_problem` can calibrate: nothing, the figure's segment lengths, the
#: cameras' focal length (perspective) or scale (orthographic), or both
CALIBRATE_MODES = ("none", "lengths", "camera", "lengths+camera")

#: the weak prior on a camera's pose unknowns (``make_problem(camera_pose=True)``): radians
#: of rotation, metres of shift; the point keyframes and the tracks place it, this only
#: keeps the step bounded where they say little
SIGMA_CAMERA_POSE = (0.5, 1.0)


def check_calibrate(calibrate) -> str:
    """``calibrate`` as one of :data:`CALIBRATE_MODES` (``None`` is ``"none"``); an
    error listing them otherwise."""
    mode = "none" if calibrate is None else calibrate
    if mode not in CALIBRATE_MODES:
        raise InputError(f"must be one of {', '.join(CALIBRATE_MODES)}, got {calibrate!r}", field="calibrate")
    return mode


def has_point_keyframes(keyframes) -> bool:
    """Whether ``keyframes`` hold a 3D point (the 3D information that fixes lengths and
    size; joint-angle keyframes do not)."""
    return any(getattr(k, "points", None) for k in keyframes or ())


def default_calibrate(figure, keyframes=None, lengths_from_tracks: bool = False, several_views: bool = False,
                      markers: bool = False) -> str:
    """The default of ``calibrate``: ``"lengths"`` for the generic human (``meta["generic"] ==
    "human"``; a figure already calibrated carries ``meta["proportions"]``) when there is 3D
    information (a point keyframe, or several given cameras, which see depth), or when the
    limb lengths are measured from the tracks first (``lengths_from_tracks``: one given
    camera, one batch solve, see :func:`pinrecon.reconstruct`), or when the figure is fitted
    to 3D markers (``markers``, :func:`pinrecon.reconstruct_markers`); ``"none"`` otherwise, and
    for any other figure (a BVH's own skeleton, a robot, a calibrated figure saved for
    reuse). Why: from one view a segment's length trades off against its depth, and
    without any 3D point or measured start the prior around the generic proportions does
    not hold it against hundreds of frames (measured in ``docs/globals.md``, section 5).
    """
    meta = getattr(figure, "meta", None) or {}
    if meta.get("generic") != "human" or "proportions" in meta:
        return "none"
    if has_point_keyframes(keyframes) or several_views or markers:
        return "lengths"
    return "lengths" if lengths_from_tracks else "none"


@dataclass(frozen=True, eq=False)
class View:
    """One camera of a problem and what it saw.

    name : the camera's name (from the calibration file, else ``"camera1"``, ...).
    tracks : its tracks, restricted to the figure's keypoints.
    camera : its :class:`~pinrecon.cameras.Camera`.
    measurement : its :class:`~pinrecon.rows.Measurement2D` rows.
    factor : reconstruction frames per frame of its tracks (tracks frame i is
        reconstruction frame ``i * factor``).
    """

    name: str
    tracks: Tracks
    camera: object
    measurement: Measurement2D
    factor: int = 1


class ReconstructionProblem:
    """A figure, a time grid and a list of row kinds: what the solver minimises.

    Built by :func:`make_problem` (2D tracks) or :func:`make_marker_problem` (3D
    markers), it also keeps the inputs the rows were built from, so that a start can
    read them: ``tracks`` (the tracks restricted to the figure's keypoints), ``camera``,
    ``keyframes``, ``factor`` (reconstruction frames per tracks frame), ``fps``,
    ``weights``, the ``measurement`` and ``smoothing`` rows, and ``active`` (the tangent
    entries the data constrain; the others are held at their start). Built by hand from
    ``(figure, n_frames, rows)`` these are ``None`` (``active`` all True).

    Several cameras: ``views`` lists one :class:`View` per camera (tracks, camera,
    measurement rows, factor), in the order they were given; ``tracks``, ``camera``,
    ``measurement`` and ``factor`` are then the first view's (a start that reads one
    camera reads the first). ``cameras``, ``measurements`` and ``camera_names`` list them
    all. A one-camera problem has one view.

    Global unknowns (``make_problem(..., calibrate=...)``, ``docs/globals.md``): ``g0``
    (n_g,) their start, ``None`` without any; ``global_names`` their names;
    ``proportions`` the figure's :class:`~pinrecon.proportions.Proportions` (its log
    factors are ``g[:proportions.n]``) or ``None``; ``calibrate`` the mode. The solver
    calls ``evaluate(Q, jacobian, g)``; without ``g`` (a solve without ``g0``, e.g. a
    start's or the feet's stage) the globals are held at ``g0``. :meth:`figure_at`,
    :meth:`cameras_at` and :meth:`keypoints` give the calibrated figure, the fitted
    cameras and the calibrated figure's keypoints at a ``g``.
    """

    def __init__(
        self,
        figure,
        n_frames: int,
        rows: Sequence,
        *,
        fps: float | None = None,
        factor: int = 1,
        tracks: Tracks | None = None,
        camera=None,
        keyframes: Keyframes | None = None,
        weights: Weights | None = None,
        measurement: Measurement2D | None = None,
        smoothing: Smoothing | None = None,
        active: np.ndarray | None = None,
        markers: Markers | None = None,
        views: Sequence[View] | None = None,
        proportions: Proportions | None = None,
        g0: np.ndarray | None = None,
        global_names: Sequence[str] | None = None,
        calibrate: str = "none",
    ):
        self.figure = figure
        self.n_frames = int(n_frames)
        self.nv = figure.nv
        self.rows = list(rows)
        kin = [np.asarray(r.kinematic_frames, dtype=int) for r in self.rows]
        self.kinematic_frames = np.unique(np.concatenate(kin)) if kin else np.zeros(0, int)
        self.fps = fps
        self.factor = int(factor)
        self.tracks = tracks
        self.camera = camera
        self.keyframes = keyframes
        self.weights = weights or Weights()
        self.measurement = measurement
        self.smoothing = smoothing
        self.active = np.ones(figure.nv, bool) if active is None else np.asarray(active, bool)
        self.markers = markers
        if views is None and measurement is not None:
            views = [View("camera1", tracks, camera, measurement, self.factor)]
        self.views = list(views or ())
        self.proportions = proportions
        self.g0 = None if g0 is None else np.asarray(g0, float).reshape(-1)
        n_g = 0 if self.g0 is None else len(self.g0)
        self.global_names = list(global_names) if global_names is not None else [f"g{i}" for i in range(n_g)]
        self.calibrate = calibrate
        # what stages found, for the result: {"hypotheses": ..., "faults": ...}, each with to_extras()
        self.reports: dict = {}

    @property
    def cameras(self) -> list:
        """Every view's camera, in order."""
        return [v.camera for v in self.views]

    @property
    def measurements(self) -> list[Measurement2D]:
        """Every view's measurement rows, in order."""
        return [v.measurement for v in self.views]

    @property
    def camera_names(self) -> list[str]:
        return [v.name for v in self.views]

    @property
    def n_globals(self) -> int:
        """Number of global unknowns (0 without calibration)."""
        return 0 if self.g0 is None else len(self.g0)

    def _globals(self, g):
        if g is None:
            return self.g0
        g = np.asarray(g, float).reshape(-1)
        if self.g0 is not None and g.shape != self.g0.shape:
            raise InputError(f"expected {len(self.g0)} global unknowns, got {g.shape}", field="g")
        return g

    def state(self, Q, jacobian=True, g=None) -> State:
        """The :class:`State` at ``Q`` and the globals ``g`` (default ``g0``): with
        proportions, the keypoints of the figure scaled by ``g[:proportions.n]``."""
        g = self._globals(g)
        if g is None:
            return State(self.figure, Q, self.kinematic_frames, jacobian)
        return State(self.figure, Q, self.kinematic_frames, jacobian, g=g, proportions=self.proportions)

    def evaluate(self, Q, jacobian=True, g=None):
        st = self.state(Q, jacobian, g)
        return [row.evaluate(st, jacobian) for row in self.rows]

    def figure_at(self, g=None):
        """The figure with the log factors ``g[:proportions.n]`` written in (a new
        :class:`~pinrecon.figure.Figure`); the figure itself without proportions."""
        g = self._globals(g)
        if self.proportions is None or g is None:
            return self.figure
        return self.proportions.calibrated_figure(g[: self.proportions.n])

    def keypoints(self, Q, g=None) -> np.ndarray:
        """(T, K, 3) keypoints of the (calibrated) figure along ``Q``."""
        g = self._globals(g)
        if self.proportions is None or g is None:
            return self.figure.keypoints(Q)
        Q = np.asarray(Q, float)
        P = self.proportions.keypoints(g[: self.proportions.n], np.atleast_2d(Q))
        return P[0] if Q.ndim == 1 else P

    def calibration(self, g=None) -> dict:
        """What the globals ``g`` (default ``g0``) say, as plain data: ``mode``; with
        proportions ``factors``, ``lengths_m`` and ``generic_lengths_m`` per group
        (:meth:`~pinrecon.proportions.Proportions.lengths_m`: a group's mean segment
        length); with camera unknowns ``cameras``: per camera name, the quantity
        (``focal_px`` or ``scale_px_per_m``), its ``start`` and ``fitted`` values.
        Empty without globals."""
        g = self._globals(g)
        if g is None:
            return {}
        out: dict = {"mode": self.calibrate, "globals": dict(zip(self.global_names, map(float, g)))}
        props = self.proportions
        if props is not None:
            theta = g[: props.n]
            out["factors"] = props.factors(theta)
            out["lengths_m"] = props.lengths_m(theta)
            out["generic_lengths_m"] = props.lengths_m()
        cams = {}
        for v in self.views:
            intr = v.measurement.intrinsics if v.measurement is not None else None
            if intr is not None:
                what = "scale_px_per_m" if intr.name == "log_scale" else "focal_px"
                cams[v.name] = {"quantity": what, "start": intr.value(np.zeros_like(g)), "fitted": intr.value(g)}
                if intr.pose_col is not None:  # how far the solve moved the camera from its start
                    cams[v.name].update(intr.pose_change(g))
        if cams:
            out["cameras"] = cams
        return out

    def cameras_at(self, g=None) -> list:
        """Every view's camera at the globals ``g`` (fitted focal length or scale)."""
        g = self._globals(g)
        out = []
        for v in self.views:
            intr = v.measurement.intrinsics if v.measurement is not None else None
            out.append(intr.camera(g) if intr is not None and g is not None else v.camera)
        return out

    def retract(self, Q, dQ):
        return self.figure.integrate(Q, dQ)

    def _rebuilt(self, n_frames: int, rows: Sequence, **changed) -> ReconstructionProblem:
        """A copy over ``n_frames`` frames with ``rows`` and the constructor's arguments ``changed``."""
        new = ReconstructionProblem.__new__(ReconstructionProblem)
        new.__dict__.update(self.__dict__)
        kw = {k: getattr(self, k) for k in ("fps", "factor", "tracks", "camera", "keyframes", "weights", "measurement",
                                            "smoothing", "active", "markers", "views", "proportions", "g0",
                                            "global_names", "calibrate")}
        ReconstructionProblem.__init__(new, self.figure, n_frames, rows, **{**kw, **changed})
        return new

    def with_rows(self, extra: Sequence, *, after: int | None = None) -> ReconstructionProblem:
        """The same problem with ``extra`` rows inserted after the first ``after`` rows
        (by default after the measurement rows of every view, limits and smoothing)."""
        if after is None:
            after = max(len(self.views), 1) + 2
        new = self._rebuilt(self.n_frames, self.rows[:after] + list(extra) + self.rows[after:])
        new.reports = self.reports
        return new

    def cropped(self, lo: int, hi: int, state: State | None = None) -> ReconstructionProblem | None:
        """The problem of frames ``lo .. hi - 1`` alone (``hi - lo`` frames, the same globals):
        every row kind's :meth:`~pinrecon.rows.base.RowKind.crop`, frames shifted to start at 0,
        row groups reaching outside the range (the smoothing across its ends) left out; a view's
        tracks cut to the range (``None`` when its frame step is not 1), no keyframes (for a
        solve, not a start). ``None`` when a row kind cannot be cropped (lifted rows whose
        rotation is estimated from the whole clip), unless ``state`` (:meth:`state` of the whole
        clip) is given: such rows are then cropped with that rotation held (``crop_at``)."""
        lo, hi = int(lo), int(hi)
        if not 0 <= lo < hi <= self.n_frames:
            raise InputError(f"frames {lo}..{hi - 1} are not within the problem's {self.n_frames}", field="frames")
        new_of = {id(r): r.crop_at(lo, hi, state) if state is not None and hasattr(r, "crop_at") else r.crop(lo, hi)
                  for r in self.rows}
        if any(c is None for c in new_of.values()):
            return None
        views = [replace(v, measurement=new_of.get(id(v.measurement), v.measurement),
                         tracks=v.tracks.frames(lo, hi) if v.factor == 1 and v.tracks is not None else None)
                 for v in self.views]
        return self._rebuilt(hi - lo, [new_of[id(r)] for r in self.rows], tracks=views[0].tracks if views else None,
                             keyframes=None, markers=None, views=views, measurement=new_of.get(id(self.measurement)),
                             smoothing=new_of.get(id(self.smoothing)))

    def with_globals(self, g) -> ReconstructionProblem:
        """The same problem started (and, in solves without ``g0``, held) at the globals ``g``."""
        new = self.with_rows([], after=len(self.rows))
        new.g0 = None if g is None else self._globals(g).copy()
        return new


# ----------------------------------------------------------------------------- helpers
def shared_keypoints(figure, names, source, what="tracks", warn=True) -> list[str]:
    """The names the figure has, in the given order. Typos of figure keypoints, no or
    fewer than 4 shared points are errors (:func:`pinrecon.layouts.shared_point_names`);
    the other ignored names (points the figure does not carry) give a warning."""
    shared, ignored = shared_point_names(names, figure.keypoint_names, what=what, source=source)
    if ignored and warn:
        warnings.warn(f"{what} points not on the figure are ignored: {ignored}{_better_human_map(figure, names)}",
                      stacklevel=3)
    return shared


def _better_human_map(figure, names) -> str:
    """For the generic human whose keypoint map leaves out points another bundled map
    carries: the hint naming that map (what the command line's ``--figure human`` takes)."""
    if figure.meta.get("generic") != "human":
        return ""
    best = human_map_for_names(names)
    carried = {k.name for k in load_keypoint_map(human_keypoint_map(best))}
    if len(set(names) & carried) <= len(set(names) & set(figure.keypoint_names)):
        return ""
    return f" (Figure.human({best!r}), or Figure.human('auto', tracks=tracks), carries more of them)"


def keyframe_rows(figure, keyframes: Keyframes, factor: int) -> list:
    """Rows for point and joint keyframes; frames mapped to the reconstruction grid."""
    rows = []
    point_items = [k for k in keyframes if k.points is not None]
    joint_items = [k for k in keyframes if k.joints is not None]
    if point_items:
        names = sorted({n for k in point_items for n in k.points}, key=figure.keypoint_names.index)
        idx = figure.keypoint_index(names)
        P = np.full((len(point_items), len(names), 3), np.nan)
        for i, k in enumerate(point_items):
            for j, n in enumerate(names):
                if n in k.points:
                    P[i, j] = k.points[n]
        frames = np.array([k.frame * factor for k in point_items])
        sig = np.array([k.sigma for k in point_items])
        rows.append(Points3D(frames, idx, P, sig, name="keyframe_points"))
    if joint_items:
        rows.append(JointKeyframes(figure, [(k.frame * factor, k.sigma, k.joints) for k in joint_items]))
    return rows


def measurement_rows(figure, tracks: Tracks, camera, factor: int, weights: Weights, intrinsics=None) -> Measurement2D:
    """2D measurement rows for ``tracks`` (names already matched to the figure's keypoints)
    on a time grid ``factor`` times finer than the tracks' (frame i -> frame i * factor);
    ``intrinsics`` a :class:`~pinrecon.rows.CameraScale` when the camera is calibrated."""
    obs_rows = np.where(tracks.observed.any(axis=1))[0]
    return Measurement2D(
        camera,
        obs_rows * factor,
        figure.keypoint_index(tracks.names),
        tracks.points[obs_rows],
        tracks.weights()[obs_rows],
        sigma_px=weights.sigma_px,
        loss=resolved_loss(weights, tracks),
        loss_scale_px=weights.loss_scale_px,
        intrinsics=intrinsics,
    )


def resolved_loss(weights: Weights, tracks: Tracks) -> str:
    """``weights.loss`` with ``"auto"`` resolved: Cauchy for tracks with confidences
    (detector output, with outliers), least squares otherwise."""
    if weights.loss != "auto":
        return weights.loss
    return "cauchy" if tracks.confidence is not None else "l2"


def prior_rows(figure, n_frames: int, fps: float, weights: Weights) -> tuple[Smoothing, JointLimits]:
    """The smoothing and joint-limit rows of an ``n_frames`` trajectory at ``fps``."""
    smoothing = Smoothing(
        figure,
        n_frames,
        1.0 / fps,
        smoothing_sigmas(figure, weights.acc_root_translation, weights.acc_root_rotation, weights.acc_joints),
        root_group=weights.root_group,
    )
    return smoothing, JointLimits(figure, n_frames, weights.sigma_limits)


def observable_mask(figure, names, keyframes) -> np.ndarray:
    """Tangent entries constrained by data: those moving a tracked or keyed keypoint, or set
    by a joint keyframe. The others (e.g. fingers nobody tracks) have only the smoothing
    prior, whose null space (linear drift) would make the problem singular: they are held
    at their initial values."""
    used = set(names)
    active = np.zeros(figure.nv, bool)
    for k in keyframes or ():
        if k.points is not None:
            used.update(k.points)
        else:
            for n in k.joints:
                active[figure.joint_slices(n)[1]] = True
    active |= figure.support_mask(sorted(used, key=figure.keypoint_names.index))
    return active


def make_problem(
    figure,
    tracks: Tracks | Sequence[Tracks],
    camera,
    keyframes: Keyframes | Sequence[Keyframe] | None = None,
    *,
    fps_out: float | None = None,
    factor: int | None = None,
    weights: Weights | None = None,
    keypoints: Sequence[str] | None = None,
    calibrate: str | None = "none",
    proportions: Proportions | None = None,
    log_factors0=None,
    sigma_proportions: float | None = None,
    sigma_camera: float | None = None,
    camera_pose: bool = False,
) -> ReconstructionProblem:
    """Validate the inputs and build the rows of :func:`pinrecon.reconstruct`'s problem.

    ``fps_out`` (or directly ``factor = fps_out / tracks.fps``) sets the time grid;
    ``keypoints`` restricts the track names used (default: every name the figure has;
    the others are ignored with a warning). Keyframes' frames index the tracks (the
    first camera's).

    Several cameras: ``tracks`` and ``camera`` are sequences of the same length, paired
    in order (:func:`camera_views`); each camera's tracks, with their own missing points
    and confidences, become measurement rows through that camera, all in the one problem
    (one :class:`View` each, ``problem.views``). Their time grids must agree
    (:func:`view_grid`).

    Calibration (``docs/globals.md``): ``calibrate`` is one of :data:`CALIBRATE_MODES`.
    ``"lengths"`` makes the figure's segment scale factors global unknowns
    (``proportions``, default :meth:`Proportions.default
    <pinrecon.proportions.Proportions.default>`: the human's named groups, else one per
    bone with left/right twins), log-parametrised, started at ``log_factors0`` (default
    0: the figure as given) with a log-normal prior of ``sigma_proportions`` (default
    ``weights.sigma_proportions``, 0.1) around the start; ``"camera"`` makes every camera's log focal length (perspective) or log scale
    (orthographic) a global (one per camera, no prior unless ``sigma_camera``);
    ``"lengths+camera"`` both. The globals are ``g = (log factors, log camera scales)``;
    ``problem.g0`` is their start. ``camera_pose`` (with ``"camera"`` in the mode; without
    it the camera is held and this is ignored): six more globals move the camera
    (:class:`~pinrecon.rows.CameraScale`: a rotation vector and a shift in its own axes,
    from zero), held by a weak prior (:data:`SIGMA_CAMERA_POSE`); only for one perspective
    camera with 3D point keyframes, which fix the world it is placed in (an InputError
    otherwise).
    """
    weights = weights or Weights()
    mode = check_calibrate(calibrate)
    pairs = camera_views(tracks, camera)
    props = _proportions_for(figure, mode, proportions)
    n_p = props.n if props is not None else 0
    theta0 = np.zeros(n_p) if log_factors0 is None or props is None else props.check(log_factors0)
    if keyframes is not None and not isinstance(keyframes, Keyframes):
        keyframes = Keyframes(list(keyframes))
    factors, T, fps = view_grid([t for _, t, _ in pairs], [n for n, _, _ in pairs], fps_out=fps_out, factor=factor)
    if keypoints is not None and len(pairs) > 1:
        known = {n for _, t, _ in pairs for n in t.names}
        unknown = [n for n in keypoints if n not in known]
        if unknown:
            raise UnknownNameError("track", unknown, sorted(known), field="keypoints")
    camera_pose = bool(camera_pose) and "camera" in mode  # a problem that calibrates no camera holds it
    if camera_pose and not (len(pairs) == 1 and isinstance(pairs[0][2], Perspective)
                            and has_point_keyframes(keyframes)):
        raise InputError("the camera's pose is an unknown only for one perspective camera with 3D point keyframes "
                         "(they fix the world it is placed in)", field="camera_pose")
    views, used = [], []
    for (name, trk, cam), f in zip(pairs, factors):
        names = list(trk.names) if keypoints is None else [n for n in keypoints if len(pairs) == 1 or n in trk.names]
        sub = trk.select(names)
        shared = shared_keypoints(figure, sub.names, trk.source)
        sub = sub.select(shared)
        if not np.isfinite(sub.points).all(axis=-1).any():
            raise InputError(f"none of the {len(shared)} point(s) the figure shares with the tracks is observed in any "
                             "frame", file=trk.source, field="points")
        used += [n for n in shared if n not in used]
        pose_col = n_p + len(pairs) if camera_pose else None
        intr = CameraScale(cam, n_p + len(views), pose_col=pose_col) if "camera" in mode else None
        views.append(View(name, sub, cam, measurement_rows(figure, sub, cam, f, weights, intr), f))
    if keyframes is not None:
        keyframes.validate(figure, pairs[0][1].T)

    smoothing, limits = prior_rows(figure, T, fps, weights)
    active = observable_mask(figure, used, keyframes)
    rows = [v.measurement for v in views] + [limits, smoothing] + lifted_rows(figure, views, weights)
    rows += [r for r in [posture_row(figure, T, weights, active), *skeleton_rows(figure, T, active)] if r is not None]
    if keyframes is not None and len(keyframes):
        rows += keyframe_rows(figure, keyframes, factors[0])
    g0, names = None, []
    if props is not None:
        sig = weights.sigma_proportions if sigma_proportions is None else sigma_proportions
        rows.append(GlobalPrior(np.arange(n_p), theta0, sig, name="prior_proportions"))
        names += list(props.names)
    if "camera" in mode:
        cols = n_p + np.arange(len(views))
        if sigma_camera is not None:
            rows.append(GlobalPrior(cols, 0.0, sigma_camera, name="prior_camera"))
        names += [f"{v.name}.{v.measurement.intrinsics.name}" for v in views]
    if camera_pose:
        cols = n_p + len(views) + np.arange(6)
        rows.append(GlobalPrior(cols, 0.0, np.repeat(SIGMA_CAMERA_POSE, 3), name="prior_camera_pose"))
        names += [f"{views[0].name}.{n}" for n in CameraScale.POSE_NAMES]
    if names:
        g0 = np.r_[theta0, np.zeros(len(names) - n_p)]
    first = views[0]
    return ReconstructionProblem(
        figure, T, rows, fps=fps, factor=first.factor, tracks=first.tracks, camera=first.camera, keyframes=keyframes,
        weights=weights, measurement=first.measurement, smoothing=smoothing, active=active, views=views,
        proportions=props, g0=g0, global_names=names, calibrate=mode,
    )


def _proportions_for(figure, mode: str, proportions: Proportions | None) -> Proportions | None:
    """The proportions a problem of calibration ``mode`` solves for: ``proportions`` (built
    for ``figure``) or :meth:`Proportions.default <pinrecon.proportions.Proportions.default>`
    when the mode calibrates lengths, else None."""
    if "lengths" not in mode:
        return None
    props = Proportions.default(figure) if proportions is None else proportions
    if props.figure is not figure:
        raise InputError("the proportions were built for another figure", field="proportions")
    return props


def make_marker_problem(
    figure,
    markers: Markers,
    keyframes: Keyframes | None = None,
    *,
    fps_out: float | None = None,
    weights: Weights | None = None,
    calibrate: str | None = "none",
    proportions: Proportions | None = None,
) -> ReconstructionProblem:
    """Rows of :func:`pinrecon.reconstruct_markers`: 3D marker rows (dropped frames are
    missing), limits, smoothing, posture and keyframes. ``problem.markers`` keeps the
    markers restricted to the figure's keypoints. ``calibrate="lengths"`` makes the
    figure's segment scale factors global unknowns as :func:`make_problem` does (the
    markers measure them in metres), with the prior ``weights.sigma_proportions``;
    ``"none"`` keeps the figure as given (there is no camera to calibrate)."""
    weights = weights or Weights()
    mode = check_calibrate(calibrate)
    if "camera" in mode:
        raise InputError(f"3D markers have no camera to calibrate: give 'lengths' or 'none', got {calibrate!r}",
                         field="calibrate")
    props = _proportions_for(figure, mode, proportions)
    factor = upsample_factor(markers.fps, fps_out)
    T = (markers.T - 1) * factor + 1
    fps = markers.fps * factor
    shared = shared_keypoints(figure, markers.names, markers.source, what="markers")
    sub = Markers(markers.points[:, [markers.names.index(n) for n in shared]], shared, markers.fps, markers.source)
    obs = np.all(np.isfinite(sub.points), axis=2)
    rows_obs = np.where(obs.any(axis=1))[0]
    if len(rows_obs) == 0:
        raise InputError("no marker is observed in any frame", file=markers.source, field="points")
    mk = Points3D(rows_obs * factor, figure.keypoint_index(shared), sub.points[rows_obs], weights.sigma_markers_m,
                  name="markers")
    smoothing, limits = prior_rows(figure, T, fps, weights)
    rows = [mk, limits, smoothing]
    posture = posture_row(figure, T, weights)
    if posture is not None:
        rows.append(posture)
    if keyframes is not None:
        keyframes.validate(figure, markers.T)
        rows += keyframe_rows(figure, keyframes, factor)
    g0, names = None, []
    if props is not None:
        rows.append(GlobalPrior(np.arange(props.n), 0.0, weights.sigma_proportions, name="prior_proportions"))
        g0, names = np.zeros(props.n), list(props.names)
    return ReconstructionProblem(
        figure, T, rows, fps=fps, factor=factor, keyframes=keyframes, weights=weights, smoothing=smoothing,
        markers=sub, proportions=props, g0=g0, global_names=names, calibrate=mode,
    )
