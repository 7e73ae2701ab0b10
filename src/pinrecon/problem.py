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
from dataclasses import dataclass, fields

import numpy as np

from .errors import InputError
from .rows import JointKeyframes, JointLimits, Measurement2D, Points3D, Posture, Smoothing, State, smoothing_sigmas
from .tracks import Keyframe, Keyframes, Markers, Tracks

__all__ = [
    "Weights",
    "ReconstructionProblem",
    "make_problem",
    "make_marker_problem",
    "upsample_factor",
    "shared_keypoints",
    "keyframe_rows",
    "measurement_rows",
    "prior_rows",
    "observable_mask",
    "rest_pose",
]


@dataclass(frozen=True)
class Weights:
    """Standard deviations that weight each row kind (all have defaults tuned on real
    human motion; see ``docs/derivations.md``, section 6).

    sigma_px : 2D measurement noise, pixels.
    loss, loss_scale_px : ``"l2"`` (default), or a robust ``"huber"``/``"cauchy"`` loss
        for detector tracks with outliers, with its scale in pixels.
    sigma_limits : joint-limit barrier, radians (small = stiff).
    acc_root_translation, acc_root_rotation, acc_joints : smoothing, standard deviation of
        acceleration in m/s^2 and rad/s^2 (constant-velocity prior; large = weak).
    sigma_markers_m : 3D marker noise for :func:`reconstruct_markers`, metres.
    sigma_init_prior : prior pulling unkeyed joints to the rest pose when a point keyframe
        is turned into a pose (radians).
    sigma_posture : weak prior of every joint towards the rest pose in every frame
        (radians; ``None`` turns it off), see :mod:`pinrecon.rows.posture`.
    root_group : group on which the root's constant-velocity prior is written,
        ``"R3xSO3"`` (world translation and orientation apart; default) or ``"SE3"``
        (the free flyer's screw motion), see :mod:`pinrecon.rows.smoothing`.
    """

    sigma_px: float = 2.0
    loss: str = "l2"
    loss_scale_px: float | None = None
    sigma_limits: float = 0.01
    acc_root_translation: float = 5.0
    acc_root_rotation: float = 10.0
    acc_joints: float = 10.0
    sigma_markers_m: float = 0.01
    sigma_init_prior: float = 1.0
    sigma_posture: float | None = 3.0
    root_group: str = "R3xSO3"

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "loss":
                if v not in ("l2", "huber", "cauchy"):
                    raise InputError(f"must be 'l2', 'huber' or 'cauchy', got {v!r}", field="weights.loss")
            elif f.name == "root_group":
                if v not in ("R3xSO3", "SE3"):
                    raise InputError(f"must be 'R3xSO3' or 'SE3', got {v!r}", field="weights.root_group")
            elif v is not None and not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise InputError(f"must be a positive number, got {v!r}", field=f"weights.{f.name}")


