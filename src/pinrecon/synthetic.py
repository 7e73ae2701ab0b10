"""Synthetic observations with known answers: the ground truth that tests, benchmarks,
examples and the demo share.

* :func:`smooth_motion` makes a smooth motion of any figure inside its joint limits.
* :func:`project_tracks` projects a motion's keypoints through a camera into 2D tracks,
  with pixel noise, randomly missing points and missing frame ranges.
* :func:`point_keyframes` samples noisy 3D point keyframes from a motion.
* :func:`bundled_motion` loads a bundled CMU clip as a figure and its motion.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from .tracks import Keyframes, Markers, Tracks, keyframes_from_points

__all__ = [
    "smooth_motion",
    "project_tracks",
    "point_keyframes",
    "noisy_markers",
    "bundled_motion",
    "body_keypoints",
    "human_walk",
    "side_camera",
    "BODY_EXCLUDE",
    "COCO_BODY_FROM_CMU",
    "coco_body_tracks",
    "perspective_side_camera",
    "detector_faults",
    "DetectorFaults",
]

#: substrings of BVH keypoint names left out of "body" keypoint sets (CMU fingers carry no data)
BODY_EXCLUDE = ("Finger", "Thumb", "Index")


def smooth_motion(figure, n_frames: int, fps: float = 30.0, seed=0, amplitude: float = 0.35, speed_mps: float = 1.0):
    """A smooth motion (n_frames, nq): every limited joint oscillates around the middle of
    its range (a sum of two sinusoids, 0.2-1.2 Hz, peak ``amplitude`` of the half range);
    unlimited joints oscillate by +-0.4 rad; a free-flyer root walks along +x at
    ``speed_mps`` with a slow yaw about +y and a small bounce."""
    rng = np.random.default_rng(seed)
    m = figure.model
    t = np.arange(n_frames) / fps
    Q = np.tile(figure.neutral(), (n_frames, 1))
    for jid in range(2 if figure.floating else 1, m.njoints):
        if m.nqs[jid] != 1 or m.nvs[jid] != 1:
            continue
        iq, iv = m.idx_qs[jid], m.idx_vs[jid]
        lo, hi = figure.lower_v[iv], figure.upper_v[iv]
        if np.isfinite(lo) and np.isfinite(hi):
            mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        else:
            mid, half = 0.0, 0.4 / max(amplitude, 1e-9)
        f1, f2 = rng.uniform(0.2, 1.2, 2)
        p1, p2 = rng.uniform(0, 2 * np.pi, 2)
        a = rng.uniform(0.3, 1.0)
        wave = a * np.sin(2 * np.pi * f1 * t + p1) + (1 - a) * np.sin(2 * np.pi * f2 * t + p2)
        Q[:, iq] = mid + amplitude * half * wave
    if figure.floating:
        from scipy.spatial.transform import Rotation

        yaw = 0.3 * np.sin(2 * np.pi * 0.1 * t + rng.uniform(0, 2 * np.pi))
        Q[:, 0] = speed_mps * t
        Q[:, 1] = 0.02 * np.sin(2 * np.pi * 1.8 * t)
        Q[:, 2] = 0.1 * np.sin(2 * np.pi * 0.15 * t)
        Q[:, 3:7] = Rotation.from_euler("y", yaw[:, None]).as_quat()
    return figure.clamp(Q)


def project_tracks(
    figure,
    Q: np.ndarray,
    camera,
    names: Sequence[str] | None = None,
    *,
    fps: float,
    noise_px: float = 1.0,
    missing: float = 0.0,
    gaps: Iterable[tuple[int, int]] = (),
    seed=0,
) -> Tracks:
    """2D tracks of keypoints ``names`` (default: all) of motion ``Q`` through ``camera``.

    ``missing`` is the share of points dropped at random; ``gaps`` are frame ranges
    [start, stop) where every point is missing.
    """
    rng = np.random.default_rng(seed)
    names = list(names) if names is not None else list(figure.keypoint_names)
    P = figure.keypoints(Q)[:, figure.keypoint_index(names)]
    uv = camera.project(P) + rng.normal(0.0, noise_px, P.shape[:2] + (2,))
    if missing > 0:
        uv[rng.random(P.shape[:2]) < missing] = np.nan
    for a, b in gaps:
        uv[a:b] = np.nan
    return Tracks(uv, names, fps)


def point_keyframes(figure, Q, frames, names=None, sigma_m=0.02, noise_m=None, seed=0) -> Keyframes:
    """3D point keyframes at ``frames``: the true keypoint positions plus Gaussian noise of
    ``noise_m`` metres (default ``sigma_m``), each keyframe carrying ``sigma_m``."""
    rng = np.random.default_rng(seed)
    names = list(names) if names is not None else list(figure.keypoint_names)
    P = figure.keypoints(Q)[:, figure.keypoint_index(names)]
    noise = sigma_m if noise_m is None else noise_m
    return keyframes_from_points(list(frames), P + rng.normal(0.0, noise, P.shape), names, sigma_m)


def noisy_markers(figure, Q, names=None, *, fps, noise_m=0.01, missing=0.0, gaps=(), seed=0) -> Markers:
    """3D motion-capture markers at keypoints ``names`` with noise and dropped frames."""
    rng = np.random.default_rng(seed)
    names = list(names) if names is not None else list(figure.keypoint_names)
    P = figure.keypoints(Q)[:, figure.keypoint_index(names)]
    P = P + rng.normal(0.0, noise_m, P.shape)
    if missing > 0:
        P[rng.random(P.shape[:2]) < missing] = np.nan
    for a, b in gaps:
        P[a:b] = np.nan
    return Markers(P, names, fps)


def bundled_motion(name: str = "walk", lock="static"):
    """A bundled CMU clip (``walk``, ``run``, ``spin``) as (figure, q, fps), T-pose frame
    dropped, lengths in metres; joints whose channels are always zero are welded."""
    from ._resources import bundled_clip
    from .io.bvh import load_bvh

    m = load_bvh(bundled_clip(name), 0.056444, skip_frames=1, lock=lock)
    return m.figure, m.q, m.fps


def body_keypoints(figure) -> list[str]:
    """The figure's distinct keypoints without fingers/thumbs (CMU: 22 body points)."""
    return [n for n in figure.distinct_keypoint_names if not any(s in n for s in BODY_EXCLUDE)]


