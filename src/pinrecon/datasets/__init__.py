"""Third-party data the project, its tests, examples and benches use: fetched, hash-checked, cached.

Every file has a name (its path in a data folder, e.g. ``"mocap/cmu-mb_02_01.bvh"``), a sha256
and the URL it is published at (a raw file at a pinned commit of its upstream repository)::

    from pinrecon import datasets
    path = datasets.fetch("mocap/cmu-mb_02_01.bvh")          # a local Path, checked
    folder = datasets.folder("pose2sim-balancing/pose/cam01_json")
    asf, amc = datasets.cmu("01_01")                           # CMU's own ASF/AMC

Where the files come from:

* ``PINRECON_DATA`` set: a local folder laid out like the registry's names. Files are read from
  there, hash-checked, and nothing is downloaded.
* otherwise: downloaded once into the user's cache (``PINRECON_CACHE``, or the platform's cache
  folder, e.g. ``~/.cache/pinrecon``) with a progress bar, through :mod:`pooch`.

A file that is missing, cannot be downloaded or does not match its hash raises
:class:`DatasetError`, one line naming the dataset, its URL and ``PINRECON_DATA``.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from ..errors import InputError

__all__ = [
    "DatasetError",
    "Entry",
    "registry",
    "names",
    "fetch",
    "folder",
    "clip",
    "cmu",
    "data_root",
    "cache_dir",
    "source",
    "CLIPS",
]

ENV_DATA = "PINRECON_DATA"
ENV_CACHE = "PINRECON_CACHE"
CMU_SITE = "http://mocap.cs.cmu.edu/subjects"

#: Short names of the CMU clips the demo, examples and benches use.
CLIPS = {
    "walk": "mocap/cmu-mb_02_01.bvh",
    "run": "mocap/cmu-mb_09_01.bvh",
    "spin": "mocap/cmu-mb_05_11.bvh",
    "dance": "mocap/cmu-mb_05_02.bvh",
}


class DatasetError(InputError):
    """A registered data file that cannot be had: missing, not downloadable, or corrupted."""


@dataclass(frozen=True)
class Entry:
    """One registered file: its name, sha256 and upstream URL (None: ``PINRECON_DATA`` only)."""

    name: str
    sha256: str
    url: str | None


@lru_cache(maxsize=None)
def registry() -> dict[str, Entry]:
    """Every registered file, by name."""
    out = {}
    text = (Path(__file__).parent / "registry.txt").read_text(encoding="utf-8")
    for line in text.splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        name, digest, url = line.split(" ", 2)
        out[name] = Entry(name, digest, None if url == "-" else url)
    return out


def names(prefix: str = "") -> list[str]:
    """The registered names that start with ``prefix`` (e.g. ``"cmu-iclone/"``), sorted."""
    return sorted(n for n in registry() if n.startswith(prefix))


def data_root() -> Path | None:
    """The ``PINRECON_DATA`` folder, or None when it is not set."""
    value = os.environ.get(ENV_DATA, "").strip()
    return Path(value).expanduser() if value else None


def cache_dir() -> Path:
    """Where downloaded files are kept (``PINRECON_CACHE`` or the platform's user cache)."""
    value = os.environ.get(ENV_CACHE, "").strip()
    if value:
        return Path(value).expanduser()
    import pooch

    return Path(pooch.os_cache("pinrecon"))


def source() -> str:
    """Where data files come from now, in words: the ``PINRECON_DATA`` folder or the cache."""
    root = data_root()
    if root is not None:
        return f"{ENV_DATA}={root}"
    return f"the download cache {cache_dir()} (set {ENV_DATA} to use a local data folder)"


def _entry(name: str) -> Entry:
    try:
        return registry()[name]
    except KeyError:
        close = [n for n in registry() if n.rsplit("/", 1)[-1] == name.rsplit("/", 1)[-1]]
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        raise DatasetError(
            f"'{name}' is not a registered dataset file{hint} (pinrecon.datasets.names() lists them)",
        ) from None


def _where(entry: Entry) -> str:
    url = entry.url or "no public URL (a file derived by the project's scripts)"
    return f"dataset '{entry.name}' ({url})"


@lru_cache(maxsize=4096)
def _sha256(path: str, size: int, mtime_ns: int) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _checked(path: Path, entry: Entry) -> Path:
    st = path.stat()
    digest = _sha256(str(path), st.st_size, st.st_mtime_ns)
    if digest != entry.sha256:
        raise DatasetError(
            f"{_where(entry)} does not match the registry's sha256 (expected {entry.sha256[:12]}..., "
            f"found {digest[:12]}...): the file is corrupted or another version; replace it",
            file=path,
        )
    return path


def fetch(name: str, *, progressbar: bool | None = None) -> Path:
    """The local path of the registered file ``name``, hash-checked.

    From ``PINRECON_DATA`` when it is set (nothing is downloaded), else from the cache,
    downloading it once from its URL. ``progressbar`` defaults to showing one on a terminal.
    """
    entry = _entry(name)
    root = data_root()
    if root is not None:
        path = root / name
        if not path.is_file():
            raise DatasetError(
                f"{_where(entry)} is not in {ENV_DATA}={root}; put it there, or unset {ENV_DATA} "
                "to download it",
            )
        return _checked(path, entry)
    cached = cache_dir() / name
    if cached.is_file():
        return _checked(cached, entry)
    if entry.url is None:
        raise DatasetError(
            f"{_where(entry)} cannot be downloaded; set {ENV_DATA} to a folder that holds it",
        )
    return _download(entry, cached, progressbar)


def _download(entry: Entry, target: Path, progressbar: bool | None) -> Path:
    import sys

    import pooch

    if progressbar is None:
        progressbar = sys.stderr.isatty()
    if progressbar:
        try:
            import tqdm  # noqa: F401  (pooch's progress bar needs it)
        except ImportError:
            progressbar = False
    try:
        got = pooch.retrieve(
            entry.url,
            known_hash=f"sha256:{entry.sha256}",
            fname=target.name,
            path=target.parent,
            progressbar=progressbar,
        )
    except ValueError as exc:  # pooch: hash mismatch of the download
        raise DatasetError(f"{_where(entry)}: the download does not match its sha256 ({exc})") from None
    except Exception as exc:  # requests' connection errors, HTTP errors, OSError
        raise DatasetError(
            f"could not download {_where(entry)}: {type(exc).__name__}; offline? set {ENV_DATA} "
            "to a local copy of the data folder",
        ) from None
    return Path(got)


def folder(prefix: str, *, progressbar: bool | None = None) -> Path:
    """The local folder holding every registered file under ``prefix`` (fetched and checked)."""
    prefix = prefix.rstrip("/") + "/"
    wanted = names(prefix)
    if not wanted:
        raise DatasetError(f"no registered dataset files under '{prefix}'", field="dataset")
    for n in wanted:
        fetch(n, progressbar=progressbar)
    return (data_root() or cache_dir()) / prefix.rstrip("/")


def clip(name: str) -> Path:
    """A CMU clip by short name (``walk``, ``run``, ``spin``, ``dance``), registered name, or a
    registered BVH file's name alone (``"cmu-mb_05_02.bvh"``)."""
    if name in CLIPS:
        return fetch(CLIPS[name])
    if name in registry():
        return fetch(name)
    same = [n for n in registry() if n.endswith(".bvh") and n.rsplit("/", 1)[-1] == name]
    if len(same) == 1:
        return fetch(same[0])
    raise DatasetError(
        f"no clip '{name}'; short names are {sorted(CLIPS)}, or give a registered name"
        + (f" ({', '.join(same)})" if same else ""),
        field="clip",
    )


def cmu(trial: str) -> tuple[Path, Path]:
    """CMU's own ASF skeleton and AMC motion of ``trial`` (``"SS_TT"``), as published.

    Registered trials come hash-checked from ``PINRECON_DATA`` or the cache; any other trial
    is downloaded once from mocap.cs.cmu.edu (no hash is known for it: a warning says so).
    Read them with :func:`pinrecon.io.amc.load_amc`.
    """
    try:
        subject, _ = trial.split("_")
        int(subject)
    except ValueError:
        raise DatasetError(f"a CMU trial is named like '02_01', not '{trial}'", field="trial") from None
    asf, amc = f"mocap/cmu-asf_{subject}.asf", f"mocap/cmu-asf_{trial}.amc"
    if asf in registry() and amc in registry():
        return fetch(asf), fetch(amc)
    return _cmu_unregistered(subject, trial)


def _cmu_unregistered(subject: str, trial: str) -> tuple[Path, Path]:
    import warnings

    import pooch

    root = data_root()
    if root is not None:
        raise DatasetError(
            f"CMU trial {trial} is not registered and {ENV_DATA} is set (nothing is downloaded); "
            f"registered: {[n for n in names('mocap/cmu-asf_') if n.endswith('.amc')]}",
            field="trial",
        )
    out = []
    for fname in (f"{subject}.asf", f"{trial}.amc"):
        url = f"{CMU_SITE}/{subject}/{fname}"
        warnings.warn(f"{url} has no registered sha256; it is downloaded unchecked", stacklevel=3)
        try:
            out.append(Path(pooch.retrieve(url, known_hash=None, fname=fname, path=cache_dir() / "cmu")))
        except Exception as exc:
            raise DatasetError(
                f"could not download CMU trial {trial} ({url}): {type(exc).__name__}; "
                f"offline? set {ENV_DATA}",
                field="trial",
            ) from None
    return out[0], out[1]