class ReconstructionProblem:
    """A figure, a time grid and a list of row kinds: what the solver minimises.

    Built by :func:`make_problem` (2D tracks) or :func:`make_marker_problem` (3D
    markers), it also keeps the inputs the rows were built from, so that a start can
    read them: ``tracks`` (the tracks restricted to the figure's keypoints), ``camera``,
    ``keyframes``, ``factor`` (reconstruction frames per tracks frame), ``fps``,
    ``weights``, the ``measurement`` and ``smoothing`` rows, and ``active`` (the tangent
    entries the data constrain; the others are held at their start). Built by hand from
    ``(figure, n_frames, rows)`` these are ``None`` (``active`` all True).
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

    def state(self, Q, jacobian=True) -> State:
        return State(self.figure, Q, self.kinematic_frames, jacobian)

    def evaluate(self, Q, jacobian=True):
        st = self.state(Q, jacobian)
        return [row.evaluate(st, jacobian) for row in self.rows]

    def retract(self, Q, dQ):
        return self.figure.integrate(Q, dQ)

    def with_rows(self, extra: Sequence, *, after: int = 3) -> ReconstructionProblem:
        """The same problem with ``extra`` rows inserted after the first ``after`` rows
        (by default after measurement, limits and smoothing)."""
        new = ReconstructionProblem.__new__(ReconstructionProblem)
        new.__dict__.update(self.__dict__)
        ReconstructionProblem.__init__(
            new, self.figure, self.n_frames, self.rows[:after] + list(extra) + self.rows[after:],
            fps=self.fps, factor=self.factor, tracks=self.tracks, camera=self.camera, keyframes=self.keyframes,
            weights=self.weights, measurement=self.measurement, smoothing=self.smoothing, active=self.active,
            markers=self.markers,
        )
        return new


# ----------------------------------------------------------------------------- helpers
def rest_pose(figure, margin=0.05):
    """The neutral configuration clamped inside the joint limits (with a margin)."""
    return figure.clamp(figure.neutral(), margin=margin)


def upsample_factor(fps_obs: float, fps_out: float | None) -> int:
    """Reconstruction frames per observed frame (``fps_out`` an integer multiple of ``fps_obs``)."""
    if fps_out is None:
        return 1
    ratio = float(fps_out) / float(fps_obs)
    factor = int(round(ratio))
    if factor < 1 or abs(ratio - factor) > 1e-6 * ratio:
        raise InputError(
            f"fps_out {fps_out:g} must be an integer multiple of the tracks' {fps_obs:g} fps", field="fps_out"
        )
    return factor


def shared_keypoints(figure, names, source, what="tracks", warn=True) -> list[str]:
    """The names the figure has, in the given order; an error when there are none, and
    a warning naming the ignored ones."""
    shared = [n for n in names if n in figure.keypoint_names]
    if not shared:
        raise InputError(
            f"the {what} and the figure share no keypoint name. {what} names: {list(names)[:40]}; "
            f"figure keypoints: {figure.keypoint_names[:60]}",
            file=source,
            field="names",
        )
    ignored = [n for n in names if n not in figure.keypoint_names]
    if ignored and warn:
        warnings.warn(f"{what} points not on the figure are ignored: {ignored}", stacklevel=3)
    return shared


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


def measurement_rows(figure, tracks: Tracks, camera, factor: int, weights: Weights) -> Measurement2D:
    """2D measurement rows for ``tracks`` (names already matched to the figure's keypoints)
    on a time grid ``factor`` times finer than the tracks' (frame i -> frame i * factor)."""
    obs_rows = np.where(tracks.observed.any(axis=1))[0]
    return Measurement2D(
        camera,
        obs_rows * factor,
        figure.keypoint_index(tracks.names),
        tracks.points[obs_rows],
        tracks.weights()[obs_rows],
        sigma_px=weights.sigma_px,
        loss=weights.loss,
        loss_scale_px=weights.loss_scale_px,
    )


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


# ----------------------------------------------------------------------------- builders
def make_problem(
    figure,
    tracks: Tracks,
    camera,
    keyframes: Keyframes | Sequence[Keyframe] | None = None,
    *,
    fps_out: float | None = None,
    factor: int | None = None,
    weights: Weights | None = None,
    keypoints: Sequence[str] | None = None,
) -> ReconstructionProblem:
    """Validate the inputs and build the rows of :func:`pinrecon.reconstruct`'s problem.

    ``fps_out`` (or directly ``factor = fps_out / tracks.fps``) sets the time grid;
    ``keypoints`` restricts the track names used (default: every name the figure has;
    the others are ignored with a warning). Keyframes' frames index the tracks.
    """
    weights = weights or Weights()
    if not isinstance(tracks, Tracks):
        raise InputError(f"tracks must be a pinrecon.Tracks, got {type(tracks).__name__}", field="tracks")
    if keyframes is not None and not isinstance(keyframes, Keyframes):
        keyframes = Keyframes(list(keyframes))
    factor = upsample_factor(tracks.fps, fps_out) if factor is None else int(factor)
    T_obs = tracks.T
    if T_obs < 1:
        raise InputError("tracks have no frames", file=tracks.source, field="points")
    T = (T_obs - 1) * factor + 1
    fps = tracks.fps * factor
    names = list(keypoints) if keypoints is not None else list(tracks.names)
    sub = tracks.select(names)
    shared = shared_keypoints(figure, sub.names, tracks.source)
    sub = sub.select(shared)
    if keyframes is not None:
        keyframes.validate(figure, T_obs)

    meas = measurement_rows(figure, sub, camera, factor, weights)
    smoothing, limits = prior_rows(figure, T, fps, weights)
    active = observable_mask(figure, shared, keyframes)
    rows = [meas, limits, smoothing]
    if weights.sigma_posture is not None:
        rows.append(Posture(figure, T, rest_pose(figure), weights.sigma_posture, active))
    if keyframes is not None and len(keyframes):
        rows += keyframe_rows(figure, keyframes, factor)
    return ReconstructionProblem(
        figure, T, rows, fps=fps, factor=factor, tracks=sub, camera=camera, keyframes=keyframes,
        weights=weights, measurement=meas, smoothing=smoothing, active=active,
    )


def make_marker_problem(
    figure,
    markers: Markers,
    keyframes: Keyframes | None = None,
    *,
    fps_out: float | None = None,
    weights: Weights | None = None,
) -> ReconstructionProblem:
    """Rows of :func:`pinrecon.reconstruct_markers`: 3D marker rows (dropped frames are
    missing), limits, smoothing, posture and keyframes. ``problem.markers`` keeps the
    markers restricted to the figure's keypoints."""
    weights = weights or Weights()
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
    if weights.sigma_posture is not None:
        rows.append(Posture(figure, T, rest_pose(figure), weights.sigma_posture))
    if keyframes is not None:
        keyframes.validate(figure, markers.T)
        rows += keyframe_rows(figure, keyframes, factor)
    return ReconstructionProblem(
        figure, T, rows, fps=fps, factor=factor, keyframes=keyframes, weights=weights, smoothing=smoothing,
        markers=sub,
    )
