"""The stages of :func:`pinrecon.reconstruct`, in the order they run.

DiFranco, Cham & Rehg's section 4 as a list: a start and the batch MAP solve, then the stages
that polish the solution. Every stage has one signature: it takes the :class:`Run` (the problem,
the current solution and what the stages share) and returns what it changed, in words; the
pipeline times it and records a :class:`StageReport` (time, the MAP cost before and after, what
changed). A stage that has nothing to do returns ``None`` and is reported as skipped::

    result = reconstruct(fig, tracks, "auto", image_size=(1920, 1080), skip=("mirrors",))
    for r in result.stages:
        print(r.name, r.seconds, r.cost_after - r.cost_before, r.changed)

=========  ======================================================================================
``labels`` spans of frames where the detector kept the person's left and right the other way
           round, found by the tracks' continuity and relabelled before anything is solved
           (:func:`pinrecon.faults.side_swap_frames`)
``solve``  the start (the rest pose placed on the tracks, or the keyframes, or the named start;
           :func:`pinrecon.starts.auto_start`: the multi-hypothesis search for one camera, the
           lifted start when the tracks carry a lifter's 3D; with one camera, the limbs'
           lengths measured from the tracks) and the batch solve; a start that is dense 3D
           keyframes' poses first adapts the pose prior to them
           (:func:`pinrecon.prior_yield.adapt_prior`). Tracks without 3D of their own take
           pinrecon's lifter's rows from the start, at ``Weights.own_lifter``, while the default
           pose prior holds (:func:`_join_from_start`)
``prior``  the generic human's pose prior switched to its broader mixture and the clip solved
           again when more of its poses than :func:`pinrecon.unfamiliar.switch_share` are
           unknown to the default, pinrecon's lifter joining as lifted-pose rows (``lifter="auto"``);
           not when the prior was adapted to keyframes (they decide the poses); with the tracks'
           own cues from the first solve's lifted start and lengths (it turns only the root,
           which no pose prior sees); where a CPU is spare, the switched solve is made in a
           child beside the first solve (:mod:`pinrecon.processes`) and taken if the clip switches
``yield``  the pose prior widened and re-centred where the data disagree with it
           (:mod:`pinrecon.prior_yield`), the clip solved again warm; with a lifter's 3D and
           the feet stage to come, judged there and solved in its solve (one solve, not two)
``turns``  fast turns the solution holds a turn too few of, wound (warm re-solves)
``mirrors`` the limbs' spans mirrored where that lowers the MAP cost (with the broader prior);
           skipped when the tracks carry a lifter's 3D
``faults`` left/right swaps of the detector repaired (warm re-solve), outliers reported
``focal``  an auto camera's focal length carried down its cost valley (with a lifter's 3D, its
           solves at most :data:`FOCAL_ITERATIONS_LIFTED` iterations each,
           :data:`FOCAL_ROUNDS_LIFTED` move, a long clip profiled on a stretch of
           :data:`FOCAL_PROFILE_FRAMES`; the profile's longer focal lengths solved beside)
``feet``   feet on the ground: floor and contact rows (and the pose prior the yield stage left
           to it adapted), solved again warm
=========  ======================================================================================

With a lifter's 3D the search and the mirror stage no longer pay: on ``bench/bench_stages.py``
(100 frames of walk, run, dances 05_02 and 05_11, and Pose2Sim's trial with MediaPipe's 3D) the
mirror stage changed nothing on any clip (11-13 s on the trial and 05_11); the lifted start
matched the search within 2 mm on the synthetic clips and was 13.5 mm better on the trial, and
the whole call ran 1.7-6 times faster (``bench/README.md``, ``bench_stages.py``).

``skip`` (names of :data:`STAGES` but ``solve``) switches stages off; the result stays valid.
"""

from __future__ import annotations

import functools
import time
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace

import numpy as np

