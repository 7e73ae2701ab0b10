"""Structure from planar motion (Hoffman & Flinchbaugh 1982).

Orthographic camera, axes x right, y down, z forward; all vectors relative to
the pivot/hinge.  See ``docs/planarity.md`` for the derivations.

* :func:`rod_from_three_views` - Proposition 1 (one rod, three views).
* :func:`hinge_from_two_views` - Proposition 2 (two hinged rods, two views).
* :func:`fit_planar_group` - robust least-squares test of a 2/3-point group
  over a sequence (verdict, lengths, plane, depths, planar spans).
* :func:`discover_links` - rigid links and hinges among many tracked points.
"""

from .groups import (
    DEFAULT_MODEL_TOL,
    GroupFit,
    HingedTriple,
    Link,
    LinkGraph,
    discover_links,
    estimate_noise_sigma,
    fit_planar_group,
)
from .propositions import DEFAULT_RTOL, PlanarSolution, hinge_from_two_views, rod_from_three_views

__all__ = [
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
