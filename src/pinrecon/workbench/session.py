"""The workbench's state, apart from any user interface: a motion being corrected.

A :class:`Session` holds the inputs of :func:`pinrecon.reconstruct` (figure, tracks,
camera, weights), the keyframes, and the current trajectory. Every edit adds, changes
or deletes a keyframe and also reshapes the current trajectory near the edit into the
warm start the next solve begins from:

* :meth:`Session.flip` flips a limb segment's depth at a frame (a partial point
  keyframe of the mirrored segment) and flips it in the warm start over the whole span of
  frames on that side of the ambiguity, so that the solve starts in the other basin;
* :meth:`Session.set_point` moves one keypoint (a point keyframe; the joints above it
  follow, spread over the neighbouring frames);
* :meth:`Session.set_joint` sets a joint's value (a joint keyframe);
* :meth:`Session.delete_keyframe`, :meth:`Session.move_keyframe`;
* :meth:`Session.undo` and :meth:`Session.redo` step through snapshots of (keyframes,
  trajectory), solves included.

:meth:`Session.solve` re-solves from the current trajectory: first only the window the
edits touched (its edges held by joint keyframes on the current motion), then the whole
sequence from there. The whole solve is the same problem ``pinrecon reconstruct`` solves
with the same keyframes (and the same ``floor``: the feet on the ground by default for the
generic human); the window, solved without the feet stage, only brings its start close.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .. import Keyframe, Keyframes, Result, SolverOptions, Tracks, Weights, reconstruct
from ..errors import InputError
from ..result import uncertain_limb_spans, unfamiliar_frames, unstable_spans
from .edits import (
    Segment,
    blend_delta,
    depth_difference,
    find_segment,
    fit_points,
    flip_span,
    mirror_segment,
    segments,
)

__all__ = ["Session", "SolveReport"]


@dataclass(frozen=True)
class _Snapshot:
    keyframes: tuple
    q: np.ndarray
    result: Result | None
    dirty: tuple[int, int] | None
    label: str


@dataclass
class SolveReport:
    """What :meth:`Session.solve` did: the window solved first (``None``: none), the
    seconds and iterations of each stage, and the final cost."""

    window: tuple[int, int] | None
    window_time: float
    window_iterations: int
    full_time: float
    full_iterations: int
    cost: float
    status: str

    @property
    def time(self) -> float:
        return self.window_time + self.full_time

    def __str__(self) -> str:
        w = ""
        if self.window is not None:
            w = f"window {self.window[0]}-{self.window[1]}: {self.window_iterations} it, {self.window_time:.2f} s; "
        return f"{w}whole: {self.full_iterations} it, {self.full_time:.2f} s ({self.status}), cost {self.cost:.6g}"


class Session:
    """A reconstruction being looked at and corrected.

    Parameters
    ----------
    figure, tracks, camera, keyframes, fps_out, weights : as for :func:`pinrecon.reconstruct`.
    floor : as for :func:`pinrecon.reconstruct` (default: its default, the feet on the ground
        for the generic human; ``"none"``: off), for the whole solves; the window solve goes
        without it (a span would estimate a floor of its own).
    result : a :class:`pinrecon.Result` to start from (e.g. ``load_result("result.npz")``);
        without one, the session solves once from scratch.
    options : :class:`pinrecon.SolverOptions` of the whole re-solve.
    sigma_flip_m, sigma_point_m, sigma_joint_rad : standard deviation of the keyframes the
        flips, the point moves and the joint sliders make.
    blend_s : seconds either side of an edited frame over which a point or joint edit is
        spread in the warm start.
    window_margin_s : seconds added either side of the edited frames for the window solve.
    warm_damping : initial Levenberg-Marquardt damping of the whole re-solve (relative to the
        diagonal; ``SolverOptions.damping`` is 1e-3 for solves from scratch). From a warm
        start the undamped first steps overshoot and are rejected: on 300 frames of the
        human the whole re-solve took 12 iterations with 1e-3, 5 of them rejected.
    """

    def __init__(
        self,
        figure,
        tracks: Tracks,
        camera,
        keyframes: Keyframes | Sequence[Keyframe] | None = None,
        *,
        result: Result | None = None,
        fps_out: float | None = None,
        weights: Weights | None = None,
        floor=None,
        options: SolverOptions | None = None,
        sigma_flip_m: float = 0.02,
        sigma_point_m: float = 0.02,
        sigma_joint_rad: float = 0.05,
        blend_s: float = 0.3,
        window_margin_s: float = 0.5,
        warm_damping: float = 1.0,
    ):
        if not isinstance(tracks, Tracks):
            raise InputError(f"tracks must be a pinrecon.Tracks, got {type(tracks).__name__}", field="tracks")
        if isinstance(camera, (list, tuple)) or not hasattr(camera, "R"):
            raise InputError("the workbench takes one camera (an Orthographic or Perspective)", field="camera")
        self.figure, self.tracks, self.camera = figure, tracks, camera
        self.weights = weights or Weights()
        self.floor = floor
        self.options = options or SolverOptions()
        self.fps_out = fps_out
        self.factor = 1 if fps_out is None else int(round(float(fps_out) / tracks.fps))
        if self.factor < 1 or abs(self.factor * tracks.fps - (fps_out or tracks.fps)) > 1e-6 * tracks.fps:
            raise InputError(f"fps_out {fps_out} must be an integer multiple of the tracks' {tracks.fps:g} fps",
                             field="fps_out")
        self.n_frames = (tracks.T - 1) * self.factor + 1
        self.fps = tracks.fps * self.factor
        self.sigma_flip_m, self.sigma_point_m, self.sigma_joint_rad = sigma_flip_m, sigma_point_m, sigma_joint_rad
        self.blend_frames = max(1, int(round(blend_s * self.fps)))
        self.window_margin = max(2, int(round(window_margin_s * self.fps)))
        self.warm_damping = float(warm_damping)
        kf = list(keyframes) if keyframes is not None else []
        Keyframes(kf).validate(figure, tracks.T)
        self._track_names = [n for n in tracks.names if n in figure.keypoint_names]
        self._segments = segments(figure)
        if result is None:
            result = self._reconstruct(kf, None, self.options, None)
        if "prior_model" in result.extras and self.weights.pose_prior_model == "auto":
            # the result was solved again with a broader pose prior (pinrecon.unfamiliar.broader_prior):
            # the edits' solves, warm, keep that one
            self.weights = replace(self.weights, pose_prior_model=str(result.extras["prior_model"]))
        q = figure.check_q(np.asarray(result.q, float), field="result.q")
        if q.shape != (self.n_frames, figure.nq):
            raise InputError(f"the result has shape {q.shape}, the tracks need {(self.n_frames, figure.nq)}",
                             field="result.q")
        self._undo: list[_Snapshot] = []
        self._redo: list[_Snapshot] = []
        self._state = _Snapshot(tuple(kf), q, result, None, "start")
        self._cache: tuple | None = None
        self._uncertain = _uncertain_spans(result, self.n_frames)

    # ------------------------------------------------------------------ reading
    @property
    def keyframes(self) -> Keyframes:
        return Keyframes(list(self._state.keyframes))

    @property
    def q(self) -> np.ndarray:
        return self._state.q

    @property
    def needs_solve(self) -> bool:
        """True when an edit has not been solved yet."""
        return self._state.dirty is not None

    @property
    def dirty_frames(self) -> tuple[int, int] | None:
        """The frames ``(first, last)`` the unsolved edits touched."""
        return self._state.dirty

    @property
    def segments(self) -> list[Segment]:
        return list(self._segments)

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    def can_redo(self) -> bool:
        return bool(self._redo)

    @property
    def history(self) -> list[str]:
        """Labels of the undoable steps, oldest first."""
        return [s.label for s in self._undo[1:]] + ([self._state.label] if self._undo else [])

    @property
    def keypoints3d(self) -> np.ndarray:
        """(T, K, 3) world keypoints of the current trajectory."""
        q = self._state.q
        if self._cache is None or self._cache[0] is not q:  # holds q, so its id is never reused
            self._cache = (q, self.figure.keypoints(q))
        return self._cache[1]

    def observed_frames(self) -> np.ndarray:
        """(T,) bool: output frames with at least one tracked point."""
        obs = np.zeros(self.n_frames, bool)
        sub = self.tracks.select(self._track_names)
        obs[np.where(sub.observed.any(axis=1))[0] * self.factor] = True
        return obs

    def reprojection_px(self) -> tuple[np.ndarray, np.ndarray]:
        """Projected keypoints (T, M, 2) of the tracked names and per-frame mean
        reprojection error (T,) in pixels (NaN where a frame has no observation)."""
        sub = self.tracks.select(self._track_names)
        idx = self.figure.keypoint_index(self._track_names)
        uv = self.camera.project(self.keypoints3d[:, idx])
        err = np.full(self.n_frames, np.nan)
        rows = np.arange(sub.T) * self.factor
        d = np.linalg.norm(uv[rows] - sub.points, axis=-1)
        d[~sub.observed] = np.nan
        has = sub.observed.any(axis=1)
        err[rows[has]] = np.nanmean(d[has], axis=1)
        return uv, err

    def result(self) -> Result:
        """The current trajectory as a :class:`pinrecon.Result` (the solver's own result
        when nothing changed since the last solve)."""
        r = self._state.result
        if r is not None and r.q is self._state.q:
            return r
        base = Result.from_motion(self.figure, self._state.q, self.fps, camera=self.camera)
        _, err = self.reprojection_px()
        return replace(base, reprojection_error_px=err, observed_frames=self.observed_frames())

    def uncertain_spans(self) -> list[tuple[int, int, str]]:
        """The spans ``(first frame, frame after the last, limb)`` whose depth the
        multi-hypothesis start of the first solve could not decide (cost gap between its
        two best hypotheses below its threshold, ``Result.extras["hypothesis_*"]``) or whose
        mirror the mirror stage found about as cheap (``["mirror_uncertain"]``), the poses
        the pose prior does not know, and the frames a stability check of the result found
        unstable (``reconstruct --stability N``): where to look for a limb on the wrong side
        first. Empty when none of these ran (e.g. with 3D keyframes, or a result made
        elsewhere)."""
        return list(self._uncertain)

    def keyframe_frames(self) -> np.ndarray:
        """Output frames that carry a keyframe (sorted, unique)."""
        return np.unique([k.frame * self.factor for k in self._state.keyframes]).astype(int)

    def joint_value(self, frame: int, joint: str) -> float:
        """Value of a 1-dof joint at ``frame`` (radians or metres)."""
        qs, _ = self._one_dof(joint)
        return float(self._state.q[frame, qs.start])

    def one_dof_joints(self) -> list[str]:
        m = self.figure.model
        return [n for n in self.figure.joint_names if m.nqs[self.figure.joint_id(n)] == 1 and m.nvs[self.figure.joint_id(n)] == 1]

    # ------------------------------------------------------------------ editing
    def _key_frame(self, frame: int) -> int:
        frame = int(frame)
        if not 0 <= frame < self.n_frames:
            raise InputError(f"frame {frame} is outside the sequence (0..{self.n_frames - 1})", field="frame", frame=frame)
        return int(round(frame / self.factor))

    def _push(self, keyframes, q, dirty, label, result=None):
        old = self._state
        if dirty is not None and old.dirty is not None:
            dirty = (min(dirty[0], old.dirty[0]), max(dirty[1], old.dirty[1]))
        self._undo.append(old)
        self._redo.clear()
        self._state = _Snapshot(tuple(keyframes), q, result, dirty, label)

    def _span(self, a, b, pad):
        return max(0, a - pad), min(self.n_frames - 1, b + pad)

    def flip(self, frame: int, segment: str, *, whole_limb: bool = False, sigma: float | None = None) -> Keyframe:
        """Flip the depth of limb ``segment`` (``"root>child"`` or the child's name) at
        ``frame``: add a point keyframe of the mirrored segment (its root, the child and
        the keypoints below it) and flip the segment in the warm start over the span of
        frames on the same side of the ambiguity. Returns the keyframe."""
        seg = find_segment(self.figure, segment)
        kf_frame = self._key_frame(frame)
        f = kf_frame * self.factor
        names = [seg.root, *seg.moved]
        idx = self.figure.keypoint_index(names)
        P = self.keypoints3d
        root, child, below = idx[0], idx[1], list(idx[2:])
        P_key = mirror_segment(self.camera, P[f], root, child, below, whole_limb)
        key = Keyframe(kf_frame, float(sigma or self.sigma_flip_m), points={n: P_key[i].copy() for n, i in zip(names, idx)})
        a, b = flip_span(self.camera, P, root, child, f)
        targets = mirror_segment(self.camera, P[a : b + 1], root, child, below, whole_limb)[:, idx[1:]]
        active = self.figure.support_mask(list(seg.moved)) & ~self.figure.support_mask([seg.root])
        Q = self._state.q.copy()
        Q[a : b + 1] = fit_points(self.figure, Q[a : b + 1], idx[1:], targets, active)
        keys = self._without_points(kf_frame, names)
        self._push([*keys, key], Q, self._span(a, b, 0), f"flip {seg.name} at {f}")
        return key

    def _without_points(self, kf_frame: int, names) -> list[Keyframe]:
        """The keyframes with ``names`` removed from the point keyframes at ``kf_frame``
        (an edit there replaces what they said about those points)."""
        out = []
        for k in self._state.keyframes:
            if k.frame == kf_frame and k.points is not None and any(n in k.points for n in names):
                rest = {n: v for n, v in k.points.items() if n not in names}
                if rest:
                    out.append(Keyframe(k.frame, k.sigma, points=rest))
                continue
            out.append(k)
        return out

    def depth_sign(self, frame: int, segment: str) -> float:
        """Sign of the segment's depth difference (child minus root, along the camera
        ray) at ``frame`` in the current trajectory."""
        seg = find_segment(self.figure, segment)
        r, c = self.figure.keypoint_index([seg.root, seg.child])
        return float(np.sign(depth_difference(self.camera, self.keypoints3d[frame], r, c)))

    def set_point(self, frame: int, keypoint: str, p_world, *, sigma: float | None = None) -> Keyframe:
        """Put ``keypoint`` at ``p_world`` (metres) at ``frame``: a point keyframe (merged
        into a point keyframe already at that frame); the joints above the keypoint move
        there in the warm start, spread over the neighbouring frames."""
        kf_frame = self._key_frame(frame)
        f = kf_frame * self.factor
        p = np.asarray(p_world, float).reshape(3)
        if not np.all(np.isfinite(p)):
            raise InputError("position must be finite", field="p_world", frame=frame)
        idx = self.figure.keypoint_index([keypoint])
        keys = self._without_points(kf_frame, [keypoint])
        last = max((i for i, k in enumerate(keys) if k.frame == kf_frame and k.points is not None), default=None)
        if last is not None:
            k = keys[last]
            key = keys[last] = Keyframe(kf_frame, k.sigma, points={**k.points, keypoint: p})
        else:
            key = Keyframe(kf_frame, float(sigma or self.sigma_point_m), points={keypoint: p})
            keys.append(key)
        active = self.figure.support_mask([keypoint])
        active[self.figure.root_v] = False
        if not active.any():
            active[self.figure.root_v] = True
        q_f = fit_points(self.figure, self._state.q[f : f + 1], idx, p[None, None], active, iterations=30)[0]
        Q = blend_delta(self.figure, self._state.q, f, q_f, self.blend_frames)
        self._push(keys, Q, self._span(f, f, self.blend_frames), f"move {keypoint} at {f}")
        return key

    def _one_dof(self, joint):
        jid = self.figure.joint_id(joint, field="joint")
        m = self.figure.model
        if not (m.nqs[jid] == 1 and m.nvs[jid] == 1):
            raise InputError(f"joint {joint!r} is not a 1-dof joint; 1-dof joints: {self.one_dof_joints()}", field="joint")
        return self.figure.joint_slices(joint)

    def set_joint(self, frame: int, joint: str, value: float, *, sigma: float | None = None) -> Keyframe:
        """Set 1-dof ``joint`` to ``value`` (radians or metres) at ``frame``: a joint
        keyframe (merged into a joint keyframe already at that frame), spread over the
        neighbouring frames in the warm start."""
        kf_frame = self._key_frame(frame)
        f = kf_frame * self.factor
        qs, _ = self._one_dof(joint)
        value = float(value)
        if not np.isfinite(value):
            raise InputError("value must be finite", field="value", frame=frame)
        keys = list(self._state.keyframes)
        for i in range(len(keys) - 1, -1, -1):
            k = keys[i]
            if k.frame == kf_frame and k.joints is not None:
                key = Keyframe(kf_frame, k.sigma, joints={**k.joints, joint: np.array(value)})
                keys[i] = key
                break
        else:
            key = Keyframe(kf_frame, float(sigma or self.sigma_joint_rad), joints={joint: np.array(value)})
            keys.append(key)
        q_f = self._state.q[f].copy()
        q_f[qs] = value
        Q = blend_delta(self.figure, self._state.q, f, self.figure.clamp(q_f), self.blend_frames)
        self._push(keys, Q, self._span(f, f, self.blend_frames), f"set {joint} at {f}")
        return key

    def delete_keyframe(self, index: int) -> Keyframe:
        """Remove keyframe ``index`` (its position in :attr:`keyframes`)."""
        keys = list(self._state.keyframes)
        if not 0 <= index < len(keys):
            raise InputError(f"no keyframe {index}; there are {len(keys)}", field="keyframe")
        k = keys.pop(index)
        f = k.frame * self.factor
        self._push(keys, self._state.q, self._span(f, f, self.window_margin), f"delete keyframe at {f}")
        return k

    def move_keyframe(self, index: int, frame: int) -> Keyframe:
        """Move keyframe ``index`` to ``frame`` (same values)."""
        keys = list(self._state.keyframes)
        if not 0 <= index < len(keys):
            raise InputError(f"no keyframe {index}; there are {len(keys)}", field="keyframe")
        kf_frame = self._key_frame(frame)
        old = keys[index]
        keys[index] = Keyframe(kf_frame, old.sigma, points=old.points, joints=old.joints)
        a, b = sorted((old.frame * self.factor, kf_frame * self.factor))
        self._push(keys, self._state.q, self._span(a, b, self.window_margin), f"move keyframe {old.frame} -> {kf_frame}")
        return keys[index]

    def undo(self) -> bool:
        if not self._undo:
            return False
        self._redo.append(self._state)
        self._state = self._undo.pop()
        return True

    def redo(self) -> bool:
        if not self._redo:
            return False
        self._undo.append(self._state)
        self._state = self._redo.pop()
        return True

    # ------------------------------------------------------------------ solving
    def _reconstruct(self, keys, init, options, callback, tracks=None):
        return reconstruct(
            self.figure,
            tracks if tracks is not None else self.tracks,
            self.camera,
            Keyframes(list(keys)) if keys else None,
            fps_out=self.fps_out,
            weights=self.weights,
            init=init,
            options=options,
            callback=callback,
            # the workbench edits motion on the figure as given (fit proportions first with
            # `pinrecon reconstruct --save-figure` and open the calibrated figure)
            calibrate="none",
            # a window's solve (tracks given) goes without the feet stage: it would estimate
            # a floor of its own from the span; the whole solve then puts the feet down
            floor="none" if tracks is not None else self.floor,
        )

    def _warm_options(self, options: SolverOptions) -> SolverOptions:
        """After the window solve the whole trajectory is near a minimum: Levenberg-Marquardt
        starts with more damping (``warm_damping``) so that its first steps are not
        rejected one after another. (The window itself starts as a user's edit left it,
        far from its minimum, and keeps the default.)"""
        return replace(options, damping=max(options.damping, self.warm_damping))

    def _window(self) -> tuple[int, int] | None:
        d = self._state.dirty
        if d is None:
            return None
        a, b = self._span(d[0], d[1], self.window_margin)
        a, b = (a // self.factor) * self.factor, -(-b // self.factor) * self.factor
        b = min(b, self.n_frames - 1)
        if b - a + 1 > 0.6 * self.n_frames or b - a < 4 * self.factor:
            return None
        return a, b

    def _solve_window(self, a, b, callback):
        """Solve frames [a, b] (output grid, multiples of the factor) from the current
        trajectory with the user's keyframes inside and the two first and last frames
        held on the current motion (unless they are the sequence's ends)."""
        f = self.factor
        ta, tb = a // f, b // f
        sub = self.tracks.frames(ta, tb + 1)
        keys = [Keyframe(k.frame - ta, k.sigma, points=k.points, joints=k.joints) for k in self._state.keyframes
                if ta <= k.frame <= tb]
        Q = self._state.q
        hold = []
        if ta > 0:
            hold += [ta, ta + 1]
        if tb < self.tracks.T - 1:
            hold += [tb - 1, tb]
        for t in hold:
            q_t = Q[t * f]
            joints = {n: q_t[self.figure.joint_slices(n)[0]].copy() for n in self.figure.joint_names}
            keys.append(Keyframe(t - ta, 1e-3, joints=joints))
        opts = replace(self.options, max_iterations=min(self.options.max_iterations, 40))
        return self._reconstruct(keys, Q[a : b + 1], opts, callback, tracks=sub)

    def solve(self, callback: Callable | None = None, *, window: bool = True) -> SolveReport:
        """Re-solve from the current trajectory (a warm start): first the window around
        the unsolved edits (when it is small), then the whole sequence.

        ``callback(stage, report)`` gets ``"window"`` or ``"whole"`` and each iteration's
        :class:`pinrecon.solver.IterationReport`; returning True stops that stage.
        """
        Q = self._state.q
        win = self._window() if window else None
        t0 = time.perf_counter()
        w_it = 0
        if win is not None:
            a, b = win
            cb = None if callback is None else (lambda rep: callback("window", rep))
            rw = self._solve_window(a, b, cb)
            Q = Q.copy()
            Q[a : b + 1] = rw.q
            w_it = rw.solve.iterations
        t1 = time.perf_counter()
        cb = None if callback is None else (lambda rep: callback("whole", rep))
        res = self._reconstruct(self._state.keyframes, Q, self._warm_options(self.options), cb)
        t2 = time.perf_counter()
        self._push(self._state.keyframes, res.q, None, "solve", result=res)
        s = res.solve
        return SolveReport(win, t1 - t0, w_it, t2 - t1, s.iterations, s.cost, s.status)

    # ------------------------------------------------------------------ keeping
    def save(self, keyframes_path=None, result_path=None) -> list[Path]:
        """Write the keyframes JSON and/or the result NPZ (each atomically)."""
        out = []
        if keyframes_path is not None:
            self.keyframes.save(keyframes_path)
            out.append(Path(keyframes_path))
        if result_path is not None:
            self.result().save(result_path)
            out.append(Path(result_path))
        return out

    def export(self, *, bvh=None, csv=None, html=None) -> list[Path]:
        """Export the current motion as BVH, CSV and/or a self-contained HTML player."""
        from ..io.bvh import write_bvh
        from ..io.csv_export import write_csv
        from .html_export import export_html

        out = []
        res = self.result()
        if bvh is not None:
            write_bvh(bvh, self.figure, res.q, res.fps, unit="m")  # metres, as every export
            out.append(Path(bvh))
        if csv is not None:
            write_csv(csv, res)
            out.append(Path(csv))
        if html is not None:
            export_html(res, html, keyframe_frames=self.keyframe_frames())
            out.append(Path(html))
        return out


#: the label of a span whose poses the pose prior does not know (:mod:`pinrecon.unfamiliar`)
UNFAMILIAR = "all limbs: pose unlike the prior's clips"
#: the start of the label of a span a stability check found unstable (:mod:`pinrecon.stability`)
UNSTABLE = "unstable"


def _uncertain_spans(result, n_frames: int) -> list[tuple[int, int, str]]:
    """``(start, stop, chain)`` of the spans the hypothesis search called uncertain
    (:func:`pinrecon.result.hypothesis_spans`), of those whose mirror the mirror stage found
    as cheap (:func:`pinrecon.result.mirror_uncertain`), of the poses the pose prior does
    not know (:func:`pinrecon.result.unfamiliar_frames`, labelled :data:`UNFAMILIAR`) and of
    the frames a stability check found unstable (:func:`pinrecon.result.unstable_spans`, a
    result of ``reconstruct --stability N``, labelled by the keypoint that moved most),
    clipped to the frames."""
    extras = getattr(result, "extras", None) or {}
    spans = [(a, b, chain) for chain, a, b in uncertain_limb_spans(extras)]
    spans += [(int(a), int(b), UNFAMILIAR) for a, b in unfamiliar_frames(extras)[2]]
    pct = 100 * float(extras.get("stability_drop", np.nan))
    spans += [(a, b, f"{UNSTABLE}: {name} moved up to {mm:.0f} mm with {pct:g} % of the detections left out")
              for a, b, name, mm, _ in unstable_spans(extras)]
    clipped = [(max(0, a), min(n_frames, b), label) for a, b, label in spans]
    return sorted((a, b, label) for a, b, label in clipped if b > a)
