"""The pipeline a user calls: build rows from inputs, initialise, solve, package a result.

``reconstruct(figure, tracks, camera, keyframes)`` is DiFranco, Cham & Rehg's batch MAP
estimate of the whole trajectory from 2D tracks (eq. 5): 2D measurement rows, joint-limit
barriers, constant-velocity smoothing on the Lie group, and full or partial keyframes
(joint-space or 3D points), solved by the block-banded Gauss-Newton of
:mod:`pinrecon.solver`. ``reconstruct_markers`` does the same from 3D markers (the
noise channel only: smoothing and gap filling of motion capture).
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields, replace

import numpy as np

from .errors import InputError
from .rows import JointKeyframes, JointLimits, Measurement2D, Points3D, Posture, Smoothing, State, smoothing_sigmas
from .solver import SolveResult, SolverOptions, solve
from .tracks import Keyframe, Keyframes, Markers, Tracks

__all__ = ["Weights", "Result", "reconstruct", "reconstruct_markers", "build_problem", "Setup", "ReconstructionProblem", "load_result"]


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
    """A figure, a time grid and a list of row kinds: what the solver minimises."""

    def __init__(self, figure, n_frames: int, rows: Sequence):
        self.figure = figure
        self.n_frames = int(n_frames)
        self.nv = figure.nv
        self.rows = list(rows)
        kin = [np.asarray(r.kinematic_frames, dtype=int) for r in self.rows]
        self.kinematic_frames = np.unique(np.concatenate(kin)) if kin else np.zeros(0, int)

    def state(self, Q, jacobian=True) -> State:
        return State(self.figure, Q, self.kinematic_frames, jacobian)

    def evaluate(self, Q, jacobian=True):
        st = self.state(Q, jacobian)
        return [row.evaluate(st, jacobian) for row in self.rows]

    def retract(self, Q, dQ):
        return self.figure.integrate(Q, dQ)


@dataclass
class Result:
    """A reconstructed motion.

    Attributes
    ----------
    figure : the figure.
    q : (T, nq) configurations.
    times : (T,) seconds.
    fps : reconstruction frame rate.
    keypoints3d : (T, K, 3) world positions of all the figure's keypoints, metres.
    reprojection_error_px : (T,) mean reprojection error of the observed points per
        frame (NaN where a frame has no 2D observation).
    solve : the solver's :class:`~pinrecon.solver.SolveResult` (status, report ...).
    observed_frames : (T,) bool, frames that had observations.
    """

    figure: object
    q: np.ndarray
    times: np.ndarray
    fps: float
    keypoints3d: np.ndarray
    reprojection_error_px: np.ndarray
    solve: SolveResult | None
    observed_frames: np.ndarray
    camera: object = None
    extras: dict = field(default_factory=dict)

    @property
    def report(self):
        return self.solve.report if self.solve else []

    @property
    def keypoint_names(self) -> list[str]:
        return list(self.figure.keypoint_names)

    @property
    def joint_names(self) -> list[str]:
        return list(self.figure.joint_names)

    @classmethod
    def from_motion(cls, figure, q, fps, camera=None) -> Result:
        """A Result for a known motion (ground truth for plots and exports)."""
        q = figure.check_q(np.asarray(q, float))
        T = q.shape[0]
        return cls(figure, q, np.arange(T) / fps, float(fps), figure.keypoints(q), np.full(T, np.nan), None,
                   np.zeros(T, bool), camera)

    def keypoint(self, name: str) -> np.ndarray:
        return self.keypoints3d[:, self.figure.keypoint_index([name])[0]]

    def joint_angles(self) -> tuple[list[str], np.ndarray]:
        """Names and values (T, n) of the 1-dof joints (radians or metres)."""
        m = self.figure.model
        names, cols = [], []
        for jid in range(1, m.njoints):
            if m.nqs[jid] == 1 and m.nvs[jid] == 1:
                names.append(m.names[jid])
                cols.append(m.idx_qs[jid])
        return names, self.q[:, cols]

    def summary(self) -> str:
        s = self.solve
        err = np.nanmean(self.reprojection_error_px) if np.any(np.isfinite(self.reprojection_error_px)) else float("nan")
        lines = [
            f"{len(self.times)} frames at {self.fps:g} fps, figure {self.figure.name!r} (nv={self.figure.nv})",
            f"reprojection error {err:.3f} px (mean over observed points)",
        ]
        if s is not None:
            lines.append(
                f"solver: {s.status} after {s.iterations} iterations in {s.time:.2f} s, cost {s.initial_cost:.6g} -> {s.cost:.6g}"
            )
        return "\n".join(lines)

    def save(self, path) -> None:
        """Write the result NPZ (``docs/formats.md``), atomically. It embeds the figure's
        URDF and keypoint map so the file alone can be plotted and exported."""
        from .io.results import save_result_npz

        fig = self.figure
        parents = np.array([-1 if p is None else p for p in fig.parents_of_keypoints])
        meta = {k: v for k, v in fig.meta.items() if not k.startswith("_")}
        save_result_npz(
            path,
            q=self.q,
            times=self.times,
            keypoints3d=self.keypoints3d,
            keypoint_names=np.array(fig.keypoint_names),
            joint_names=np.array(fig.joint_names),
            fps=np.float64(self.fps),
            reprojection_error_px=self.reprojection_error_px,
            observed_frames=self.observed_frames,
            keypoint_parents=parents,
            figure_name=np.array(fig.name),
            figure_urdf=np.array(fig.urdf_xml or ""),
            figure_floating=np.array(fig.floating),
            figure_keypoints=np.array(json.dumps(fig.keypoint_map_dict())),
            figure_meta=np.array(json.dumps(meta)),
            figure_limits=np.array(json.dumps({k: list(v) for k, v in fig._limit_dict().items()})),
            camera=np.array(json.dumps(self.camera.to_dict()) if self.camera is not None else ""),
            solver_status=np.array(self.solve.status if self.solve else ""),
            solver_iterations=np.int64(self.solve.iterations if self.solve else 0),
            **{k: v for k, v in self.extras.items()},
        )


def load_result(path) -> Result:
    """Read a result NPZ back into a :class:`Result` (figure rebuilt from the embedded URDF)."""
    from .cameras import camera_from_dict
    from .figure import Figure, _parse_keypoint_entries
    from .io.results import load_result_npz

    d = load_result_npz(path)
    fig = None
    if "figure_urdf" in d and str(d["figure_urdf"]):
        kps = _parse_keypoint_entries(json.loads(str(d["figure_keypoints"]))["keypoints"], file=path)
        limits = {k: tuple(v) for k, v in json.loads(str(d.get("figure_limits", "{}"))).items()}
        fig = Figure.from_urdf_string(
            str(d["figure_urdf"]),
            kps,
            root="free" if bool(d["figure_floating"]) else "fixed",
            name=str(d["figure_name"]),
            limits=limits,
            meta=json.loads(str(d["figure_meta"])),
            source=str(path),
        )
    cam = None
    if "camera" in d and str(d["camera"]):
        cam = camera_from_dict(json.loads(str(d["camera"])), file=path)
    fps = float(d["fps"]) if "fps" in d else (1.0 / np.diff(d["times"]).mean() if len(d["times"]) > 1 else 1.0)
    T = d["q"].shape[0]
    return Result(
        figure=fig,
        q=d["q"],
        times=d["times"],
        fps=fps,
        keypoints3d=d["keypoints3d"],
        reprojection_error_px=d.get("reprojection_error_px", np.full(T, np.nan)),
        solve=None,
        observed_frames=d.get("observed_frames", np.zeros(T, bool)),
        camera=cam,
    )


# ----------------------------------------------------------------------------- building
def _upsample_factor(fps_obs: float, fps_out: float | None) -> int:
    if fps_out is None:
        return 1
    ratio = float(fps_out) / float(fps_obs)
    factor = int(round(ratio))
    if factor < 1 or abs(ratio - factor) > 1e-6 * ratio:
        raise InputError(
            f"fps_out {fps_out:g} must be an integer multiple of the tracks' {fps_obs:g} fps", field="fps_out"
        )
    return factor


def _shared_names(figure, names, source, what="tracks"):
    shared = [n for n in names if n in figure.keypoint_names]
    if not shared:
        raise InputError(
            f"the {what} and the figure share no keypoint name. {what} names: {list(names)[:40]}; "
            f"figure keypoints: {figure.keypoint_names[:60]}",
            file=source,
            field="names",
        )
    ignored = [n for n in names if n not in figure.keypoint_names]
    if ignored:
        warnings.warn(f"{what} points not on the figure are ignored: {ignored}", stacklevel=3)
    return shared


def _keyframe_rows(figure, keyframes: Keyframes, factor: int):
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


def _kabsch(A, B):
    """Rotation R, translation t minimising |R A + t - B| over rows (points (n, 3))."""
    ca, cb = A.mean(0), B.mean(0)
    H = (A - ca).T @ (B - cb)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ np.diag([1, 1, d]) @ U.T
    return R, cb - R @ ca


def rest_pose(figure, margin=0.05):
    """The neutral configuration clamped inside the joint limits (with a margin)."""
    return figure.clamp(figure.neutral(), margin=margin)


def pose_from_keyframe(figure, items: Sequence[Keyframe], weights: Weights, q_start=None, options=None):
    """One configuration matching the keyframes of one frame (points and/or joints),
    by the same solver on that single frame, from a rigidly aligned rest pose."""
    import pinocchio as pin

    q0 = rest_pose(figure) if q_start is None else np.array(q_start, float)
    rows = []
    joints = {}
    for k in items:
        if k.joints is not None:
            joints.update(k.joints)
    points = [k for k in items if k.points is not None]
    if figure.floating and points:
        names = [n for k in points for n in k.points]
        if len(names) >= 3:
            idx = figure.keypoint_index(names)
            B = np.array([p for k in points for p in k.points.values()])
            R, t = _kabsch(figure.keypoints(q0)[idx], B)
            q0[:7] = pin.SE3ToXYZQUAT(pin.SE3(R, t) * pin.XYZQUATToSE3(q0[:7]))
        else:
            idx = figure.keypoint_index(names)
            B = np.array([p for k in points for p in k.points.values()])
            q0[:3] += B.mean(0) - figure.keypoints(q0)[idx].mean(0)
    if joints:
        for name, val in joints.items():
            qs, _ = figure.joint_slices(name)
            val = np.atleast_1d(np.asarray(val, float))
            if figure.floating and figure.joint_id(name) == 1 and val.size == 3:
                q0[0:3] = val
            else:
                q0[qs] = val
    one = Keyframes([replace(k, frame=0) for k in items])
    rows += _keyframe_rows(figure, one, 1)
    rows.append(JointLimits(figure, 1, weights.sigma_limits))
    # weak prior towards the rest pose on every joint (keeps unkeyed joints sensible)
    rest = rest_pose(figure)
    prior = {n: rest[figure.joint_slices(n)[0]] for n in figure.joint_names if not (figure.floating and figure.joint_id(n) == 1)}
    if prior:
        rows.append(JointKeyframes(figure, [(0, weights.sigma_init_prior, prior)]))
        rows[-1].name = "rest_prior"
    problem = ReconstructionProblem(figure, 1, rows)
    res = solve(problem, q0[None], options or SolverOptions(max_iterations=60, ftol=1e-9))
    return res.x[0]


def init_from_keyframes(figure, keyframes: Keyframes, n_frames: int, factor: int, weights: Weights):
    """Poses at the keyframes' frames, geodesically interpolated (held constant outside)."""
    by_frame: dict[int, list[Keyframe]] = {}
    for k in keyframes:
        by_frame.setdefault(k.frame * factor, []).append(k)
    frames = sorted(by_frame)
    poses = {}
    prev = None
    for f in frames:
        poses[f] = pose_from_keyframe(figure, by_frame[f], weights, q_start=prev)
        prev = poses[f]
    Q = np.empty((n_frames, figure.nq))
    for t in range(n_frames):
        if t <= frames[0]:
            Q[t] = poses[frames[0]]
        elif t >= frames[-1]:
            Q[t] = poses[frames[-1]]
        else:
            k = np.searchsorted(frames, t, side="right")
            a, b = frames[k - 1], frames[k]
            Q[t] = figure.interpolate(poses[a], poses[b], (t - a) / (b - a))
    return Q


