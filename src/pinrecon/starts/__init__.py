"""Starts: initial trajectories behind one signature, ``start(problem) -> Q0`` with
``Q0`` of shape ``(problem.n_frames, figure.nq)``.

==============  ============================================================
name            start
==============  ============================================================
``"auto"``      ``"hypotheses"`` for one camera's tracks without keyframes or with
                sparse ones (:func:`sparse_keyframes`), ``"lifted"`` instead when the
                tracks carry a lifter's 3D; else ``"keyframes"`` when there are
                keyframes, else ``"rest"``
``"rest"``      rest pose placed on the tracks, root fitted (:mod:`.rest`)
``"keyframes"`` poses at the keyframes, interpolated, placed on the tracks
``"planarity"`` Hoffman-Flinchbaugh planarity seed (:mod:`.planarity`)
``"hypotheses"`` limb and trunk reflections enumerated, scored, a path chosen (:mod:`.hypotheses`)
``"lifted"``    the rest start turned to a lifter's facing, placed on the tracks (:mod:`.lifted`)
``"markers"``   poses from 3D markers (:func:`pinrecon.reconstruct_markers`)
==============  ============================================================

:func:`register_start` adds a start by name; the pipeline never changes for it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import InputError
from ..problem import ReconstructionProblem
from .keyframes import keyframe_start, marker_start
from .hypotheses import hypotheses_start
from .lifted import has_lifted, lifted_start
from .planarity import planarity_start
from .rest import rest_start

__all__ = ["available_starts", "register_start", "get_start", "initial_trajectory", "auto_start", "searches",
           "sparse_keyframes"]

Start = Callable[[ReconstructionProblem], np.ndarray]


def sparse_keyframes(problem: ReconstructionProblem, max_gap_s: float = 1.0) -> bool:
    """Whether the keyframes leave a stretch longer than ``max_gap_s`` seconds without a
    keyframe (counting from the first and to the last frame); True without keyframes."""
    frames = sorted({int(k.frame) * problem.factor for k in (problem.keyframes or ())})
    if not frames:
        return True
    gaps = np.diff([0] + frames + [problem.n_frames - 1])
    return bool(gaps.max() > max_gap_s * float(problem.fps or 1.0))


def auto_start(problem: ReconstructionProblem, lifted: bool = True, guard_base: bool = True) -> np.ndarray:
    """The multi-hypothesis start for one camera's 2D tracks without keyframes or with
    sparse ones (a stretch of more than a second without any, :func:`sparse_keyframes`);
    the keyframe start with denser keyframes; the rest-pose start otherwise. With ``lifted``
    (default) and lifted-pose rows in the problem, the lifted start (:mod:`.lifted`) instead
    of the multi-hypothesis one. ``guard_base``: as :func:`~.hypotheses.search_hypotheses`.

    Measured in ``bench/bench_real.py`` (the calibrated human on detector-like tracks,
    mean of two views): without keyframes the multi-hypothesis start took the walk from
    204 to 65 mm PA-MPJPE and 40 to 7 % flipped limbs, the run from 216 to 166 mm and 48
    to 23 % (the dance: no change). With keyframes on the first and last frame only it
    first did worse than the keyframe start (walk 76 against 50 mm); with the human's
    correlated pose prior it is as good on the walk (23.4 / 6.0 % against 23.1 / 5.9 %) and
    the run (31.0 / 4.1 % against 31.0 / 4.2 %) and better on the dance (116 against 147
    mm), and on the lab case it picks the planarity seed (walk 23.3 -> 1.1 % flips)."""
    if _one_view_sparse(problem):
        if lifted and has_lifted(problem):
            return lifted_start(problem)
        return hypotheses_start(problem, guard_base=guard_base)
    if problem.keyframes is not None and len(problem.keyframes):
        return keyframe_start(problem)
    return rest_start(problem)


def _one_view_sparse(problem: ReconstructionProblem) -> bool:
    one_camera = len(getattr(problem, "views", None) or [None]) == 1  # several cameras see depth
    return problem.measurement is not None and problem.tracks is not None and one_camera and sparse_keyframes(problem)


def searches(problem: ReconstructionProblem, lifted: bool = True) -> bool:
    """Whether :func:`auto_start` (with ``lifted``) starts ``problem`` with the
    multi-hypothesis search (:func:`~.hypotheses.hypotheses_start`)."""
    return _one_view_sparse(problem) and not (lifted and has_lifted(problem))


_STARTS: dict[str, Start] = {
    "auto": auto_start,
    "rest": rest_start,
    "keyframes": keyframe_start,
    "planarity": planarity_start,
    "hypotheses": hypotheses_start,
    "lifted": lifted_start,
    "markers": marker_start,
}


def available_starts() -> list[str]:
    """The names of the registered starts."""
    return sorted(_STARTS)


def register_start(name: str, start: Start) -> None:
    """Make ``start(problem) -> Q0`` available as ``reconstruct(..., seed=name)``."""
    _STARTS[str(name)] = start


def get_start(name: str) -> Start:
    """The start registered as ``name``; an error listing the names otherwise."""
    try:
        return _STARTS[name]
    except (KeyError, TypeError):
        raise InputError(f"unknown seed {name!r}; the starts are {sorted(_STARTS)}", field="seed") from None


def initial_trajectory(problem: ReconstructionProblem, start: str | Start | np.ndarray = "auto") -> np.ndarray:
    """The start trajectory of ``problem``: a registered start's name, a callable with
    the start signature, or a given ``(T, nq)`` array; clamped inside the joint limits."""
    fig = problem.figure
    if isinstance(start, str):
        Q0 = get_start(start)(problem)
    elif callable(start):
        Q0 = start(problem)
    else:
        Q0 = fig.check_q(np.asarray(start, float), field="init")
        if Q0.shape != (problem.n_frames, fig.nq):
            raise InputError(f"expected shape {(problem.n_frames, fig.nq)}, got {Q0.shape}", field="init")
        Q0 = fig.normalize(Q0)
    return fig.clamp(Q0, margin=1e-3)
