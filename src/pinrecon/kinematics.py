"""Forward kinematics and WORLD joint Jacobians of a whole trajectory at once.

Pinocchio computes one configuration per call; a trajectory of T frames then costs T
Python round trips (about 0.1 s for the 92 joints of a CMU skeleton over 1000 frames).
For models whose joints are all free flyers, revolute or prismatic joints (the human of
example-robot-data, every BVH figure), :func:`batch_joint_kinematics` runs the same
recursion with NumPy over frames, one step per joint:

    oMi[j] = oMi[parent(j)] * jointPlacement[j] * motion_j(q_j),

arrays laid out frames-last (``R[j]`` is (3, 3, T)) so that every step works on
contiguous length-T vectors; axis-aligned rotations (``JointModelRX/RY/RZ``) rotate two
columns, identity placements are skipped. The WORLD Jacobian follows Pinocchio's
convention (the linear part is the velocity of the point at the world origin,
``o x w`` for a rotation ``w`` about an axis through ``o``; a free flyer's columns are
its local twist acted to the world). Both agree with Pinocchio to rounding
(``tests/test_kinematics_batch.py``).

:func:`joint_kinds` says whether a model qualifies (else callers loop over Pinocchio).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .errors import InputError

__all__ = [
    "BATCH_MIN_FRAMES",
    "batch_joint_kinematics",
    "integrate_trajectory",
    "joint_kinds",
    "joint_kinematics",
    "keypoint_jacobians_from_world",
    "keypoint_positions",
    "loop_joint_kinematics",
    "point_jacobian_factors",
    "point_kinematics",
    "quaternion_matrices",
    "rows_of",
    "support_mask",
]

#: below this many frames Pinocchio frame by frame is cheaper than the NumPy recursion
BATCH_MIN_FRAMES = 64

_AXES = {"X": 0, "Y": 1, "Z": 2}


def joint_kinds(model) -> list | None:
    """Per joint ``(kind, axis)``: ``("free", None)``, ``("rev", k)`` / ``("pri", k)`` for a
    joint about / along coordinate axis ``k``, ``("rev", v)`` / ``("pri", v)`` with a unit
    vector ``v`` for unaligned ones; ``None`` when some joint is of another type."""
    kinds: list = [None]
    for j in range(1, model.njoints):
        name = model.joints[j].shortname()
        if name == "JointModelFreeFlyer":
            kinds.append(("free", None))
        elif name in ("JointModelRX", "JointModelRY", "JointModelRZ"):
            kinds.append(("rev", _AXES[name[-1]]))
        elif name in ("JointModelPX", "JointModelPY", "JointModelPZ"):
            kinds.append(("pri", _AXES[name[-1]]))
        elif name in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
            axis = np.array(model.joints[j].extract().axis, float)
            norm = np.linalg.norm(axis)
            if not (np.isfinite(norm) and norm > 1e-12):
                raise InputError(f"joint {model.names[j]!r}: its axis {axis.tolist()} has no direction",
                                 field="axis")
            kinds.append(("rev" if "Revolute" in name else "pri", axis / norm))
        else:
            return None
    return kinds


def _rot_vec(R, v):
    """R (3, 3, T) times a constant vector v (3,) -> (3, T), skipping zero components."""
    out = None
    for b in range(3):
        if v[b] != 0.0:
            term = R[:, b] * v[b]
            out = term if out is None else out + term
    return np.zeros(R[:, 0].shape) if out is None else out


def _rot_mat(R, M):
    """R (3, 3, T) times a constant matrix M (3, 3) -> (3, 3, T)."""
    return np.einsum("abt,bc->act", R, M)


def _cross_into(out, a, b):
    """out[:] = a x b for (3, T) arrays."""
    np.multiply(a[1], b[2], out=out[0])
    out[0] -= a[2] * b[1]
    np.multiply(a[2], b[0], out=out[1])
    out[1] -= a[0] * b[2]
    np.multiply(a[0], b[1], out=out[2])
    out[2] -= a[1] * b[0]


def quaternion_matrices(x, y, z, w):
    """Rotation matrices (3, 3, T) of unit quaternions given as (T,) components (frames last,
    as :func:`batch_joint_kinematics` works)."""
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def batch_joint_kinematics(model, kinds, Q, joints, jacobian: bool):
    """World poses of ``joints`` and the WORLD joint Jacobian for every frame of ``Q``.

    Parameters
    ----------
    model : a Pinocchio model whose :func:`joint_kinds` is ``kinds`` (not ``None``).
    Q : (T, nq) configurations.
    joints : joint ids whose poses are returned.
    jacobian : also return the WORLD Jacobian (what ``pin.computeJointJacobians`` fills).

    Returns
    -------
    R (T, U, 3, 3) and p (T, U, 3): rotations and origins of ``joints``; Jw (T, 6, nv)
    or ``None``.
    """
    QT = np.ascontiguousarray(np.asarray(Q, float).T)  # (nq, T): one contiguous row per coordinate
    T = QT.shape[1]
    nj = model.njoints
    R: list = [None] * nj
    p: list = [None] * nj
    R[0] = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, T))
    p[0] = np.zeros((3, T))
    Jw = np.zeros((6, model.nv, T)) if jacobian else None
    eye = np.eye(3)
    for j in range(1, nj):
        par = model.parents[j]
        M = model.jointPlacements[j]
        t_M, R_M = M.translation, M.rotation
        # a joint whose placement is the identity shares its parent's arrays (no copy)
        p_par = p[par] if not t_M.any() else p[par] + _rot_vec(R[par], t_M)
        R_par = R[par] if (R_M == eye).all() else _rot_mat(R[par], R_M)
        kind, axis = kinds[j]
        iq, iv = model.idx_qs[j], model.idx_vs[j]
        if kind == "free":
            Rq = quaternion_matrices(QT[iq + 3], QT[iq + 4], QT[iq + 5], QT[iq + 6])
            R[j] = np.einsum("abt,bct->act", R_par, Rq)
            p[j] = p_par + np.einsum("abt,bt->at", R_par, QT[iq : iq + 3])
            if jacobian:
                Jw[0:3, iv : iv + 3] = R[j]  # local linear velocity -> world
                Jw[3:6, iv + 3 : iv + 6] = R[j]  # local angular velocity -> world
                for a in range(3):
                    _cross_into(Jw[0:3, iv + 3 + a], p[j], R[j][:, a])
            continue
        q = QT[iq]
        if kind == "rev":
            c, s = np.cos(q), np.sin(q)
            if isinstance(axis, int):
                a, b = (axis + 1) % 3, (axis + 2) % 3
                Rj = np.empty((3, 3, T))
                Rj[:, axis] = R_par[:, axis]
                np.multiply(R_par[:, a], c, out=Rj[:, a])
                Rj[:, a] += s * R_par[:, b]
                np.multiply(R_par[:, b], c, out=Rj[:, b])
                Rj[:, b] -= s * R_par[:, a]
                w = R_par[:, axis]
            else:
                K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
                Rj = R_par + s * _rot_mat(R_par, K) + (1.0 - c) * _rot_mat(R_par, K @ K)
                w = _rot_vec(R_par, axis)
            R[j], p[j] = Rj, p_par
            if jacobian:
                Jw[3:6, iv] = w
                _cross_into(Jw[0:3, iv], p_par, w)
        else:  # prismatic
            d_world = R_par[:, axis] if isinstance(axis, int) else _rot_vec(R_par, axis)
            R[j], p[j] = R_par, p_par + d_world * q
            if jacobian:
                Jw[0:3, iv] = d_world
    sel = [int(u) for u in joints]
    R_out = np.stack([R[u] for u in sel]).transpose(3, 0, 1, 2) if sel else np.zeros((T, 0, 3, 3))
    p_out = np.stack([p[u] for u in sel]).transpose(2, 0, 1) if sel else np.zeros((T, 0, 3))
    return np.ascontiguousarray(R_out), np.ascontiguousarray(p_out), (
        None if Jw is None else np.ascontiguousarray(Jw.transpose(2, 0, 1))
    )


def loop_joint_kinematics(model, data, Q, joints, jacobian: bool):
    """:func:`batch_joint_kinematics` through Pinocchio, frame by frame (any joint type)."""
    Q = np.asarray(Q, float)
    T, sel = Q.shape[0], [int(u) for u in joints]
    R, p = np.empty((T, len(sel), 3, 3)), np.empty((T, len(sel), 3))
    Jw = np.empty((T, 6, model.nv)) if jacobian else None
    for t in range(T):
        if jacobian:
            Jw[t] = pin.computeJointJacobians(model, data, Q[t]).reshape(6, -1)  # (6,) when nv == 1
        else:
            pin.forwardKinematics(model, data, Q[t])
        oMi = data.oMi
        H = np.array([oMi[j].homogeneous for j in sel]).reshape(len(sel), 4, 4)  # one call per joint
        R[t], p[t] = H[:, :3, :3], H[:, :3, 3]
    return R, p, Jw


def joint_kinematics(model, data, kinds, Q, joints, jacobian: bool):
    """:func:`batch_joint_kinematics` when the model qualifies (``kinds`` not ``None``) and
    the trajectory has at least :data:`BATCH_MIN_FRAMES` frames, else Pinocchio frame by frame."""
    if kinds is not None and len(Q) >= BATCH_MIN_FRAMES:
        return batch_joint_kinematics(model, kinds, Q, joints, jacobian)
    return loop_joint_kinematics(model, data, Q, joints, jacobian)


#: frames per chunk of a long trajectory (bounded scratch memory in the NumPy recursion)
CHUNK_FRAMES = 4096


def point_kinematics(model, data, kinds, Q, joints, slot, p_joint, jacobian: bool):
    """Points fixed in joints (``p_world = R[slot[k]] p_joint[k] + p[slot[k]]``, (T, K, 3))
    along a trajectory and the WORLD joint Jacobian (T, 6, nv) or ``None``: the joints'
    poses (:func:`joint_kinematics`) are formed :data:`CHUNK_FRAMES` frames at a time."""
    Q = np.asarray(Q, float)
    T = Q.shape[0]
    if T <= CHUNK_FRAMES:
        R, p, Jw = joint_kinematics(model, data, kinds, Q, joints, jacobian)
        return keypoint_positions(R, p, slot, p_joint), Jw
    P = np.empty((T, len(slot), 3))
    Jw = np.empty((T, 6, model.nv)) if jacobian else None
    for a in range(0, T, CHUNK_FRAMES):
        b = min(a + CHUNK_FRAMES, T)
        R, p, J = joint_kinematics(model, data, kinds, Q[a:b], joints, jacobian)
        P[a:b] = keypoint_positions(R, p, slot, p_joint)
        if jacobian:
            Jw[a:b] = J
    return P, Jw


def keypoint_positions(R, p, slot, p_joint):
    """Points fixed in joints: ``R[:, slot[k]] p_joint[k] + p[:, slot[k]]`` -> (T, K, 3)."""
    Rk = R[:, slot]
    return np.einsum("tkab,kb->tka", Rk, p_joint) + p[:, slot]


def point_jacobian_factors(P, A=None):
    """``G = A [I, -[p]x]`` (..., r, 6) for points P (..., 3) and row maps A ((r, 3) or
    (..., r, 3); default the identity), so that ``A dp/dv = G Jw`` with the WORLD joint
    Jacobian Jw (6, nv) (before the support mask): ``v_p = J_lin v + (J_ang v) x p``.
    Row i of ``-A [p]x`` is ``(p x a_i)^T``."""
    P = np.asarray(P, float)
    A = np.eye(3) if A is None else np.asarray(A, float)
    shape = P.shape[:-1] + A.shape[-2:-1]
    G = np.empty(shape + (6,))
    G[..., :3] = A
    a = [A[..., k][None] if A.ndim == 2 else A[..., k] for k in range(3)]  # (..., r) columns
    p = [P[..., k, None] for k in range(3)]
    G[..., 3] = p[1] * a[2] - p[2] * a[1]
    G[..., 4] = p[2] * a[0] - p[0] * a[2]
    G[..., 5] = p[0] * a[1] - p[1] * a[0]
    return G


def keypoint_jacobians_from_world(P, Jw, support):
    """d p / d v (T, K, 3, nv) of points P (T, K, 3) from the WORLD joint Jacobian Jw
    (T, 6, nv): ``J_p = J_lin - [p]x J_ang`` (:func:`point_jacobian_factors`), restricted
    to the columns of the joints supporting each point (``support`` (K, nv))."""
    T, K = P.shape[:2]
    G = point_jacobian_factors(P).reshape(T, 3 * K, 6)
    J = np.matmul(G, Jw).reshape(T, K, 3, Jw.shape[-1])
    J *= support[None, :, None, :]
    return J


def support_mask(model, joint_ids) -> np.ndarray:
    """(len(joint_ids), nv) bool: the tangent entries of the joints supporting each joint
    (itself and its ancestors), i.e. the columns a point fixed in it can depend on."""
    mask = np.zeros((len(joint_ids), model.nv), dtype=bool)
    for i, j in enumerate(joint_ids):
        for s in model.supports[int(j)]:
            if s > 0:
                mask[i, model.idx_vs[s] : model.idx_vs[s] + model.nvs[s]] = True
    return mask


def rows_of(a: np.ndarray, idx) -> np.ndarray:
    """``a[idx]``, as a view when ``idx`` is a long run of consecutive indices."""
    idx = np.asarray(idx)
    n = len(idx)
    if n > 32 and idx[-1] - idx[0] == n - 1 and bool((np.diff(idx) == 1).all()):
        return a[idx[0] : idx[-1] + 1]
    return a[idx]


def integrate_trajectory(model, kinds, Q, V):
    """``pin.integrate`` frame by frame, ``Q (+) V`` for (T, nq) and (T, nv): NumPy over
    frames when every joint is a free flyer (``q * exp6(v)``, the local twist, quaternion
    re-normalised to first order as Pinocchio does) or a 1-dof joint (``q + v``), else
    Pinocchio per frame."""
    Q, V = np.asarray(Q, float), np.asarray(V, float)
    if kinds is None or len(Q) < BATCH_MIN_FRAMES:
        return np.stack([pin.integrate(model, a, b) for a, b in zip(Q, V)])
    out = Q.copy()
    one = [j for j in range(1, model.njoints) if kinds[j][0] != "free"]
    out[:, [model.idx_qs[j] for j in one]] += V[:, [model.idx_vs[j] for j in one]]  # 1-dof joints: q + v
    for j in range(1, model.njoints):
        iq, iv = model.idx_qs[j], model.idx_vs[j]
        if kinds[j][0] != "free":
            continue
        nu, w = V[:, iv : iv + 3], V[:, iv + 3 : iv + 6]
        th2 = np.einsum("ta,ta->t", w, w)
        th = np.sqrt(th2)
        small = th < 1e-4
        ths = np.where(small, 1.0, th)
        a = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(ths)) / ths**2)  # V(w) = I + a [w]x + b [w]x^2
        b = np.where(small, 1.0 / 6.0 - th2 / 120.0, (ths - np.sin(ths)) / ths**3)
        wxn = np.cross(w, nu)
        t = nu + a[:, None] * wxn + b[:, None] * np.cross(w, wxn)
        h = np.where(small, 0.5 - th2 / 48.0, np.sin(0.5 * ths) / ths)  # exp3 as a quaternion
        qe = np.concatenate([h[:, None] * w, np.cos(0.5 * th)[:, None]], axis=1)
        q0 = Q[:, iq + 3 : iq + 7]
        x0, y0, z0, w0 = q0.T
        R = np.stack([
            np.stack([1 - 2 * (y0 * y0 + z0 * z0), 2 * (x0 * y0 - z0 * w0), 2 * (x0 * z0 + y0 * w0)], -1),
            np.stack([2 * (x0 * y0 + z0 * w0), 1 - 2 * (x0 * x0 + z0 * z0), 2 * (y0 * z0 - x0 * w0)], -1),
            np.stack([2 * (x0 * z0 - y0 * w0), 2 * (y0 * z0 + x0 * w0), 1 - 2 * (x0 * x0 + y0 * y0)], -1),
        ], -2)
        out[:, iq : iq + 3] = Q[:, iq : iq + 3] + np.einsum("tab,tb->ta", R, t)
        xe, ye, ze, we = qe.T
        qn = np.stack([w0 * xe + x0 * we + y0 * ze - z0 * ye, w0 * ye - x0 * ze + y0 * we + z0 * xe,
                       w0 * ze + x0 * ye - y0 * xe + z0 * we, w0 * we - x0 * xe - y0 * ye - z0 * ze], axis=1)
        qn *= np.where(np.einsum("ta,ta->t", qn, q0) < 0.0, -1.0, 1.0)[:, None]
        out[:, iq + 3 : iq + 7] = qn * (0.5 * (3.0 - np.einsum("ta,ta->t", qn, qn)))[:, None]
    return out
