"""A posture prior: every 1-dof joint pulled towards a reference pose.

``r = (q_joint - q_ref) / sigma`` per frame, a diagonal block; ``sigma`` one number or one
per configuration entry (``(nq,)``, read at the joints' q indices). The generic human gets
its pose prior learned from motion capture instead (:class:`PosePrior`, :func:`posture_row`):
the joints that move in the clips are held by their joint Gaussian (mean and covariance),
the others by their mean and standard deviation; so does a BVH figure of the CMU skeleton
layout when asked for (``Weights(pose_prior_model="cmu_bvh_pose")``: off by default,
``models/priors/README.md`` says why); other figures get the rest pose and one weak
``sigma``. With a large ``sigma``
(default 1 rad) it barely moves well-observed joints (the bias on a joint is about
``(q - q_ref) / (sigma^2 H_data)``), but it gives the directions the data cannot see
(the twist of a limb whose keypoints are collinear, redundant rotations of zero-length
BVH joints) a definite value, which keeps the normal equations well conditioned. This
plays the role of DiFranco et al.'s stabilising term ``kI``, in joint space.
"""

from __future__ import annotations

import copy
import functools
from pathlib import Path

import numpy as np

from .._resources import model_path
from ..errors import InputError
from ..io.jsonfile import read_json
from .base import RowBlock, RowKind, State, crop_every_frame

__all__ = ["PosePrior", "Posture", "pose_prior", "pose_prior_covariance", "pose_prior_distances", "pose_prior_names",
           "posture_row", "prior_for", "rest_directions", "rest_pose", "unused_priors"]

#: the largest angle (degrees) between a BVH figure's rest bone direction and the prior's
#: clips' mean one: the CMU subjects' own skeletons differ by up to 9 degrees among themselves
REST_DIRECTION_TOLERANCE_DEG = 25.0


class Posture(RowKind):
    name = "posture"

    def __init__(self, figure, n_frames, q_ref, sigma=1.0, active=None):
        m = figure.model
        cols, qidx = [], []
        for jid in range(1, m.njoints):
            if m.nqs[jid] == 1 and m.nvs[jid] == 1:
                iv = m.idx_vs[jid]
                if active is None or active[iv]:
                    cols.append(iv)
                    qidx.append(m.idx_qs[jid])
        self.cols = np.array(cols, dtype=int)
        self.qidx = np.array(qidx, dtype=int)
        self.q_ref = np.asarray(q_ref, float)[self.qidx]
        sig = np.asarray(sigma, float)
        self.inv_sigma = 1.0 / (sig[self.qidx] if sig.ndim else np.full(len(self.qidx), float(sig)))
        self.frames = np.arange(n_frames)

    def crop(self, lo: int, hi: int) -> Posture:
        return crop_every_frame(self, lo, hi)

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        r = (state.Q[:, self.qidx] - self.q_ref) * self.inv_sigma
        J = None
        if jacobian:
            J = np.broadcast_to(self.inv_sigma, (len(self.frames), 1, len(self.cols)))
        return RowBlock(self.frames[:, None], r, J, self.cols, self.name, diagonal=True)


