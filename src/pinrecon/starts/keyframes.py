"""The keyframe start: a pose solved at every keyed frame, geodesically interpolated
between them (held constant outside), then placed on the tracks. Also the marker start
of :func:`pinrecon.reconstruct_markers` (every observed frame's markers as a point
keyframe)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ..errors import InputError
from ..problem import ReconstructionProblem, Weights, keyframe_rows, rest_pose
from ..rows import JointKeyframes, JointLimits
from ..solver import SolverOptions, solve
from ..tracks import Keyframe, Keyframes
from .rest import place_on_tracks

__all__ = ["keyframe_start", "marker_start", "pose_from_keyframe", "init_from_keyframes", "kabsch"]


def kabsch(A, B):
    """Rotation R, translation t minimising |R A + t - B| over rows (points (n, 3))."""
    ca, cb = A.mean(0), B.mean(0)
    H = (A - ca).T @ (B - cb)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ np.diag([1, 1, d]) @ U.T
    return R, cb - R @ ca


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
        idx = figure.keypoint_index(names)
        B = np.array([p for k in points for p in k.points.values()])
        if len(names) >= 3:
            R, t = kabsch(figure.keypoints(q0)[idx], B)
            q0[:7] = pin.SE3ToXYZQUAT(pin.SE3(R, t) * pin.XYZQUATToSE3(q0[:7]))
        else:
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
    rows += keyframe_rows(figure, one, 1)
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


def keyframe_start(problem: ReconstructionProblem) -> np.ndarray:
    """Poses solved at the keyframes, interpolated, then placed on the tracks."""
    if problem.keyframes is None or not len(problem.keyframes):
        raise InputError("the keyframe start needs keyframes", field="init")
    Q = init_from_keyframes(problem.figure, problem.keyframes, problem.n_frames, problem.factor, problem.weights)
    return place_on_tracks(problem.figure, Q, problem.camera, problem.measurement)


def marker_start(problem: ReconstructionProblem) -> np.ndarray:
    """Every observed frame's markers (at most about 60 frames, evenly spread) turned into
    a pose as a point keyframe, interpolated in between."""
    mk, weights = problem.markers, problem.weights
    if mk is None:
        raise InputError("the marker start needs a marker problem (make_marker_problem)", field="init")
    obs = mk.observed
    rows_obs = np.where(obs.any(axis=1))[0]
    step = max(1, len(rows_obs) // 60)
    kf = []
    for f in rows_obs[::step]:
        d = {n: mk.points[f, j] for j, n in enumerate(mk.names) if obs[f, j]}
        if len(d) >= 3:
            kf.append(Keyframe(int(f), weights.sigma_markers_m, points=d))
    if not kf:
        raise InputError("no frame has 3 or more markers to start from", file=mk.source, field="points")
    return init_from_keyframes(problem.figure, Keyframes(kf), problem.n_frames, problem.factor, weights)