def _place_on_tracks(figure, Q, camera, meas: Measurement2D):
    """Translate each observed frame's root so the figure's observed keypoints project
    onto the tracks' centroid (in the image plane, keeping camera depth); frames in
    between get the interpolated shift."""
    if not figure.floating or meas is None or len(meas.frames) == 0:
        return Q
    Q = Q.copy()
    P = figure.keypoints(Q[meas.frames])[:, meas.keypoints]  # (N, M, 3)
    obs = meas.observed
    shift = np.zeros((len(meas.frames), 3))
    R = camera.R
    for n in range(len(meas.frames)):
        o = obs[n]
        if o.sum() == 0:
            continue
        uv_model = camera.project(P[n, o]).mean(0)
        uv_obs = meas.uv_px[n, o].mean(0)
        if hasattr(camera, "scale"):
            d_cam = np.r_[(uv_obs - uv_model) / camera.scale, 0.0]
        else:
            z = max(float(camera.depth(P[n, o]).mean()), 1e-3)
            d_cam = np.r_[(uv_obs - uv_model) * z / np.array([camera.K[0, 0], camera.K[1, 1]]), 0.0]
        shift[n] = R.T @ d_cam
    ok = obs.any(axis=1)
    if not ok.any():
        return Q
    fr = meas.frames[ok]
    for a in range(3):
        Q[:, a] += np.interp(np.arange(len(Q)), fr, shift[ok, a])
    return Q


