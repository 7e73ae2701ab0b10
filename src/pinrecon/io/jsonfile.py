"""The one place input files are opened and decoded: JSON, text and NPZ.

Every reader of pinrecon takes its bytes through here, so the limits hold everywhere and
each failure is one :class:`~pinrecon.errors.InputError` naming the file (and the field and
frame when the caller gives them), never an ``OSError``, ``UnicodeDecodeError``,
``RecursionError`` or ``zipfile`` error:

* :func:`read_json` / :func:`parse_json` (a file, or JSON embedded in a string field):
  nesting deeper than :data:`MAX_DEPTH` and integer literals longer than
  :data:`MAX_INT_DIGITS` digits are refused; ``NaN``, ``Infinity`` and ``1e999`` parse to
  floats, which each reader refuses (or takes as missing) naming the field.
* :func:`read_text`: missing files, folders, symlink loops, unreadable files, text that is
  not UTF-8.
* :func:`read_npz`: anything :func:`numpy.load` cannot read (a truncated zip, pickled
  objects) and a file holding no arrays.

What a reader does with the decoded values (types, shapes, ranges) it checks with
:mod:`pinrecon.io.fields`.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["read_json", "parse_json", "read_text", "read_npz", "MAX_DEPTH", "MAX_INT_DIGITS"]

#: deepest nesting of arrays and objects accepted (real files: under 10)
MAX_DEPTH = 64
#: longest integer literal accepted, in digits (2**64 has 20)
MAX_INT_DIGITS = 20

_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.DOTALL)


class _Refused(ValueError):
    """A literal the JSON limits refuse (raised inside the parser's hooks)."""


def _parse_int(s: str) -> int:
    if len(s) - s.startswith("-") > MAX_INT_DIGITS:
        raise _Refused(f"an integer of {len(s) - s.startswith('-')} digits (at most {MAX_INT_DIGITS})")
    return int(s)


def _depth(text: str) -> int:
    """The deepest nesting of ``[`` and ``{`` outside strings (vectorised: no recursion)."""
    if text.count("[") + text.count("{") <= MAX_DEPTH:
        return 0
    b = np.frombuffer(_STRING.sub('""', text).encode("utf-8", "surrogatepass"), np.uint8)
    step = ((b == 91) | (b == 123)).astype(np.int32) - ((b == 93) | (b == 125))
    return int(np.cumsum(step).max()) if len(step) else 0


def parse_json(text: str, *, file=None, field: str | None = None, frame: int | None = None):
    """Parse JSON text under the limits above; one InputError naming ``file``/``field``/
    ``frame`` on failure."""
    if not isinstance(text, str):
        raise InputError(f"expected JSON text, got {type(text).__name__}", file=file, field=field, frame=frame)
    depth = _depth(text)
    if depth > MAX_DEPTH:
        raise InputError(f"not valid JSON here (nested {depth} levels deep, at most {MAX_DEPTH})", file=file,
                         field=field, frame=frame)
    try:
        return json.loads(text, parse_int=_parse_int)
    except _Refused as exc:
        raise InputError(f"not valid JSON here ({exc})", file=file, field=field, frame=frame) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON ({exc.msg} at line {exc.lineno})", file=file, field=field,
                         frame=frame) from None
    except (RecursionError, ValueError) as exc:  # RecursionError: a depth our scan missed
        raise InputError(f"not valid JSON ({type(exc).__name__}: {str(exc)[:80]})", file=file, field=field,
                         frame=frame) from None


def _opening(exc: OSError) -> str:
    if isinstance(exc, FileNotFoundError):
        return "file not found"
    if isinstance(exc, IsADirectoryError):
        return "is a folder, expected a file"
    if isinstance(exc, PermissionError):
        return "cannot be read (permission denied)"
    if getattr(exc, "errno", None) == 40:  # ELOOP
        return "is a symbolic link that loops"
    return f"cannot be read ({exc.strerror or exc})"


def read_bytes(path: str | os.PathLike, *, frame: int | None = None) -> bytes:
    """A file's bytes; one InputError for anything the file system refuses."""
    try:
        return Path(path).read_bytes()
    except OSError as exc:
        raise InputError(_opening(exc), file=path, frame=frame) from None


def read_text(path: str | os.PathLike, *, frame: int | None = None, errors: str = "strict",
              encoding: str = "utf-8") -> str:
    """A text file's content (UTF-8; a byte-order mark is dropped). ``errors="replace"``
    keeps going over undecodable bytes (formats whose headers carry free text)."""
    data = read_bytes(path, frame=frame)
    try:
        text = data.decode(encoding, errors=errors)
    except UnicodeDecodeError as exc:
        raise InputError(f"is not text (UTF-8): undecodable byte at offset {exc.start}", file=path,
                         frame=frame) from None
    return text[1:] if text.startswith("\ufeff") else text


def read_json(path: str | os.PathLike, *, frame: int | None = None):
    """Parse a JSON file; a missing file, a folder, a symlink loop, undecodable text, bad
    JSON or a literal beyond the limits raise one :class:`~pinrecon.errors.InputError`
    naming the file (and ``frame`` when given)."""
    path = Path(path)
    text = read_text(path, frame=frame)
    return parse_json(text, file=path, frame=frame)


def read_npz(path: str | os.PathLike) -> dict:
    """Every array of an NPZ file (no pickled objects), as a dict; one InputError for a file
    that is missing, not a zip, truncated or corrupt."""
    path = Path(path)
    try:
        with open(path, "rb"):
            pass
    except OSError as exc:  # the file system's refusals (missing, folder, loop) as one error
        raise InputError(_opening(exc), file=path) from None
    try:
        with np.load(path, allow_pickle=False) as z:
            if not hasattr(z, "files"):
                raise InputError("is a single .npy array, expected an NPZ archive", file=path)
            return {k: z[k] for k in z.files}
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - zipfile, zlib, EOF, struct, ValueError: all "not a readable NPZ"
        raise InputError(f"not a readable NPZ file ({type(exc).__name__}: {str(exc)[:100]})", file=path) from None
