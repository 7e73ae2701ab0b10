"""Block-banded Gauss-Newton / Levenberg-Marquardt over a trajectory of T frames.

The solver knows row blocks and tangent spaces, nothing about figures or cameras.
A *problem* provides:

* ``n_frames`` (T) and ``nv`` (tangent size per frame),
* ``evaluate(x, jacobian) -> list[RowBlock]`` (see :mod:`pinrecon.rows.base`),
* ``retract(x, dx) -> x'`` (``pin.integrate`` frame by frame for figures).

Each iteration assembles the normal equations ``H = J^T J`` and ``g = J^T r`` directly
in block-banded form: a row group that touches frames t_i and t_j adds ``J_i^T J_j`` to
block (t_i, t_j), so H has block bandwidth equal to the widest frame span of any row
(2 for constant-velocity smoothing). The scalar half-bandwidth is computed from the
blocks' column structure (diagonal blocks across frames only couple equal tangent
indices), stored in LAPACK's lower band format and factored with a banded Cholesky
(``scipy.linalg.cholesky_banded``). No dense (T nv)^2 matrix is ever formed; memory
and time are linear in T.

Damping is Levenberg-Marquardt's ``(H + lambda D) dx = -g`` with ``D`` the (floored)
diagonal of H (the paper's stabilising ``kI``, scaled and made adaptive with
Nielsen's update), optionally with geodesic acceleration. A step is accepted only if it lowers the cost and gives finite
residuals; otherwise it is rejected, said so in the report, and the damping grows.
The returned trajectory is never NaN.

**Global unknowns.** A problem may also have a few time-invariant unknowns ``g``
(``solve(..., g0=...)``; the problem is then evaluated as ``evaluate(x, jacobian, g)``
and row blocks carry ``Jg``/``gcols``). The normal equations become an arrowhead,

    [A   B] [dx]     [g_x]
    [B^T C] [dg] = - [g_g],   A banded (T nv), B (T nv, n_g), C (n_g, n_g),

both diagonal blocks damped. With ``A = L L^T`` (the same banded Cholesky) and
``Z = L^-1 B`` (one banded triangular solve per global), the Schur complement
``S = C - Z^T Z`` is a small dense SPD matrix: ``dg = S^-1 (-g_g - Z^T z)`` with
``z = L^-1 (-g_x)``, then ``dx = L^-T (z - Z dg)``. Time and memory stay linear in T;
``g`` is retracted by plain addition (log factors are additive).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import LinAlgError, cho_factor, cho_solve
from scipy.linalg.lapack import dpbtrf as _pbtrf
from scipy.linalg.lapack import dpbtrs as _pbtrs
from scipy.linalg.lapack import dtbtrs as _tbtrs

__all__ = ["SolverOptions", "IterationReport", "SolveResult", "solve", "BandedNormalEquations", "ArrowheadFactor"]


@dataclass
class SolverOptions:
    """Termination and damping settings.

    ftol : stop when an accepted step lowers the cost by less than ``ftol * cost``. The
        cost is a whitened least-squares cost (in nats), so 1e-5 stops when steps gain a
        tiny fraction of a nat on typical problems; the tail Levenberg-Marquardt spends
        creeping along the flat valleys of limb twists beyond that changed the mean
        per-joint error by 0.2 mm (11.4 -> 11.2 mm) on the 1000-frame benchmark while
        tripling the time. Use 1e-6 or lower for a strict solve.
    gtol : stop when ``max |g| <= gtol * (1 + cost)`` (first-order optimality).
    xtol : stop when ``|dx| <= xtol * (sqrt(T nv) + |dx|)``.
    max_iterations : cap on linearisations (accepted or not).
    damping : initial lambda (relative to diag(H)).
    geodesic_acceleration : add Transtrum & Sethna's geodesic acceleration to each step
        (one extra residual evaluation per iteration): the second directional derivative
        of the residuals along the step corrects it for the curvature of the valley it
        runs along; steps whose correction is larger than ``geodesic_alpha`` times the step
        are rejected (``geodesic_h``: the relative finite-difference step). Off by default:
        on the 1000-frame benchmark it costs 60 % more time for the same result (2.1 vs
        1.3 s); on fast motion it can find better minima (the run clip: 44 vs 51 mm mean
        per-joint error over three views, though not in every view), so try it there.
    blas_threads : BLAS/LAPACK threads while solving (``None`` leaves them alone). The
        work is many small matrix operations plus one banded Cholesky; OpenBLAS threads
        that spin-wait for a busy core made one 1000-frame solve 30 times slower here
        (89 s instead of 3 s on a loaded 2-core machine), so the default is 1.
    """

    max_iterations: int = 100
    ftol: float = 1e-5
    gtol: float = 1e-10
    xtol: float = 1e-10
    damping: float = 1e-3
    max_damping: float = 1e12
    diag_floor: float = 1e-9
    blas_threads: int | None = 1
    geodesic_acceleration: bool = False
    geodesic_h: float = 0.1
    geodesic_alpha: float = 0.75


@dataclass
class IterationReport:
    """One line of the iteration log."""

    iteration: int
    cost: float
    costs: dict[str, float]
    step_norm: float
    damping: float
    gradient_norm: float
    accepted: bool
    time: float
    message: str = ""

    def __str__(self) -> str:
        kinds = " ".join(f"{k}={v:.4g}" for k, v in self.costs.items())
        flag = "" if self.accepted else f"  REJECTED ({self.message})"
        return (
            f"iter {self.iteration:3d}  cost {self.cost:.6g}  [{kinds}]  |dx| {self.step_norm:.3g}  "
            f"lambda {self.damping:.2g}  |g| {self.gradient_norm:.3g}  {self.time:.2f}s{flag}"
        )


@dataclass
class SolveResult:
    x: np.ndarray
    cost: float
    costs: dict[str, float]
    iterations: int
    converged: bool
    status: str
    report: list[IterationReport] = field(default_factory=list)
    time: float = 0.0
    initial_cost: float = float("nan")
    g: np.ndarray | None = None  # the global unknowns at the solution (None without globals)


def _costs(blocks) -> dict[str, float]:
    out: dict[str, float] = {}
    for b in blocks:
        out[b.name] = out.get(b.name, 0.0) + b.cost
    return out


def _blocks_times(blocks, dx, dg=None):
    """J v for every row block, v = (dx (T, nv), dg (n_g,) or None)."""
    out = []
    for b in blocks:
        jv = np.zeros_like(b.r)
        cols = np.asarray(b.cols)
        for i in range(b.frames.shape[1]):
            d = dx[b.frames[:, i]][:, cols]
            jv += b.J[:, i] * d if b.diagonal else np.einsum("nmc,nc->nm", b.J[:, i], d)
        if dg is not None and b.Jg is not None and b.r.size:
            jv += np.einsum("nmg,g->nm", b.Jg, dg[np.asarray(b.gcols, dtype=int)])
        out.append(jv)
    return out


def _globals_gradient(blocks, residuals, n_g):
    """J_g^T r over the blocks' global columns for residuals ``residuals`` (list of (N, m))."""
    gg = np.zeros(n_g)
    for b, r in zip(blocks, residuals):
        if b.Jg is not None and r.size:
            np.add.at(gg, np.asarray(b.gcols, dtype=int), np.einsum("nmg,nm->g", b.Jg, r))
    return gg


