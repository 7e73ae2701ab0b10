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

import functools
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from .contact import foot_keypoints
from .errors import InputError
from .identifiability import proportions_identifiability
from .lifter import DEFAULT_LIFTER, attach_lifter, resolve_lifter
from .prior_yield import adapt_prior, decided_by_keyframes
from .problem import (
    ReconstructionProblem,
    Weights,
    default_calibrate,
    has_point_keyframes,
    make_marker_problem,
    make_problem,
)
from .processes import Beside, forkable
from .result import Result, load_result
from .rows import Measurement2D
from .rows.lifted import LiftedPose, disagreement_extras
from .rows.posture import prior_for
from .solver import SolveResult, SolverOptions, globals_of, solve
from .stages import Run, StageReport, check_skip, relabel_inputs, run_stages, with_lengths
from .starts import available_starts, get_start, initial_trajectory, sparse_keyframes
from .starts.camera_auto import (
    AutoCamera,
    auto_camera,
    camera_scale_from_keyframes,
    doubt_focal,
    image_size_of,
    keyframe_correspondences,
    keyframe_focal_interval,
    placed_by_keyframes,
)
from .starts.lifted import has_lifted
from .starts.limbs import kept_lengths, limb_segments, measured_lengths
from .tracks import Keyframe, Keyframes, Markers, Tracks
from .unfamiliar import (
    BROADER_PRIOR,
    SWITCH_SHARE,
    broader_prior,
    early_verdict,
    switch_extras,
    switch_share,
    unfamiliar_poses,
)
from .windowed import lead_base, solve_lead, solve_windowed, windowed_length

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
    g0: np.ndarray | None = None


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


def _lengths_measurable(auto_projection: str | None) -> bool:
    """Whether one camera's tracks can measure the limb lengths: a given camera
    (``auto_projection`` None), or the perspective auto camera (its start places the
    figure by its size, so the lengths come out relative to the figure's whatever the
    focal length); not the orthographic auto camera (measured worse with them)."""
    return auto_projection is None or auto_projection == "perspective"


def default_feet(figure, tracks, keypoints=None) -> bool:
    """Whether :func:`reconstruct` puts the feet on the ground when neither ``floor`` nor
    ``contact`` is given: for the generic human (``meta["generic"] == "human"``, calibrated
    or not) whose tracks see a foot point (an ankle, heel or toe) in some frame. Other figures (a robot,
    a BVH skeleton) may not stand on a floor; pass ``floor="auto"`` for them. Measured in
    ``bench/README.md`` (issue 10's detector walk with first and last keyframes: flipped
    limb segments 6.0 -> 4.4 %; the run, whose ankles are never still, unchanged)."""
    if (getattr(figure, "meta", None) or {}).get("generic") != "human":
        return False
    names = {n for t in (tracks if isinstance(tracks, (list, tuple)) else [tracks])
             for n, seen in zip(t.names, t.observed.any(axis=0)) if seen}
    if keypoints is not None:
        names &= set(keypoints)
    return bool(foot_keypoints(figure, sorted(names & set(figure.keypoint_names))))


def _several_views(tracks) -> bool:
    """Whether ``tracks`` are several cameras' (a list of two or more): they see depth."""
    return isinstance(tracks, (list, tuple)) and len(tracks) > 1


