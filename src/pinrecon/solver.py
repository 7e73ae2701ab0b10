"""Block-banded Gauss-Newton / Levenberg-Marquardt over a trajectory of T frames.

The solver knows row blocks and tangent spaces, nothing about figures or cameras.
A *problem* provides:

* ``n_frames`` (T) and ``nv`` (tangent size per frame),
* ``evaluate(x, jacobian) -> list[RowBlock]`` (see :mod:`pinrecon.rows.base`),
* ``retract(x, dx) -> x'`` (``pin.integrate`` frame by frame for figures).

Each iteration assembles the normal equations ``H = J^T J`` and ``g = J^T r`` directly
in block-banded form over the *active* tangent entries (held ones are not unknowns):
a row group that touches frames t_i and t_j adds ``J_i^T J_j`` to block (t_i, t_j), so
H has block bandwidth equal to the widest frame span of any row (2 for
constant-velocity smoothing). The scalar half-bandwidth is computed from the blocks'
column structure (diagonal blocks across frames only couple equal tangent indices);
:class:`~pinrecon.banded.ActiveNormalEquations` writes H into a Fortran-ordered LAPACK
lower band buffer reused by every iteration, factored in place with a banded Cholesky
(``dpbtrf``). No dense (T nv)^2 matrix is ever formed; memory and time are linear in T.

Damping is Levenberg-Marquardt's ``(H + lambda D) dx = -g`` with ``D`` the (floored)
diagonal of H (the paper's stabilising ``kI``, scaled and made adaptive with
Nielsen's update), with a line search along the step (``SolverOptions.line_search``)
or, optionally, geodesic acceleration. A step is accepted only if it lowers the cost and
gives finite residuals; otherwise it is rejected, said so in the report, and the
damping grows. The returned trajectory is never NaN.

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
from scipy.linalg import LinAlgError

from .banded import ActiveNormalEquations, ArrowheadFactor, BandedNormalEquations, schur_complement

__all__ = ["SolverOptions", "IterationReport", "SolveResult", "costs_at", "flatten_blocks", "globals_of", "globals_information", "solve", "BandedNormalEquations", "ArrowheadFactor"]


@dataclass
class SolverOptions:
    """Termination and damping settings.

    ftol : stop when an accepted step lowers the cost by less than ``ftol * cost``. The
        cost is a whitened least-squares cost (in nats). With the line search (below) the
        default 1e-4 ends at a lower cost than plain Levenberg-Marquardt did at 1e-5, in
        fewer iterations, on the 1000-frame human benchmark (10 iterations, cost 6189.9,
        11.3 mm mean per-joint error; was 13, 6190.6, 11.3 mm) and on the 1123-frame CMU
        dance from the same start (13 iterations, 7344.0, 8.9 mm; was 21, 7444.5, 8.9 mm);
        ``bench/bench_accuracy.py`` prints the same errors. Use 1e-6 or lower for a strict
        solve.
    gtol : stop when ``max |g| <= gtol * (1 + cost)`` (first-order optimality).
    xtol : stop when ``|dx| <= xtol * (sqrt(T nv) + |dx|)``.
    max_iterations : cap on linearisations (accepted or not).
    damping : initial lambda (relative to diag(H)).
    geodesic_acceleration : add Transtrum & Sethna's geodesic acceleration to each step
        (one extra residual evaluation per iteration): the second directional derivative
        of the residuals along the step corrects it for the curvature of the valley it
        runs along; steps whose correction is larger than ``geodesic_alpha`` times the step
        are rejected (``geodesic_h``: the relative finite-difference step). Off by default:
        on the 1000-frame benchmark it costs more time for the same result (0.95 vs 0.78 s
        CPU; 2.1 vs 1.3 s before the speed work); on fast motion it can find better minima (the run clip: 44 vs 51 mm mean
        per-joint error over three views, though not in every view), so try it there.
    blas_threads : BLAS/LAPACK threads while solving (``None`` leaves them alone). The
        work is many small matrix operations plus one banded Cholesky; OpenBLAS threads
        that spin-wait for a busy core made one 1000-frame solve 30 times slower here
        (89 s instead of 3 s on a loaded 2-core machine), and two threads made the dance's
        banded Cholesky 20 times slower in CPU time on the loaded machine, so the default is 1.
    line_search : the cost along a step is modelled as the parabola through f(0),
        f'(0) = g.dx and f(1); when the step failed, or the parabola's minimum t* lies
        clearly beyond it (t* > 1.25: the Gauss-Newton model too pessimistic), the point
        t* dx is evaluated too and kept if lower. A failed step is so rescued by
        backtracking, without a new factorisation. ``line_search_max`` caps t*.
    """

    max_iterations: int = 100
    ftol: float = 1e-4
    gtol: float = 1e-10
    xtol: float = 1e-10
    damping: float = 1e-3
    max_damping: float = 1e12
    diag_floor: float = 1e-9
    blas_threads: int | None = 1
    geodesic_acceleration: bool = False
    geodesic_h: float = 0.1
    geodesic_alpha: float = 0.75
    line_search: bool = True
    line_search_max: float = 4.0


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


def globals_of(res) -> np.ndarray | None:
    """A solve result's global unknowns (``res.g``), None when it has none."""
    g = getattr(res, "g", None)
    return None if g is None or not len(g) else g