def _flatten(blocks):
    out = []
    for b in blocks:
        if isinstance(b, (list, tuple)):
            out.extend(_flatten(b))
        elif b is not None:
            out.append(b)
    return out


class BandedNormalEquations:
    """``H = J^T J``, ``g = J^T r`` assembled from row blocks into LAPACK lower band storage.

    Blocks of H are kept per frame distance d: ``D[0]`` (T, nv, nv) dense within-frame
    blocks, and for d >= 1 only the structurally non-zero entries of block (t+d, t),
    ``Dd[d]`` (T-d, nnz_d). ``kd`` is the scalar half-bandwidth implied by the structure.
    """

    def __init__(self, T: int, nv: int, blocks):
        self.T, self.nv = T, nv
        masks: dict[int, np.ndarray] = {}
        for b in blocks:
            s = b.frames.shape[1]
            cols = np.asarray(b.cols)
            for i in range(s):
                for j in range(i):
                    dist = np.unique(b.frames[:, i] - b.frames[:, j])
                    if np.any(dist < 0):
                        raise ValueError(f"row kind {b.name!r}: frames must be increasing within a row group")
                    for d in dist:
                        d = int(d)
                        if d == 0:
                            continue
                        m = masks.setdefault(d, np.zeros((nv, nv), dtype=bool))
                        if b.diagonal:
                            m[cols, cols] = True
                        else:
                            m[np.ix_(cols, cols)] = True
        kd = nv - 1
        self.pos: dict[int, np.ndarray] = {}
        self.entries: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for d, m in masks.items():
            a, c = np.nonzero(m)  # block (t+d, t): row a of frame t+d, col c of frame t
            kd = max(kd, int(np.max(d * nv + a - c)))
            pos = np.full((nv, nv), -1, dtype=np.int64)
            pos[a, c] = np.arange(len(a))
            self.pos[d] = pos
            self.entries[d] = (a, c)
        self.kd = kd
        self.distances = sorted(masks)

    @staticmethod
    def _scatter(target, idx_frames, values, idx_rest):
        """target[idx_frames, *idx_rest] += values, safe for repeated frames."""
        n = len(idx_frames)
        step = np.diff(idx_frames)
        increasing = bool(np.all(step > 0))  # row groups list frames in order: no repeats
        if n and not idx_rest and increasing and idx_frames[-1] - idx_frames[0] == n - 1:
            target[idx_frames[0] : idx_frames[0] + n] += values  # contiguous frames: a slice
            return
        nd = max((np.ndim(a) for a in idx_rest), default=1)
        fr = idx_frames.reshape((-1,) + (1,) * (nd - 1)) if idx_rest else idx_frames
        if increasing or len(np.unique(idx_frames)) == n:
            target[(fr,) + idx_rest] += values
        else:
            np.add.at(target, (fr,) + idx_rest, values)

    def assemble(self, blocks):
        T, nv = self.T, self.nv
        D0 = np.zeros((T, nv, nv))
        Dd = {d: np.zeros((T - d, len(self.entries[d][0]))) for d in self.distances}
        g = np.zeros((T, nv))
        for b in blocks:
            F, r, J, cols = b.frames, b.r, b.J, np.asarray(b.cols)
            if F.shape[0] == 0 or len(cols) == 0 or r.shape[1] == 0:
                continue
            full = len(cols) == nv and np.array_equal(cols, np.arange(nv))
            s = F.shape[1]
            for i in range(s):
                fi = F[:, i]
                if b.diagonal:
                    self._scatter(g, fi, J[:, i] * r, (cols[None, :],))
                else:
                    gi = np.einsum("nmc,nm->nc", J[:, i], r)
                    if full:
                        self._scatter(g, fi, gi, ())
                    else:
                        self._scatter(g, fi, gi, (cols[None, :],))
                for j in range(i + 1):
                    fj = F[:, j]
                    dist = fi - fj
                    if b.diagonal:
                        B = J[:, i] * J[:, j]  # (N, c)
                    else:
                        B = np.matmul(J[:, i].transpose(0, 2, 1), J[:, j])  # (N, c, c)
                    ds = (dist[0],) if (len(dist) and np.all(dist == dist[0])) else np.unique(dist)
                    for d in ds:
                        sel = dist == d
                        Bs = B if sel.all() else B[sel]
                        rows_f, cols_f = fi[sel], fj[sel]
                        if d == 0:
                            if i != j:  # same frame twice in one row group: add both halves
                                Bs = Bs + (Bs if b.diagonal else Bs.transpose(0, 2, 1))
                            if b.diagonal:
                                self._scatter(D0, rows_f, Bs, (cols[None, :], cols[None, :]))
                            elif full:
                                self._scatter(D0, rows_f, Bs, ())
                            else:
                                self._scatter(D0, rows_f, Bs, (cols[None, :, None], cols[None, None, :]))
                        else:
                            pos = self.pos[int(d)]
                            if b.diagonal:
                                k = pos[cols, cols]
                                self._scatter(Dd[int(d)], cols_f, Bs, (k[None, :],))
                            else:
                                k = pos[np.ix_(cols, cols)]
                                self._scatter(Dd[int(d)], cols_f, Bs, (k[None, :, :],))
        return D0, Dd, g.reshape(-1)

    def assemble_globals(self, blocks, n_g: int):
        """The border of the arrowhead: ``B = J_x^T J_g`` (T nv, n_g), ``C = J_g^T J_g``
        (n_g, n_g) and ``g_g = J_g^T r`` (n_g,), from the blocks' ``Jg``/``gcols``."""
        T, nv = self.T, self.nv
        B = np.zeros((n_g, T, nv)).transpose(1, 2, 0)  # (T, nv, n_g), column-major as (T nv, n_g)
        C = np.zeros((n_g, n_g))
        gg = np.zeros(n_g)
        for b in blocks:
            if b.Jg is None or b.r.size == 0:
                continue
            gc = np.asarray(b.gcols, dtype=int)
            Jg = b.Jg
            Jflat = Jg.reshape(-1, len(gc))
            C[np.ix_(gc, gc)] += Jflat.T @ Jflat
            gg[gc] += Jflat.T @ b.r.reshape(-1)
            cols = np.asarray(b.cols)
            if len(cols) == 0:
                continue
            all_g = len(gc) == n_g and np.array_equal(gc, np.arange(n_g))
            full = all_g and len(cols) == nv and np.array_equal(cols, np.arange(nv))
            for i in range(b.frames.shape[1]):
                if b.diagonal:
                    Bi = b.J[:, i][:, :, None] * Jg  # (N, c, g)
                else:
                    Bi = np.matmul(b.J[:, i].transpose(0, 2, 1), Jg)  # (N, c, g)
                fi = b.frames[:, i]
                if full:
                    self._scatter(B, fi, Bi, ())
                else:
                    self._scatter(B, fi, Bi, (cols[None, :, None], gc[None, None, :]))
        return B.reshape(T * nv, n_g), C, gg

    def gradient(self, blocks, residuals) -> np.ndarray:
        """J^T r for the blocks' Jacobians and other residuals ``residuals`` (list of (N, m))."""
        g = np.zeros((self.T, self.nv))
        for b, r in zip(blocks, residuals):
            cols = np.asarray(b.cols)
            if b.frames.shape[0] == 0 or len(cols) == 0 or r.shape[1] == 0:
                continue
            for i in range(b.frames.shape[1]):
                gi = b.J[:, i] * r if b.diagonal else np.einsum("nmc,nm->nc", b.J[:, i], r)
                self._scatter(g, b.frames[:, i], gi, (cols[None, :],))
        return g.reshape(-1)

    def band(self, D0, Dd, out: np.ndarray | None = None) -> np.ndarray:
        """LAPACK lower band storage ``ab[i - j, j] = H[i, j]`` (i >= j), into ``out`` when
        given (a buffer reused across iterations: no fresh 30 MB page faults each time)."""
        T, nv, kd = self.T, self.nv, self.kd
        if out is None:
            ab = np.zeros((kd + 1, T * nv))
        else:
            ab = out
            ab.fill(0.0)
        # within-frame blocks, one sub-diagonal k at a time: ab[k, t nv + c] = D0[t, c + k, c]
        for k in range(nv):
            ab[k].reshape(T, nv)[:, : nv - k] = np.diagonal(D0, -k, axis1=1, axis2=2)
        for d in self.distances:
            a, c = self.entries[d]
            base_d = (np.arange(T - d) * nv)[:, None]
            ab[(d * nv + a - c)[None, :], base_d + c[None, :]] = Dd[d]
        return ab


