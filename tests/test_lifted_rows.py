"""Lifted-pose rows (pinrecon.rows.lifted): Jacobians against finite differences on the
manifold, the profiled rotation of an unknown lifter frame, and what the rows do in a
reconstruction (a mirrored limb the image cannot decide, a lifter wrong on a span, scale
and translation of the lifted points, the rotation recovered), against ground truth."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from dense_blocks import dense_jacobian
from scipy.spatial.transform import Rotation

import pinrecon as pr
from pinrecon import metrics
from pinrecon.lifted import Lifted
from pinrecon.proportions import Proportions
from pinrecon.reconstruct import build_problem
from pinrecon.rows import State
from pinrecon.rows.lifted import LiftedPose, lifted_bones, procrustes_rotation
from pinrecon.solver import solve
from pinrecon.synthetic import project_tracks, side_camera, smooth_motion

T = 5


@pytest.fixture(scope="module")
def setting():
    fig = pr.Figure.human()
    rng = np.random.default_rng(0)
    Q = smooth_motion(fig, T, 30.0, seed=1)
    Q = np.stack([fig.integrate(q, 0.3 * rng.normal(size=fig.nv)) for q in Q])
    cam = pr.Perspective.look_at([0.5, 1.0, -4.0], [0.5, 0.0, 0.0])
    return fig, Q, cam


def _lifted_row(fig, Q, cam, frame, loss="l2", seed=3):
    """A lifted row whose lifter saw Q (camera axes, or axes turned by a known rotation) with
    noisy directions and uneven confidences."""
    rng = np.random.default_rng(seed)
    pairs = lifted_bones(fig, fig.keypoint_names)
    bones = np.array([[fig.keypoint_names.index(a), fig.keypoint_names.index(b)] for a, b in pairs])
    P = fig.keypoints(Q)
    v = P[:, bones[:, 1]] - P[:, bones[:, 0]]
    v += 0.05 * rng.normal(size=v.shape)
    L = v / np.linalg.norm(v, axis=-1, keepdims=True) @ cam.R.T  # camera axes
    R_lifter_cam = Rotation.from_rotvec([0.3, -1.2, 0.5]).as_matrix()
    if frame == "unknown":
        L = L @ R_lifter_cam.T
    conf = rng.uniform(0.3, 1.0, L.shape[:2])
    L[1, 2] = np.nan  # a missing bone
    R = cam.R.T if frame == "camera" else None
    return LiftedPose(np.arange(T), bones, L, conf, R, weight=30.0, loss=loss, loss_scale=0.3), R_lifter_cam


def _eval(row, fig, Q, jacobian, g=None, props=None, **kw):
    st = State(fig, Q, np.arange(T), jacobian, g=g, proportions=props)
    return row.evaluate(st, jacobian, **kw)


def _fd_jacobian(f, fig, Q, eps=1e-6):
    cols = []
    for t in range(T):
        for i in range(fig.nv):
            dv = np.zeros(fig.nv)
            dv[i] = eps
            Qp, Qm = Q.copy(), Q.copy()
            Qp[t] = fig.integrate(Q[t], dv)
            Qm[t] = fig.integrate(Q[t], -dv)
            cols.append((f(Qp) - f(Qm)) / (2 * eps))
    return np.stack(cols, axis=-1)


def _chords(row, fig, Q, R, g=None, props=None):
    """The rows' residuals as the module's docstring writes them, three per bone:
    ``sqrt(w c) (d - R l)`` (l2 loss), computed here from the keypoints."""
    P = fig.keypoints(Q) if props is None else props.keypoints(g, Q)
    v = P[:, row.bones[:, 1]] - P[:, row.bones[:, 0]]
    d = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return (np.sqrt(row.w)[..., None] * (d - row.L @ R.T)).ravel()


@pytest.mark.parametrize("frame", ["camera", "unknown"])
def test_normal_equations_match_manifold_finite_differences(setting, frame):
    """The rows' J^T J and J^T r are those of the three chord residuals per bone, whose
    Jacobian is taken by central differences of pin.integrate (two rows per bone carry
    them: the chord's part along the bone has no derivative); 0.5 |r|^2 per frame plus that
    part is ``group_cost``. An unknown frame's rotation held at its profiled value."""
    fig, Q, cam = setting
    row, _ = _lifted_row(fig, Q, cam, frame)
    R = row.rotation(State(fig, Q, np.arange(T), False))
    b = _eval(row, fig, Q, True, R=R)
    assert b.r.shape == (T, 2 * len(row.bones))
    J = dense_jacobian([b], T, fig.nv)[0]
    fd = _fd_jacobian(lambda QQ: _chords(row, fig, QQ, R), fig, Q)
    e = _chords(row, fig, Q, R)
    assert np.abs(fd).max() > 0.1
    H, H_fd = J.T @ J, fd.T @ fd
    assert np.abs(H - H_fd).max() <= 1e-6 * np.abs(H_fd).max()
    assert np.abs(J.T @ b.r.ravel() - fd.T @ e).max() <= 1e-6 * np.abs(fd.T @ e).max()
    assert np.allclose(b.group_cost, 0.5 * (e.reshape(T, -1) ** 2).sum(1), rtol=1e-12)
    assert np.isclose(b.cost, 0.5 * e @ e, rtol=1e-12)


@pytest.mark.parametrize("frame", ["camera", "unknown"])
@pytest.mark.parametrize("loss", ["l2", "cauchy", "huber"])
def test_gradient_of_the_profiled_robust_cost_is_exact(setting, frame, loss):
    """J^T r of the reweighted rows is the gradient of the row's own cost, the unknown
    frame's rotation re-solved at every evaluation (the envelope theorem); the robust cost
    is below the plain one."""
    fig, Q, cam = setting
    row, _ = _lifted_row(fig, Q, cam, frame, loss)
    row.irls = 100  # the robust Procrustes converged, so the profiled cost is stationary in R
    b = _eval(row, fig, Q, True)
    grad = dense_jacobian([b], T, fig.nv)[0].T @ b.r.ravel()
    fd = _fd_jacobian(lambda QQ: np.array(_eval(row, fig, QQ, False).cost), fig, Q)
    assert np.abs(grad - fd).max() <= 2e-5 * np.abs(grad).max()
    if loss != "l2":
        l2, _ = _lifted_row(fig, Q, cam, frame, "l2")
        assert b.cost < _eval(l2, fig, Q, False).cost


def test_proportions_columns_match_finite_differences(setting):
    """With the figure's segment scale factors as globals: the rows' Jg^T Jg and Jg^T r
    against central differences of the chord residuals in g."""
    fig, Q, cam = setting
    props = Proportions.default(fig)
    g = 0.1 * np.random.default_rng(5).normal(size=props.n)
    row, _ = _lifted_row(fig, Q, cam, "camera")
    b = _eval(row, fig, Q, True, g=g, props=props)
    eps = 1e-6
    R = row.R_fixed
    fd = np.stack([(_chords(row, fig, Q, R, g + eps * e, props) - _chords(row, fig, Q, R, g - eps * e, props))
                   / (2 * eps) for e in np.eye(props.n)], axis=-1)
    Jg = np.zeros((b.r.size, props.n))
    Jg[:, b.gcols] = b.Jg.reshape(b.r.size, -1)
    assert np.abs(fd).max() > 0.01
    H, H_fd = Jg.T @ Jg, fd.T @ fd
    assert np.abs(H - H_fd).max() <= 1e-6 * np.abs(H_fd).max()
    grad_fd = fd.T @ _chords(row, fig, Q, R, g, props)
    assert np.abs(Jg.T @ b.r.ravel() - grad_fd).max() <= 1e-6 * np.abs(grad_fd).max()


def test_the_normal_basis_is_orthonormal_and_normal_at_every_direction():
    """The two rows' basis ``U`` (3 x 2) of the plane normal to a bone: ``U^T d = 0`` and
    ``U^T U = I`` for random directions and the poles and equator where a branchy formula fails."""
    from pinrecon.rows.lifted import _normal_basis

    rng = np.random.default_rng(4)
    d = rng.normal(size=(500, 3))
    d = np.r_[d, [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, -1, 0], [0, 1e-12, -1], [1e-9, 0, 1]]]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    U = _normal_basis(d)
    assert np.abs(np.einsum("nij,ni->nj", U, d)).max() < 1e-12
    assert np.abs(np.einsum("nij,nik->njk", U, U) - np.eye(2)).max() < 1e-12