def _camera_and_mode(figure, tracks, camera, keyframes, calibrate, image_size=None, lengths_from_tracks=False):
    """The camera(s) to build the problem with and the calibration mode.

    ``camera="auto"`` (or an :class:`~pinrecon.starts.camera_auto.AutoCamera`): the
    auto camera (:func:`~pinrecon.starts.camera_auto.auto_camera`), its focal length (or
    scale) calibrated unless ``calibrate`` says otherwise. A given camera whose scale is
    calibrated starts from the point keyframes' least-squares value
    (:func:`~pinrecon.starts.camera_auto.camera_scale_from_keyframes`). Returns
    ``(camera, mode, auto)`` with ``auto`` a description of the auto camera or ``None``.
    """
    auto = AutoCamera.parse(camera, image_size=image_size) if isinstance(camera, (str, AutoCamera)) else None
    one_view = _lengths_measurable(auto and auto.projection) and not isinstance(tracks, (list, tuple))
    several = _several_views(tracks)  # with the auto camera: refused just below
    mode = default_calibrate(figure, keyframes, lengths_from_tracks and one_view, several) if calibrate is None else calibrate
    if isinstance(camera, str) and auto is None:
        raise InputError(f"a camera, a list of cameras or 'auto', got {camera!r}", field="camera")
    if auto is not None:
        if isinstance(tracks, (list, tuple)):
            raise InputError("the auto camera is for one camera's tracks; give every camera of several", field="camera")
        if auto.image_size is None and image_size is not None:
            auto = AutoCamera(image_size, auto.projection, auto.fov_deg)
        camera = auto_camera(tracks, figure, auto.image_size, auto.projection, fov_deg=auto.fov_deg,
                             keyframes=keyframes)
        if calibrate is None:
            mode = "lengths+camera" if mode == "lengths" else "camera"
        posed = has_point_keyframes(keyframes)
        if posed:  # their own faults (a frame outside the clip, a misspelt name) first, by name
            keyframes.validate(figure, tracks.T)
        placed = placed_by_keyframes(camera)
        if posed and not placed:  # the keyframes' world is not the gauge camera's: they would contradict it
            n = len(keyframe_correspondences(tracks, keyframes)[0])
            raise InputError(
                f"the point keyframes meet the tracks in {n} point(s): placing the auto camera in their world needs "
                "4 or more, not all in one plane. Give a camera file (--camera FILE), more keyframe points, or no "
                "point keyframes", file=getattr(keyframes, "source", None), field="keyframes")
        desc = {"projection": auto.projection, "image_size": list(image_size_of(tracks, auto.image_size)),
                "start": camera.to_dict(),
                "pose": "from the point keyframes" if placed else "gauge: the world is the camera's (optical centre "
                "at the origin, looking along +Z, +Y up)"}
        if auto.projection == "perspective":
            desc["fov_deg"] = float(auto.fov_deg)
            X, uv = keyframe_correspondences(tracks, keyframes) if posed else ((), ())
            if len(X) >= 6:  # how far they fix the focal length, placing the camera too
                (lo, hi), bounded = keyframe_focal_interval(X, uv, camera)
                desc["keyframe_focal"] = {"interval_px": [lo, hi], "bounded": list(bounded), "points": len(X),
                                          "frames": len({k.frame for k in keyframes if k.points})}
        return camera, mode, desc
    if "camera" in str(mode) and keyframes is not None:
        if isinstance(camera, (list, tuple)):
            trk = tracks if isinstance(tracks, (list, tuple)) else [tracks]
            same = all(t.fps == trk[0].fps and t.T == trk[0].T for t in trk)
            camera = [camera_scale_from_keyframes(c, t, keyframes) if same or i == 0 else c
                      for i, (c, t) in enumerate(zip(camera, trk))]
        else:
            camera = camera_scale_from_keyframes(camera, tracks, keyframes)
    return camera, mode, None


def _pose_unknown(auto: dict | None, mode: str, camera) -> bool:
    """Whether the auto camera's pose is a global unknown of the one batch solve: a
    perspective auto camera that the 3D point keyframes placed
    (:func:`~pinrecon.starts.camera_auto.placed_by_keyframes`: they fix the world, so
    where the camera stands in it is observable, and the tracks of every frame say more
    about it than the keyframes' few points), its focal length calibrated. Long clips
    solved in windows keep it where the keyframes put it (a window without a keyframe
    cannot see it)."""
    return (auto is not None and auto.get("projection") == "perspective" and "camera" in str(mode)
            and placed_by_keyframes(camera))


def build_problem(
    figure,
    tracks: Tracks | Sequence[Tracks],
    camera,
    keyframes: Keyframes | Sequence[Keyframe] | None = None,
    *,
    fps_out: float | None = None,
    weights: Weights | None = None,
    init: np.ndarray | str | None = None,
    seed: str | None = None,
    keypoints: Sequence[str] | None = None,
    calibrate: str | None = None,
    image_size=None,
    lifter="none",
) -> Setup:
    """The problem and its start, unsolved; see :func:`reconstruct` (solve it with
    ``solve(setup.problem, setup.q0, active=setup.active, g0=setup.g0)``). ``lifter``
    (``"auto"`` or a weights file) puts pinrecon's lifter's rows in from the start (reconstruct's
    first solve has them only when its pose prior may not switch). With 3D keyframes dense enough
    to be the start, the pose prior is adapted to them as reconstruct's ``solve`` stage does
    (:func:`pinrecon.prior_yield.adapt_prior`)."""
    camera, mode, auto = _camera_and_mode(figure, tracks, camera, keyframes, calibrate, image_size)
    tracks = attach_lifter(figure, tracks, camera, lifter, intrinsics=auto is None)
    problem = make_problem(figure, tracks, camera, keyframes, fps_out=fps_out, weights=weights, keypoints=keypoints,
                           calibrate=mode, camera_pose=_pose_unknown(auto, mode, camera))
    q0 = initial_trajectory(problem, _start_name(init, seed))
    if _yield_at_start(problem, keyframes, init, seed, ()):  # as reconstruct's solve stage: the prior adapted
        problem, _ = adapt_prior(problem, q0, problem.g0, keyframes=True)
    return Setup(problem, q0, problem.active, problem.measurement, problem.fps, problem.camera, problem.g0)



