"""``--quick``: a short run of a bench script, to check that it runs to completion (CI runs
every bench this way: ``python bench/run_quick.py``). The numbers a quick run prints are not
the bench's: its tables come from the full run, with the command its section gives.

A script calls :func:`take` before it imports pinrecon. With ``--quick`` on its command line,
``take`` removes it, appends the script's own short options (``args``), and, unless
``cut=False``, cuts every BVH clip pinrecon loads to its first :data:`QUICK_FRAMES` frames
(``pinrecon.io.bvh.load_bvh``, which the bundled clips and the datasets' clips go through).
"""

from __future__ import annotations

import sys

QUICK_FRAMES = 150


def take(args: list[str] | None = None, *, cut: bool = True) -> bool:
    """Whether ``--quick`` was given (then applied as above)."""
    if "--quick" not in sys.argv[1:]:
        return False
    sys.argv.remove("--quick")
    sys.argv += list(args or [])
    if cut:
        from dataclasses import replace

        import pinrecon.io.bvh as bvh

        full = bvh.load_bvh

        def load_bvh(*a, **kw):
            m = full(*a, **kw)
            return replace(m, q=m.q[:QUICK_FRAMES])

        bvh.load_bvh = load_bvh
    print(f"(--quick: a short check that the script runs{'; clips cut to ' + str(QUICK_FRAMES) + ' frames' if cut else ''}"
          "; the numbers are not the bench's)", flush=True)
    return True