#: human-figure joint centres -> CMU BVH joints, for retargeting the bundled walk
HUMAN_FROM_CMU = {
    "pelvis": "Hips", "left_hip": "LeftUpLeg", "left_knee": "LeftLeg", "left_ankle": "LeftFoot",
    "left_toe": "LeftToeBase_end", "right_hip": "RightUpLeg", "right_knee": "RightLeg",
    "right_ankle": "RightFoot", "right_toe": "RightToeBase_end", "thorax": "Spine1", "neck": "Neck1",
    "head_top": "Head_end", "left_shoulder": "LeftArm", "left_elbow": "LeftForeArm", "left_wrist": "LeftHand",
    "right_shoulder": "RightArm", "right_elbow": "RightForeArm", "right_wrist": "RightHand",
}


def human_walk(n_frames: int, fps: float = 30.0):
    """Real walking on the example-robot-data human figure, of any length.

    The bundled CMU walk is retargeted to ``Figure.human()`` by fitting the figure's joint
    centres to the clip's joints (:func:`pinrecon.reconstruct_markers`, with the figure's
    joint limits and the weak rest-pose posture prior, not the pose prior), at ``fps`` (120 divisible by it). The most repeatable gait cycle (start
    and end pose and velocity closest) is then looped, treadmill-free: each loop continues
    from where the last ended. Returns (figure with COCO-17 keypoints, q (n_frames, nq)).
    """
    from .figure import Figure

    q_cycle, shift = _human_walk_cycle(float(fps))
    reps = int(np.ceil(n_frames / len(q_cycle)))
    loops = []
    for k in range(reps):
        c = q_cycle.copy()
        c[:, :3] += k * shift
        loops.append(c)
    Q = np.concatenate(loops)[:n_frames]
    return Figure.human(), Q


_CYCLE_CACHE: dict[float, tuple[np.ndarray, np.ndarray]] = {}


