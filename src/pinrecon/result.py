"""The result layer: a reconstructed motion, its NPZ file, and reading it back.

Exports (:mod:`pinrecon.io.bvh_export`, :mod:`pinrecon.io.csv_export`) and pictures
(:mod:`pinrecon.viz`) import this module, never the pipeline.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from .cameras import camera_from_dict
from .figure import Figure, parse_keypoint_entries
from .io.results import load_result_npz, save_result_npz
from .solver import SolveResult

__all__ = ["Result", "load_result"]


@dataclass
class Result:
    """A reconstructed motion.

    Attributes
    ----------
    figure : the figure.
    q : (T, nq) configurations.
    times : (T,) seconds.
    fps : reconstruction frame rate.
    keypoints3d : (T, K, 3) world positions of all the figure's keypoints, metres.
    reprojection_error_px : (T,) mean reprojection error of the observed points per
        frame (NaN where a frame has no 2D observation).
    solve : the solver's :class:`~pinrecon.solver.SolveResult` (status, report ...).
    observed_frames : (T,) bool, frames that had observations.
    """

    figure: object
    q: np.ndarray
    times: np.ndarray
    fps: float
    keypoints3d: np.ndarray
    reprojection_error_px: np.ndarray
    solve: SolveResult | None
    observed_frames: np.ndarray
    camera: object = None
    extras: dict = field(default_factory=dict)

    @property
    def report(self):
        return self.solve.report if self.solve else []

    @property
    def keypoint_names(self) -> list[str]:
        return list(self.figure.keypoint_names)

    @property
    def joint_names(self) -> list[str]:
        return list(self.figure.joint_names)

    @classmethod
    def from_motion(cls, figure, q, fps, camera=None) -> Result:
        """A Result for a known motion (ground truth for plots and exports)."""
        q = figure.check_q(np.asarray(q, float))
        T = q.shape[0]
        return cls(figure, q, np.arange(T) / fps, float(fps), figure.keypoints(q), np.full(T, np.nan), None,
                   np.zeros(T, bool), camera)

    def keypoint(self, name: str) -> np.ndarray:
        return self.keypoints3d[:, self.figure.keypoint_index([name])[0]]

    def joint_angles(self) -> tuple[list[str], np.ndarray]:
        """Names and values (T, n) of the 1-dof joints (radians or metres)."""
        m = self.figure.model
        names, cols = [], []
        for jid in range(1, m.njoints):
            if m.nqs[jid] == 1 and m.nvs[jid] == 1:
                names.append(m.names[jid])
                cols.append(m.idx_qs[jid])
        return names, self.q[:, cols]

    def summary(self) -> str:
        s = self.solve
        err = np.nanmean(self.reprojection_error_px) if np.any(np.isfinite(self.reprojection_error_px)) else float("nan")
        lines = [
            f"{len(self.times)} frames at {self.fps:g} fps, figure {self.figure.name!r} (nv={self.figure.nv})",
            f"reprojection error {err:.3f} px (mean over observed points)",
        ]
        if s is not None:
            lines.append(
                f"solver: {s.status} after {s.iterations} iterations in {s.time:.2f} s, cost {s.initial_cost:.6g} -> {s.cost:.6g}"
            )
        return "\n".join(lines)

    def save(self, path) -> None:
        """Write the result NPZ (``docs/formats.md``), atomically. It embeds the figure's
        URDF and keypoint map so the file alone can be plotted and exported."""
        fig = self.figure
        parents = np.array([-1 if p is None else p for p in fig.parents_of_keypoints])
        meta = {k: v for k, v in fig.meta.items() if not k.startswith("_")}
        save_result_npz(
            path,
            q=self.q,
            times=self.times,
            keypoints3d=self.keypoints3d,
            keypoint_names=np.array(fig.keypoint_names),
            joint_names=np.array(fig.joint_names),
            fps=np.float64(self.fps),
            reprojection_error_px=self.reprojection_error_px,
            observed_frames=self.observed_frames,
            keypoint_parents=parents,
            figure_name=np.array(fig.name),
            figure_urdf=np.array(fig.urdf_xml or ""),
            figure_floating=np.array(fig.floating),
            figure_keypoints=np.array(json.dumps(fig.keypoint_map_dict())),
            figure_meta=np.array(json.dumps(meta)),
            figure_limits=np.array(json.dumps({k: list(v) for k, v in fig.limits_dict().items()})),
            camera=np.array(json.dumps(self.camera.to_dict()) if self.camera is not None else ""),
            solver_status=np.array(self.solve.status if self.solve else ""),
            solver_iterations=np.int64(self.solve.iterations if self.solve else 0),
            **{k: v for k, v in self.extras.items()},
        )


def load_result(path) -> Result:
    """Read a result NPZ back into a :class:`Result` (figure rebuilt from the embedded URDF)."""
    d = load_result_npz(path)
    fig = None
    if "figure_urdf" in d and str(d["figure_urdf"]):
        kps = parse_keypoint_entries(json.loads(str(d["figure_keypoints"]))["keypoints"], file=path)
        limits = {k: tuple(v) for k, v in json.loads(str(d.get("figure_limits", "{}"))).items()}
        fig = Figure.from_urdf_string(
            str(d["figure_urdf"]),
            kps,
            root="free" if bool(d["figure_floating"]) else "fixed",
            name=str(d["figure_name"]),
            limits=limits,
            meta=json.loads(str(d["figure_meta"])),
            source=str(path),
        )
    cam = None
    if "camera" in d and str(d["camera"]):
        cam = camera_from_dict(json.loads(str(d["camera"])), file=path)
    fps = float(d["fps"]) if "fps" in d else (1.0 / np.diff(d["times"]).mean() if len(d["times"]) > 1 else 1.0)
    T = d["q"].shape[0]
    return Result(
        figure=fig,
        q=d["q"],
        times=d["times"],
        fps=fps,
        keypoints3d=d["keypoints3d"],
        reprojection_error_px=d.get("reprojection_error_px", np.full(T, np.nan)),
        solve=None,
        observed_frames=d.get("observed_frames", np.zeros(T, bool)),
        camera=cam,
    )