def globals_information(problem, x, g, active=None, *, rows: Callable | None = None,
                        jitter: float = 1e-9) -> np.ndarray:
    """What the rows say about the global unknowns ``g`` at ``(x, g)`` with the motion
    marginalised out: ``S = C - B^T A^-1 B``, the Schur complement of the undamped
    Gauss-Newton normal equations ``J^T J`` (the arrowhead of the module docstring).

    The cost is ``0.5 |r|^2`` in whitened rows, so ``S`` is the curvature of the cost
    profiled over the motion, and ``inv(S)`` over all rows is the Laplace approximation of
    the globals' posterior covariance. ``rows`` (a predicate on a row block) keeps only
    some rows, e.g. the measurements, to ask what the data alone determine; motion
    directions no kept row touches are then free (``jitter``, relative to the largest
    diagonal entry, keeps ``A`` factorable), so a global that they can trade against is
    left undetermined. With robust losses the reweighted rows at ``(x, g)`` are read.
    ``(0, 0)`` without globals.
    """
    if g is None or not np.size(g):
        return np.zeros((0, 0))
    gv = np.asarray(g, float).reshape(-1)
    n_g = gv.size
    blocks = _flatten(problem.evaluate(x, True, gv))
    if rows is not None:
        blocks = [b for b in blocks if rows(b)]
    if not blocks:
        return np.zeros((n_g, n_g))
    normal = ActiveNormalEquations(problem.n_frames, problem.nv, blocks, active)
    _, (B, C, _) = normal.assemble(blocks, n_g)
    diag = normal.diagonal()
    floor = jitter * max(float(diag.max()) if diag.size else 0.0, 1e-300)
    normal.ab[0] += floor + np.where(diag > floor, 0.0, 1.0)
    _, S = schur_complement(ArrowheadFactor(normal.ab).c, B, C)
    return 0.5 * (S + S.T)


def _costs(blocks) -> dict[str, float]:
    out: dict[str, float] = {}
    for b in blocks:
        out[b.name] = out.get(b.name, 0.0) + b.cost
    return out


def costs_at(problem, x, g=None) -> dict[str, float]:
    """The MAP cost of ``problem`` at the trajectory ``x`` and the globals ``g`` (default its
    ``g0``), per row kind (``0.5 |r|^2``, or a robust kind's own cost)."""
    return _costs(_flatten(problem.evaluate(x, False) if g is None else problem.evaluate(x, False, g)))


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


def flatten_blocks(blocks) -> list:
    """The row blocks of ``problem.evaluate(...)`` as one flat list (a row kind may return several)."""
    return _flatten(blocks)


def _flatten(blocks):
    out = []
    for b in blocks:
        if isinstance(b, (list, tuple)):
            out.extend(_flatten(b))
        elif b is not None:
            out.append(b)
    return out


