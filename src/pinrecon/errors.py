"""Typed, helpful exceptions.

Every error raised on bad input names *where* the problem is (file, field, frame)
and, for unknown names, lists the valid ones. They derive from ``ValueError`` so
generic callers can still catch them.
"""

from __future__ import annotations

from collections.abc import Iterable
from os import PathLike

__all__ = ["PinreconError", "InputError", "UnknownNameError", "format_location"]


class PinreconError(ValueError):
    """Base class of all errors pinrecon raises on bad input."""


def format_location(
    file: str | PathLike | None = None, field: str | None = None, frame: int | None = None
) -> str:
    parts = []
    if file is not None:
        parts.append(f"{file}")
    if field is not None:
        parts.append(f"field '{field}'")
    if frame is not None:
        parts.append(f"frame {frame}")
    return ", ".join(parts)


class InputError(PinreconError):
    """Bad input data, located by file, field and frame where they are known."""

    def __init__(
        self,
        message: str,
        *,
        file: str | PathLike | None = None,
        field: str | None = None,
        frame: int | None = None,
    ):
        self.file = None if file is None else str(file)
        self.field = field
        self.frame = frame
        self.message = message
        where = format_location(file, field, frame)
        super().__init__(f"{where}: {message}" if where else message)

    def located(self, *, file=None, field=None, frame=None) -> InputError:
        """A copy with missing location parts filled in (used when re-raising upward)."""
        return type(self)(
            self.message,
            file=self.file if self.file is not None else file,
            field=self.field if self.field is not None else field,
            frame=self.frame if self.frame is not None else frame,
        )


class UnknownNameError(InputError):
    """A keypoint, joint or frame name that the figure does not have."""

    def __init__(
        self,
        kind: str,
        names: Iterable[str],
        valid: Iterable[str],
        *,
        file=None,
        field=None,
        frame=None,
    ):
        self.kind = kind
        self.names = list(names)
        self.valid = list(valid)
        shown = ", ".join(self.valid[:60]) + (" ..." if len(self.valid) > 60 else "")
        unknown = ", ".join(repr(n) for n in self.names)
        super().__init__(
            f"unknown {kind} name(s) {unknown}; valid {kind} names are: {shown}",
            file=file,
            field=field,
            frame=frame,
        )

    def located(self, *, file=None, field=None, frame=None) -> UnknownNameError:
        return UnknownNameError(
            self.kind,
            self.names,
            self.valid,
            file=self.file if self.file is not None else file,
            field=self.field if self.field is not None else field,
            frame=self.frame if self.frame is not None else frame,
        )
