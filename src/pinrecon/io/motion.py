"""The motion a result holds, checked before anything writes or draws it.

:func:`check_motion` refuses what no export can write (a BVH with Frame Time 0, an SVD of
infinities): called by :func:`pinrecon.result.load_result` and by every writer of motions
(:func:`pinrecon.io.bvh.write_bvh`, :func:`pinrecon.io.csv_export.write_csv`,
:meth:`pinrecon.Result.save`).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .fields import first_bad_frame, number_field
from .results import MAX_FPS, MAX_VALUE

__all__ = ["check_motion"]


def check_motion(figure, q, fps, *, file=None) -> None:
    """Refuse a motion no export can write: ``fps`` not a finite positive number, ``q`` of
    the wrong width, with a NaN, an infinity or a value beyond ``MAX_VALUE``, or a quaternion
    (or a continuous joint's cos/sin pair) of zero length. One InputError naming the field
    and the frame."""
    q = np.asarray(q)
    number_field(fps, file=file, field="fps", low=0, low_open=True, high=MAX_FPS)
    if q.ndim != 2 or q.shape[1] != figure.nq or q.dtype.kind not in "iuf":
        raise InputError(f"must be (T, {figure.nq}) numbers for figure {figure.name!r}, got {q.dtype} {q.shape}",
                         file=file, field="q")
    q = q.astype(float)
    t = first_bad_frame(~np.isfinite(q))
    if t is not None:
        raise InputError("NaN or infinite configuration value", file=file, field="q", frame=t)
    t = first_bad_frame(np.abs(q) > MAX_VALUE)
    if t is not None:
        raise InputError(f"a joint value beyond +-{MAX_VALUE:g}", file=file, field="q", frame=t)
    m = figure.model
    for jid in range(1, m.njoints):
        nq, nv, iq = m.nqs[jid], m.nvs[jid], m.idx_qs[jid]
        if nq == nv:
            continue
        shortname = m.joints[jid].shortname()
        k = 2 if ("Unbounded" in shortname or "Planar" in shortname) else 4
        unit = q[:, iq + nq - k: iq + nq]
        norm = np.linalg.norm(unit, axis=1)
        t = first_bad_frame(norm < 1e-6)
        if t is not None:
            raise InputError(f"joint {m.names[jid]!r}: its quaternion (or cos/sin pair) has zero length",
                             file=file, field="q", frame=t)
