"""Reading JSON input files with errors that name the file (and frame)."""

from __future__ import annotations

import json
import os
from pathlib import Path

from ..errors import InputError

__all__ = ["read_json"]


def read_json(path: str | os.PathLike, *, frame: int | None = None):
    """Parse a JSON file; a missing file, a folder, undecodable text or bad JSON raise one
    :class:`~pinrecon.errors.InputError` naming the file (and ``frame`` when given)."""
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError("file not found", file=path, frame=frame) from None
    except IsADirectoryError:
        raise InputError("is a folder, expected a JSON file", file=path, frame=frame) from None
    except UnicodeDecodeError:
        raise InputError("is not text (UTF-8)", file=path, frame=frame) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON ({exc.msg} at line {exc.lineno})", file=path, frame=frame) from None
