"""Feet on the ground: the floor, foot contacts, their rows, and the foot metrics.

* :class:`Floor` - the plane ``n . p = d`` (unit up normal ``n``, world axes; ``d`` in
  metres); given (``"y=0"``, ``"z=0"``, ``"nx,ny,nz,d"``) or :func:`estimate_floor`:
  fitted under the lowest foot points over time, robust to jumps and to frames where no
  foot is down.
* :func:`foot_keypoints` - the figure's foot points (ankle, heel, toe, foot).
* :func:`detect_contacts` - contact per frame and foot point from low height and low
  speed, with hysteresis.
* :func:`contact_rows` - the rows of :mod:`pinrecon.rows.contact` (zero velocity,
  height on the floor) and :mod:`pinrecon.rows.floor` (non-penetration).
* :func:`hold_rows` - 3D point rows holding the points off the feet where the first
  solve put them, so that the feet stage refines that solve rather than re-solving it.
* :func:`solve_on_the_floor` - solve, detect, add the rows, re-solve warm, re-estimate
  the floor and contacts between solves (the floor is fixed within a solve).
* :func:`foot_metrics` - foot skating (mean horizontal speed of a foot point in
  contact), penetration depth and floating height.

Every height is measured along the floor normal from the floor plane. A foot keypoint
is a joint centre, not the sole: each has its own **contact height** (its height when
its part of the foot rests on the floor; an ankle ~8 cm, a toe end ~2 cm) and its own
**clearance** (the lowest it goes; it may not go lower).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace

import numpy as np

from .errors import InputError, UnknownNameError
from .floor import Floor, as_floor
from .rows.contact import ContactHeight, ContactVelocity
from .rows.floor import FloorPenetration
from .rows.points3d import Points3D
from .solver import SolverOptions, globals_of, solve

__all__ = [
    "FOOT_EXTRAS", "ContactSettings", "Floor", "FootContact", "body_up", "contact_heights", "contact_rows",
    "contacts_from_spec", "detect_contacts", "detection_settings", "estimate_floor", "foot_keypoints",
    "foot_metrics", "foot_speeds",
    "ground_contacts", "hold_rows", "leg_points", "sole_offset", "solve_on_the_floor", "true_runs",
]

#: a keypoint whose name contains one of these (case-insensitive) is a foot point
FOOT_PATTERN = re.compile(r"(?i)ankle|heel|toe|foot")

#: the result NPZ entries of a :class:`FootContact` (:meth:`FootContact.to_extras`)
FOOT_EXTRAS = ("floor", "foot_names", "foot_contact", "foot_contact_height_m", "foot_clearance_m")


# ----------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class ContactSettings:
    """Weights of the contact rows and thresholds of the contact detection.

    Weights (standard deviations; chosen on ``bench/bench_contact.py``, see its table).
    A planted foot point is not a pin: CMU's planted ankles and toes creep 1-3 cm over a
    stance (the joint centres move as the foot rolls) and move 15-40 cm/s in the frames
    at heel strike and toe-off that a detector counts as contact. The zero-velocity rows
    are therefore stiff in mid-stance (2 cm/s) and soft where the foot point is seen to
    move: the row of frames (t, t + 1) has the standard deviation
    ``sqrt(sigma_velocity_mps^2 + (velocity_slack * max(0, v_seen - slack_from_mps))^2)``
    with ``v_seen`` the point's speed in the directions the data see (a single camera:
    without its viewing direction; all of it otherwise; smoothed over ``slack_smooth_s``),
    averaged over the pair: what moves in the image at more than 10 cm/s is taken to move
    as much in depth. On the lab walk this gives skating 1.3 cm/s and 1.1 mm less error
    than no rows; with the slack from 5 cm/s, a pin at 1 cm/s gave 1.1 cm/s and 1.6 mm
    more error, 5 cm/s without slack 2.3 cm/s and 0.7 mm more (the same detection). The
    height rows are soft (2 cm: a planted ankle rises as the foot rolls; 1 cm raised the
    lab spin's error by 0.2 mm), the barrier stiff but only below the point's lowest
    height (acting on every frame's lowest 5 % lifted the spin's error from 11.5 to
    16.5 mm).

    sigma_velocity_mps : speed of a planted foot point in mid-stance, m/s (zero-velocity rows).
    velocity_slack, slack_from_mps : the softening above (``velocity_slack = 0``: a
        uniform ``sigma_velocity_mps``).
    sigma_height_m : height of a planted foot point about its contact height, metres.
    sigma_floor_m : non-penetration barrier, metres (small = stiff).

    Detection (heights above the point's own lowest level, speeds in m/s, smoothed over
    ``smooth_s`` seconds; with one camera the speed leaves out the velocity along its
    viewing direction, see :func:`detect_contacts`). The defaults find the run's short
    stances (a running forefoot is never slower than about 10 cm/s at 60 fps); stricter
    thresholds (12 / 20 cm/s, or contacts trimmed by 20 ms) left the lab walk's error
    0.1-0.3 mm above no rows and raised its skating to 1.7-2.7 cm/s.

    height_on_m, speed_on_mps : a foot point enters contact below both;
    height_off_m, speed_off_mps : it leaves contact above either (hysteresis);
    min_contact_s : shorter contacts are dropped; gaps shorter than ``max_gap_s`` are filled.
    low_quantile : the quantile of a point's heights taken as its lowest level.
    rounds : solves with contact rows (detection and floor refined before each).
    refine_iterations : Gauss-Newton iterations at most in each round but the last (its
        solution only refines the next round's detection and floor; the last round runs to
        convergence).
    floor_margin_m : how far below its lowest height (1st percentile over the motion, or
        its contact height when lower) a foot point may go before the non-penetration
        barrier acts.
    trim_s : each detected contact is shortened by this at both ends (not at the clip's
        ends); 0 by default (trimming 20 ms cost the run its short stances).
    lift_s : detected contacts' no-sliding rows go on this long after each (toe-off: the
        heel rises while the forefoot holds; generic walk 3.75 -> 1.92 cm/s).
    land_s : ... and start this long before each (the smoothing and hysteresis start a
        contact a frame late; on the generic dance a foot left free in that frame jumped
        in depth at up to 2.5 m/s: skating 2.70 -> 1.30 cm/s; 35 ms put rows on the
        descending ankle of the generic run's false contacts, 0.1 mm more error than none).
    slack_smooth_s : the speed that softens the rows (``velocity_slack``) is smoothed over
        this long (detection uses ``smooth_s``): over 50 ms, and with the slack from
        5 cm/s, the tracking noise of a generic figure's ankle read as motion (generic
        dance 3.55 -> 2.70 cm/s); detection smoothed as long lost the run's short stances
        (lab run 0.9 -> 18 cm/s).
    hold_m : tracked points off the feet held where the first solve put them (metres,
        :func:`hold_rows`; 0: not). Unheld, the rows moved the figure's depth (generic walk
        83.8 -> 112.3 mm); held, the error is lower than without rows in bench_contact.
    ankle_height_m : when the foot points have no toe or heel (COCO-17's ankles), the
        estimated floor is put this far below the planted ankles (an adult's ankle joint
        centre stands 6-9 cm above the floor), so that the feet stand on it.
    ankle_rise_m : when the foot points have no toe or heel, the detection's height
        thresholds are raised by this much: the forefoot stays planted while the heel
        rises (a pivot, a releve, toe-off) and lifts the ankle 5-10 cm; with toes tracked
        the toe carries that contact (generic dance of bench_contact: its planted ankles'
        true contacts found 87 -> 99 %, skating 8.38 -> 3.55 cm/s).
    """

    sigma_velocity_mps: float = 0.02
    sigma_height_m: float = 0.02
    sigma_floor_m: float = 0.003
    height_on_m: float = 0.03
    height_off_m: float = 0.05
    speed_on_mps: float = 0.15
    speed_off_mps: float = 0.25
    smooth_s: float = 0.05
    min_contact_s: float = 0.05
    max_gap_s: float = 0.04
    low_quantile: float = 0.05
    rounds: int = 2
    refine_iterations: int = 12
    ankle_height_m: float = 0.07
    floor_margin_m: float = 0.005
    trim_s: float = 0.0
    velocity_slack: float = 1.0
    slack_from_mps: float = 0.1
    slack_smooth_s: float = 0.1
    hold_m: float = 0.1
    lift_s: float = 0.035
    land_s: float = 0.02
    ankle_rise_m: float = 0.05

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            ok = isinstance(v, (int, float)) and np.isfinite(v) and v >= 0
            if f.name.startswith("sigma") or f.name in ("rounds", "refine_iterations"):
                ok = ok and v > 0
            if not ok:
                raise InputError(f"must be a non-negative number (positive for weights), got {v!r}",
                                 field=f"contact_settings.{f.name}")


@dataclass
class FootContact:
    """Where the feet are: the floor, the foot points, their contact per frame.

    floor : the :class:`Floor`.
    names : (F,) foot keypoint names.
    contact : (T, F) bool, foot point f in contact at frame t.
    contact_height_m : (F,) height of each foot point above the floor in contact.
    clearance_m : (F,) the lowest each foot point may go (non-penetration).
    extra : ``"seen_speed_mps"`` (T, F), the speed the data see, smoothed over
        ``ContactSettings.slack_smooth_s`` (:func:`ground_contacts`,
        detected contacts only: contacts given by the user are held as given), which
        softens the zero-velocity rows (:class:`ContactSettings`); not saved.
    """

    floor: Floor
    names: list[str]
    contact: np.ndarray
    contact_height_m: np.ndarray
    clearance_m: np.ndarray
    extra: dict = field(default_factory=dict)

    def to_extras(self) -> dict:
        """Entries for :attr:`pinrecon.Result.extras` (saved in the result NPZ)."""
        return {
            "floor": self.floor.as_array(),
            "foot_names": np.array(self.names),
            "foot_contact": np.asarray(self.contact, bool),
            "foot_contact_height_m": np.asarray(self.contact_height_m, float),
            "foot_clearance_m": np.asarray(self.clearance_m, float),
        }

    @classmethod
    def from_extras(cls, d: Mapping) -> FootContact | None:
        if "floor" not in d or "foot_names" not in d:
            return None
        return cls(Floor.from_array(d["floor"]), [str(n) for n in np.asarray(d["foot_names"]).ravel()],
                   np.asarray(d["foot_contact"], bool), np.asarray(d["foot_contact_height_m"], float),
                   np.asarray(d["foot_clearance_m"], float))


# ----------------------------------------------------------------------------- foot points
def foot_keypoints(figure, names: Sequence[str] | None = None) -> list[str]:
    """The figure's foot points: distinct keypoints whose name contains ankle, heel, toe
    or foot (case-insensitive), restricted to ``names`` when given, in figure order."""
    allowed = None if names is None else set(names)
    group = {n: gi for gi, g in enumerate(figure.coincident_keypoints()) for n in g}
    out, used = [], set()
    for n in figure.keypoint_names:
        if FOOT_PATTERN.search(n) and (allowed is None or n in allowed) and group[n] not in used:
            out.append(n)
            used.add(group[n])
    return out


def body_up(p_feet, p_upper) -> np.ndarray:
    """The figure's mean up direction: the mean over frames of the unit vector from the
    foot points' centroid to ``p_upper`` ((T, 3), e.g. the pelvis, or (T, K, 3): their centroid)."""
    up = np.asarray(p_upper, float)
    if up.ndim == 3:
        up = np.nanmean(up, axis=1)
    v = up - np.nanmean(np.asarray(p_feet, float), axis=1)
    v = v[np.all(np.isfinite(v), axis=1)]
    v = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)
    m = v.mean(axis=0) if len(v) else np.zeros(3)
    n = np.linalg.norm(m)
    return m / n if n > 1e-9 else np.array([0.0, 1.0, 0.0])


