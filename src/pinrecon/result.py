"""The result layer: a reconstructed motion, its NPZ file, and reading it back.

Exports (:mod:`pinrecon.io.bvh_export`, :mod:`pinrecon.io.csv_export`) and pictures
(:mod:`pinrecon.viz`) import this module, never the pipeline.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from .cameras import camera_from_dict
from .contact import FOOT_EXTRAS, FootContact, foot_metrics, true_runs

#: extras of the hypotheses start, the fault stage, the pose prior's check and :mod:`pinrecon.stability`,
#: kept by :func:`load_result`
FAULT_EXTRAS_PREFIXES = ("hypothesis_", "repaired_", "outlier_", "prior_", "solution_turns", "solution_mirrors",
                         "mirror_chains", "mirror_uncertain", "stability_", "run_time_s", "lifted_")
from .errors import InputError
from .figure import Figure, parse_keypoint_entries
from .io.fields import string_field
from .io.motion import check_motion
from .io.results import check_calibration, load_result_npz, save_result_npz, text_json
from .rows.posture import unused_priors
from .solver import SolveResult
from .starts.camera_auto import implausible_focal
from .starts.limbs import LENGTH_RATIO_BOUNDS

__all__ = ["Result", "StageReport", "check_motion", "hypothesis_spans", "load_result"]


def spans_text(frames, limit: int | None = None) -> str:
    """Frames as ranges: ``41-63, 65, 67-73``; with ``limit``, at most that many ranges, then
    ``... (N ranges, M frames in all)``."""
    f = np.asarray(frames, int)
    if not len(f):
        return ""
    cut = np.flatnonzero(np.diff(f) > 1)
    starts, ends = f[np.r_[0, cut + 1]], f[np.r_[cut, len(f) - 1]]
    text = [str(a) if a == b else f"{a}-{b}" for a, b in zip(starts, ends)]
    if limit is not None and len(text) > limit:
        return ", ".join(text[:limit]) + f", ... ({len(text)} ranges, {len(f)} frames in all)"
    return ", ".join(text)


def span_text(a, b, fps: float) -> str:
    """The frames ``a`` to ``b - 1`` and their times: ``frames 84-90 (1.40-1.50 s)``, or
    ``frame 93 (1.55 s)`` for one."""
    a, b = int(a), int(b)
    if b - a == 1:
        return f"frame {a} ({a / fps:.2f} s)"
    return f"frames {a}-{b - 1} ({a / fps:.2f}-{(b - 1) / fps:.2f} s)"


#: ranges of frames a summary line lists at most (the result's extras hold them all)
SPANS_SHOWN = 12


@dataclass
class StageReport:
    """What one stage did: its name, wall time (s), the MAP cost before and after (the
    solver's cost, half the sum of squared whitened rows), and what it changed in words
    (``"skipped: ..."`` when it had nothing to do or was switched off)."""

    name: str
    seconds: float
    cost_before: float
    cost_after: float
    changed: str

    @property
    def ran(self) -> bool:
        return not self.changed.startswith("skipped")

    def to_dict(self) -> dict:
        return {"name": self.name, "seconds": float(self.seconds), "cost_before": float(self.cost_before),
                "cost_after": float(self.cost_after), "changed": self.changed}

    @classmethod
    def from_dict(cls, d: dict) -> StageReport:
        return cls(str(d["name"]), float(d["seconds"]), float(d["cost_before"]), float(d["cost_after"]),
                   str(d["changed"]))


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
    camera : the camera (the first camera when there are several).
    cameras : every camera, in the order they were given (``[camera]`` with one).
    camera_names : their names (from the calibration file, else ``camera1`` ...).
    reprojection_error_px_per_camera : (C, T) mean reprojection error of each camera's
        observed points per frame (NaN where that camera observed nothing); the
        ``reprojection_error_px`` above is the mean over every camera's points.
    stages : one :class:`StageReport` per stage of the pipeline that made it
        (:mod:`pinrecon.stages`), in the order they ran.
    calibration : what a calibrated solve fitted (:meth:`pinrecon.problem.
        ReconstructionProblem.calibration`): ``mode``, the segment groups' ``factors``,
        ``lengths_m`` and ``generic_lengths_m``, the ``cameras``' start and fitted focal
        length (or scale); empty without calibration. ``figure`` is then the calibrated
        figure and ``camera``/``cameras`` the fitted cameras.
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
    cameras: list = field(default_factory=list)
    camera_names: list = field(default_factory=list)
    reprojection_error_px_per_camera: np.ndarray | None = None
    calibration: dict = field(default_factory=dict)
    stages: list = field(default_factory=list)

    def __post_init__(self):
        if not self.cameras and self.camera is not None:
            self.cameras = [self.camera]
        if self.camera is None and self.cameras:
            self.camera = self.cameras[0]
        if len(self.camera_names) != len(self.cameras):
            self.camera_names = [f"camera{i + 1}" for i in range(len(self.cameras))]

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
        fig = self.figure
        what = f"figure {fig.name!r} (nv={fig.nv})" if fig is not None else "no embedded figure"
        lines = [f"{len(self.times)} frames at {self.fps:g} fps, {what}"]
        if np.isfinite(err) or self.cameras:  # a fit to 3D markers has no image to reproject into
            lines.append(f"reprojection error {err:.3f} px (mean over observed points)")
        per = self.reprojection_error_px_per_camera
        if per is not None and len(self.cameras) > 1:
            for name, e in zip(self.camera_names, per):
                m = np.nanmean(e) if np.any(np.isfinite(e)) else float("nan")
                lines.append(f"  camera {name!r}: {m:.3f} px")
        run = self.extras.get("run_time_s")
        if s is not None:
            took = f"solved in {float(run):.1f} s in all" if run is not None else f"solved in {s.time:.2f} s"
            lines.append(f"{took}; the last solve stopped ({s.status}) after {s.iterations} iterations, cost "
                         f"{s.initial_cost:.6g} -> {s.cost:.6g} (cost: see docs/glossary.md)")
        elif run is not None:
            lines.append(f"solved in {float(run):.1f} s in all")
        lines += self.stages_summary()
        lines += self.calibration_summary()
        lines += self.feet_summary()
        lines += self.faults_summary()
        lines += stability_lines(self.extras, self.fps)
        lines += lifted_lines(self.extras, self.fps)
        if self.cameras:  # a fit to 3D markers sees no image
            lines += unobserved_lines(self.observed_frames, self.fps)
        return "\n".join(lines)

    def stages_summary(self) -> list[str]:
        """The stages as a short table: name, time, MAP cost before and after, what changed."""
        if not self.stages:
            return []
        total = sum(s.seconds for s in self.stages)
        lines = [f"stages ({total:.2f} s in all): time, cost before -> after, what changed"]
        for s in self.stages:
            cost = f"{s.cost_before:.6g} -> {s.cost_after:.6g}" if s.ran and np.isfinite(s.cost_after) else "-"
            lines.append(f"  {s.name:<8} {s.seconds:7.2f} s  {cost:<24} {s.changed}")
        return lines

    def faults_summary(self, limit: int = 6) -> list[str]:
        """Uncertain limb-reflection spans (the hypotheses start), poses the pose prior does
        not know (:mod:`pinrecon.unfamiliar`), repaired left/right swaps and outliers (the
        fault stage), from ``extras``; frames of the reconstruction (spans) and of the
        tracks (repairs, outliers)."""
        x, lines = self.extras, []
        if "hypothesis_spans" in x:
            chains, spans, thr = hypothesis_spans(x)
            unc = spans[spans[:, 4] < thr]
            lines.append(f"limb reflections: {len(spans)} spans over {len(chains)} limbs, {len(unc)} uncertain "
                         f"(the mirror costs less than {thr:g} more: a keyframe there would decide them)")
            for c, a, b, _, gap in unc[np.argsort(unc[:, 4])][:limit]:
                lines.append(f"  {chains[int(c)]}: {span_text(a, b, self.fps)}, the mirror costs {gap:.1f} more")
            if len(unc) > limit:
                lines.append(f"  ... and {len(unc) - limit} more")
        for key, who, where in (("hypothesis_turns", "start took", "pinrecon.starts.turns"),
                                ("solution_turns", "solve had", "pinrecon.starts.turns.turn_stage")):
            wound = np.asarray(x.get(key, np.zeros((0, 4))), float).reshape(-1, 4)
            for a, b, k, gain in wound[wound[:, 2] != 0]:
                lines.append(f"trunk turned {int(k):+d} whole turn in {span_text(a, b, self.fps)}, cost {gain:.0f} lower (a fast turn the {who} the "
                             f"wrong way round; {where})")
        mirrors = np.asarray(x.get("solution_mirrors", np.zeros((0, 5))), float).reshape(-1, 5)
        kept = mirrors[np.isfinite(mirrors[:, 4])]
        if len(kept):
            labels = [str(c) for c in np.asarray(x.get("mirror_chains", []), dtype=str)]
            lines.append(f"limb spans mirrored after the solve: {len(kept)} of {len(mirrors)} tried, "
                         f"cost {float(kept[:, 4].sum()):.0f} lower (pinrecon.starts.mirrors.mirror_stage)")
            for c, _, a, b, gain in kept[np.argsort(-kept[:, 4])][:limit]:
                name = labels[int(c)] if int(c) < len(labels) else str(int(c))
                lines.append(f"  {name}: {span_text(a, b, self.fps)}, cost {gain:.0f} lower")
            if len(kept) > limit:
                lines.append(f"  ... and {len(kept) - limit} more")
        labels, ties, tie = mirror_uncertain(x)
        if len(ties):
            lines.append(f"limb spans whose mirror costs about the same (within {tie:g}): {len(ties)}, "
                         "uncertain: a keyframe there would decide them (pinrecon.starts.mirrors)")
            for c, a, b, gain in ties[np.argsort(np.abs(ties[:, 3]))][:limit]:
                name = labels[int(c)] if int(c) < len(labels) else str(int(c))
                lines.append(f"  {name}: {span_text(a, b, self.fps)}, the mirror costs {abs(gain):.1f} {'less' if gain > 0 else 'more'}")
            if len(ties) > limit:
                lines.append(f"  ... and {len(ties) - limit} more")
        if "prior_switch_focal_px" in x:
            lines.append(f"pose prior: {x['prior_model']!s} (the first solve put the auto camera's focal length at "
                         f"{float(x['prior_switch_focal_px']):.0f} px, where no ordinary lens is: a degenerate solution, "
                         "solved again with this broader prior and the lifter's cues, as for unfamiliar poses)")
        elif "prior_default_unfamiliar" in x:
            early = bool(x.get("prior_switch_early", False))
            at = int(x.get("prior_switch_iteration", 0))
            when = ("at the start's brief solve: solved with this broader one from the start" if early else
                    f"{at} iterations into the first solve: solved again with this broader one" if at else
                    "as first solved: solved again with this broader one")
            lines.append(f"pose prior: {x['prior_model']!s} (the default did not know "
                         f"{100 * float(x['prior_default_unfamiliar']):.0f} % of the frames' poses {when}"
                         "; pinrecon.unfamiliar.broader_prior)")
        conflict = [str(j) for j in x.get("prior_conflict_joints", ())]
        if conflict:
            lines.append(f"the data disagree with the pose prior on {len(conflict)} joint(s) ({', '.join(conflict)}): "
                         "the prior was widened and re-centred there (pinrecon.prior_yield)")
        d, lim, sp = unfamiliar_frames(x)
        if len(sp):
            n = int(np.sum(d > lim))
            judge = str(x["prior_distance_model"]) if "prior_distance_model" in x else ""
            whose = (f"the default pose prior's ({judge}) clips" if judge else "the pose prior's clips")
            fallback = (f"; the broader {x['prior_model']!s} they were solved with is a fallback, no surer of them"
                        if judge and "prior_model" in x else "")
            lines.append(f"poses unlike {whose} in {n} of {len(d)} frames ({100 * n / len(d):.0f} %; "
                         f"more than {lim:.1f} standard deviations from its typical poses, its 99th percentile): limb "
                         "depths there are the "
                         f"prior's extrapolation and may be mirrored{fallback}; 3D keyframes there would decide them")
            for a, b in sp[np.argsort([-d[a:b].max() for a, b in sp])][:limit]:
                lines.append(f"  {span_text(a, b, self.fps)}, up to {d[a:b].max():.1f} standard deviations")
            if len(sp) > limit:
                lines.append(f"  ... and {len(sp) - limit} more")
        if "prior_distance" not in x and self.figure is not None:
            for name in unused_priors(self.figure):
                lines.append(f"no learned pose prior in this solve, but {name!r} fits this figure: with detector "
                             f"tracks and few keyframes it decides most limb depths (--pose-prior-model {name}; "
                             "models/priors/README.md)")
        f = np.asarray(x.get("relabelled_frames", ()), int)
        g = np.asarray(x["relabelled_lifted_frames"], int) if "relabelled_lifted_frames" in x else f
        if len(f) or len(g):
            lines.append("the detector kept left and right the other way round on frames "
                         f"{spans_text(f, SPANS_SHOWN) or 'none'}" + ("" if np.array_equal(f, g) else
                                                                     f" (its 3D on frames "
                                                                     f"{spans_text(g, SPANS_SHOWN) or 'none'})")
                         + " (the tracks' continuity says so): relabelled before the solve; --skip labels keeps "
                         "the detector's labels")
        if "repaired_frames" in x:
            fr = np.asarray(x["repaired_frames"], int)
            shown = ", ".join(str(f) for f in fr[:20]) + (" ..." if len(fr) > 20 else "")
            lines.append(f"left/right swaps repaired in {len(fr)} frames" + (f": {shown}" if len(fr) else ""))
        if "outlier_frames" in x:
            fr, names, err = (np.asarray(x[k]) for k in ("outlier_frames", "outlier_points", "outlier_error_px"))
            lines.append(f"{len(fr)} points stayed far off after convergence (> "
                         f"{float(x.get('outlier_threshold_px', np.nan)):.1f} px; down-weighted as outliers)")
            for f, n, e in sorted(zip(fr.tolist(), names.tolist(), err.tolist()), key=lambda r: -r[2])[:limit]:
                lines.append(f"  frame {f} {n}: {e:.1f} px")
        return lines

    def calibration_summary(self) -> list[str]:
        """The fitted segment lengths (each group's mean segment length, generic ->
        fitted) and cameras, as summary lines."""
        c = self.calibration or {}
        if not c:
            return []
        lines = [f"calibration: {c.get('mode', '?')}"]
        fitted, generic = c.get("lengths_m") or {}, c.get("generic_lengths_m") or {}
        if fitted:
            lines.append("  segment lengths (generic -> fitted):")
            items = [f"{plain_segment(g)} {generic.get(g, float('nan')):.3f} -> {m:.3f} m "
                     f"({100 * (m / generic[g] - 1):+.1f} %)"
                     if generic.get(g) else f"{plain_segment(g)} {m:.3f} m" for g, m in fitted.items()]
            lines += [f"    {'; '.join(items[i:i + 3])}" for i in range(0, len(items), 3)]
        measured = c.get("lengths_from_tracks") or {}
        if measured:  # no 3D keyframe: the fit started at what the tracks measure (reconstruct's lengths_from_tracks)
            lines.append("  measured from the tracks (the fit's start; other groups held at the figure's): "
                         + "; ".join(f"{plain_segment(g)} {m:.3f} m" for g, m in measured.items()))
        lines += _identifiability_lines(c.get("identifiability"), list(fitted))
        lo, hi = LENGTH_RATIO_BOUNDS
        off = {s: r for s, r in (c.get("lengths_kept") or {}).items() if not lo <= r <= hi}
        if off:  # a figure's own lengths kept (a BVH's, a robot's): where the subject's proportions are not its
            lines.append("  the figure's own limb lengths were kept, but the tracks measure "
                         + "; ".join(f"{s} at {r:.2f}" for s, r in off.items()) + " times them (at the solution's "
                         "depths; about 1 where the figure has the subject's proportions): the joint angles bend to "
                         "make up the difference. If this skeleton is not the subject's, --calibrate lengths fits "
                         "its lengths to the tracks (calibrate='lengths')")
        for name, cam in (c.get("cameras") or {}).items():
            what, unit = ("focal length", "px") if cam.get("quantity") == "focal_px" else ("scale", "px/m")
            lines.append(f"  camera {name!r}: {what} {cam['start']:.1f} -> {cam['fitted']:.1f} {unit}")
        auto = c.get("camera_auto")
        if auto and self.camera is not None:
            cam = self.camera
            if getattr(cam, "model", "") == "perspective":
                what = (f"f {cam.K[0, 0]:.1f} px, principal point ({cam.K[0, 2]:.1f}, {cam.K[1, 2]:.1f}), "
                        f"centre at {np.round(-cam.R.T @ cam.t, 3).tolist()} m")
            else:
                what = f"scale {cam.scale:.1f} px/m, world origin at ({cam.center[0]:.1f}, {cam.center[1]:.1f}) px"
            lines.append(f"  auto camera ({auto.get('projection')}): {what}; pose: {auto.get('pose')}")
            focal = auto.get("focal")
            if isinstance(focal, dict) and focal.get("message"):
                flag = "" if focal.get("determined") else "WARNING: "
                lines.append(f"  {flag}{focal['message']}")
            size = auto.get("image_size")
            odd = implausible_focal(float(cam.K[0, 0]), size) if size and hasattr(cam, "K") else None
            if odd:
                lines.append(f"  WARNING: {odd}")
        return lines

    def foot_metrics(self) -> dict | None:
        """Skating, penetration and floating of the foot points against the result's own
        floor and contacts (:func:`pinrecon.contact.foot_metrics`), when it has them."""
        feet = FootContact.from_extras(self.extras)
        if feet is None or self.figure is None:
            return None
        P = self.keypoints3d[:, self.figure.keypoint_index(feet.names)]
        return foot_metrics(P, feet.floor, feet.contact, self.fps, clearance_m=feet.clearance_m,
                            contact_height_m=feet.contact_height_m)

    def feet_summary(self) -> list[str]:
        m = self.foot_metrics()
        if m is None:
            return []
        fl = FootContact.from_extras(self.extras).floor
        n = ", ".join(f"{x:.3f}" for x in fl.normal)
        return [
            f"floor: normal ({n}), height {fl.offset_m:.3f} m; {m['contact_frames']} foot-point contacts",
            f"feet: skating {100 * m['skating_mps']:.2f} cm/s in contact, penetration {1000 * m['penetration_m']:.1f} mm "
            f"(max {1000 * m['penetration_max_m']:.1f} mm), floating {1000 * m['floating_m']:.1f} mm",
        ]

    def _cameras_arrays(self) -> dict:
        """The several-camera keys (``cameras``, ``camera_names``,
        ``reprojection_error_px_per_camera``), written only for two or more cameras: a
        one-camera file has ``camera`` alone."""
        if len(self.cameras) < 2:
            return {}
        return {
            "cameras": np.array(json.dumps([c.to_dict() for c in self.cameras])),
            "camera_names": np.array(json.dumps(list(self.camera_names))),
            "reprojection_error_px_per_camera": self.reprojection_error_px_per_camera,
        }

    def save_figure(self, path) -> list[str]:
        """Write the result's figure (the calibrated one after a calibrated solve) for
        reuse: its URDF to ``path``, with the figure's joint limits written into the
        limited joints, and its keypoint map to ``<path stem>.keypoints.json`` next to it.
        Read it back with ``Figure.from_urdf(path, "<stem>.keypoints.json")`` (CLI:
        ``--figure path --keypoints <stem>.keypoints.json``). Returns the two paths."""
        from pathlib import Path

        from .io.atomic import atomic_write_text
        from .joint_limits import urdf_with_limits

        fig = self.figure
        if fig is None or not fig.urdf_xml:
            raise InputError("the result has no figure with a URDF to save", field="figure")
        path = Path(path)
        kp_path = path.with_name(path.stem + ".keypoints.json")
        atomic_write_text(path, urdf_with_limits(fig.urdf_xml, fig.limits_dict(), add_missing=True))
        atomic_write_text(kp_path, json.dumps(fig.keypoint_map_dict(), indent=1))
        return [str(path), str(kp_path)]

    def save(self, path) -> None:
        """Write the result NPZ (``docs/formats.md``), atomically. It embeds the figure's
        URDF and keypoint map so the file alone can be plotted and exported."""
        fig = self.figure
        check_motion(fig, self.q, self.fps, file=path)
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
            **self._cameras_arrays(),
            **({"calibration": np.array(json.dumps(self.calibration))} if self.calibration else {}),
            **({"stages": np.array(json.dumps([s.to_dict() for s in self.stages]))} if self.stages else {}),
            solver_status=np.array(self.solve.status if self.solve else ""),
            solver_iterations=np.int64(self.solve.iterations if self.solve else 0),
            **{k: v for k, v in self.extras.items()},
        )


def _stages(d, path) -> list[StageReport]:
    """The ``stages`` JSON of a result file ([] when absent)."""
    items = text_json(d, "stages", file=path, default=[], expect=list)
    try:
        return [StageReport.from_dict(x) for x in items]
    except (ValueError, TypeError, KeyError, OverflowError) as exc:
        raise InputError(f"not a list of stage reports ({exc})", file=path, field="stages") from None


def plain_segment(name: str) -> str:
    """A segment or group name as the summary shows it: a segment that only carries keypoints
    (``middle_pelvis.keypoints``) is named by its body (``pelvis keypoints``), without the
    figure's internal suffix and side prefix ``middle_``."""
    name = str(name)
    if name.endswith(".keypoints"):
        name = name[: -len(".keypoints")] + " keypoints"
    return name.removeprefix("middle_").replace("_", " ") if "." not in name else name


def _identifiability_lines(ident, groups: list[str]) -> list[str]:
    """The calibration summary's word on the lengths the data do not fix
    (:func:`pinrecon.identifiability.proportions_identifiability`)."""
    if not ident:
        return []
    und = [g for g in ident.get("undetermined", []) if g in groups]
    every = bool(und) and len(und) == len(groups)
    lines = []
    if every and ident.get("one_view"):
        lines.append("  NOT fixed by the tracks alone: any of these lengths. One view bounds each from below (a limb "
                     "is at least as long as its longest image), but a longer one leaning out of the image costs "
                     "nothing in the tracks: the pose prior and the joint limits chose the values. A 3D keyframe, "
                     "a second camera or 3D markers fix them")
    elif und:
        named = "any of these lengths" if every else ", ".join(plain_segment(g) for g in und)
        lines.append(f"  NOT fixed by the data alone: {named} (a small "
                     "change is taken up by the poses at no cost in the data, so the priors chose the value)")
    if not ident.get("size_determined", True) and not every:
        lines.append("  NOT fixed by the data alone: the overall size (all lengths larger or smaller together, at no "
                     "cost in the data); a 3D keyframe, a second camera or 3D markers fix it")
    return lines


def load_result(path) -> Result:
    """Read a result NPZ back into a :class:`Result` (figure rebuilt from the embedded URDF).
    Every field is checked first (:func:`pinrecon.io.results.load_result_npz`, then the
    motion against the figure: :func:`check_motion`); a bad file is one InputError naming
    the field and frame."""
    d = load_result_npz(path)
    fig = None
    if string_field(d, "figure_urdf", file=path, required=False):
        kp_map = text_json(d, "figure_keypoints", file=path, default={}, expect=dict)
        if not isinstance(kp_map.get("keypoints"), (dict, list)):
            raise InputError("must hold {'keypoints': ...}", file=path, field="figure_keypoints")
        kps = parse_keypoint_entries(kp_map["keypoints"], file=path)
        limits = text_json(d, "figure_limits", file=path, default={}, expect=dict)
        for k, v in limits.items():
            if not (isinstance(v, list) and len(v) == 2 and all(_is_number(x) for x in v)):
                raise InputError(f"joint {k!r}: a limit must be [lower, upper] numbers", file=path,
                                 field="figure_limits")
        fig = Figure.from_urdf_string(
            string_field(d, "figure_urdf", file=path),
            kps,
            root="free" if bool(d.get("figure_floating", True)) else "fixed",
            name=string_field(d, "figure_name", file=path, required=False, default="figure"),
            limits={k: tuple(v) for k, v in limits.items()},
            meta=text_json(d, "figure_meta", file=path, default={}, expect=dict),
            source=str(path),
        )
    cam_dict = text_json(d, "camera", file=path, default=None, expect=dict)
    cam = camera_from_dict(cam_dict, file=path) if cam_dict is not None else None
    cams = [camera_from_dict(c, file=path) for c in text_json(d, "cameras", file=path, default=[], expect=list)]
    cam_names = [str(n) for n in text_json(d, "camera_names", file=path, default=[], expect=list)]
    fps = float(d["fps"]) if "fps" in d else (1.0 / np.diff(d["times"]).mean() if len(d["times"]) > 1 else 1.0)
    T = d["q"].shape[0]
    if fig is not None:
        check_motion(fig, d["q"], fps, file=path)
        if list(map(str, d["keypoint_names"])) != list(fig.keypoint_names):
            raise InputError("do not match the embedded figure's keypoints", file=path, field="keypoint_names")
        if "foot_names" in d:
            try:
                fig.keypoint_index([str(n) for n in d["foot_names"]])
            except InputError as exc:
                raise exc.located(file=path, field="foot_names") from None
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
        cameras=cams,
        camera_names=cam_names,
        reprojection_error_px_per_camera=d.get("reprojection_error_px_per_camera"),
        extras={k: d[k] for k in d if k in FOOT_EXTRAS or k.startswith(FAULT_EXTRAS_PREFIXES)},
        calibration=check_calibration(text_json(d, "calibration", file=path, default={}, expect=dict), path),
        stages=_stages(d, path),
    )


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def hypothesis_spans(extras) -> tuple[list[str], np.ndarray, float]:
    """What the multi-hypothesis start left in a result's ``extras``: its limb labels,
    its spans (S, 5) (rows: chain index, first frame, frame after the last, state, cost
    gap in nats) and the gap below which a span is uncertain; no limbs and no spans when
    it did not run."""
    chains = [str(c) for c in np.asarray(extras.get("hypothesis_chains", [])).ravel().tolist()]
    spans = np.asarray(extras.get("hypothesis_spans", np.zeros((0, 5))), float).reshape(-1, 5)
    return chains, spans, float(np.asarray(extras.get("hypothesis_threshold", 2.0)))