def test_procrustes_recovers_a_rotation_from_noisy_directions():
    rng = np.random.default_rng(1)
    L = rng.normal(size=(200, 3))
    L /= np.linalg.norm(L, axis=1, keepdims=True)
    R = Rotation.from_rotvec([2.0, -0.4, 1.1]).as_matrix()
    D = L @ R.T + 0.02 * rng.normal(size=L.shape)
    R_est = procrustes_rotation(D, L, np.ones(len(L)))
    assert np.degrees(Rotation.from_matrix(R_est @ R.T).magnitude()) < 1.0
    assert np.isclose(np.linalg.det(R_est), 1.0)
    # mirrored data gives the best rotation, never a reflection
    assert np.isclose(np.linalg.det(procrustes_rotation(D * [1, 1, -1], L, np.ones(len(L)))), 1.0)


# ----------------------------------------------------------------------------- in a reconstruction
SEGMENTS = [("left_shoulder", "left_elbow"), ("left_elbow", "left_wrist"), ("right_shoulder", "right_elbow"),
            ("right_elbow", "right_wrist"), ("left_hip", "left_knee"), ("left_knee", "left_ankle"),
            ("right_hip", "right_knee"), ("right_knee", "right_ankle")]


@pytest.fixture(scope="module")
def clip():
    """A smooth motion of the human seen from 45 degrees by an orthographic camera (the two
    depth reflections of a limb have the same image), 1 px noise, and its truth."""
    fig = pr.Figure.human()
    Q = smooth_motion(fig, 24, 30.0, seed=1)
    cam = side_camera(Q, 45.0)
    tracks = project_tracks(fig, Q, cam, fps=30.0, noise_px=1.0, seed=1)
    return fig, Q, cam, tracks, fig.keypoints(Q)