class PosePrior(Posture):
    """The generic human's pose prior: :class:`Posture` (each joint to its mean, ``sigma``
    its standard deviation times ``scale``), except the joints ``qcorr`` (q indices), whose
    rows are ``z = A (q[qcorr] - mean)`` with ``A^T A = cov^-1 / scale^2``: ``|z|`` is their
    Mahalanobis distance ``m`` from the mean in units of ``scale``. A frame pays ``rho(m)``:

    * ``loss="cauchy"``: ``0.5 k^2 log(1 + m^2 / k^2)``, quadratic near the mean and only
      logarithmic far from it: the prior tells a pose like its clips' from one unlike them,
      but barely ranks two poses unlike them (a dancer's arms raised in front or behind);
    * ``loss="huber"``: ``0.5 m^2`` up to ``m = k``, ``k m - 0.5 k^2`` beyond: a bounded
      pull, but one that still prefers the unlike pose nearer the clips';
    * ``k=None``: always quadratic.

    A mixture of Gaussians (``mixture``: weights, means and covariances of the ``qcorr``
    joints, ``tools/fit_pose_prior.py --components``) holds each frame by its least-cost
    component, ``rho(m_k) + c_k`` with ``c_k = (-log w_k + 0.5 log det cov_k) / scale^2`` (less
    the least of them): the max-mixture of SMPLify (Bogo et al. 2016), which keeps a
    Gauss-Newton row per frame. ``scale`` tempers the whole density (its negative log divided
    by ``scale^2``, as for one Gaussian), so without a robust loss the component a frame
    takes does not depend on it. Inflating each covariance instead keeps the constants whole
    (up to 35 nats apart in ``human_pose_mixture``) against distances shrunk four-fold: on
    bench_real's dance (45 degrees, no keyframes) the solve from the true poses then ended
    917 nats *above* one with the true trunk and mirrored limbs; tempered, 1331 nats below.
    The component's constant is one more row (its Jacobian zero), so
    that ``0.5 |r|^2`` is the frame's cost; the chosen component may change between iterations.

    Robust losses are reweighted rows (as the measurement's): the rows are scaled by
    ``sqrt(rho'(m) / m)`` and the block reports the true cost. :meth:`adapted` widens and
    re-centres the rows for one clip (:mod:`pinrecon.prior_yield`). The rows of every correlated
    joint are written (a joint that is not ``active`` enters at its current value, i.e. the
    conditional Gaussian of the active ones); the Jacobian covers the active columns.
    """

    LOSSES = ("huber", "cauchy")
    #: adapted to 3D keyframes' poses (:func:`pinrecon.prior_yield.adapt_prior`), which decide the poses
    decided_by_keyframes = False

    def __init__(self, figure, n_frames, q_ref, sigma, qcorr, cov, scale, active=None, k=None, loss="huber",
                 quantiles=None, mixture=None):
        super().__init__(figure, n_frames, q_ref, sigma, active)
        #: percentiles of the prior's own clips' distances (:meth:`distances`), e.g. ``{"99": 9.0}``
        self.quantiles = dict(quantiles or {})
        if loss not in self.LOSSES:
            raise ValueError(f"loss must be one of {self.LOSSES}, got {loss!r}")
        self.k = None if k is None else float(k)
        self.loss = loss
        self.qcorr = np.asarray(qcorr, int)
        self.scale = float(scale)
        if mixture is None:  # one Gaussian: the joints' mean and covariance
            weights, means, covs = [1.0], [np.asarray(q_ref, float)[self.qcorr]], [cov]
        else:
            weights, means, covs = mixture
        #: (K, d) the components' means, (K, d, d) their whitening ``A_k`` (``A_k^T A_k = cov_k^-1 /
        #: scale^2``), (K,) their constants ``(-log w_k + 0.5 log det cov_k) / scale^2``, least 0
        self.means = np.asarray(means, float).reshape(len(weights), len(self.qcorr))
        self.As, logdet = [], []
        for c in covs:
            c = np.asarray(c, float)
            self.As.append(np.linalg.cholesky(np.linalg.inv(c)).T / self.scale)  # cov^-1 = L L^T
            logdet.append(np.linalg.slogdet(c)[1])
        self.As = np.stack(self.As)
        const = -np.log(np.asarray(weights, float)) + 0.5 * np.asarray(logdet)
        self.consts = (const - const.min()) / self.scale**2  # the density tempered by scale^2, as the distances
        pos = {int(q): k for k, q in enumerate(self.qidx)}
        corr = set(self.qcorr.tolist())
        self.diag = np.array([k for k, q in enumerate(self.qidx) if int(q) not in corr], int)
        # columns of the active correlated joints: (k in qcorr, k in cols)
        self._corr_in = np.array([i for i, q in enumerate(self.qcorr) if int(q) in pos], int)
        self._corr_col = np.array([pos[int(self.qcorr[i])] for i in self._corr_in], int)
        #: the clips' own means and whitening, which :meth:`distances` measures against whatever
        #: :meth:`adapted` makes of the rows
        self.clips = (self.means, self.As)
        self._jacobian_blocks()

    def _jacobian_blocks(self):
        """(K, rows, cols) each component's Jacobian of its rows (the constant's row: zero)."""
        nd, dc, mixed = len(self.diag), len(self.qcorr), len(self.means) > 1
        self._Jf = np.zeros((len(self.means), nd + dc + int(mixed), len(self.cols)))
        self._Jf[:, np.arange(nd), self.diag] = self.inv_sigma[self.diag]
        for i, A in enumerate(self.As):
            self._Jf[i][np.ix_(nd + np.arange(dc), self._corr_col)] = A[:, self._corr_in]

    def for_frames(self, n_frames: int) -> PosePrior:
        """The same prior (as adapted) over ``n_frames`` frames (a window of the clip)."""
        new = copy.copy(self)
        new.frames = np.arange(int(n_frames))
        return new

    def adapted(self, widen_diag, widen_corr, centre_diag=None, centre_corr=None) -> PosePrior:
        """A copy whose rows answer to a clip: each joint outside the correlated ones with its
        standard deviation times ``widen_diag[i]`` (in the order of ``diag``) and its mean moved
        to ``centre_diag`` (or kept); each correlated row ``i`` (of every component's whitening)
        divided by ``widen_corr[i]``, every component's mean moved by ``centre_corr`` (a (d,)
        offset, or none). :meth:`distances` still measures the clips' distances."""
        new = copy.copy(self)
        new.inv_sigma = self.inv_sigma.copy()
        new.inv_sigma[self.diag] /= np.asarray(widen_diag, float)
        new.As = self.As / np.asarray(widen_corr, float)[None, :, None]
        new.q_ref = self.q_ref.copy()
        if centre_diag is not None:
            new.q_ref[self.diag] = centre_diag
        if centre_corr is not None:
            new.means = self.means + np.asarray(centre_corr, float)
        new._jacobian_blocks()
        return new

    def _residuals(self, Q):
        """(rd, rc, const, best): the diagonal rows (joints outside ``qcorr``), the Mahalanobis
        rows of each frame's component (the one of least cost), that component's constant and
        its index."""
        rd = (Q[:, self.qidx[self.diag]] - self.q_ref[self.diag]) * self.inv_sigma[self.diag]
        rc = self._whitened(Q)
        if len(self.means) == 1:
            return rd, rc[:, 0], np.zeros(len(Q)), np.zeros(len(Q), int)
        m = np.linalg.norm(rc, axis=2)
        cost = (0.5 * m**2 if self.k is None else self._robust(m)[0]) + self.consts
        best = np.argmin(cost, axis=1)
        return rd, rc[np.arange(len(Q)), best], self.consts[best], best

    def raw_rows(self, Q) -> tuple[np.ndarray, np.ndarray]:
        """``(rd, rc)``: the rows of trajectory ``Q`` before any robust reweighting: (T, nd)
        the joints outside ``qcorr``, (T, d) the correlated joints' whitened offsets from each
        frame's component."""
        rd, rc, _, _ = self._residuals(np.asarray(Q, float))
        return rd, rc

    def _whitened(self, Q):
        """(T, K, d) the correlated joints' offsets from each component's mean, whitened by it
        (in units of ``scale``): their norms are the frame's Mahalanobis distances."""
        return np.einsum("kij,tkj->tki", self.As, Q[:, None, self.qcorr] - self.means)

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        N, nd, dc = len(self.frames), len(self.diag), len(self.qcorr)
        rd, rc, const, best = self._residuals(state.Q)
        mixed = len(self.means) > 1
        cv = None
        if self.k is not None:  # the robust loss on the frame's distance m, reweighted rows
            rho, sw = self._robust(np.linalg.norm(rc, axis=1))
            cv = float(rho.sum() + const.sum() + 0.5 * (rd**2).sum())
            rc = rc * sw[:, None]
        parts = [rd, rc] + ([np.sqrt(2.0 * const)[:, None]] if mixed else [])  # the component's constant
        r = np.concatenate(parts, axis=1)
        J = None
        if jacobian:
            Jf = self._Jf
            nr = Jf.shape[1]
            if self.k is None and not mixed:
                J = np.broadcast_to(Jf[0], (N, 1) + Jf.shape[1:])
            else:
                w_rows = np.ones((N, nr))
                if self.k is not None:
                    w_rows[:, nd:nd + dc] = sw[:, None]
                J = (w_rows[:, :, None] * Jf[best])[:, None]
        return RowBlock(self.frames[:, None], r, J, self.cols, self.name, cost_value=cv)

    def _robust(self, m):
        """(rho(m), sqrt(rho'(m) / m)) per frame."""
        k = self.k
        if self.loss == "cauchy":
            u = (m / k) ** 2
            return 0.5 * k**2 * np.log1p(u), 1.0 / np.sqrt(1.0 + u)
        out = m <= k
        return np.where(out, 0.5 * m**2, k * m - 0.5 * k**2), np.sqrt(np.where(out, 1.0, k / np.maximum(m, 1e-300)))

    def distances(self, Q) -> np.ndarray:
        """(T,) each frame's Mahalanobis distance of the correlated joints from the mean (of
        a mixture: from the nearest component's), in standard deviations of the prior's clips
        (not in units of ``scale``)."""
        means, As = self.clips
        z = np.einsum("kij,tkj->tki", As, np.asarray(Q, float)[:, None, self.qcorr] - means)
        return self.scale * np.linalg.norm(z, axis=2).min(axis=1)

    def frame_costs(self, Q) -> np.ndarray:
        """(T,) each frame's cost of trajectory ``Q`` (T, nq) under this prior (the robust
        loss itself, not the reweighted rows' 0.5 |r|^2; of a mixture, its least-cost
        component's with that component's constant)."""
        rd, rc, const, _ = self._residuals(np.asarray(Q, float))
        m = np.linalg.norm(rc, axis=1)
        rho = 0.5 * m**2 if self.k is None else self._robust(m)[0]
        return rho + const + 0.5 * (rd**2).sum(axis=1)


