"""Typed checks of decoded fields: the second half of the reading layer (:mod:`pinrecon.io.jsonfile`
decodes, this checks types, shapes, dtypes, finiteness and ranges).

Every check raises one :class:`~pinrecon.errors.InputError` naming the file, the field and,
for per-frame arrays (frames along the first axis), the first bad frame::

    q = array_field(data, "q", file=path, ndim=2, kind="number", finite=True, bound=1e6)
    fps = number_field(data["fps"], file=path, field="fps", low=0, high=1e6, low_open=True)
    text = string_field(data, "figure_urdf", file=path)
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

__all__ = ["array_field", "number_field", "string_field", "first_bad_frame", "KINDS"]

#: numpy dtype kinds each ``kind`` accepts
KINDS = {"number": "iuf", "float": "f", "integer": "iu", "bool": "b", "bool-like": "biu", "string": "U"}


def first_bad_frame(bad: np.ndarray) -> int | None:
    """Index along the first axis of the first True of ``bad`` (None when none; 0-d: 0)."""
    bad = np.asarray(bad)
    if not bad.any():
        return None
    if bad.ndim == 0:
        return None
    return int(np.argmax(bad.reshape(len(bad), -1).any(axis=1)))


def array_field(data: dict, key: str, *, file=None, ndim: int | None = None, shape: tuple | None = None,
                kind: str = "number", finite: bool = False, bound: float | None = None,
                required: bool = True, default=None) -> np.ndarray:
    """``data[key]`` as an array of the given ``kind`` (:data:`KINDS`), dimensions and
    ``shape`` (``None`` entries are free), with no NaN/inf when ``finite`` and no
    magnitude over ``bound``. A missing key: ``default`` unless ``required``."""
    if key not in data:
        if required:
            raise InputError("missing", file=file, field=key)
        return default
    a = np.asarray(data[key])
    if a.dtype.kind not in KINDS[kind]:
        raise InputError(f"must be an array of {kind}s, got dtype {a.dtype}", file=file, field=key)
    if ndim is not None and a.ndim != ndim:
        raise InputError(f"must have {ndim} dimension(s), got shape {a.shape}", file=file, field=key)
    if shape is not None and (a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape))):
        want = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
        raise InputError(f"must have shape {want}, got {a.shape}", file=file, field=key)
    if a.dtype.kind == "f":
        if finite:
            t = first_bad_frame(~np.isfinite(a)) if a.ndim else (None if np.isfinite(a) else -1)
            if t is not None:
                raise InputError("must be finite (no NaN or infinity)", file=file, field=key,
                                 frame=None if t < 0 else t)
        if bound is not None:
            with np.errstate(invalid="ignore"):
                over = np.abs(a) > bound
            t = first_bad_frame(over) if a.ndim else (-1 if over else None)
            if t is not None:
                raise InputError(f"a value beyond +-{bound:g}", file=file, field=key, frame=None if t < 0 else t)
    elif a.dtype.kind in "iu" and bound is not None and a.size and np.abs(a.astype(float)).max() > bound:
        t = first_bad_frame(np.abs(a.astype(float)) > bound) if a.ndim else None
        raise InputError(f"a value beyond +-{bound:g}", file=file, field=key, frame=t)
    return a


def number_field(value, *, file=None, field: str | None = None, frame: int | None = None, low: float | None = None,
                 high: float | None = None, low_open: bool = False, integer: bool = False) -> float:
    """``value`` as a finite float (an int with ``integer``) in ``[low, high]`` (``(low,
    high]`` with ``low_open``); 0-d arrays and numpy scalars are numbers, booleans are not."""
    a = np.asarray(value) if not isinstance(value, (int, float)) else None
    if a is not None:
        if a.shape != () or a.dtype.kind not in ("iu" if integer else "iuf"):
            raise InputError(f"must be a number, got {_describe(value)}", file=file, field=field, frame=frame)
        value = a.item()
    if isinstance(value, bool) or (integer and not isinstance(value, int)):
        raise InputError(f"must be {'an integer' if integer else 'a number'}, got {_describe(value)}", file=file,
                         field=field, frame=frame)
    try:
        v = float(value)
    except OverflowError:
        raise InputError("is out of range", file=file, field=field, frame=frame) from None
    if not np.isfinite(v):
        raise InputError(f"must be finite, got {v}", file=file, field=field, frame=frame)
    if low is not None and (v < low or (low_open and v == low)):
        raise InputError(f"must be {'>' if low_open else '>='} {low:g}, got {v:g}", file=file, field=field,
                         frame=frame)
    if high is not None and v > high:
        raise InputError(f"must be <= {high:g}, got {v:g}", file=file, field=field, frame=frame)
    return int(value) if integer else v


def string_field(data: dict, key: str, *, file=None, required: bool = True, default: str | None = None) -> str | None:
    """``data[key]`` as a str (a 0-d string array, as NPZ files store text)."""
    if key not in data:
        if required:
            raise InputError("missing", file=file, field=key)
        return default
    a = np.asarray(data[key])
    if a.shape != () or a.dtype.kind != "U":
        raise InputError(f"must be a text, got {_describe(data[key])}", file=file, field=key)
    return str(a)


def _describe(value) -> str:
    if isinstance(value, np.ndarray):
        return f"an array of dtype {value.dtype} and shape {value.shape}"
    return type(value).__name__
