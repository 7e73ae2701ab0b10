"""``pinrecon batch`` on 40 clips: killed part-way and run again, it loses nothing and
repeats nothing; clips per minute with 1 and 2 workers, and each worker's peak memory.

The clips: synthetic COCO-17 tracks (2 px noise) of the bench's CMU clips (walk, run, spin,
dance), 10 cuts of each varied in start, length (20-40 frames), rate (60 or 40 fps), camera
angle (30-70 degrees from side-on) and noise seed, one camera file per clip named in a CSV
manifest. Every clip is solved the quick way (``--seed rest --floor none --max-iterations
15``: this bench measures the batch, not the solve) without stick strips.

1. Each clip through a single ``pinrecon reconstruct`` (this process): the reference.
2. ``pinrecon batch manifest.csv --jobs 2`` as a subprocess, killed (SIGKILL, its whole process
   group) once ``--kill-after`` clips are done, then run again to the end: every clip's
   result.npz exists once (no half-written files left), equals the reference bit for bit, and
   summary.csv lists all 40, each run once (``ran``).
3. The same with ``--scheduler local-dask``.
4. Clean runs with ``--jobs 1`` and ``--jobs 2`` (and local-dask with 2 workers): clips per
   minute (wall time of the whole command, start-up included), and each worker's peak resident
   memory (``worker_peak_mb`` of summary.csv: ``getrusage`` in the worker process; with
   ``--jobs 1`` the clips run in the batch process itself).

    nice python bench/bench_batch.py                      # about 5 minutes on 2 busy cores
    python bench/bench_batch.py --clips 8 --kill-after 3  # a quick look
"""

from __future__ import annotations

import quick  # noqa: E402 - bench/quick.py: --quick, applied before pinrecon is imported

QUICK = quick.take(["--clips", "4", "--kill-after", "2"], cut=False)

import argparse
import csv
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
from provenance import provenance

from pinrecon.cli import main as pinrecon_main
from pinrecon.synthetic import bundled_motion, coco_body_tracks, perspective_side_camera

SOLVE = ["--figure", "human", "--seed", "rest", "--floor", "none", "--max-iterations", "15"]
MOTIONS = ("walk", "run", "spin", "dance")


def make_clips(root: Path, n: int, seed: int = 0) -> Path:
    """``n`` clips (tracks + camera) under ``root`` and their manifest; returns its path."""
    rng = np.random.default_rng(seed)
    motions = {m: bundled_motion(m) for m in MOTIONS}
    rows = []
    for i in range(n):
        name = MOTIONS[i % len(MOTIONS)]
        fig, q, fps = motions[name]
        step = int(rng.choice([2, 3]))
        length = int(rng.integers(20, 41))
        start = int(rng.integers(0, len(q) - step * length))
        qc = q[start:start + step * length:step]
        cam = perspective_side_camera(qc, float(rng.uniform(30, 70)), distance_m=6.0, f_px=1100.0,
                                      center=(640.0, 360.0))
        tracks, _ = coco_body_tracks(fig, qc, cam, fps=fps / step, noise_px=2.0, seed=i)
        clip = f"{name}_{i:02d}"
        tracks.save(root / f"{clip}.json")
        cam.save(root / f"{clip}.camera.json")
        rows.append((f"{clip}.json", clip, f"{clip}.camera.json"))
    manifest = root / "manifest.csv"
    with open(manifest, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["input", "name", "camera"])
        w.writerows(rows)
    return manifest


def load_npz(path) -> dict:
    """A result NPZ's arrays; the stage reports without their wall-clock seconds, and without
    the run's wall time (``run_time_s``): what differs from run to run."""
    with np.load(path) as d:
        out = {k: d[k] for k in d.files if k != "run_time_s"}  # the whole run's wall time, as the seconds
    if "stages" in out:
        stages = [{k: v for k, v in st.items() if k != "seconds"} for st in json.loads(str(out["stages"]))]
        out["stages"] = np.array(json.dumps(stages))
    return out


def references(root: Path, manifest: Path) -> dict:
    out = root / "reference"
    ref = {}
    with open(manifest, newline="") as f:
        for r in csv.DictReader(f):
            path = out / f"{r['name']}.npz"
            assert pinrecon_main(["reconstruct", "--tracks", str(root / r["input"]), "--camera",
                                  str(root / r["camera"]), "--out", str(path), "--quiet", *SOLVE]) == 0
            ref[r["name"]] = load_npz(path)
    return ref


