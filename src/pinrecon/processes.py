"""Work on this machine's other CPU: the CPUs a process may use, and a computation run beside
the caller in a forked child.

:class:`Beside` runs ``fn(*args)`` in a child process forked from this one (it inherits
everything in memory: nothing is pickled to it) while the caller goes on, and gives its value
when asked; where no child can be forked (:func:`forkable`) or the child fails, the value is
computed in the caller instead, so the answer is the same either way::

    with Beside(profile_up, problem) as up:
        down = profile_down(problem)
        both = up.result() + down

The child's warnings are issued again in the caller when its value is taken (each text from
each place once); a value never taken (the block left early, :meth:`Beside.cancel`) stops the
child. The value goes back through a pipe: it must pickle.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import sys
import warnings
from collections.abc import Callable
from typing import Self

from .errors import InputError

__all__ = ["BESIDE_FRAMES", "Beside", "forkable", "may_fork", "n_processes", "usable_cpus"]


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity where the platform has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def n_processes(n_jobs, at_most: int, cpus: int) -> int:
    """The processes ``n_jobs`` asks for, scikit-learn's convention (``None`` or 1: this one,
    -1: one per CPU of ``cpus``), at most ``at_most``; anything else refused (field ``n_jobs``)."""
    if n_jobs is None:
        return 1
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, int) or n_jobs == 0 or n_jobs < -1:
        raise InputError(f"must be a whole number of processes (-1: one per CPU); got {n_jobs!r}", field="n_jobs")
    return max(1, min(at_most, cpus if n_jobs == -1 else n_jobs))


#: a solve made beside another holds as much memory as it: only for clips up to this many
#: frames (a long clip's window; a window's worker peaks at about 650 MB, bench_long_clip)
BESIDE_FRAMES = 2000


def may_fork() -> bool:
    """Whether this process may fork workers: the platform forks (a child started afresh would
    import the caller's script again, which a script without a ``__main__`` guard does not
    survive), and it is not itself a worker (``pinrecon batch``'s, Dask's: their pool already
    uses the cores)."""
    return "fork" in multiprocessing.get_all_start_methods() and multiprocessing.parent_process() is None


def forkable(frames: int | None = None) -> bool:
    """Whether work may go to a child forked beside this process: :func:`may_fork`, on Linux
    (macOS's system libraries are not safe to fork), this process may use two CPUs or more, the
    clip has at most :data:`BESIDE_FRAMES` ``frames``, and the environment does not say
    ``PINRECON_BESIDE=0`` (set it where the caller's own processes already use the cores:
    pinrecon's test configuration does under ``pytest -n``)."""
    return (sys.platform.startswith("linux") and may_fork() and usable_cpus() >= 2
            and (frames is None or frames <= BESIDE_FRAMES) and os.environ.get("PINRECON_BESIDE", "1") != "0")


def _child(conn, fn: Callable, args: tuple) -> None:
    try:
        with warnings.catch_warnings(record=True) as caught:
            value = fn(*args)
        said = [(w.message, w.category, w.filename, w.lineno) for w in caught]
        conn.send(("value", value, said))
    except BaseException:  # the caller computes it again, and raises there  # noqa: BLE001
        with contextlib.suppress(Exception):  # the pipe is gone: the caller sees it closed
            conn.send(("failed", None, []))
    finally:
        conn.close()


class Beside:
    """``fn(*args)`` computed in a forked child while the caller goes on (module docstring);
    in the caller, when asked, where :func:`forkable` is False or the child fails."""

    def __init__(self, fn: Callable, *args, fork: bool | None = None):
        self.fn, self.args = fn, args
        self._proc = self._conn = None
        self._done = False
        self.forked = forkable() if fork is None else bool(fork)
        if self.forked:
            ctx = multiprocessing.get_context("fork")
            self._conn, there = ctx.Pipe(duplex=False)
            self._proc = ctx.Process(target=_child, args=(there, fn, args), daemon=True)
            self._proc.start()
            there.close()

    def result(self):
        """The value: the child's (its warnings issued again here), or computed here."""
        if self._done:
            raise RuntimeError("the value of a Beside is taken once")
        got = self._receive()
        if got is None or got[0] != "value":
            return self.fn(*self.args)
        said = set()
        for message, category, filename, lineno in got[2]:  # once per text and place, as Python's default
            if (key := (category, str(message), filename, lineno)) not in said:
                said.add(key)
                warnings.warn_explicit(message, category, filename, lineno)
        return got[1]

    def wait(self):
        """The child's value once it ends, never computed here: None where no child ran, or it
        failed or died (for a caller that failed itself and cleans up what the child made)."""
        if self._done:
            return None
        got = self._receive()
        return got[1] if got is not None and got[0] == "value" else None

    def _receive(self):
        self._done = True
        got = None
        if self._proc is not None:
            try:
                while not self._conn.poll(0.5):
                    if not self._proc.is_alive() and not self._conn.poll(0):
                        raise EOFError
                got = self._conn.recv()
            except (EOFError, OSError):  # the child died before it said anything
                got = None
            self._reap()
        return got

    def cancel(self) -> None:
        """Stop the child (its value is not wanted)."""
        self._done = True
        if self._proc is not None and self._proc.is_alive():
            self._proc.terminate()
        self._reap()

    def _reap(self) -> None:
        if self._proc is not None:
            self._proc.join()
            self._conn.close()
            self._proc = self._conn = None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.cancel()