def default_init(figure, n_frames, camera, meas: Measurement2D | None, smoothing, options=None):
    """A rest pose placed where the 2D tracks are, then rigidly fitted (root only)."""
    q_rest = rest_pose(figure)
    Q = np.tile(q_rest, (n_frames, 1))
    if meas is None or not figure.floating:
        return Q
    if not hasattr(camera, "scale"):
        # perspective: put the figure at a depth where its size matches the tracks
        P = figure.keypoints(q_rest)[meas.keypoints]
        span_model = np.ptp(P, axis=0).max()
        uv = meas.uv_px[meas.observed.any(1)]
        span_px = np.nanmax(np.ptp(uv, axis=1)) if uv.size else 1.0
        f = float(np.mean([camera.K[0, 0], camera.K[1, 1]]))
        z = f * span_model / max(span_px, 1e-6)
        centre_cam = np.array([0.0, 0.0, z])
        Q[:, :3] = (camera.R.T @ (centre_cam - camera.t))[None, :] - (P.mean(0) - q_rest[:3])
    Q = _place_on_tracks(figure, Q, camera, meas)
    active = np.zeros(figure.nv, bool)
    active[figure.root_v] = True
    problem = ReconstructionProblem(figure, n_frames, [meas, smoothing])
    res = solve(problem, Q, options or SolverOptions(max_iterations=30, ftol=1e-5), active=active)
    return res.x


