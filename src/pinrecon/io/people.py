"""Several people per frame: follow one subject through the sequence.

Detectors list the people of a frame in no stable order: the N-th entry of one frame
is not the N-th of the next. :func:`select_subject` picks the subject once (by index
or bounding box in the first frame where it can, or the most prominent person), then
follows them frame by frame: in each frame it takes the detection whose pose is
closest to the subject's last seen pose (median distance over the points both
detected, in units of the subject's size), provided it is within 0.2 sizes (plus 0.1
per frame the subject was not seen, at most 0.6) and closer to the subject than to
any other person of the previous frame; otherwise the subject is missing in that
frame. It runs forwards and backwards from the frame where the subject was picked.
(On Pose2Sim's two-participant trial a person moves at most 0.01 sizes between
frames, and the nearest other person is 0.24 sizes away.)

``person="largest"`` does not follow anyone: each frame keeps its most prominent
person (for collections of unrelated images, e.g. a COCO dataset file).

Plain data only: numpy arrays in, numpy arrays and a :class:`SubjectReport` out.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["Detection", "SubjectReport", "select_subject", "natural_key", "parse_person", "MAX_COORD"]

MAX_COORD = 1e6
"""Coordinates beyond +-1e6 px are no image position: read as missing."""

GATE_FIRST = 0.2
GATE_PER_FRAME = 0.1
GATE_MAX = 0.6


def natural_key(value) -> tuple:
    """Sort key putting ``"2.jpg"`` before ``"10.jpg"`` (numbers compare as numbers)."""
    parts = re.split(r"(\d+)", str(value))
    return tuple((0, int(p), "") if p.isdigit() else (1, 0, p) for p in parts if p != "")


def _number(value) -> float | None:
    """A finite float of moderate size, else None."""
    if isinstance(value, bool):
        return None
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        return None
    return v if np.isfinite(v) and abs(v) <= MAX_COORD else None


@dataclass
class Detection:
    """One person in one frame: ``points`` (K, 2) NaN where missing, ``conf`` (K,) in
    [0, 1] (0 where missing), optional ``bbox`` (x1, y1, x2, y2) and detector ``score``."""

    points: np.ndarray
    conf: np.ndarray
    bbox: np.ndarray | None = None
    score: float | None = None

    @classmethod
    def from_values(cls, xy, conf, bbox=None, score=None) -> Detection:
        """Clean arrays: non-finite or huge coordinates and confidence <= 0 (or NaN) are
        missing points; confidence is clipped to [0, 1]."""
        xy = np.array(xy, dtype=float).reshape(-1, 2)
        c = np.array(conf, dtype=float).reshape(-1)
        with np.errstate(invalid="ignore"):
            ok = np.all(np.isfinite(xy) & (np.abs(xy) <= MAX_COORD), axis=1) & np.isfinite(c) & (c > 0)
        xy[~ok] = np.nan
        c = np.where(ok, np.clip(np.where(np.isfinite(c), c, 0.0), 0.0, 1.0), 0.0)
        b = None
        if bbox is not None:
            b = np.array(bbox, dtype=float).reshape(-1)[:4]
            if b.shape != (4,) or not np.all(np.isfinite(b) & (np.abs(b) <= MAX_COORD)):
                b = None
        s = _number(score)
        return cls(xy, c, b, s)

    @property
    def K(self) -> int:
        return self.points.shape[0]

    def box(self) -> np.ndarray | None:
        """The detector's box, else the box around the detected points (None if < 2)."""
        if self.bbox is not None:
            return self.bbox
        ok = np.all(np.isfinite(self.points), axis=1)
        if ok.sum() < 2:
            return None
        p = self.points[ok]
        return np.concatenate([p.min(axis=0), p.max(axis=0)])

    def prominence(self) -> float:
        """Detector score if any, else box area times mean confidence of detected points."""
        if self.score is not None:
            return self.score
        b = self.box()
        if b is None:
            return 0.0
        ok = self.conf > 0
        return float(max(b[2] - b[0], 0.0) * max(b[3] - b[1], 0.0) * (self.conf[ok].mean() if ok.any() else 0.0))


@dataclass(frozen=True)
class SubjectReport:
    """How the subject was followed: the frame where it was picked, the frames where it
    was found, the frames where the detector's entry order changed around it (identity
    switches that a take-the-N-th-entry reading would have made), and the frames with
    people where it was not found."""

    mode: str
    start_frame: int | None
    found: int
    order_changes: tuple[int, ...]
    lost: tuple[int, ...]
    crowded: int = 0

    def text(self, n_frames: int) -> str | None:
        """One line for the user; None when there was nobody else to mix up."""
        if self.mode == "largest" or self.start_frame is None or not (self.crowded or self.lost):
            return None
        parts = [f"followed one person from frame {self.start_frame}: found in {self.found} of {n_frames} frames"]
        if self.order_changes:
            parts.append(
                f"{len(self.order_changes)} identity switches of the detector's order resolved "
                f"(first at frame {self.order_changes[0]})"
            )
        if self.lost:
            parts.append(
                f"not found in {len(self.lost)} frames where others were detected (first: {self.lost[0]})"
                + ("; for unrelated images use person='largest'" if 2 * len(self.lost) > n_frames else "")
            )
        return "; ".join(parts)


