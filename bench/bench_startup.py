"""The command line's start-up: from launching ``pinrecon reconstruct`` to its first stage
(issue 43's target: under 1.5 s on this 2-core machine).

A tracks file (the bundled walk's 12 COCO-17 points seen by a perspective camera, 100
frames, no faults) is written to a temporary folder; ``pinrecon reconstruct
--figure human --tracks FILE --camera auto --image-size 1920 1080`` is launched ``--runs``
times (the console script ``pip`` installs), and the wall time from the launch to the first ``pinrecon: stage`` line on its
standard error is taken (Python's own start, the imports, the figure and the tracks read, the
problem made). Beside it, ``python -c "import pinrecon"`` and ``python -c pass`` the same way.
The median and the fastest run are printed.

    OMP_NUM_THREADS=1 python bench/bench_startup.py
"""

from __future__ import annotations

import quick

QUICK = quick.take(["--runs", "1"], cut=False)

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pinrecon as pr
from pinrecon.synthetic import bundled_motion, coco_body_tracks, perspective_side_camera


def until_first_stage(cmd: list[str]) -> float:
    """Seconds from launching ``cmd`` to its first ``pinrecon: stage`` line (the process is
    stopped there)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    try:
        for line in proc.stderr:
            if line.startswith("pinrecon: stage "):
                return time.perf_counter() - t0
    finally:
        proc.kill()
        proc.wait()
    raise RuntimeError(f"no stage line from {' '.join(cmd)}")


def whole(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=7)
    a = ap.parse_args(argv)
    from provenance import provenance

    print(provenance())
    print("command: OMP_NUM_THREADS=1 python bench/bench_startup.py" + (" --quick" if QUICK else ""))
    fig, q, fps = bundled_motion("walk")
    q = q[:100]
    tracks, _ = coco_body_tracks(fig, q, perspective_side_camera(q, 45.0), fps=fps)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "tracks.json"
        tracks.save(path)
        exe = shutil.which("pinrecon", path=str(Path(sys.executable).parent)) or shutil.which("pinrecon")
        cli = [exe, "reconstruct", "--figure", "human", "--tracks", str(path),
               "--camera", "auto", "--image-size", "1920", "1080", "--out", str(Path(d) / "r.npz")]
        rows = [("`pinrecon reconstruct` to its first stage", [until_first_stage(cli) for _ in range(a.runs)]),
                ('`python -c "import pinrecon"`', [whole([sys.executable, "-c", "import pinrecon"])
                                                   for _ in range(a.runs)]),
                ("`python -c pass`", [whole([sys.executable, "-c", "pass"]) for _ in range(a.runs)])]
    print(f"\n{a.runs} runs each, wall clock (pinrecon {pr.__version__})\n")
    print("| what | median (s) | fastest (s) |")
    print("|---|---:|---:|")
    for name, t in rows:
        print(f"| {name} | {statistics.median(t):.2f} | {min(t):.2f} |")
    print(f"\ntarget (issue 43): the command's start-up under 1.5 s: "
          f"{'met' if statistics.median(rows[0][1]) < 1.5 else 'NOT met'}")


if __name__ == "__main__":
    main()