# ----------------------------------------------------------------------------- API
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


@dataclass
class Setup:
    """Everything :func:`reconstruct` solves: the problem (rows on the time grid), the
    start, the tangent entries the data constrains, and the measurement rows."""

    problem: ReconstructionProblem
    q0: np.ndarray
    active: np.ndarray
    measurement: Measurement2D
    fps: float
    camera: object


def build_problem(
    figure,
    tracks: Tracks,
    camera,
    keyframes: Keyframes | Sequence[Keyframe] | None = None,
    *,
    fps_out: float | None = None,
    weights: Weights | None = None,
    init: np.ndarray | str | None = None,
    seed: str | None = None,
    keypoints: Sequence[str] | None = None,
) -> Setup:
    """Validate the inputs, build the rows and the start; see :func:`reconstruct`."""
    weights = weights or Weights()
    if not isinstance(tracks, Tracks):
        raise InputError(f"tracks must be a pinrecon.Tracks, got {type(tracks).__name__}", field="tracks")
    if keyframes is not None and not isinstance(keyframes, Keyframes):
        keyframes = Keyframes(list(keyframes))
    factor = _upsample_factor(tracks.fps, fps_out)
    T_obs = tracks.T
    if T_obs < 1:
        raise InputError("tracks have no frames", file=tracks.source, field="points")
    T = (T_obs - 1) * factor + 1
    fps = tracks.fps * factor
    names = list(keypoints) if keypoints is not None else list(tracks.names)
    sub = tracks.select(names)
    shared = _shared_names(figure, sub.names, tracks.source)
    sub = sub.select(shared)
    if keyframes is not None:
        keyframes.validate(figure, T_obs)

    meas = measurement_rows(figure, sub, camera, factor, weights)
    smoothing, limits = prior_rows(figure, T, fps, weights)
    active = _observable(figure, shared, keyframes)
    rows = [meas, limits, smoothing]
    if weights.sigma_posture is not None:
        rows.append(Posture(figure, T, rest_pose(figure), weights.sigma_posture, active))
    if keyframes is not None and len(keyframes):
        rows += _keyframe_rows(figure, keyframes, factor)

    # --- initial trajectory
    if seed is not None:
        if seed != "planarity":
            raise InputError(f"unknown seed {seed!r}; the only seed is 'planarity'", field="seed")
        from .planarity.seed import planarity_seed

        Q0 = planarity_seed(figure, sub, camera, keyframes, factor=factor, weights=weights)
    elif isinstance(init, np.ndarray) or (init is not None and not isinstance(init, str)):
        Q0 = figure.check_q(np.asarray(init, float), field="init")
        if Q0.shape != (T, figure.nq):
            raise InputError(f"expected shape {(T, figure.nq)}, got {Q0.shape}", field="init")
        Q0 = figure.normalize(Q0)
    else:
        mode = init or ("keyframes" if keyframes is not None and len(keyframes) else "default")
        if mode == "keyframes":
            if keyframes is None or not len(keyframes):
                raise InputError("init='keyframes' needs keyframes", field="init")
            Q0 = init_from_keyframes(figure, keyframes, T, factor, weights)
            Q0 = _place_on_tracks(figure, Q0, camera, meas)
        elif mode == "default":
            Q0 = default_init(figure, T, camera, meas, smoothing)
        else:
            raise InputError(f"init must be an array, 'keyframes' or 'default', got {init!r}", field="init")
    Q0 = figure.clamp(Q0, margin=1e-3)
    return Setup(ReconstructionProblem(figure, T, rows), Q0, active, meas, fps, camera)


