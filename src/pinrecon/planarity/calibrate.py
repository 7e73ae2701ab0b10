"""Segment lengths from 2D tracks, figure calibration and scale estimation.

Everything here starts from 2D tracks alone.  A figure's *segments* are the pairs
(parent keypoint, child keypoint) of its kinematic tree among the tracked points
(coincident keypoints, e.g. BVH joints with zero OFFSET, count as one point), and its
*kinematic triples* are the chains ``(parent, hinge, child)`` through one tracked
keypoint.  Each triple is tested with :func:`~pinrecon.planarity.fit_planar_group`
(hinge in the middle); a triple that passes gives the 3D lengths of both its rods in
image units, up to nothing: lengths are invariant under the reflection pair.

Lengths are graded:

* ``"limb"``: from an accepted triple that is an unbranched chain (the parent's only
  tracked child is the hinge and the hinge's only tracked child is the end: thigh-shank,
  upper arm-forearm, shank-foot).  These are the reliable ones.
* ``"triple"``: from another accepted triple (e.g. pelvis-thigh at the hip).  A
  branching point does not hinge in one plane, so such a fit can pass and still be
  wrong (on the CMU walk the pelvis half comes out 22 % short): reported, not used to
  calibrate.
* ``"projected"``: no planar fit; the 99th percentile of the projected length, a lower
  bound of the 3D length (exact only if the segment is sometimes seen side-on).

Image units become metres with the orthographic camera's scale (pixels per metre).  A
perspective camera has no single scale; pass ``scale`` (the local scale ``f / depth``
at the figure, weak perspective) to get metres.

See ``docs/planarity.md`` (section "Seeding").
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from .fit_types import GroupFit
from .groups import estimate_noise_sigma, fit_planar_group

__all__ = [
    "Calibration",
    "ScaleEstimate",
    "SegmentLength",
    "SegmentLengths",
    "calibrate_figure",
    "estimate_scale",
    "figure_segments",
    "kinematic_triples",
    "model_lengths",
    "segment_lengths",
    "track_array",
]

#: gradings, best first
METHODS = ("limb", "short", "triple", "projected")

#: a limb rod shorter than this many image-noise sigmas is graded "short"
MIN_LENGTH_SIGMAS = 25.0


# --------------------------------------------------------------------------
# figure structure
# --------------------------------------------------------------------------
def _representatives(figure, names: Sequence[str]) -> dict[str, str]:
    """Map every keypoint of the figure to the tracked name it coincides with (if any)."""
    tracked = set(names)
    rep = {n: n for n in names}
    for group in figure.coincident_keypoints():
        hit = [g for g in group if g in tracked]
        if hit:
            for g in group:
                rep.setdefault(g, hit[0])
    return rep


def _tracked_parents(figure, names: Sequence[str]) -> dict[str, str | None]:
    """Nearest tracked ancestor of each tracked keypoint (coincident points merged)."""
    names = list(names)
    figure.keypoint_index(names)  # raises a helpful error for unknown names
    rep = _representatives(figure, names)
    parents = figure.parents_of_keypoints
    kn = figure.keypoint_names
    out: dict[str, str | None] = {}
    for n in names:
        p = parents[kn.index(n)]
        seen = 0
        found = None
        while p is not None and seen <= len(kn):
            cand = rep.get(kn[p])
            if cand is not None and cand != n:
                found = cand
                break
            p = parents[p]
            seen += 1
        out[n] = found
    return out


def figure_segments(figure, names: Sequence[str] | None = None) -> list[tuple[str, str]]:
    """(parent, child) keypoint pairs of the kinematic tree among ``names``.

    ``names`` defaults to the figure's distinct keypoints.  The parent is the nearest
    ancestor keypoint that is in ``names`` (keypoints coinciding with a named one count
    as that one), so untracked intermediate points are skipped.
    """
    names = list(figure.distinct_keypoint_names if names is None else names)
    par = _tracked_parents(figure, names)
    return [(p, n) for n, p in par.items() if p is not None]


def kinematic_triples(figure, names: Sequence[str] | None = None) -> list[tuple[tuple[str, str, str], bool]]:
    """Chains ``(parent, hinge, child)`` among ``names`` and whether each is a *limb*.

    A limb triple is unbranched: the parent's only child among ``names`` is the hinge
    and the hinge's only child is the end (hip-knee-ankle, shoulder-elbow-wrist for
    COCO-17; LeftUpLeg-LeftLeg-LeftFoot for the CMU skeleton).
    """
    segs = figure_segments(figure, names)
    children: dict[str, list[str]] = {}
    parent: dict[str, str] = {}
    for p, c in segs:
        children.setdefault(p, []).append(c)
        parent[c] = p
    out = []
    for p, j in segs:
        for c in children.get(j, []):
            limb = len(children[p]) == 1 and len(children[j]) == 1
            out.append(((p, j, c), limb))
    return out


def model_lengths(figure, segments: Sequence[tuple[str, str]]) -> tuple[np.ndarray, np.ndarray]:
    """Segment lengths (metres) of the figure and whether each is rigid (constant).

    ``segments``: (parent keypoint, child keypoint) name pairs.  Returns ``(length_m
    (S,), rigid (S,) bool)``; a segment is rigid when its length is the same in the
    neutral and two random configurations.
    """
    qs = [figure.neutral(), figure.random_configuration(3), figure.random_configuration(4)]
    if not segments:
        return np.zeros(0), np.zeros(0, bool)
    a = figure.keypoint_index([s[0] for s in segments])
    b = figure.keypoint_index([s[1] for s in segments])
    L = np.stack([np.linalg.norm(figure.keypoints(q)[b] - figure.keypoints(q)[a], axis=1) for q in qs])
    rigid = np.ptp(L, axis=0) <= 1e-6 * np.maximum(L[0], 1e-9) + 1e-12
    return L[0], rigid


# --------------------------------------------------------------------------
# lengths from tracks
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class SegmentLength:
    """Estimated 3D length of one segment.

    ``length`` is in image units, ``length_m`` in metres (NaN without a scale); ``std``
    its standard error (image units); ``method`` one of ``"limb"``, ``"short"``,
    ``"triple"``, ``"projected"`` (see the module docstring; only ``"limb"`` is
    ``reliable``); ``hinge`` the triple it came from.
    """

    segment: tuple[str, str]
    length: float
    length_m: float
    std: float
    method: str
    hinge: tuple[str, str, str] | None = None

    @property
    def reliable(self) -> bool:
        return self.method == "limb"


@dataclass(frozen=True)
class SegmentLengths:
    """Result of :func:`segment_lengths`: one :class:`SegmentLength` per segment, the
    accepted triple fits (``fits``: (parent, hinge, child) -> GroupFit), the scale
    (px/m or None) and the image noise ``sigma`` used to grade short rods."""

    items: tuple[SegmentLength, ...]
    scale: float | None
    fits: dict = field(default_factory=dict)
    sigma: float = float("nan")

    def __iter__(self):
        return iter(self.items)

    def __len__(self):
        return len(self.items)

    def __getitem__(self, segment) -> SegmentLength:
        seg = tuple(segment)
        for it in self.items:
            if it.segment == seg or it.segment == seg[::-1]:
                return it
        raise KeyError(f"no segment {seg}; segments are {[it.segment for it in self.items]}")

    def as_dict(self, unit: str = "m", reliable_only: bool = False) -> dict[tuple[str, str], float]:
        """{segment: length} in metres (``unit="m"``) or image units (``"px"``)."""
        return {
            it.segment: (it.length_m if unit == "m" else it.length)
            for it in self.items
            if it.reliable or not reliable_only
        }

    def summary(self) -> str:
        lines = [f"segment lengths ({'scale %.6g px/m' % self.scale if self.scale else 'no scale'})"]
        for it in self.items:
            val = f"{it.length:9.2f} px" + (f"  {it.length_m:7.4f} m" if self.scale else "")
            via = f" via {'-'.join(it.hinge)}" if it.hinge else ""
            seg = f"{it.segment[0]:>16s} -> {it.segment[1]:<16s}"
            lines.append(f"  {seg} {val}  +- {it.std:.2g} px  [{it.method}{via}]")
        return "\n".join(lines)

    __str__ = summary


def _scale_of(camera, scale):
    if scale is not None:
        s = float(scale)
        if not (np.isfinite(s) and s > 0):
            raise InputError(f"must be a positive number (pixels per metre), got {scale!r}", field="scale")
        return s
    if camera is not None and hasattr(camera, "scale"):
        return float(camera.scale)
    return None


def track_array(tracks, names):
    """Image positions (T, len(names), 2) of the named points of ``tracks`` (NaN missing).

    An unknown name raises :class:`~pinrecon.errors.UnknownNameError` listing the
    tracked names.
    """
    idx = {n: i for i, n in enumerate(tracks.names)}
    missing = [n for n in names if n not in idx]
    if missing:
        from ..errors import UnknownNameError

        raise UnknownNameError("track", missing, tracks.names, file=tracks.source, field="names")
    return tracks.points[:, [idx[n] for n in names]]


def _projected_length(x: np.ndarray, window: int = 9) -> tuple[float, float]:
    """Lower bound of a segment's 3D length: the 99th percentile of its projected length,
    smoothed over ``window`` frames first (image noise would otherwise push a high
    percentile above the true length)."""
    d = np.linalg.norm(x[:, 1] - x[:, 0], axis=-1)
    ok = np.isfinite(d)
    if not ok.any():
        return float("nan"), float("nan")
    w = min(window, int(ok.sum()))
    k = np.ones(w)
    num = np.convolve(np.where(ok, d, 0.0), k, mode="valid")
    den = np.convolve(ok.astype(float), k, mode="valid")
    sm = num[den >= 0.75 * w] / den[den >= 0.75 * w]
    if not sm.size:
        sm = d[ok]
    return float(np.percentile(sm, 99)), float(np.std(d[ok]) / np.sqrt(w))


def _fit_ok(f: GroupFit) -> bool:
    return bool(f.planar and f.degeneracy in (None, "plane_parallel_to_image") and f.n_frames >= 4)


def segment_lengths(
    tracks,
    figure=None,
    *,
    segments: Sequence[tuple[str, str]] | None = None,
    camera=None,
    scale: float | None = None,
    sigma: float | None = None,
    branching: bool = False,
    min_length_sigmas: float = MIN_LENGTH_SIGMAS,
    seed: int | None = 0,
) -> SegmentLengths:
    """3D segment lengths from 2D tracks.

    Parameters
    ----------
    tracks : :class:`pinrecon.Tracks`.
    figure : gives the kinematic tree (which points are joined); without one, pass
        ``segments`` and the triples are the chains formed by them.
    segments : (parent, child) name pairs; default :func:`figure_segments`.
    camera, scale : the orthographic camera (its ``scale``) or a scale in pixels per
        metre, for ``length_m``; otherwise ``length_m`` is NaN.
    sigma : image noise (pixels) for the group fits; None estimates it from the tracks.
    branching : also fit the triples through branching points (graded ``"triple"``).
    min_length_sigmas : a limb rod shorter than this many noise sigmas is graded
        ``"short"`` (its relative error is too large to calibrate with).
    seed : random seed of the group fits.

    Returns
    -------
    SegmentLengths
    """
    s = _scale_of(camera, scale)
    if figure is not None:
        names = [n for n in tracks.names if n in figure.keypoint_names]
        if segments is None:
            segments = figure_segments(figure, names)
        triples = [(t, limb) for t, limb in kinematic_triples(figure, names) if limb or branching]
    else:
        if segments is None:
            raise InputError("pass a figure or the segments (parent, child) to measure", field="segments")
        segments = [(str(sg[0]), str(sg[1])) for sg in segments]
        children: dict[str, list[str]] = {}
        for p, c in segments:
            children.setdefault(p, []).append(c)
        triples = []
        for p, j in segments:
            for c in children.get(j, []):
                limb = len(children[p]) == 1 and len(children[j]) == 1
                if limb or branching:
                    triples.append(((p, j, c), limb))
    involved = sorted({n for sg in segments for n in sg})
    sig_img = float(sigma) if sigma is not None else estimate_noise_sigma(track_array(tracks, involved))
    fits = []
    for tri, limb in triples:
        x = track_array(tracks, list(tri))
        fits.append((tri, limb, fit_planar_group(x, hinge=1, sigma=sigma, seed=seed)))
    # candidates per segment
    cand: dict[frozenset, list] = {}
    accepted = {}
    for tri, limb, f in fits:
        use = f if _fit_ok(f) else None
        if use is None and f.span_fits:
            ok = [sf for sf in f.span_fits if _fit_ok(sf)]
            use = max(ok, key=lambda sf: sf.n_frames) if ok else None  # the longest planar span
        if use is None:
            continue
        accepted[tri] = use
        for k, seg in enumerate(((tri[0], tri[1]), (tri[1], tri[2]))):
            L, sd = float(use.lengths[k]), float(use.length_std[k])
            method = "limb" if limb else "triple"
            if method == "limb" and np.isfinite(sig_img) and L < min_length_sigmas * sig_img:
                method = "short"
            cand.setdefault(frozenset(seg), []).append((METHODS.index(method), sd / max(L, 1e-12), L, sd, method, tri))
    items = []
    for seg in segments:
        seg = (str(seg[0]), str(seg[1]))
        c = cand.get(frozenset(seg))
        if c:
            _, _, L, sd, method, tri = min(c, key=lambda e: (e[0], e[1]))
        else:
            L, sd = _projected_length(track_array(tracks, list(seg)))
            method, tri = "projected", None
        items.append(SegmentLength(seg, L, L / s if s else float("nan"), sd, method, tri))
    return SegmentLengths(tuple(items), s, accepted, sig_img)


# --------------------------------------------------------------------------
# scale and calibration
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class ScaleEstimate:
    """Orthographic scale (pixels per metre) from measured vs model segment lengths.

    ``scale`` is the weighted median of the per-segment ratios ``ratios``
    (segment -> px/m) of the reliable segments; ``spread`` their relative
    median absolute deviation.
    """

    scale: float
    spread: float
    ratios: dict
    n_segments: int

    def __float__(self):
        return float(self.scale)


def _wmedian(x, w):
    o = np.argsort(x)
    x, w = np.asarray(x)[o], np.asarray(w)[o]
    c = np.cumsum(w)
    return float(x[np.searchsorted(c, 0.5 * c[-1])])


def estimate_scale(figure, tracks, *, lengths: SegmentLengths | None = None, sigma=None, seed=0) -> ScaleEstimate:
    """Estimate the orthographic scale (px/m) of ``tracks`` of a known ``figure``.

    Each reliable (``"limb"``) segment gives ``measured px / model m``; the estimate is
    their median weighted by the model length (long segments are relatively more
    precise).  Without any reliable segment, the accepted ``"triple"`` ones are used.
    """
    lengths = lengths or segment_lengths(tracks, figure, sigma=sigma, seed=seed)
    segs = [it for it in lengths if it.method == "limb"] or [it for it in lengths if it.method == "triple"]
    if not segs:
        raise InputError(
            "no planar limb was found in the tracks, so the scale cannot be estimated "
            "(needs a hinged chain such as hip-knee-ankle moving in a plane)",
            field="tracks",
        )
    L_model, rigid = model_lengths(figure, [it.segment for it in segs])
    keep = [(it, Lm) for it, Lm, r in zip(segs, L_model, rigid) if r and Lm > 0]
    ratios = {it.segment: it.length / Lm for it, Lm in keep}
    x = np.array(list(ratios.values()))
    w = np.array([Lm for _, Lm in keep])
    s = _wmedian(x, w)
    spread = float(1.4826 * np.median(np.abs(x / s - 1.0)))
    return ScaleEstimate(s, spread, ratios, len(keep))


@dataclass(frozen=True)
class Calibration:
    """Result of :func:`calibrate_figure`.

    figure : the calibrated :class:`~pinrecon.Figure` (URDF segments rescaled).
    joint_scales : URDF joint name -> factor applied to its origin translation.
    segment_scales : segment -> factor (measured / model length).
    global_scale : factor applied to segments that were not reliably measured.
    lengths : the measured :class:`SegmentLengths`.
    """

    figure: object
    joint_scales: dict
    segment_scales: dict
    global_scale: float
    lengths: SegmentLengths

    def save_urdf(self, path: str | os.PathLike) -> None:
        """Write the calibrated URDF (atomically)."""
        self.figure.save_urdf(path)

    def summary(self) -> str:
        lines = [f"calibration: global factor {self.global_scale:.4f}"]
        for seg, f in self.segment_scales.items():
            lines.append(f"  {seg[0]} -> {seg[1]}: x{f:.4f}")
        return "\n".join(lines)


def _segment_joints(figure, segment: tuple[str, str]) -> list[str]:
    """URDF joints (movable and fixed) on the kinematic path from the parent keypoint's
    frame to the child keypoint's frame: their origins carry the segment's length."""
    model = figure.model
    kp = {k.name: k for k in figure.keypoints_def}
    fa = model.getFrameId(kp[segment[0]].frame)
    fb = model.getFrameId(kp[segment[1]].frame)

    def chain(fid):
        out = []
        while True:
            out.append(fid)
            if fid == 0:
                return out
            fid = model.frames[fid].parentFrame

    anc_a = set(chain(fa))
    joints = []
    for fid in chain(fb):
        if fid in anc_a:
            break
        fr = model.frames[fid]
        if fr.type in _joint_frame_types():
            joints.append(fr.name)
    return joints


def _joint_frame_types():
    import pinocchio as pin

    return (pin.FrameType.JOINT, pin.FrameType.FIXED_JOINT)


def calibrate_figure(
    figure,
    tracks=None,
    *,
    camera=None,
    scale: float | None = None,
    lengths: SegmentLengths | Mapping | None = None,
    sigma=None,
    seed=0,
    iterations: int = 3,
) -> Calibration:
    """Rescale the figure's URDF segments to lengths measured from 2D tracks.

    Parameters
    ----------
    figure : the figure to calibrate (needs its URDF text).
    tracks : 2D tracks of (some of) its keypoints; not needed when ``lengths`` is given.
    camera, scale : the pixel-to-metre scale (orthographic camera or px/m).
    lengths : a :class:`SegmentLengths`, or a mapping ``{(parent, child): metres}``.
    iterations : fixed-point corrections (a keypoint offset from its frame makes a
        segment's length not exactly proportional to its joints' translations).

    Returns
    -------
    Calibration
        Reliable segments get their own factor (measured / model length); every other
        URDF joint and keypoint offset gets the weighted median factor, so the figure is
        never left at a wrong overall size.  ``Calibration.figure.save_urdf(path)``
        writes it.
    """
    if figure.urdf_xml is None:
        raise InputError("this figure has no URDF to rescale", field="figure")
    if lengths is None:
        if tracks is None:
            raise InputError("pass tracks or measured lengths", field="tracks")
        s = _scale_of(camera, scale)
        if s is None:
            raise InputError(
                "calibrating in metres needs the camera scale: pass an orthographic camera "
                "or scale=pixels per metre (for a perspective camera, f / depth)",
                field="scale",
            )
        lengths = segment_lengths(tracks, figure, camera=camera, scale=s, sigma=sigma, seed=seed)
    if isinstance(lengths, SegmentLengths):
        target = lengths.as_dict("m", reliable_only=True)
        if not target:
            target = {it.segment: it.length_m for it in lengths if it.method == "triple"}
        seg_lengths = lengths
    else:
        target = {tuple(k): float(v) for k, v in lengths.items()}
        seg_lengths = SegmentLengths(
            tuple(SegmentLength(k, float("nan"), v, float("nan"), "given") for k, v in target.items()), None
        )
    target = {k: v for k, v in target.items() if np.isfinite(v) and v > 0}
    if not target:
        raise InputError("no reliable segment length to calibrate with", field="lengths")
    segs = list(target)
    L0, rigid = model_lengths(figure, segs)
    bad = [sg for sg, r, l0 in zip(segs, rigid, L0) if not r or l0 <= 0]
    segs = [sg for sg in segs if sg not in bad]
    if not segs:
        raise InputError(f"the measured segments {bad} are not rigid segments of the figure", field="lengths")
    L0 = model_lengths(figure, segs)[0]
    ratio = np.array([target[sg] for sg in segs]) / L0
    g = _wmedian(ratio, L0)
    seg_scale = dict(zip(segs, ratio))
    # URDF joint -> factor
    from ..figure_files import urdf_joint_names

    all_joints = urdf_joint_names(figure.urdf_xml)
    owner: dict[str, tuple[str, str]] = {}
    for sg in segs:
        for jn in _segment_joints(figure, sg):
            if jn in all_joints:
                owner.setdefault(jn, sg)
    kp_owner = {sg[1]: sg for sg in segs}
    factors = dict(seg_scale)
    cal = figure
    for _ in range(max(1, iterations)):
        js = {jn: (factors[owner[jn]] if jn in owner else g) for jn in all_joints}
        ks = {k.name: (factors[kp_owner[k.name]] if k.name in kp_owner else g) for k in figure.keypoints_def}
        cal = figure.rescaled(js, ks)
        got = model_lengths(cal, segs)[0]
        err = np.array([target[sg] for sg in segs]) / got
        if np.max(np.abs(err - 1.0)) < 1e-9:
            break
        factors = {sg: factors[sg] * e for sg, e in zip(segs, err)}
    return Calibration(cal, js, {sg: float(factors[sg]) for sg in segs}, float(g), seg_lengths)