from .contact import solve_on_the_floor
from .errors import InputError
from .faults import fault_stage, relabel_sides, report_outliers, side_swap_frames
from .prior_yield import adapt_prior, pose_prior_row, yield_to_data
from .problem import ReconstructionProblem, make_problem
from .processes import Beside, forkable
from .result import SPANS_SHOWN, StageReport, spans_text
from .solver import SolveResult, SolverOptions, globals_of, solve
from .starts import auto_start, initial_trajectory, searches
from .starts.camera_auto import fitted_focal, implausible_focal, settle_focal
from .starts.hypotheses import hypotheses_start
from .starts.lifted import has_lifted
from .starts.mirrors import mirror_stage
from .starts.turns import turn_stage
from .unfamiliar import (
    BROADER_PRIOR,
    JudgedWhile,
    broader_prior,
    early_verdict,
    judged_at_base,
    unfamiliar_poses,
    unfamiliar_share,
)
from .weights import Weights

#: the focal stage's solves with lifted cues: at most this many iterations each (bench_stages:
#: the same PA-MPJPE and flips on the five clips, the stage 30 % shorter on Pose2Sim's trial)
FOCAL_ITERATIONS_LIFTED = 10
#: with lifted cues, the focal stage moves down its valley once, and reports from the profile
#: already solved (not profiled again): the cues leave the profile no valley on any bench_stages
#: clip, and further moves changed no PA-MPJPE or flip on its five clips (bench_video's four: the
#: mean the same to 0.1 mm)
FOCAL_ROUNDS_LIFTED = 1
#: with lifted cues, where the focal length's cost profile is no valley, the focal stage moves it
#: only within these multiples of the image's diagonal: from a wide angle (a field of view of 118
#: degrees) to a normal lens (focal length = the diagonal, 53 degrees; phones' main cameras are
#: wider). bench_lifted_real's Pose2Sim camera 3 went down such a profile to 3.1 diagonals (6876
#: px, the calibration's 1682) and 92.9 mm, 86.6 with the solve's own 2789 px kept; with 1.5
#: diagonals, cameras 2-4 still moved away from the calibration (2931 -> 3242, 2789 -> 3084, 1934
#: -> 2613 px) and lost 1.5-1.9 mm (bench_stages); the synthetic dances' first 100 frames move
#: down (1682 -> 924, 1588 -> 1178 px), as before
FOCAL_PLAUSIBLE = (0.3, 1.0)
#: with lifted cues, a clip longer than this many frames has its focal length profiled on the
#: stretch of this many where the subject's depth changes most, and moved on the whole clip
#: (:func:`~pinrecon.starts.camera_auto.profile_stretch`; bench_video_long)
FOCAL_PROFILE_FRAMES = 600

__all__ = ["STAGES", "Run", "StageReport", "check_skip", "relabel_inputs", "relabel_spans", "run_stages"]


@dataclass
class Run:
    """What the stages share: the problem (a stage may rebuild it), the current solution, the
    inputs ``make_problem`` was called with (``inputs``, ``mode``), the auto camera's
    description, and the settings the stages read."""

    problem: ReconstructionProblem
    inputs: dict
    mode: str
    start: str | np.ndarray
    options: object = None
    callback: Callable | None = None
    auto: dict | None = None
    res: SolveResult | None = None
    lengths: bool = False  # measure the limbs' lengths from the tracks before the solve
    default_prior: str | None = None  # the default prior named, when a broader one may replace it
    switch_limit: float = 0.5
    mirrors: bool = False
    floor: object = None
    contact: object = None
    contact_settings: object = None
    measure_lengths: Callable | None = None  # (problem, q0, start, inputs) -> (problem, q0)
    yield_at_start: bool = False  # the pose prior adapted to the start (the keyframes' poses) before the solve
    lifter: Callable | None = None  # tracks -> tracks with pinrecon's lifter's 3D cues (pinrecon.lifter)
    joined: bool = False  # pinrecon's lifter joined (the cue rules below are for given cues)
    unjoined: tuple | None = None  # (tracks, weights) before the lifter joined from the start (_join_from_start)
    # what the stages leave for the result
    switch: tuple | None = None
    switch_focal: float | None = None  # the first solve's implausible focal length (px) that switched the prior
    judge: str | None = None
    feet: object = None
    conflict: object = None  # the pose prior's variance factors (pinrecon.prior_yield.PriorConflict)
    relabelled: dict = field(default_factory=dict)  # extras key -> tracks frames relabelled by the stage labels
    caught: list = field(default_factory=list)
    started: tuple | None = None  # the lifted start's (q0, problem): the prior's switch solves from it again
    spare_cpu: bool = False  # a child may solve beside this process (pinrecon.processes.forkable)
    judging: bool = False  # the prior stage runs (it judges the first solve's poses)
    early: bool = False  # the prior switched at the search's base, before any first solve (EARLY_SWITCH)
    judged: JudgedWhile | None = None  # the first solve's judge (its share and iteration where it switched)
    beside: Beside | None = None  # the prior's switched solve made beside the first solve
    skip: frozenset = frozenset()  # the stages switched off (run_stages)
    yield_at_feet: bool = False  # the yield stage left the prior's adaptation to the feet stage's solve


