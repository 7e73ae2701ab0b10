"""Atomic file writes, and a command's outputs checked before the work and committed together.

One file: :func:`atomic_path` / :func:`atomic_write_text` write to a temporary sibling, then
rename; nothing is ever half-written.

A command's files: :class:`Outputs`. Declare every path the command will write, check them
all before the work (a read-only folder, a parent that is a file, a path that is a folder:
one :class:`~pinrecon.errors.InputError` naming the path, and nothing created), then do the
work and write inside :meth:`Outputs.commit`: every :func:`atomic_path` under it (so every
writer of pinrecon: ``Result.save``, ``Camera.save``, exports, plots, animations) is staged,
and the staged files are renamed into place together when the block ends, or all removed
when it raises::

    from pinrecon.io.atomic import Outputs

    outs = Outputs([args.out, args.save_camera])   # None entries are ignored
    outs.check()                                    # before the solve: InputError naming a path
    result = reconstruct(...)                       # the work
    with outs.commit():                             # all or none
        result.save(args.out)
        result.camera.save(args.save_camera)

A writer may add paths it only learns late (``outs.add(path)`` before :meth:`check`); files
written under :meth:`commit` that were not declared are committed with the rest.
"""

from __future__ import annotations

import contextvars
import errno
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

from ..errors import InputError

__all__ = ["Outputs", "atomic_path", "atomic_write_bytes", "atomic_write_text", "check_writable", "unstaged"]

#: the transaction of the :meth:`Outputs.commit` block running in this context (None outside one)
_STAGE: contextvars.ContextVar = contextvars.ContextVar("pinrecon_outputs_stage", default=None)


def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.stem}.tmp{os.getpid()}{path.suffix}")


@contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path next to ``path`` (same suffix, so writers that pick the format
    from it still work); on success it replaces ``path``. Creates the folder. Inside an
    :meth:`Outputs.commit` block the replacement waits for the block's end."""
    path = Path(path)
    stage = _STAGE.get()
    if stage is not None:
        with stage.stage(path) as tmp:
            yield tmp
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_name(path)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


@contextmanager
def unstaged():
    """:func:`atomic_path` writes in place under this block, even inside an
    :meth:`Outputs.commit` block (a forked child's staging would never be published: it
    writes elsewhere and hands the bytes back)."""
    token = _STAGE.set(None)
    try:
        yield
    finally:
        _STAGE.reset(token)


def _why_not_writable(path: Path) -> str | None:
    """Why ``path`` cannot be written (None when it can), creating nothing."""
    if path.is_dir():
        return "is a folder, not a file"
    parent = path.parent
    missing = []
    while not parent.exists():
        if parent.is_symlink():
            return f"its folder {parent} is a broken link"
        missing.append(parent)
        if parent.parent == parent:
            break
        parent = parent.parent
    if not parent.is_dir():
        return f"its folder {parent} is a file, not a folder"
    if missing:  # the folder would be created under ``parent``: that must be writable
        if not os.access(parent, os.W_OK | os.X_OK):
            return f"cannot create the folder {missing[-1]}: {parent} is not writable"
        return _probe(parent, f"cannot create the folder {missing[-1]} in {parent}")
    return _probe(parent, f"cannot write in the folder {parent}")


def _probe(folder: Path, what: str) -> str | None:
    """Create and remove a file in ``folder`` (the only sure test of a read-only mount)."""
    try:
        fd, name = tempfile.mkstemp(prefix=".pinrecon-probe-", dir=folder)
    except OSError as exc:
        return f"{what} ({exc.strerror or exc})"
    os.close(fd)
    os.unlink(name)
    return None


def check_writable(path: str | os.PathLike, *, field: str | None = None) -> None:
    """Raise one :class:`~pinrecon.errors.InputError` naming ``path`` when it cannot be
    written (a read-only folder, a parent that is a file, a path that is a folder). Creates
    nothing."""
    why = _why_not_writable(Path(path))
    if why:
        raise InputError(f"cannot write the output: {why}", file=path, field=field)


