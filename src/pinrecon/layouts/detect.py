"""Which layout is this? Geometry tells layouts with the same number of points apart.

BODY_25 and BODY_25B both write 25 points, COCO-17 and H36M-17 both 17: read under the
wrong names a sequence still loads, with every point on the wrong body part. The
names carry geometry that only the right reading satisfies:

* ``neck`` is the shoulders' midpoint and ``mid_hip`` the hips' (OpenPose computes them
  so): within 6 % of the person's size;
* eyes and ears are near the nose (within 30 % of the person's size);
* toes and heels are near their ankle (25 %);
* limbs are shorter than 60 % of the person (elbow-shoulder, wrist-elbow, knee-hip,
  ankle-knee);
* H36M's thorax lies near the shoulders' midpoint (12 %).

The person's size in a frame is the diagonal of the box around its detected points.
Each check is scored by its median over the frames where its points are detected, so
a few bad frames do not decide. A layout *fits* when every check it can evaluate
passes, is *contradicted* when one fails, and is *undecided* when none can be
evaluated. :func:`detect_layout` picks the one candidate that fits when the others are
contradicted (or, for the format's default layout, cannot be evaluated); it refuses to
guess when two fit or when the points cannot tell them apart, and falls back to the
format's default layout (with a warning) when the geometry contradicts every candidate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from . import Layout

__all__ = ["Check", "checks_for", "check_layout", "detect_layout", "LayoutVerdict"]


@dataclass(frozen=True)
class Check:
    """``point`` lies within ``tol`` person-sizes of ``ref`` (one name) or of the
    midpoint of ``ref`` and ``ref2``."""

    point: str
    ref: str
    ref2: str | None
    tol: float

    def describe(self) -> str:
        target = f"the midpoint of {self.ref} and {self.ref2}" if self.ref2 else self.ref
        return f"{self.point} within {self.tol:g} person-sizes of {target}"


def _rules() -> list[Check]:
    out = [
        Check("neck", "left_shoulder", "right_shoulder", 0.06),
        Check("mid_hip", "left_hip", "right_hip", 0.06),
        Check("h36m_thorax", "left_shoulder", "right_shoulder", 0.12),
    ]
    out += [Check(p, "nose", None, 0.3) for p in ("left_eye", "right_eye", "left_ear", "right_ear")]
    for side in ("left", "right"):
        out += [Check(f"{side}_{p}", f"{side}_ankle", None, 0.25) for p in ("big_toe", "small_toe", "heel")]
        out += [
            Check(f"{side}_elbow", f"{side}_shoulder", None, 0.6),
            Check(f"{side}_wrist", f"{side}_elbow", None, 0.6),
            Check(f"{side}_knee", f"{side}_hip", None, 0.6),
            Check(f"{side}_ankle", f"{side}_knee", None, 0.6),
        ]
    return out


RULES = _rules()


def checks_for(names) -> list[Check]:
    """The geometry checks a layout with these point names can be held to."""
    have = set(names)
    return [c for c in RULES if c.point in have and c.ref in have and (c.ref2 is None or c.ref2 in have)]


@dataclass(frozen=True)
class LayoutVerdict:
    """``layout`` read against its checks: ``scores`` holds, per evaluated check, the
    median error in person-sizes and the number of frames it was measured on."""

    layout: Layout
    scores: tuple[tuple[Check, float, int], ...]

    @property
    def evaluated(self) -> bool:
        return bool(self.scores)

    @property
    def fits(self) -> bool:
        return self.evaluated and all(err <= c.tol for c, err, _ in self.scores)

    @property
    def contradicted(self) -> bool:
        return any(err > c.tol for c, err, _ in self.scores)

    def worst(self) -> str:
        c, err, n = max(self.scores, key=lambda s: s[1] / s[0].tol)
        return f"{c.describe()}: median {err:.2f} over {n} frame(s)"


def _person_size(points: np.ndarray) -> np.ndarray:
    """(T,) diagonal of the box around each frame's detected points (NaN if < 3 points)."""
    ok = np.all(np.isfinite(points), axis=2)
    n = ok.sum(axis=1)
    big = np.where(ok[..., None], points, np.nan)
    size = np.full(points.shape[0], np.nan)
    rows = n >= 3
    if rows.any():
        sub = big[rows]
        lo = np.nanmin(sub, axis=1)
        hi = np.nanmax(sub, axis=1)
        size[rows] = np.hypot(*(hi - lo).T)
    size[~(size > 0)] = np.nan
    return size


def check_layout(points: np.ndarray, layout: Layout) -> LayoutVerdict:
    """Score ``points`` ((T, >= len(layout.names), 2), NaN where missing) against the
    checks of ``layout``'s names."""
    names = list(layout.names)
    pts = np.asarray(points, dtype=float)[:, : len(names)]
    size = _person_size(pts)
    index = {n: i for i, n in enumerate(names)}
    scores = []
    for c in checks_for(names):
        target = pts[:, index[c.ref]]
        if c.ref2 is not None:
            target = 0.5 * (target + pts[:, index[c.ref2]])
        d = np.hypot(*(pts[:, index[c.point]] - target).T) / size
        d = d[np.isfinite(d)]
        if d.size:
            scores.append((c, float(np.median(d)), int(d.size)))
    return LayoutVerdict(layout, tuple(scores))


def detect_layout(
    points: np.ndarray,
    candidates: list[Layout],
    *,
    default: Layout | None = None,
    source=None,
    field: str | None = None,
) -> tuple[Layout, str | None]:
    """Pick the layout of ``points`` ((T, n_points, 2), NaN where missing) among
    ``candidates`` (all with the same number of points).

    Returns the layout and a warning text (None when the choice is clean). Raises an
    :class:`~pinrecon.errors.InputError` when two candidates fit, or when the geometry
    cannot tell them apart; ``default`` is used (with a warning) when every candidate
    is contradicted.
    """
    if len(candidates) == 1:
        v = check_layout(points, candidates[0])
        if v.contradicted:
            return candidates[0], (
                f"the points do not look like {candidates[0].title} ({v.worst()}); "
                "check the detector's layout"
            )
        return candidates[0], None
    verdicts = [check_layout(points, lay) for lay in candidates]
    fits = [v for v in verdicts if v.fits]
    choices = ", ".join(lay.name for lay in candidates)
    if len(fits) == 1 and all(v.contradicted for v in verdicts if v is not fits[0]):
        return fits[0].layout, None
    if len(fits) == 1 and fits[0].layout is default and not any(v.fits for v in verdicts if v is not fits[0]):
        return default, None  # the format's own layout fits; the others cannot be evaluated
    if len(fits) >= 2 or any(not v.evaluated for v in verdicts):
        which = " and ".join(v.layout.title for v in (fits if len(fits) >= 2 else verdicts))
        raise InputError(
            f"{candidates[0].n_points} points per person: the geometry cannot tell {which} apart; "
            f"name the layout (--layout / layout=): one of {choices}",
            file=source,
            field=field or "layout",
        )
    if default is None or default not in candidates:
        raise InputError(
            f"{candidates[0].n_points} points per person fit none of the layouts with that many points "
            f"({'; '.join(f'{v.layout.title}: {v.worst()}' for v in verdicts)}); "
            f"name the layout (--layout / layout=): one of {choices}",
            file=source,
            field=field or "layout",
        )
    return default, (
        f"the points fit none of {', '.join(lay.title for lay in candidates)} by their geometry "
        f"({'; '.join(f'{v.layout.title}: {v.worst()}' for v in verdicts)}); read as {default.title}, "
        f"the format's default: name the layout (--layout / layout=) if that is wrong"
    )
