"""Accuracy of a reconstruction against ground truth, as the field reports it.

All functions take keypoint positions ``P_est`` and ``P_true`` of shape (T, K, 3) in
metres (the same K points, in the same order; NaN-free) and return millimetres or
shares. They compare points, not joint angles, so the estimate may come from another
figure than the truth (``Figure.human()`` against a CMU skeleton).

* :func:`mpjpe` - mean per-joint position error.
* :func:`pa_mpjpe` - the same after a similarity alignment (rotation, translation,
  scale) of every frame (Procrustes; the field's "PA-MPJPE").
* :func:`depth_offset` / :func:`mpjpe_depth_aligned` - the one constant offset along
  the camera's line of sight that a monocular view hardly sees, and the error without it.
* :func:`root_error` - mean distance of the root (mean of the hips) from the truth,
  after removing that depth offset.
* :func:`flip_rate` - share of limb segments whose depth order along the line of sight
  is wrong (the reflective ambiguity), as :func:`pinrecon.planarity.limb_flip_rate`
  defines it, on points.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["depth_offset", "flip_rate", "flipped_segments", "mpjpe", "mpjpe_depth_aligned", "pa_mpjpe", "procrustes", "root_error"]


def _pair(P_est, P_true):
    P, G = np.asarray(P_est, float), np.asarray(P_true, float)
    if P.shape != G.shape or P.ndim != 3 or P.shape[-1] != 3:
        raise ValueError(f"expected two (T, K, 3) arrays of the same shape, got {P.shape} and {G.shape}")
    return P, G


def mpjpe(P_est, P_true) -> float:
    """Mean per-joint position error, millimetres."""
    P, G = _pair(P_est, P_true)
    return 1000.0 * float(np.linalg.norm(P - G, axis=-1).mean())


def procrustes(P_est, P_true) -> np.ndarray:
    """``P_est`` aligned to ``P_true`` frame by frame by the similarity (proper rotation,
    translation, uniform scale) minimising the squared distance (Umeyama 1991)."""
    P, G = _pair(P_est, P_true)
    mp, mg = P.mean(axis=1, keepdims=True), G.mean(axis=1, keepdims=True)
    X, Y = P - mp, G - mg
    H = np.einsum("tki,tkj->tij", X, Y)  # (T, 3, 3)
    U, S, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.einsum("tij,tjk->tik", U, Vt)))
    D = np.ones((len(P), 3))
    D[:, 2] = d
    R = np.einsum("tji,tj,tkj->tik", Vt, D, U)  # V diag(D) U^T: maps X onto Y
    var = np.einsum("tki,tki->t", X, X)
    s = np.einsum("ti,ti->t", S, D) / np.maximum(var, 1e-300)
    return s[:, None, None] * np.einsum("tij,tkj->tki", R, X) + mg


def pa_mpjpe(P_est, P_true) -> float:
    """MPJPE after a per-frame similarity alignment (Procrustes), millimetres."""
    return mpjpe(procrustes(P_est, P_true), P_true)


def _forward(camera) -> np.ndarray:
    return np.asarray(camera.R, float)[2]


def depth_offset(P_est, P_true, camera) -> float:
    """The constant shift along the camera's line of sight (metres, + away from the
    camera) that best moves ``P_est`` onto ``P_true``."""
    P, G = _pair(P_est, P_true)
    return float(((G - P) @ _forward(camera)).mean())


def mpjpe_depth_aligned(P_est, P_true, camera) -> float:
    """MPJPE after removing the one depth offset (:func:`depth_offset`), millimetres."""
    P, G = _pair(P_est, P_true)
    return mpjpe(P + depth_offset(P, G, camera) * _forward(camera), G)


def root_error(P_est, P_true, camera, root: Sequence[int]) -> float:
    """Mean distance (mm) between the estimated and true root trajectories, the root
    being the mean of the points ``root`` (e.g. both hips), after removing the one depth
    offset."""
    P, G = _pair(P_est, P_true)
    P = P + depth_offset(P, G, camera) * _forward(camera)
    idx = list(root)
    return 1000.0 * float(np.linalg.norm(P[:, idx].mean(1) - G[:, idx].mean(1), axis=-1).mean())


def flipped_segments(P_est, P_true, camera, segments: Sequence[tuple[int, int]], *, min_fraction: float = 0.1):
    """(flipped, counted), (T, S) bool: per frame and limb segment (parent, child point
    indices), whether it counts (its true depth difference along the line of sight exceeds
    ``min_fraction`` of its true length) and, counted, whether the estimate's depth sign
    (child minus parent) differs from the truth's."""
    P, G = _pair(P_est, P_true)
    a = np.array([s[0] for s in segments], int)
    b = np.array([s[1] for s in segments], int)
    dz_e = camera.depth(P[:, b]) - camera.depth(P[:, a])
    dz_t = camera.depth(G[:, b]) - camera.depth(G[:, a])
    L = np.linalg.norm(G[:, b] - G[:, a], axis=-1)
    count = np.abs(dz_t) > min_fraction * L
    return count & (np.sign(dz_e) != np.sign(dz_t)), count


def flip_rate(P_est, P_true, camera, segments: Sequence[tuple[int, int]], *, min_fraction: float = 0.1,
              per_segment: bool = False):
    """Share of limb segments (parent, child point indices) whose depth sign along the
    line of sight (child minus parent) differs from the truth's, over the frames where
    the true depth difference exceeds ``min_fraction`` of the segment's true length
    (:func:`flipped_segments`). NaN if nothing counts; with ``per_segment`` also
    ``[(flipped, counted)]``."""
    flip, count = flipped_segments(P_est, P_true, camera, segments, min_fraction=min_fraction)
    n = int(count.sum())
    rate = float(flip.sum() / n) if n else float("nan")
    if per_segment:
        return rate, [(int(flip[:, k].sum()), int(count[:, k].sum())) for k in range(flip.shape[1])]
    return rate
