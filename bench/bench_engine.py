"""Engine speed and memory, and pinrecon against scipy.optimize.least_squares.

The problem: the example-robot-data human figure (nv = 42) with COCO-17 keypoints
walking (the bundled CMU walk retargeted onto it and looped, `pinrecon.synthetic.
human_walk`), 30 fps, seen by an orthographic camera 45 degrees from side-on with 1 px
noise, with all four row kinds of DiFranco et al.: 2D measurements, joint-limit
barriers, constant-velocity smoothing, and 3D point keyframes (2 cm) every 8 frames,
plus the generic human's pose prior, adapted to the keyframes' start where they disagree with
it (``pinrecon.prior_yield``; ``build_problem`` does it as ``reconstruct`` does). Start: the
keyframes' poses interpolated (what `reconstruct` does).

1. Speed at 1000 frames: time to convergence (pinrecon's own termination: relative
   cost decrease below 1e-4), iterations, accuracy.
2. Memory: peak resident memory of a fresh process solving 100, 1000 and 10000 frames.
3. scipy.optimize.least_squares (method "trf", the sparse Jacobian by finite differences
   with `jac_sparsity`, default tolerances) on the same residuals from the same start,
   parametrised by tangent offsets from the start; and the same with pinrecon's analytic
   sparse Jacobian (to separate the linear algebra from the finite differences). The
   ratio compares scipy's time with the time pinrecon first reaches scipy's final cost.

4. Calibration (issue 9): the same problem with the figure's proportions and the
   camera's scale as global unknowns (``calibrate="lengths+camera"``: the 9 proportion
   groups COCO-17 sees and the orthographic scale, eliminated by the Schur complement).
   Speed: seconds per iteration over the same fixed number of iterations from the same
   start, with and without, in 11 interleaved pairs (``--calibration-pairs``; the
   machine's speed drifts by tens of per cent between minutes, so the ratio is the median
   of the pairs' ratios, with their range); memory: the calibrated columns of table 2. The motion-only
   rows of tables 1-3 are built with ``calibrate="none"`` (the human's default would be
   ``"lengths"`` with these keyframes).

5. The CMU dance 05_02 (1123 frames, its own skeleton, nv = 96): the whole
   ``pinrecon reconstruct`` run in a fresh process, imports included.
6. Long clips: ``reconstruct(..., window=2000)`` (what it does by itself past 10000
   frames, :mod:`pinrecon.windowed`) of 10000 and 100000 frames of the looped walk in
   fresh processes: CPU per frame (linear in frames) and peak resident memory.

Times: CPU seconds of the process (or of the child, user + sys) unless a column says
wall; the machine is shared, and wall time there counts other people's work.

Run: ``OPENBLAS_NUM_THREADS=1 python bench/bench_engine.py --scipy-frames 120`` (the
100000-frame row takes several minutes: ``--long-sizes 10000`` for a quicker run;
``--skip-scipy``, ``--skip-memory``, ``--skip-dance``). Prints markdown tables.
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take(["--frames", "100", "--scipy-frames", "50", "--memory-sizes", "100", "--skip-dance", "--calibration-pairs", "2",
                     "--long-sizes", "500"], cut=False)

import argparse
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def build(n_frames, seed=0, calibrate="none", weights_none=False):
    from pinrecon.reconstruct import build_problem
    from pinrecon.synthetic import human_walk, point_keyframes, project_tracks, side_camera

    fig, q = human_walk(n_frames, 30.0)
    cam = side_camera(q, 45.0, scale=300.0, center=(640, 360))
    tracks = project_tracks(fig, q, cam, fps=30.0, noise_px=1.0, seed=seed + 1)
    keys = point_keyframes(fig, q, range(0, n_frames, 8), sigma_m=0.02, seed=seed + 2)
    t = time.perf_counter()
    from pinrecon.problem import Weights

    weights = Weights(pose_prior=None) if weights_none else None
    setup = build_problem(fig, tracks, cam, keys, calibrate=calibrate, weights=weights)
    return fig, q, setup, time.perf_counter() - t


def run_pinrecon(setup, ftol=None, max_iterations=100, geodesic=False):
    """Solve from the setup's start; the trace has the CPU seconds of this process at each
    iteration (the scipy comparison uses the same clock)."""
    from pinrecon.solver import SolverOptions, solve

    trace = []
    t0 = time.process_time()

    def cb(rep):
        trace.append((time.process_time() - t0, rep.cost, rep.accepted))

    kw = dict(max_iterations=max_iterations, geodesic_acceleration=geodesic)
    if ftol is not None:
        kw["ftol"] = ftol
    opts = SolverOptions(**kw)
    res = solve(setup.problem, setup.q0, opts, callback=cb, active=setup.active, g0=setup.g0)
    return res, trace


def mpjpe_mm(fig, qa, qb, problem=None, g=None):
    """MPJPE of ``qa`` against ``qb``; with a calibrated ``problem``, ``qa``'s keypoints
    are those of the figure scaled by the globals ``g``."""
    pa = fig.keypoints(qa) if problem is None or g is None else problem.keypoints(qa, g)
    return 1000 * float(np.linalg.norm(pa - fig.keypoints(qb), axis=-1).mean())


# --------------------------------------------------------------------------- memory
def memory_child(n_frames, calibrate="none"):
    """Solve n_frames in this (fresh) process and print JSON with time and peak RSS."""
    import tracemalloc

    base_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    fig, q, setup, t_build = build(n_frames, calibrate=calibrate)
    after_build = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    tracemalloc.start()
    res, trace = run_pinrecon(setup)
    _, peak_traced = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(
        json.dumps(
            dict(
                frames=n_frames,
                build_s=t_build,
                solve_s=res.time,
                iterations=res.iterations,
                s_per_iteration=res.time / max(res.iterations, 1),
                peak_rss_mb=peak / 1024,
                rss_before_solve_mb=after_build / 1024,
                rss_at_start_mb=base_rss / 1024,
                solve_traced_peak_mb=peak_traced / 2**20,
                mpjpe_mm=mpjpe_mm(fig, res.x, q, setup.problem, res.g),
                calibrate=calibrate,
            )
        )
    )


def _child(n, calibrate):
    out = subprocess.run(
        [sys.executable, __file__, "--memory-child", str(n), "--child-calibrate", calibrate],
        capture_output=True,
        text=True,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
    )
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def memory_table(sizes, calibration=True):
    rows = [_child(n, "none") for n in sizes]
    cal = [_child(n, "lengths+camera") for n in sizes] if calibration else []
    print("\n### Time and memory against the number of frames\n")
    print("| frames | iterations | solve (s) | s / iteration | peak RSS (MB) | solver's own peak allocation (MB) | MPJPE (mm) |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(
            f"| {r['frames']} | {r['iterations']} | {r['solve_s']:.2f} | {r['s_per_iteration']:.3f} | "
            f"{r['peak_rss_mb']:.0f} | {r['solve_traced_peak_mb']:.0f} | {r['mpjpe_mm']:.1f} |"
        )
    if len(rows) >= 2:
        a, b = rows[-2], rows[-1]
        print(
            f"\nSolver allocation per frame: {1024 * a['solve_traced_peak_mb'] / a['frames']:.0f} KB at {a['frames']} frames, "
            f"{1024 * b['solve_traced_peak_mb'] / b['frames']:.0f} KB at {b['frames']} frames (linear in T)."
        )
    if cal:
        print("\n### Calibration column: lengths+camera (10 globals) against motion only\n")
        print("| frames | s / iteration, motion only | s / iteration, calibrated | ratio | solver peak (MB), motion only | "
              "solver peak (MB), calibrated | MPJPE calibrated (mm) |")
        print("|---:|---:|---:|---:|---:|---:|---:|")
        for a, b in zip(rows, cal):
            print(
                f"| {a['frames']} | {a['s_per_iteration']:.3f} | {b['s_per_iteration']:.3f} | "
                f"{b['s_per_iteration'] / a['s_per_iteration']:.2f} | {a['solve_traced_peak_mb']:.0f} | "
                f"{b['solve_traced_peak_mb']:.0f} | {b['mpjpe_mm']:.1f} |"
            )
    return rows


# --------------------------------------------------------------------------- scipy
class ScipyProblem:
    """The same residuals as a function of tangent offsets x from the start Q0 (active
    entries only), for scipy.optimize.least_squares."""

    def __init__(self, setup):
        import pinocchio as pin

        self.pin = pin
        self.setup = setup
        self.prob = setup.problem
        self.fig = self.prob.figure
        self.T, self.nv = self.prob.n_frames, self.prob.nv
        self.mask = np.tile(setup.active, self.T)
        self.n = int(self.mask.sum())
        self.nfev = 0
        blocks = self._blocks(setup.q0, True)
        self.m = sum(b.r.size for b in blocks)
        self.pattern = self._pattern(blocks)

    def Q(self, x):
        dq = np.zeros(self.T * self.nv)
        dq[self.mask] = x
        return self.prob.retract(self.setup.q0, dq.reshape(self.T, self.nv))

    def _blocks(self, Q, jac):
        from pinrecon.solver import _flatten

        return _flatten(self.prob.evaluate(Q, jac))

    def fun(self, x):
        self.nfev += 1
        return np.concatenate([b.r.ravel() for b in self._blocks(self.Q(x), False)])

    def _entries(self, blocks, values):
        rows, cols, vals = [], [], []
        r0 = 0
        nv = self.nv
        for b in blocks:
            N, m = b.r.shape
            c = np.asarray(b.cols)
            for i in range(b.frames.shape[1]):
                base = (b.frames[:, i] * nv)[:, None]
                if b.diagonal:
                    rr = r0 + np.arange(N)[:, None] * m + np.arange(m)[None, :]
                    cc = base + c[None, :]
                    rows.append(rr.ravel())
                    cols.append(cc.ravel())
                    vals.append((b.J[:, i] if values else np.ones((N, m))).ravel())
                else:
                    rr = r0 + np.arange(N)[:, None, None] * m + np.arange(m)[None, :, None]
                    cc = base[:, :, None] + c[None, None, :]
                    rr, cc = np.broadcast_arrays(rr, cc)
                    rows.append(rr.ravel())
                    cols.append(cc.ravel())
                    vals.append((b.J[:, i] if values else np.ones((N, m, len(c)))).ravel())
            r0 += N * m
        return np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)

    def _pattern(self, blocks):
        import scipy.sparse as sp

        r, c, _ = self._entries(blocks, values=False)
        full = sp.csr_matrix((np.ones_like(r, float), (r, c)), shape=(self.m, self.T * self.nv))
        return (full[:, np.where(self.mask)[0]] != 0).astype(np.int8)

    def jac(self, x):
        """Analytic sparse Jacobian w.r.t. x: pinrecon's row Jacobians (w.r.t. the local
        tangent at Q) times d(local tangent)/dx = pin.dIntegrate(q0, dx, ARG1) per frame."""
        import scipy.sparse as sp

        Q = self.Q(x)
        blocks = self._blocks(Q, True)
        r, c, v = self._entries(blocks, values=True)
        J = sp.csr_matrix((v, (r, c)), shape=(self.m, self.T * self.nv))
        dq = np.zeros(self.T * self.nv)
        dq[self.mask] = x
        dq = dq.reshape(self.T, self.nv)
        D = [self.pin.dIntegrate(self.fig.model, self.setup.q0[t], dq[t], self.pin.ARG1) for t in range(self.T)]
        return (J @ sp.block_diag(D, format="csr"))[:, np.where(self.mask)[0]]


def scipy_table(n_frames, analytic=True):
    from scipy.optimize import least_squares

    fig, q, setup, _ = build(n_frames)
    res_d, trace_d = run_pinrecon(setup)  # default termination
    res_d.time = trace_d[-1][0]  # CPU seconds, the clock of every time below
    res_s, trace_s = run_pinrecon(setup, ftol=1e-10, max_iterations=300)  # run on, for the strict comparison
    res_s.time = trace_s[-1][0]
    sp_prob = ScipyProblem(setup)
    x0 = np.zeros(sp_prob.n)
    c0 = 0.5 * float(sp_prob.fun(x0) @ sp_prob.fun(x0))
    runs = [("scipy trf, jac_sparsity (finite differences)", dict(jac="2-point", jac_sparsity=sp_prob.pattern))]
    if analytic:
        runs.append(("scipy trf, pinrecon's analytic sparse Jacobian", dict(jac=sp_prob.jac)))
    results = []
    for name, kw in runs:
        trace = []
        t = time.process_time()

        def cb(intermediate_result):
            trace.append((time.process_time() - t, float(intermediate_result.cost)))

        out = least_squares(sp_prob.fun, x0, method="trf", x_scale="jac", callback=cb, **kw)
        dt = time.process_time() - t
        results.append((name, dt, float(out.cost), out.nfev, out.njev, trace, mpjpe_mm(fig, sp_prob.Q(out.x), q)))

    def first(trace, cost):
        return next((tt for tt, cc, *acc in trace if (not acc or acc[0]) and cc <= cost), None)

    print(
        f"\n### pinrecon against scipy.optimize.least_squares ({n_frames} frames, {sp_prob.n} unknowns, "
        f"{sp_prob.m} residuals; same start, cost {c0:.1f})\n"
    )
    print("| solver | CPU time (s) | final cost | iterations / evaluations | MPJPE (mm) |")
    print("|---|---:|---:|---|---:|")
    print(f"| pinrecon, default termination | {res_d.time:.2f} | {res_d.cost:.2f} | {res_d.iterations} iterations | {mpjpe_mm(fig, res_d.x, q):.1f} |")
    print(f"| pinrecon, run on (ftol 1e-10) | {res_s.time:.2f} | {res_s.cost:.2f} | {res_s.iterations} iterations | {mpjpe_mm(fig, res_s.x, q):.1f} |")
    for name, dt, cost, nfev, njev, trace, err in results:
        print(f"| {name} | {dt:.1f} | {cost:.2f} | {nfev} residual + {njev} Jacobian evaluations | {err:.1f} |")
    print()
    for name, dt, cost, nfev, njev, trace, err in results:
        t_reach = first(trace, res_d.cost)
        if t_reach is not None:
            print(
                f"- {name}: reaches pinrecon's converged cost {res_d.cost:.2f} after {t_reach:.1f} s, "
                f"pinrecon after {res_d.time:.2f} s: **{t_reach / res_d.time:.0f}x**."
            )
        p_reach = first(trace_s, cost)
        if p_reach is not None:
            print(f"  Its own final cost {cost:.2f}: scipy {dt:.1f} s, pinrecon {p_reach:.2f} s ({dt / p_reach:.0f}x).")
        else:
            print(
                f"  Its own final cost {cost:.2f} is {res_s.cost - cost:.2f} below the minimum pinrecon settles in "
                f"({res_s.cost:.2f}): a neighbouring basin of the same reconstruction (MPJPE {err:.1f} vs "
                f"{mpjpe_mm(fig, res_s.x, q):.1f} mm)."
            )


def speed_table(n_frames, repeats=5):
    """Each termination solved ``repeats`` times from the same start: the best and the
    median CPU time of this process (steadier than wall time on a shared machine whose
    speed drifts: quote the median, the best says what the code can do) and the wall time
    of the best run."""
    fig, q, setup, t_build = build(n_frames)
    print(f"\n### Speed: human figure (nv = {fig.nv}), {fig.K} keypoints, {n_frames} frames, all four row kinds\n")
    print(f"Start (keyframe poses solved and interpolated, rows built): {t_build:.2f} s.\n")
    print(f"| termination | solve, CPU (median of {repeats}) | best | wall (best run) | iterations | status | "
          "CPU per iteration (median) | final cost | MPJPE |")
    print("|---|---:|---:|---:|---:|---|---:|---:|---:|")
    for label, ftol, geo in (
        ("default (relative cost decrease below 1e-4, line search)", None, False),
        ("strict (below 1e-6)", 1e-6, False),
        ("default + geodesic acceleration", None, True),
    ):
        runs = []
        for _ in range(repeats):
            c0 = time.process_time()
            res, trace = run_pinrecon(setup, ftol=ftol, geodesic=geo)
            runs.append((time.process_time() - c0, res))
        cpus = np.array([c for c, _ in runs])
        cpu, res = min(runs, key=lambda r: r[0])
        med = float(np.median(cpus))
        print(
            f"| {label} | **{med:.2f} s** | {cpu:.2f} s | {res.time:.2f} s | {res.iterations} | {res.status} | "
            f"{med / res.iterations:.3f} s | {res.cost:.1f} | {mpjpe_mm(fig, res.x, q):.1f} mm |"
        )
    free = build(n_frames, weights_none=True)[2]
    res, _ = run_pinrecon(free)
    print(f"\nWithout the pose prior (`Weights(pose_prior=None)`), default termination: "
          f"{res.iterations} iterations, MPJPE {mpjpe_mm(fig, res.x, q):.1f} mm. (`build_problem` adapts the pose "
          "prior to these dense keyframes' start, as reconstruct does: `pinrecon.prior_yield`.)")


def calibration_speed(n_frames, iterations=10, repeats=11):
    """CPU seconds per iteration with and without the globals, same start, same number
    of iterations (ftol 0: no early stop), ``repeats`` interleaved runs each (CPU time of
    this process): the ratio of each interleaved pair (robust to the machine's drift), its
    median, and the best times."""
    setups = {mode: build(n_frames, calibrate=mode)[2] for mode in ("none", "lengths+camera")}
    per = {mode: [] for mode in setups}
    for _ in range(repeats):
        for mode, setup in setups.items():
            c0 = time.process_time()
            res, _ = run_pinrecon(setup, ftol=0.0, max_iterations=iterations)
            per[mode].append((time.process_time() - c0) / max(res.iterations, 1))
    ratios = np.array(per["lengths+camera"]) / np.array(per["none"])
    print(f"\n### Calibration: cost per iteration ({n_frames} frames, {iterations} iterations from the same start, "
          f"{repeats} interleaved pairs)\n")
    print("| calibrate | globals | CPU s / iteration (median) | best | ratio to motion only (median of pairs) | range |")
    print("|---|---:|---:|---:|---:|---|")
    for mode, setup in setups.items():
        r = np.ones(repeats) if mode == "none" else ratios
        print(f"| {mode} | {setup.problem.n_globals} | {np.median(per[mode]):.3f} | {min(per[mode]):.3f} | "
              f"{np.median(r):.2f} | {r.min():.2f} - {r.max():.2f} |")


def _dance_inputs(folder):
    """The 1123-frame CMU dance 05_02 (its own skeleton, nv = 96) seen orthographically
    45 degrees from side-on: the 22 body joints with 1 px noise and a 30-frame gap, 3D
    point keyframes (2 cm) every 0.25 s. Writes the CLI's input files; returns the
    figure, the true motion and the tracked names."""
    from pinrecon.io.bvh import load_bvh
    from pinrecon.synthetic import body_keypoints, point_keyframes, project_tracks, side_camera

    from pinrecon import datasets

    bvh = datasets.clip("dance")
    m = load_bvh(bvh, 0.056444, skip_frames=1)
    fig, q, fps = m.figure, m.q, m.fps
    names = body_keypoints(fig)
    cam = side_camera(q, 45.0, scale=300.0, center=(640.0, 360.0))
    T = len(q)
    tracks = project_tracks(fig, q, cam, names, fps=fps, noise_px=1.0, gaps=[(T // 2, T // 2 + 30)], seed=0)
    keys = point_keyframes(fig, q, range(0, T, int(round(0.25 * fps))), names, sigma_m=0.02, seed=1)
    tracks.save(os.path.join(folder, "tracks.json"))
    cam.save(os.path.join(folder, "camera.json"))
    keys.save(os.path.join(folder, "keyframes.json"))
    return bvh, fig, q, names


def dance_table(repeats=2):
    """The whole ``pinrecon reconstruct`` run on the dance, imports included, in a fresh
    process each time: CPU seconds of the child (user + sys, best of ``repeats``) and its
    wall time; the mean per-joint error of its result against the clip."""
    import re
    import tempfile

    from pinrecon import load_result

    with tempfile.TemporaryDirectory() as d:
        bvh, fig, q, names = _dance_inputs(d)
        cmd = [sys.executable, "-m", "pinrecon.cli", "reconstruct", "--figure", bvh, "--length-scale", "0.056444",
               "--tracks", os.path.join(d, "tracks.json"), "--camera", os.path.join(d, "camera.json"),
               "--keyframes", os.path.join(d, "keyframes.json"), "--out", os.path.join(d, "result.npz")]
        best = None
        for _ in range(repeats):
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            w0 = time.perf_counter()
            out = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
            wall = time.perf_counter() - w0
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            if out.returncode != 0:
                raise RuntimeError(out.stderr[-2000:])
            cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
            if best is None or cpu < best[0]:
                best = (cpu, wall, out.stderr)
        cpu, wall, log = best
        its = re.search(r"after (\d+) iterations", log)
        res = load_result(os.path.join(d, "result.npz"))
    idx = fig.keypoint_index(names)
    err = 1000 * float(np.linalg.norm(res.keypoints3d[:, idx] - fig.keypoints(q)[:, idx], axis=-1).mean())
    print(f"\n### The CMU dance 05_02: the whole `pinrecon reconstruct` run, imports included (best of {repeats})\n")
    print("| clip | CPU (user + sys) | wall | solver iterations | MPJPE (22 body joints) |")
    print("|---|---:|---:|---:|---:|")
    print(f"| 05_02 dance, {len(q)} frames at 120 fps, nv = {fig.nv}, orthographic 45 deg, 1 px, a 30-frame gap, "
          f"keyframes every 0.25 s | **{cpu:.1f} s** | {wall:.1f} s | {its.group(1) if its else '?'} | {err:.2f} mm |")


def long_child(n_frames, window=2000):
    """Reconstruct ``n_frames`` of the looped human walk with ``pinrecon.reconstruct`` in
    windows of ``window`` frames (what it does by itself past 10000 frames) and print JSON:
    CPU and wall seconds, peak resident memory, windows, MPJPE."""
    from pinrecon.reconstruct import reconstruct
    from pinrecon.synthetic import human_walk, point_keyframes, project_tracks, side_camera

    fig, q = human_walk(n_frames, 30.0)
    cam = side_camera(q, 45.0, scale=300.0, center=(640, 360))
    tracks = project_tracks(fig, q, cam, fps=30.0, noise_px=1.0, seed=1)
    keys = point_keyframes(fig, q, range(0, n_frames, 8), sigma_m=0.02, seed=2)
    c0, w0 = time.process_time(), time.perf_counter()
    res = reconstruct(fig, tracks, cam, keys, window=window)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    err = 1000 * float(np.linalg.norm(res.keypoints3d - fig.keypoints(q), axis=-1).mean())
    print(json.dumps(dict(frames=n_frames, cpu_s=cpu, wall_s=wall, status=res.solve.status,
                          iterations=res.solve.iterations, mpjpe_mm=err,
                          peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)))


def long_table(sizes):
    print("\n### Long clips: `reconstruct(..., window=2000)` of the looped walk (keyframes every 8 frames, the "
          "start included), a fresh process each\n")
    print("| frames | solve | CPU (s) | wall (s) | CPU per 1000 frames (s) | peak RSS (MB) | iterations | MPJPE (mm) |")
    print("|---:|---|---:|---:|---:|---:|---:|---:|", flush=True)
    for n in sizes:
        out = subprocess.run([sys.executable, __file__, "--long-child", str(n)], capture_output=True, text=True,
                             env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
        if out.returncode != 0:
            raise RuntimeError(out.stderr[-2000:])
        r = json.loads(out.stdout.strip().splitlines()[-1])
        how = r["status"].split(":")[0] if r["status"].startswith("windowed") else "batch"
        print(f"| {r['frames']} | {how} | {r['cpu_s']:.1f} | {r['wall_s']:.1f} | {1000 * r['cpu_s'] / r['frames']:.2f} | "
              f"{r['peak_rss_mb']:.0f} | {r['iterations']} | {r['mpjpe_mm']:.1f} |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--scipy-frames", type=int, default=1000)
    ap.add_argument("--memory-sizes", type=int, nargs="*", default=[100, 1000, 10000])
    ap.add_argument("--skip-scipy", action="store_true")
    ap.add_argument("--skip-memory", action="store_true")
    ap.add_argument("--no-analytic", action="store_true", help="skip scipy with the analytic Jacobian")
    ap.add_argument("--skip-calibration", action="store_true", help="skip the calibration rows and columns")
    ap.add_argument("--skip-speed", action="store_true", help="skip table 1")
    ap.add_argument("--calibration-pairs", type=int, default=11,
                    help="interleaved motion-only / calibrated runs for the per-iteration ratio (table 4)")
    ap.add_argument("--skip-dance", action="store_true", help="skip the CMU dance CLI run")
    ap.add_argument("--long-sizes", type=int, nargs="*", default=[10000, 100000],
                    help="frames of the long-clip rows (100000 takes several minutes)")
    ap.add_argument("--memory-child", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--child-calibrate", default="none", help=argparse.SUPPRESS)
    ap.add_argument("--long-child", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.memory_child:
        memory_child(args.memory_child, args.child_calibrate)
        return
    if args.long_child:
        long_child(args.long_child)
        return
    import platform

    from provenance import provenance

    print(provenance())
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}")
    if not args.skip_speed:
        speed_table(args.frames)
    if not args.skip_calibration:
        calibration_speed(args.frames, repeats=args.calibration_pairs)
    if not args.skip_memory:
        memory_table(args.memory_sizes, calibration=not args.skip_calibration)
    if not args.skip_scipy:
        scipy_table(args.scipy_frames, analytic=not args.no_analytic)
    if not args.skip_dance:
        dance_table()
    if args.long_sizes:
        long_table(args.long_sizes)


if __name__ == "__main__":
    main()
