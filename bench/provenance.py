"""What a benchmark ran on, printed above its tables: the commit of the pinrecon that was
imported and whether its tree had uncommitted changes (a table in a README should be one
a commit prints: a working tree's numbers cannot be reproduced)."""

from __future__ import annotations

import subprocess
from pathlib import Path


def provenance() -> str:
    """``"pinrecon <version> at <commit>"`` (``", with uncommitted changes"`` when the
    tree is dirty), or ``"pinrecon <version> (not in a git checkout)"``."""
    import pinrecon

    root = Path(pinrecon.__file__).resolve().parents[2]
    version = getattr(pinrecon, "__version__", "?")

    def git(*args):
        return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=30, check=False)

    try:
        head = git("rev-parse", "--short", "HEAD")
        if head.returncode != 0:
            return f"pinrecon {version} (not in a git checkout)"
        dirty = git("status", "--porcelain", "--untracked-files=no").stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return f"pinrecon {version} (git not available)"
    return f"pinrecon {version} at {head.stdout.strip()}" + (", with uncommitted changes" if dirty else "")