def _human_walk_cycle(fps: float):
    if fps in _CYCLE_CACHE:
        return _CYCLE_CACHE[fps]
    from .figure import Figure
    from .problem import Weights
    from .reconstruct import reconstruct_markers

    step = 120.0 / fps
    if abs(step - round(step)) > 1e-9 or step < 1:
        raise ValueError(f"fps must divide 120, got {fps}")
    bfig, bq, bfps = bundled_motion("walk")
    bq = bq[:: int(round(step))]
    human = Figure.human("joints")
    names = list(HUMAN_FROM_CMU)
    P = bfig.keypoints(bq)[:, bfig.keypoint_index([HUMAN_FROM_CMU[n] for n in names])]
    # the rest-pose posture prior: a ground truth made from the clip, not from the pose prior
    res = reconstruct_markers(human, Markers(P, names, fps), weights=Weights(sigma_markers_m=0.02, pose_prior=None),
                              calibrate="none")
    q = res.q
    # most repeatable cycle of 0.8 - 1.4 s: closest joint angles and joint velocities
    n = len(q)
    lo, hi = int(0.8 * fps), int(1.4 * fps)
    best = None
    for t0 in range(1, n - lo - 1):
        for t1 in range(t0 + lo, min(t0 + hi, n - 1)):
            d = np.linalg.norm(human.difference(q[t0], q[t1])[6:])
            dv = np.linalg.norm(human.difference(q[t0 + 1], q[t1 + 1])[6:] - human.difference(q[t0], q[t1])[6:])
            score = d + 0.5 * dv
            if best is None or score < best[0]:
                best = (score, t0, t1)
    _, t0, t1 = best
    shift = q[t1, :3] - q[t0, :3]
    _CYCLE_CACHE[fps] = (q[t0:t1].copy(), shift)
    return _CYCLE_CACHE[fps]


def side_camera(q, azimuth_deg: float = 45.0, *, scale: float = 300.0, center=(500.0, 500.0)):
    """An orthographic camera looking at a motion ``azimuth_deg`` away from side-on.

    Side-on means looking horizontally (world Y up) perpendicular to the root's overall
    direction of travel, from ``q[0]`` to ``q[-1]`` (0 degrees: the limbs swing in the image
    plane, the degenerate case of the planarity propositions).
    """
    from .cameras import Orthographic

    d = np.array(q[-1, :3] - q[0, :3], float)
    d[1] = 0.0
    n = np.linalg.norm(d)
    d = d / n if n > 1e-6 else np.array([0.0, 0.0, 1.0])
    side = np.cross([0.0, 1.0, 0.0], d)
    a = np.radians(azimuth_deg)
    return Orthographic.from_view(np.cos(a) * side + np.sin(a) * d, scale=scale, center=center)


#: the 12 COCO-17 body points -> the joints of the CMU MotionBuilder-friendly BVH skeletons
COCO_BODY_FROM_CMU = {
    "left_shoulder": "LeftArm", "right_shoulder": "RightArm", "left_elbow": "LeftForeArm",
    "right_elbow": "RightForeArm", "left_wrist": "LeftHand", "right_wrist": "RightHand",
    "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "left_knee": "LeftLeg", "right_knee": "RightLeg",
    "left_ankle": "LeftFoot", "right_ankle": "RightFoot",
}


def coco_body_tracks(figure, Q, camera, *, fps: float, noise_px: float = 0.0, seed=0,
                     joints: dict | None = None) -> tuple[Tracks, np.ndarray]:
    """A CMU clip's 12 body joints seen by ``camera`` as COCO-17 named tracks.

    ``joints``: COCO name -> the figure's joint (default :data:`COCO_BODY_FROM_CMU`, the
    motionbuilder release's names; another CMU release names them otherwise). Returns the
    tracks (``noise_px`` Gaussian pixel noise, nothing missing) and the true 3D positions
    (T, 12, 3) of those joints in the tracks' order (the ground truth a reconstruction with
    another figure, e.g. ``Figure.human()``, is scored against)."""
    joints = joints or COCO_BODY_FROM_CMU
    coco = list(joints)
    P = figure.keypoints(Q)[:, figure.keypoint_index([joints[n] for n in coco])]
    rng = np.random.default_rng(seed)
    uv = camera.project(P) + rng.normal(0.0, noise_px, P.shape[:2] + (2,))
    return Tracks(uv, coco, fps), P


