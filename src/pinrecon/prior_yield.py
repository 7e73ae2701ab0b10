"""The pose prior yields to strong data: its widths and centre estimated from the clip.

The generic human's pose prior (:class:`~pinrecon.rows.posture.PosePrior`) is fitted to a few
dozen motion-capture clips. Where the data decide a joint (point keyframes, several cameras,
learned 3D cues), a prior whose mean or width is wrong for this subject only biases the result:
on the synthetic walk of ``bench/bench_engine.py`` (one orthographic view, 3D keyframes every
8 frames) the default prior held the neck 15 standard deviations from where the keyframes put
it. Where the data do not decide a joint (a limb's depth in one view), the prior is what decides
it and must keep its width.

:func:`prior_conflict` tells the two apart with a variance-component estimate (Helmert, Förstner):
for each group of the prior's rows (one per joint outside the correlated ones, one per row of
the correlated joints' whitening), ``s2 = |r_g|^2 / red_g``, the group's squared residuals at the
solution over its redundancy ``red_g = n_g - tr(J_g H^-1 J_g^T)`` (``H``: the Gauss-Newton
matrix of all rows; the trace by Hutchinson's estimator, ``probes`` solves with the factor).
A group the data decide has redundancy near its row count, and ``s2`` is how many of the prior's
variances its residuals span; a group only the prior decides has little redundancy and little
residual. Under a prior that fits the clip, ``s2`` is about 1.

:func:`yield_to_data` acts on it: when some group's ``s2`` exceeds :data:`CONFLICT` the prior is
widened by ``sqrt(s2)`` on those groups and re-centred by the share of each joint the data decide
(the clip's mean pose, shrunk toward the prior's by the redundancy), and the clip solved again
from where it was. The stage ``yield`` of :mod:`pinrecon.stages` runs it (with a lifter's 3D, the
stage ``feet`` adapts the prior and its solve is the one solve); the result says which
joints the data disagreed with (``Result.extras["prior_conflict_joints"]``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .anatomy import joint_title
from .banded import ActiveNormalEquations, ArrowheadFactor
from .rows.posture import PosePrior
from .solver import flatten_blocks, globals_of, solve

__all__ = ["CONFLICT", "PriorConflict", "adapt_prior", "decided_by_keyframes", "pose_prior_row", "prior_conflict",
           "with_pose_prior", "yield_to_data"]

#: a row group's variance factor past which the data are said to disagree with the prior: the
#: estimate's own spread over a clip of a few hundred frames is about 0.1
CONFLICT = 4.0


@dataclass
class PriorConflict:
    """Per row group of a :class:`PosePrior`: ``s2`` the variance factor, ``redundancy`` the share
    of the group's rows the data decide (0 to 1), ``names`` the joints' movements in anatomical
    words (a correlated row is named by its joint in the whitening's order)."""

    s2: np.ndarray
    redundancy: np.ndarray
    names: list[str]
    n_diag: int

    @property
    def conflicting(self) -> list[str]:
        return [n for n, s in zip(self.names, self.s2) if s > CONFLICT]

    def to_extras(self) -> dict:
        return {"prior_conflict_s2": np.asarray(self.s2, float),
                "prior_conflict_joints": np.array(self.conflicting, dtype=str)}


def _prior_row(problem) -> tuple[int, PosePrior] | None:
    for i, row in enumerate(problem.rows):
        if isinstance(row, PosePrior):
            return i, row
    return None


def pose_prior_row(problem) -> PosePrior | None:
    """The problem's learned pose prior row (None without one)."""
    found = _prior_row(problem)
    return None if found is None else found[1]


def with_pose_prior(problem, row: PosePrior):
    """A copy of ``problem`` with ``row`` (over the problem's frames) for its pose prior row."""
    i, _ = _prior_row(problem)
    out = problem.with_rows([], after=len(problem.rows))  # a copy with its own list of rows
    out.rows[i] = row if len(row.frames) == problem.n_frames else row.for_frames(problem.n_frames)
    return out


def prior_conflict(problem, x, g=None, *, probes: int = 16, seed: int = 0) -> PriorConflict | None:
    """The variance factors of the problem's pose prior at the solution ``x`` (globals ``g``
    held); None without a learned pose prior."""
    found = _prior_row(problem)
    if found is None:
        return None
    _, row = found
    n_g = 0 if g is None else int(np.size(g))
    blocks = flatten_blocks(problem.evaluate(x, True) if g is None else problem.evaluate(x, True, g))
    normal = ActiveNormalEquations(problem.n_frames, problem.nv, blocks, problem.active)
    _, border = normal.assemble(blocks, n_g)
    diag = normal.diagonal()
    floor = 1e-9 * max(float(diag.max()), 1e-300)
    normal.ab[0] += floor + np.where(diag > 0, 0.0, 1.0)
    B, C = (None, None) if border is None else border[:2]
    if C is not None:  # the globals (a figure's proportions, a camera) are unknowns too
        C = C + np.diag(floor + np.where(np.diag(C) > 0, 0.0, 1.0))
    factor = ArrowheadFactor(normal.ab, B, C)
    zero_g = np.zeros(n_g)
    pb = next(b for b in blocks if b.name == row.name)
    J = pb.J[:, 0]  # (N, m, c): a pose prior row group touches its own frame
    frames, cols = pb.frames[:, 0], np.asarray(pb.cols)
    nd, dc = len(row.diag), len(row.qcorr)
    rng = np.random.default_rng(seed)
    lev = np.zeros(J.shape[1])
    for _ in range(probes):  # Hutchinson: E[z_i (J H^-1 J^T z)_i] = (J H^-1 J^T)_ii
        z = rng.choice([-1.0, 1.0], size=J.shape[:2])
        v = np.zeros((problem.n_frames, problem.nv))
        np.add.at(v, (frames[:, None], cols[None, :]), np.einsum("nmc,nm->nc", J, z))
        u, _ = factor.solve(v[:, normal.act].reshape(-1), zero_g)
        U = normal.expand(u)[frames][:, cols]
        lev += (z * np.einsum("nmc,nc->nm", J, U)).sum(axis=0)
    n = len(frames)
    red = np.clip(n - lev[:nd + dc] / probes, 1.0, n)
    rd, rc = row.raw_rows(x)  # before reweighting: the loss is robust, the estimate is not
    s2 = np.concatenate([(rd**2).sum(axis=0), (rc**2).sum(axis=0)]) / red
    m = problem.figure.model
    qname = {m.idx_qs[j]: joint_title(problem.figure, m.names[j]) for j in range(1, m.njoints) if m.nqs[j] == 1}
    names = [qname.get(int(row.qidx[k]), str(k)) for k in row.diag] + [qname.get(int(q), str(q)) for q in row.qcorr]
    return PriorConflict(s2, red / n, names, nd)


def adapt_prior(problem, x, g=None, *, probes: int = 16, keyframes: bool = False):
    """``(problem, conflict)``: the problem with its pose prior widened and re-centred where the
    data at ``x`` (globals ``g``) disagree with it (:func:`prior_conflict`), or unchanged;
    ``conflict`` is None without a prior. ``keyframes``: ``x`` is the 3D keyframes' own poses,
    which then decide the poses the prior does not know (the adapted row says so:
    ``decided_by_keyframes``)."""
    row = pose_prior_row(problem)
    conflict = None if row is None else prior_conflict(problem, x, g, probes=probes)
    if conflict is None or not conflict.conflicting:
        return problem, conflict
    nd = conflict.n_diag
    widen = np.sqrt(np.maximum(conflict.s2, 1.0))
    x = np.asarray(x, float)
    share = conflict.redundancy
    hit = conflict.s2 > CONFLICT
    move = np.where(hit[:nd], share[:nd], 0.0)
    centre_diag = row.q_ref[row.diag] + move * (x[:, row.qidx[row.diag]].mean(axis=0) - row.q_ref[row.diag])
    offset = x[:, row.qcorr].mean(axis=0) - row.means.mean(axis=0)
    centre_corr = float(np.mean(share[nd:])) * offset if hit[nd:].any() else None
    new = row.adapted(widen[:nd], widen[nd:], centre_diag, centre_corr)
    new.decided_by_keyframes = keyframes or row.decided_by_keyframes
    return with_pose_prior(problem, new), conflict


def decided_by_keyframes(problem) -> bool:
    """Whether the problem's pose prior was adapted to 3D keyframes' poses (:func:`adapt_prior`)."""
    row = pose_prior_row(problem)
    return row is not None and row.decided_by_keyframes


def yield_to_data(problem, res, options=None, callback=None, *, probes: int = 16, rounds: int = 3):
    """``(problem, res, conflict)``: while the data disagree with the pose prior (at most
    ``rounds`` times), the prior adapted (:func:`adapt_prior`) and the clip solved again from
    where it was; else the inputs unchanged. ``conflict`` is the first round's (None without a
    prior)."""
    first = None
    for _ in range(rounds):
        adapted, conflict = adapt_prior(problem, res.x, globals_of(res), probes=probes)
        first = first or conflict
        if adapted is problem:
            break
        problem = adapted
        res = solve(problem, res.x, options, callback, active=problem.active, g0=globals_of(res))
    return problem, res, first