def mirror_uncertain(extras) -> tuple[list[str], np.ndarray, float]:
    """What the mirror stage (:mod:`pinrecon.starts.mirrors`) left in a result's ``extras``
    as uncertain: the chains' labels, (U, 4) rows (chain index, first frame, frame after the
    last, nats the mirror saved: negative, it costs more), each a limb span whose mirror
    ended turned over within the threshold of the solution, and that threshold in nats;
    no rows when it did not run."""
    labels = [str(c) for c in np.asarray(extras.get("mirror_chains", []), dtype=str).ravel().tolist()]
    rows = np.asarray(extras.get("mirror_uncertain", np.zeros((0, 4))), float).reshape(-1, 4)
    return labels, rows, float(np.asarray(extras.get("mirror_uncertain_nats", np.nan)))


def uncertain_limb_spans(extras) -> list[tuple[str, int, int]]:
    """``(limb chain, first frame, frame after the last)`` of every span whose reflection a
    result calls uncertain: the hypothesis search's below its gap threshold
    (:func:`hypothesis_spans`) and the mirror stage's (:func:`mirror_uncertain`); a chain
    index with no label is named ``"chain N"``."""
    def label(names, c):
        return names[int(c)] if 0 <= int(c) < len(names) else f"chain {int(c)}"

    chains, spans, thr = hypothesis_spans(extras)
    out = [(label(chains, c), int(a), int(b)) for c, a, b, _state, gap in spans if gap < thr]
    labels, ties, _ = mirror_uncertain(extras)
    return out + [(label(labels, c), int(a), int(b)) for c, a, b, _gain in ties]


