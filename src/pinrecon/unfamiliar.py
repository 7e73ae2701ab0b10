"""Poses the pose prior does not know: where a result's limb depths are an extrapolation.

Without 3D keyframes, a limb's two depth reflections are told apart by the figure's joint
limits, the smoothing prior and, for the generic human, its pose prior learned from motion
capture (``Weights.pose_prior``; clips of walking, running, jumping and basketball:
``models/priors/README.md``). Where the subject's pose is unlike every pose of those clips
the prior still ranks the reflections, but its ranking is an extrapolation: on the bundled
dance (a double pirouette, bench_real), solved from the truth, the prior preferred the
mirrored limbs by 1535 nats, and the hypothesis search's own cost gaps, which take the
prior at its word, called 1 % of the flipped limb frames uncertain.

This check says so instead of staying silent. A frame is *unfamiliar* when the
Mahalanobis distance of its correlated joints from the prior's mean
(:meth:`~pinrecon.rows.posture.PosePrior.distances`, in standard deviations) exceeds the
distance below which 99 % of the prior's own clips' frames lie (stored with the prior by
``tools/fit_pose_prior.py``: 9.0). Measured on ``bench/bench_real.py``'s detector cases
(README there): 79-90 % of the dance's frames, none of the walk's or the run's; every frame
of Pose2Sim's real balancing trial.

:func:`unfamiliar_poses` is run by the pipeline on the solved trajectory; ``Result.extras``
carries ``prior_distance`` (per frame), ``prior_distance_limit`` and
``prior_unfamiliar_spans`` ((n, 2) [start, stop) reconstruction frames), and the summary
names the spans.

When more than half of a clip's frames are unfamiliar and the prior was the default's (more
than a fifth when one camera and no keyframe decide the depths, :func:`switch_share`), the
clip is solved again with a broader one (:func:`broader_prior`: the generic human's single
Gaussian -> its mixture of 8 Gaussians over 57 clips, ``models/priors/README.md``), and the
result says so (``prior_model``, ``prior_default_unfamiliar``). On bench_real's dance the
mixture takes first-and-last-keyframe PA-MPJPE from 113 to about 55 mm; on Pose2Sim's real
balancing trial from 141 to 90 mm (bench/README.md). The result's poses are still measured
against the default's clips (``unfamiliar_poses(model=)``, ``prior_distance_model``): the
broader prior is a fallback, and on the dance its flipped limbs were as frequent in the frames
it knew as in the rest.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from .rows.posture import PosePrior, posture_row

__all__ = ["BROADER_PRIOR", "EARLY_SWITCH", "JUDGED_FROM_ITERATION", "SWITCH_SHARE", "SWITCH_SHARE_MONOCULAR",
           "JudgedWhile", "UnfamiliarPoses", "broader_prior", "early_verdict", "judged_at_base", "judged_share", "switch_extras",
           "switch_share", "unfamiliar_poses", "unfamiliar_share"]

#: the broader prior a clip is solved again with when its default prior does not know most of
#: its poses: the generic human's single Gaussian (walking, running, jumping, basketball; sharp
#: on gait) -> its mixture of 8 Gaussians over 57 clips (``models/priors/README.md``)
BROADER_PRIOR = {"human_pose": "human_pose_mixture"}
#: the share of a clip's frames beyond the default prior's limit past which it is solved again
#: with the broader prior (the share that also doubts an auto camera's focal length)
SWITCH_SHARE = 0.5
#: the same share for one camera without keyframes, where nothing but the pose prior ranks a
#: limb's two depth reflections. Measured on dances the mixture was not fitted to (bench/README.md,
#: "A lower switch without keyframes"): CMU 05_02 (30-35 % unfamiliar) and salsa 60_01, 60_05 and
#: 61_01 (22-38 % at the main solve) flip fewer limb segments with the mixture in every case
#: without keyframes; with first and last keyframes it is further in five of six, so the half stays. The walk and the run (0 %)
#: are untouched; the prior's own clips lie beyond its 99th percentile in 1 % of their frames.
SWITCH_SHARE_MONOCULAR = 0.2
#: the prior's switch judged at the multi-hypothesis search's base (the problem solved briefly
#: from the rest pose, the search's first step; :func:`early_verdict`): where more than this many
#: times the switch's share of its poses are unfamiliar, the clip is solved with the broader prior
#: at once (no first solve to judge); where less than ``EARLY_SWITCH[0]`` times, no switched solve
#: is made beside the first in case it switches; between, both as before. Measured at the base and
#: after the first solve (the switch's share 0.2; bench/README.md, bench_stages): Pose2Sim's four
#: cameras 0.88-1.00 and 0.85-1.00, the spin 05_11 0.74 and 0.80, the dance 05_02 0.33 and 0.33,
#: the walk and the run 0.00-0.09 and 0.00
EARLY_SWITCH = (0.5, 2.0)
#: the same verdict judged while the first solve runs (:func:`judged_share`, from this iteration on,
#: after each accepted step): "switch" stops that solve (the switched one does not depend on it),
#: "keep" drops the switched solve made beside it. Measured on bench_stages' clips with lifted cues
#: (the first solve's share at iterations 2 / 4 / 6 / 8 / 12 -> converged): Pose2Sim's four cameras
#: with MediaPipe's 3D 0.76 / 0.87 / 1.00 / 1.00 / 1.00 -> 1.00, 0.52 / 0.92 / 0.93 / 0.92 / 0.90 ->
#: 0.88, 0.47 / 0.60 / 0.58 / 0.62 / 0.74 -> 0.76, 0.22 / 0.61 / 0.69 / 0.82 / 0.86 -> 0.89; the spin
#: 0.00 / 0.64 / 0.94 / 0.98 / 0.98 -> 0.99; the dance 05_02 0.00 / 0.23 / 0.35 / 0.37 / 0.37 -> 0.36;
#: the walk and the run 0.00 throughout
JUDGED_FROM_ITERATION = 6


@dataclass
class UnfamiliarPoses:
    """Frames whose pose lies beyond ``limit`` (Mahalanobis distance, standard deviations)
    from the pose prior's mean; ``spans`` [start, stop) reconstruction frames."""

    distance: np.ndarray
    limit: float
    spans: list[tuple[int, int]] = field(default_factory=list)
    #: the prior measured against when it is not the one the problem was solved with (the
    #: default of a clip solved again with a broader one), else None
    model: str | None = None

    @property
    def share(self) -> float:
        """Share of the frames beyond the limit."""
        return float(np.mean(self.distance > self.limit)) if len(self.distance) else 0.0

    def to_extras(self) -> dict:
        return {"prior_distance": np.asarray(self.distance, float), "prior_distance_limit": np.float64(self.limit),
                "prior_unfamiliar_spans": np.array(self.spans, int).reshape(-1, 2),
                **({"prior_distance_model": np.array(self.model)} if self.model else {})}


