"""Figures: a Pinocchio model built from a URDF plus a named keypoint map.

A keypoint is a point rigidly attached to a Pinocchio frame: ``p_world = oMf * offset``.
The figure gives keypoint positions and their analytic Jacobians with respect to the
tangent space of the configuration (``nv``), joint limits per tangent index, and the
Lie-group operations the solver needs (all taken from Pinocchio).

Conventions (see ``docs/derivations.md``):

* ``q`` has ``nq`` entries, tangent vectors ``v`` have ``nv``; with a free-flyer root
  ``q[:7] = (x, y, z, qx, qy, qz, qw)`` and ``v[:6]`` is a *local* SE(3) twist
  ``(v_local, w_local)``, so ``q (+) v = pin.integrate(q, v) = q * exp6(v)``.
* Keypoint Jacobians are d p_world / d v: the velocity of the keypoint in world axes
  per unit tangent velocity. From Pinocchio's WORLD joint Jacobian ``J = [J_lin; J_ang]``
  (velocity of the point at the world origin) the keypoint's is
  ``J_p = J_lin - [p]x J_ang``, restricted to the keypoint's supporting joints.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np
import pinocchio as pin

from . import kinematics
from ._resources import example_robot_data_robots, model_path
from .errors import InputError, UnknownNameError
from .figure_files import (
    Keypoint,
    load_keypoint_map,
    parse_keypoint_entries,
    scale_urdf_origins,
    urdf_joint_limits,
    urdf_joint_names,
    xml_file,
)

__all__ = ["Figure", "Keypoint", "load_keypoint_map", "parse_keypoint_entries", "xml_file"]

ROOT_JOINT = "root_joint"


def _human_stature_m(figure) -> float:
    """Standing height of the human URDF as built (scale 1): top of the head to the
    soles in the neutral pose, Y up, from the head-top and toe points of the bundled
    ``joints`` keypoint map (1.77 m)."""
    from .layouts import human_keypoint_map

    kps = {k.name: k for k in load_keypoint_map(human_keypoint_map("joints"))}
    q = figure.neutral()

    def height(name):
        k = kps[name]
        return float(figure.frame_placement(q, k.frame).act(np.asarray(k.offset, float))[1])

    return height("head_top") - min(height("left_toe"), height("right_toe"))


class Figure:
    """A Pinocchio model and a keypoint map.

    Build one with :meth:`from_urdf`, :meth:`human` or :meth:`from_bvh`.

    Attributes
    ----------
    model, data : the Pinocchio model and a data buffer owned by this figure.
    keypoint_names : names of the K keypoints, in order.
    joint_names : names of the movable joints (Pinocchio order, root first when free).
    lower_v, upper_v : (nv,) joint limits per tangent index, -inf/+inf where unset.
    urdf_xml : the URDF text the model was built from (used to edit and save figures).
    """

    def __init__(
        self,
        model: pin.Model,
        keypoints: Iterable[Keypoint],
        *,
        name: str = "figure",
        urdf_xml: str | None = None,
        limits: Mapping[str, tuple[float, float]] | None = None,
        source: str | None = None,
        floating: bool = True,
        meta: dict | None = None,
    ):
        self.model = model
        self.data = model.createData()
        self.name = name
        self.urdf_xml = urdf_xml
        self.source = source
        self.floating = floating
        self.meta = dict(meta or {})
        self.nq, self.nv = model.nq, model.nv
        self.joint_names = list(model.names[1:])
        self._joint_ids = {n: i for i, n in enumerate(model.names) if i > 0}
        self._set_limits(limits or {})
        self._set_keypoints(list(keypoints))

    def __getstate__(self) -> dict:
        """Pickled without Pinocchio's workspace (``data``: 9 MB for the human, 94 MB for a
        CMU BVH skeleton), which is made again from the model: the figure goes to another
        process (``pinrecon.stability``'s ``n_jobs``) in milliseconds, not seconds."""
        state = self.__dict__.copy()
        state.pop("data", None)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.data = self.model.createData()

    # ------------------------------------------------------------------ building
    @classmethod
    def from_urdf_string(
        cls,
        xml: str,
        keypoints: Iterable[Keypoint] | str | os.PathLike | None = None,
        *,
        root: str = "free",
        name: str | None = None,
        source: str | None = None,
        limits: Mapping[str, tuple[float, float]] | None | str = "urdf",
        meta: dict | None = None,
    ) -> Figure:
        """Build a figure from URDF text. See :meth:`from_urdf`."""
        where = source or "<urdf string>"
        if root not in ("free", "fixed"):
            raise InputError(f"root must be 'free' or 'fixed', got {root!r}", field="root")
        try:
            if root == "free":
                model = pin.buildModelFromXML(xml, pin.JointModelFreeFlyer())
            else:
                model = pin.buildModelFromXML(xml)
        except (ValueError, RuntimeError) as exc:
            msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise InputError(f"URDF does not parse: {msg}", file=where) from None
        if limits == "urdf":
            try:
                limits = urdf_joint_limits(xml)
            except (SyntaxError, ValueError) as exc:  # ElementTree's ParseError, a limit that is no number
                raise InputError(f"URDF does not parse: {exc}", file=where) from None
        if keypoints is None:
            keypoints = [Keypoint(model.names[j], model.names[j]) for j in range(1, model.njoints)]
        elif isinstance(keypoints, (str, os.PathLike)):
            kp_file = keypoints
            try:
                return cls.from_urdf_string(
                    xml, load_keypoint_map(kp_file), root=root, name=name, source=source, limits=limits, meta=meta
                )
            except InputError as exc:
                raise exc.located(file=kp_file) from None
        robot_name = name or model.name or "figure"
        fig = cls(
            model,
            keypoints,
            name=robot_name,
            urdf_xml=xml,
            limits=limits,
            source=source,
            floating=root == "free",
            meta=meta,
        )
        return fig

    @classmethod
    def from_urdf(
        cls,
        path: str | os.PathLike,
        keypoints: Iterable[Keypoint] | str | os.PathLike | None = None,
        *,
        root: str = "free",
        name: str | None = None,
    ) -> Figure:
        """Load a URDF file.

        Parameters
        ----------
        path : URDF file.
        keypoints : keypoint list or keypoint-map JSON path; default: one keypoint at each
            joint origin, named as the joint.
        root : ``"free"`` (free-flyer root, SE(3)) or ``"fixed"`` (base fixed to the world).
        """
        from .io.jsonfile import read_text

        path = Path(path)
        xml = read_text(path)
        return cls.from_urdf_string(xml, keypoints, root=root, name=name, source=str(path))

    @classmethod
    def human(cls, keypoints: str = "coco17", *, tracks=None, root: str = "free", height: float | None = None) -> Figure:
        """The human model of example-robot-data (38 joints, nv = 42 with the free flyer).

        ``keypoints``: a bundled map ``models/keypoints/human_<name>.json`` (``coco17``,
        ``body25``, ``body25b``, ``halpe26``: see :mod:`pinrecon.layouts`; ``joints``: the
        joint centres) or a keypoint-map JSON file; another name lists the bundled maps;
        ``"auto"``: the map for ``tracks`` (one :class:`~pinrecon.Tracks` or a list), their
        detector layout's, else the map sharing most of their point names
        (:func:`pinrecon.layouts.human_map_for`), as the command line's ``--figure human``
        chooses. ``tracks`` is for ``"auto"`` only.
        ``height``: the stature in metres (top of the head to the soles, standing), the
        whole figure scaled uniformly to it; default the model's own (1.77 m).
        ``meta["generic"] == "human"`` marks it as the generic human (calibrated by
        default, :func:`pinrecon.reconstruct`).
        """
        from .layouts import human_keypoint_map, human_map_for

        if isinstance(keypoints, str) and keypoints.lower() == "auto":
            if tracks is None:
                raise InputError("'auto' chooses the map for tracks: give tracks=", field="keypoints")
            keypoints = human_map_for(tracks)
        elif tracks is not None:
            raise InputError(f"tracks= is for keypoints='auto' (the map chosen for them), not {keypoints!r}",
                             field="tracks")
        urdf = example_robot_data_robots() / "human_description" / "robots" / "human.urdf"
        kp_path = human_keypoint_map(keypoints)
        try:
            fig = cls.from_urdf(urdf, load_keypoint_map(kp_path), root=root, name="human")
        except InputError as exc:
            raise exc.located(file=kp_path) from None
        # anatomical limits (published ranges of motion, docs/limits.md) over the URDF's
        fig = fig.with_limits(model_path("limits", "human.json"))
        fig.meta["generic"] = "human"
        if height is not None:
            h = float(height) if isinstance(height, (int, float)) and not isinstance(height, bool) else float("nan")
            if not (0.3 <= h <= 3.0):
                raise InputError(f"must be a stature in metres between 0.3 and 3, got {height!r}", field="height")
            s = h / _human_stature_m(fig)
            kps = [Keypoint(k.name, k.frame, tuple(s * float(v) for v in k.offset)) for k in fig.keypoints_def]
            fig = cls.from_urdf_string(fig.scaled_urdf(s), kps, root=root, name="human",
                                       source=fig.source, limits=fig.limits_dict(), meta={**fig.meta, "height_m": h})
        return fig

    @classmethod
    def from_bvh(cls, path, length_scale: float = 1.0, *, lock: Iterable[str] | str = ()) -> Figure:
        """The figure of a BVH file's skeleton (its motion is ignored).

        ``length_scale`` is metres per file unit (CMU: 0.056444); ``lock`` welds the named
        BVH joints (or ``"static"``). See :mod:`pinrecon.figure_bvh` for the construction
        and :func:`pinrecon.io.bvh.load_bvh` for the figure and its motion.
        """
        from .io.bvh_format import read_bvh

        return cls.from_bvh_clip(read_bvh(path), length_scale, lock=lock)

    @classmethod
    def from_bvh_clip(cls, clip, length_scale: float = 1.0, *, lock: Iterable[str] | str = ()) -> Figure:
        """The figure of an already parsed BVH skeleton (a :class:`pinrecon.io.bvh.BvhClip`)."""
        from .figure_bvh import bvh_figure_data

        d = bvh_figure_data(clip, length_scale, lock=lock)
        return cls.from_urdf_string(
            d.urdf_xml,
            [Keypoint(n, f, off) for n, f, off in d.keypoints],
            root="free",
            name=d.name,
            source=d.source,
            limits=d.limits,
            meta=d.meta,
        )

    def with_keypoints(self, keypoints: Iterable[Keypoint] | str | os.PathLike) -> Figure:
        """The same model with another keypoint map."""
        kp_file = None
        if isinstance(keypoints, (str, os.PathLike)):
            kp_file = keypoints
            keypoints = load_keypoint_map(keypoints)
        try:
            return self._with_keypoints(keypoints)
        except InputError as exc:
            raise exc.located(file=kp_file) from None

    def with_limits(self, limits: Mapping[str, tuple[float, float]] | str | os.PathLike) -> Figure:
        """The same figure with the given joint limits (radians) replacing its own; joints
        not named keep theirs. ``limits`` may be a file (:func:`pinrecon.joint_limits.load_limits`:
        a limits JSON, or a CMU ASF skeleton for a BVH figure, whose one-DOF bones also
        become hinges, ``meta["hinges"]`` (:mod:`pinrecon.rows.hinges`), and whose other
        bones keep their own DOFs and limits, ``meta["bones"]`` (:mod:`pinrecon.rows.bones`))."""
        from .joint_limits import load_limits, urdf_with_limits

        meta = self.meta
        if isinstance(limits, (str, os.PathLike)):
            src = limits
            if str(src).lower().endswith(".asf"):  # read once: limits, and its bones' own DOFs (rows.hinges, .bones)
                from .io import asf as acclaim

                sk = acclaim.read_asf(src)
                limits = acclaim.bvh_limits_from_asf(sk, self.joint_names)
                found = {"hinges": acclaim.bvh_hinges_from_asf(sk, self.joint_names),
                         "bones": acclaim.bvh_bones_from_asf(sk, self.joint_names)}
                meta = {**(meta or {}), **{k: v for k, v in found.items() if v}}
            else:
                limits = load_limits(limits, self.joint_names)
            unknown = [n for n in limits if n not in self._joint_ids]
            if unknown:
                raise UnknownNameError("joint", unknown, self.joint_names, file=src, field="limits")
        given = {str(k): (float(a), float(b)) for k, (a, b) in dict(limits).items()}
        xml = urdf_with_limits(self.urdf_xml, given) if self.urdf_xml else None  # saved URDFs keep them
        return Figure(self.model, self.keypoints_def, name=self.name, urdf_xml=xml, limits={**self.limits_dict(), **given},
                      source=self.source, floating=self.floating, meta=meta)

    def _with_keypoints(self, keypoints):
        return Figure(
            self.model,
            keypoints,
            name=self.name,
            urdf_xml=self.urdf_xml,
            limits=self.limits_dict(),
            source=self.source,
            floating=self.floating,
            meta=self.meta,
        )

    # ------------------------------------------------------------------ structure
    def _set_limits(self, limits: Mapping[str, tuple[float, float]]):
        lower = np.full(self.nv, -np.inf)
        upper = np.full(self.nv, np.inf)
        unknown = [n for n in limits if n not in self._joint_ids]
        if unknown:
            raise UnknownNameError("joint", unknown, self.joint_names, field="limits")
        for jname, (lo, hi) in limits.items():
            jid = self._joint_ids[jname]
            if self.model.nvs[jid] != 1 or self.model.nqs[jid] != 1:
                continue  # limits are only meaningful on 1-dof joints with nq == nv
            iv = self.model.idx_vs[jid]
            lower[iv], upper[iv] = lo, hi
        self.lower_v, self.upper_v = lower, upper
        self.limited_v = np.isfinite(lower) | np.isfinite(upper)

    def limits_dict(self) -> dict[str, tuple[float, float]]:
        """Joint name -> (lower, upper) of every limited 1-dof joint: the ``limits``
        argument that rebuilds this figure (:meth:`from_urdf_string`); saved in results."""
        out = {}
        for jname, jid in self._joint_ids.items():
            if self.model.nvs[jid] == 1 and self.model.nqs[jid] == 1:
                iv = self.model.idx_vs[jid]
                if self.limited_v[iv]:
                    out[jname] = (self.lower_v[iv], self.upper_v[iv])
        return out

    def _set_keypoints(self, keypoints: list[Keypoint]):
        model = self.model
        names = [k.name for k in keypoints]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise InputError(f"duplicate keypoint names {dup}", field="keypoints")
        frame_names = [f.name for f in model.frames]
        bad = [k.frame for k in keypoints if not model.existFrame(k.frame)]
        if bad:
            raise UnknownNameError("frame", bad, frame_names, field="keypoints")
        self.keypoints_def = keypoints
        self.keypoint_names = names
        self.K = len(keypoints)
        self._kp_index = {n: i for i, n in enumerate(names)}
        joint_ids = np.empty(self.K, dtype=int)
        p_joint = np.empty((self.K, 3))
        for i, kp in enumerate(keypoints):
            frame = model.frames[model.getFrameId(kp.frame)]
            joint_ids[i] = frame.parentJoint
            p_joint[i] = frame.placement.act(np.asarray(kp.offset, float))
        self._kp_joint = joint_ids
        self._kp_p_joint = p_joint
        self._kp_unique_joints, self._kp_joint_slot = np.unique(joint_ids, return_inverse=True)
        self._kp_joint_list = [int(j) for j in self._kp_unique_joints]
        self.keypoint_support = kinematics.support_mask(model, joint_ids)  # (K, nv) bool
        self._kin_kinds = kinematics.joint_kinds(model)

    def support_mask(self, keypoint_names: Iterable[str], tol: float = 1e-9) -> np.ndarray:
        """(nv,) bool: tangent entries that move at least one of the named keypoints.

        Decided from the keypoint Jacobian columns at three random configurations, so a
        rotation whose axis passes through every keypoint it carries (e.g. the hand's own
        rotation when only the wrist point is used) counts as not moving anything.
        """
        idx = self.keypoint_index(list(keypoint_names))
        if not len(idx):
            return np.zeros(self.nv, bool)
        Q = np.stack([self.random_configuration(s, unlimited=1.0) for s in (11, 12, 13)])
        _, J = self.keypoint_jacobians(Q)
        return np.abs(J[:, idx]).max(axis=(0, 1, 2)) > tol

    def keypoint_index(self, names: Iterable[str], *, file=None, field=None) -> np.ndarray:
        """Indices of keypoint ``names``; unknown names raise an error listing the valid ones."""
        names = list(names)
        unknown = [n for n in names if n not in self._kp_index]
        if unknown:
            raise UnknownNameError("keypoint", unknown, self.keypoint_names, file=file, field=field)
        return np.array([self._kp_index[n] for n in names], dtype=int)

    def joint_id(self, name: str, *, file=None, field=None, frame=None) -> int:
        if name not in self._joint_ids:
            raise UnknownNameError("joint", [name], self.joint_names, file=file, field=field, frame=frame)
        return self._joint_ids[name]

    def joint_slices(self, name: str) -> tuple[slice, slice]:
        """(q slice, v slice) of joint ``name``."""
        j = self.joint_id(name)
        m = self.model
        return (
            slice(m.idx_qs[j], m.idx_qs[j] + m.nqs[j]),
            slice(m.idx_vs[j], m.idx_vs[j] + m.nvs[j]),
        )

    @property
    def root_v(self) -> slice:
        """Tangent slice of the free-flyer root (empty for a fixed root)."""
        return slice(0, 6) if self.floating else slice(0, 0)

    @property
    def tangent_names(self) -> list[str]:
        """One name per tangent index: root components, then joint names."""
        out = []
        for j in range(1, self.model.njoints):
            nv = self.model.nvs[j]
            n = self.model.names[j]
            if nv == 1:
                out.append(n)
            elif self.floating and j == 1 and nv == 6:
                out += [f"{n}.{c}" for c in ("vx", "vy", "vz", "wx", "wy", "wz")]
            else:
                out += [f"{n}.{k}" for k in range(nv)]
        return out

    @property
    def parents_of_keypoints(self) -> list[int | None]:
        """For drawing: the nearest ancestor keypoint of each keypoint in the kinematic tree."""
        model = self.model
        by_joint: dict[int, list[int]] = {}
        for i, j in enumerate(self._kp_joint):
            by_joint.setdefault(int(j), []).append(i)
        # within a joint, a keypoint at the joint origin is the parent of the others
        out: list[int | None] = [None] * self.K
        origin_kp = {}
        for j, kps in by_joint.items():
            at_origin = [i for i in kps if np.linalg.norm(self._kp_p_joint[i]) < 1e-9]
            origin_kp[j] = at_origin[0] if at_origin else None
        for i, j in enumerate(self._kp_joint):
            j = int(j)
            if origin_kp[j] is not None and origin_kp[j] != i:
                out[i] = origin_kp[j]
                continue
            a = model.parents[j]
            while a > 0 and a not in by_joint:
                a = model.parents[a]
            if a > 0:
                cand = by_joint[a]
                out[i] = origin_kp[a] if origin_kp[a] is not None else cand[0]
        return out

    # ------------------------------------------------------------------ Lie group
    def neutral(self) -> np.ndarray:
        return pin.neutral(self.model)

    def integrate(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``q (+) v`` for one configuration or a trajectory (T, nq) with (T, nv)."""
        q, v = np.asarray(q, float), np.asarray(v, float)
        if q.ndim == 1:
            return pin.integrate(self.model, q, v)
        return kinematics.integrate_trajectory(self.model, self._kin_kinds, q, v)  # NumPy over frames

    def difference(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """``q1 (-) q0``: the tangent v with ``q0 (+) v = q1`` (trajectories allowed)."""
        q0, q1 = np.asarray(q0, float), np.asarray(q1, float)
        if q0.ndim == 1 and q1.ndim == 1:
            return pin.difference(self.model, q0, q1)
        q0, q1 = np.broadcast_arrays(q0, q1)
        return np.stack([pin.difference(self.model, a, b) for a, b in zip(q0, q1)])

    def d_difference(self, q0: np.ndarray, q1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Jacobians of ``difference(q0, q1)`` w.r.t. the tangents at q0 and at q1."""
        return (
            pin.dDifference(self.model, q0, q1, pin.ARG0),
            pin.dDifference(self.model, q0, q1, pin.ARG1),
        )

    def interpolate(self, q0, q1, alpha: float) -> np.ndarray:
        """Geodesic interpolation ``q0 (+) alpha (q1 (-) q0)``."""
        return pin.interpolate(self.model, q0, q1, float(alpha))

    def normalize(self, q: np.ndarray) -> np.ndarray:
        """Re-normalise quaternions (in place on a copy)."""
        q = np.array(q, float)
        if q.ndim == 1:
            return pin.normalize(self.model, q)
        for i in range(q.shape[0]):
            q[i] = pin.normalize(self.model, q[i])
        return q

    def clamp(self, q: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Clamp the limited 1-dof joints of ``q`` (or a trajectory) inside their limits."""
        q = np.array(q, float)
        m = self.model
        for jid in range(1, m.njoints):
            if m.nvs[jid] == 1 and m.nqs[jid] == 1:
                iv, iq = m.idx_vs[jid], m.idx_qs[jid]
                if self.limited_v[iv]:
                    lo, hi = self.lower_v[iv], self.upper_v[iv]
                    mg = min(margin, 0.25 * (hi - lo))
                    q[..., iq] = np.clip(q[..., iq], lo + mg, hi - mg)
        return q

    def random_configuration(self, rng=None, *, root_box: float = 1.0, unlimited: float = np.pi) -> np.ndarray:
        """A random configuration inside the joint limits.

        The root translation is uniform in ``[-root_box, root_box]^3`` with a uniformly
        random orientation; joints without limits are uniform in ``[-unlimited, unlimited]``.
        """
        rng = np.random.default_rng(rng)
        m = self.model
        q = pin.neutral(m)
        if self.floating:
            q[:3] = rng.uniform(-root_box, root_box, 3)
            quat = rng.normal(size=4)
            q[3:7] = quat / np.linalg.norm(quat)
        for jid in range(2 if self.floating else 1, m.njoints):
            iq, nq, iv, nv = m.idx_qs[jid], m.nqs[jid], m.idx_vs[jid], m.nvs[jid]
            if nq == 1 and nv == 1:
                lo = self.lower_v[iv] if np.isfinite(self.lower_v[iv]) else -unlimited
                hi = self.upper_v[iv] if np.isfinite(self.upper_v[iv]) else unlimited
                q[iq] = rng.uniform(lo, hi)
            else:
                v = np.zeros(m.nv)
                v[iv : iv + nv] = rng.normal(size=nv)
                q = pin.integrate(m, q, v)
        return q

    # ------------------------------------------------------------------ kinematics
    def check_q(self, q, *, field="q"):
        q = np.asarray(q, dtype=float)
        if q.shape[-1] != self.nq:
            raise InputError(f"expected configurations of size nq={self.nq}, got shape {q.shape}", field=field)
        return q

    def world_kinematics(self, Q: np.ndarray, jacobian: bool = True):
        """Keypoints (T, K, 3) along a trajectory (T, nq) and the WORLD joint Jacobian
        (T, 6, nv) (``None`` without ``jacobian``): vectorised over frames when the joints
        allow it (:mod:`pinrecon.kinematics`), else Pinocchio frame by frame."""
        return kinematics.point_kinematics(self.model, self.data, self._kin_kinds, Q, self._kp_joint_list,
                                           self._kp_joint_slot, self._kp_p_joint, jacobian)

    def keypoints(self, q: np.ndarray) -> np.ndarray:
        """World positions of the keypoints: (K, 3) for q (nq,), (T, K, 3) for (T, nq)."""
        q = self.check_q(q)
        P, _ = self.world_kinematics(q[None] if q.ndim == 1 else q, jacobian=False)
        return P[0] if q.ndim == 1 else P

    def keypoint_jacobians(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Keypoint positions (K, 3) and Jacobians d p_world / d v (K, 3, nv); for a
        trajectory (T, nq), (T, K, 3) and (T, K, 3, nv)."""
        q = self.check_q(q)
        single = q.ndim == 1
        p, J_world = self.world_kinematics(q[None] if single else q)
        J = kinematics.keypoint_jacobians_from_world(p, J_world, self.keypoint_support)
        return (p[0], J[0]) if single else (p, J)

    def frame_placement(self, q: np.ndarray, frame: str) -> pin.SE3:
        q = self.check_q(q)
        fid = self.model.getFrameId(frame)
        if fid >= self.model.nframes:
            raise UnknownNameError("frame", [frame], [f.name for f in self.model.frames])
        pin.forwardKinematics(self.model, self.data, q)
        return pin.updateFramePlacement(self.model, self.data, fid).copy()

    def coincident_keypoints(self, tol: float = 1e-9) -> list[list[str]]:
        """Groups of keypoints that coincide in every configuration (e.g. BVH joints with
        zero OFFSET, which sit at their parent). Checked at the neutral and two random
        configurations."""
        qs = [self.neutral(), self.random_configuration(0), self.random_configuration(1)]
        P = np.stack([self.keypoints(q) for q in qs])  # (3, K, 3)
        groups: list[list[int]] = []
        assigned = np.full(self.K, -1)
        for i in range(self.K):
            if assigned[i] >= 0:
                continue
            same = np.where(np.all(np.linalg.norm(P - P[:, i : i + 1], axis=-1) < tol, axis=0))[0]
            same = [int(s) for s in same if assigned[s] < 0]
            assigned[same] = len(groups)
            groups.append(same)
        return [[self.keypoint_names[i] for i in g] for g in groups]

    @property
    def distinct_keypoint_names(self) -> list[str]:
        """One keypoint name per distinct position: the first of each coincident group."""
        if "_distinct" not in self.meta:
            self.meta["_distinct"] = [g[0] for g in self.coincident_keypoints()]
        return list(self.meta["_distinct"])

    # ------------------------------------------------------------------ editing
    def scaled_urdf(self, joint_scales: Mapping[str, float] | float) -> str:
        """URDF text with the origin translations of the named URDF joints scaled.

        ``joint_scales`` maps URDF joint names to factors, or is one factor for all joints.
        Edited with the standard library's ElementTree: only the ``xyz`` of each named
        joint's ``<origin>`` changes, everything else in the file is kept.
        """
        if self.urdf_xml is None:
            raise InputError("this figure has no URDF to edit", field="urdf")
        if not isinstance(joint_scales, Mapping):
            joint_scales = {n: float(joint_scales) for n in urdf_joint_names(self.urdf_xml)}
        return scale_urdf_origins(self.urdf_xml, joint_scales)

    def rescaled(self, joint_scales: Mapping[str, float] | float, keypoint_scales: Mapping[str, float] | None = None) -> Figure:
        """A new figure whose URDF joint origins (and optionally keypoint offsets) are scaled."""
        xml = self.scaled_urdf(joint_scales)
        kps = []
        uniform = None if isinstance(joint_scales, Mapping) else float(joint_scales)
        for k in self.keypoints_def:
            f = (keypoint_scales or {}).get(k.name, uniform if uniform is not None else 1.0)
            kps.append(Keypoint(k.name, k.frame, tuple(f * np.asarray(k.offset))))
        return Figure.from_urdf_string(
            xml,
            kps,
            root="free" if self.floating else "fixed",
            name=self.name,
            source=None,
            limits=self.limits_dict(),
            meta={k: v for k, v in self.meta.items() if not k.startswith("_")},
        )

    def save_urdf(self, path: str | os.PathLike) -> None:
        """Write the figure's URDF atomically."""
        if self.urdf_xml is None:
            raise InputError("this figure has no URDF to save", field="urdf")
        from .io.atomic import atomic_write_text

        atomic_write_text(path, self.urdf_xml)

    def keypoint_map_dict(self) -> dict:
        return {
            "figure": self.name,
            "keypoints": {k.name: {"frame": k.frame, "offset": list(k.offset)} for k in self.keypoints_def},
        }

    def __repr__(self) -> str:
        root = "free-flyer" if self.floating else "fixed"
        return (
            f"Figure({self.name!r}, {self.model.njoints} joints, nq={self.nq}, nv={self.nv}, "
            f"{root} root, {self.K} keypoints, {int(self.limited_v.sum())} limited dofs)"
        )