def estimate_floor(p_feet, *, up=None, p_upper=None, fps: float | None = None, tilt_prior_rad: float = 0.1,
                   min_spread_m: float = 0.1, tol_m: float = 0.03, planted_mps: float = 0.3,
                   iterations: int = 10) -> Floor:
    """The floor under the planted foot points.

    Parameters
    ----------
    p_feet : (T, F, 3) foot points, world metres.
    up : the prior up direction; default :func:`body_up` of ``p_upper`` (the pelvis
        (T, 3) or all keypoints (T, K, 3)), else +Y.
    fps : frame rate; with it, only foot points slower than ``planted_mps`` count (a foot
        on the floor is still: flight phases, swings and jumps are left out).
    tilt_prior_rad, min_spread_m : the floor's tilt from ``up`` has this standard
        deviation along directions in which each foot point's planted positions spread
        (standard deviation) over at least ``min_spread_m``; along the others (sideways in a
        straight walk, everywhere when dancing on the spot) the floor is perpendicular to
        ``up``: a few centimetres of lever cannot tell a tilt from how a foot rolls.
        The prior ``up`` (feet to pelvis) is only as good as the legs' depth: on
        bench_contact's generic dance (one view) it leaned 8.5 degrees; with 25 cm the
        planted ankles (13 and 27 cm along their main axes) left the floor there, 26 of
        133 contact frames were missed and the feet skated 7.8 cm/s; with 10 cm the
        floor is 5.3 degrees off and they skate 1.4 (the walk, run and lab rows alike).
    tol_m : the scale of the robust (Cauchy) weights of the planted points: a point this
        far from the plane counts half (a jump's apex, a foot on a step); without ``fps``
        only the points within this of their own lowest level count.

    Model: a planted foot point ``p`` of foot keypoint k satisfies ``n . p - d = c_k``
    with its own contact height ``c_k`` (1 cm noise); ``n = normalise(up + a u1 + b u2)``
    with the tilt prior on ``(a, b)``. Iteratively reweighted least squares in
    ``(a, b, c_1 .. c_F)``; ``d`` puts the lowest contact height at 0, so the floor
    passes through the lowest planted foot keypoint (a joint centre: with ankles only,
    the floor is at ankle height).
    """
    P = np.asarray(p_feet, float)
    if P.ndim != 3 or P.shape[-1] != 3 or P.shape[1] == 0 or P.shape[0] == 0:
        raise InputError(f"expected foot points (T, F, 3), got shape {P.shape}", field="p_feet")
    if up is not None:
        n0 = np.asarray(up, float) / np.linalg.norm(up)
    elif p_upper is not None:
        n0 = body_up(P, p_upper)
    else:
        n0 = np.array([0.0, 1.0, 0.0])
    a = np.eye(3)[int(np.argmin(np.abs(n0)))]
    u1 = np.cross(n0, a)
    u1 /= np.linalg.norm(u1)
    u2 = np.cross(n0, u1)
    finite = np.all(np.isfinite(P), axis=-1)
    if not finite.any():
        raise InputError("no finite foot point to estimate the floor from", field="p_feet")
    slow = finite & (_speeds(P, float(fps), 0.05) < planted_mps) if fps else finite
    F = P.shape[1]
    use = slow if slow.sum() >= 3 else finite
    if not fps:  # no speeds: the points within tol_m of their own lowest level (along the prior)
        h0 = np.where(finite, np.nan_to_num(P) @ n0, np.nan)
        level = np.array([np.nanquantile(h0[:, k], 0.05) if finite[:, k].any() else np.nan for k in range(F)])
        use = finite & (h0 - level <= tol_m)
    t_idx, k_idx = np.nonzero(use)
    L = P[t_idx, k_idx]
    ks = np.unique(k_idx)
    col = np.searchsorted(ks, k_idx)
    # rows: (L . u1) a + (L . u2) b - c_k = -(L . n0), in units of 1 cm; prior rows on a, b
    A = np.zeros((len(L) + 2, 2 + len(ks)))
    A[: len(L), 0], A[: len(L), 1] = L @ u1, L @ u2
    A[np.arange(len(L)), 2 + col] = -1.0
    A[: len(L)] /= 0.01
    b = np.concatenate([-(L @ n0) / 0.01, np.zeros(2)])
    # the prior: weak along directions the planted points spread over (per foot point,
    # std >= min_spread_m), stiff along the others (a few cm of lever cannot tell a tilt)
    uv = A[: len(L), :2] * 0.01
    uv = uv - np.array([uv[col == j].mean(axis=0) for j in range(len(ks))])[col]
    evals, evecs = np.linalg.eigh(uv.T @ uv / max(len(L), 1))
    for r, (lam, e) in enumerate(zip(evals, evecs.T)):
        stiff = np.sqrt(max(lam, 0.0)) < min_spread_m
        A[len(L) + r, :2] = e / (1e-4 if stiff else tilt_prior_rad)
    w = np.ones(len(L) + 2)
    for _ in range(iterations):
        x = np.linalg.lstsq(A * w[:, None], b * w, rcond=None)[0]
        # Cauchy weights (scale tol_m): a jump's apex, a foot on a step count less and less
        res = (A[: len(L)] @ x - b[: len(L)]) * 0.01
        w[: len(L)] = 1.0 / np.sqrt(1.0 + (res / tol_m) ** 2)
    m = n0 + x[0] * u1 + x[1] * u2
    norm = np.linalg.norm(m)
    n = m / norm
    c = np.full(F, np.nan)
    c[ks] = x[2:] / norm
    d = float(np.nanmin(c[ks]))
    return Floor(tuple(n), d)


