"""The pipeline a user calls: build the problem, start, solve, package a result.

``reconstruct(figure, tracks, camera, keyframes)`` is DiFranco, Cham & Rehg's batch MAP
estimate of the whole trajectory from 2D tracks (their section 4, eq. 5):

1. the problem (:mod:`pinrecon.problem`): 2D measurement rows, joint-limit barriers,
   constant-velocity smoothing on the Lie group, full or partial keyframes;
2. a start (:mod:`pinrecon.starts`): the rest pose on the tracks, the keyframes
   interpolated, the planarity seed, or any registered start;
3. the solve: the block-banded Gauss-Newton of :mod:`pinrecon.solver`;
4. the result (:mod:`pinrecon.result`).

``reconstruct_markers`` does the same from 3D markers (the noise channel only:
smoothing and gap filling of motion capture).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .problem import ReconstructionProblem, Weights, make_marker_problem, make_problem
from .result import Result, load_result
from .rows import Measurement2D
from .solver import SolveResult, SolverOptions, solve
from .starts import available_starts, get_start, initial_trajectory
from .tracks import Keyframe, Keyframes, Markers, Tracks

__all__ = [
    "reconstruct",
    "reconstruct_markers",
    "build_problem",
    "Setup",
    # re-exported for compatibility: they live in problem.py and result.py
    "Weights",
    "ReconstructionProblem",
    "Result",
    "load_result",
]


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


def _start_name(init, seed):
    """``seed`` names a start; ``init`` is an array (a warm start), a start's name, or
    ``"default"`` (the rest-pose start)."""
    if seed is not None:
        get_start(seed)  # an error listing the starts when unknown
        return seed
    if init is None:
        return "auto"
    if isinstance(init, str):
        if init == "default":
            return "rest"
        if init not in available_starts():
            raise InputError(
                f"init must be a (T, nq) array, 'default' or a start's name {available_starts()}, got {init!r}",
                field="init",
            )
    return init


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
    """The problem and its start, unsolved; see :func:`reconstruct`."""
    problem = make_problem(figure, tracks, camera, keyframes, fps_out=fps_out, weights=weights, keypoints=keypoints)
    q0 = initial_trajectory(problem, _start_name(init, seed))
    return Setup(problem, q0, problem.active, problem.measurement, problem.fps, camera)


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
    weights : :class:`~pinrecon.problem.Weights`.
    init : a (T_out, nq) start (a warm start), or the name of a start; ``"default"`` is
        the rest-pose start. Default: the keyframe start when there are keyframes, else
        the rest-pose start (the rest pose placed on the tracks and rigidly fitted).
    seed : the name of a start (:func:`pinrecon.starts.available_starts`: ``"auto"``,
        ``"rest"``, ``"keyframes"``, ``"planarity"``, and any registered with
        :func:`pinrecon.starts.register_start`); overrides ``init``.
    options : :class:`~pinrecon.solver.SolverOptions`.
    callback : called with each :class:`~pinrecon.solver.IterationReport`; return True to stop.
    keypoints : track names to use (default: every track name the figure has).

    Returns
    -------
    :class:`~pinrecon.result.Result`
    """
    problem = make_problem(figure, tracks, camera, keyframes, fps_out=fps_out, weights=weights, keypoints=keypoints)
    q0 = initial_trajectory(problem, _start_name(init, seed))
    res = solve(problem, q0, options, callback, active=problem.active)
    return _package(problem, res)


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
    problem = make_marker_problem(figure, markers, keyframes, fps_out=fps_out, weights=weights)
    q0 = initial_trajectory(problem, "markers" if init is None else init)
    res = solve(problem, q0, options, callback)
    return _package(problem, res)


def _package(problem: ReconstructionProblem, res: SolveResult) -> Result:
    """The solved trajectory as a :class:`Result`: keypoints and per-frame reprojection error."""
    figure, meas = problem.figure, problem.measurement
    Q = figure.normalize(res.x)
    P = figure.keypoints(Q)
    T = Q.shape[0]
    err = np.full(T, np.nan)
    observed = np.zeros(T, bool)
    if meas is not None and len(meas.frames):
        e = meas.reprojection_error_px(problem.state(Q, jacobian=False))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            err[meas.frames] = np.nanmean(e, axis=1)
        observed[meas.frames] = True
    return Result(figure, Q, np.arange(T) / problem.fps, problem.fps, P, err, res, observed, problem.camera)