def _timed(fn):
    """Record the whole call's wall time in the result (``extras["run_time_s"]``), which the
    summary reports (the solver's own time is that of its last solve only); and say each
    warning of the call once: its stages make the problem again (the lengths measured, the
    prior's switch), which would repeat its notes (points not on the figure, ...). The caller's
    filters and ``warnings.showwarning`` apply as before."""

    @functools.wraps(fn)
    def run(*args, **kwargs):
        t0 = time.perf_counter()
        with warnings.catch_warnings():  # restores the caller's showwarning
            said, show = set(), warnings.showwarning

            def once(message, category, filename, lineno, file=None, line=None):
                if (category, str(message)) not in said:
                    said.add((category, str(message)))
                    show(message, category, filename, lineno, file, line)

            warnings.showwarning = once
            result = fn(*args, **kwargs)
        result.extras["run_time_s"] = np.float64(time.perf_counter() - t0)
        return result

    return run


@_timed
def reconstruct(
    figure, tracks: Tracks | Sequence[Tracks], camera, keyframes: Keyframes | Sequence[Keyframe] | None = None, *,
    fps_out: float | None = None, weights: Weights | None = None, init: np.ndarray | str | None = None,
    seed: str | None = None, options: SolverOptions | None = None, callback: Callable | None = None,
    keypoints: Sequence[str] | None = None, floor=None, contact=None, contact_settings=None,
    calibrate: str | None = None, image_size=None, window: int | None = None, lengths_from_tracks: bool = True,
    skip: Sequence[str] = (), progress: Callable | None = None, lifter=DEFAULT_LIFTER,
) -> Result:
    """Reconstruct the figure's motion from 2D tracks seen by ``camera`` (or cameras)::

        result = reconstruct(Figure.human(), tracks, "auto", image_size=(1920, 1080))
        result = reconstruct(fig, [tracks1, tracks2], load_cameras("Calib.toml"), keyframes)

    ``tracks``: :class:`~pinrecon.tracks.Tracks` (a lifter's 3D in ``tracks.lifted`` enters as
    lifted-pose rows), or one per camera. ``camera``: a camera, a list of them paired with
    ``tracks``, or ``"auto"`` / ``"auto:orthographic"`` / an :class:`~pinrecon.starts.camera_auto.
    AutoCamera` (estimated from the tracks; ``image_size`` (W, H)). ``keyframes``: optional
    :class:`~pinrecon.tracks.Keyframes`. ``fps_out``: a multiple of the tracks' rate.
    ``weights``: :class:`~pinrecon.weights.Weights`. ``init``: a (T, nq) warm start or a start's
    name; ``seed``: a start's name (:func:`pinrecon.starts.available_starts`). ``options``,
    ``callback``: the solver's (:class:`~pinrecon.solver.SolverOptions`; ``callback(report)``
    returning True stops). ``keypoints``: the track names to use. ``floor``, ``contact``,
    ``contact_settings``: feet on the ground (:mod:`pinrecon.contact`; on by default for the
    generic human, ``floor="none"`` turns it off). ``calibrate``: ``"none"``, ``"lengths"``,
    ``"camera"`` or ``"lengths+camera"`` (default :func:`pinrecon.problem.default_calibrate`;
    ``lengths_from_tracks`` starts one camera's lengths where the tracks measure them).
    ``window``: frames per window of a long clip (:mod:`pinrecon.windowed`, solved on every core; 0: one batch).
    ``skip``: stages to switch off; ``progress(name)``: called as each starts (:data:`pinrecon.stages.STAGES`).
    ``lifter``: pinrecon's own lifter (``"auto"``, ``"none"`` or a weights file), joining with the
    broader prior. Parameters in full: ``docs/reconstruct.md``. Returns a :class:`~pinrecon.result.Result`;
    ``result.stages``: a :class:`~pinrecon.stages.StageReport` per stage (time, cost change, what changed).
    """
    skip = check_skip(skip)
    floor, contact, off = _feet_settings(floor, contact)
    camera, mode, auto = _camera_and_mode(figure, tracks, camera, keyframes, calibrate, image_size,
                                          lengths_from_tracks=bool(lengths_from_tracks))
    default = prior_for(figure, "auto") if _may_broaden(figure, weights, init) else None
    lift = None if default is None else functools.partial(  # it joins with the broader prior (the prior stage)
        attach_lifter, figure, camera=camera, lifter=resolve_lifter(lifter), intrinsics=auto is None)
    if default is not None:  # the default prior named; a broader one when it does not know the clip
        weights = replace(weights or Weights(), pose_prior_model=default)
    inputs = {"figure": figure, "tracks": tracks, "camera": camera, "keyframes": keyframes, "fps_out": fps_out,
              "weights": weights, "keypoints": keypoints}
    problem = make_problem(**inputs, calibrate=mode)
    limit = switch_share(bool(keyframes), _several_views(tracks))  # the unfamiliar share that switches
    adapt = _yield_at_start(problem, keyframes, init, seed, skip)  # the prior adapted to dense keyframes
    span = windowed_length(problem.n_frames, window if window is not None or floor is None and contact is None else 0)
    if span:  # a long clip: windows in bounded memory (the fault stage runs in each)
        if floor is not None or contact is not None:
            raise InputError("the feet stage (floor, contact) needs one batch solve: pass window=0", field="window")
        problem, relabelled = _labels_up_front(problem, inputs, mode, skip)  # the windows run no stages
        result = _reconstruct_windowed(problem, inputs, mode, calibrate, auto, _start_name(init, seed), init, span,
                                       default, limit, options, callback, lift, adapt)
        result.extras.update(relabelled)
        return result
    run = _run(problem, inputs, mode, auto, init, seed, options, callback, default, limit, lengths_from_tracks,
               None if off else (floor, contact), contact_settings, lift, adapt)
    return _result(run, run_stages(run, skip, progress))