def pose_prior(figure, rest: np.ndarray, name: str = "human_pose") -> tuple[np.ndarray, np.ndarray]:
    """(q_ref (nq,), sigma (nq,)): the joint means and standard deviations of pose prior
    ``name`` (``models/priors/<name>.json``, made by ``tools/fit_pose_prior.py``; default the
    generic human's); entries the file does not name keep ``rest`` and 1 rad."""
    table = _pose_prior_file(name)["joints"]
    m = figure.model
    ref, sigma = np.array(rest, float), np.ones(figure.nq)
    for jid in range(1, m.njoints):
        if m.names[jid] in table and m.nqs[jid] == 1:
            ref[m.idx_qs[jid]], sigma[m.idx_qs[jid]] = table[m.names[jid]]
    return ref, sigma


def pose_prior_covariance(figure, name: str = "human_pose") -> tuple[np.ndarray, np.ndarray]:
    """(q indices (d,), covariance (d, d)) of the joints that move in pose prior ``name``'s
    clips (``"correlated"``; radians squared)."""
    names, cov = _pose_prior_file(name)["correlated"]
    m = figure.model
    jid = {m.names[j]: j for j in range(1, m.njoints)}
    return np.array([m.idx_qs[jid[n]] for n in names], int), cov


def pose_prior_distances(name: str = "human_pose") -> dict[str, float]:
    """Percentiles (``"50"``, ``"90"``, ``"99"``, ``"100"``) of the Mahalanobis distance
    (:meth:`PosePrior.distances`) of pose prior ``name``'s own clips' frames from its mean."""
    return dict(_pose_prior_file(name)["distances"])


