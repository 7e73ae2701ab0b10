"""How far a reconstruction holds: the same solve on copies of the tracks with a few
detections left out.

A result already says where two limb reflections cost about the same (the hypothesis
search's cost gaps, the mirror stage's ties) and where the poses are unlike the pose
prior's clips. It cannot say when the whole solve would land in another basin after a
small change of its input. On Pose2Sim's real balancing trial that happens: with 1 % of
the detections removed at random, the calibrated 17-COCO-point setting ends at 98-104 mm
PA-MPJPE in some draws and 124-192 mm in others (``bench/bench_video_spread.py``), and the
MAP cost does not tell the better one (bench/README.md). :func:`stability` measures it
for the user's own clip: it runs :func:`pinrecon.reconstruct` again on ``runs`` copies of
the tracks, each with ``drop`` of its observed points removed at random (a detector's
missed points), and compares each copy's 3D keypoints with the result's, frame by frame
after a similarity alignment (so a camera fitted a little differently does not count).
Frames where a copy differs by more than ``threshold_mm`` are where the data allow more
than one answer: a 3D keyframe there (the workbench) decides it.

It costs ``runs`` more solves, which ``n_jobs`` spreads over processes (the copies are
independent; the answer is the same whatever the number of processes). The numbers go into the
result's ``extras`` (``stability_*``, ``docs/formats.md``) and its summary; the CLI's
``--stability N`` runs it (``--jobs J`` for the processes).
"""

from __future__ import annotations

import os
import pickle
import warnings
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .metrics import procrustes
from .reconstruct import reconstruct
from .result import Result, stability_lines
from .tracks import Tracks
from .windowed import n_processes

__all__ = ["Stability", "drop_detections", "stability"]


@dataclass
class Stability:
    """What :func:`stability` measured.

    drop : share of the observed points removed in each copy.
    seeds : the random seed of each copy.
    spread_mm : (runs, T) per copy and frame, the mean distance of its keypoints from the
        result's after the frame's similarity alignment, millimetres.
    keypoint_spread_mm : (T, K) per frame and keypoint, the largest such distance over the
        copies.
    names : the K keypoints compared (the tracked ones).
    threshold_mm : a frame where a copy's mean distance exceeds it is unstable.
    fps : the reconstruction's frame rate (for the summary's times).
    """

    drop: float
    seeds: tuple[int, ...]
    spread_mm: np.ndarray
    keypoint_spread_mm: np.ndarray
    names: list[str]
    threshold_mm: float
    fps: float

    def to_extras(self) -> dict:
        return {"stability_drop": float(self.drop), "stability_seeds": np.asarray(self.seeds, int),
                "stability_spread_mm": np.asarray(self.spread_mm, float),
                "stability_keypoint_spread_mm": np.asarray(self.keypoint_spread_mm, float),
                "stability_names": np.asarray(self.names, dtype=str),
                "stability_threshold_mm": float(self.threshold_mm)}

    def summary(self) -> str:
        return "\n".join(stability_lines(self.to_extras(), self.fps))


def drop_detections(tracks: Tracks, share: float, seed: int) -> Tracks:
    """A copy of ``tracks`` with ``share`` of its observed points (at least one) made
    missing, chosen at random with ``seed``."""
    rng = np.random.default_rng(seed)
    pts = tracks.points.copy()
    conf = None if tracks.confidence is None else tracks.confidence.copy()
    t, k = np.nonzero(tracks.observed)
    if len(t) == 0:
        return tracks
    pick = rng.choice(len(t), size=min(len(t), max(1, round(share * len(t)))), replace=False)
    pts[t[pick], k[pick]] = np.nan
    if conf is not None:
        conf[t[pick], k[pick]] = 0.0
    return Tracks(pts, tracks.names, tracks.fps, conf, tracks.source, tracks.layout, tracks.lifted)