def reconstruct(
    figure,
    tracks: Tracks,
    camera,
    keyframes: Keyframes | Sequence[Keyframe] | None = None,
    *,
    fps_out: float | None = None,
    weights: Weights | None = None,
    init: np.ndarray | str | None = None,
    seed: str | None = None,
    options: SolverOptions | None = None,
    callback: Callable | None = None,
    keypoints: Sequence[str] | None = None,
) -> Result:
    """Reconstruct the figure's motion from 2D tracks seen by ``camera``.

    Parameters
    ----------
    figure : :class:`pinrecon.Figure`.
    tracks : :class:`pinrecon.Tracks`; names are matched to the figure's keypoints.
    camera : :class:`~pinrecon.cameras.Orthographic` or :class:`~pinrecon.cameras.Perspective`.
    keyframes : optional :class:`~pinrecon.tracks.Keyframes` (frames index the tracks).
    fps_out : reconstruction rate, an integer multiple of ``tracks.fps`` (super-sampled
        frames have no observation); default ``tracks.fps``.
    weights : :class:`Weights`.
    init : a (T_out, nq) start, or ``"keyframes"``, ``"default"``; default: keyframes
        when there are any, else the default start (the rest pose placed on the tracks
        and rigidly fitted). ``seed`` overrides it.
    seed : ``"planarity"`` to start from the planarity module's seed (hinge axes and
        depth signs of the limbs from the 2D tracks; see :mod:`pinrecon.planarity.seed`).
    options : :class:`~pinrecon.solver.SolverOptions`.
    callback : called with each :class:`~pinrecon.solver.IterationReport`; return True to stop.
    keypoints : track names to use (default: every track name the figure has).

    Returns
    -------
    :class:`Result`
    """
    setup = build_problem(
        figure, tracks, camera, keyframes, fps_out=fps_out, weights=weights, init=init, seed=seed, keypoints=keypoints
    )
    res = solve(setup.problem, setup.q0, options, callback, active=setup.active)
    return _package(figure, res, setup.problem, setup.measurement, setup.fps, camera)