def relabel_spans(tracks):
    """``(tracks, frames, lifted)``: the tracks (or list of them, one per camera) with the
    frames whose left and right labels are the other way round relabelled
    (:func:`pinrecon.faults.side_swap_frames`; a lifter's 3D on the tracks by its own
    continuity, the 2D's frames its prior), and those frames per camera (lists: the 2D's, the 3D's, None for tracks without
    a lifter's 3D)."""
    several = isinstance(tracks, (list, tuple))
    out, frames, lifted = [], [], []
    for t in tracks if several else [tracks]:
        f = side_swap_frames(t)
        g = side_swap_frames(t.lifted, prior=f) if t.lifted is not None else None
        out.append(relabel_sides(t, f, g) if len(f) or g is not None and len(g) else t)
        frames.append(f)
        lifted.append(g)
    return (out if several else out[0]), frames, lifted


def _relabelled_extras(frames, lifted, names) -> dict:
    """The result's extras of :func:`relabel_spans`' frames (``relabelled_frames``,
    ``relabelled_lifted_frames``; ``<camera>_`` before them for every camera but the first)."""
    out = {}
    for v, (f, g) in enumerate(zip(frames, lifted)):
        prefix = "" if v == 0 else f"{names[v]}_"
        out[prefix + "relabelled_frames"] = np.asarray(f, int)
        if g is not None:
            out[prefix + "relabelled_lifted_frames"] = np.asarray(g, int)
    return out


def relabel_inputs(inputs: dict, mode: str):
    """The stage ``labels`` on :func:`~pinrecon.problem.make_problem`'s ``inputs`` (whose
    tracks it replaces): ``(problem, extras, frames, lifted)``, the problem made again on the
    relabelled tracks and the result's extras, or ``(None, {}, frames, lifted)`` when nothing
    was relabelled (frames as :func:`relabel_spans`)."""
    tracks, frames, lifted = relabel_spans(inputs["tracks"])
    if not any(len(f) for f in frames + lifted if f is not None):
        return None, {}, frames, lifted
    inputs["tracks"] = tracks
    problem = make_problem(**inputs, calibrate=mode)
    return problem, _relabelled_extras(frames, lifted, problem.camera_names), frames, lifted


def _labels(run: Run) -> str | None:
    problem, extras, frames, lifted = relabel_inputs(run.inputs, run.mode)
    if problem is None:
        return None
    run.problem, run.relabelled = problem, extras
    names = problem.camera_names
    said = [(f"{names[v]}: " if v else "") + (spans_text(f, SPANS_SHOWN) or "none")
            + ("" if g is None or np.array_equal(f, g) else f" (its 3D: {spans_text(g, SPANS_SHOWN) or 'none'})")
            for v, (f, g) in enumerate(zip(frames, lifted)) if len(f) or g is not None and len(g)]
    return f"left and right exchanged back on frames {'; '.join(said)}"