def unfamiliar_poses(problem, Q, *, quantile: str = "99", merge_s: float = 0.2,
                     model: str | None = None) -> UnfamiliarPoses | None:
    """The frames of trajectory ``Q`` whose pose the problem's pose prior does not know
    (beyond its clips' ``quantile`` percentile of distance); runs closer than ``merge_s``
    seconds are one span. None when the problem has no learned pose prior (figures other
    than the generic human unless asked, ``Weights(pose_prior=None)``).

    With ``model`` (a prior's name), measured against that prior instead: the default of a
    clip solved again with the broader one (:func:`broader_prior`), which is a fallback, not
    a prior that knows the poses. On bench_real's dance (05_11) the mixture called 11 % of
    the solved frames unfamiliar, and its flipped limb segments were as frequent in the frames
    it knew (22.7 % at 60 degrees with first and last keyframes, 10.6 % at 45 without) as
    overall (22.1 %, 10.8 %); the default single Gaussian called every frame unfamiliar."""
    if model is not None:
        prior = posture_row(problem.figure, problem.n_frames, replace(problem.weights, pose_prior_model=model))
        prior = prior if isinstance(prior, PosePrior) else None
    else:
        prior = next((r for r in problem.rows if isinstance(r, PosePrior)), None)
    limit = None if prior is None else prior.quantiles.get(quantile)
    if limit is None:
        return None
    d = prior.distances(Q)
    far = np.flatnonzero(d > limit)
    spans: list[tuple[int, int]] = []
    gap = max(1, round(merge_s * float(problem.fps or 30.0)))
    for f in far.tolist():
        if spans and f - spans[-1][1] < gap:
            spans[-1] = (spans[-1][0], f + 1)
        else:
            spans.append((f, f + 1))
    return UnfamiliarPoses(d, float(limit), spans, model)


def switch_share(keyframes: bool, several_views: bool) -> float:
    """The share of unfamiliar frames past which :func:`broader_prior` switches: :data:`SWITCH_SHARE`
    when 3D keyframes or several cameras also decide the limbs' depths, else
    :data:`SWITCH_SHARE_MONOCULAR`."""
    return SWITCH_SHARE if keyframes or several_views else SWITCH_SHARE_MONOCULAR


