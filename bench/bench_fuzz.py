"""Fuzzing benchmark: 50,000 mutated inputs through every reader, the exports and the CLI.

The same mutation engines as the tests (tests/fuzzing.py: the tracks loaders and the CLI;
tests/fuzzing_files.py: cameras, calibrations, keypoint maps, limits, URDF, BVH, ASF, TRC,
keyframes, result NPZ and their export), with the choices drawn by ``random.Random(case
number)`` instead of hypothesis, so a failing case is reproduced by its number. The kinds
include JSON nested 3000 deep, 5000-digit integers, symlink loops, folders and empty files
for paths, non-UTF-8 bytes, truncated zips, NPZ fields of the wrong type, shape or dtype,
invalid embedded JSON, zero quaternions, infinite fps and joint values, and CLI runs whose
second output cannot be written.

Prints, per target, how many cases gave a result, a PinreconError, and how many broke the
contract: another exception (crash), NaN in a result's values (nan), a failed run that
changed an earlier output or left a temporary (half-written).

    OMP_NUM_THREADS=1 nice python bench/bench_fuzz.py            # 50,000 cases (49,400 readers, 600 CLI)
    python bench/bench_fuzz.py 5000 100                          # fewer
"""

from __future__ import annotations

import os
import random
import shutil
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from fuzzing import (  # the tests folder is put on the path just above
    CLI_SEEDS,
    LOADER_SEEDS,
    RandomChooser,
    run_cli_case,
    run_loader_case,
    scratch_dir,
    seeds,
)
from fuzzing_files import FILE_SEEDS, file_seeds, run_file_case
from provenance import provenance

OUTCOMES = ("result", "error", "crash", "nan", "half-written")


class _QuietFd2:
    """C libraries (urdfdom) print parse errors straight to file descriptor 2: hush them."""

    def __enter__(self):
        sys.stderr.flush()
        self.saved = os.dup(2)
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 2)
        os.close(null)

    def __exit__(self, *exc):
        sys.stderr.flush()
        os.dup2(self.saved, 2)
        os.close(self.saved)


def main(n_loader: int = 49_400, n_cli: int = 600) -> int:
    import tempfile

    from pinrecon import datasets

    print(provenance())
    print("command: python bench/bench_fuzz.py " + " ".join(sys.argv[1:]))
    fallback = Path(tempfile.mkdtemp(prefix="pinrecon-fuzz-"))
    root = scratch_dir(fallback)
    content = {**seeds(), **file_seeds(lambda name: datasets.fetch(name, progressbar=False))}
    targets = LOADER_SEEDS + FILE_SEEDS
    counts: dict[str, Counter] = defaultdict(Counter)
    seconds: Counter = Counter()
    bad: list[tuple[str, int, str, str]] = []
    cases = [("reader", targets[i % len(targets)], i) for i in range(n_loader)]
    cases += [("cli", CLI_SEEDS[i % len(CLI_SEEDS)], n_loader + i) for i in range(n_cli)]
    with _QuietFd2():
        for what, name, i in cases:
            ch = RandomChooser(random.Random(i))
            t0 = time.perf_counter()
            if what == "cli":
                outcome, detail = run_cli_case(name, content[name], ch, root / "case", root / "fixed")
            elif name in FILE_SEEDS:
                outcome, detail = run_file_case(name, content[name], ch, root / "files")
            else:
                outcome, detail = run_loader_case(name, content[name], ch, root / "case")
            key = f"{what}: {name}"
            seconds[key] += time.perf_counter() - t0
            counts[key][outcome] += 1
            if outcome not in ("result", "error"):
                bad.append((key, i, outcome, detail.strip().splitlines()[-1] if detail.strip() else ""))
    shutil.rmtree(root, ignore_errors=True)
    shutil.rmtree(fallback, ignore_errors=True)

    print(f"{'target':<28}{'cases':>8}" + "".join(f"{o:>14}" for o in OUTCOMES) + f"{'ms/case':>10}")
    total = Counter()
    for key in sorted(counts):
        c = counts[key]
        total.update(c)
        n = sum(c.values())
        print(f"{key:<28}{n:>8}" + "".join(f"{c[o]:>14}" for o in OUTCOMES) + f"{1e3 * seconds[key] / n:>10.2f}")
    n = sum(total.values())
    print(f"{'all':<28}{n:>8}" + "".join(f"{total[o]:>14}" for o in OUTCOMES)
          + f"{1e3 * sum(seconds.values()) / n:>10.2f}")
    for key, i, outcome, last in bad[:20]:
        print(f"  case {i} ({key}): {outcome}: {last}")
    return 1 if bad else 0


if __name__ == "__main__":
    if "--quick" in sys.argv:  # a short check that it runs (CI); the table needs the full run
        sys.argv.remove("--quick")
        sys.argv[1:] = ["300", "5"]
    args = [int(a) for a in sys.argv[1:3]]
    sys.exit(main(*args))
