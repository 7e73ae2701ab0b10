"""Fuzzing benchmark: 50,000 mutated inputs through every tracks loader and the CLI.

The same mutation engine as tests/test_fuzz_loaders.py (tests/fuzzing.py), with the
choices drawn by ``random.Random(case number)`` instead of hypothesis, so a failing case
is reproduced by its number. Prints, per seed, how many cases gave a result, a
PinreconError, and how many broke the contract: another exception (crash), NaN in a
result's non-missing values, a failed CLI run that changed the existing output file.

    python bench/bench_fuzz.py            # 50,000 cases (49,400 loader, 600 CLI runs)
    python bench/bench_fuzz.py 5000 100   # fewer
"""

from __future__ import annotations

import random
import shutil
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from fuzzing import (  # the tests folder is put on the path just above
    CLI_SEEDS,
    LOADER_SEEDS,
    RandomChooser,
    run_cli_case,
    run_loader_case,
    scratch_dir,
    seeds,
)

OUTCOMES = ("result", "error", "crash", "nan", "half-written")


def main(n_loader: int = 49_400, n_cli: int = 600) -> int:
    import tempfile

    fallback = Path(tempfile.mkdtemp(prefix="pinrecon-fuzz-"))
    root = scratch_dir(fallback)
    content = seeds()
    counts: dict[str, Counter] = defaultdict(Counter)
    seconds: Counter = Counter()
    bad: list[tuple[str, int, str, str]] = []
    cases = [("loader", LOADER_SEEDS[i % len(LOADER_SEEDS)], i) for i in range(n_loader)]
    cases += [("cli", CLI_SEEDS[i % len(CLI_SEEDS)], n_loader + i) for i in range(n_cli)]
    for what, name, i in cases:
        ch = RandomChooser(random.Random(i))
        t0 = time.perf_counter()
        if what == "loader":
            outcome, detail = run_loader_case(name, content[name], ch, root / "case")
        else:
            outcome, detail = run_cli_case(name, content[name], ch, root / "case", root / "fixed")
        key = f"{what}: {name}"
        seconds[key] += time.perf_counter() - t0
        counts[key][outcome] += 1
        if outcome not in ("result", "error"):
            bad.append((key, i, outcome, detail.strip().splitlines()[-1] if detail.strip() else ""))
    shutil.rmtree(root, ignore_errors=True)
    shutil.rmtree(fallback, ignore_errors=True)

    print(f"{'target':<26}{'cases':>8}" + "".join(f"{o:>14}" for o in OUTCOMES) + f"{'ms/case':>10}")
    total = Counter()
    for key in sorted(counts):
        c = counts[key]
        total.update(c)
        n = sum(c.values())
        print(f"{key:<26}{n:>8}" + "".join(f"{c[o]:>14}" for o in OUTCOMES) + f"{1e3 * seconds[key] / n:>10.2f}")
    n = sum(total.values())
    print(f"{'all':<26}{n:>8}" + "".join(f"{total[o]:>14}" for o in OUTCOMES)
          + f"{1e3 * sum(seconds.values()) / n:>10.2f}")
    for key, i, outcome, last in bad[:20]:
        print(f"  case {i} ({key}): {outcome}: {last}")
    return 1 if bad else 0


if __name__ == "__main__":
    args = [int(a) for a in sys.argv[1:3]]
    sys.exit(main(*args))