def _labels_up_front(problem, inputs, mode, skip):
    """``(problem, extras)``: the stage ``labels`` for a clip solved in windows (which run no
    stages), :func:`pinrecon.stages.relabel_inputs`."""
    if "labels" in skip:
        return problem, {}
    relabelled, extras, _, _ = relabel_inputs(inputs, mode)
    return relabelled or problem, extras


def _feet_settings(floor, contact):
    """``(floor, contact, off)``: ``floor="none"`` (or False) turns the feet stage off."""
    off = floor is False or isinstance(floor, str) and floor.strip().lower() == "none"
    if off and contact not in (None, False):
        raise InputError("contacts need a floor: drop floor='none' or the contacts", field="contact")
    return (None, None, True) if off else (floor, contact, False)


def _run(problem, inputs, mode, auto, init, seed, options, callback, default, limit, lengths_from_tracks, feet,
         contact_settings, lift, adapt) -> Run:
    """The :class:`~pinrecon.stages.Run` of one batch solve; ``feet`` is ``(floor, contact)``,
    or None when the feet stage is off; ``lift`` attaches the lifter at the prior's switch; ``adapt``:
    the pose prior adapted to the start (the keyframes' poses) before the solve."""
    camera, tracks = inputs["camera"], inputs["tracks"]
    if _pose_unknown(auto, mode, camera):  # the keyframes placed the auto camera: its place refined too
        inputs["camera_pose"] = True
        problem = make_problem(**inputs, calibrate=mode)
        auto = {**auto, "pose": "from the point keyframes, then refined by the solve with the tracks"}
    floor, contact = feet or (None, None)
    if feet is not None and floor is None and contact is None and \
            default_feet(inputs["figure"], tracks, inputs["keypoints"]):
        floor = contact = "auto"
    return Run(problem, inputs, mode, _start_name(init, seed), options, callback, auto, default_prior=default,
               lengths=bool(lengths_from_tracks) and _lengths_measurable(auto and auto["projection"])
               and _cold_start(init), switch_limit=limit, mirrors=_mirrors(problem, init), floor=floor,
               contact=contact, contact_settings=contact_settings, measure_lengths=_lengths_from_tracks, lifter=lift,
               yield_at_start=adapt)


