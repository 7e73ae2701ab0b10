"""Structure from planar motion (Hoffman & Flinchbaugh 1982).

Orthographic camera, axes x right, y down, z forward; all vectors relative to
the pivot/hinge.  See ``docs/planarity.md`` for the derivations.

* :func:`rod_from_three_views` - Proposition 1 (one rod, three views).
* :func:`hinge_from_two_views` - Proposition 2 (two hinged rods, two views).
* :func:`fit_planar_group` - robust least-squares test of a 2/3-point group
  over a sequence (verdict, lengths, plane, depths, planar spans).
* :func:`discover_links` - rigid links and hinges among many tracked points.
* :func:`segment_lengths`, :func:`calibrate_figure`, :func:`estimate_scale` - a
  figure's segment lengths, calibrated URDF and the orthographic scale from 2D tracks.
* :func:`planarity_seed` / :func:`seed_trajectory` - the start trajectory of
  ``reconstruct(..., seed="planarity")``; :func:`limb_flip_rate` - share of limbs on
  the wrong side of their reflection; :func:`links_report` - ``pinrecon links``.
"""

from .fit_types import GroupFit, HingedTriple, Link, LinkGraph
from .groups import DEFAULT_MODEL_TOL, estimate_noise_sigma, fit_planar_group
from .links import discover_links
from .calibrate import (
    Calibration,
    ScaleEstimate,
    SegmentLength,
    SegmentLengths,
    calibrate_figure,
    estimate_scale,
    figure_segments,
    kinematic_triples,
    segment_lengths,
)
from .propositions import DEFAULT_RTOL, PlanarSolution, hinge_from_two_views, rod_from_three_views
from .seed import (
    LimbLift,
    RelativeDepth,
    Seed,
    default_limbs,
    lift_limbs,
    limb_flip_rate,
    links_report,
    planarity_seed,
    seed_trajectory,
)

__all__ = [
    "Calibration",
    "LimbLift",
    "RelativeDepth",
    "ScaleEstimate",
    "Seed",
    "SegmentLength",
    "SegmentLengths",
    "calibrate_figure",
    "default_limbs",
    "estimate_scale",
    "figure_segments",
    "kinematic_triples",
    "lift_limbs",
    "limb_flip_rate",
    "links_report",
    "planarity_seed",
    "seed_trajectory",
    "segment_lengths",
    "DEFAULT_MODEL_TOL",
    "DEFAULT_RTOL",
    "GroupFit",
    "HingedTriple",
    "Link",
    "LinkGraph",
    "PlanarSolution",
    "discover_links",
    "estimate_noise_sigma",
    "fit_planar_group",
    "hinge_from_two_views",
    "rod_from_three_views",
]