class ArrowheadFactor:
    """Factor ``[[A, B], [B^T, C]]`` (A banded in LAPACK lower storage, already damped;
    B (N, n_g) dense; C (n_g, n_g), already damped) once, then solve for any right-hand
    side through the Schur complement (see the module docstring).

    ``ab`` is overwritten by its Cholesky factor. Raises :class:`scipy.linalg.LinAlgError`
    when A or the Schur complement is not positive definite. Without a border (``B`` is
    ``None`` or has no column) this is the plain banded solve ``dpbtrs``.
    """

    def __init__(self, ab: np.ndarray, B: np.ndarray | None = None, C: np.ndarray | None = None):
        c, info = _pbtrf(ab, lower=1, overwrite_ab=1)  # in place: no copy of the band
        if info != 0:
            raise LinAlgError(f"banded Cholesky failed (info {info})")
        self.c = c
        self.n_g = 0 if B is None else B.shape[1]
        self.Z = self.S = None
        if self.n_g:
            # Z = L^-1 B, one banded forward substitution per global that couples to the
            # motion (a column of B that is zero, e.g. a held global, stays zero)
            coupled = np.flatnonzero(np.abs(B).max(axis=0) > 0) if B.shape[0] else np.zeros(0, int)
            if len(coupled) == self.n_g:
                Z, info = _tbtrs(c, B, uplo="L", trans="N")
            else:
                Z, info = np.zeros(B.shape, order="F"), 0
                if len(coupled):
                    Z[:, coupled], info = _tbtrs(c, B[:, coupled], uplo="L", trans="N")
            if info != 0:
                raise LinAlgError(f"banded triangular solve failed (info {info})")
            S = C - Z.T @ Z
            self.Z, self.S = Z, cho_factor(S, lower=True, check_finite=False)

    def solve(self, b_x: np.ndarray, b_g: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """``(x, y)`` with ``A x + B y = b_x`` and ``B^T x + C y = b_g``."""
        if not self.n_g:
            x, info = _pbtrs(self.c, b_x, lower=1)
            if info != 0:
                raise LinAlgError(f"banded solve failed (info {info})")
            return x, (None if b_g is None else np.zeros(0))
        z, info = _tbtrs(self.c, b_x[:, None], uplo="L", trans="N")
        z = z[:, 0]
        y = cho_solve(self.S, b_g - self.Z.T @ z, check_finite=False)
        x, info2 = _tbtrs(self.c, (z - self.Z @ y)[:, None], uplo="L", trans="T")
        if info or info2:
            raise LinAlgError("banded triangular solve failed")
        return x[:, 0], y


def solve(problem, x0, options=None, callback=None, active=None, g0=None, active_globals=None) -> SolveResult:
    """Minimise ``0.5 sum |r|^2`` over the trajectory starting from ``x0``.

    Parameters
    ----------
    problem : see the module docstring.
    x0 : (T, nq) start.
    options : :class:`SolverOptions`.
    callback : called with each :class:`IterationReport`; return True to stop early.
    active : optional (nv,) bool, tangent indices that may move (others stay fixed).
    g0 : optional (n_g,) start of the global unknowns. Given, the problem is evaluated
        as ``problem.evaluate(x, jacobian, g)`` and the result's ``g`` is their solution;
        omitted (``None``), the solve is exactly the motion-only one.
    active_globals : optional (n_g,) bool, globals that may move (others stay fixed).
    """
    opt = options or SolverOptions()
    if opt.blas_threads is None:
        return _solve(problem, x0, opt, callback, active, g0, active_globals)
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=opt.blas_threads, user_api="blas"):
        return _solve(problem, x0, opt, callback, active, g0, active_globals)


