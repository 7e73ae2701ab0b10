"""The planarity start: hinge planes and limb depth signs from the 2D tracks
(Hoffman & Flinchbaugh), fitted into a trajectory; see :mod:`pinrecon.planarity.seed`."""

from __future__ import annotations

import numpy as np

from ..problem import ReconstructionProblem

__all__ = ["planarity_start"]


def planarity_start(problem: ReconstructionProblem) -> np.ndarray:
    """The planarity seed of ``problem``'s tracks, camera and keyframes."""
    # imported here: the planarity package is heavy and only this start needs it
    from ..planarity.seed import planarity_seed

    return planarity_seed(problem.figure, problem.tracks, problem.camera, problem.keyframes,
                          factor=problem.factor, weights=problem.weights)