def perspective_side_camera(q, azimuth_deg: float = 45.0, *, distance_m: float = 6.0, f_px: float = 1200.0,
                            height_m: float = 0.0, center=(960.0, 540.0)):
    """A perspective camera ``azimuth_deg`` from side-on (as :func:`side_camera`), standing
    ``distance_m`` from the middle of the root's path (horizontally) and ``height_m`` above
    it, looking at it."""
    from .cameras import Perspective

    d = np.array(q[-1, :3] - q[0, :3], float)
    d[1] = 0.0
    n = np.linalg.norm(d)
    d = d / n if n > 1e-6 else np.array([0.0, 0.0, 1.0])
    side = np.cross([0.0, 1.0, 0.0], d)
    a = np.radians(azimuth_deg)
    forward = np.cos(a) * side + np.sin(a) * d
    target = 0.5 * (np.asarray(q[0, :3], float) + np.asarray(q[-1, :3], float))
    eye = target - distance_m * forward + np.array([0.0, height_m, 0.0])
    return Perspective.look_at(eye, target, f_px=f_px, center=center)


class DetectorFaults(dict):
    """What :func:`detector_faults` did: ``swapped_frames`` (frames whose left and right
    labels were exchanged), ``outliers`` ((n, 2) frame, point index), ``missing`` ((T, K)
    bool)."""


def detector_faults(tracks: Tracks, *, noise_px: float = 2.0, outliers: float = 0.02,
                    outlier_px: tuple[float, float] = (20.0, 80.0), swaps: float = 0.01, missing: float = 0.03,
                    confidence: tuple[float, float] = (0.6, 1.0),
                    outlier_confidence: tuple[float, float] = (0.2, 0.6), seed=0) -> tuple[Tracks, DetectorFaults]:
    """Clean tracks made to look like a 2D detector's output.

    ``noise_px`` Gaussian noise on every point; a share ``outliers`` of the points thrown
    ``outlier_px`` pixels away in a random direction, with confidence drawn from
    ``outlier_confidence`` (the others from ``confidence``); a share ``swaps`` of the frames
    with every ``left_*``/``right_*`` (``Left*``/``Right*``) pair of labels exchanged
    (at least one frame when ``swaps > 0``); a share ``missing`` of the points dropped.
    Returns the faulty tracks (with confidences) and a :class:`DetectorFaults` log."""
    rng = np.random.default_rng(seed)
    uv = np.array(tracks.points, float)
    T, K = uv.shape[:2]
    uv += rng.normal(0.0, noise_px, uv.shape)
    conf = rng.uniform(*confidence, (T, K))
    n_out = int(round(outliers * T * K))
    flat = rng.choice(T * K, n_out, replace=False) if n_out else np.zeros(0, int)
    ft, fk = np.unravel_index(flat, (T, K))
    ang = rng.uniform(0.0, 2.0 * np.pi, n_out)
    r = rng.uniform(*outlier_px, n_out)
    uv[ft, fk] += np.stack([np.cos(ang), np.sin(ang)], axis=1) * r[:, None]
    conf[ft, fk] = rng.uniform(*outlier_confidence, n_out)
    from .faults import left_right_pairs

    pairs = left_right_pairs(tracks.names)
    n_swap = max(1, int(round(swaps * T))) if swaps > 0 and pairs else 0
    swapped = np.sort(rng.choice(T, n_swap, replace=False)) if n_swap else np.zeros(0, int)
    for a, b in pairs:
        uv[swapped[:, None], [a, b]] = uv[swapped[:, None], [b, a]]
        conf[swapped[:, None], [a, b]] = conf[swapped[:, None], [b, a]]
    miss = rng.random((T, K)) < missing
    uv[miss] = np.nan
    conf[miss] = 0.0
    log = DetectorFaults(swapped_frames=swapped, outliers=np.stack([ft, fk], axis=1), missing=miss)
    return Tracks(uv, list(tracks.names), tracks.fps, conf, tracks.source), log
