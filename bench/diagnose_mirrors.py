"""Every candidate of the mirror stage on one bench_real case, against the truth.

For one clip, view angle and keyframe setting of ``bench_real.py`` (12 COCO-17 points with
detector faults, the generic human, the auto start), this runs ``pinrecon.reconstruct`` with
the mirror stage observed (``mirror_stage(observe=)``) and prints, for every candidate it
tried: the limb chain, the mode, the frames, the nats it saved (negative: it cost more), whether
it ended turned over and whether it was kept, and its chain's flipped segment-frames in its span
against the clip, before and after (of those counted: the true depth over 10 % of the length).
With ``--terms``, the candidate's cost minus the state it was tried on, row by row (measurement,
posture, smoothing, ...). It is how bench/README.md's "Mirrored limb spans" measurements were
made: a candidate that turns the flips back but costs more is the MAP cost's preference, not
the search's miss. The stage runs where the broader pose prior is in use (the dance)::

    python bench/diagnose_mirrors.py --clip spin --keyframes first+last --angle 60 --terms
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take(["--clip", "walk"])

import argparse
import importlib
import time
import warnings
from itertools import pairwise

import numpy as np
from bench_real import SEGMENTS, detector_case, score

import pinrecon as pr
from pinrecon import metrics
from pinrecon.solver import globals_of
from pinrecon.starts.mirrors import mirror_stage


def _row_costs(problem, x, g) -> dict:
    """Half the squared residuals of every row of ``problem`` at ``x`` and globals ``g``, by row name."""
    out: dict = {}
    for blocks in problem.evaluate(x, False, g):
        for b in blocks if isinstance(blocks, (list, tuple)) else [blocks]:
            if b is not None and np.asarray(b.r).size:
                out[b.name] = out.get(b.name, 0.0) + 0.5 * float(np.sum(np.asarray(b.r) ** 2))
    return out


def diagnose(clip: str, keyframes: str, angle: float, terms: bool = False) -> None:
    tracks, cam, keys, P, _ = detector_case(clip, angle, keyframes, None, seed=int(angle))
    names = list(tracks.names)
    rows = []

    def staged(problem, res, options=None, callback=None, **kw):
        fig = problem.figure
        kp = fig.keypoint_index(names)

        def flips(x, g, chain, a, b):
            K = problem.keypoints(fig.normalize(x), g)[a:b][:, kp]
            pts = chain.split("-")
            segs = [(names.index(p), names.index(q)) for p, q in pairwise(pts)]
            f, c = metrics.flipped_segments(K, P[a:b], problem.cameras_at(g)[0], segs)
            return int(f.sum()), int(c.sum())

        def observe(m, current, cand):
            g = globals_of(current)
            row = [m.chain, m.mode, f"{m.first}-{m.last - 1}", f"{m.gain:.1f}", "yes" if m.turned else "no",
                   "yes" if m.kept else "no", "{} / {}".format(*flips(current.x, g, m.chain, m.first, m.last)),
                   "{} / {}".format(*flips(cand.x, g, m.chain, m.first, m.last))]
            if terms:
                c0, c1 = _row_costs(problem, current.x, g), _row_costs(problem, cand.x, g)
                row.append(", ".join(f"{k} {c1.get(k, 0.0) - c0.get(k, 0.0):+.1f}" for k in sorted(set(c0) | set(c1))
                                     if abs(c1.get(k, 0.0) - c0.get(k, 0.0)) >= 0.05))
            rows.append(row)

        return mirror_stage(problem, res, options, callback, observe=observe, **kw)

    # the one place the pipeline calls the stage (pinrecon.stages), observed for this run only
    stages_module = importlib.import_module("pinrecon.stages")
    original = stages_module.mirror_stage
    stages_module.mirror_stage = staged
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0 = time.perf_counter()
            res = pr.reconstruct(pr.Figure.human(), tracks, cam, keys, seed="auto")
            dt = time.perf_counter() - t0
    finally:
        stages_module.mirror_stage = original
    s = score(res.keypoints3d[:, res.figure.keypoint_index(names)], P, cam, names)
    print(f"{clip}, keyframes {keyframes}, {angle:g} degrees: PA-MPJPE {s['pa']:.1f} mm, flips {s['flips']:.1f} %, "
          f"{dt:.0f} s; {len(rows)} candidates (segments {', '.join(f'{a}-{b}' for a, b in SEGMENTS)})")
    if not rows:
        print("the mirror stage did not run (the default pose prior was kept) or found no span")
        return
    head = ["chain", "mode", "frames", "nats saved", "turned", "kept", "flipped before", "flipped after"]
    head += ["cost by row, candidate minus current (nats)"] if terms else []
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for row in rows:
        print("| " + " | ".join(row) + " |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clip", default="spin", help="bench_real's clip (walk, run, spin)")
    ap.add_argument("--keyframes", default="first+last", help="first+last, none, or N")
    ap.add_argument("--angle", type=float, default=45.0, help="view angle from side-on, degrees")
    ap.add_argument("--terms", action="store_true", help="each candidate's cost change row by row")
    a = ap.parse_args(argv)
    diagnose(a.clip, a.keyframes, a.angle, a.terms)


if __name__ == "__main__":
    main()