class Outputs:
    """The files one command writes: checked before the work, committed all or none.

    See the module's docstring for the pattern. ``fields`` optionally names each path's
    option (``{"--out": path}``) so an error says which one."""

    def __init__(self, paths=(), fields: dict | None = None):
        self.paths: list[Path] = []
        self.fields: dict[Path, str] = {}
        self.folders: list[Path] = []
        self.clashes: list[tuple[Path, str, str]] = []
        for p in paths:
            self.add(p)
        for field, p in (fields or {}).items():
            self.add(p, field=field)
        self._staged: list[tuple[Path, Path]] = []
        self._made_dirs: list[Path] = []

    def add(self, path, *, field: str | None = None) -> Path | None:
        """Declare an output path (``None`` is ignored); returns it as a Path."""
        if path is None:
            return None
        path = Path(path)
        if path in self.paths and field and self.fields.get(path, field) != field:
            self.clashes.append((path, self.fields[path], field))
        if path not in self.paths:
            self.paths.append(path)
        if field:
            self.fields.setdefault(path, field)
        return path

    def add_folder(self, folder, *, field: str | None = None) -> Path:
        """Declare a folder the command writes files into (plots): :meth:`check` tests that a
        file can be written there (the folder is made at commit when missing)."""
        folder = Path(folder)
        self.folders.append(folder)
        if field:
            self.fields[folder] = field
        return folder

    def check(self) -> None:
        """One InputError for the first declared path that cannot be written; also when two
        declared outputs are the same file. Creates nothing."""
        for p, first, second in self.clashes:
            raise InputError(f"is given for two outputs ({first} and {second})", file=p)
        seen = {}
        for p in self.paths:
            key = os.path.abspath(p)
            if key in seen:
                raise InputError(f"is given for two outputs ({self.fields.get(seen[key], seen[key])} and this one)",
                                 file=p, field=self.fields.get(p))
            seen[key] = p
            check_writable(p, field=self.fields.get(p))
        for folder in self.folders:
            if folder.exists() and not folder.is_dir():
                raise InputError("cannot write the output: is a file, not a folder", file=folder,
                                 field=self.fields.get(folder))
            why = _why_not_writable(folder / ".pinrecon-output")
            if why:
                raise InputError(f"cannot write the output: {why}", file=folder, field=self.fields.get(folder))

    @contextmanager
    def stage(self, path):
        """A temporary path for ``path``'s content, renamed into place at :meth:`commit`'s end."""
        path = Path(path)
        self._mkdirs(path.parent)
        tmp = _tmp_name(path)
        ok = False
        try:
            yield tmp
            ok = tmp.exists()
        finally:
            if ok:
                self._staged = [(t, p) for t, p in self._staged if p != path] + [(tmp, path)]
            elif tmp.exists():
                tmp.unlink()
        self.add(path)

    def _mkdirs(self, folder: Path) -> None:
        missing = []
        while not folder.exists() and folder.parent != folder:
            missing.append(folder)
            folder = folder.parent
        for d in reversed(missing):
            d.mkdir()
            self._made_dirs.append(d)

    @contextmanager
    def commit(self):
        """Stage every write under this block (:func:`atomic_path`); on a clean exit rename
        them all into place (restoring every earlier file if a rename fails), on an error
        remove them all and the folders made for them."""
        token = _STAGE.set(self)
        try:
            yield self
        except BaseException:
            _STAGE.reset(token)
            self._discard()
            raise
        _STAGE.reset(token)
        self._publish()

    def _discard(self) -> None:
        for tmp, _ in self._staged:
            if tmp.exists():
                tmp.unlink()
        self._staged = []
        for d in reversed(self._made_dirs):
            try:
                d.rmdir()
            except OSError:
                pass
        self._made_dirs = []

    def _publish(self) -> None:
        done: list[tuple[Path, Path | None]] = []
        try:
            for tmp, path in self._staged:
                backup = None
                if path.exists():
                    backup = path.with_name(f".{path.name}.bak{os.getpid()}")
                    os.replace(path, backup)
                done.append((path, backup))
                os.replace(tmp, path)
        except OSError as exc:
            for path, backup in reversed(done):
                if backup is not None:
                    os.replace(backup, path)
                elif path.exists():
                    path.unlink()
            self._discard()
            if exc.errno in (errno.EACCES, errno.EROFS, errno.EPERM, errno.ENOSPC):
                raise InputError(f"cannot write the output ({exc.strerror}); nothing was written",
                                 file=exc.filename) from None
            raise
        for _, backup in done:
            if backup is not None and backup.exists():
                backup.unlink()
        self._staged = []
        self._made_dirs = []