def unstable_spans(extras) -> list[tuple[int, int, str, float, int]]:
    """``(first frame, frame after the last, keypoint, largest distance mm, copies)`` of
    every run of frames where a copy of :mod:`pinrecon.stability` differed from the result
    by more than its threshold (mean over the keypoints, after the frame's similarity
    alignment): the keypoint that moved most there, by how much, in how many copies.
    Empty when the result has no stability extras."""
    if "stability_spread_mm" not in extras:
        return []
    spread = np.atleast_2d(np.asarray(extras["stability_spread_mm"], float))
    per_point = np.asarray(extras["stability_keypoint_spread_mm"], float)
    names = [str(n) for n in np.asarray(extras["stability_names"], dtype=str)]
    over = spread > float(extras["stability_threshold_mm"])
    bad = np.flatnonzero(over.any(axis=0))
    out = []
    for run in np.split(bad, np.flatnonzero(np.diff(bad) > 1) + 1) if len(bad) else []:
        a, b = int(run[0]), int(run[-1]) + 1
        k = int(np.argmax(per_point[a:b].max(axis=0)))
        out.append((a, b, names[k], float(per_point[a:b, k].max()), int(over[:, a:b].any(axis=1).sum())))
    return out


def stability_lines(extras, fps: float, limit: int = 6) -> list[str]:
    """The summary's lines for :mod:`pinrecon.stability`'s extras (none without them)."""
    if "stability_spread_mm" not in extras:
        return []
    spread = np.atleast_2d(np.asarray(extras["stability_spread_mm"], float))
    thr, n = float(extras["stability_threshold_mm"]), len(spread)
    means = ", ".join(f"{m:.1f}" for m in spread.mean(axis=1))
    lines = [(f"stability: solved again on {n} copies of the tracks with {100 * float(extras['stability_drop']):g} % "
              f"of the detections left out: mean difference from this result {means} mm (per frame, after a "
              "similarity alignment; pinrecon.stability)")]
    spans = unstable_spans(extras)
    if not spans:
        lines.append(f"  every frame within {thr:g} mm in every copy")
        return lines
    frames = sum(b - a for a, b, *_ in spans)
    lines.append(f"  {frames} of {spread.shape[1]} frames differ by more than {thr:g} mm in some copy: the data allow "
                 "more than one answer there, and a 3D keyframe there would decide it")
    for a, b, name, mm, k in sorted(spans, key=lambda r: -r[3])[:limit]:
        lines.append(f"  {span_text(a, b, fps)}: {k} of {n} copies, most at {name} "
                     f"({mm:.0f} mm)")
    if len(spans) > limit:
        lines.append(f"  ... and {len(spans) - limit} more")
    return lines