def pose_prior_names() -> list[str]:
    """The bundled pose priors (``models/priors/*.json``)."""
    return sorted(p.stem for p in model_path("priors").glob("*.json"))


@functools.cache
def _pose_prior_file(name: str) -> dict:
    path = Path(name) if name.endswith(".json") else model_path("priors", f"{name}.json")
    if not path.is_file():
        raise InputError(f"no pose prior {name!r}; bundled: {', '.join(pose_prior_names())}, or a JSON file made by "
                         "tools/fit_pose_prior.py", field="weights.pose_prior_model")
    data = read_json(path)
    try:
        corr = data["correlated"]
        mix = corr.get("mixture")
        if mix is not None:
            mix = (np.array(mix["weights"], float), np.array(mix["means"], float), np.array(mix["covariances"], float))
        return {"joints": {k: (float(v[0]), float(v[1])) for k, v in data["joints"].items()},
                "correlated": (list(corr["joints"]), np.array(corr["covariance"], float)),
                "mixture": mix,
                "distances": {k: float(v) for k, v in corr.get("distance_quantiles", {}).items()},
                "rest_directions": {k: np.asarray(v, float) for k, v in data.get("rest_directions", {}).items()},
                "figure": str(data.get("figure", ""))}
    except (ValueError, KeyError, TypeError, IndexError, AttributeError) as exc:
        raise InputError(f"not a pose prior made by tools/fit_pose_prior.py ({exc})", file=path,
                         field="weights.pose_prior_model") from None