def broader_prior(used: str | None, model: str, extras: dict, *, share: float = SWITCH_SHARE
                  ) -> tuple[str, float] | None:
    """``(name, share)``: the broader prior (:data:`BROADER_PRIOR`) to solve a clip again with,
    when its pose prior was chosen by default (``model`` ``"auto"``), ``used`` has a broader
    one, and more than ``share`` (:func:`switch_share`) of the frames of the result
    (``extras``, with :meth:`UnfamiliarPoses.to_extras`) lie beyond its limit; else None. The
    bundled dance (bench_real, 05_11) is 79-90 % unfamiliar under the default and the walk and
    the run 0 %."""
    if model != "auto" or used not in BROADER_PRIOR or "prior_distance" not in extras:
        return None
    found = unfamiliar_share(extras)
    return (BROADER_PRIOR[used], found) if found > share else None


def unfamiliar_share(extras: dict) -> float:
    """The share of a result's frames beyond its pose prior's limit (``extras`` with
    :meth:`UnfamiliarPoses.to_extras`; 0 without the check)."""
    d = np.asarray(extras.get("prior_distance", ()), float)
    return float(np.mean(d > float(extras["prior_distance_limit"]))) if len(d) else 0.0


def judged_share(problem, Q) -> float:
    """The share of trajectory ``Q``'s poses ``problem``'s pose prior does not know (0 without
    a learned prior)."""
    unfamiliar = unfamiliar_poses(problem, problem.figure.normalize(Q))
    return unfamiliar_share({} if unfamiliar is None else unfamiliar.to_extras())


class JudgedWhile:
    """``stop_when`` of a first solve of ``problem`` (:func:`pinrecon.solver.solve`): from
    iteration :data:`JUDGED_FROM_ITERATION` on, after each accepted step, the share of the
    iterate's poses ``problem``'s pose prior does not know, by :func:`early_verdict` at the
    switch's share ``limit``. "switch" stops the solve (:attr:`share` and :attr:`iteration` say
    where; the switched solve does not depend on it); "keep" calls ``on_keep()`` (the switched
    solve made beside is not wanted) and judges no more; otherwise it goes on judging."""

    def __init__(self, problem, limit: float, on_keep: Callable[[], None] | None = None):
        self.problem, self.limit, self.on_keep = problem, float(limit), on_keep
        self.share: float | None = None
        self.iteration: int | None = None
        self.kept = False

    @property
    def stopped(self) -> bool:
        """Whether it stopped the solve (the clip switches: :attr:`share`, :attr:`iteration`)."""
        return self.iteration is not None

    def __call__(self, iteration: int, x: np.ndarray) -> str | None:
        if iteration < JUDGED_FROM_ITERATION or self.kept:
            return None
        share = judged_share(self.problem, x)
        verdict = early_verdict(share, self.limit)
        if verdict == "switch":
            self.share, self.iteration = share, iteration
            return f"stopped: {100 * share:.0f} % of the poses unfamiliar (the prior's switch)"
        if verdict == "keep":
            self.kept = True
            if self.on_keep is not None:
                self.on_keep()
        return None


def judged_at_base(problem) -> tuple[np.ndarray, float]:
    """``(base, share)``: the multi-hypothesis search's base of ``problem``
    (:func:`pinrecon.starts.hypotheses.base_solve`, which its search takes as ``base``) and the
    share of the base's poses ``problem``'s pose prior does not know (:func:`judged_share`)."""
    from .starts.hypotheses import base_solve

    base = base_solve(problem)
    return base, judged_share(problem, base)


def early_verdict(share: float | None, limit: float) -> str | None:
    """What ``share``, the unfamiliar poses at the search's base (:func:`judged_at_base`), decides
    of a switch at ``limit`` (:data:`EARLY_SWITCH`): ``"switch"`` (to the broader prior at once),
    ``"keep"`` (no switched solve made beside the first in case), or None (judged after the first
    solve, as without a share)."""
    if share is None:
        return None
    if share > EARLY_SWITCH[1] * limit:
        return "switch"
    return "keep" if share < EARLY_SWITCH[0] * limit else None


def switch_extras(name: str, share: float) -> dict:
    """What a result solved again with the broader prior ``name`` carries in ``extras``: its
    name (``prior_model``) and the share of frames the default did not know
    (``prior_default_unfamiliar``)."""
    return {"prior_model": np.array(name), "prior_default_unfamiliar": np.float64(share)}
