"""Shared fixtures: paths of the data files and the figures several test files load."""

from __future__ import annotations

from pathlib import Path

import pytest
from threadpoolctl import threadpool_limits

# One BLAS thread for the whole session: the tests are many small matrix operations, and
# OpenBLAS threads that spin-wait on a busy 2-core machine made solves 30x slower here.
_BLAS_LIMIT = threadpool_limits(limits=1, user_api="blas")

TESTS_DIR = Path(__file__).resolve().parent
REPO = TESTS_DIR.parent
DATA = TESTS_DIR / "data"
WALK_BVH = REPO / "models" / "mocap" / "cmu-mb_02_01.bvh"
MIXED_BVH = DATA / "cmu-max_131_03.bvh"
CMU_UNIT_M = 0.056444


@pytest.fixture(scope="session")
def human():
    from pinrecon import Figure

    return Figure.human()


@pytest.fixture(scope="session")
def human_joints():
    from pinrecon import Figure

    return Figure.human("joints")


@pytest.fixture(scope="session")
def walk():
    """The CMU walk as a BvhMotion (figure + q), metres, all frames (frame 0 = T-pose)."""
    from pinrecon.io.bvh import load_bvh

    return load_bvh(WALK_BVH, CMU_UNIT_M)
