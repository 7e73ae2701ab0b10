"""Run every bench script's ``--quick`` mode, one after another, and say which failed.

    OMP_NUM_THREADS=1 python bench/run_quick.py            # every script
    python bench/run_quick.py bench_engine bench_fuzz        # some

Each script runs in its own process from the repository root, with its output kept in
``bench-quick-logs/SCRIPT.log``; the exit status is the number of scripts that failed.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: every script in bench/ that prints a table (provenance.py, quick.py and this one are helpers)
SCRIPTS = sorted(p.stem for p in HERE.glob("*.py") if p.stem not in ("provenance", "quick", "run_quick"))


def main(names: list[str]) -> int:
    logs = HERE.parent / "bench-quick-logs"
    logs.mkdir(exist_ok=True)
    failed = []
    for name in names or SCRIPTS:
        t0 = time.perf_counter()
        with open(logs / f"{name}.log", "w") as log:
            rc = subprocess.run([sys.executable, str(HERE / f"{name}.py"), "--quick"], cwd=HERE.parent,
                                stdout=log, stderr=subprocess.STDOUT).returncode
        print(f"{name}: {'ok' if rc == 0 else f'FAILED (exit {rc})'} in {time.perf_counter() - t0:.0f} s", flush=True)
        if rc:
            failed.append(name)
    if failed:
        print(f"failed: {', '.join(failed)} (logs in {logs})")
    return len(failed)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