def lifted_lines(extras, fps: float, limit: int = 6) -> list[str]:
    """The summary's lines for the lifted-pose rows' extras (:func:`pinrecon.rows.lifted.
    disagreement_extras`): how far the solved bones are from the lifter's, and the spans of
    frames where a bone disagrees by more than the threshold (none without a lifted pose)."""
    if "lifted_disagreement_deg" not in extras:
        return []
    ang = np.asarray(extras["lifted_disagreement_deg"], float)
    names = [str(n) for n in np.asarray(extras["lifted_bones"], dtype=str)]
    thr = float(extras["lifted_threshold_deg"])
    spans = np.asarray(extras["lifted_spans"], float).reshape(-1, 4)
    seen = np.isfinite(ang)
    med = float(np.median(ang[seen])) if seen.any() else float("nan")
    share = 100.0 * float((ang[seen] > thr).mean()) if seen.any() else 0.0
    lines = [f"lifted pose: the solved bones are {med:.1f} degrees from the lifter's (median over {seen.any(1).sum()} "
             f"frames and {len(names)} bones); {share:.1f} % of the bone-frames disagree by more than {thr:g} degrees "
             "(the image and the other rows outvoted the lifter there)"]
    for b, a, e, m in spans[np.argsort(-(spans[:, 2] - spans[:, 1]))][:limit]:
        lines.append(f"  {names[int(b)]}: {span_text(a, e, fps)}, up to {m:.0f} degrees")
    if len(spans) > limit:
        lines.append(f"  ... and {len(spans) - limit} more")
    return lines


