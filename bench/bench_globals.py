"""Cost of global unknowns in the solver: segment proportions and the focal length.

The problem: the example-robot-data human figure (nv = 42) with COCO-17 keypoints in a
smooth synthetic motion in place (`pinrecon.synthetic.smooth_motion`), 30 fps, seen by a
perspective camera with 1 px noise, with 2D measurements, joint-limit barriers,
constant-velocity smoothing, the posture prior and 3D point keyframes (2 cm) every 8
frames. Calibration adds 10 globals: the 9 human proportion groups COCO-17 sees
(`Proportions.human`) and the log focal length, with a 10 % prior on the factors.

1. Per-iteration cost, 1000 frames: the solver's own time per iteration over the same
   number of iterations from the same start, with and without the globals, and the
   cost of one linearisation (evaluate with Jacobians + assemble the normal equations)
   and of one damped factor-and-solve (band alone vs band + Schur complement).
2. Time and memory against the number of frames (100 / 1000 / 10000): each in a fresh
   process, CPU seconds per iteration and the solver's peak allocation (tracemalloc).

Run: ``OPENBLAS_NUM_THREADS=1 python bench/bench_globals.py`` (about 2 minutes;
``--skip-scaling`` for part 1 only). Prints markdown tables.
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take(["--frames", "100", "--skip-scaling"], cut=False)

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


class Problem:
    """Rows on a time grid; with ``proportions`` the figure's log factors are globals."""

    def __init__(self, figure, n_frames, rows, proportions=None):
        self.figure, self.n_frames, self.nv, self.rows = figure, n_frames, figure.nv, rows
        self.proportions = proportions
        self.kinematic_frames = np.unique(np.concatenate([np.asarray(r.kinematic_frames, int) for r in rows]))

    def evaluate(self, Q, jacobian=True, g=None):
        from pinrecon.rows import State

        props = self.proportions if g is not None else None
        st = State(self.figure, Q, self.kinematic_frames, jacobian, g=g, proportions=props)
        return [r.evaluate(st, jacobian) for r in self.rows]

    def retract(self, Q, dQ):
        return self.figure.integrate(Q, dQ)


def build(n_frames, calibrate, seed=0):
    import pinrecon as pr
    from pinrecon.rows import CameraScale
    from pinrecon.proportions import Proportions
    from pinrecon.rows import GlobalPrior, JointLimits, Measurement2D, Points3D, Posture, Smoothing, smoothing_sigmas
    from pinrecon.synthetic import smooth_motion

    fig = pr.Figure.human()
    T = n_frames
    Q = smooth_motion(fig, T, 30.0, seed=seed + 1, speed_mps=0.0)  # in place, always in view
    cam = pr.Perspective.look_at([2.5, 1.2, 4.0], [1.0, 0.0, 0.0], f_px=1000.0)
    rng = np.random.default_rng(seed + 2)
    P = fig.keypoints(Q)
    uv = cam.project(P) + rng.normal(0.0, 1.0, P.shape[:2] + (2,))
    k = np.arange(fig.K)
    kf = np.arange(0, T, 8)
    props = Proportions.human(fig) if calibrate else None
    intr = CameraScale(cam, col=props.n) if calibrate else None
    rows = [
        Measurement2D(cam, np.arange(T), k, uv, np.ones((T, fig.K)), sigma_px=2.0, intrinsics=intr),
        JointLimits(fig, T, 0.01),
        Smoothing(fig, T, 1 / 30, smoothing_sigmas(fig)),
        Posture(fig, T, fig.neutral(), 3.0),
        Points3D(kf, k, P[kf] + rng.normal(0.0, 0.02, P[kf].shape), 0.02),
    ]
    g0 = None
    if calibrate:
        rows.append(GlobalPrior(np.arange(props.n), 0.0, 0.1))
        g0 = np.zeros(props.n + 1)
    Q0 = np.stack([fig.integrate(q, 0.05 * rng.normal(size=fig.nv)) for q in Q])
    return Problem(fig, T, rows, props), Q0, g0


def one_linearisation(problem, Q0, g0):
    """CPU seconds: evaluate+assemble, and damped factor+solve, once."""
    from pinrecon.solver import ArrowheadFactor, BandedNormalEquations

    t = time.process_time()
    out = problem.evaluate(Q0, True) if g0 is None else problem.evaluate(Q0, True, g0)
    blocks = [b for item in out for b in (item if isinstance(item, list) else [item])]
    ne = BandedNormalEquations(problem.n_frames, problem.nv, blocks)
    D0, Dd, g = ne.assemble(blocks)
    border = ne.assemble_globals(blocks, len(g0)) if g0 is not None else None
    ab = ne.band(D0, Dd)
    t_lin = time.process_time() - t
    t = time.process_time()
    ab[0] *= 1.001
    if border is None:
        ArrowheadFactor(ab).solve(-g)
    else:
        B, C, gg = border
        ArrowheadFactor(ab, B, C + 1e-3 * np.diag(np.diag(C))).solve(-g, -gg)
    return t_lin, time.process_time() - t


