"""Planar spans: the frame ranges over which a group that fails as a whole is planar.

A limb is only approximately a rigid rod in one plane (a walking leg turns its
plane at every step; a detector loses a point); when the whole sequence is
rejected, :func:`planar_spans` slides a window of ``W`` frames (stride ``W / 2``)
along it, fits each window with :func:`~.fit_core.core_fit`, merges overlapping
accepted windows while the merged range still fits, and keeps the merged ranges
whose fit is planar with a determined plane.  Each span gets its own
:class:`~.fit_types.GroupFit` (``GroupFit.spans`` / ``GroupFit.span_fits``).
"""

from __future__ import annotations

import numpy as np

from .fit_core import core_fit, make_fit

__all__ = ["planar_spans"]


def planar_spans(U, valid, sigma, window, rng, n_hyp, kw, hinge, points):
    """Frame ranges ``[start, stop)`` where the group is planar, and their fits.

    ``U`` (T, R, 2): hinge-relative image vectors; ``valid`` (T,): frames with
    every point present; ``sigma``: per-coordinate image noise; ``window``:
    window length (None: ``max(8, T // 10)``); ``rng`` / ``n_hyp``: hypothesis
    sampling (at most 64 hypotheses per window); ``kw``: the remaining
    :func:`~.fit_core.core_fit` options; ``hinge`` / ``points`` label the fits.
    Returns ``(spans, span_fits)``, two tuples, empty when no window passes.
    """
    T, R, _ = U.shape
    n_min = (3 if R == 1 else 2) + 2
    W = int(window) if window is not None else max(8, T // 10)
    W = max(W, n_min)
    if W > T:
        return (), ()
    stride = max(1, W // 2)
    starts = list(range(0, T - W + 1, stride))
    if starts[-1] != T - W:
        starts.append(T - W)

    def fit(a, b):
        fr = np.flatnonzero(valid[a:b]) + a
        if fr.size < n_min:
            return None
        c = core_fit(U, fr, sigma, n_hyp=min(n_hyp, 64), rng=rng, **kw)
        # windows too short to determine the plane still count if their residual passes
        return c if c["status"] in ("planar", "insufficient_motion") else None

    spans = []
    cur = None  # (start, stop, core)
    for a in starts:
        c = fit(a, a + W)
        if c is None:
            continue
        if cur is not None and a <= cur[1]:
            merged = fit(cur[0], a + W)
            if merged is not None:
                cur = (cur[0], a + W, merged)
                continue
            spans.append(cur)
        elif cur is not None:
            spans.append(cur)
        cur = (a, a + W, c)
    if cur is not None:
        spans.append(cur)
    spans = [sp for sp in spans if sp[2]["status"] == "planar"]
    out_spans = tuple((int(s[2]["frames"][0]), int(s[2]["frames"][-1]) + 1) for s in spans)
    out_fits = tuple(make_fit(s[2], T, hinge, points, sigma) for s in spans)
    return out_spans, out_fits
