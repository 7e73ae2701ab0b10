"""The lifted start (pinrecon.starts.lifted): the lifter's axes recovered from the tracks, and
the trunk turned to the lifter's facing where the rest start took the other one."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

import pinrecon as pr
from pinrecon.lifted import Lifted
from pinrecon.reconstruct import build_problem
from pinrecon.starts import auto_start, rest_start
from pinrecon.starts.lifted import camera_rotation_from_tracks, has_lifted, lifted_start
from pinrecon.synthetic import project_tracks, smooth_motion

T = 12


def test_camera_rotation_from_tracks_recovers_the_lifters_axes():
    rng = np.random.default_rng(0)
    R = Rotation.from_rotvec([0.4, -2.0, 0.3]).as_matrix()  # R_cam_lifter
    L = rng.normal(size=(200, 3))
    L /= np.linalg.norm(L, axis=1, keepdims=True)
    uv = 0.7 * (L @ R.T)[:, :2] + rng.normal(0.0, 0.01, (200, 2))  # scaled orthographic, noisy
    R_est = camera_rotation_from_tracks(uv, L, np.ones(200))
    angle = np.degrees(np.arccos(np.clip((np.trace(R_est.T @ R) - 1) / 2, -1, 1)))
    assert angle < 2.0
    assert np.linalg.det(R_est) > 0.99


def _case(frame):
    """A figure facing away from where the rest start puts it: its trunk turned 180 degrees
    about the vertical (the image of a turned trunk is nearly the same: the rest start cannot tell)."""
    fig = pr.Figure.human()
    Q = smooth_motion(fig, T, 30.0, seed=1)
    turn = Rotation.from_rotvec([0.0, np.pi, 0.0])
    Q[:, 3:7] = (turn * Rotation.from_quat(Q[:, 3:7])).as_quat()
    cam = pr.Perspective.look_at([0.0, 1.0, -4.0], [0.0, 1.0, 0.0])
    tracks = project_tracks(fig, Q, cam, fps=30.0)
    P = fig.keypoints(Q)[:, fig.keypoint_index(tracks.names)]
    X = P @ np.asarray(cam.R).T if frame == "camera" else P @ Rotation.from_rotvec([0.2, 1.0, 0.1]).as_matrix().T
    tracks.lifted = Lifted(X, list(tracks.names), np.ones(X.shape[:2]), frame, "truth")
    return fig, Q, cam, tracks


def _facing_error_deg(fig, Q, Q_true):
    """Per frame, the angle (degrees) between the root's forward axes."""
    f = Rotation.from_quat(Q[:, 3:7]).apply([0.0, 0.0, 1.0])
    g = Rotation.from_quat(Q_true[:, 3:7]).apply([0.0, 0.0, 1.0])
    return np.degrees(np.arccos(np.clip(np.sum(f * g, axis=1), -1.0, 1.0)))


def test_lifted_start_takes_the_lifters_facing():
    for frame in ("camera", "unknown"):
        fig, Q, cam, tracks = _case(frame)
        problem = build_problem(fig, tracks, cam, seed="rest").problem
        assert has_lifted(problem)
        Q0 = lifted_start(problem)
        assert np.array_equal(auto_start(problem), Q0)  # one camera, no keyframes, lifted cues
        assert np.median(_facing_error_deg(fig, Q0, Q)) < 45.0, frame
    # the rest start alone faces the camera (the other way round)
    assert np.median(_facing_error_deg(fig, rest_start(problem), Q)) > 90.0


def test_without_cues_the_auto_start_is_the_hypotheses_start():
    fig, _, cam, tracks = _case("camera")
    tracks.lifted = None
    problem = build_problem(fig, tracks, cam, seed="rest").problem
    assert not has_lifted(problem)
    assert np.array_equal(lifted_start(problem), rest_start(problem))


def test_a_rigid_body_moves_the_figures_kinematics_by_its_root():
    """The root-only fits (the rest start's, the lifted start's) form the body's kinematics once
    and move them by each frame's root: the same keypoints and WORLD Jacobian as Pinocchio's
    (frame by frame below 64 frames), for any root and body; another body in some frame, or a
    fixed root, keeps the figure's own kinematics."""
    from pinrecon.starts.rest import RigidBody

    fig = pr.Figure.human()
    rng = np.random.default_rng(3)
    Q = np.tile(fig.random_configuration(rng), (T, 1))
    Q[:, :7] = [fig.random_configuration(rng)[:7] for _ in range(T)]
    Q[:, :3] += rng.normal(0.0, 2.0, (T, 3))
    body = RigidBody.of(fig, Q)
    assert isinstance(body, RigidBody) and body.nv == fig.nv and body.keypoint_names == fig.keypoint_names
    P, J = fig.world_kinematics(Q, True)
    P1, J1 = body.world_kinematics(Q, True)
    np.testing.assert_allclose(P1, P, atol=1e-12)
    np.testing.assert_allclose(J1, J, atol=1e-12)
    assert np.abs(J[:, :, 6:]).max() > 0.5  # the joints' columns, moved with the root, not only the root's
    P2, none = body.world_kinematics(Q, False)
    assert none is None and np.array_equal(P2, P1)
    Q[5, 12] += 0.2
    assert RigidBody.of(fig, Q) is fig
    fixed = pr.Figure.human(root="fixed")
    assert RigidBody.of(fixed, np.tile(fixed.neutral(), (T, 1))) is fixed
