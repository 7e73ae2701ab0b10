"""Fuzzing every reader besides the tracks loaders, and the exports, with hypothesis (issue 44).

Each case mutates a small valid file (tests/fuzzing_files.py: cameras, calibrations,
keypoint maps, limits, URDF, BVH, ASF, TRC, keyframes, result NPZ; deep nesting, huge
integers, bad numbers, non-UTF-8 bytes, truncated zips, zero quaternions, symlink loops)
and reads it; a result that loads is exported over earlier files. The outcome must be a
value or a PinreconError, never another exception, NaN or a half-written export.
``bench/bench_fuzz.py`` runs the same engine on 50,000 cases.
"""

from __future__ import annotations

import pytest
from fuzzing_files import FILE_SEEDS, file_seeds, run_file_case
from hypothesis import given, settings
from hypothesis import strategies as st
from test_fuzz_loaders import SETTINGS, DrawChooser

CASES = 40


@pytest.fixture(scope="module")
def SEEDS():
    from conftest import data_file

    return file_seeds(data_file)


@pytest.mark.parametrize("name", FILE_SEEDS)
def test_readers_never_crash(name, scratch, SEEDS):
    outcomes = []

    @settings(max_examples=CASES, **SETTINGS)
    @given(st.data())
    def case(data):
        outcome, detail = run_file_case(name, SEEDS[name], DrawChooser(data), scratch)
        outcomes.append(outcome)
        assert outcome in ("result", "error"), f"{outcome}: {detail}"

    case()
    assert len(outcomes) >= CASES and "error" in outcomes