def solve(problem, x0, options=None, callback=None, active=None, g0=None, active_globals=None, *,
          stop_when=None) -> SolveResult:
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
    stop_when : optional ``stop_when(iteration, x)``, called after each accepted step with the
        new (T, nq) trajectory; a string returned stops the solve, with that string as its
        ``status`` (``converged`` False).
    """
    opt = options or SolverOptions()
    if opt.blas_threads is None:
        return _solve(problem, x0, opt, callback, active, g0, active_globals, stop_when)
    with _blas_controller().limit(limits=opt.blas_threads, user_api="blas"):
        return _solve(problem, x0, opt, callback, active, g0, active_globals, stop_when)


_CONTROLLER: list = []


def _blas_controller():
    """threadpoolctl's controller, found once (building one lists the loaded libraries:
    about a millisecond, paid by every small solve of a start otherwise)."""
    if not _CONTROLLER:
        from threadpoolctl import ThreadpoolController

        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0]


def _solve(
    problem,
    x0: np.ndarray,
    options: SolverOptions | None = None,
    callback: Callable[[IterationReport], bool | None] | None = None,
    active: np.ndarray | None = None,
    g0: np.ndarray | None = None,
    active_globals: np.ndarray | None = None,
    stop_when: Callable[[int, np.ndarray], str | None] | None = None,
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
    # the unknowns are the active tangent entries (the others are held at their start)
    normal = ActiveNormalEquations(T, nv, blocks, active)
    frozen_g = np.zeros(0, dtype=int)
    if active_globals is not None and n_g:
        frozen_g = np.where(~np.asarray(active_globals, bool))[0]
    lam = opt.damping
    nu = 2.0
    report: list[IterationReport] = []
    status, converged = "max_iterations", False
    initial_cost = cost

    def linearise(blocks):
        """Normal equations at the current blocks (``H`` into ``normal.ab``); held globals
        get zero rows and columns and a unit diagonal (their steps are exactly zero)."""
        g, border = normal.assemble(blocks, n_g)
        if border is not None and len(frozen_g):
            B, C, gg = border
            B[:, frozen_g] = 0.0
            C[frozen_g, :] = 0.0
            C[:, frozen_g] = 0.0
            C[frozen_g, frozen_g] = 1.0
            gg[frozen_g] = 0.0
        return g, border

    def gradient(blocks, residuals):
        """``J^T r`` over the active entries and the globals (held ones zero)."""
        gx = normal.gradient(blocks, residuals)
        gg = _globals_gradient(blocks, residuals, n_g) if n_g else None
        if n_g and len(frozen_g):
            gg[frozen_g] = 0.0
        return gx, gg

    def grad_norm(g, gg):
        m = float(np.max(np.abs(g))) if g.size else 0.0
        if gg is not None and gg.size:
            m = max(m, float(np.max(np.abs(gg))))
        return m

    g, border = linearise(blocks)
    gg = None if border is None else border[2]
    band_ready = True
    fac = None
    dscale = dscale_g = None
    old_cost = cost
    it = 0
    while it < opt.max_iterations:
        gnorm = grad_norm(g, gg)
        if gnorm <= opt.gtol * (1.0 + cost):
            status, converged = "gtol", True
            break
        it += 1
        why, dx, dg = None, None, None
        if not band_ready:  # assemble the band (the last factorisation overwrote it)
            g, border = linearise(blocks)
            gg = None if border is None else border[2]
        ab = normal.ab
        diag = normal.diagonal()
        dmax = float(diag.max()) if diag.size else 0.0
        if n_g:
            diag_g = np.diag(border[1]).copy()
            dmax = max(dmax, float(diag_g.max()))
        dscale = np.maximum(diag, opt.diag_floor * max(dmax, 1e-300))
        ab[0] += lam * dscale
        dscale_g = None
        fac = None
        try:
            if n_g:
                dscale_g = np.maximum(diag_g, opt.diag_floor * max(dmax, 1e-300))
                fac = ArrowheadFactor(ab, border[0], border[1] + lam * np.diag(dscale_g))
                dx, dg = fac.solve(-g, -gg)
            else:
                fac = ArrowheadFactor(ab)
                dx, _ = fac.solve(-g)
            if not (np.all(np.isfinite(dx)) and (dg is None or np.all(np.isfinite(dg)))):
                why, fac = "non-finite step", None
        except LinAlgError:
            why, dx, dg, fac = "factorisation failed", None, None, None
        band_ready = False
        v_lm, vg_lm = dx, dg  # the Levenberg-Marquardt step, whose decrease the quadratic model predicts
        if why is None and opt.geodesic_acceleration:
            # second directional derivative of the residuals along v = dx, by finite
            # differences on the manifold: r'' ~ 2/h ((r(x (+) h v) - r(x)) / h - J v)
            h = opt.geodesic_h
            v = normal.expand(dx)
            r_h = evaluate(problem.retract(x, h * v), None if gv is None else gv + h * dg, False)
            jv = _blocks_times(blocks, v, dg)
            rpp = [(2.0 / h) * ((bh.r - b.r) / h - j) for bh, b, j in zip(r_h, blocks, jv)]
            g2, g2g = gradient(blocks, rpp)
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
        rescued = False
        if why is None:
            x_new = problem.retract(x, normal.expand(dx))
            g_new = None if gv is None else (gv if dg is None else gv + dg)
            new_blocks = evaluate(x_new, g_new, True)
            new_costs = _costs(new_blocks)
            new_cost = sum(new_costs.values())
            slope = float(g @ v_lm) + (float(gg @ vg_lm) if n_g else 0.0)  # d cost / dt along the step
            predicted = 0.5 * (-slope + lam * float(v_lm @ (dscale * v_lm)))  # (H + lam D) v = -g
            if n_g:
                predicted += 0.5 * lam * float(vg_lm @ (dscale_g * vg_lm))
            rho = (cost - new_cost) / predicted if predicted > 0 else -1.0
            finite = bool(np.isfinite(new_cost) and np.all(np.isfinite(x_new)))
            if finite and opt.line_search and not opt.geodesic_acceleration and slope < 0:
                # the cost along the step through f(0), f'(0) and f(1) is a parabola: when the
                # step failed or is clearly too short, its minimum t* is tried as well
                curv = 2.0 * (new_cost - cost - slope)
                t_star = float(np.clip(-slope / curv if curv > 0 else opt.line_search_max, 0.1, opt.line_search_max))
                if not rho > 1e-4 or t_star > 1.25:  # rejected (backtrack), or clearly too short
                    x_t = problem.retract(x, normal.expand(t_star * dx))
                    g_t = None if gv is None else (gv if dg is None else gv + t_star * dg)
                    blocks_t = evaluate(x_t, g_t, True)
                    costs_t = _costs(blocks_t)
                    cost_t = sum(costs_t.values())
                    if np.isfinite(cost_t) and np.all(np.isfinite(x_t)) and cost_t < min(new_cost, cost):
                        rescued = not rho > 1e-4
                        x_new, g_new, new_blocks, new_costs, new_cost = x_t, g_t, blocks_t, costs_t, cost_t
            if not finite:
                why = "non-finite residuals"
            elif not (rho > 1e-4 or rescued):
                why = "cost did not decrease"
        if why is None:
            if rescued:  # the full step failed and a shorter one along it did not: damp more
                lam = lam * 2.0
            else:
                lam = max(lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 1e-15)
                nu = 2.0
            old_cost = cost
            x, gv, blocks, costs, cost = x_new, g_new, new_blocks, new_costs, new_cost
            stop = None
            if old_cost - cost <= opt.ftol * cost:
                stop = "ftol"
            elif step_norm <= opt.xtol * (np.sqrt(T * nv + n_g) + step_norm):
                stop = "xtol"
            if stop is None:
                g, border = linearise(blocks)
                gg = None if border is None else border[2]
                band_ready = True
            else:  # the last step: the gradient for the report, no normal equations
                g, gg = gradient(blocks, [b.r for b in blocks])
            rep = _rep(it, cost, costs, step_norm, lam, grad_norm(g, gg), True, t_start)
        else:
            stop = None
            lam, nu = lam * nu, nu * 2.0
            rep = _rep(it, cost, costs, step_norm, lam, gnorm, False, t_start, why)
        report.append(rep)
        if callback is not None and callback(rep):
            status = "stopped by callback"
            break
        if stop is not None:
            status, converged = stop, True
            break
        if stop_when is not None and rep.accepted:
            said = stop_when(it, x)
            if said:
                status = str(said)
                break
        if not rep.accepted and lam > opt.max_damping:
            status = "no_progress"
            break
    res = _result(x, cost, costs, it, converged, status, report, t_start, initial_cost)
    res.g = gv
    return res


def _rep(it, cost, costs, step, lam, gnorm, accepted, t_start, message=""):
    return IterationReport(it, cost, dict(costs), step, lam, gnorm, accepted, time.perf_counter() - t_start, message)


def _result(x, cost, costs, it, converged, status, report, t_start, initial_cost):
    return SolveResult(x, cost, costs, it, converged, status, report, time.perf_counter() - t_start, initial_cost)
