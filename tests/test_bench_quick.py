"""Every bench script has a quick mode, and bench/run_quick.py (which .ci/run calls) runs
them all: a script added without one fails here. The quick runs themselves are in .ci/run
(they take longer than the test command may)."""

from __future__ import annotations

from conftest import REPO, checkout_module

HELPERS = {"provenance", "quick", "run_quick"}


def test_every_bench_script_has_a_quick_mode():
    scripts = sorted(p for p in (REPO / "bench").glob("*.py") if p.stem not in HELPERS)
    assert scripts
    lacking = [p.name for p in scripts if "--quick" not in p.read_text() and "quick.take(" not in p.read_text()]
    assert lacking == []


def test_run_quick_lists_every_script():
    mod = checkout_module("bench/run_quick.py")
    assert mod.SCRIPTS == sorted(p.stem for p in (REPO / "bench").glob("*.py") if p.stem not in HELPERS)