def batch_cmd(manifest: Path, out: Path, jobs: int, dask: bool) -> list[str]:
    cmd = [sys.executable, "-m", "pinrecon.cli", "batch", str(manifest), "--out", str(out), "--jobs", str(jobs),
           "--no-pictures", "--quiet", *SOLVE]
    return cmd + (["--scheduler", "local-dask"] if dask else [])


def run(cmd, kill_after: int | None = None, out: Path | None = None) -> tuple[float, int]:
    """Run ``cmd``; with ``kill_after``, SIGKILL its process group once that many clips of
    ``out`` are done. Returns (seconds, clips done when killed or at the end)."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if kill_after is None:
        _, err = p.communicate()
        if p.returncode != 0:
            sys.exit(f"batch failed ({p.returncode}):\n{err}")
        return time.perf_counter() - t0, len(list(out.glob("*/done.json")))
    while p.poll() is None and len(list(out.glob("*/done.json"))) < kill_after:
        time.sleep(0.2)
    os.killpg(p.pid, signal.SIGKILL)
    p.wait()
    return time.perf_counter() - t0, len(list(out.glob("*/done.json")))


def check(out: Path, ref: dict) -> tuple[int, int, int]:
    """(clips equal to their reference, rows in summary.csv, leftover temporary files)."""
    same = 0
    for name, r in ref.items():
        results = list((out / name).glob("*.npz"))
        if len(results) != 1:
            continue
        b = load_npz(results[0])
        same += r.keys() == b.keys() and all(np.array_equal(r[k], b[k], equal_nan=r[k].dtype.kind == "f") for k in r)
    with open(out / "summary.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["status"] == "ok"]
    return same, len(rows), len(list(out.glob("*/.*.tmp*")))


def summary_rows(out: Path) -> list[dict]:
    with open(out / "summary.csv", newline="") as f:
        return list(csv.DictReader(f))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clips", type=int, default=40)
    ap.add_argument("--kill-after", type=int, default=15, help="clips done before the kill")
    ap.add_argument("--work", help="folder for the clips and outputs (default: a temporary one)")
    args = ap.parse_args()
    root = Path(args.work or tempfile.mkdtemp(prefix="bench_batch_"))
    root.mkdir(parents=True, exist_ok=True)
    print(provenance())
    print("command: python bench/bench_batch.py " + " ".join(sys.argv[1:]))
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the start; clips solved with: "
          f"{' '.join(SOLVE)}; work folder {root}")
    manifest = make_clips(root, args.clips)
    t0 = time.perf_counter()
    ref = references(root, manifest)
    print(f"{args.clips} clips of {', '.join(MOTIONS)}; single reconstructs in this process: "
          f"{time.perf_counter() - t0:.0f} s")

    print("\n| run | killed after (clips done) | clips equal to a single reconstruct | rows in summary.csv | "
          "run once | temporary files left |")
    print("|---|---:|---:|---:|---:|---:|")
    for label, dask in (("--jobs 2", False), ("--scheduler local-dask --jobs 2", True)):
        out = root / ("killed_dask" if dask else "killed_pool")
        cmd = batch_cmd(manifest, out, 2, dask)
        _, done_at_kill = run(cmd, kill_after=args.kill_after, out=out)
        before = {p.parent.name for p in out.glob("*/done.json")}
        run(cmd, out=out)
        rows = summary_rows(out)
        once = sum((r["ran"] == "earlier") == (r["clip"] in before) for r in rows)
        same, listed, tmp = check(out, ref)
        print(f"| {label} | {done_at_kill} | {same}/{args.clips} | {listed} | {once}/{args.clips} | {tmp} |")

    print("\n| workers | wall time (s) | clips per minute | worker peak memory, max over clips (MB) |")
    print("|---|---:|---:|---:|")
    for label, jobs, dask in (("1 (this process)", 1, False), ("2 (process pool)", 2, False),
                              ("2 (local-dask)", 2, True)):
        out = root / f"clean_{jobs}{'_dask' if dask else ''}"
        seconds, _ = run(batch_cmd(manifest, out, jobs, dask), out=out)
        same, listed, _ = check(out, ref)
        assert same == listed == args.clips, (label, same, listed)
        peak = max(float(r["worker_peak_mb"]) for r in summary_rows(out))
        print(f"| {label} | {seconds:.1f} | {args.clips / seconds * 60:.1f} | {peak:.0f} |  (load average "
              f"{os.getloadavg()[0]:.1f})", flush=True)


if __name__ == "__main__":
    main()