def _solve(run: Run) -> str:
    # with a broader prior in reserve, the warnings wait for the prior stage's verdict
    with warnings.catch_warnings(record=run.default_prior is not None) as caught:
        if run.default_prior is not None:
            warnings.simplefilter("always")
        auto = isinstance(run.start, str) and run.start == "auto"
        what = "start and batch solve" + _join_from_start(run)
        guard = run.unjoined is None  # the lifter joined from the start: the search's base is no candidate
        start = functools.partial(auto_start, lifted=False, guard_base=guard) if run.joined and auto else run.start
        base = _judged_base(run)
        verdict = early_verdict(None if base is None else base[1], run.switch_limit)
        if verdict is None and run.started is None and not _lifted_start(run):
            _switch_beside(run)  # the switched solve starts afresh (pinrecon's lifter joins): from now on
    if verdict == "switch":
        return _switch_early(run, base[1])
    with warnings.catch_warnings(record=run.default_prior is not None) as more:
        if run.default_prior is not None:
            warnings.simplefilter("always")
        if run.started is not None:  # the lifted start and lengths of before the prior's switch
            q0, run.problem = run.started[0], _remade(run.problem, run.started[1], run.inputs, run.mode)
        else:
            q0 = initial_trajectory(run.problem, start if base is None else functools.partial(
                hypotheses_start, base=base[0], guard_base=guard))
            if run.lengths and run.measure_lengths is not None:
                run.problem, q0 = run.measure_lengths(run.problem, q0, start, run.inputs)
            if _lifted_start(run):
                run.started = (q0, run.problem)
                _switch_beside(run)
        if getattr(run.problem, "measured_lengths", None):
            what += f", {len(run.problem.measured_lengths)} limb lengths measured from the tracks"
        if run.yield_at_start:  # the start is the keyframes' poses: the data's own, before any compromise
            run.problem, run.conflict = adapt_prior(run.problem, q0, run.problem.g0, keyframes=True)
            if run.conflict is not None and run.conflict.conflicting:
                what += f", pose prior adapted to the keyframes on {len(run.conflict.conflicting)} joint(s)"
        run.res = solve(run.problem, q0, run.options, run.callback, active=run.problem.active, g0=run.problem.g0,
                        stop_when=_judge_while(run))
    run.caught = list(caught or []) + list(more or [])
    return f"{what}: {run.res.iterations} iterations, {run.res.status}"


def _join_from_start(run: Run) -> str:
    """Pinrecon's lifter's rows put in from the start, at ``Weights.own_lifter``, for tracks
    without 3D of their own while the default pose prior holds (the auto start, no 3D
    keyframes: they decide what the lifter would guess); its directions only, not its
    proportions (``Weights.lifted_lengths``: the same scores, a fifth less time on
    bench_lifter's walk and run). The inputs it had are kept in ``run.unjoined`` and come
    back if the prior switches (:func:`_switch_to`: the lifter then joins at
    ``Weights.lifted``). Returns what the solve stage says of it ("" when it does not join).
    Measured in bench/bench_lifter.py (``--seeds``)."""
    weights = run.inputs.get("weights") or Weights()
    weight = weights.own_lifter
    if run.lifter is None or not weight or run.joined or _cued(run) or run.started is not None \
            or run.yield_at_start or run.default_prior not in BROADER_PRIOR or run.inputs.get("keyframes") \
            or not (isinstance(run.start, str) and run.start == "auto"):
        return ""
    tracks = run.inputs["tracks"]
    joined = run.lifter(tracks)
    if getattr(joined, "lifted", None) is None:
        return ""
    run.unjoined = (tracks, weights)
    run.inputs["tracks"], run.inputs["weights"] = joined, replace(weights, lifted=weight, lifted_lengths=None)
    run.joined = True
    reports = dict(run.problem.reports)
    run.problem = make_problem(**run.inputs, calibrate=run.mode)
    run.problem.reports.update(reports)
    return f" with pinrecon's lifter's rows (weight {weight:g})"


