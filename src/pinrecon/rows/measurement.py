"""2D measurement rows (DiFranco et al. eq. 1): reprojection error of tracked keypoints.

For frame t and keypoint k observed at ``uv_obs``:
``r = sqrt(w_tk) (pi(p_k(q_t)) - uv_obs) / sigma_px`` with Jacobian
``sqrt(w_tk) / sigma_px * d pi / d X * J_k(q_t)`` (``J_k`` the keypoint Jacobian).
A missing point contributes zero rows. Optional robust loss (Huber or Cauchy, scale in
pixels) is applied by iteratively reweighting each point's two rows.

Global unknowns: with the figure's proportions in the state, ``d r / d theta =
sqrt(w) / sigma_px * d pi / d X * d p_k / d theta``; with ``intrinsics`` (a
:class:`pinrecon.rows.CameraScale`) the camera is the one at ``g`` and
``d r / d log f = sqrt(w) / sigma_px * (uv - c)``, and with its pose unknowns the pose's
columns (:meth:`~pinrecon.rows.CameraScale.jacobian`).
"""

from __future__ import annotations

import numpy as np

from .base import RowBlock, RowKind, State, crop_aligned, supported_columns

__all__ = ["Measurement2D"]


class Measurement2D(RowKind):
    """Reprojection rows for 2D observations.

    Parameters
    ----------
    camera : a :class:`pinrecon.cameras.Camera`.
    frames : (N,) reconstruction frames that have observations.
    keypoints : (M,) figure keypoint indices observed.
    uv_px : (N, M, 2) observed image points, NaN where missing.
    weights : (N, M) per-point weights (confidence), 0 where missing.
    sigma_px : pixel standard deviation.
    loss : ``"l2"``, ``"huber"`` or ``"cauchy"``; ``loss_scale_px`` its scale.
    intrinsics : optional :class:`pinrecon.rows.CameraScale` making the camera's
        log scale / log focal length the global unknown ``g[intrinsics.col]``.
    """

    name = "measurement"

    def __init__(
        self, camera, frames, keypoints, uv_px, weights, sigma_px=2.0, loss="l2", loss_scale_px=None, intrinsics=None
    ):
        self.camera = camera
        self.intrinsics = intrinsics
        self.frames = np.asarray(frames, dtype=int)
        self.kinematic_frames = self.frames
        self.keypoints = np.asarray(keypoints, dtype=int)
        self.uv_px = np.asarray(uv_px, float)
        w = np.asarray(weights, float)
        observed = np.all(np.isfinite(self.uv_px), axis=-1) & (w > 0)
        self.observed = observed
        self.sqrt_w = np.sqrt(np.where(observed, w, 0.0)) / float(sigma_px)
        self.uv_filled = np.where(observed[..., None], self.uv_px, 0.0)
        self.sigma_px = float(sigma_px)
        if loss not in ("l2", "huber", "cauchy"):
            raise ValueError(f"loss must be 'l2', 'huber' or 'cauchy', got {loss!r}")
        self.loss = loss
        self.loss_scale = float(loss_scale_px if loss_scale_px is not None else 3.0 * sigma_px) / float(sigma_px)

    def _robust(self, e):
        """For whitened point errors e = |r_k|: (rho(e^2), sqrt(rho'(e^2))) per point.

        Huber: rho(s) = s for s <= c^2, else 2 c sqrt(s) - c^2.  Cauchy: rho(s) = c^2 log(1 + s/c^2).
        The Gauss-Newton rows are scaled by sqrt(rho') (iteratively reweighted least squares)
        and the reported cost is 0.5 * sum rho, which is what the solver's step test uses.
        """
        c = self.loss_scale
        s = e * e
        if self.loss == "huber":
            inside = e <= c
            rho = np.where(inside, s, 2.0 * c * e - c * c)
            w = np.where(inside, 1.0, np.sqrt(c / np.maximum(e, 1e-300)))
        else:  # cauchy
            rho = c * c * np.log1p(s / (c * c))
            w = 1.0 / np.sqrt(1.0 + s / (c * c))
        return rho, w

    def crop(self, lo: int, hi: int) -> Measurement2D:
        return crop_aligned(self, lo, hi, ("uv_px", "observed", "sqrt_w", "uv_filled"))

    def camera_at(self, state: State):
        """The camera at the state's globals (the fixed camera without intrinsics)."""
        if self.intrinsics is None or state.g is None:
            return self.camera
        return self.intrinsics.camera(state.g)

    def evaluate(self, state: State, jacobian: bool = True) -> RowBlock:
        slots = state.slot[self.frames]
        P = state.points[slots][:, self.keypoints]  # (N, M, 3)
        camera = self.camera_at(state)
        if jacobian:
            uv, d_uv = camera.project_with_jacobian(P)  # (N, M, 2), (N, M, 2, 3)
        else:
            uv = camera.project(P)
        err = (uv - self.uv_filled) * self.sqrt_w[..., None]
        scale, cost = self.sqrt_w, None
        if self.loss != "l2":
            rho, rw = self._robust(np.linalg.norm(err, axis=-1))
            err = err * rw[..., None]
            scale, cost = self.sqrt_w * rw, 0.5 * float(rho.sum())
        N, M = len(self.frames), len(self.keypoints)
        r = err.reshape(N, 2 * M)
        J = Jg = gcols = None
        if jacobian:
            ortho = hasattr(camera, "scale")  # orthographic: d uv / d X is one constant 2x3 matrix
            # sqrt(w) d uv / d X  d p_k / d v, projected before forming the keypoint Jacobians
            cols = self._columns(state.figure)  # structurally non-zero columns only
            A = camera.scale * camera.R[:2] if ortho else d_uv
            J = state.point_jacobians(slots, self.keypoints, A, scale, cols)
            J = J.reshape(N, 1, 2 * M, -1)
            n_p = len(state.proportion_cols) if state.has_global_points else 0
            cam_cols = self.intrinsics.cols if self.intrinsics is not None and state.g is not None else np.zeros(0, int)
            if n_p or len(cam_cols):  # (N, M, 2, globals): the proportions' columns, then the camera's
                Jg = np.empty((N, M, 2, n_p + len(cam_cols)))
                if n_p:
                    state.global_point_jacobians(slots, self.keypoints, A, out=Jg[..., :n_p])
                if len(cam_cols):
                    Jg[..., n_p:] = self.intrinsics.jacobian(state.g, uv, d_uv, P)
                Jg *= scale[..., None, None]
                Jg = Jg.reshape(N, 2 * M, -1)
                gcols = np.r_[np.asarray(state.proportion_cols, dtype=int)[:n_p], cam_cols].astype(int)
        cols = self._columns(state.figure) if jacobian else np.arange(state.figure.nv)
        return RowBlock(self.frames[:, None], r, J, cols, self.name, cost_value=cost, Jg=Jg, gcols=gcols)

    def _columns(self, figure) -> np.ndarray:
        return supported_columns(figure, self.keypoints)

    def reprojection_error_px(self, state: State) -> np.ndarray:
        """(N, M) pixel distance between projection and observation, NaN where missing."""
        P = state.points[state.slot[self.frames]][:, self.keypoints]
        d = np.linalg.norm(self.camera_at(state).project(P) - self.uv_px, axis=-1)
        return np.where(self.observed, d, np.nan)