# ----------------------------------------------------------------------------- contacts
def _speeds(P, fps, smooth_s, unseen=None):
    """(T, F) speed of each point, m/s: central differences of positions averaged over
    ``smooth_s`` seconds (NaN positions give NaN); without the velocity's component along
    the unit vector ``unseen`` when given."""
    T = P.shape[0]
    if T < 2:
        return np.zeros(P.shape[:2])
    V = np.gradient(P, axis=0) * fps
    if unseen is not None:
        u = np.asarray(unseen, float) / np.linalg.norm(unseen)
        V = V - (V @ u)[..., None] * u
    half = int(round(0.5 * smooth_s * fps))
    if half > 0:
        kernel = np.ones(2 * half + 1) / (2 * half + 1)
        pad = np.pad(V, ((half, half), (0, 0), (0, 0)), mode="edge")
        V = np.apply_along_axis(lambda x: np.convolve(x, kernel, mode="valid"), 0, pad)
    return np.linalg.norm(V, axis=-1)


def true_runs(mask) -> list[tuple[int, int]]:
    """(start, stop) of the True runs of a 1D bool array (frames: the first, the one after the last)."""
    d = np.diff(np.r_[0, mask.astype(int), 0])
    return list(zip(np.where(d == 1)[0], np.where(d == -1)[0]))