def _judged_base(run: Run) -> tuple[np.ndarray, float] | None:
    """The first solve's search base and its share of poses the default prior does not know
    (:func:`~pinrecon.unfamiliar.judged_at_base`); None where the prior stage judges no switch
    or the start is no search."""
    broader = BROADER_PRIOR.get(run.default_prior) if run.default_prior is not None else None
    if broader is None or not run.judging or run.yield_at_start or run.started is not None \
            or run.joined and run.unjoined is None \
            or not (isinstance(run.start, str) and run.start == "auto") or not searches(run.problem, not run.joined):
        return None
    return judged_at_base(run.problem)


def _judge_while(run: Run) -> JudgedWhile | None:
    """The first solve's ``stop_when`` where the prior stage judges it (:class:`~pinrecon.unfamiliar.
    JudgedWhile`; ``run.judged``): far beyond the switch's share it stops there, far under it the
    switched solve made beside is dropped (the converged solve is judged as before)."""
    if not run.judging or run.early or run.yield_at_start or run.default_prior not in BROADER_PRIOR:
        return None

    def drop():
        if run.beside is not None:
            run.beside.cancel()
            run.beside = None

    run.judged = JudgedWhile(run.problem, run.switch_limit, on_keep=drop)
    return run.judged


def _stopped(run: Run) -> bool:
    """Whether the first solve stopped where its judge decided the switch (:func:`_judge_while`)."""
    return run.judged is not None and run.judged.stopped


def _switch_early(run: Run, share: float) -> str:
    """The prior's switch made before any first solve (:data:`~pinrecon.unfamiliar.EARLY_SWITCH`):
    the clip solved with the broader prior (and pinrecon's lifter) from its start; the prior
    stage reports it."""
    default = run.default_prior
    name = BROADER_PRIOR[default]
    what = _switch_to(run, name)
    run.switch, run.judge, run.early, run.caught = (name, share), default, True, []
    run.mirrors = run.mirrors or name in BROADER_PRIOR.values()
    return what


def _remade(problem, measured, inputs: dict, mode: str):
    """``problem`` (made from ``inputs`` after the prior's switch) with the limb lengths the
    problem ``measured`` had measured from the tracks; ``problem`` itself when it had none.
    The lifted start depends on neither prior: it turns only the root (:mod:`.starts.lifted`)."""
    lengths = getattr(measured, "lengths_from_tracks", None)
    if not lengths:
        return problem
    return with_lengths(inputs, mode, lengths, measured.measured_lengths, measured.reports)


def with_lengths(inputs: dict, mode: str, lengths: dict, measured: dict, reports: dict | None = None):
    """:func:`~pinrecon.problem.make_problem` of ``inputs`` (calibration ``mode``) with the
    limb lengths measured from the tracks as the proportions' start and the centre of their
    prior: ``lengths``, make_problem's ``log_factors0`` and ``sigma_proportions``; ``measured``,
    metres per segment group (the result's ``calibration["lengths_from_tracks"]``); ``reports``
    added to the problem's."""
    new = make_problem(**inputs, calibrate=mode, **lengths)
    new.reports.update(reports or {})
    new.measured_lengths, new.lengths_from_tracks = measured, lengths
    return new


def _lifted_start(run: Run) -> bool:
    """Whether the start is the lifted one (the tracks' own cues, the ``auto`` start)."""
    return isinstance(run.start, str) and run.start == "auto" and _cued(run)


def _cued(run: Run) -> bool:
    """Whether the tracks came with a lifter's 3D (measured in bench_stages; pinrecon's own
    lifter joining at the prior's switch keeps the stages it was measured with)."""
    return has_lifted(run.problem) and not run.joined


def _reissue(run: Run) -> None:
    for c in run.caught:
        warnings.warn_explicit(c.message, c.category, c.filename, c.lineno, source=c.source)
    run.caught = []