def _result(run: Run, reports) -> Result:
    """The :class:`Result` of a run of the stages, with their reports."""
    # a clip solved again with the broader prior is judged by the default's clips (a fallback knows no poses)
    result = _package(run.problem, run.res, run.auto, judge=run.judge)
    if run.feet is not None:
        result.extras.update(run.feet.to_extras())
    if run.switch is not None:
        result.extras.update(switch_extras(*run.switch))
        if run.switch_focal is not None:
            result.extras["prior_switch_focal_px"] = np.float64(run.switch_focal)
        if run.early:  # judged at the start's base solve, before any first solve
            result.extras["prior_switch_early"] = np.bool_(True)
        elif run.judged is not None and run.judged.stopped:  # the first solve stopped there
            result.extras["prior_switch_iteration"] = np.int64(run.judged.iteration)
    if run.conflict is not None:
        result.extras.update(run.conflict.to_extras())
    result.extras.update(run.relabelled)
    result.stages = reports
    return result


def _reconstruct_windowed(problem, inputs, mode, calibrate, auto, start, init, span, default, limit, options,
                          callback, lift=None, adapt=False) -> Result:
    """:func:`reconstruct` of a long clip in windows of ``span`` frames (:mod:`pinrecon.windowed`),
    with the broader prior when the default does not know the poses of its leading stretch (solved
    first, and held by the windows when the clip keeps the default); ``adapt``: each window's prior
    adapted to its keyframes instead (the stage ``yield``)."""
    import time

    t0 = time.perf_counter()
    figure, keyframes = inputs["figure"], inputs["keyframes"]
    found = None
    if calibrate is None and mode in ("lengths", "lengths+camera") and \
            default_calibrate(figure, keyframes, several_views=_several_views(inputs["tracks"])) == "none":
        # the lengths come from the tracks alone: measured on the clip's first frames, as the batch solve's
        found = _stretch_lengths(inputs, mode, start) if _lengths_measurable(auto and auto["projection"]) else None
        if found is None:  # nothing measured: the figure's own lengths
            mode = "camera" if auto is not None else "none"
        problem = with_lengths(inputs, mode, *found) if found else make_problem(**inputs, calibrate=mode)
    # the tracks' own lifted cues decide the limbs' reflections and the heading: no mirror or turn stage (as stages)
    uncued = not has_lifted(problem)
    lead, switch, beside, verdict, at = None, None, None, None, None
    try:
        if default is not None and not adapt:  # the prior judged on the leading stretch's poses, as its globals
            broader = BROADER_PRIOR.get(default)
            # first at its search's base, as the stages' solve: far beyond the share, no stretch solved
            judged = lead_base(problem, start, window=span) if broader else None
            verdict = early_verdict(None if judged is None else judged[1], limit)
            if verdict == "switch":
                switch = (broader, judged[1])
            else:
                if broader and forkable() and verdict is None:  # the broader prior's stretch meanwhile, in a child
                    beside = Beside(_broader_lead, inputs, mode, found, broader, lift, start, options, span, fork=True)
                lead = solve_lead(problem, start, options, callback, window=span, judge=True,
                                  base=None if judged is None else judged[0], limit=limit if broader else None,
                                  on_keep=None if beside is None else beside.cancel)  # far under the share
                judge = lead.judged  # the judge while the stretch was solved (None without a broader prior)
                beside = None if judge is not None and judge.kept else beside  # kept: the child was cancelled
                if judge is not None and judge.stopped:  # far beyond the share: the stretch stopped there
                    switch, at = (broader, judge.share), judge.iteration
                else:
                    unfamiliar = unfamiliar_poses(lead.problem, lead.problem.figure.normalize(lead.x))
                    switch = broader_prior(default, "auto", {} if unfamiliar is None else unfamiliar.to_extras(),
                                           share=limit)
        if switch is not None:
            inputs, problem = _switched(inputs, mode, found, switch[0], lift)
            lead = _taken_lead(beside, callback)  # the broader prior's own stretch (None: solved in the windows')
    finally:
        if beside is not None:
            beside.cancel()  # not taken: the clip keeps the default
    res = solve_windowed(problem, start, options, callback, window=span, mirrors=uncued and _mirrors(problem, init),
                         adapt_prior=adapt, n_jobs=-1, lead=lead, turns=uncued)
    result = _package(problem, res, auto, identify=False, judge=default if switch else None)
    if switch is not None:
        result.extras.update(switch_extras(*switch))
        if verdict == "switch":
            result.extras["prior_switch_early"] = np.bool_(True)
        elif at:
            result.extras["prior_switch_iteration"] = np.int64(at)
    changed = f"windows of {span} frames" + (
        f", pose prior -> {switch[0]} ({100 * switch[1]:.0f} % of the leading stretch's poses unfamiliar"
        f"{' at its base solve' if verdict == 'switch' else f' {at} iterations into its solve' if at else ''})"
        if switch else "")
    result.stages = [StageReport("windowed", time.perf_counter() - t0, float(res.initial_cost), float(res.cost),
                                 changed)]
    return result