def foot_speeds(p_feet, fps: float, settings: ContactSettings | None = None, unseen=None) -> np.ndarray:
    """(T, F) speeds (m/s) of the foot points as contact detection sees them: smoothed over
    ``settings.smooth_s``, without the velocity along ``unseen`` (see :func:`detect_contacts`)."""
    s = settings or ContactSettings()
    return _speeds(np.asarray(p_feet, float), float(fps), s.smooth_s, unseen)


def detect_contacts(p_feet, floor: Floor, fps: float, settings: ContactSettings | None = None, *,
                    unseen=None, speeds=None) -> np.ndarray:
    """(T, F) bool: foot point f is in contact at frame t.

    A point enters contact when its height above its own lowest level (the
    ``low_quantile`` of its heights) is below ``height_on_m`` and its speed below
    ``speed_on_mps``; it stays in contact until either passes ``height_off_m`` /
    ``speed_off_mps`` (hysteresis). Gaps shorter than ``max_gap_s`` are filled, then
    contacts shorter than ``min_contact_s`` dropped.

    ``unseen``: a direction the data do not see (a single camera's viewing direction);
    the speed then leaves out the velocity along it: a reconstruction's depth wanders
    where the image does not, and a planted foot is still in the image too. ``speeds``:
    those speeds (T, F) when the caller has them already (:func:`foot_speeds`).
    """
    s = settings or ContactSettings()
    P = np.asarray(p_feet, float)
    h = floor.height(P)
    level = np.nanquantile(h, s.low_quantile, axis=0)
    rel = h - level
    v = foot_speeds(P, float(fps), s, unseen) if speeds is None else np.asarray(speeds, float)
    T, F = h.shape
    on = (rel < s.height_on_m) & (v < s.speed_on_mps)
    stay = (rel < s.height_off_m) & (v < s.speed_off_mps)
    out = np.zeros((T, F), bool)
    gap = int(round(s.max_gap_s * fps))
    shortest = max(1, int(round(s.min_contact_s * fps)))
    for f in range(F):
        state = False
        for t in range(T):
            state = bool(on[t, f]) or (state and bool(stay[t, f]))
            out[t, f] = state
        # hysteresis backwards too: a contact starts where "stay" starts, not where "on" does
        for t in range(T - 2, -1, -1):
            if out[t + 1, f] and stay[t, f]:
                out[t, f] = True
        for a, b in true_runs(~out[:, f]):
            if 0 < a and b < T and b - a <= gap:
                out[a:b, f] = True
        trim = int(round(s.trim_s * fps))
        for a, b in true_runs(out[:, f]):
            a2, b2 = a + trim * (a > 0), b - trim * (b < T)
            out[a:b, f] = False
            if b2 - a2 >= shortest:
                out[a2:b2, f] = True
    return out


