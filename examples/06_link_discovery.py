"""Link discovery from 2D tracks alone (Hoffman & Flinchbaugh 1982), on a real walk.

No figure is needed: if two rods joined at a hinge turn in one plane, the hinge is the
point that makes the three tracks a rigid planar structure, and the fit gives both rod
lengths (and the plane, up to its reflection). Here the hip, knee and ankle tracks of
each leg of the bundled CMU walk (orthographic camera 45 degrees from side-on, 300 px/m,
1 px noise) are tested with each point as the hinge (``discover_links``); the knee should
win, and the fitted thigh and shank lengths are compared with the clip's. Then
``links_report`` lists the hinges and links it finds among all six leg points (also
written to ``links_report.txt`` in the output folder).

Real legs are only roughly planar (hip ab/adduction, axial rotation), so a model
tolerance of 3.5 % of the rod length is accepted (``DEFAULT_MODEL_TOL``). Over the short
arcs of a walk some long "rods" that are not limbs pass too (e.g. left knee to right
hip): read the report's shortest rods, as real limbs join near neighbours.

    PYTHONPATH=src python examples/06_link_discovery.py [--out DIR] [--quick]

``--quick`` uses the first second of the walk (one stride).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import pinrecon as pr
from pinrecon.planarity import discover_links, links_report
from pinrecon.synthetic import bundled_motion, project_tracks

JOINTS = ("UpLeg", "Leg", "Foot")  # CMU names of the hip, knee and ankle keypoints
LABELS = ("hip", "knee", "ankle")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="examples_out/06", help="folder for links_report.txt")
    ap.add_argument("--quick", action="store_true", help="first second of the walk only")
    args = ap.parse_args(argv)

    figure, q, fps = bundled_motion("walk")
    if args.quick:
        q = q[: round(fps)]
    az = np.radians(45.0)
    camera = pr.Orthographic.from_view([np.cos(az), 0, np.sin(az)], scale=300.0, center=(500.0, 500.0))
    legs = [side + j for side in ("Left", "Right") for j in JOINTS]
    tracks = project_tracks(figure, q, camera, legs, fps=fps, noise_px=1.0, seed=0)
    P = figure.keypoints(q[:1])[0]
    print(f"walk: {len(q)} frames at {fps:.0f} fps; score = fit rms / threshold (<= 1: planar)\n")

    for side in ("Left", "Right"):
        names = [side + j for j in JOINTS]
        uv = tracks.select(names).points
        graph = discover_links(uv, names=LABELS)
        scores = ", ".join(f"{n} {f.score:.2f}" for n, f in zip(LABELS, graph.candidates))
        hinge = "none" if graph.hinge is None else LABELS[graph.hinge]
        print(f"{side.lower()} leg: hinge = {hinge} (scores with each point as the hinge: {scores})")
        if graph.hinge == 1:
            thigh_m, shank_m = graph.candidates[1].lengths / camera.scale  # knee-hip, knee-ankle
            hip, knee, ankle = figure.keypoint_index(names)
            for label, fit_m, a, b in (("thigh", thigh_m, hip, knee), ("shank", shank_m, knee, ankle)):
                true_m = np.linalg.norm(P[a] - P[b])
                pct = 100 * (fit_m / true_m - 1)
                print(f"  {label}: {fit_m:.3f} m, clip {true_m:.3f} m ({pct:+.1f} %)")
            print(f"  plane tilt from the image: {graph.candidates[1].tilt_deg:.0f} deg")

    report = links_report(tracks, scale=camera.scale)
    print("\n" + report)
    path = Path(args.out) / "links_report.txt"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(report + "\n")
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
