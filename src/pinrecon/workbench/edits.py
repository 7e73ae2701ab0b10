"""The geometry of the workbench's corrections, with no state and no UI.

* :func:`segments` lists the figure's limb segments (parent keypoint -> child keypoint,
  with the keypoints the child carries below it).
* :func:`view_direction` and :func:`mirror_segment` make the depth flip: the child
  keypoint is reflected in the plane through the segment's root keypoint that is
  perpendicular to the camera ray there, so its image does not move (exactly for an
  orthographic camera, to first order for a perspective one); the keypoints below the
  child either follow it rigidly (``whole_limb=False``: only this segment's depth sign
  changes) or are reflected too (``whole_limb=True``: the limb is mirrored as one piece).
* :func:`flip_span` finds the frames around an edited frame on the same side of that
  ambiguity (until the segment's depth difference changes sign), where the warm start is
  flipped too, so that one flip moves the solver into the other basin for the whole span.
* :func:`fit_points` moves a subset of joints so named keypoints reach targets: a damped
  Gauss-Newton vectorised over frames (the start the session hands to the solver).
* :func:`blend_delta` spreads a one-frame change over its neighbours (raised cosine).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["Segment", "segments", "skeleton_edges", "view_direction", "mirror_segment", "flip_span", "fit_points", "blend_delta"]


@dataclass(frozen=True)
class Segment:
    """A limb segment: ``root`` -> ``child`` keypoints, and the keypoints below the child."""

    root: str
    child: str
    below: tuple[str, ...]

    @property
    def name(self) -> str:
        return f"{self.root}>{self.child}"

    @property
    def moved(self) -> tuple[str, ...]:
        """The keypoints a flip moves: the child and everything below it."""
        return (self.child,) + self.below


def segments(figure) -> list[Segment]:
    """Every parent -> child pair of the figure's keypoint tree
    (:attr:`pinrecon.Figure.parents_of_keypoints`), distinct keypoints only."""
    names = list(figure.keypoint_names)
    parents = list(figure.parents_of_keypoints)
    distinct = set(figure.distinct_keypoint_names)
    children: dict[int, list[int]] = {}
    for i, p in enumerate(parents):
        if p is not None:
            children.setdefault(p, []).append(i)

    def below(i):
        out = []
        for c in children.get(i, []):
            out.append(c)
            out += below(c)
        return out

    out = []
    for i, p in enumerate(parents):
        if p is None or names[i] not in distinct or names[p] not in distinct:
            continue
        out.append(Segment(names[p], names[i], tuple(names[j] for j in below(i) if names[j] in distinct)))
    return out


def skeleton_edges(figure) -> list[tuple[int, int]]:
    """Keypoint index pairs to draw: every parent -> child segment, plus a minimum spanning
    tree over the keypoints that have no parent (e.g. COCO's shoulders, hips and face
    points), by their distances in the rest pose, so the torso is drawn too."""
    names = list(figure.keypoint_names)
    distinct = set(figure.distinct_keypoint_names)
    parents = list(figure.parents_of_keypoints)
    edges = [(p, i) for i, p in enumerate(parents) if p is not None and names[i] in distinct and names[p] in distinct]
    roots = [i for i, p in enumerate(parents) if p is None and names[i] in distinct]
    if len(roots) > 1:
        P = figure.keypoints(figure.neutral())[roots]
        D = np.linalg.norm(P[:, None] - P[None], axis=-1)
        inside, rest = [0], list(range(1, len(roots)))
        while rest:
            a, b = min(((a, b) for a in inside for b in rest), key=lambda ab: D[ab])
            edges.append((roots[a], roots[b]))
            inside.append(b)
            rest.remove(b)
        # left/right pairs among them close the torso (shoulder-shoulder, hip-hip ...)
        for i in roots:
            for pre, other in (("left_", "right_"), ("Left", "Right")):
                if names[i].startswith(pre) and (other + names[i][len(pre):]) in names:
                    j = names.index(other + names[i][len(pre):])
                    if j in roots and (i, j) not in edges and (j, i) not in edges:
                        edges.append((i, j))
        mirror = {n: ("right_" + n[5:] if n.startswith("left_") else "left_" + n[6:] if n.startswith("right_") else n)
                  for n in names}
        for a, b in list(edges):
            if a in roots and b in roots:
                ma, mb = mirror[names[a]], mirror[names[b]]
                if ma in names and mb in names:
                    pair = (names.index(ma), names.index(mb))
                    if pair not in edges and pair[::-1] not in edges:
                        edges.append(pair)
    return edges


def find_segment(figure, name: str) -> Segment:
    """The segment called ``root>child`` (or named by its child keypoint)."""
    segs = segments(figure)
    for s in segs:
        if name in (s.name, s.child):
            return s
    raise InputError(f"unknown limb segment {name!r}; valid: {[s.name for s in segs]}", field="segment")


def view_direction(camera, p_world: np.ndarray) -> np.ndarray:
    """Unit camera ray direction (world) through points ``p_world`` (..., 3)."""
    p_world = np.asarray(p_world, float)
    R = np.asarray(camera.R, float)
    if getattr(camera, "model", "") == "perspective":
        centre = -R.T @ np.asarray(camera.t, float)
        d = p_world - centre
        return d / np.linalg.norm(d, axis=-1, keepdims=True)
    return np.broadcast_to(R[2], p_world.shape).copy()


def mirror_segment(camera, P: np.ndarray, root: int, child: int, below, whole_limb: bool = False) -> np.ndarray:
    """Keypoints ``P`` (..., K, 3) with segment ``root -> child`` flipped in depth.

    The child is reflected in the plane through the root perpendicular to the camera ray
    through the root; the keypoints ``below`` it translate with it (``whole_limb=False``)
    or are reflected in the same plane (``True``).
    """
    P = np.array(P, float)
    below = list(below)
    r = P[..., root, :]
    d = view_direction(camera, r)
    c = P[..., child, :]
    c_new = c - 2.0 * np.sum((c - r) * d, axis=-1, keepdims=True) * d
    if below:
        if whole_limb:
            x = P[..., below, :]
            P[..., below, :] = x - 2.0 * np.sum((x - r[..., None, :]) * d[..., None, :], -1, keepdims=True) * d[..., None, :]
        else:
            P[..., below, :] += (c_new - c)[..., None, :]
    P[..., child, :] = c_new
    return P


def depth_difference(camera, P: np.ndarray, root: int, child: int) -> np.ndarray:
    """Signed depth of the child relative to the root along the camera ray, (...,)."""
    r = P[..., root, :]
    return np.sum((P[..., child, :] - r) * view_direction(camera, r), axis=-1)


def flip_span(camera, P: np.ndarray, root: int, child: int, frame: int) -> tuple[int, int]:
    """Frames ``[a, b]`` around ``frame`` that belong to the same excursion of the
    segment out of the image plane (``P``: (T, K, 3)): the hump of the depth difference
    containing ``frame``, bounded by a change of sign or by the next local minimum of its
    magnitude (where the two mirror solutions come closest)."""
    dz = depth_difference(camera, P, root, child)
    s = np.sign(dz[frame])
    if s == 0:
        return frame, frame
    m = np.abs(dz)

    def walk(step):
        t, rising = frame, True
        while 0 <= t + step < len(dz) and np.sign(dz[t + step]) == s:
            if m[t + step] >= m[t]:
                if not rising:
                    break
            else:
                rising = False
            t += step
        return t

    return walk(-1), walk(1)


def fit_points(figure, Q: np.ndarray, kp_index, targets: np.ndarray, active: np.ndarray, *, iterations: int = 12,
               damping: float = 1e-4) -> np.ndarray:
    """Configurations near ``Q`` (T, nq) whose keypoints ``kp_index`` reach ``targets``
    (T, M, 3), moving only the tangent entries ``active`` (nv,) bool.

    Levenberg-Marquardt per frame, vectorised over frames (one batched solve of the small
    normal equations per iteration); joint limits are kept by clamping.
    """
    Q = np.array(Q, float)
    kp_index = np.asarray(kp_index, int)
    cols = np.where(active)[0]
    if not len(cols) or not len(Q):
        return Q
    lam = np.full(len(Q), damping)
    for _ in range(iterations):
        P, J = figure.keypoint_jacobians(Q)
        r = (P[:, kp_index] - targets).reshape(len(Q), -1)  # (T, 3M)
        A = J[:, kp_index][..., cols].reshape(len(Q), -1, len(cols))  # (T, 3M, a)
        H = np.einsum("tia,tib->tab", A, A)
        g = np.einsum("tia,ti->ta", A, r)
        diag = np.einsum("taa->ta", H)
        Hd = H + (lam[:, None] * np.maximum(diag, 1e-6))[:, :, None] * np.eye(len(cols))
        dx = -np.linalg.solve(Hd, g[..., None])[..., 0]
        V = np.zeros((len(Q), figure.nv))
        V[:, cols] = dx
        Q_new = figure.clamp(figure.integrate(Q, V))
        r_new = (figure.keypoints(Q_new)[:, kp_index] - targets).reshape(len(Q), -1)
        better = np.sum(r_new**2, 1) < np.sum(r**2, 1)
        Q[better] = Q_new[better]
        lam = np.where(better, lam * 0.3, lam * 10.0)
        if np.max(np.abs(dx)) < 1e-7:
            break
    return Q


def blend_delta(figure, Q: np.ndarray, frame: int, q_new: np.ndarray, half_width: int) -> np.ndarray:
    """``Q`` with frame ``frame`` set to ``q_new`` and the same tangent change applied to
    the frames within ``half_width`` with a raised-cosine weight (1 at ``frame``)."""
    Q = np.array(Q, float)
    v = figure.difference(Q[frame], q_new)
    T = len(Q)
    a, b = max(0, frame - half_width), min(T - 1, frame + half_width)
    t = np.arange(a, b + 1)
    w = 0.5 * (1.0 + np.cos(np.pi * (t - frame) / (half_width + 1)))
    Q[a : b + 1] = figure.integrate(Q[a : b + 1], w[:, None] * v[None])
    Q[frame] = q_new
    return figure.clamp(Q)
