"""The weights of a reconstruction's rows (:class:`Weights`): one frozen record of standard
deviations and loss choices, read by the rows (:mod:`pinrecon.rows`) and the problem
(:mod:`pinrecon.problem`, which exports it too)."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from .errors import InputError
from .rows.posture import PosePrior

__all__ = ["Weights"]

_CHOICES = {"loss": ("auto", "l2", "huber", "cauchy"), "lifted_loss": ("l2", "huber", "cauchy"), "pose_prior_loss": PosePrior.LOSSES, "root_group": ("R3xSO3", "SE3")}


@dataclass(frozen=True)
class Weights:
    """Standard deviations that weight each row kind (all have defaults tuned on real
    human motion; see ``docs/derivations.md``, section 6).

    sigma_px : 2D measurement noise, pixels.
    loss, loss_scale_px : ``"auto"`` (``"cauchy"`` for tracks with confidences, else ``"l2"``),
        ``"l2"``, ``"huber"`` or ``"cauchy"``; scale in pixels (default ``3 sigma_px``) for a point
        of confidence 1 (errors are scaled by ``sqrt(c)`` first: ``loss_scale_px / sqrt(c)`` px).
    sigma_limits : joint-limit barrier, radians (small = stiff).
    acc_root_translation, acc_root_rotation, acc_joints : smoothing, standard deviation of
        acceleration in m/s^2 and rad/s^2 (constant-velocity prior; large = weak). The root's
        translation is held at 2 m/s^2 (5 before): one camera does not see its depth, and at 5
        the dance of ``bench/bench_real.py`` swung 0.3-0.6 m towards the camera and back
        through its pirouette (a figure nearer the camera must foreshorten its limbs to keep
        its image, so its limbs flipped with it); at 2, without keyframes, its PA-MPJPE fell
        from 91.6-120.8 to 72.1-97.6 mm and its flips from 28.3-30.7 to 21.0-24.1 % at 45, 50,
        55 and 60 degrees, and the walk's from 20.7 / 4.4 % to 19.7 / 3.9 with first and last
        keyframes (README, "Root smoothing").
    sigma_markers_m : 3D marker noise for :func:`reconstruct_markers`, metres.
    sigma_init_prior : prior pulling unkeyed joints to the rest pose when a point keyframe
        is turned into a pose (radians).
    sigma_posture : weak prior of every joint towards the rest pose in every frame
        (radians; ``None`` turns it off), see :mod:`pinrecon.rows.posture`.
    pose_prior : the generic human (``Figure.human()``) has a pose prior learned from
        motion capture instead (``models/priors/human_pose.json``): the joints that move in
        its clips held by their joint Gaussian, i.e. their Mahalanobis distance from the
        mean in units of ``pose_prior``, every other 1-dof joint pulled to its mean with its
        standard deviation times ``pose_prior`` (2: nine clips are a small sample of human
        poses; ``None``: the rest-pose prior of ``sigma_posture``, as other figures).
    pose_prior_model : ``"auto"`` (the human's for ``Figure.human()``, else none), ``"none"``, or
        a prior in ``models/priors`` (``"human_pose"``: the human's default, one Gaussian, kept
        whatever the clip; ``"human_pose_mixture"``: a mixture of 8 Gaussians over 57 clips,
        which ``"auto"`` solves a clip again with when the default does not know more than half
        of its poses (a fifth with one camera and no keyframes), :func:`pinrecon.unfamiliar.
        broader_prior`; ``"cmu_bvh_pose"``: CMU BVH
        figures) or a JSON file of ``tools/fit_pose_prior.py``; one that does not fit is refused
        (``rows.posture.prior_for``).
    pose_prior_loss, pose_prior_k : robust loss on a frame's Mahalanobis distance, quadratic up
        to ``k`` (``None``: always), then ``"huber"`` linear or ``"cauchy"`` logarithmic (better
        on dance, worse for an auto focal: bench/README.md; :class:`~.rows.posture.PosePrior`).
    sigma_proportions : log-normal prior on the figure's segment scale factors when they
        are calibrated (``calibrate="lengths"``): standard deviation of the log factor
        around its start (0.1: about 10 %).
    lifted : weight of the lifted-pose rows (:mod:`pinrecon.rows.lifted`), used whenever the
        tracks carry a lifter's 3D (``Tracks.lifted``): the inverse variance of a bone's chord
        ``|d - R l|`` between the figure's unit bone direction and the lifter's (25: a standard
        deviation of 0.2, about 11 degrees), times the lifter's confidence; ``0`` or ``None``
        turns them off. Measured in ``bench/bench_lifted.py``.
    own_lifter : weight of pinrecon's own lifter's rows (``reconstruct(lifter=...)``, for tracks
        without a lifter's 3D) while the clip is solved with the default pose prior: they
        join from the start at this weight (as ``lifted``, times the lifter's confidence;
        without ``lifted_lengths``), and at ``lifted`` when the prior switches to its broader
        mixture; ``None``: only then. 3 measured in ``bench/bench_lifter.py`` (``--seeds``).
    lifted_loss, lifted_loss_scale : their robust loss (``"cauchy"``, ``"huber"``, ``"l2"``)
        on the chord, and its scale in chord units (0.5: about 29 degrees), so a bone the
        lifter got wrong is outvoted by the image and the other rows.
    lifted_lengths : the figure's proportions (its bones' log lengths about their mean)
        pulled to the lifter's median ones over the clip with this standard deviation
        (:class:`pinrecon.rows.lifted.LiftedLengths`), whenever the lifted rows are on;
        ``None``: not. 0.05 measured in ``bench/bench_lifted_real.py`` (Pose2Sim's trial, mean
        PA-MPJPE 92.0 -> 89.1 mm) and ``bench/bench_lifted.py`` (the same to 0.2 mm).
    root_group : group on which the root's constant-velocity prior is written,
        ``"R3xSO3"`` (world translation and orientation apart; default) or ``"SE3"``
        (the free flyer's screw motion), see :mod:`pinrecon.rows.smoothing`.
    """

    sigma_px: float = 2.0
    loss: str = "auto"
    loss_scale_px: float | None = None
    sigma_limits: float = 0.01
    acc_root_translation: float = 2.0
    acc_root_rotation: float = 10.0
    acc_joints: float = 10.0
    sigma_markers_m: float = 0.01
    sigma_init_prior: float = 1.0
    sigma_posture: float | None = 3.0
    pose_prior: float | None = 2.0
    pose_prior_model: str = "auto"
    pose_prior_loss: str = "huber"
    pose_prior_k: float | None = 2.0
    root_group: str = "R3xSO3"
    sigma_proportions: float = 0.1
    lifted: float | None = 25.0
    own_lifter: float | None = 3.0
    lifted_loss: str = "cauchy"
    lifted_loss_scale: float = 0.5
    lifted_lengths: float | None = 0.05

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in _CHOICES:
                if v not in _CHOICES[f.name]:
                    raise InputError(f"must be one of {', '.join(_CHOICES[f.name])}, got {v!r}", field=f"weights.{f.name}")
            elif f.name == "pose_prior_model":
                if not (isinstance(v, str) and v):
                    raise InputError(f"must be 'auto', 'none', a prior's name or file, got {v!r}", field="weights.pose_prior_model")
            elif f.name == "lifted" and v is not None and isinstance(v, (int, float)) and v == 0:
                continue
            elif v is not None and not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise InputError(f"must be a positive number, got {v!r}", field=f"weights.{f.name}")
