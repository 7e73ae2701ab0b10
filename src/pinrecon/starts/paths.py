"""Min-sum paths over a chain of discrete states: the dynamic programming of the
multi-hypothesis start (:mod:`.hypotheses`).

A path ``h_0 .. h_{N-1}`` costs ``sum_t unary[t, h_t] + sum_t trans[t, h_t, h_{t+1}]`` and,
with a second-order term, ``+ sum_t acc[t, h_t, h_{t+1}, h_{t+2}]`` (a cost on three
consecutive states: the limb search scores a reflection's depth *acceleration* with it,
so a limb that bounces off the image plane instead of crossing it pays what the
smoothing prior would charge). The second-order chain is solved as a first-order chain
over pairs of consecutive states (``H^2`` of them).
"""

from __future__ import annotations

import numpy as np

__all__ = ["min_sum_path", "span_gaps"]


def _pairs(unary, trans, acc):
    """The first-order chain over pair states ``(h_{t-1}, h_t)`` (index ``a H + b``) of
    a second-order chain; at t = 0 only ``(h, h)`` exists."""
    N, H = unary.shape
    U2 = np.full((N, H * H), np.inf)
    U2[0, np.arange(H) * (H + 1)] = unary[0]
    U2[1:] = np.tile(unary[1:], (1, H))
    T2 = np.full((N - 1, H * H, H * H), np.inf)
    a, b, c = np.meshgrid(np.arange(H), np.arange(H), np.arange(H), indexing="ij")
    accp = np.concatenate([np.zeros((1, H, H, H)), acc], axis=0)  # centred at t: none at t = 0
    T2[:, a * H + b, b * H + c] = trans[:, b, c] + accp[:, a, b, c]
    return U2, T2


def _forward(unary, trans):
    N, H = unary.shape
    F = np.empty((N, H))
    arg = np.zeros((N, H), int)
    F[0] = unary[0]
    for t in range(1, N):
        c = F[t - 1][:, None] + trans[t - 1]
        arg[t] = np.argmin(c, axis=0)
        F[t] = c.min(axis=0) + unary[t]
    return F, arg


def _backward(unary, trans):
    N, H = unary.shape
    B = np.zeros((N, H))
    for t in range(N - 2, -1, -1):
        B[t] = (trans[t] + (unary[t + 1] + B[t + 1])[None, :]).min(axis=1)
    return B


def min_sum_path(unary, trans, acc=None):
    """Min-sum over paths h_0..h_{N-1} of sum_t unary[t, h_t] + sum_t trans[t, h_t,
    h_{t+1}] (``unary`` (N, H), ``trans`` (N-1, H, H)) and, when given, sum_t acc[t, h_t,
    h_{t+1}, h_{t+2}] (``acc`` (N-2, H, H, H)). Returns (best path (N,), min-marginals
    (N, H): the cost of the best path through each state)."""
    unary = np.asarray(unary, float)
    N, H = unary.shape
    if acc is not None and N >= 3:
        U2, T2 = _pairs(unary, trans, acc)
        path2, marg2 = min_sum_path(U2, T2)
        return path2 % H, marg2.reshape(N, H, H).min(axis=1)
    F, arg = _forward(unary, trans)
    B = _backward(unary, trans)
    path = np.empty(N, int)
    path[-1] = int(np.argmin(F[-1]))
    for t in range(N - 1, 0, -1):
        path[t - 1] = arg[t][path[t]]
    return path, F + B


def _runs(path):
    out, a = [], 0
    for t in range(1, len(path) + 1):
        if t < len(path) and path[t] == path[a]:
            continue
        out.append((a, t, int(path[a])))
        a = t
    return out


def span_gaps(unary, trans, path, acc=None):
    """Per run of one state on ``path`` (a *span*, DP frames [a, b)): the extra cost of the
    best path that puts the whole span in another single state, the rest free.
    Returns ``[(a, b, state, gap)]``."""
    unary = np.asarray(unary, float)
    N, H = unary.shape
    if acc is not None and N >= 3:
        U2, T2 = _pairs(unary, trans, acc)
        best = float(_forward(U2, T2)[0][-1].min())
        first, second = np.divmod(np.arange(H * H), H)
        out = []
        for a, b, h in _runs(path):
            alt = np.full(H, np.inf)
            for g in range(H):
                if g == h:
                    continue
                Ug = U2.copy()
                Ug[a:b, second != g] = np.inf  # the span in state g ...
                Ug[a + 1 : b, first != g] = np.inf  # ... throughout
                alt[g] = _forward(Ug, T2)[0][-1].min()
            out.append((a, b, h, float(alt.min() - best) if H > 1 else float("inf")))
        return out
    F, _ = _forward(unary, trans)
    B = _backward(unary, trans)
    best = float(F[-1].min())
    cum = np.vstack([np.zeros(H), np.cumsum(unary, axis=0)])
    out = []
    for a, b, h in _runs(path):
        inner = cum[b] - cum[a]  # (H,) the span held in each state
        into = (F[a - 1][:, None] + trans[a - 1]).min(axis=0) if a > 0 else np.zeros(H)
        out_of = (trans[b - 1] + (unary[b] + B[b])[None, :]).min(axis=1) if b < N else np.zeros(H)
        alt = into + inner + out_of
        alt[h] = np.inf
        out.append((a, b, h, float(alt.min() - best) if H > 1 else float("inf")))
    return out
