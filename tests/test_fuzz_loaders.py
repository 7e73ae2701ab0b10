"""Fuzzing every tracks loader and the command line with hypothesis (issue 11).

Each case mutates a small cut of a real detector fixture (tests/fuzzing.py: wrong types,
missing keys, NaN / Inf, huge numbers, wrong shapes, out-of-range frames, truncated
files, byte flips, missing or extra frame files) and loads it, or runs ``pinrecon
reconstruct`` / ``pinrecon links`` on it. The outcome must be a result or a
PinreconError, never another exception; a result holds no NaN among its non-missing
values; a failed CLI run leaves the existing output file byte-identical.

5,240 cases in all (12 loader seeds x 420, 200 CLI runs), derandomized so that CI runs
the same cases every time; ``bench/bench_fuzz.py`` runs 50,000.
"""

from __future__ import annotations

import pytest
from fuzzing import CLI_SEEDS, LOADER_SEEDS, run_cli_case, run_loader_case, seeds
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

LOADER_CASES = 420
CLI_CASES = 100
SETTINGS = {"deadline": None, "derandomize": True, "database": None, "suppress_health_check": list(HealthCheck)}


class DrawChooser:
    """The fuzzing engine's choices, drawn by hypothesis (so failures shrink)."""

    def __init__(self, data):
        self.data = data

    def int(self, lo: int, hi: int) -> int:
        return self.data.draw(st.integers(lo, hi))

    def pick(self, seq):
        return seq[self.data.draw(st.integers(0, len(seq) - 1))]


@pytest.fixture(scope="module")
def SEEDS():
    from conftest import data_folder

    return seeds(data_folder("project-test-data/detectors"))


@pytest.mark.parametrize("name", LOADER_SEEDS)
def test_loaders_never_crash(name, scratch, SEEDS):
    outcomes = []

    @settings(max_examples=LOADER_CASES, **SETTINGS)
    @given(st.data())
    def case(data):
        outcome, detail = run_loader_case(name, SEEDS[name], DrawChooser(data), scratch / "case")
        outcomes.append(outcome)
        assert outcome in ("result", "error"), f"{outcome}: {detail}"

    case()
    assert len(outcomes) >= LOADER_CASES and "result" in outcomes and "error" in outcomes


@pytest.mark.parametrize("name", CLI_SEEDS)
def test_cli_never_crashes_nor_half_writes(name, scratch, SEEDS):
    outcomes = []

    @settings(max_examples=CLI_CASES, **SETTINGS)
    @given(st.data())
    def case(data):
        outcome, detail = run_cli_case(name, SEEDS[name], DrawChooser(data), scratch / "case", scratch / "fixed")
        outcomes.append(outcome)
        assert outcome in ("result", "error"), f"{outcome}: {detail}"

    case()
    assert len(outcomes) >= CLI_CASES and "result" in outcomes and "error" in outcomes