def _prior(run: Run) -> str | None:
    if run.early:
        return (f"pose prior {run.judge} -> {run.switch[0]} ({100 * run.switch[1]:.0f} % of the poses "
                "unfamiliar at the start's base solve): solved with it from the start")
    if run.default_prior is None:
        return None
    if run.conflict is not None and run.conflict.conflicting:  # adapted to the keyframes: they decide the poses
        _reissue(run)
        return None
    if _stopped(run):  # the first solve stopped where its poses decided (_judge_while)
        switch, focal = (BROADER_PRIOR[run.default_prior], run.judged.share), None
    else:
        unfamiliar = unfamiliar_poses(run.problem, run.problem.figure.normalize(run.res.x))
        extras = {} if unfamiliar is None else unfamiliar.to_extras()
        switch = broader_prior(run.default_prior, "auto", extras, share=run.switch_limit)
        focal = _degenerate_focal(run) if switch is None and run.default_prior in BROADER_PRIOR else None
    if focal is not None:  # a degenerate first solve: the broader route (and the lifter's cues) from the start
        switch, run.switch_focal = (BROADER_PRIOR[run.default_prior], unfamiliar_share(extras)), focal
    beside, run.beside = run.beside, None
    if switch is None:
        if beside is not None:
            beside.cancel()
        _reissue(run)
        return None
    run.caught = []  # the first solve's warnings are dropped
    default = run.default_prior
    _switch_to(run, switch[0], _taken(run, beside))
    run.switch, run.judge = switch, default
    run.mirrors = run.mirrors or run.problem.weights.pose_prior_model in BROADER_PRIOR.values()
    why = f"the auto camera's focal length at {focal:.0f} px, implausible" if focal is not None else \
        f"{100 * switch[1]:.0f} % of the poses unfamiliar" + (
            f" {run.judged.iteration} iterations into the first solve" if _stopped(run) else "")
    return f"pose prior {default} -> {switch[0]} ({why}), solved again"


@dataclass
class _Made:
    """What the prior stage needs of a switched solve made beside: its result, and what its
    start left on the problem (the start's reports, the limb lengths measured from the tracks)."""

    res: SolveResult
    reports: dict
    lengths: dict | None
    measured: dict | None


def _switch_to(run: Run, name: str, made: _Made | None = None) -> str | None:
    """The prior stage's switch to the broader prior ``name`` on ``run``: its inputs, problem
    and start made again and solved (the solve's description returned), or the problem made
    again and ``made``'s solve taken."""
    if run.unjoined is not None:  # the lifter joined from the start: it joins again at Weights.lifted
        (run.inputs["tracks"], run.inputs["weights"]), run.unjoined, run.joined = run.unjoined, None, False
    run.inputs["weights"] = replace(run.inputs["weights"], pose_prior_model=name)
    if run.lifter is not None:  # poses the default prior does not know: the lifter's cues join
        given = getattr(run.inputs["tracks"], "lifted", None) is not None
        run.inputs["tracks"] = run.lifter(run.inputs["tracks"])
        run.joined = not given and getattr(run.inputs["tracks"], "lifted", None) is not None
    if made is not None and made.lengths:
        run.problem = with_lengths(run.inputs, run.mode, made.lengths, made.measured, made.reports)
    else:
        run.problem = make_problem(**run.inputs, calibrate=run.mode)
        if made is not None:  # what the child's start left on its problem
            run.problem.reports.update(made.reports)
    if run.started is not None and not _lifted_start(run):
        run.started = None  # the lifter joined: its start now
    if made is not None:
        run.res, run.caught = made.res, []
        return None
    default, run.default_prior = run.default_prior, None
    what = _solve(run)
    run.default_prior = default
    return what


def _made_beside(run: Run, name: str) -> _Made:
    """:func:`_switch_to` in the child (whose copy of ``run`` is its own), as :class:`_Made`."""
    _switch_to(run, name)
    p = run.problem
    return _Made(run.res, dict(p.reports), getattr(p, "lengths_from_tracks", None), getattr(p, "measured_lengths", None))


