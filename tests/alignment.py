"""PA-MPJPE written out here, independently of ``pinrecon.metrics``: per frame, the best
similarity (rotation, translation, scale) taking the estimate onto the truth, Umeyama's
closed form (1991), then the mean joint distance. Tests score reconstructions with it."""

from __future__ import annotations

import numpy as np


def pa_mpjpe_mm(P, G) -> float:
    """Mean per-joint error of ``P`` against ``G`` (T, K, 3) after the best similarity per
    frame, millimetres."""
    err = []
    for p, g in zip(P, G):
        X, Y = p - p.mean(0), g - g.mean(0)
        U, S, Vt = np.linalg.svd(Y.T @ X)
        D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
        R = U @ D @ Vt
        s = np.trace(np.diag(S) @ D) / (X * X).sum()
        err.append(np.linalg.norm(s * X @ R.T - Y, axis=-1).mean())
    return 1000 * float(np.mean(err))