def _switched(inputs, mode, found, name: str, lift):
    """``(inputs, problem)`` of a clip solved in windows switched to the broader prior ``name``
    (the lifter's cues joined; ``found``: the limb lengths measured from the tracks, or None)."""
    if lift is not None:  # poses the default prior does not know: the lifter's cues join
        inputs = {**inputs, "tracks": lift(inputs["tracks"])}
    inputs = {**inputs, "weights": replace(inputs["weights"], pose_prior_model=name)}
    return inputs, (with_lengths(inputs, mode, *found) if found else make_problem(**inputs, calibrate=mode))


def _broader_lead(inputs, mode, found, name: str, lift, start, options, span):
    """The leading stretch of the clip switched to ``name`` (:func:`_switched`), as
    :func:`solve_windowed` would solve it, made in a child beside the default's (the switch
    does not depend on it): ``(Lead, its iterations)``, the stretch's problem left here."""
    heard = []
    lead = solve_lead(_switched(inputs, mode, found, name, lift)[1], start, options, heard.append, window=span)
    return replace(lead, problem=None, x=None), heard


def _taken_lead(beside, callback):
    """The broader prior's leading stretch made beside (:func:`_broader_lead`), its iterations
    replayed to the callback; None when there is none or the callback stops it (then
    :func:`solve_windowed` solves it, where the callback is heard)."""
    if beside is None:
        return None
    lead, heard = beside.result()
    if callback is not None and any(callback(rep) for rep in heard):
        return None
    return lead


def _may_broaden(figure, weights, init) -> bool:
    """Whether a solve may be run again with a broader pose prior (:func:`pinrecon.unfamiliar.
    broader_prior`): the figure's prior chosen by default and one broader exists, and a cold
    start (``init`` a start's name or none: a warm start, such as the workbench's, keeps its
    prior)."""
    w = weights or Weights()
    return (w.pose_prior is not None and w.pose_prior_model == "auto" and _cold_start(init)
            and prior_for(figure, "auto") in BROADER_PRIOR)


def _mirrors(problem, init) -> bool:
    """Whether the mirror stage (:func:`pinrecon.starts.mirrors.mirror_stage`) runs: a cold
    start (a warm start, the workbench's, keeps the reflections it is given) with the broader
    pose prior in use (switched to, or named). Where the default prior knows the clip's poses
    its limb scores hold: on bench_real's walk and run every span tried cost more (20 and 16
    candidates, none kept) and only doubled the time; on the dance, whose poses it does not
    know, PA-MPJPE without keyframes went from 74.0 mm before the stage to 41.1 now (arms
    only, runs cut at dips; bench/README.md, "Mirrored limb spans")."""
    return _cold_start(init) and problem.weights.pose_prior_model in BROADER_PRIOR.values()


def _yield_at_start(problem, keyframes, init, seed, skip) -> bool:
    """Whether the pose prior is adapted to the start before the solve (stage ``yield``):
    when the start is the 3D keyframes' poses, dense enough that no search runs."""
    start = _start_name(init, seed)
    return ("yield" not in skip and has_point_keyframes(keyframes) and isinstance(start, str) and start == "auto"
            and not sparse_keyframes(problem))


def _cold_start(init) -> bool:
    """Whether ``init`` asks for a cold start (none, or a start's name), not a warm one."""
    return init is None or isinstance(init, str)


@_timed
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
    calibrate: str | None = None,
) -> Result:
    """Fit the figure to noisy 3D markers with dropped frames (motion-capture smoothing
    and gap filling): 3D point rows, limits and smoothing in one batch solve.

    ``calibrate``: ``"lengths"`` fits the figure's segment lengths to the markers too (its
    proportions as global unknowns, :func:`pinrecon.problem.make_marker_problem`); the
    result's ``figure`` is then the fitted one and ``calibration`` says by how much.
    ``"none"`` keeps the figure as given. Default: ``"lengths"`` for the generic human
    (:meth:`Figure.human <pinrecon.Figure.human>`, not yet calibrated), whose proportions
    are nobody's, ``"none"`` for any other figure (a BVH's own skeleton, a robot). On
    Pose2Sim's triangulated balancing trial (``pinrecon.io.trc.load_trc``) the mean
    distance from its 13 COCO-17 points went from 34.8 mm to 17.7 with the lengths fitted.
    """
    mode = default_calibrate(figure, keyframes, markers=True) if calibrate is None else calibrate
    problem = make_marker_problem(figure, markers, keyframes, fps_out=fps_out, weights=weights, calibrate=mode)
    q0 = initial_trajectory(problem, "markers" if init is None else init)
    res = solve(problem, q0, options, callback, g0=problem.g0)
    return _package(problem, res)


