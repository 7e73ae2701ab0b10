"""The reflective ambiguity of one link, and what each constraint does to it.

DiFranco, Cham & Rehg (2001), figures 2 to 5. A rod of 0.5 m turns about a vertical
hinge; an orthographic camera looks along the depth axis, so the tip's image is the same
for the angle +t (pose B, the truth) and -t (pose A, its mirror image in depth). From the
2D data alone the start decides the answer. Each of the paper's constraints selects B:

* a joint limit that forbids A's side (figure 3), even from a start at A;
* smoothing over neighbouring frames whose poses are known (figure 4), from a start
  just on A's side of the fold;
* a keyframe near B (figure 5). An approximate keyframe (0.15 rad off, standard deviation
  0.3 rad) works through the start: by default the keyed pose is where the solve begins.
  A weak keyframe row alone cannot pull a start at A over the fold; a confident one can.

Prints a table (start, angle found, pose A or B) and draws each case seen from above.

    PYTHONPATH=src python examples/01_reflective_ambiguity.py [--out DIR] [--quick]
"""

from __future__ import annotations

import argparse
import textwrap
from pathlib import Path

import numpy as np

import pinrecon as pr
from pinrecon.tracks import Keyframe, Keyframes

ROD_M, THETA_B = 0.5, 0.9  # rod length, true hinge angle (pose B); pose A is -THETA_B
CAMERA = pr.Orthographic.from_view([0, 0, 1], scale=400.0, center=(320.0, 240.0))


def rod(lower=-3.1, upper=3.1):
    """A fixed base and one revolute link about world +y, with a keypoint at its tip."""
    urdf = f"""<robot name="rod"><link name="base"/><link name="rod"/>
      <joint name="hinge" type="revolute"><parent link="base"/><child link="rod"/>
        <axis xyz="0 1 0"/><limit lower="{lower}" upper="{upper}" effort="0" velocity="0"/>
      </joint></robot>"""
    tip = pr.Keypoint("tip", "rod", (ROD_M, 0.0, 0.0))
    return pr.Figure.from_urdf_string(urdf, [tip], root="fixed")


def tracks(thetas):
    """2D tracks of the tip (exact): the tip at angle t is (L cos t, 0, -L sin t)."""
    t = np.asarray(thetas, float)
    tip = np.stack([ROD_M * np.cos(t), 0 * t, -ROD_M * np.sin(t)], -1)
    return pr.Tracks(CAMERA.project(tip)[:, None], ["tip"], fps=30.0)


def solve(figure, thetas, start, keyframes=None, weights=None):
    init = None if start is None else np.asarray(start, float)[:, None]
    return pr.reconstruct(figure, tracks(thetas), CAMERA, keyframes, init=init, weights=weights)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="examples_out/01", help="folder for the picture")
    ap.add_argument("--quick", action="store_true", help="(this example is always quick)")
    args = ap.parse_args(argv)

    # Figure 4: the neighbours (frames 0 and 2) are keyed near B; frame 1 starts at the fold,
    # just on A's side. The constant-velocity prior carries it over to B.
    truth3 = THETA_B + np.array([-0.05, 0.0, 0.05])
    neighbours = Keyframes([Keyframe(f, 0.01, joints={"hinge": truth3[f]}) for f in (0, 2)])
    start3 = [truth3[0], -0.05, truth3[2]]
    smooth, loose = (pr.Weights(acc_joints=a, sigma_posture=None) for a in (1.0, 1e6))
    # Figure 5: an approximate keyframe 0.15 rad off B (sd 0.3 rad); a confident one (0.02 rad)
    approx_key = Keyframes([Keyframe(0, 0.3, joints={"hinge": THETA_B + 0.15})])
    sure_key = Keyframes([Keyframe(0, 0.02, joints={"hinge": THETA_B + 0.05})])

    cases = [  # label, figure, true angles, start (None: the keyed pose), keyframes, weights, frame
        ("no constraint, start near B", rod(), [THETA_B], [0.3], None, None, 0),
        ("no constraint, start near A", rod(), [THETA_B], [-0.3], None, None, 0),
        ("joint limit [0, 3.1], start at A", rod(0.0, 3.1), [THETA_B], [-THETA_B], None, None, 0),
        ("neighbours keyed, no smoothing", rod(), truth3, start3, neighbours, loose, 1),
        ("smoothing over neighbours", rod(), truth3, start3, neighbours, smooth, 1),
        ("approximate keyframe near B", rod(), [THETA_B], None, approx_key, None, 0),
        ("confident keyframe, start at A", rod(), [THETA_B], [-THETA_B], sure_key, None, 0),
    ]
    print(f"pose B = {THETA_B:+.3f} rad (truth), pose A = {-THETA_B:+.3f} rad: same image\n")
    print(f"{'case':32s} {'start':>7s} {'found':>7s}  pose")
    found = []
    for label, fig, thetas, start, keys, weights, f in cases:
        theta = solve(fig, thetas, start, keys, weights).q[f, 0]
        pose = "B" if abs(theta - thetas[f]) < 0.05 else "A" if abs(theta + thetas[f]) < 0.05 else "?"
        s0 = None if start is None else start[f]
        s0_text = "keyed" if s0 is None else f"{s0:+.3f}"
        print(f"{label:32s} {s0_text:>7s} {theta:+7.3f}  {pose}")
        found.append((label, s0, theta))

    try:
        from matplotlib.figure import Figure
    except ImportError as exc:  # matplotlib is the optional "viz" extra
        print(f"\nno picture: {exc}")
        return
    fig = Figure(figsize=(1.5 * len(found), 2.9), layout="constrained")
    for ax, (label, start, theta) in zip(fig.subplots(1, len(found)), found):
        # x right, distance towards the camera up: the tip at angle t is at (L cos t, L sin t)
        if start is not None:
            ax.plot([0, ROD_M * np.cos(start)], [0, ROD_M * np.sin(start)], ":", c="grey", label="start")
        ax.plot([0, ROD_M * np.cos(theta)], [0, ROD_M * np.sin(theta)], "-o", c="C0", label="found")
        ax.plot([ROD_M * np.cos(THETA_B)] * 2, [-0.55, 0.55], "--", c="C3", lw=0.8, label="image ray")
        ax.set(xlim=(-0.1, 0.6), ylim=(-0.6, 0.6), aspect="equal", xticks=[], yticks=[])
        ax.set_title(textwrap.fill(label, 20), fontsize=7)
    fig.axes[0].legend(fontsize=6, loc="lower left")
    fig.suptitle("seen from above; the camera, at the top, sees x only", size=8)
    path = Path(args.out) / "reflective_ambiguity.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