def contact_heights(p_feet, floor: Floor, contact, settings: ContactSettings | None = None):
    """Per foot point: (contact height, clearance), metres above ``floor``.

    The contact height is the median height over the point's contact frames (its lowest
    level when it has none); the clearance is ``floor_margin_m`` below the lower of its
    lowest height over the motion (1st percentile) and its contact height: the barrier
    stops feet sinking further, it does not lift what the data put low.
    """
    s = settings or ContactSettings()
    h = floor.height(np.asarray(p_feet, float))
    level = np.nanquantile(h, s.low_quantile, axis=0)
    c = np.asarray(contact, bool)
    height = np.array([np.nanmedian(h[c[:, f], f]) if c[:, f].any() else level[f] for f in range(h.shape[1])])
    return height, np.minimum(np.nanquantile(h, 0.01, axis=0), height) - s.floor_margin_m


def contacts_from_spec(spec, names: Sequence[str], n_frames: int, factor: int = 1) -> np.ndarray:
    """A user's contacts on the reconstruction grid: (T, F) bool for foot points ``names``.

    ``spec`` is a (T_tracks, F) bool array in the order of ``names``, or a mapping
    ``{foot keypoint name: (T_tracks,) bool, or a list of [first, last] tracks frames}``
    (missing names: never in contact). Tracks frame i is reconstruction frame ``i * factor``;
    a super-sampled frame is in contact when both observed frames around it are.
    """
    T_obs = (n_frames - 1) // factor + 1
    C = np.zeros((T_obs, len(names)), bool)
    if isinstance(spec, Mapping):
        unknown = [k for k in spec if k not in names]
        if unknown:
            raise UnknownNameError("foot keypoint", unknown, names, field="contact")
        for k, v in spec.items():
            j = names.index(k)
            arr = np.asarray(v)
            if arr.dtype == bool:
                if arr.shape != (T_obs,):
                    raise InputError(f"expected {T_obs} booleans, got shape {arr.shape}", field=f"contact.{k}")
                C[:, j] = arr
                continue
            for rng in np.asarray(v, dtype=float).reshape(-1, 2) if len(arr) else []:
                a, b = int(rng[0]), int(rng[1])
                if not (0 <= a <= b < T_obs):
                    raise InputError(f"frame range [{a}, {b}] outside the {T_obs} tracks frames", field=f"contact.{k}")
                C[a : b + 1, j] = True
    else:
        C = np.asarray(spec)
        if C.shape != (T_obs, len(names)):
            raise InputError(f"expected contacts of shape ({T_obs}, {len(names)}) for foot points {list(names)}, "
                             f"got {C.shape}", field="contact")
        C = C.astype(bool)
    if factor == 1:
        return C
    out = np.zeros((n_frames, len(names)), bool)
    out[::factor] = C
    for t in range(n_frames):
        if t % factor:
            i = t // factor
            out[t] = C[i] & C[min(i + 1, T_obs - 1)]
    return out


