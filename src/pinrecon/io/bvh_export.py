"""Exports of a saved result: :func:`export_result` for the ``pinrecon export`` command.

It reads the result through :mod:`pinrecon.result` (never the pipeline) and writes with
:func:`pinrecon.io.bvh.write_bvh` and :func:`pinrecon.io.csv_export.write_csv`.
:func:`urdf_figure_to_bvh` (:mod:`pinrecon.io.bvh_urdf`) and :func:`continuous_euler`
(:mod:`pinrecon.rotations`) are re-exported here, where they used to live.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import InputError
from ..result import load_result
from ..rotations import continuous_euler
from .bvh import write_bvh
from .bvh_urdf import urdf_figure_to_bvh
from .csv_export import write_csv

__all__ = ["export_result", "urdf_figure_to_bvh", "continuous_euler"]


def export_result(
    npz_path: str | os.PathLike,
    bvh: str | os.PathLike | None = None,
    csv: str | os.PathLike | None = None,
) -> list[Path]:
    """Export a result NPZ as BVH and/or CSV (the ``pinrecon export`` command).

    Parameters
    ----------
    npz_path : a result written by :meth:`pinrecon.Result.save`.
    bvh : BVH output path (:func:`pinrecon.io.bvh.write_bvh`; BVH figures write back
        in their own skeleton and unit, URDF figures in metres, see
        :func:`urdf_figure_to_bvh`).
    csv : CSV output path (:func:`pinrecon.io.csv_export.write_csv`).

    Returns the paths written. Output folders are created.
    """
    if bvh is None and csv is None:
        raise InputError("nothing to do: give a BVH and/or a CSV output path", field="bvh/csv")
    result = load_result(npz_path)
    if result.figure is None:
        raise InputError(
            "the result has no embedded figure; cannot export", file=npz_path, field="figure_urdf"
        )
    written = []
    if bvh is not None:
        bvh = Path(bvh)
        bvh.parent.mkdir(parents=True, exist_ok=True)
        write_bvh(bvh, result.figure, result.q, result.fps)
        written.append(bvh)
    if csv is not None:
        csv = Path(csv)
        csv.parent.mkdir(parents=True, exist_ok=True)
        write_csv(csv, result)
        written.append(csv)
    return written
