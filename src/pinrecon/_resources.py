"""Where bundled models and clips live, installed or in a source checkout."""

from __future__ import annotations

import importlib.metadata
from functools import lru_cache
from pathlib import Path

from .errors import InputError

_PKG = Path(__file__).resolve().parent


@lru_cache(maxsize=None)
def models_dir() -> Path:
    """The ``models/`` folder: inside the installed wheel, else the repository root."""
    for candidate in (_PKG / "models", _PKG.parent.parent / "models"):
        if (candidate / "keypoints").is_dir():
            return candidate
    raise FileNotFoundError(
        "pinrecon's bundled models/ folder was not found; reinstall pinrecon (pip install .)"
    )


def model_path(*parts: str) -> Path:
    return models_dir().joinpath(*parts)


def bundled_clip(name: str = "walk") -> Path:
    """Path of a CMU clip: 'walk' (02_01), 'run' (09_01), 'spin' (05_11), 'dance' (05_02), or a
    registered dataset name; fetched through :mod:`pinrecon.datasets`."""
    from .datasets import clip

    return clip(name)


@lru_cache(maxsize=None)
def example_robot_data_robots() -> Path:
    """``share/example-robot-data/robots`` of the installed example-robot-data package.

    example-robot-data 6 ships no Python loader; its files sit under the cmeel prefix of
    the distribution, which we locate through the package metadata (no hard-coded
    site-packages path).
    """
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError as exc:  # pragma: no cover - dependency
        raise FileNotFoundError(
            "example-robot-data is not installed: pip install example-robot-data"
        ) from exc
    for f in dist.files or ():
        s = str(f).replace("\\", "/")
        if s.endswith("robots/human_description/robots/human.urdf"):
            urdf = Path(dist.locate_file(f)).resolve()
            return urdf.parents[2]
    raise FileNotFoundError("example-robot-data is installed but has no human_description")