#: the prior on the proportions no tracked limb measures, as a fraction of
#: ``Weights.sigma_proportions``, when the lengths are measured from the tracks: one view
#: does not tell a shoulder's width from the trunk's twist (left free, it drifted by tens
#: of per cent), so they keep the figure's own
HELD_SIGMA = 0.1
#: a clip solved in windows measures one camera's limb lengths on its first this many frames
#: (a long clip's 2000-frame leading stretch measured them as well and raised the 18,000-frame
#: bench's peak memory by 100 MB a process: bench/README.md, bench_long_clip)
LENGTH_FRAMES = 1000


def _lengths_from_tracks(problem: ReconstructionProblem, q0: np.ndarray, start: str, inputs: dict):
    """With proportions as unknowns, one camera and no 3D keyframe, the limb segments'
    lengths measured from the tracks at ``q0``'s depths (:func:`_measured`) become the
    factors' start and the centre of their prior; the start is run again on the figure with
    those lengths (its geometry uses the figure's own lengths). Returns ``(problem, q0)``,
    unchanged when nothing applies. Without it the prior holds the generic figure's
    proportions, which one view cannot correct (a forearm 50 % too long stays too long and
    pushes its error into the joint angles)."""
    found = _measured(problem, q0)
    if found is None:
        return problem, q0
    lengths, measured = found
    motion = make_problem(**{**inputs, "figure": problem.proportions.calibrated_figure(lengths["log_factors0"])},
                          calibrate="none")
    q0 = initial_trajectory(motion, start)
    return with_lengths(inputs, problem.calibrate, lengths, measured, getattr(motion, "reports", {})), q0


def _stretch_lengths(inputs: dict, mode: str, start):
    """:func:`_measured` on the first :data:`LENGTH_FRAMES` frames of a clip solved in windows
    (inside the leading stretch where the windows' globals are solved, with these lengths as
    their start and prior), at its start's depths; None where nothing is measured."""
    if not isinstance(start, str):  # a given start trajectory: no start to measure at
        return None
    tracks = inputs["tracks"]
    lead = make_problem(**{**inputs, "tracks": tracks.frames(0, min(tracks.T, LENGTH_FRAMES))}, calibrate=mode)
    return _measured(lead, initial_trajectory(lead, start))


def _measured(problem: ReconstructionProblem, q0: np.ndarray):
    """``(make_problem's keyword arguments, {group: metres})`` of the limb lengths the tracks
    measure at ``q0``'s depths (:func:`pinrecon.starts.limbs.measured_lengths`: the thighs,
    shanks, upper arms and forearms of the human, each a pair of tracked keypoints one group
    alone scales, :meth:`Proportions.pair_groups`): the factors' start and the centre of their
    prior, the other groups held at the figure's. None without proportions to measure, with
    several cameras or 3D keyframes (they measure the lengths themselves), or nothing measured."""
    props = problem.proportions
    if props is None or len(problem.views) != 1 or has_point_keyframes(problem.keyframes):
        return None
    pairs = limb_segments(problem.figure, list(problem.tracks.names))
    if not pairs:
        return None
    groups = props.pair_groups(pairs)
    L = measured_lengths(problem, q0, pairs)
    Q0 = problem.keypoints(problem.figure.neutral()[None])[0]  # lengths at g0
    theta = np.array(problem.g0[: props.n], float)
    held = np.ones(props.n, bool)  # groups no tracked limb measures keep the figure's proportions
    measured = {}
    for g in sorted({int(x) for x in groups if x >= 0}):
        sel = [i for i, x in enumerate(groups) if x == g and np.isfinite(L[i]) and L[i] > 0]
        if not sel:
            continue
        model = np.array([np.linalg.norm(Q0[pairs[i][0]] - Q0[pairs[i][1]]) for i in sel])
        ratio = float(np.exp(np.mean(np.log(L[sel] / model))))
        if not 0.5 <= ratio <= 2.0:  # a camera or tracks far from the figure: say so, use the bound
            warnings.warn(f"the tracks measure the {props.names[g]} at {ratio:.2f} times the figure's; "
                          f"starting it at {float(np.clip(ratio, 0.5, 2.0)):.1f} times (check the camera and the "
                          "keypoint names)", stacklevel=4)
            ratio = float(np.clip(ratio, 0.5, 2.0))
        theta[g] += float(np.log(ratio))
        measured[props.names[g]] = float(np.mean(model) * ratio)
        held[g] = False
    if not measured:
        return None
    sigma = problem.weights.sigma_proportions
    return {"log_factors0": theta, "sigma_proportions": np.where(held, HELD_SIGMA * sigma, sigma)}, measured


