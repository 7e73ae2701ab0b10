"""Subcommands of ``pinrecon`` that live in modules of their own.

Each module here has ``register(sub)``: it adds its parser to the ``argparse`` subparsers
``sub`` and sets ``func`` (a function ``args -> exit status``). ``cli.build_parser`` calls
every module listed in :data:`MODULES`, in order, so adding a command is one file and one line.
"""

from __future__ import annotations

import importlib

#: Command modules, in the order their commands appear in ``pinrecon --help``.
MODULES: list[str] = ["track", "video", "batch", "data"]


def register_all(sub) -> None:
    """Add every listed module's subcommand to ``sub``."""
    for name in MODULES:
        importlib.import_module(f"{__name__}.{name}").register(sub)
