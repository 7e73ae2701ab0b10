"""From per-frame detections to one subject's tracks, for every detector format.

The detector readers (:mod:`~pinrecon.io.openpose_json`, :mod:`~pinrecon.io.coco`,
:mod:`~pinrecon.io.mmpose`) parse their files into a :class:`Detections`: per frame a
list of :class:`~pinrecon.io.people.Detection`, plus the frames and detections that
could not be read. :func:`to_track_arrays` then does the same for all of them:

1. the number of points per person is the one most frames agree on; a detection with
   another count is dropped (counted in one warning), and when no count holds a
   majority the file is refused;
2. the layout is the one named (``layout=``), the one the file names, or the one the
   geometry picks among the registered layouts with that many points
   (:func:`pinrecon.layouts.detect.detect_layout`);
3. one subject is followed through the frames (:func:`~pinrecon.io.people.select_subject`);
4. frames that could not be read are missing frames, reported in one warning; the
   load fails (with the first problem found) only when no point is left;
5. in files of sub-pixel coordinates, a detected point with a coordinate exactly 0 is
   missing, said in one warning (OpenPose writes 0 for a point it did not find; one such
   coordinate beside a real one, with its confidence kept, is in Pose2Sim's own demo files).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..layouts import (
    BOX,
    LAYOUTS,
    Layout,
    get_layout,
    layout_from_names,
    layouts_with,
    normalise_point_name,
)
from ..layouts.detect import detect_layout
from .people import Detection, select_subject
from .track_arrays import TrackArrays

__all__ = ["Detections", "to_track_arrays", "FORMAT_DEFAULTS"]

# the layout a format means when the geometry contradicts every candidate
FORMAT_DEFAULTS = {"openpose": {25: "body25", 17: "coco17"}, "coco": {17: "coco17", 25: "body25"},
                   "mmpose": {17: "coco17", 25: "body25"}}


@dataclass
class Detections:
    """What a reader found: ``frames[t]`` the detections of frame ``t``; ``broken``
    the errors of frames that could not be read; ``dropped`` the errors of single
    detections that could not be read; ``names`` the point names the file states
    (COCO categories, MMPose meta), if any."""

    source: str
    fmt: str
    frames: list[list[Detection]] = field(default_factory=list)
    broken: list[InputError] = field(default_factory=list)
    dropped: list[InputError] = field(default_factory=list)
    names: list[str] | None = None

    def add_frame(self, detections: list[Detection] | None = None) -> int:
        self.frames.append(list(detections or ()))
        return len(self.frames) - 1


def _first_problem(det: Detections) -> InputError | None:
    probs = det.broken + det.dropped
    return min(probs, key=lambda e: (e.frame is None, e.frame or 0)) if probs else None


def _count(det: Detections) -> int:
    votes = Counter(k for dets in det.frames for k in {d.K for d in dets})
    n_frames = sum(1 for dets in det.frames if dets)
    if not votes:
        first = _first_problem(det)
        if first is not None:
            raise first
        raise InputError("no person is detected in any frame", file=det.source)
    (top, n_top), *rest = votes.most_common()
    if rest and 2 * n_top <= n_frames:
        counts = ", ".join(f"{k} points in {n} frame(s)" for k, n in votes.most_common())
        raise InputError(
            f"the frames disagree on the number of points per person ({counts}): "
            "no count holds a majority, so the broken frames cannot be told",
            file=det.source,
        )
    for t, dets in enumerate(det.frames):
        keep = [d for d in dets if d.K == top]
        if len(keep) < len(dets):
            det.dropped.append(
                InputError(
                    f"{len(dets) - len(keep)} detection(s) with another number of points than {top}",
                    file=det.source,
                    frame=t,
                )
            )
        det.frames[t] = keep
    return top


def _layout(det: Detections, n: int, layout) -> tuple[Layout | None, list[Layout]]:
    """(layout, []) when decided, (None, candidates) when the geometry must decide."""
    if layout is not None:
        lay = get_layout(layout)
        if lay.n_points != n:
            raise InputError(
                f"layout {lay.name} has {lay.n_points} points per person but the file has {n}",
                file=det.source,
                field="layout",
            )
        return lay, []
    if det.names is not None:
        named = layout_from_names(det.names)
        if named is not None and named.n_points == n:
            return named, []
        if len(det.names) == n and all(det.names):
            names = tuple(normalise_point_name(x) for x in det.names)
            if len(set(names)) == len(names):
                return Layout("file", "the file's own point names", n, names, None), []
    candidates = layouts_with(n)
    if not candidates:
        known = ", ".join(f"{lay.n_points} ({lay.title})" for lay in sorted(LAYOUTS.values(), key=lambda x: x.n_points))
        raise InputError(
            f"{n} points per person: no known layout has {n} points (known: {known})",
            file=det.source,
        )
    if len(candidates) == 1:
        return candidates[0], []
    return None, candidates


def to_track_arrays(det: Detections, *, person=None, layout=None, box_only: bool = False) -> TrackArrays:
    """The subject's :class:`TrackArrays` (no frame rate) from a reader's detections;
    see the module docstring. ``box_only``: the detections are boxes (two corners)."""
    notes: list[str] = []
    if box_only:
        if layout is not None and get_layout(layout) is not BOX:
            raise InputError("the file holds boxes only: its layout is 'box'", file=det.source, field="layout")
        n, lay, candidates = _count(det), BOX, []
    else:
        n = _count(det)
        lay, candidates = _layout(det, n, layout)
    T = len(det.frames)
    zeros = [] if box_only else _zero_coordinates(det)
    try:
        pts, conf, report = select_subject(det.frames, n, person)
    except InputError as exc:
        raise exc.located(file=det.source) from None
    if lay is None:
        default = FORMAT_DEFAULTS.get(det.fmt, {}).get(n)
        lay, note = detect_layout(
            pts, candidates, default=get_layout(default) if default else None, source=det.source
        )
    elif lay.name not in ("file", "box") and layout is None:
        lay, note = detect_layout(pts, [lay], source=det.source)
    else:
        note = None
    k = len(lay.names)
    pts, conf = pts[:, :k].copy(), conf[:, :k].copy()
    if not np.isfinite(pts).any():
        first = _first_problem(det)
        if first is not None:
            raise first
        raise InputError("the subject has no detected point in any frame", file=det.source)
    if det.broken:
        frames = sorted({e.frame for e in det.broken if e.frame is not None})
        notes.append(
            f"{det.source}: {len(det.broken)} of {T} frames could not be read and are missing "
            f"(frames {_short(frames)}; first problem: {det.broken[0]})"
        )
    if det.dropped:
        frames = sorted({e.frame for e in det.dropped if e.frame is not None})
        notes.append(
            f"{det.source}: {len(det.dropped)} detection(s) could not be read and were dropped "
            f"(frames {_short(frames)}; first problem: {det.dropped[0].message})"
        )
    if zeros:
        names = sorted({lay.names[k] if k < len(lay.names) else f"point {k}" for _, k in zeros})
        notes.append(
            f"{det.source}: {len(zeros)} detected point(s) had a coordinate exactly 0 with a confidence above 0 "
            f"({', '.join(names[:4])}{' ...' if len(names) > 4 else ''} in frames "
            f"{_short(sorted({t for t, _ in zeros}))}): read as missing. A detector writes 0 for a point it did not "
            "find, and a point clipped to the image's edge is not where it was"
        )
    text = report.text(T)
    if text:
        notes.append(f"{det.source}: {text}")
    if note:
        notes.append(f"{det.source}: {note}")
    return TrackArrays(pts, list(lay.names), None, conf, det.source, lay.name, tuple(notes))


def _zero_coordinates(det: Detections) -> list[tuple[int, int]]:
    """Detected points (confidence above 0) with a coordinate exactly 0, made missing in
    place before the subject is followed (a point at the image's edge would stretch its
    box); returns their (frame, point index). Only in files of sub-pixel coordinates (a
    detector's): where every coordinate is a whole pixel (annotations, such as COCO's),
    0 is the image's first row or column. Pose2Sim's balancing trial has six: the
    nose at x = 0 with confidence 0.65-0.69 in frames 4-8 and 15, its neighbours 530 px
    away."""
    with np.errstate(invalid="ignore"):
        fractional = any(np.any(np.mod(d.points, 1.0) > 0) for dets in det.frames for d in dets)
    if not fractional:  # whole pixels (annotations): 0 is the image's first row or column
        return []
    found = []
    for t, dets in enumerate(det.frames):
        for d in dets:
            bad = (d.conf > 0) & np.any(d.points == 0.0, axis=1)
            if bad.any():
                d.points[bad] = np.nan
                d.conf[bad] = 0.0
                found += [(t, int(k)) for k in np.flatnonzero(bad)]
    return found


def _short(frames: list[int]) -> str:
    return ", ".join(map(str, frames[:8])) + (" ..." if len(frames) > 8 else "")