def _package(problem: ReconstructionProblem, res: SolveResult, auto: dict | None = None, *,
             identify: bool = True, judge: str | None = None) -> Result:
    """The solved trajectory as a :class:`Result`: keypoints and per-frame reprojection
    error, over all cameras and per camera. With global unknowns: the calibrated figure,
    its keypoints, the fitted cameras and ``calibration`` (with fitted lengths, and
    ``identify``, which of them the data fix: :func:`~pinrecon.identifiability.
    proportions_identifiability`; a windowed solve brings its own, from the leading
    stretch that fitted them, instead of assembling the whole clip at once). ``judge``, the
    prior whose clips the poses are measured against (:func:`~pinrecon.unfamiliar.
    unfamiliar_poses`) when it is not the one solved with: the default of a clip solved again
    with the broader one."""
    g = globals_of(res)
    g = problem.g0 if g is None else g
    Q = problem.figure.normalize(res.x)
    figure = problem.figure_at(g)
    P = figure.keypoints(Q)
    T = Q.shape[0]
    views = problem.views
    err_sum, err_n = np.zeros(T), np.zeros(T)
    per_camera = np.full((len(views), T), np.nan)
    observed = np.zeros(T, bool)
    if views:
        state = problem.state(Q, jacobian=False, g=g)
    for c, view in enumerate(views):
        meas = view.measurement
        if not len(meas.frames):
            continue
        e = meas.reprojection_error_px(state)
        ok = np.isfinite(e)
        n = ok.sum(axis=1)
        s = np.where(ok, e, 0.0).sum(axis=1)
        np.add.at(err_sum, meas.frames, s)
        np.add.at(err_n, meas.frames, n)
        with np.errstate(invalid="ignore", divide="ignore"):
            per_camera[c, meas.frames] = np.where(n > 0, s / np.maximum(n, 1), np.nan)
        observed[meas.frames] = True
    with np.errstate(invalid="ignore", divide="ignore"):
        err = np.where(err_n > 0, err_sum / np.maximum(err_n, 1), np.nan)
    # where the pose prior extrapolates, and limb depths from 2D with it (3D markers measure them)
    unfamiliar = unfamiliar_poses(problem, Q, model=judge) if getattr(problem, "markers", None) is None else None
    if unfamiliar is not None and not decided_by_keyframes(problem):  # ... and an auto focal length, owed to the prior
        auto = doubt_focal(auto, unfamiliar.share, limit=SWITCH_SHARE,
                           broader=problem.weights.pose_prior_model if judge else None)
    ident = proportions_identifiability(problem, Q, g) if identify else getattr(res, "identifiability", None)
    result = Result(
        figure, Q, np.arange(T) / problem.fps, problem.fps, P, err, res, observed,
        cameras=problem.cameras_at(g), camera_names=problem.camera_names,
        reprojection_error_px_per_camera=per_camera if views else None,
        calibration={**problem.calibration(g), **({"camera_auto": auto} if auto else {}),
                     **({"identifiability": ident} if ident else {}), **kept_lengths(problem, Q, g),
                     **({"lengths_from_tracks": problem.measured_lengths} if getattr(problem, "measured_lengths", None)
                        else {})},
    )
    for report in getattr(problem, "reports", {}).values():  # the hypotheses start, the fault stage
        result.extras.update(report.to_extras())
    if unfamiliar is not None:
        result.extras.update(unfamiliar.to_extras())
    lifted = [r for r in problem.rows if isinstance(r, LiftedPose)]
    if lifted:  # where the lifter and the solution disagree, per frame and bone
        result.extras.update(disagreement_extras(lifted, problem.state(Q, jacobian=False, g=g), T))
    return result