def _solve(
    problem,
    x0: np.ndarray,
    options: SolverOptions | None = None,
    callback: Callable[[IterationReport], bool | None] | None = None,
    active: np.ndarray | None = None,
    g0: np.ndarray | None = None,
    active_globals: np.ndarray | None = None,
) -> SolveResult:
    opt = options
    t_start = time.perf_counter()
    T, nv = problem.n_frames, problem.nv
    x = np.array(x0, float)
    gv = None if g0 is None else np.array(g0, float).reshape(-1)
    n_g = 0 if gv is None else gv.size

    def evaluate(xx, gg, jacobian):
        return _flatten(problem.evaluate(xx, jacobian) if gg is None else problem.evaluate(xx, jacobian, gg))

    blocks = evaluate(x, gv, True)
    costs = _costs(blocks)
    cost = sum(costs.values())
    if not np.isfinite(cost):
        raise FloatingPointError("the initial trajectory gives non-finite residuals")
    normal = BandedNormalEquations(T, nv, blocks)
    frozen = None
    frozen_cols = None
    if active is not None:
        active = np.asarray(active, bool)
        frozen = np.where(np.tile(~active, T))[0]
        frozen_cols = np.where(~active)[0]
        # Dd entries (compressed per frame distance) in a frozen row or column
        frozen_dd = {d: np.isin(a, frozen_cols) | np.isin(c, frozen_cols) for d, (a, c) in normal.entries.items()}
    frozen_g = np.zeros(0, dtype=int)
    if active_globals is not None and n_g:
        frozen_g = np.where(~np.asarray(active_globals, bool))[0]
    lam = opt.damping
    nu = 2.0
    report: list[IterationReport] = []
    status, converged = "max_iterations", False
    initial_cost = cost

    def linearise(blocks):
        """Normal equations at the current blocks; frozen entries get zero rows and
        columns and a unit diagonal (their steps are exactly zero)."""
        D0, Dd, g = normal.assemble(blocks)
        border = normal.assemble_globals(blocks, n_g) if n_g else None
        if frozen is not None:
            D0[:, frozen_cols, :] = 0.0
            D0[:, :, frozen_cols] = 0.0
            D0[:, frozen_cols, frozen_cols] = 1.0
            for d, mask in frozen_dd.items():
                Dd[d][:, mask] = 0.0
            g[frozen] = 0.0
            if border is not None:
                border[0][frozen] = 0.0
        if border is not None and len(frozen_g):
            B, C, gg = border
            B[:, frozen_g] = 0.0
            C[frozen_g, :] = 0.0
            C[:, frozen_g] = 0.0
            C[frozen_g, frozen_g] = 1.0
            gg[frozen_g] = 0.0
        return D0, Dd, g, border

    def grad_norm(g, border):
        m = float(np.max(np.abs(g))) if g.size else 0.0
        if border is not None and n_g:
            m = max(m, float(np.max(np.abs(border[2]))))
        return m

    D0, Dd, g, border = linearise(blocks)
    band_buffer = np.empty((normal.kd + 1, T * nv))
    ab = normal.band(D0, Dd, band_buffer)
    it = 0
    while it < opt.max_iterations:
        gnorm = grad_norm(g, border)
        if gnorm <= opt.gtol * (1.0 + cost):
            status, converged = "gtol", True
            break
        it += 1
        if ab is None:  # the last factorisation overwrote the band: rebuild it
            ab = normal.band(D0, Dd, band_buffer)
        diag = ab[0].copy()
        dmax = float(diag.max())
        if n_g:
            diag_g = np.diag(border[1]).copy()
            dmax = max(dmax, float(diag_g.max()))
        dscale = np.maximum(diag, opt.diag_floor * max(dmax, 1e-300))
        ab[0] += lam * dscale
        dscale_g = None
        why, dx, dg = None, None, None
        try:
            if n_g:
                dscale_g = np.maximum(diag_g, opt.diag_floor * max(dmax, 1e-300))
                fac = ArrowheadFactor(ab, border[0], border[1] + lam * np.diag(dscale_g))
                dx, dg = fac.solve(-g, -border[2])
            else:
                fac = ArrowheadFactor(ab)
                dx, _ = fac.solve(-g)
            if not (np.all(np.isfinite(dx)) and (dg is None or np.all(np.isfinite(dg)))):
                why = "non-finite step"
        except LinAlgError:
            why, dx, dg = "factorisation failed", None, None
        ab = None
        v_lm, vg_lm = dx, dg  # the Levenberg-Marquardt step, whose decrease the quadratic model predicts
        if why is None and opt.geodesic_acceleration:
            # second directional derivative of the residuals along v = dx, by finite
            # differences on the manifold: r'' ~ 2/h ((r(x (+) h v) - r(x)) / h - J v)
            h = opt.geodesic_h
            v = dx.reshape(T, nv)
            r_h = evaluate(problem.retract(x, h * v), None if gv is None else gv + h * dg, False)
            jv = _blocks_times(blocks, v, dg)
            rpp = [(2.0 / h) * ((bh.r - b.r) / h - j) for bh, b, j in zip(r_h, blocks, jv)]
            g2 = normal.gradient(blocks, rpp)
            g2g = _globals_gradient(blocks, rpp, n_g) if n_g else None
            if frozen is not None:
                g2[frozen] = 0.0
            if n_g and len(frozen_g):
                g2g[frozen_g] = 0.0
            acc, acc_g = fac.solve(-g2, g2g if g2g is None else -g2g)
            acc_all = acc if acc_g is None else np.concatenate([acc, acc_g])
            step_all = dx if dg is None else np.concatenate([dx, dg])
            small = np.linalg.norm(acc_all) <= opt.geodesic_alpha * np.linalg.norm(step_all)
            if np.all(np.isfinite(acc_all)) and small:
                dx = dx + 0.5 * acc
                if dg is not None:
                    dg = dg + 0.5 * acc_g
            elif np.all(np.isfinite(acc_all)):
                why = "geodesic acceleration too large"
        step_norm = 0.0
        if dx is not None:
            step_norm = float(np.sqrt(dx @ dx + (0.0 if dg is None else dg @ dg)))
        if why is None:
            x_new = problem.retract(x, dx.reshape(T, nv))
            g_new = None if gv is None else gv + dg
            new_blocks = evaluate(x_new, g_new, True)
            new_costs = _costs(new_blocks)
            new_cost = sum(new_costs.values())
            predicted = 0.5 * (float(-g @ v_lm) + lam * float(v_lm @ (dscale * v_lm)))
            if n_g:
                predicted += 0.5 * (float(-border[2] @ vg_lm) + lam * float(vg_lm @ (dscale_g * vg_lm)))
            rho = (cost - new_cost) / predicted if predicted > 0 else -1.0
            if not (np.isfinite(new_cost) and np.all(np.isfinite(x_new))):
                why = "non-finite residuals"
            elif not rho > 1e-4:
                why = "cost did not decrease"
        if why is None:
            lam = max(lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 1e-15)
            nu = 2.0
            old_cost = cost
            x, gv, blocks, costs, cost = x_new, g_new, new_blocks, new_costs, new_cost
            D0, Dd, g, border = linearise(blocks)
            rep = _rep(it, cost, costs, step_norm, lam, grad_norm(g, border), True, t_start)
        else:
            lam, nu = lam * nu, nu * 2.0
            rep = _rep(it, cost, costs, step_norm, lam, gnorm, False, t_start, why)
        report.append(rep)
        if callback is not None and callback(rep):
            status = "stopped by callback"
            break
        if rep.accepted:
            if old_cost - cost <= opt.ftol * cost:
                status, converged = "ftol", True
                break
            if step_norm <= opt.xtol * (np.sqrt(T * nv + n_g) + step_norm):
                status, converged = "xtol", True
                break
        elif lam > opt.max_damping:
            status = "no_progress"
            break
    res = _result(x, cost, costs, it, converged, status, report, t_start, initial_cost)
    res.g = gv
    return res


def _rep(it, cost, costs, step, lam, gnorm, accepted, t_start, message=""):
    return IterationReport(it, cost, dict(costs), step, lam, gnorm, accepted, time.perf_counter() - t_start, message)


def _result(x, cost, costs, it, converged, status, report, t_start, initial_cost):
    return SolveResult(x, cost, costs, it, converged, status, report, time.perf_counter() - t_start, initial_cost)
