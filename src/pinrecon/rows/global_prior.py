"""A Gaussian prior on global unknowns (segment log-scale factors, camera log focal).

``r = (g[cols] - mean) / sigma``: one row group that touches no frame, with the diagonal
Jacobian ``1 / sigma`` on the globals ``cols``. On a log factor, ``sigma = 0.1`` says the
factor is within about 10 % of ``exp(mean)`` (log-normal). It fixes the gauge of
unknowns the data cannot see (a segment no tracked keypoint depends on).
"""

from __future__ import annotations

import numpy as np

from .base import RowBlock, RowKind, State

__all__ = ["GlobalPrior"]


class GlobalPrior(RowKind):
    """Prior rows on ``g[cols]``.

    Parameters
    ----------
    cols : (n,) indices into the global vector.
    mean : (n,) or scalar prior mean (the start, usually).
    sigma : (n,) or scalar standard deviation (default 0.1: 10 % on a log factor).
    name : cost-report label.
    """

    def __init__(self, cols, mean=0.0, sigma=0.1, name="prior_globals"):
        self.name = name
        self.cols = np.atleast_1d(np.asarray(cols, dtype=int))
        n = len(self.cols)
        self.mean = np.broadcast_to(np.asarray(mean, float), (n,)).copy()
        sigma = np.broadcast_to(np.asarray(sigma, float), (n,))
        if not np.all(np.isfinite(sigma) & (sigma > 0)):
            raise ValueError(f"GlobalPrior: sigma must be positive, got {sigma}")
        self.inv_sigma = 1.0 / sigma
        self.kinematic_frames = np.zeros(0, dtype=int)

    def crop(self, lo: int, hi: int) -> GlobalPrior:
        return self  # on the globals alone, no frame

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        if state.g is None:
            raise ValueError("GlobalPrior needs the global vector g in the state")
        n = len(self.cols)
        r = ((state.g[self.cols] - self.mean) * self.inv_sigma)[None, :]
        J = Jg = None
        if jacobian:
            J = np.zeros((1, 0, n, 0))
            Jg = np.diag(self.inv_sigma)[None]
        return RowBlock(np.zeros((1, 0), dtype=int), r, J, np.zeros(0, dtype=int), self.name, Jg=Jg, gcols=self.cols)
