"""Starts: initial trajectories behind one signature, ``start(problem) -> Q0`` with
``Q0`` of shape ``(problem.n_frames, figure.nq)``.

==============  ============================================================
name            start
==============  ============================================================
``"auto"``      ``"keyframes"`` when the problem has keyframes, else ``"rest"``
``"rest"``      rest pose placed on the tracks, root fitted (:mod:`.rest`)
``"keyframes"`` poses at the keyframes, interpolated, placed on the tracks
``"planarity"`` Hoffman-Flinchbaugh planarity seed (:mod:`.planarity`)
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
from .planarity import planarity_start
from .rest import rest_start

__all__ = ["available_starts", "register_start", "get_start", "initial_trajectory", "auto_start"]

Start = Callable[[ReconstructionProblem], np.ndarray]


def auto_start(problem: ReconstructionProblem) -> np.ndarray:
    """The keyframe start when there are keyframes, else the rest-pose start."""
    if problem.keyframes is not None and len(problem.keyframes):
        return keyframe_start(problem)
    return rest_start(problem)


_STARTS: dict[str, Start] = {
    "auto": auto_start,
    "rest": rest_start,
    "keyframes": keyframe_start,
    "planarity": planarity_start,
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