def parse_person(person):
    """``None``, ``"largest"``, an index (int or digit string) or a box ``(x1, y1, x2, y2)``
    (sequence or ``"x1,y1,x2,y2"``); anything else raises an InputError."""
    if person is None or isinstance(person, (int, np.integer)) and not isinstance(person, bool):
        if person is not None and person < 0:
            raise InputError(f"must be >= 0, got {person}", field="person")
        return None if person is None else int(person)
    if isinstance(person, str):
        s = person.strip().lower()
        if s == "largest":
            return "largest"
        if s.isdigit():
            return int(s)
        person = s.replace(" ", "").split(",")
    try:
        box = np.array(person, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        box = np.zeros(0)
    if box.shape != (4,) or not np.all(np.isfinite(box)) or box[2] <= box[0] or box[3] <= box[1]:
        raise InputError(
            f"expected an index, 'largest' or a box x1,y1,x2,y2 (x2 > x1, y2 > y1), got {person!r}",
            field="person",
        )
    return tuple(float(v) for v in box)


def _size(points: np.ndarray) -> float:
    ok = np.all(np.isfinite(points), axis=1)
    if ok.sum() < 2:
        return np.nan
    p = points[ok]
    s = float(np.hypot(*(p.max(axis=0) - p.min(axis=0))))
    return s if s > 0 else np.nan


def _distance(subject: np.ndarray, det: Detection) -> float:
    """Median point distance over the points both have, in subject sizes (box centres
    when fewer than 2 points are shared); inf when nothing can be compared."""
    size = _size(subject)
    if not np.isfinite(size):
        return np.inf
    both = np.all(np.isfinite(subject), axis=1) & np.all(np.isfinite(det.points), axis=1)
    if both.sum() >= 2:
        return float(np.median(np.hypot(*(subject[both] - det.points[both]).T)) / size)
    ok = np.all(np.isfinite(subject), axis=1)
    b = det.box()
    if b is None:
        return np.inf
    c_sub = 0.5 * (subject[ok].min(axis=0) + subject[ok].max(axis=0))
    return float(np.hypot(*(0.5 * (b[:2] + b[2:]) - c_sub)) / size)


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    if w <= 0 or h <= 0:
        return 0.0
    inter = w * h
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return float(inter / union) if union > 0 else 0.0


def _start(frames: list[list[Detection]], person) -> tuple[int, int] | None:
    """(frame, index) where the subject is picked, or None when nobody fits."""
    for t, dets in enumerate(frames):
        if not dets:
            continue
        if person is None:
            return t, int(np.argmax([d.prominence() for d in dets]))
        if isinstance(person, int):
            if len(dets) > person:
                return t, person
            continue
        box = np.array(person)
        ious = [(_iou(box, b), i) for i, d in enumerate(dets) if (b := d.box()) is not None]
        best = max(ious, default=(0.0, -1))
        if best[0] > 0.1:
            return t, best[1]
    return None


def _follow(frames, t0: int, i0: int, step: int, chosen: list, order_changes: list, lost: list) -> None:
    last = frames[t0][i0].points
    last_t, last_i = t0, i0
    others = [d.points for i, d in enumerate(frames[t0]) if i != i0]
    t = t0 + step
    while 0 <= t < len(frames):
        dets = frames[t]
        if dets:
            gap = abs(t - last_t)
            gate = min(GATE_FIRST + GATE_PER_FRAME * (gap - 1), GATE_MAX)
            d = [_distance(last, det) for det in dets]
            k = int(np.argmin(d))
            # the best candidate must be within the gate and closer to the subject than to
            # anyone else seen in the previous frame with people (no swap onto a neighbour)
            if d[k] <= gate and all(_distance(o, dets[k]) > d[k] for o in others):
                chosen[t] = k
                if k != last_i:
                    order_changes.append(t)
                last, last_t, last_i = dets[k].points, t, k
                others = [x.points for i, x in enumerate(dets) if i != k]
            else:
                lost.append(t)
                others = [x.points for x in dets]
        t += step


def select_subject(frames: list[list[Detection]], K: int, person=None) -> tuple[np.ndarray, np.ndarray, SubjectReport]:
    """(T, K, 2) points and (T, K) confidence of one person through ``frames`` (lists of
    detections with K points each), and how it was followed. ``person``: see
    :func:`parse_person`."""
    person = parse_person(person)
    T = len(frames)
    pts = np.full((T, K, 2), np.nan)
    conf = np.zeros((T, K))
    if person == "largest":
        n = 0
        for t, dets in enumerate(frames):
            if dets:
                d = dets[int(np.argmax([x.prominence() for x in dets]))]
                pts[t], conf[t] = d.points, d.conf
                n += 1
        return pts, conf, SubjectReport("largest", None, n, (), ())
    start = _start(frames, person)
    if start is None:
        what = "nobody is detected in any frame" if person is None else (
            f"no frame has a person {person}" if isinstance(person, int)
            else f"no detection overlaps the box {person}"
        )
        raise InputError(what, field="person")
    t0, i0 = start
    chosen: list[int | None] = [None] * T
    chosen[t0] = i0
    order_changes: list[int] = []
    lost: list[int] = []
    _follow(frames, t0, i0, +1, chosen, order_changes, lost)
    _follow(frames, t0, i0, -1, chosen, order_changes, lost)
    for t, k in enumerate(chosen):
        if k is not None:
            pts[t], conf[t] = frames[t][k].points, frames[t][k].conf
    found = sum(k is not None for k in chosen)
    crowded = sum(len(dets) > 1 for dets in frames)
    report = SubjectReport("follow", t0, found, tuple(sorted(order_changes)), tuple(sorted(lost)), crowded)
    return pts, conf, report