def stability(figure, tracks: Tracks | Sequence[Tracks], camera, keyframes=None, *, result: Result | None = None,
              runs: int = 4, drop: float = 0.01, random_seed: int = 0, threshold_mm: float = 30.0,
              n_jobs: int | None = None, **kwargs) -> Stability:
    """Solve again on ``runs`` copies of ``tracks`` with ``drop`` of the observed points
    removed at random (seeds ``random_seed``, ``random_seed + 1``, ...) and compare with ``result`` (the
    solve of the tracks as they are, computed here when not given). ``figure``, ``camera``,
    ``keyframes`` and ``kwargs`` are :func:`pinrecon.reconstruct`'s, as the result was made
    with them (a warm ``init`` is refused: the copies would start from the answer). With
    several cameras, each camera's tracks lose the same share. The copies' warnings are not
    repeated (they are the result's). ``n_jobs``: how many processes solve the copies at once
    (scikit-learn's convention: ``None`` or 1 one after another here, -1 one per CPU, at most
    ``runs``); every argument must then be one Python can send to another process (pickle), so
    a ``callback`` written as a lambda is refused. Returns a :class:`Stability`;
    ``result.extras.update(s.to_extras())`` puts it in the result and its summary."""
    if not isinstance(runs, int) or isinstance(runs, bool) or runs < 1:
        raise InputError(f"must be a whole number of solves, at least 1; got {runs!r}", field="runs")
    if not 0.0 < _number(drop) < 0.5:
        raise InputError(f"must be a share of the detections between 0 and 0.5; got {drop!r}", field="drop")
    if not _number(threshold_mm) > 0.0:
        raise InputError(f"must be a distance in mm above 0; got {threshold_mm!r}", field="threshold_mm")
    if kwargs.get("init") is not None and not isinstance(kwargs["init"], str):
        raise InputError("a warm start would start every copy from the answer: give a start's name or none",
                         field="init")
    jobs = _jobs(n_jobs, runs)
    several = not isinstance(tracks, Tracks)
    views = list(tracks) if several else [tracks]
    base = result if result is not None else reconstruct(figure, tracks, camera, keyframes, **kwargs)
    names = [n for n in dict.fromkeys(n for t in views for n in t.names) if n in base.figure.keypoint_names]
    idx = base.figure.keypoint_index(names)
    ref = base.keypoints3d[:, idx]
    seeds = tuple(int(random_seed) + i for i in range(runs))
    tasks = [([drop_detections(t, float(drop), s + 7919 * v) for v, t in enumerate(views)], several)
             for s in seeds]
    solved = _solve_copies(jobs, (figure, camera, keyframes, kwargs, names), tasks)
    spread, per_point = [], np.zeros(ref.shape[:2])
    for P in solved:
        d_mm = 1000.0 * np.linalg.norm(procrustes(P, ref) - ref, axis=-1)  # (T, K)
        spread.append(d_mm.mean(axis=1))
        per_point = np.maximum(per_point, d_mm)
    return Stability(float(drop), seeds, np.array(spread), per_point, names, float(threshold_mm), float(base.fps))


def _solve_copy(common, task) -> np.ndarray:
    """One copy's solve: its (T, K) keypoints of ``names``."""
    figure, camera, keyframes, kwargs, names = common
    copies, several = task
    with warnings.catch_warnings():  # the copies' warnings are the result's again
        warnings.simplefilter("ignore")
        res = reconstruct(figure, copies if several else copies[0], camera, keyframes, **kwargs)
    return res.keypoints3d[:, res.figure.keypoint_index(names)]


def _solve_copies(jobs: int, common, tasks) -> list[np.ndarray]:
    """Every copy's keypoints, in the order of ``tasks``: here, or in ``jobs`` processes."""
    if jobs == 1:
        return [_solve_copy(common, t) for t in tasks]
    try:
        pickle.dumps(common)
    except (pickle.PicklingError, TypeError, AttributeError) as exc:
        raise InputError(f"with n_jobs={jobs} the solve's arguments go to other processes, and one of them cannot "
                         f"({exc}); give n_jobs=1, or a callback defined at module level", field="n_jobs") from None
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        return list(pool.map(_solve_copy, [common] * len(tasks), tasks))


def _jobs(n_jobs, runs: int) -> int:
    """The number of processes ``n_jobs`` asks for (scikit-learn's convention), at most ``runs``."""
    return n_processes(n_jobs, runs, os.cpu_count() or 1)


def _number(x) -> float:
    """``x`` as a float, NaN when it is not a number (so that the checks above refuse it)."""
    if isinstance(x, bool):
        return float("nan")
    try:
        return float(x)
    except (TypeError, ValueError):
        return float("nan")
