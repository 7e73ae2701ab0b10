"""Shared pieces of the plots: matplotlib loading, atomic saving, motions, skeletons, views.

matplotlib is imported lazily (inside functions), and only its object-oriented API is
used (``matplotlib.figure.Figure`` on a ``FigureCanvasAgg``): nothing is registered with
pyplot, so no global backend is switched, nothing needs a display, and figures are freed
as soon as they are no longer referenced (no figure leak in loops).
"""

from __future__ import annotations

import os
import re
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_path

from ..errors import InputError, PinreconError

__all__ = ["MissingDependencyError"]


class MissingDependencyError(PinreconError, ImportError):
    """An optional dependency (matplotlib, ffmpeg) is missing; the message says how to get it."""


def require_matplotlib():
    """(Figure, FigureCanvasAgg) classes, or a clear error naming the ``viz`` extra."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MissingDependencyError(
            "pinrecon's plots and animations need matplotlib; install the 'viz' extra: "
            "from a pinrecon checkout, pip install \".[viz]\" (or pip install matplotlib)"
        ) from exc
    return Figure, FigureCanvasAgg


#: where the pictures' axes titles sit (axes fraction): placed, not measured. matplotlib's automatic
#: placement (``y=None``) draws every tick of an axes to find its top edge, 0.05 s of the four
#: pictures, for this same place on axes without ticks on top
TITLE_Y = 1.0


def new_figure(figsize, dpi: float = 100, layout: str | None = "constrained"):
    """A matplotlib Figure with its own Agg canvas (headless, not known to pyplot);
    ``layout=None`` for a grid placed by :func:`place_grid` (fixed margins, drawn in half
    the time of matplotlib's constrained layout)."""
    Figure, FigureCanvasAgg = require_matplotlib()
    fig = Figure(figsize=figsize, dpi=dpi, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def place_grid(fig, nrows: int, ncols: int, *, left: float = 0.6, right: float = 0.15, bottom: float = 0.5,
               top: float = 0.3, wgap: float = 0.5, hgap: float = 0.5) -> None:
    """Place ``fig``'s grid of ``nrows`` x ``ncols`` axes with margins and gaps in inches
    (room for the tick labels, axis labels and titles a plot draws at its font sizes)."""
    w, h = fig.get_size_inches()
    aw = max((w - left - right - (ncols - 1) * wgap) / ncols, 1e-3)
    ah = max((h - top - bottom - (nrows - 1) * hgap) / nrows, 1e-3)
    fig.subplots_adjust(left=left / w, right=1 - right / w, bottom=bottom / h, top=1 - top / h,
                        wspace=wgap / aw, hspace=hgap / ah)


def save_figure(fig, out: str | os.PathLike, dpi: float | None = None) -> Path:
    """Save ``fig`` as PNG (or the format of ``out``'s suffix), atomically."""
    out = Path(out)
    fmt = out.suffix.lstrip(".").lower() or "png"
    with atomic_path(out) as tmp:
        fig.savefig(tmp, format=fmt, dpi=dpi)
    return out


# ---------------------------------------------------------------------------- motions
@dataclass
class Motion:
    """What the plots need of a result or a ground truth: figure, q, times, keypoints."""

    figure: object
    q: np.ndarray
    times: np.ndarray
    keypoints3d: np.ndarray
    fps: float
    label: str = ""
    feet: object = None  # a pinrecon.contact.FootContact (floor and contacts), when the result has one

    def frame_at(self, t: float) -> int:
        """Index of the frame nearest to time ``t`` (seconds)."""
        return int(np.argmin(np.abs(self.times - t)))


def as_motion(
    obj, label: str = "", *, length_scale: float | None = None, skip_frames: int = 0
) -> Motion:
    """A :class:`Motion` from a Result, a BvhMotion, a Motion, or a path (result NPZ or BVH)."""
    if isinstance(obj, Motion):
        return obj
    if isinstance(obj, (str, os.PathLike)):
        p = Path(obj)
        if p.suffix.lower() == ".bvh":
            from ..io.bvh import load_bvh

            scale = 1.0 if length_scale is None else length_scale
            obj = load_bvh(p, scale, skip_frames=skip_frames)
        else:
            from ..result import load_result

            obj = load_result(p)
        label = label or p.stem
    fig = getattr(obj, "figure", None)
    q = getattr(obj, "q", None)
    if fig is None or q is None:
        raise InputError(
            "expected a Result, a BvhMotion or a path to a result NPZ or BVH file, "
            f"got {type(obj).__name__}",
            field="truth",
        )
    times = np.asarray(obj.times, float)
    P = getattr(obj, "keypoints3d", None)
    if P is None:
        P = fig.keypoints(q)
    fps = float(getattr(obj, "fps", 0) or (1.0 / np.diff(times).mean() if len(times) > 1 else 1.0))
    from ..contact import FootContact

    feet = FootContact.from_extras(getattr(obj, "extras", None) or {})
    return Motion(fig, np.asarray(q, float), times, np.asarray(P, float), fps, label, feet)


def check_frames(frames, n: int, field: str = "frames") -> np.ndarray:
    idx = np.asarray(list(frames), dtype=int).ravel()
    if idx.size == 0:
        raise InputError("no frames selected", field=field)
    bad = idx[(idx < -n) | (idx >= n)]
    if bad.size:
        raise InputError(
            f"frame {int(bad[0])} is out of range: the motion has {n} frames", field=field
        )
    return np.where(idx < 0, idx + n, idx)


def even_frames(n: int, count: int) -> np.ndarray:
    return np.unique(np.linspace(0, n - 1, min(count, n)).round().astype(int))


# ---------------------------------------------------------------------------- joint series
def joint_series(motion: Motion) -> dict[str, tuple[np.ndarray, str]]:
    """Plottable curves: CSV column name -> (values, unit) (degrees or metres)."""
    from ..io.csv_export import motion_columns

    names, units, table = motion_columns(motion.figure, motion.q, motion.times)
    return {n: (table[:, k], u) for k, (n, u) in enumerate(zip(names, units)) if n != "time"}


def find_series(series: dict, name: str):
    if name in series:
        return name
    if f"{name}_m" in series:
        return f"{name}_m"
    return None


# ---------------------------------------------------------------------------- skeletons
@dataclass(frozen=True)
class Skeleton:
    """Bones to draw: ``edges`` index the points ``[keypoints..., hubs...]``, where hubs are
    joint origins (Pinocchio joint ids ``hub_joints``) added to connect keypoints that
    :attr:`pinrecon.Figure.parents_of_keypoints` leaves unconnected (COCO-17 has no
    torso point: shoulders, hips and face are joined through the pelvis, thorax and
    neck joint origins)."""

    K: int
    edges: tuple[tuple[int, int], ...]
    hub_joints: tuple[int, ...]
    side: tuple[str, ...]  # per edge: "L", "R" or "C"

    @property
    def keypoint_edges(self) -> list[tuple[int, int]]:
        return [(a, b) for a, b in self.edges if a < self.K and b < self.K]


_SKELETONS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_LEFT = re.compile(r"(?i)left|(^|_)l(_|$)|^L(?=[A-Z])|^l(?=hand|foot|hip|knee|elbow)")
_RIGHT = re.compile(r"(?i)right|(^|_)r(_|$)|^R(?=[A-Z])|^r(?=hand|foot|hip|knee|elbow)")


def _side(name: str) -> str:
    if _LEFT.search(name):
        return "L"
    if _RIGHT.search(name):
        return "R"
    return "C"


def skeleton(figure) -> Skeleton:
    """The :class:`Skeleton` of ``figure`` (cached per figure)."""
    try:
        return _SKELETONS[figure]
    except (KeyError, TypeError):
        pass
    model = figure.model
    K = figure.K
    parents = list(figure.parents_of_keypoints)
    edges = [(p, i) for i, p in enumerate(parents) if p is not None]
    orphans = [i for i, p in enumerate(parents) if p is None]
    hubs: list[int] = []
    if len(orphans) > 1:
        kp_joint, at_origin = [], []
        for kp in figure.keypoints_def:
            fr = model.frames[model.getFrameId(kp.frame)]
            kp_joint.append(int(fr.parentJoint))
            at_origin.append(np.linalg.norm(fr.placement.act(np.asarray(kp.offset, float))) < 1e-9)

        def path_up(j):
            out = [j]
            while j > 0:
                j = model.parents[j]
                out.append(j)
            return out

        paths = {kp_joint[i]: path_up(kp_joint[i]) for i in orphans}
        common = set.intersection(*(set(p) for p in paths.values()))
        first = next(iter(paths.values()))
        lca = next(j for j in first if j in common)
        union: set[int] = set()
        for p in paths.values():
            union.update(p[: p.index(lca) + 1])
        branches = {n: 0 for n in union}
        for n in union:
            if n != lca:
                branches[model.parents[n]] += 1
        for i in orphans:
            branches[kp_joint[i]] += 1
        hub_set = {n for n, b in branches.items() if b >= 2} | {lca}
        point_of: dict[int, int] = {}
        for n in sorted(hub_set):
            own = [i for i in orphans if kp_joint[i] == n and at_origin[i]]
            if own:
                point_of[n] = own[0]
            else:
                point_of[n] = K + len(hubs)
                hubs.append(n)

        def hub_above(j, strict):
            j = model.parents[j] if strict and j > 0 else j
            while j not in hub_set:
                j = model.parents[j]
            return j

        for i in orphans:
            j = kp_joint[i]
            if point_of.get(j) == i:
                continue
            edges.append((point_of[hub_above(j, False)], i))
        for n in sorted(hub_set):
            if n != lca:
                edges.append((point_of[hub_above(n, True)], point_of[n]))
    names = list(figure.keypoint_names)
    side = tuple(_side(names[b]) if b < K else "C" for _, b in edges)
    sk = Skeleton(K, tuple(edges), tuple(hubs), side)
    try:
        _SKELETONS[figure] = sk
    except TypeError:  # pragma: no cover - figure not weak-referenceable
        pass
    return sk


def skeleton_points(motion: Motion, sk: Skeleton, frames: Sequence[int]) -> np.ndarray:
    """(F, K + H, 3) keypoints and hub joint origins of ``motion`` at ``frames``."""
    frames = np.asarray(frames, int)
    P = motion.keypoints3d[frames]
    if not sk.hub_joints:
        return P
    import pinocchio as pin

    model, data = motion.figure.model, motion.figure.model.createData()
    H = np.empty((len(frames), len(sk.hub_joints), 3))
    for k, f in enumerate(frames):
        pin.forwardKinematics(model, data, motion.q[f])
        for h, j in enumerate(sk.hub_joints):
            H[k, h] = data.oMi[j].translation
    return np.concatenate([P, H], axis=1)


SIDE_COLORS = {"L": "#1f77b4", "R": "#d62728", "C": "#333333"}
TRUTH_COLOR = "#9a9a9a"


def draw_stick(
    ax, uv: np.ndarray, sk: Skeleton, *, truth: bool = False, label: str | None = None, prefix: str = ""
):
    """Draw one stick figure from image points ``uv`` (K + H, 2). Returns (keypoint line,
    bone collection): the line has gid ``prefix + "keypoints"`` and holds exactly the K
    keypoints' coordinates; bones are a LineCollection with gid ``prefix + "bones"``."""
    from matplotlib.collections import LineCollection

    segs = [uv[[a, b]] for a, b in sk.edges]
    if truth:
        colors = [TRUTH_COLOR] * len(segs)
        lw, z = 3.0, 1
    else:
        colors = [SIDE_COLORS[s] for s in sk.side]
        lw, z = 1.8, 3
    bones = LineCollection(segs, colors=colors, linewidths=lw, zorder=z, capstyle="round")
    bones.set_gid(prefix + "bones")
    ax.add_collection(bones)
    (pts,) = ax.plot(
        uv[: sk.K, 0],
        uv[: sk.K, 1],
        "o",
        ms=2.5 if not truth else 3.5,
        color=TRUTH_COLOR if truth else "black",
        zorder=z + 1,
        label=label,
    )
    pts.set_gid(prefix + "keypoints")
    return pts, bones


# ---------------------------------------------------------------------------- views
def camera_up(camera) -> np.ndarray:
    """The world coordinate axis (signed) closest to the camera's up direction."""
    up = -np.asarray(camera.R, float)[1]
    k = int(np.argmax(np.abs(up)))
    out = np.zeros(3)
    out[k] = np.sign(up[k])
    return out


def default_camera():
    """Orthographic front view (looking along -Z, +Y up, metres) for results without one."""
    from ..cameras import Orthographic

    return Orthographic.from_view([0.0, 0.0, -1.0], (0.0, 1.0, 0.0), scale=1.0)


def second_view_camera(camera, second_view=None, up=None):
    """The second viewpoint: a camera, or the camera turned by ``second_view`` degrees
    (default 90) about the world up axis (``up``, default the coordinate axis nearest the
    camera's up), levelled (its image's vertical is ``up``). Returned as an orthographic
    camera in metres (scale 1)."""
    from scipy.spatial.transform import Rotation

    from ..cameras import Camera, Orthographic

    if isinstance(second_view, Camera):
        return second_view
    angle = 90.0 if second_view is None else float(second_view)
    up = camera_up(camera) if up is None else np.asarray(up, float) / np.linalg.norm(up)
    R = np.asarray(camera.R, float)
    fwd = R[2] - (R[2] @ up) * up  # the camera's viewing direction, levelled
    if np.linalg.norm(fwd) < 1e-6:  # looking straight down or up: its image's up, levelled
        fwd = -R[1] - (-R[1] @ up) * up
    fwd = Rotation.from_rotvec(np.radians(angle) * up).apply(fwd / np.linalg.norm(fwd))
    y = -up  # a level view: image y down is the world's down, so the floor is a horizontal line
    return Orthographic(np.stack([np.cross(y, fwd), y, fwd]), 1.0, (0.0, 0.0))


def view_up(camera, feet=None) -> np.ndarray:
    """The world up of the pictures' second view: the floor's normal when the result has a
    floor (it points up, to the body's side, whichever way the camera is rolled), else the
    coordinate axis nearest the camera's up."""
    if feet is None:
        return camera_up(camera)
    return np.asarray(feet.floor.n, float)


def view_unit(camera) -> str:
    from ..cameras import Orthographic

    if isinstance(camera, Orthographic) and camera.scale == 1.0:
        return "m"
    return "px"


FLOOR_COLOR = "#8c6d31"
CONTACT_COLOR = "#2ca02c"


def legend_handles(truth: bool = False, floor: bool = False, contact: bool = False) -> list:
    """Proxy artists naming the colours: left side, right side, centre (and the truth,
    the floor and the contacts when drawn)."""
    from matplotlib.lines import Line2D

    h = [Line2D([], [], color=SIDE_COLORS["L"], lw=2, label="left"),
         Line2D([], [], color=SIDE_COLORS["R"], lw=2, label="right"),
         Line2D([], [], color=SIDE_COLORS["C"], lw=2, label="centre")]
    if truth:
        h.append(Line2D([], [], color=TRUTH_COLOR, lw=3, label="ground truth"))
    if floor:
        h.append(Line2D([], [], color=FLOOR_COLOR, lw=2, label="floor"))
    if contact:
        h.append(Line2D([], [], color=CONTACT_COLOR, marker="s", ls="", ms=5, label="foot in contact"))
    return h


def height_ticks(ax, floor=None, up=None):
    """Label the (inverted, y-down) vertical axis of a metric view with heights: ``-v``,
    above the floor when ``floor`` (a :class:`pinrecon.contact.Floor`) is given and its
    normal is the view's ``up``; ticks at round heights; the drawn data do not change.
    Call it after the axis limits are set."""
    from matplotlib.ticker import MaxNLocator

    off = 0.0
    if floor is not None and up is not None and abs(float(np.dot(floor.n, up))) > 0.99:
        off = float(floor.offset_m) * float(np.sign(np.dot(floor.n, up)))
    v0, v1 = ax.get_ylim()
    lo, hi = sorted((-v0 - off, -v1 - off))
    heights = [h for h in MaxNLocator(5).tick_values(lo, hi) if lo <= h <= hi]
    ax.set_yticks([-(h + off) for h in heights], [f"{h:.3g}" for h in heights])
    ax.set_ylim(v0, v1)
    level = floor is not None and up is not None and abs(float(np.dot(floor.n, up))) > 0.99
    return "height above the floor" if level else "height"


def floor_segment(view, floor, centre_world, half_m: float) -> np.ndarray:
    """(2, 2) image points of the floor's line under ``centre_world``, along the view's
    horizontal direction, ``half_m`` metres each side."""
    n = floor.n
    base = np.asarray(centre_world, float) - floor.height(centre_world) * n
    right = np.asarray(view.R, float)[0]
    right = right - (right @ n) * n
    norm = np.linalg.norm(right)
    right = right / norm if norm > 1e-9 else np.cross(n, np.asarray(view.R, float)[2])
    return view.project(np.stack([base - half_m * right, base + half_m * right]))


def draw_floor(ax, seg_uv, prefix: str = ""):
    """The floor's line (gid ``prefix + "floor"``)."""
    (line,) = ax.plot(seg_uv[:, 0], seg_uv[:, 1], "-", color=FLOOR_COLOR, lw=2.0, zorder=0.5)
    line.set_gid(prefix + "floor")
    return line


def draw_contacts(ax, uv, prefix: str = ""):
    """Squares on the foot points in contact, ``uv`` (M, 2) (gid ``prefix + "contacts"``)."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    (pts,) = ax.plot(uv[:, 0], uv[:, 1], "s", ms=5, mfc="none", mec=CONTACT_COLOR, mew=1.5, zorder=6)
    pts.set_gid(prefix + "contacts")
    return pts


def square_limits(ax, center, half):
    """Equal-aspect square window of half-width ``half`` around ``center``, y down."""
    cx, cy = center
    ax.set_xlim(cx - half, cx + half)
    ax.set_ylim(cy + half, cy - half)  # image y down
    ax.set_aspect("equal", adjustable="box")