def per_iteration(n_frames=1000, iterations=8, repeats=4):
    """Both modes measured alternately, ``repeats`` times, best kept. CPU time of this
    process (``time.process_time``), not wall time: the machine these numbers come from is
    shared, and wall time there swung by a factor of two between identical runs."""
    from pinrecon.solver import SolverOptions, solve

    setups = {cal: build(n_frames, cal) for cal in (False, True)}
    out = {cal: dict(s_it=np.inf, lin=np.inf, fac=np.inf) for cal in (False, True)}
    for _ in range(repeats):
        for cal, (prob, Q0, g0) in setups.items():
            for _ in range(2):
                lin, fac = one_linearisation(prob, Q0, g0)
                out[cal]["lin"], out[cal]["fac"] = min(out[cal]["lin"], lin), min(out[cal]["fac"], fac)
            t = time.process_time()
            res = solve(prob, Q0, SolverOptions(max_iterations=iterations, ftol=0.0), g0=g0)
            out[cal]["s_it"] = min(out[cal]["s_it"], (time.process_time() - t) / max(res.iterations, 1))
            out[cal]["its"] = res.iterations
            out[cal]["accepted"] = sum(r.accepted for r in res.report)
    a, b = out[False], out[True]
    print(f"\n### Per-iteration cost, {n_frames} frames, human (nv = 42), 10 globals vs none\n")
    print(f"CPU time, best of {repeats} alternating runs.\n")
    print("| | motion only | + 10 globals | ratio |")
    print("|---|---:|---:|---:|")
    print(f"| solver, per iteration (s), {a['its']} iterations | {a['s_it']:.3f} ({a['accepted']} accepted) | "
          f"{b['s_it']:.3f} ({b['accepted']} accepted) | {b['s_it'] / a['s_it']:.2f} |")
    print(f"| evaluate + assemble (s) | {a['lin']:.3f} | {b['lin']:.3f} | {b['lin'] / a['lin']:.2f} |")
    print(f"| damped factor + solve (s) | {a['fac']:.3f} | {b['fac']:.3f} | {b['fac'] / a['fac']:.2f} |")
    tot_a, tot_b = a["lin"] + a["fac"], b["lin"] + b["fac"]
    print(f"| one linearisation + step (s) | {tot_a:.3f} | {tot_b:.3f} | {tot_b / tot_a:.2f} |")
    return out


def scaling_child(n_frames, calibrate, iterations):
    import tracemalloc

    from pinrecon.solver import SolverOptions, solve

    prob, Q0, g0 = build(n_frames, calibrate)
    t = time.process_time()
    res = solve(prob, Q0, SolverOptions(max_iterations=iterations, ftol=0.0), g0=g0)
    cpu = time.process_time() - t
    tracemalloc.start()
    solve(prob, Q0, SolverOptions(max_iterations=2, ftol=0.0), g0=g0)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(json.dumps(dict(frames=n_frames, calibrate=calibrate, s_it=cpu / max(res.iterations, 1),
                          its=res.iterations, peak_mb=peak / 2**20)))


def scaling(sizes, iterations=3):
    rows = []
    for n in sizes:
        for calibrate in (False, True):
            cmd = [sys.executable, __file__, "--child", str(n), str(int(calibrate)), str(iterations)]
            out = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
            if out.returncode != 0:
                raise RuntimeError(out.stderr[-2000:])
            rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
    print("\n### Time and memory against the number of frames\n")
    print("CPU time; each size in a fresh process.\n")
    print("| frames | globals | s / iteration | s / iteration / 1000 frames | solver peak allocation (MB) | KB / frame |")
    print("|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['frames']} | {10 if r['calibrate'] else 0} | {r['s_it']:.3f} | {1000 * r['s_it'] / r['frames']:.3f} | "
              f"{r['peak_mb']:.1f} | {1024 * r['peak_mb'] / r['frames']:.0f} |")
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--child", nargs=3, type=int, help=argparse.SUPPRESS)
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--skip-scaling", action="store_true")
    args = ap.parse_args()
    if args.child:
        scaling_child(args.child[0], bool(args.child[1]), args.child[2])
        return
    per_iteration(args.frames)
    if not args.skip_scaling:
        scaling([100, 1000, 10000])


if __name__ == "__main__":
    main()
