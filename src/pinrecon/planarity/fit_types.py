"""Result types of the planarity group fits and of link discovery.

:class:`GroupFit` is the verdict of :func:`~pinrecon.planarity.fit_planar_group`
on one 2- or 3-point group (lengths, plane normal, depths relative to the hinge,
residual against its threshold, planar spans); :class:`Link` (a rigid rod),
:class:`HingedTriple` (two rods hinged in one plane) and :class:`LinkGraph` (all
links and hinges among ``N`` tracked points) are what
:func:`~pinrecon.planarity.discover_links` returns.  They are frozen data with
read-only arrays and human-readable ``summary()`` texts, and compute nothing;
frames and sign conventions are those of :mod:`pinrecon.planarity.propositions`
(orthographic camera, x right, y down, z forward, one global member of the
reflection pair).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .conics import readonly

__all__ = ["GroupFit", "HingedTriple", "Link", "LinkGraph"]


@dataclass(frozen=True, eq=False)
class GroupFit:
    """Result of :func:`fit_planar_group`.

    Attributes
    ----------
    hinge : int
        Index (into the group's points) of the hinge / pivot.
    points : tuple of int
        Indices of the other points, in order; they index the columns of
        ``depths`` and the entries of ``lengths``.
    depths : ndarray, shape (T, R)
        Depth (camera z, forward) of each other point relative to the hinge,
        from the fitted model, one global member of the reflection pair; NaN in
        skipped frames (any needed point missing).
    lengths : ndarray, shape (R,)
        3D rod lengths (input units).
    normal : ndarray, shape (3,)
        Unit plane normal in camera axes, ``n_z >= 0``.
    gradient : ndarray, shape (2,)
        Depth gradient ``g`` (``z = g . uv`` relative to the hinge).
    rms : float
        RMS 2D residual of the hinge-relative image vectors (input units).
    threshold : float
        Largest ``rms`` accepted as planar (noise + model tolerance).
    sigma : float
        Per-coordinate image noise used (given or estimated), input units.
    planar : bool
        Verdict: the group is a pairwise-rigid structure in planar motion over
        all used frames, with a determined plane.
    reason : str
        Short explanation of the verdict.
    degeneracy : str or None
        ``None``, ``"no_planar_interpretation"``, ``"insufficient_motion"``
        (plane/lengths not determined by the data), ``"plane_parallel_to_image"``,
        or ``"too_few_frames"``.
    spans : tuple of (int, int)
        Frame ranges ``[start, stop)`` where planarity holds (the whole used
        range when ``planar``; sliding-window spans otherwise).
    span_fits : tuple of GroupFit
        Separate fits of the spans when the whole sequence is not planar.
    frame_rms : ndarray, shape (T,)
        Per-frame RMS residual (NaN in skipped frames).
    used : ndarray of bool, shape (T,)
        Frames used by the fit.
    length_std : ndarray, shape (R,)
        Standard errors of ``lengths`` (a-posteriori residual variance).
    normal_std_deg : float
        Standard error of the normal direction, degrees.
    """

    hinge: int
    points: tuple[int, ...]
    depths: np.ndarray
    lengths: np.ndarray
    normal: np.ndarray
    gradient: np.ndarray
    rms: float
    threshold: float
    sigma: float
    planar: bool
    reason: str
    degeneracy: str | None
    spans: tuple[tuple[int, int], ...]
    frame_rms: np.ndarray
    used: np.ndarray
    length_std: np.ndarray
    normal_std_deg: float
    span_fits: tuple[GroupFit, ...] = field(default=())

    @property
    def n_frames(self) -> int:
        """Number of frames used."""
        return int(np.count_nonzero(self.used))

    @property
    def tilt_deg(self) -> float:
        """Angle between the motion plane and the image plane, degrees."""
        return float(np.degrees(np.arccos(np.clip(self.normal[2], -1.0, 1.0))))

    @property
    def score(self) -> float:
        """``rms / threshold`` (<= 1 means the residual test passes)."""
        return float(self.rms / self.threshold) if self.threshold > 0 else float("inf")

    def reflected(self) -> GroupFit:
        """The other member of the reflection pair (all depths negated)."""
        return replace(
            self,
            depths=readonly(-self.depths),
            normal=readonly(self.normal * np.array([-1.0, -1.0, 1.0])),
            gradient=readonly(-self.gradient),
            span_fits=tuple(f.reflected() for f in self.span_fits),
        )

    def pair(self) -> tuple[GroupFit, GroupFit]:
        """Both members of the reflection pair."""
        return self, self.reflected()

    def summary(self, names: list[str] | tuple[str, ...] | None = None) -> str:
        """Multi-line human-readable description (``names`` label the group's points)."""
        lab = (lambda i: names[i]) if names is not None else (lambda i: f"p{i}")
        head = "PLANAR" if self.planar else "not planar"
        lines = [f"group hinge={lab(self.hinge)}: {head} ({self.reason})"]
        for k, p in enumerate(self.points):
            lines.append(
                f"  |{lab(self.hinge)}-{lab(p)}| = {self.lengths[k]:.6g} +- {self.length_std[k]:.2g}"
            )
        if np.all(np.isfinite(self.normal)):
            n = self.normal
            lines.append(
                f"  normal (camera x right, y down, z fwd): ({n[0]:+.4f}, {n[1]:+.4f}, {n[2]:+.4f})"
                f"  tilt {self.tilt_deg:.2f} deg +- {self.normal_std_deg:.2g}"
            )
        lines.append(
            f"  residual RMS {self.rms:.4g} (threshold {self.threshold:.4g}, sigma {self.sigma:.3g}), "
            f"{self.n_frames} frames"
        )
        if self.degeneracy:
            lines.append(f"  degeneracy: {self.degeneracy}")
        if self.spans:
            lines.append("  spans: " + ", ".join(f"[{a}, {b})" for a, b in self.spans))
        return "\n".join(lines)

    def __repr__(self) -> str:
        lens = ", ".join(f"{x:.5g}" for x in self.lengths)
        nrm = (
            ("(" + ", ".join(f"{x:+.3f}" for x in self.normal) + ")")
            if np.all(np.isfinite(self.normal))
            else "undetermined"
        )
        return (
            f"GroupFit(hinge={self.hinge}, points={self.points}, planar={self.planar}, lengths=[{lens}], "
            f"normal={nrm}, rms={self.rms:.4g}, threshold={self.threshold:.4g}, "
            f"degeneracy={self.degeneracy!r}, frames={self.n_frames}, spans={list(self.spans)})"
        )

    __str__ = summary


@dataclass(frozen=True, eq=False)
class Link:
    """A rigid rod in planar motion between two points."""

    points: tuple[int, int]
    names: tuple[str, str] | None
    fit: GroupFit

    @property
    def length(self) -> float:
        return float(self.fit.lengths[0])

    @property
    def normal(self) -> np.ndarray:
        return self.fit.normal

    @property
    def rms(self) -> float:
        return self.fit.rms

    def __repr__(self) -> str:
        who = (
            f"{self.names[0]}--{self.names[1]}"
            if self.names
            else f"{self.points[0]}--{self.points[1]}"
        )
        return f"Link({who}, length={self.length:.5g}, rms={self.rms:.3g}, tilt={self.fit.tilt_deg:.1f} deg)"


@dataclass(frozen=True, eq=False)
class HingedTriple:
    """Two rods hinged at ``hinge`` moving in one plane; ``points`` = (end, hinge, end)."""

    points: tuple[int, int, int]
    hinge: int
    names: tuple[str, str, str] | None
    fit: GroupFit
    rigid_triangle: bool = False

    @property
    def lengths(self) -> np.ndarray:
        return self.fit.lengths

    @property
    def normal(self) -> np.ndarray:
        return self.fit.normal

    @property
    def rms(self) -> float:
        return self.fit.rms

    def __repr__(self) -> str:
        lab = self.names or tuple(str(p) for p in self.points)
        tri = ", rigid triangle" if self.rigid_triangle else ""
        return (
            f"HingedTriple({lab[0]}-[{lab[1]}]-{lab[2]}, lengths=({self.lengths[0]:.5g}, "
            f"{self.lengths[1]:.5g}), rms={self.rms:.3g}, tilt={self.fit.tilt_deg:.1f} deg{tri})"
        )


@dataclass(frozen=True, eq=False)
class LinkGraph:
    """Result of :func:`discover_links`.

    Attributes
    ----------
    n_points : int
    names : tuple of str or None
    links : tuple of Link
        Pairs consistent with a rigid rod in planar motion (determined plane).
    triples : tuple of HingedTriple
        Hinged triples (both rods rigid, one common plane).
    hinge : int or None
        For ``n_points == 3``: the point accepted as the hinge (None if no
        hypothesis passed).  For larger sets: None (see ``triples``).
    candidates : tuple of GroupFit
        For ``n_points == 3``: the fits with point 0, 1, 2 as the hinge.
    sigma : float
        Noise level used (input units).
    n_pairs : int
        Pairs examined; ``n_pairs_fitted`` of them survived the cheap prune.
    n_pairs_fitted : int
    """

    n_points: int
    names: tuple[str, ...] | None
    links: tuple[Link, ...]
    triples: tuple[HingedTriple, ...]
    hinge: int | None
    candidates: tuple[GroupFit, ...]
    sigma: float
    n_pairs: int
    n_pairs_fitted: int

    def _chosen(self) -> GroupFit | None:
        return self.candidates[self.hinge] if (self.hinge is not None and self.candidates) else None

    @property
    def depths(self) -> np.ndarray | None:
        """For a triple with an accepted hinge: depths (T, 2) of the other points."""
        f = self._chosen()
        return None if f is None else f.depths

    @property
    def lengths(self) -> np.ndarray | None:
        """For a triple with an accepted hinge: the two rod lengths."""
        f = self._chosen()
        return None if f is None else f.lengths

    @property
    def normal(self) -> np.ndarray | None:
        """For a triple with an accepted hinge: the plane normal."""
        f = self._chosen()
        return None if f is None else f.normal

    @property
    def degeneracy(self) -> str | None:
        """For a triple: None if a hinge was found, else ``"no_hinge_found"``."""
        if self.n_points != 3:
            return None
        return None if self.hinge is not None else "no_hinge_found"

    def _lab(self, i: int) -> str:
        return self.names[i] if self.names else f"p{i}"

    def summary(self) -> str:
        """Multi-line human-readable description."""
        lines = [
            (
                f"LinkGraph: {self.n_points} points, {len(self.links)} links, {len(self.triples)} hinged triples "
                f"(sigma {self.sigma:.3g}; {self.n_pairs_fitted}/{self.n_pairs} pairs fitted after pruning)"
            )
        ]
        if self.candidates:
            for h, f in enumerate(self.candidates):
                mark = "  <- hinge" if h == self.hinge else ""
                lines.append(
                    f"  hinge {self._lab(h)}: {'planar' if f.planar else 'rejected'}, rms {f.rms:.4g} "
                    f"/ threshold {f.threshold:.4g}{mark}"
                )
        for ln in self.links:
            i, j = ln.points
            lines.append(
                f"  link {self._lab(i)} -- {self._lab(j)}: length {ln.length:.5g}, rms {ln.rms:.3g}, "
                f"tilt {ln.fit.tilt_deg:.1f} deg"
            )
        for tr in self.triples:
            i, h, k = tr.points
            lines.append(
                f"  hinge {self._lab(h)} joins {self._lab(i)} ({tr.lengths[0]:.5g}) and {self._lab(k)} "
                f"({tr.lengths[1]:.5g}), rms {tr.rms:.3g}, tilt {tr.fit.tilt_deg:.1f} deg"
                + (" [rigid triangle]" if tr.rigid_triangle else "")
            )
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (
            f"LinkGraph(n_points={self.n_points}, links={[ln.points for ln in self.links]}, "
            f"triples={[t.points for t in self.triples]}, hinge={self.hinge})"
        )

    __str__ = summary