def _switch_beside(run: Run) -> None:
    """The prior stage's switched solve does not depend on the first solve (with the tracks' own
    cues it starts from the same lifted start and lengths, :func:`_remade`; without them
    pinrecon's lifter joins and its start is made afresh): where a CPU is spare, a child makes it
    while the first solve runs, so that a switch costs no time of its own (``run.beside``). The
    child's solve reports its iterations to nobody; :func:`_taken` replays them."""
    broader = BROADER_PRIOR.get(run.default_prior) if run.default_prior is not None else None
    if broader is None or not run.spare_cpu or run.yield_at_start or run.beside is not None:
        return
    callback, run.callback = run.callback, None
    try:
        run.beside = Beside(_made_beside, run, broader, fork=True)
    finally:
        run.callback = callback


def _taken(run: Run, beside: Beside | None) -> _Made | None:
    """The switched solve made beside (:func:`_switch_beside`: the default's broader prior, the
    one every switch goes to), its iterations replayed to the callback; None when there is none,
    or the callback stops it (then it is solved here, where the callback is heard)."""
    if beside is None:
        return None
    made = beside.result()
    if run.callback is not None and any(run.callback(rep) for rep in made.res.report):
        return None
    return made


def _degenerate_focal(run: Run) -> float | None:
    """The auto camera's focal length (px) after the first solve when no lens but a fisheye or
    beyond a telephoto has it (:func:`~pinrecon.starts.camera_auto.implausible_focal`): the
    solve bent the depths and lengths to fit (the bench's fast spin 05_11 without cues: 239 px for
    1920 x 1080, 265 mm PA-MPJPE; solved again as for unfamiliar poses, 798 px and 54 mm); else None."""
    size = (run.auto or {}).get("image_size")
    if not size or run.auto.get("projection") != "perspective":
        return None
    f = fitted_focal(run.problem, run.res)
    return f if f is not None and implausible_focal(f, size) else None


def _feet_solve(run: Run) -> bool:
    """Whether the feet stage will solve the clip again (it runs, with a floor or contacts)."""
    return "feet" not in run.skip and not (run.floor is None and run.contact is None)


def _keep_conflict(run: Run, conflict) -> None:
    if run.conflict is None or not run.conflict.conflicting:  # what the start found, or this
        run.conflict = conflict


def _yield(run: Run) -> str | None:
    if _cued(run) and _feet_solve(run) and pose_prior_row(run.problem) is not None:
        # the lifted rows hold the poses: the feet stage's solve takes the adapted prior (_feet), one solve
        # instead of two (measured in bench/README.md, bench_video's section)
        run.yield_at_feet = True
        return "left to the feet stage: the pose prior adapted there, where the data disagree, and solved in its solve"
    run.problem, res, conflict = yield_to_data(run.problem, run.res, run.options, run.callback)
    if conflict is None:
        return None
    _keep_conflict(run, conflict)
    if res is run.res:
        return "the pose prior agrees with the data"
    run.res = res
    joints = conflict.conflicting
    return (f"the data disagree with the pose prior on {len(joints)} joint(s) ({', '.join(joints[:4])}"
            f"{', ...' if len(joints) > 4 else ''}): prior widened and re-centred there, solved again")


def _warm(name: str, fn, cued: str | None = None) -> Callable:
    """A stage that re-solves warm through ``fn(problem, res, options, callback) -> res``;
    ``cued``: what the tracks' own lifted cues decide instead, when the stage is skipped with them."""

    def stage(run: Run) -> str | None:
        if name == "mirrors" and not run.mirrors:
            return None
        if cued is not None and _cued(run):
            return f"skipped: the lifted cues decide {cued}"
        before = run.res
        run.res = fn(run.problem, run.res, run.options, run.callback)
        return "nothing kept" if run.res is before else "changed (warm re-solve kept)"

    stage.__name__ = f"_{name}"
    return stage