# ----------------------------------------------------------------------------- rows and solve
def contact_rows(figure, feet: FootContact, fps: float, settings: ContactSettings | None = None,
                 factor: int = 1) -> list:
    """The zero-velocity, contact-height and non-penetration rows of ``feet``.

    On a grid super-sampled ``factor`` times, each frame's rows weigh ``1 / factor`` (the
    contact rows keep the weight of one observed frame). With ``feet.extra["seen_speed_mps"]``
    the zero-velocity rows are softened where the point is seen to move
    (``ContactSettings.velocity_slack``), start ``land_s`` before each contact and go on
    ``lift_s`` after it."""
    s = settings or ContactSettings()
    idx = figure.keypoint_index(feet.names)
    T = feet.contact.shape[0]
    w = np.full((T, len(idx)), 1.0 / factor)
    fl = feet.floor
    rows = [FloorPenetration(idx, np.arange(T), fl.n, fl.offset_m, feet.clearance_m, s.sigma_floor_m, w[:, 0])]
    if feet.contact.any():
        rows.insert(0, ContactHeight(idx, feet.contact, fl.n, fl.offset_m, feet.contact_height_m,
                                     s.sigma_height_m, w))
        wv = w
        seen = feet.extra.get("seen_speed_mps")
        if seen is not None and s.velocity_slack > 0:
            v = np.asarray(seen, float)
            v = 0.5 * (v + np.vstack([v[1:], v[-1:]]))  # the pair (t, t + 1)
            v = np.maximum(0.0, v - s.slack_from_mps)
            wv = w * s.sigma_velocity_mps**2 / (s.sigma_velocity_mps**2 + (s.velocity_slack * v) ** 2)
        held = feet.contact
        if seen is not None:
            held = _lifting(feet.contact, round(s.lift_s * fps), round(s.land_s * fps))
        rows.insert(0, ContactVelocity(idx, held, fps, s.sigma_velocity_mps, wv, normal=fl.n))
    return rows


def hold_rows(problem, Q, g=None, foot_names: Sequence[str] = (), sigma_m: float = 0.1) -> list:
    """3D point rows ``(p_k(q_t) - p_k(Q_t)) / sigma_m`` on every frame (named ``"hold"``)
    holding each observed keypoint but ``foot_names`` where ``Q`` (and globals ``g``) put it."""
    fig = problem.figure
    seen = _observed_names(problem) or list(fig.keypoint_names)
    feet = set(foot_names)
    idx = fig.keypoint_index([n for n in seen if n not in feet])
    if not len(idx):
        return []
    P = problem.keypoints(Q, g) if hasattr(problem, "keypoints") else fig.keypoints(Q)
    T = len(Q)
    w = np.full((T, len(idx)), 1.0 / max(int(getattr(problem, "factor", 1)), 1))
    return [Points3D(np.arange(T), idx, P[:, idx], float(sigma_m), name="hold", weights=w)]