#: the summary names the spans of frames without a 2D observation lasting at least this long
#: (shorter gaps, and a result's frames between the tracks' at a higher ``fps_out``, are
#: filled by the smoothing like any interpolation)
UNOBSERVED_S = 0.1


def unobserved_lines(observed, fps: float, limit: int = 6) -> list[str]:
    """The summary's lines for the spans of at least :data:`UNOBSERVED_S` seconds in which no
    camera observed a point (a detector that found nobody): the motion there is not measured."""
    seen = np.asarray(observed, bool)
    if not len(seen) or not seen.any():
        return []
    spans = [(a, b) for a, b in true_runs(~seen) if (b - a) / fps >= UNOBSERVED_S]
    if not spans:
        return []
    n = sum(b - a for a, b in spans)
    lines = [(f"not observed: {n} of {len(seen)} frames have no 2D point, in spans of {UNOBSERVED_S:g} s or more; the "
              "motion there is not measured: the smoothing, the joint limits and the pose prior carry it "
              "(result.observed_frames)")]
    for a, b in sorted(spans, key=lambda ab: ab[0] - ab[1])[:limit]:
        lines.append(f"  {span_text(a, b, fps)}")
    if len(spans) > limit:
        lines.append(f"  ... and {len(spans) - limit} more")
    return lines


def unfamiliar_frames(extras) -> tuple[np.ndarray, float, np.ndarray]:
    """What :mod:`pinrecon.unfamiliar` left in a result's ``extras``: each frame's distance
    from the pose prior, the limit, and the (n, 2) spans beyond it; an empty distance and
    no spans when the problem had no learned prior. ``(distance > limit).sum()`` counts the
    frames."""
    d = np.asarray(extras.get("prior_distance", np.zeros(0)), float)
    lim = float(extras.get("prior_distance_limit", np.inf))
    return d, lim, np.asarray(extras.get("prior_unfamiliar_spans", np.zeros((0, 2))), int).reshape(-1, 2)