def _observable(figure, names, keyframes):
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


def _package(figure, res: SolveResult, problem, meas, fps, camera):
    Q = figure.normalize(res.x)
    P = figure.keypoints(Q)
    T = Q.shape[0]
    err = np.full(T, np.nan)
    observed = np.zeros(T, bool)
    if meas is not None and len(meas.frames):
        st = problem.state(Q, jacobian=False)
        e = meas.reprojection_error_px(st)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            err[meas.frames] = np.nanmean(e, axis=1)
        observed[meas.frames] = True
    return Result(figure, Q, np.arange(T) / fps, fps, P, err, res, observed, camera)


def reconstruct_markers(
    figure,
    markers: Markers,
    keyframes: Keyframes | None = None,
    *,
    fps_out: float | None = None,
    weights: Weights | None = None,
    init: np.ndarray | None = None,
    options: SolverOptions | None = None,
    callback: Callable | None = None,
) -> Result:
    """Fit the figure to noisy 3D markers with dropped frames (motion-capture smoothing
    and gap filling): 3D point rows, limits and smoothing in one batch solve."""
    weights = weights or Weights()
    factor = _upsample_factor(markers.fps, fps_out)
    T = (markers.T - 1) * factor + 1
    fps = markers.fps * factor
    shared = _shared_names(figure, markers.names, markers.source, what="markers")
    idx_m = [markers.names.index(n) for n in shared]
    pts = markers.points[:, idx_m]
    obs = np.all(np.isfinite(pts), axis=2)
    rows_obs = np.where(obs.any(axis=1))[0]
    if len(rows_obs) == 0:
        raise InputError("no marker is observed in any frame", file=markers.source, field="points")
    mk = Points3D(rows_obs * factor, figure.keypoint_index(shared), pts[rows_obs], weights.sigma_markers_m, name="markers")
    smoothing, limits = prior_rows(figure, T, fps, weights)
    rows = [mk, limits, smoothing]
    if weights.sigma_posture is not None:
        rows.append(Posture(figure, T, rest_pose(figure), weights.sigma_posture))
    if keyframes is not None:
        keyframes.validate(figure, markers.T)
        rows += _keyframe_rows(figure, keyframes, factor)
    if init is None:
        # each observed frame: pose from its markers (as a point keyframe); interpolate
        step = max(1, len(rows_obs) // 60)
        kf = []
        for f in rows_obs[::step]:
            d = {n: pts[f, j] for j, n in enumerate(shared) if obs[f, j]}
            if len(d) >= 3:
                kf.append(Keyframe(int(f), weights.sigma_markers_m, points=d))
        if not kf:
            raise InputError("no frame has 3 or more markers to start from", file=markers.source, field="points")
        Q0 = init_from_keyframes(figure, Keyframes(kf), T, factor, weights)
    else:
        Q0 = figure.normalize(np.asarray(init, float))
    problem = ReconstructionProblem(figure, T, rows)
    res = solve(problem, figure.clamp(Q0, 1e-3), options, callback)
    return _package(figure, res, problem, None, fps, None)