def leg_points(figure, foot_names: Sequence[str], names: Sequence[str] | None = None) -> list[str]:
    """The keypoints among ``names`` (default: all) that a leg carries to its foot points:
    moved by a joint whose motion moves a foot point and no keypoint off that foot's chain
    (every keypoint it moves depends on no joint the foot does not). On the human: the knees
    (the hip's rotation moves the knee and the ankle only); not the hips (at the hip joint's
    centre they move with the pelvis) nor anything above. Decided from the keypoint
    Jacobians' sparsity at three random configurations, for any figure."""
    names = list(figure.keypoint_names if names is None else names)
    feet = [n for n in foot_names if n in names]
    if not feet:
        return []
    Q = np.stack([figure.random_configuration(s, unlimited=1.0) for s in (11, 12, 13)])
    _, J = figure.keypoint_jacobians(Q)
    moves = np.abs(J[:, figure.keypoint_index(names)]).max(axis=(0, 2)) > 1e-9  # (K, nv)
    out: set[str] = set()
    for f in feet:
        chain = moves[names.index(f)]
        inside = ~(moves & ~chain).any(axis=1)  # keypoints whose joints all lie on f's chain
        leg = chain & ~(moves & ~inside[:, None]).any(axis=0)  # joints moving only those
        out |= {n for n, m in zip(names, moves) if (m & leg).any()}
    return [n for n in names if n in out and n not in foot_names]


def _observed_names(problem) -> list[str] | None:
    """The keypoints the problem's data observe (tracks of every view, or markers)."""
    views = getattr(problem, "views", None) or []
    if views:
        return list(dict.fromkeys(n for v in views for n in v.tracks.names))
    src = next((x for x in (getattr(problem, "tracks", None), getattr(problem, "markers", None)) if x is not None), None)
    return None if src is None else list(src.names)


def _lifting(C, n: int, n_before: int = 0):
    """Contacts ``C`` (T, F) each extended by ``n`` frames after its end and ``n_before``
    frames before its start."""
    out = np.array(C, bool)
    for _ in range(int(n)):
        out[1:] |= out[:-1].copy()
    for _ in range(int(n_before)):
        out[:-1] |= out[1:].copy()
    return out


def _foot_names(problem) -> list[str]:
    fig = problem.figure
    seen = _observed_names(problem)
    names = foot_keypoints(fig, seen)
    if not names and seen is not None:
        names = foot_keypoints(fig)
    if not names:
        raise InputError(
            f"the figure has no foot keypoint (a name containing ankle, heel, toe or foot): "
            f"{fig.keypoint_names[:40]}", field="floor",
        )
    return names


def sole_offset(names: Sequence[str], settings: ContactSettings | None = None) -> float:
    """How far the floor lies below the lowest planted foot keypoint: 0 when the foot
    points include a toe or a heel, else (ankles only) ``settings.ankle_height_m``."""
    s = settings or ContactSettings()
    return 0.0 if any(re.search(r"(?i)toe|heel", n) for n in names) else float(s.ankle_height_m)


def detection_settings(names: Sequence[str], settings: ContactSettings | None = None):
    """The settings :func:`detect_contacts` uses for foot points ``names``: with ankles only
    (no toe or heel) the height thresholds are raised by ``settings.ankle_rise_m``."""
    s = settings or ContactSettings()
    if sole_offset(names, s) == 0:
        return s
    rise = s.ankle_rise_m
    return replace(s, height_on_m=s.height_on_m + rise, height_off_m=s.height_off_m + rise)


def _unseen(problem):
    """The viewing direction of a problem's single camera (world axes), else None."""
    views = getattr(problem, "views", None) or []
    if len(views) != 1 or not hasattr(views[0].camera, "R"):
        return None
    return np.asarray(views[0].camera.R, float)[2]


def ground_contacts(problem, Q, floor="auto", contact="auto", settings: ContactSettings | None = None,
                    names: Sequence[str] | None = None, g=None) -> FootContact:
    """The floor and contacts of trajectory ``Q`` of ``problem`` (see :func:`solve_on_the_floor`);
    ``g`` the global unknowns (the figure's proportions) when the problem has them."""
    s = settings or ContactSettings()
    fig = problem.figure
    names = list(names) if names is not None else _foot_names(problem)
    P_all = problem.keypoints(Q, g) if hasattr(problem, "keypoints") else fig.keypoints(Q)
    feet = P_all[:, fig.keypoint_index(names)]
    fl = as_floor(floor)
    if fl == "auto":
        upper = Q[:, :3] if fig.floating else P_all
        fl = estimate_floor(feet, p_upper=upper, fps=problem.fps)
        fl = Floor(fl.normal, fl.offset_m - sole_offset(names, s))
    auto = isinstance(contact, str) and contact == "auto"
    seen = None
    if auto:
        unseen = _unseen(problem)
        C = detect_contacts(feet, fl, problem.fps, detection_settings(names, s),
                            speeds=foot_speeds(feet, float(problem.fps), s, unseen))
        seen = _speeds(feet, float(problem.fps), s.slack_smooth_s, unseen)
    elif contact is None or contact is False:
        C = np.zeros(feet.shape[:2], bool)
    else:
        C = contacts_from_spec(contact, names, len(Q), problem.factor)
    height, clearance = contact_heights(feet, fl, C, s)
    if not auto:  # the user's contacts: planted as given
        return FootContact(fl, names, C, height, clearance)
    return FootContact(fl, names, C, height, clearance, extra={"seen_speed_mps": seen})