def prior_for(figure, model: str = "auto") -> str | None:
    """The pose prior that ``figure`` is held by under ``Weights.pose_prior_model``:
    ``"auto"``: the generic human's (``"human_pose"``) for ``Figure.human()``, none for other
    figures; ``"none"``; or a prior's name (``models/priors``) or JSON file, which must fit the
    figure: every joint it correlates is one of the figure's one-DOF joints, and, for a prior
    of a BVH layout, the figure's rest bone directions within
    :data:`REST_DIRECTION_TOLERANCE_DEG` of the prior's clips' (same names, another rest pose,
    would be another pose). Raises :class:`~pinrecon.errors.InputError` otherwise."""
    if model == "none":
        return None
    if model == "auto":
        return "human_pose" if figure.meta.get("generic") == "human" else None
    data = _pose_prior_file(model)
    m = figure.model
    have = {m.names[j] for j in range(1, m.njoints) if m.nqs[j] == 1}
    missing = [n for n in data["correlated"][0] if n not in have]
    if missing:
        raise InputError(f"pose prior {model!r} ({data['figure']}) does not fit figure {figure.name!r}: "
                         f"{len(missing)} of its joints are not the figure's (e.g. {', '.join(missing[:3])})",
                         field="weights.pose_prior_model")
    dirs = data["rest_directions"]
    if dirs:
        bvh = figure.meta.get("bvh")
        if not bvh:
            raise InputError(f"pose prior {model!r} is for BVH figures ({data['figure']}); figure {figure.name!r} "
                             "was not made from a BVH file", field="weights.pose_prior_model")
        worst, where = 0.0, ""
        for n, u in rest_directions(figure).items():
            if n in dirs:
                a = float(np.degrees(np.arccos(np.clip(u @ dirs[n], -1.0, 1.0))))
                worst, where = max((worst, where), (a, n))
        if worst > REST_DIRECTION_TOLERANCE_DEG:
            raise InputError(f"pose prior {model!r} does not fit figure {figure.name!r}: its rest pose differs from "
                             f"the prior's clips' (bone {where} {worst:.0f} degrees off, more than "
                             f"{REST_DIRECTION_TOLERANCE_DEG:.0f}): the same joint angles would be another pose",
                             field="weights.pose_prior_model")
    return model


def rest_directions(figure) -> dict[str, np.ndarray]:
    """A BVH figure's rest bone directions: each non-root joint's unit OFFSET (``meta["bvh"]``),
    joints at their parent's position left out; what a BVH pose prior's clips stored
    (``"rest_directions"``, ``tools/fit_pose_prior.py --figure bvh``) and :func:`prior_for` checks."""
    bvh = figure.meta["bvh"]
    return {n: np.asarray(o, float) / np.linalg.norm(o) for n, p, o in zip(bvh["names"], bvh["parents"], bvh["offsets"])
            if p >= 0 and np.linalg.norm(o) > 1e-9}


def unused_priors(figure) -> list[str]:
    """The bundled pose priors that fit ``figure`` (:func:`prior_for`) but are not its default
    (``"auto"``): what a user of a BVH figure may turn on (``--pose-prior-model``)."""
    default, out = prior_for(figure), []
    for name in pose_prior_names():
        try:
            if name != default and prior_for(figure, name):
                out.append(name)
        except InputError:
            pass
    return out


def posture_row(figure, n_frames: int, weights, active=None) -> Posture | None:
    """The posture prior of ``figure`` (``weights`` a :class:`pinrecon.problem.Weights`): a pose
    prior learned from motion capture (:class:`PosePrior` at the scale ``weights.pose_prior``,
    :func:`prior_for` chooses it by ``weights.pose_prior_model``: by default the generic
    human's), else the rest pose with ``weights.sigma_posture`` (``None``: no row)."""
    name = prior_for(figure, weights.pose_prior_model) if weights.pose_prior is not None else None
    if name is not None:
        ref, sigma = pose_prior(figure, rest_pose(figure), name)
        qcorr, cov = pose_prior_covariance(figure, name)
        s = weights.pose_prior
        return PosePrior(figure, n_frames, ref, sigma * s, qcorr, cov, s, active, weights.pose_prior_k,
                         weights.pose_prior_loss, pose_prior_distances(name), _pose_prior_file(name)["mixture"])
    if weights.sigma_posture is None:
        return None
    return Posture(figure, n_frames, rest_pose(figure), weights.sigma_posture, active)


def rest_pose(figure, margin=0.05):
    """The neutral configuration clamped inside the joint limits (with a margin)."""
    return figure.clamp(figure.neutral(), margin=margin)
