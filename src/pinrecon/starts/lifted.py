"""The lifted start: the rest start with its trunk turned to a lifter's facing, placed on the tracks.

When the tracks carry a lifter's 3D (:mod:`pinrecon.rows.lifted`), the limbs' depth
reflections the multi-hypothesis search (:mod:`.hypotheses`) enumerates are the lifter's
to tell, in the main solve's lifted-pose rows; the start only has to face the right way. From
the rest start (:func:`~.rest.rest_start`), the trunk's keypoints are chained from the hip
along the lifter's unit bone directions of the trunk (turned into world axes) with the
figure's own bone lengths, and one batch inverse kinematics of the root alone (3D targets,
joint limits, the posture prior; every frame on its own) turns the trunk onto them; the root
is then placed on the tracks (:func:`~.rest.place_on_tracks`), and kept only on frames where
its facing parts from the rest start's by more than :data:`FACING_DEG`. The limbs stay at the
rest start's: the main solve, with the lifted-pose rows and their robust loss, decides what the
lifter got wrong (limbs posed on the lifter's bone directions too start real clips in worse
basins: bench/README.md, bench_stages).

The lifter's axes: ``"camera"`` lifters are read in the camera's axes; for ``"unknown"`` ones
the rotation to the camera is the one whose first two rows best turn the lifter's bones onto
the tracks' 2D bones (a scaled-orthographic Procrustes over all frames and bones; its third
row completes a rotation, so the lifter's handedness, which tells a limb from its mirror
image, is kept).
"""

from __future__ import annotations

import numpy as np

from ..problem import ReconstructionProblem, posture_row, rest_pose
from ..rows import JointLimits, Points3D, Posture
from ..rows.lifted import LiftedPose
from ..solver import SolverOptions, solve
from .rest import RigidBody, place_on_tracks, rest_start
from .triangulation import normalized_coords

__all__ = ["camera_rotation_from_tracks", "has_lifted", "lifted_start"]

#: how hard the inverse kinematics holds the chained targets (metres)
SIGMA_TARGET_M = 0.05
#: the inverse kinematics' iterations (every frame on its own: a few Gauss-Newton steps)
#: the trunk is turned to the lifter's facing where the two part by more than this (degrees)
FACING_DEG = 60.0
IK_OPTIONS = SolverOptions(max_iterations=15, ftol=1e-4)


def has_lifted(problem) -> bool:
    """Whether the problem holds lifted-pose rows (its tracks carry a lifter's 3D)."""
    return any(isinstance(r, LiftedPose) for r in getattr(problem, "rows", ()))


