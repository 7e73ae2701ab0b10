"""Subcommands of ``pinrecon`` that live in modules of their own.

Each module here has ``register(sub)``: it adds its parser to the ``argparse`` subparsers
``sub`` and sets ``func`` (a function ``args -> exit status``). ``cli.build_parser`` calls
every module listed in :data:`MODULES`, in order, so adding a command is one file and one line.
"""

from __future__ import annotations

import importlib
import sys
import time

__all__ = ["MODULES", "SolveProgress", "register_all"]

#: Command modules, in the order their commands appear in ``pinrecon --help``.
MODULES: list[str] = ["track", "video", "batch", "data"]


def register_all(sub) -> None:
    """Add every listed module's subcommand to ``sub``."""
    for name in MODULES:
        importlib.import_module(f"{__name__}.{name}").register(sub)


class SolveProgress:
    """The commands' solver progress on stderr: a labelled line as each stage of
    :func:`pinrecon.reconstruct` starts (:meth:`stage`), and the solver's iterations (the
    instance is its ``callback``): a live line on a terminal; when stderr is a file or a pipe, a
    stage's first iteration, every 10th of each solve and every rejected step (a stage that tries
    many short solves, as the mirror stage does, shows one line, not one per solve). ``quiet``:
    nothing."""

    def __init__(self, quiet: bool, max_iterations: int):
        self.quiet = quiet
        self.max = max_iterations
        self.t0 = time.perf_counter()
        self.tty = sys.stderr.isatty()
        self.dirty = False
        self.label = ""
        self.shown = False  # the stage's first iteration shown (file or pipe)

    def stage(self, name: str):
        """A stage of :func:`pinrecon.reconstruct` starts (:mod:`pinrecon.stages`): one labelled line."""
        if self.quiet:
            return
        self.close()
        print(f"pinrecon: stage {name} ({time.perf_counter() - self.t0:.1f}s)", file=sys.stderr, flush=True)
        self.label = f"{name}: "
        self.shown = False

    def __call__(self, rep) -> None:
        if self.quiet:
            return
        line = (
            f"{self.label}iter {rep.iteration:3d}/{self.max}  cost {rep.cost:.6g}  |dx| {rep.step_norm:.2g}  "
            f"{time.perf_counter() - self.t0:5.1f}s"
        )
        if not rep.accepted:
            line += f"  (rejected: {rep.message})"
        if self.tty:
            print("\r" + line.ljust(78), end="", file=sys.stderr, flush=True)
            self.dirty = True
        elif not rep.accepted or rep.iteration % 10 == 0 or (rep.iteration == 1 and not self.shown):
            print(line, file=sys.stderr, flush=True)
            self.shown = True

    def window(self, rep):
        """One solved window of a long clip (:class:`pinrecon.windowed.WindowReport`), with
        the time left at the pace so far."""
        if self.quiet:
            return
        elapsed = time.perf_counter() - self.t0
        left = elapsed / rep.index * (rep.count - rep.index)
        print(("\r" if self.tty else "") + f"{rep}  (elapsed {elapsed:.0f}s, about {left:.0f}s left)".ljust(78),
              file=sys.stderr, flush=True)
        self.dirty = False

    def close(self):
        if not self.quiet and self.dirty:
            print(file=sys.stderr)
            self.dirty = False
