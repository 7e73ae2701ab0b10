"""Shared fixtures: paths of the data files and the figures several test files load."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings
from threadpoolctl import threadpool_limits

# One BLAS thread for the whole session: the tests are many small matrix operations, and
# OpenBLAS threads that spin-wait on a busy 2-core machine made solves 30x slower here.
_BLAS_LIMIT = threadpool_limits(limits=1, user_api="blas")

# Under ``pytest -n`` the workers already use the cores: no solve forks a child beside it
# (pinrecon.processes.forkable); the tests of that path ask for the child themselves.
if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ.setdefault("PINRECON_BESIDE", "0")
    os.environ.setdefault("PINRECON_DETECTOR_THREADS", "1")  # the workers already use the cores

# Hypothesis profiles: "ci" (the default: few, fixed examples, so the property tests take
# well under two minutes and every run tries the same cases) and "long" (a deeper search).
# Choose with PINRECON_HYPOTHESIS_PROFILE=long.
settings.register_profile("ci", max_examples=25, deadline=None, derandomize=True, database=None)
settings.register_profile("long", max_examples=1000, deadline=None)
settings.load_profile(os.environ.get("PINRECON_HYPOTHESIS_PROFILE", "ci"))

TESTS_DIR = Path(__file__).resolve().parent
REPO = TESTS_DIR.parent
DATA = TESTS_DIR / "data"  # the project's own synthetic fixtures
CMU_UNIT_M = 0.056444


# The files that take longest (CPU seconds of their default tests, measured with -n 2), run
# first, the rest after them in their usual order: with ``-n auto`` each worker takes the next
# whole file (``--dist loadfile --no-loadscope-reorder`` in pyproject.toml; xdist would otherwise
# order the files by their number of tests, and test_your_video.py's 40 s, in four tests, came
# last, one core idle meanwhile). Order only; a name missing here runs in its usual place.
RUN_FIRST = ("test_your_video.py", "test_fuzz_loaders.py", "test_stages.py", "test_stability.py",
             "test_planarity_seed.py", "test_camera_auto_focal.py", "test_windowed.py", "test_multicam.py",
             "test_batch.py", "test_prior_switch.py", "test_examples.py", "test_viz.py", "test_contact.py",
             "test_video.py", "test_camera_auto.py", "test_edges.py")


#: the modules that define pinrecon's warning categories (tests/test_house.py checks the list)
WARNING_MODULES = ("pinrecon.io.track_arrays", "pinrecon.starts.camera_auto")


def pytest_configure(config):
    """Under ``pytest -n``, the controller rebuilds each warning a worker reports by importing the
    module of its category (``pinrecon.io.track_arrays.TracksWarning``,
    ``pinrecon.starts.camera_auto.FocalLengthWarning``), in one thread per worker: two such
    warnings at once imported pinrecon in two threads and deadlocked on its import chain
    (``_DeadlockError``, the run aborted). Imported here first, in one thread."""
    if not hasattr(config, "workerinput") and config.pluginmanager.hasplugin("xdist"):
        import importlib

        for module in WARNING_MODULES:
            importlib.import_module(module)


def pytest_collection_modifyitems(config, items):
    """The longest files first (:data:`RUN_FIRST`). Tests marked ``slow`` are skipped, with the
    reason printed (``-ra``), unless ``PINRECON_SLOW=1``: the test command stays under 5 minutes;
    ``.ci/run`` runs them all."""
    import os

    rank = {name: i for i, name in enumerate(RUN_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(RUN_FIRST)))  # stable: order within a file kept
    if os.environ.get("PINRECON_SLOW") == "1":
        return
    skip = pytest.mark.skip(reason="slow test: set PINRECON_SLOW=1 to run it (.ci/run does)")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


def _registered(get: str, name: str, *, module: bool) -> Path:
    """``pinrecon.datasets.<get>(name)``; where it cannot be had, the test (``module``: the whole
    module) is skipped with the dataset's one-line reason, or, with PINRECON_DATA set (as in
    CI), fails."""
    from pinrecon import datasets

    try:
        return getattr(datasets, get)(name, progressbar=False)
    except datasets.DatasetError as exc:
        if datasets.data_root() is not None:
            raise
        pytest.skip(str(exc), allow_module_level=module)


def checkout_module(relative: str):
    """A script of the checkout that is not installed (``tools/...``, ``bench/...``), loaded as a
    module from ``relative`` (a path from the repository's root)."""
    import importlib.util

    path = REPO / relative
    spec = importlib.util.spec_from_file_location(path.stem, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def data_file(name: str) -> Path:
    """A registered third-party data file (pinrecon.datasets): from PINRECON_DATA or the cache;
    where it cannot be had, the test is skipped (fails with PINRECON_DATA set)."""
    return _registered("fetch", name, module=False)


def data_folder(prefix: str) -> Path:
    """A registered folder of third-party files (see :func:`data_file`)."""
    return _registered("folder", prefix, module=False)


def data_path(name: str) -> Path:
    """:func:`data_file` for a module's constants: the whole module is skipped instead."""
    return _registered("fetch", name, module=True)


def data_dir(prefix: str) -> Path:
    """:func:`data_folder` for a module's constants (see :func:`data_path`)."""
    return _registered("folder", prefix, module=True)


def openpose_body25_folder() -> Path:
    """Three OpenPose BODY_25 frames ``walk_00000000000t_keypoints.json``, written by formula
    into a folder of this test process (tests/data/SOURCES.md): person 0 of frame t has point k
    at ``(100 + 10 k + t, 200 + 5 k)`` with confidence 0.9, except point 3 of frame 0, written
    ``0, 0, 0`` (not detected); frame 1 has no people; frame 2 has a second person shifted by
    +1000 px in x."""
    global _OPENPOSE
    if _OPENPOSE is None:
        import atexit
        import json
        import shutil
        import tempfile

        folder = Path(tempfile.mkdtemp(prefix="pinrecon-openpose-")) / "openpose_body25"
        folder.mkdir()
        atexit.register(shutil.rmtree, folder.parent, True)

        def person(t, shift=0.0, missing=()):
            flat = []
            for k in range(25):
                flat += [0.0, 0.0, 0.0] if k in missing else [100.0 + 10 * k + t + shift, 200.0 + 5.0 * k, 0.9]
            return {"person_id": [-1], "pose_keypoints_2d": flat, "face_keypoints_2d": [],
                    "hand_left_keypoints_2d": [], "hand_right_keypoints_2d": []}

        frames = [[person(0, missing=(3,))], [], [person(2), person(2, shift=1000.0)]]
        for t, people in enumerate(frames):
            (folder / f"walk_{t:012d}_keypoints.json").write_text(json.dumps({"version": 1.3, "people": people}))
        _OPENPOSE = folder
    return _OPENPOSE


_OPENPOSE: Path | None = None


WALK = "mocap/cmu-mb_02_01.bvh"  # registered names (pinrecon.datasets) of the clips tests use
MIXED = "project-test-data/cmu-max_131_03.bvh"
ASF = "project-test-data/cmu-asf_01.asf"


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

    return load_bvh(data_file("mocap/cmu-mb_02_01.bvh"), CMU_UNIT_M)


@pytest.fixture(scope="session")
def coco_walk():
    """The first 2 s of the CMU walk at 60 fps tracked as a detector would see it: the 12
    COCO-17 body points with 2 px noise through a perspective camera (f = 1100 px,
    1280 x 720, 45 degrees from side-on, 6 m away), and 5 cm point keyframes every
    0.25 s. Returns (camera, tracks, true points (T, 12, 3), keyframes)."""
    import numpy as np

    from pinrecon.synthetic import bundled_motion, coco_body_tracks, perspective_side_camera
    from pinrecon.tracks import keyframes_from_points

    bfig, q, fps = bundled_motion("walk")
    q, fps = q[:240:2], fps / 2
    cam = perspective_side_camera(q, 45.0, distance_m=6.0, f_px=1100.0, center=(640.0, 360.0))
    tracks, P = coco_body_tracks(bfig, q, cam, fps=fps, noise_px=2.0, seed=1)
    rng = np.random.default_rng(2)
    kf = keyframes_from_points(list(range(0, len(q), 15)), P + rng.normal(0.0, 0.05, P.shape), list(tracks.names),
                               0.05)
    return cam, tracks, P, kf


@pytest.fixture
def scratch(tmp_path):
    """A scratch folder for the fuzzing tests: in memory when there is one (fuzzing.scratch_dir)."""
    import shutil

    from fuzzing import scratch_dir

    path = scratch_dir(tmp_path)
    yield path
    if path != tmp_path:
        shutil.rmtree(path, ignore_errors=True)


@pytest.fixture
def spy_beside(monkeypatch):
    """``spy_beside(module)``: ``module.Beside`` replaced by one that records, in the list
    returned, whether each computation was forked (the tests of work made beside the caller)."""
    from pinrecon import processes

    def spy(module):
        forked = []

        class Spy(processes.Beside):
            def __init__(self, fn, *args, fork=None):
                super().__init__(fn, *args, fork=fork)
                forked.append(self.forked)

        monkeypatch.setattr(module, "Beside", Spy)
        return forked

    return spy
