"""A computation beside the caller (``pinrecon.processes.Beside``): the same value from a forked
child as from the caller, the caller's own computation where the child fails or cannot be
forked, the child's warnings said in the caller, a value not wanted stops the child.
Ground truth: the function called in the test's own process."""

from __future__ import annotations

import os
import time
import warnings

import pytest

from pinrecon import processes
from pinrecon.processes import Beside, forkable, usable_cpus

pytestmark = pytest.mark.skipif("fork" not in __import__("multiprocessing").get_all_start_methods(),
                                reason="the platform cannot fork")


def _square_and_pid(x):
    return x * x, os.getpid()


def test_the_value_comes_from_a_child_and_equals_the_callers():
    with Beside(_square_and_pid, 7, fork=True) as job:
        here = _square_and_pid(7)
        there = job.result()
    assert there[0] == here[0] == 49
    assert there[1] != os.getpid()


def test_without_a_child_the_caller_computes_it(monkeypatch):
    monkeypatch.setattr(processes, "usable_cpus", lambda: 1)
    assert not forkable()
    job = Beside(_square_and_pid, 5)
    assert not job.forked and job.result() == (25, os.getpid())


def _fails_there(parent):
    if os.getpid() != parent:
        raise ValueError("only in the child")
    return "computed here"


def _dies_there(parent):
    if os.getpid() != parent:
        os._exit(3)
    return "computed here"


@pytest.mark.parametrize("fn", [_fails_there, _dies_there])
def test_a_child_that_fails_or_dies_leaves_the_value_to_the_caller(fn):
    assert Beside(fn, os.getpid(), fork=True).result() == "computed here"


@pytest.mark.parametrize("fn", [_fails_there, _dies_there])
def test_wait_gives_the_childs_value_and_never_computes_it_here(fn):
    """A caller that failed itself waits for the child to clean up after it: the child's
    value, or None, never a computation here."""
    assert Beside(_square_and_pid, 3, fork=True).wait()[0] == 9
    assert Beside(fn, os.getpid(), fork=True).wait() is None
    assert Beside(_square_and_pid, 3, fork=False).wait() is None
    job = Beside(_square_and_pid, 3, fork=True)
    job.result()
    assert job.wait() is None  # taken already


def _raises(_):
    raise KeyError("wrong")


def test_an_error_is_raised_in_the_caller():
    with pytest.raises(KeyError, match="wrong"):
        Beside(_raises, 0, fork=True).result()


def _warns(x):
    for _ in range(3):
        warnings.warn(f"careful with {x}", UserWarning, stacklevel=1)
    return x


def test_the_childs_warnings_are_said_in_the_caller_once_each():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert Beside(_warns, 3, fork=True).result() == 3
    assert [str(w.message) for w in caught] == ["careful with 3"]


def test_a_value_not_wanted_stops_the_child():
    t0 = time.perf_counter()
    with Beside(time.sleep, 60.0, fork=True) as job:
        proc = job._proc
        assert proc.is_alive()
    assert not proc.is_alive() and time.perf_counter() - t0 < 10.0
    with pytest.raises(RuntimeError, match="once"):
        job.result()


def test_a_clip_longer_than_a_window_is_not_solved_twice_at_once(monkeypatch):
    monkeypatch.setattr(processes, "usable_cpus", lambda: 2)
    monkeypatch.delenv("PINRECON_BESIDE", raising=False)
    assert forkable() and forkable(processes.BESIDE_FRAMES)
    assert not forkable(processes.BESIDE_FRAMES + 1)
    monkeypatch.setenv("PINRECON_BESIDE", "0")  # the caller's processes use the cores
    assert not forkable()


def test_usable_cpus_is_the_affinity():
    assert 1 <= usable_cpus() <= (os.cpu_count() or 1)