def _with_lifted(tracks, points, frame="camera", confidence=None):
    return pr.Tracks(tracks.points, tracks.names, tracks.fps,
                     lifted=Lifted(points, list(tracks.names), confidence, frame, "test"))


def _flips(fig, P_est, P_true, cam):
    segs = [tuple(fig.keypoint_index(list(s))) for s in SEGMENTS]
    flip, count = metrics.flipped_segments(P_est, P_true, cam, segs)
    return flip.sum(axis=0), count.sum(axis=0)


def _solve(fig, tracks, cam, weights, seed="rest", init=None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = build_problem(fig, tracks, cam, weights=weights, seed=seed, init=init, calibrate="none")
        res = solve(s.problem, s.q0, active=s.active)
    return s.problem, fig.normalize(res.x), res


def test_the_lifted_cue_alone_decides_the_limbs_reflections(clip):
    """One orthographic camera, no keyframes: the multi-hypothesis start leaves limbs mirrored
    (the image cannot tell); the lifter's camera-frame pose (the truth, its own size and
    place) decides every limb, and the solve matches the truth."""
    fig, Q, cam, tracks, P = clip
    lifted = _with_lifted(tracks, 2.0 * (P @ cam.R.T) + [0.1, 0.2, 3.0])
    _, Q0, _ = _solve(fig, lifted, cam, pr.Weights(lifted=0), seed="hypotheses")
    flips0, count = _flips(fig, fig.keypoints(Q0), P, cam)
    assert flips0.sum() >= 0.1 * count.sum()  # without the rows: mirrored limbs
    _, Q1, _ = _solve(fig, lifted, cam, pr.Weights(), seed="hypotheses")
    flips1, _ = _flips(fig, fig.keypoints(Q1), P, cam)
    assert flips1.sum() == 0
    assert metrics.pa_mpjpe(fig.keypoints(Q1), P) < 25.0 < metrics.pa_mpjpe(fig.keypoints(Q0), P)


def test_a_lifter_wrong_by_180_degrees_on_a_span_is_outvoted(clip, tmp_path):
    """The lifter's left forearm points the opposite way in frames 6-17: the image outvotes
    it under the robust loss (the forearm stays within a few degrees of the truth there),
    the result reports that span for that bone, and the report survives save/load. Under
    least squares and a strong weight the same lifter drags the forearm off."""
    fig, Q, cam, tracks, P = clip
    X = P @ cam.R.T
    e, w = fig.keypoint_index(["left_elbow", "left_wrist"])
    X[6:18, w] = 2 * X[6:18, e] - X[6:18, w]
    lifted = _with_lifted(tracks, X)
    span = slice(6, 18)

    def forearm_error_deg(Qs):
        K = fig.keypoints(Qs)
        a, b = K[span, w] - K[span, e], P[span, w] - P[span, e]
        cos = np.sum(a * b, -1) / np.linalg.norm(a, axis=-1) / np.linalg.norm(b, axis=-1)
        return np.degrees(np.arccos(np.clip(cos, -1, 1))).max()

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct(fig, lifted, cam, init=Q, floor="none", calibrate="none")
    assert forearm_error_deg(res.q) < 10.0
    _, Q_l2, _ = _solve(fig, lifted, cam, pr.Weights(lifted=2000.0, lifted_loss="l2"), seed=None, init=Q)
    assert forearm_error_deg(Q_l2) > 30.0
    x = res.extras
    bones = [str(b) for b in x["lifted_bones"]]
    spans = x["lifted_spans"]
    hit = spans[spans[:, 0] == bones.index("left_elbow-left_wrist")]
    assert len(hit) == 1 and tuple(hit[0, 1:3]) == (6, 18) and hit[0, 3] > 150.0
    assert set(spans[:, 0].astype(int)) == {bones.index("left_elbow-left_wrist")}
    assert np.nanmax(x["lifted_disagreement_deg"][:6]) < 20.0
    assert "left_elbow-left_wrist: frames 6-17" in res.summary()
    path = tmp_path / "r.npz"
    res.save(path)
    back = pr.load_result(path)
    for k in ("lifted_disagreement_deg", "lifted_frame_deg", "lifted_spans", "lifted_rotation", "lifted_bones"):
        np.testing.assert_array_equal(np.asarray(back.extras[k]), np.asarray(x[k]))
    assert "left_elbow-left_wrist: frames 6-17" in back.summary()


def test_scale_and_translation_of_the_lifted_points_do_not_matter(clip):
    fig, Q, cam, tracks, P = clip
    X = P @ cam.R.T + 0.02 * np.random.default_rng(2).normal(size=P.shape)
    Q0 = np.stack([fig.integrate(q, 0.1 * np.random.default_rng(4).normal(size=fig.nv)) for q in Q])
    _, Qa, ra = _solve(fig, _with_lifted(tracks, X), cam, pr.Weights(), seed=None, init=Q0)
    _, Qb, rb = _solve(fig, _with_lifted(tracks, 3.0 * X + [5.0, -2.0, 40.0]), cam, pr.Weights(), seed=None, init=Q0)
    _, Qc, _ = _solve(fig, _with_lifted(tracks, X), cam, pr.Weights(lifted=0), seed=None, init=Q0)
    assert np.abs(Qa - Qb).max() < 1e-6 and abs(ra.cost - rb.cost) < 1e-6 * ra.cost
    assert np.abs(Qa - Qc).max() > 1e-3  # the rows do act


def test_an_unknown_lifter_frame_is_recovered(clip):
    """The lifter's axes turned by a fixed rotation: the profiled rotation at the solution is
    that rotation (to the noise), and the solution is the camera-frame lifter's."""
    fig, Q, cam, tracks, P = clip
    X = P @ cam.R.T + 0.02 * np.random.default_rng(3).normal(size=P.shape)
    R_lifter_cam = Rotation.from_rotvec([0.4, 2.5, -0.3]).as_matrix()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = pr.reconstruct(fig, _with_lifted(tracks, X @ R_lifter_cam.T, "unknown"), cam, init=Q, floor="none",
                             calibrate="none")
    R_world_lifter = (R_lifter_cam @ cam.R).T
    err = Rotation.from_matrix(res.extras["lifted_rotation"][0] @ R_world_lifter.T).magnitude()
    assert np.degrees(err) < 2.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        known = pr.reconstruct(fig, _with_lifted(tracks, X), cam, init=Q, floor="none", calibrate="none")
    assert metrics.mpjpe(res.keypoints3d, known.keypoints3d) < 5.0


@pytest.mark.parametrize("source", ["mediapipe", "motionbert"])
def test_mediapipes_foot_points_are_no_cue(source):
    """MediaPipe's heels and foot tips (its least accurate 3D, pinrecon.lifted.UNUSED_CUES) make
    no lifted bone; the same points from another lifter do. Their 2D points are measured either
    way, and the lifted positions themselves are kept."""
    fig = pr.Figure.human("mediapipe33")
    Q = smooth_motion(fig, 6, 30.0, seed=2)
    cam = side_camera(Q, 45.0)
    tracks = project_tracks(fig, Q, cam, fps=30.0, noise_px=0.5, seed=2)
    lifted = Lifted(fig.keypoints(Q), list(tracks.names), None, "unknown", source)  # the truth, world axes
    cues = lifted.cues()
    feet = {"left_heel", "right_heel", "left_foot_index", "right_foot_index"}
    np.testing.assert_array_equal(cues.points, lifted.points)
    assert (cues.confidence[:, [tracks.names.index(n) for n in feet]] == 0).all() == (source == "mediapipe")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = build_problem(fig, pr.Tracks(tracks.points, tracks.names, tracks.fps, lifted=lifted), cam,
                          calibrate="none")
    (row,) = [r for r in s.problem.rows if isinstance(r, LiftedPose)]
    touched = {n for bone in row.names for n in bone.split("-")}
    assert (touched & feet == set()) == (source == "mediapipe")
    assert {"left_knee", "left_ankle", "left_shoulder", "right_wrist"} <= touched
    assert feet <= set(s.problem.views[0].tracks.names)  # the feet still measured in 2D