def _focal(run: Run) -> str | None:
    if not run.auto or run.auto.get("projection") != "perspective":
        return None
    before = run.res
    options, rounds = run.options, {}
    if _cued(run):  # the lifted cues hold the poses: a few steps settle each point of the valley
        options = replace(options or SolverOptions(), max_iterations=FOCAL_ITERATIONS_LIFTED)
        rounds = {"rounds": FOCAL_ROUNDS_LIFTED, "final_profile": False, "profile_frames": FOCAL_PROFILE_FRAMES}
    span = None
    if _cued(run) and run.auto.get("image_size"):  # a profile that is no valley moves only to plausible lengths
        span = tuple(f * float(np.hypot(*run.auto["image_size"])) for f in FOCAL_PLAUSIBLE)
    run.res, run.auto = settle_focal(run.problem, run.res, run.auto, options=options, undetermined_range=span, **rounds)
    if run.res is before:
        return "focal length at the bottom of its valley"
    report_outliers(run.problem, run.res)  # restarted down the valley: the outliers of where it ended
    return "focal length carried down its valley (solved again)"


def _feet(run: Run) -> str | None:
    if not _feet_solve(run):
        return None
    said = ""
    if run.yield_at_feet:  # the yield stage's adaptation (_yield), solved below
        run.problem, conflict = adapt_prior(run.problem, run.res.x, globals_of(run.res))
        _keep_conflict(run, conflict)
        if conflict is not None and conflict.conflicting:
            said = f"; the pose prior widened and re-centred on {len(conflict.conflicting)} joint(s) the data disagree with"
    run.problem, run.res, run.feet = solve_on_the_floor(
        run.problem, run.res, "auto" if run.floor is None else run.floor,
        "auto" if run.contact is None else run.contact,
        settings=run.contact_settings, options=run.options, callback=run.callback,
    )
    return "feet on the floor: contact rows added, solved again" + said


#: The stages in the order they run: name -> function of the :class:`Run`.
STAGES: dict[str, Callable[[Run], str | None]] = {
    "labels": _labels,
    "solve": _solve,
    "prior": _prior,
    "yield": _yield,
    # looked up when called, so a diagnostic may observe a stage (bench/diagnose_mirrors.py)
    # with cues: the turns kept nothing on bench_stages' clips and took 15 s on a long video
    "turns": _warm("turns", lambda *a: turn_stage(*a), cued="the heading through fast turns"),
    "mirrors": _warm("mirrors", lambda *a: mirror_stage(*a), cued="the limbs' reflections"),
    "faults": _warm("faults", lambda *a: fault_stage(*a)),
    "focal": _focal,
    "feet": _feet,
}


def check_skip(skip: Iterable[str] | None) -> frozenset:
    """``skip`` as a set of stage names, refusing unknown names and ``solve``."""
    names = frozenset(skip or ())
    bad = sorted(n for n in names if n not in STAGES or n == "solve")
    if bad:
        raise InputError(f"unknown stage(s) {bad} to skip; stages that can be skipped: "
                         f"{', '.join(n for n in STAGES if n != 'solve')}", field="skip")
    return names


def run_stages(run: Run, skip: Iterable[str] = (), progress: Callable | None = None) -> list[StageReport]:
    """Run :data:`STAGES` in order on ``run`` (all but those in ``skip``); ``progress(name)``
    is called as each stage starts. Returns one :class:`StageReport` per stage."""
    reports = []
    run.skip = frozenset(skip)
    run.judging = "prior" not in skip
    run.spare_cpu = run.judging and forkable(run.problem.n_frames)
    try:
        _run_each(run, skip, progress, reports)
    finally:
        if run.beside is not None:  # a stage failed, or never took it
            run.beside.cancel()
            run.beside = None
    _reissue(run)  # the main solve's warnings when the prior stage was switched off
    return reports


def _run_each(run: Run, skip, progress, reports: list) -> None:
    for name, stage in STAGES.items():
        cost = float(run.res.cost) if run.res is not None else float("nan")
        if name in skip:
            reports.append(StageReport(name, 0.0, cost, cost, "skipped: switched off"))
            continue
        if progress is not None:
            progress(name)
        t0 = time.perf_counter()
        changed = stage(run)
        after = float(run.res.cost) if run.res is not None else float("nan")
        if name == "solve":
            cost = float(run.res.initial_cost)
        reports.append(StageReport(name, time.perf_counter() - t0, cost, after,
                                   changed if changed is not None else "skipped: nothing to do"))