def camera_rotation_from_tracks(uv_bones: np.ndarray, l_bones: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``R_cam_lifter`` (3, 3): the rotation whose first two rows map the lifter's unit bone
    directions ``l_bones`` (..., 3) onto the bones' image vectors ``uv_bones`` (..., 2,
    normalised image coordinates, any scale), weighted by ``w`` (...): the weighted least-squares
    2 x 3 map made orthonormal (its polar factor); the third row is the cross product of the
    first two."""
    ok = np.isfinite(uv_bones).all(-1) & np.isfinite(l_bones).all(-1) & (w > 0)
    M = np.einsum("n,ni,nj->ij", w[ok], uv_bones[ok], l_bones[ok])  # (2, 3)
    S = np.einsum("n,ni,nj->ij", w[ok], l_bones[ok], l_bones[ok])  # bones are far from isotropic
    U, _, Vt = np.linalg.svd(M @ np.linalg.pinv(S), full_matrices=False)  # least squares, then its rotation
    A = U @ Vt  # the nearest 2 x 3 with orthonormal rows
    return np.vstack([A, np.cross(A[0], A[1])])


def _rotation(problem, row: LiftedPose) -> np.ndarray:
    """``R_world_lifter`` of ``row``: its own, or estimated from the tracks (module docstring)."""
    if row.R_fixed is not None:
        return row.R_fixed
    cam, meas = problem.camera, problem.measurement
    K = problem.figure.K
    uv = np.full((problem.n_frames, K, 2), np.nan)
    uv[np.ix_(meas.frames, meas.keypoints)] = np.where(meas.observed[..., None], meas.uv_px, np.nan)
    n = normalized_coords(cam, uv[row.frames])  # (N, K, 2)
    v = n[:, row.bones[:, 1]] - n[:, row.bones[:, 0]]  # (N, B, 2)
    R_cam_lifter = camera_rotation_from_tracks(v, row.L, row.w)
    return np.asarray(cam.R, float).T @ R_cam_lifter


def _targets(row: LiftedPose, R: np.ndarray, P_rest: np.ndarray, T: int, use=None):
    """(keypoints (M,), targets (T, M, 3)): the keypoints reached from the first bone's start
    along the bones (a spanning tree; only bones ``use`` (B,) bool), NaN where a bone on the
    way has no lifted direction."""
    D = np.full((T, len(row.bones), 3), np.nan)
    D[row.frames] = np.where(row.observed[..., None], row.L @ R.T, np.nan)
    lengths = np.median(np.linalg.norm(P_rest[:, row.bones[:, 1]] - P_rest[:, row.bones[:, 0]], axis=-1), axis=0)
    used = row.bones if use is None else row.bones[use]
    if not len(used):
        return np.zeros(0, int), np.zeros((T, 0, 3))
    anchor = int(used[0, 0])
    placed = {anchor: P_rest[:, anchor]}
    grew = True
    while grew:  # breadth first over the bones, either way along them
        grew = False
        for b, (i, j) in enumerate(row.bones):
            if use is not None and not use[b]:
                continue
            for a, c, s in ((i, j, 1.0), (j, i, -1.0)):
                if a in placed and c not in placed:
                    placed[int(c)] = placed[a] + s * lengths[b] * D[:, b]
                    grew = True
    kps = np.array(sorted(placed), int)
    return kps, np.stack([placed[k] for k in kps], axis=1)


def lifted_start(problem: ReconstructionProblem) -> np.ndarray:
    """The lifted start (module docstring); the rest-pose start without lifted-pose rows."""
    Q_rest = rest_start(problem)
    rows = [r for r in problem.rows if isinstance(r, LiftedPose)]
    if not rows or problem.camera is None or problem.measurement is None:
        return Q_rest
    fig, T, w = problem.figure, problem.n_frames, problem.weights
    row = rows[0]
    names = np.array(fig.keypoint_names)[row.bones]
    trunk = np.char.endswith(names, "shoulder") | np.char.endswith(names, "hip")
    kps, targets = _targets(row, _rotation(problem, row), fig.keypoints(Q_rest), T, trunk.all(axis=1))
    if not np.isfinite(targets).any():
        return Q_rest
    ik = ReconstructionProblem(RigidBody.of(fig, Q_rest), T, [  # the root alone moves
        Points3D(np.arange(T), kps, targets, SIGMA_TARGET_M, name="lifted_targets"),
        JointLimits(fig, T, w.sigma_limits),
        posture_row(fig, T, w, problem.active) or Posture(fig, T, rest_pose(fig), 3.0, problem.active),
    ])
    root = np.zeros(fig.nv, bool)
    root[:6 if fig.floating else 0] = True  # the trunk turned, the limbs left at the rest start's
    Q = fig.normalize(solve(ik, Q_rest, IK_OPTIONS, active=root & problem.active).x)
    Q = place_on_tracks(fig, Q, problem.camera, problem.measurement)
    if fig.floating:  # the lifter decides the trunk's facing, the image its fit: turned only where they part
        dot = np.abs(np.einsum("ti,ti->t", Q[:, 3:7], Q_rest[:, 3:7]))
        Q = np.where((2.0 * np.degrees(np.arccos(np.clip(dot, 0.0, 1.0))) > FACING_DEG)[:, None], Q, Q_rest)
    return fig.clamp(Q, margin=1e-3)