def _free_globals(problem, g) -> np.ndarray:
    """The global unknowns the feet stage may move: the proportions, not a camera's focal
    length or scale (settled over the whole clip before it, and reported as such)."""
    props = getattr(problem, "proportions", None)
    return np.arange(len(g)) < (props.n if props is not None else 0)


def solve_on_the_floor(problem, res, floor="auto", contact="auto", *, settings: ContactSettings | None = None,
                       options=None, callback=None):
    """Solve ``problem`` again with the feet on the ground, from solution ``res``.

    Each of ``settings.rounds`` rounds re-estimates the floor (``floor="auto"``; a given
    :class:`Floor` or spec stays) and the contacts (``contact="auto"``; a given array or
    mapping stays, see :func:`contacts_from_spec`; ``False``: no contact rows, only the
    floor) from the current trajectory, adds the contact rows to the problem and solves
    warm from it. The points off the feet are held where ``res`` put them
    (:func:`hold_rows`, ``settings.hold_m``), but for the legs' points (:func:`leg_points`:
    the knees, which must follow a planted ankle); a calibrated camera's focal length or
    scale stays where the first solve put it. Returns (the problem with the last rows,
    the solve result, the :class:`FootContact` the last solve used).
    """
    s = settings or ContactSettings()
    x = res.x
    feet = None
    out_problem = problem
    names = _foot_names(problem)
    free = names + leg_points(problem.figure, names, _observed_names(problem))
    hold = hold_rows(problem, x, globals_of(res), free, s.hold_m) if s.hold_m > 0 else []
    opt = options or SolverOptions()
    refine = replace(opt, max_iterations=min(opt.max_iterations, int(s.refine_iterations)))
    for k in range(int(s.rounds)):
        g = globals_of(res)
        feet = ground_contacts(problem, x, floor, contact, s, names=names, g=g)
        out_problem = problem.with_rows(contact_rows(problem.figure, feet, problem.fps, s, problem.factor) + hold)
        res = solve(out_problem, x, opt if k == int(s.rounds) - 1 else refine, callback, active=problem.active, g0=g,
                    active_globals=None if g is None else _free_globals(problem, g))
        x = res.x
    return out_problem, res, feet


# ----------------------------------------------------------------------------- metrics
def foot_metrics(p_feet, floor: Floor, contact, fps: float, *, clearance_m=None, contact_height_m=None) -> dict:
    """Skating, penetration and floating of foot points ``p_feet`` (T, F, 3).

    * ``skating_mps``: mean horizontal speed (parallel to the floor) of a foot point
      between frames t and t + 1 when it is in contact at both.
    * ``penetration_m`` / ``penetration_max_m``: mean / largest depth of a foot point
      below its clearance (default 0: the floor plane), over all frames and foot points.
    * ``floating_m``: mean height of a foot point above its contact height (default its
      clearance) over its contact frames, 0 where it is lower.
    * ``contact_frames``: number of (frame, foot point) contacts.

    ``clearance_m`` and ``contact_height_m`` are (F,) or (T, F).
    """
    P = np.asarray(p_feet, float)
    C = np.asarray(contact, bool)
    h = floor.height(P)
    clear = np.zeros(h.shape) if clearance_m is None else np.broadcast_to(np.asarray(clearance_m, float), h.shape)
    ch = clear if contact_height_m is None else np.broadcast_to(np.asarray(contact_height_m, float), h.shape)
    both = C[:-1] & C[1:]
    step = floor.horizontal(np.diff(P, axis=0))
    speed = np.linalg.norm(step, axis=-1) * float(fps)
    depth = np.maximum(0.0, clear - h)
    return {
        "skating_mps": float(speed[both].mean()) if both.any() else float("nan"),
        "penetration_m": float(depth.mean()),
        "penetration_max_m": float(depth.max()) if depth.size else 0.0,
        "floating_m": float(np.maximum(0.0, h - ch)[C].mean()) if C.any() else float("nan"),
        "contact_frames": int(C.sum()),
    }
