"""The workbench page: a viser scene and GUI on top of a :class:`~.session.Session`.

Look: the stick figure in 3D (orbit, floor grid, the camera drawn), the camera's view with
the 2D tracks and the reprojection, a timeline with the per-frame reprojection error and
the keyframes, a frame slider and play. Correct: flip a limb segment's depth, drag a
keypoint (transform control), set a joint angle, delete or move keyframes, undo, redo.
Re-solve with progress. Keep: save the keyframes JSON and the result NPZ, export BVH, CSV
and the HTML player, reload the saved files.

Every control calls one :class:`~.session.Session` method; the page holds no state of
its own besides the current frame and the selections.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from pathlib import Path

import numpy as np

from ..errors import PinreconError
from .edits import skeleton_edges
from .panels import image_view, timeline
from .session import Session

__all__ = ["Workbench", "serve", "edit_from_args"]


def _viser():
    try:
        import viser
    except ImportError:  # pragma: no cover - depends on the install
        raise PinreconError('the workbench needs the \'edit\' extra: from a pinrecon checkout, '
                            'pip install ".[edit]"') from None
    return viser


def titled_client(title: str) -> Path:
    """A folder holding viser's web client (one ``index.html``) with the page titled
    ``title`` instead of "Viser" (written once per viser version, in the temp folder)."""
    import tempfile

    import viser

    src = Path(viser.__file__).resolve().parent / "client" / "build" / "index.html"
    root = Path(tempfile.gettempdir()) / f"pinrecon-viser-{getattr(viser, '__version__', 'x')}-{title}"
    page = root / "index.html"
    if not page.is_file():
        root.mkdir(parents=True, exist_ok=True)
        tmp = root / f"index.{os.getpid()}.tmp"
        tmp.write_text(src.read_text(encoding="utf-8").replace("<title>Viser</title>", f"<title>{title}</title>", 1),
                       encoding="utf-8")
        os.replace(tmp, page)
    return root


@contextlib.contextmanager
def page_title(title: str):
    """While open, a ``viser.ViserServer`` created serves its page titled ``title``: its web
    server is given :func:`titled_client`'s folder in place of viser's own build folder."""
    from viser import infra

    made = infra.WebsockServer
    root = titled_client(title)

    def server(*args, **kwargs):
        kwargs["http_server_root"] = root
        return made(*args, **kwargs)

    infra.WebsockServer = server
    try:
        yield root
    finally:
        infra.WebsockServer = made


def view_half_px(uv_px: np.ndarray) -> float:
    """Half the camera view's size: 0.6 times the tracks' largest per-frame extent over
    frames with two or more points seen (``uv_px`` (T, K, 2)); 100 px when there is none."""
    uv_px = np.asarray(uv_px, float)
    seen = np.isfinite(uv_px).all(axis=2)
    frames = seen.sum(axis=1) >= 2
    if not frames.any():
        return 100.0
    ext = [np.ptp(uv_px[t][seen[t]], axis=0).max() for t in np.flatnonzero(frames)]
    return 0.6 * float(max(ext))


def _wxyz(R_world_cam: np.ndarray) -> tuple[float, float, float, float]:
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R_world_cam).as_quat()
    return (float(w), float(x), float(y), float(z))


class Workbench:
    """Serve ``session`` at ``http://host:port``.

    ``keyframes_path`` / ``result_path`` are where Save writes (and Reload reads);
    exports go to ``out_dir``.
    """

    def __init__(self, session: Session, *, host: str = "127.0.0.1", port: int = 8080, out_dir="pinrecon-edit",
                 keyframes_path=None, result_path=None, frame: int = 0, segment: str | None = None):
        viser = _viser()
        self.session = session
        self.out_dir = Path(out_dir)
        self.keyframes_path = Path(keyframes_path) if keyframes_path else self.out_dir / "keyframes.json"
        self.result_path = Path(result_path) if result_path else self.out_dir / "result.npz"
        self.host, self.port = host, int(port)
        self.lock = threading.RLock()
        self.frame = int(np.clip(frame, 0, session.n_frames - 1))
        self.solving = False
        self.last_solve = ""
        self.message = ""
        with page_title("pinrecon"):
            self.server = viser.ViserServer(host=host, port=port, label="pinrecon workbench", verbose=False)
        self._setup_static()
        self._setup_gui(segment)
        self.show(self.frame)

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    # ------------------------------------------------------------------ scene
    def _setup_static(self):
        s, sc = self.session, self.server.scene
        cam = s.camera
        R = np.asarray(cam.R, float)
        self.up = -R[1]
        sc.set_up_direction(tuple(self.up))
        fig = s.figure
        self.names = list(fig.keypoint_names)
        self.edges = skeleton_edges(fig)
        self.track_names = [n for n in s.tracks.names if n in self.names]
        self.track_idx = [self.names.index(n) for n in self.track_names]
        self.edges_tracked = [(self.track_idx.index(a), self.track_idx.index(b)) for a, b in self.edges
                              if a in self.track_idx and b in self.track_idx]
        self.edge_colours = np.array([[(31, 111, 209)] * 2 if self.names[b].lower().startswith("left")
                                      else [(209, 67, 31)] * 2 if self.names[b].lower().startswith("right")
                                      else [(60, 60, 60)] * 2 for _, b in self.edges], np.uint8)
        P = s.keypoints3d
        centre = np.nanmean(P.reshape(-1, 3), axis=0)
        floor = float(np.nanmin(P.reshape(-1, 3) @ self.up))
        span = float(np.nanmax(np.ptp(P.reshape(-1, 3), axis=0))) + 2.0
        plane = {0: "yz", 1: "xz", 2: "xy"}[int(np.argmax(np.abs(self.up)))]
        ground = centre - (centre @ self.up - floor) * self.up
        sc.add_grid("/floor", width=span, height=span, plane=plane, position=tuple(ground), cell_size=0.5)
        if getattr(cam, "model", "") == "perspective":
            pos = -R.T @ np.asarray(cam.t, float)
            fov = 2 * np.arctan(max(cam.K[1, 2], 1.0) / cam.K[1, 1])
            aspect = max(cam.K[0, 2], 1.0) / max(cam.K[1, 2], 1.0)
        else:
            pos = centre - 2.0 * R[2]
            fov, aspect = 0.35, 4 / 3
        sc.add_camera_frustum("/camera", fov=float(fov), aspect=float(aspect), scale=0.25, wxyz=_wxyz(R.T),
                              position=tuple(pos), color=(40, 40, 40))
        self.bones = sc.add_line_segments("/figure/bones", np.zeros((len(self.edges), 2, 3)), self.edge_colours,
                                          thickness=0.025)
        self.joints = sc.add_point_cloud("/figure/joints", np.zeros((len(self.names), 3)), (20, 20, 20),
                                         point_size=0.045, point_shape="circle")
        self.keyed = sc.add_point_cloud("/figure/keyed", np.zeros((1, 3)), (240, 170, 0), point_size=0.06,
                                        point_shape="diamond", visible=False)
        # the camera view follows the figure at one scale: the largest per-frame extent
        self.view_half = view_half_px(s.tracks.select(self.track_names).points)
        # the page's own viewpoint: 60 degrees round from the camera's, a little above
        from scipy.spatial.transform import Rotation

        fwd = Rotation.from_rotvec(np.radians(60.0) * self.up).apply(R[2])
        eye = P[self.frame].mean(0) - 3.2 * fwd + 1.0 * self.up
        self.server.initial_camera.look_at = tuple(P[self.frame].mean(0))
        self.server.initial_camera.position = tuple(eye)

    # ------------------------------------------------------------------ GUI
    def _setup_gui(self, segment):
        s, gui = self.session, self.server.gui
        segs = [g.name for g in s.segments]
        kps = list(s.figure.distinct_keypoint_names)
        joints = s.one_dof_joints()
        self.status = gui.add_markdown("")
        self.timeline_img = gui.add_image(timeline(np.zeros(s.n_frames), 0), label="Timeline")
        self.frame_slider = gui.add_slider("Frame", min=0, max=s.n_frames - 1, step=1, initial_value=self.frame)
        self.play = gui.add_checkbox("Play", False)
        self.view_img = gui.add_image(np.zeros((360, 480, 3), np.uint8), label="Camera view")
        with gui.add_folder("Correct"):
            self.segment = gui.add_dropdown("Limb", segs or ["(none)"], initial_value=segment if segment in segs else (segs or ["(none)"])[0])
            self.whole = gui.add_checkbox("Mirror the whole limb below", False)
            self.flip_button = gui.add_button("Flip depth")
            self.point = gui.add_dropdown("Keypoint to drag", kps, initial_value=kps[0])
            self.joint = gui.add_dropdown("Joint", joints or ["(none)"], initial_value=(joints or ["(none)"])[0])
            self.joint_slider = gui.add_slider("Angle (rad)", min=-3.2, max=3.2, step=0.01, initial_value=0.0)
            self.joint_button = gui.add_button("Set joint keyframe")
            self.undo_button = gui.add_button("Undo")
            self.redo_button = gui.add_button("Redo")
        with gui.add_folder("Keyframes"):
            self.key_list = gui.add_dropdown("Keyframe", ["(none)"], initial_value="(none)")
            self.goto_button = gui.add_button("Go to keyframe")
            self.move_button = gui.add_button("Move keyframe here")
            self.delete_button = gui.add_button("Delete keyframe")
        with gui.add_folder("Solve"):
            self.solve_button = gui.add_button("Re-solve")
            self.progress = gui.add_progress_bar(0.0, visible=False)
        with gui.add_folder("Keep"):
            self.kf_path = gui.add_text("Keyframes JSON", str(self.keyframes_path))
            self.npz_path = gui.add_text("Result NPZ", str(self.result_path))
            self.save_button = gui.add_button("Save keyframes + result")
            self.reload_button = gui.add_button("Reload saved")
            self.bvh_button = gui.add_button("Export BVH")
            self.csv_button = gui.add_button("Export CSV")
            self.html_button = gui.add_button("Export HTML player")
        self.drag = self.server.scene.add_transform_controls("/drag", scale=0.3, disable_rotations=True)

        self.frame_slider.on_update(lambda _: self.show(int(self.frame_slider.value)))
        self.play.on_update(lambda _: self._start_play() if self.play.value else None)
        self.point.on_update(lambda _: self.show(self.frame))
        self.joint.on_update(lambda _: self._sync_joint())
        def S():  # the session may be replaced by Reload
            return self.session

        self.flip_button.on_click(lambda _: self._edit(
            lambda: S().flip(self.frame, self.segment.value, whole_limb=self.whole.value), f"flipped {self.segment.value}"))
        self.joint_button.on_click(lambda _: self._edit(
            lambda: S().set_joint(self.frame, self.joint.value, self.joint_slider.value), "joint keyed"))
        self.drag.on_update(lambda ev: self._edit(
            lambda: S().set_point(self.frame, self.point.value, np.asarray(self.drag.position)), "point keyed")
            if getattr(ev, "phase", "end") == "end" else None)
        self.undo_button.on_click(lambda _: self._edit(lambda: S().undo(), "undone"))
        self.redo_button.on_click(lambda _: self._edit(lambda: S().redo(), "redone"))
        self.goto_button.on_click(lambda _: self._goto_key())
        self.move_button.on_click(lambda _: self._edit(lambda: S().move_keyframe(self._key_index(), self.frame), "moved"))
        self.delete_button.on_click(lambda _: self._edit(lambda: S().delete_keyframe(self._key_index()), "deleted"))
        self.solve_button.on_click(lambda _: self._start_solve())
        self.save_button.on_click(lambda _: self._edit(
            lambda: S().save(self.kf_path.value, self.npz_path.value), f"saved {self.kf_path.value}, {self.npz_path.value}"))
        self.reload_button.on_click(lambda _: self._edit(self._reload, "reloaded the saved files"))
        out = self.out_dir
        for button, kind, name in ((self.bvh_button, "bvh", "motion.bvh"), (self.csv_button, "csv", "motion.csv"),
                                   (self.html_button, "html", "motion.html")):
            button.on_click(lambda _, k=kind, n=name: self._edit(lambda: S().export(**{k: out / n}), f"wrote {out / n}"))

    # ------------------------------------------------------------------ actions
    def _edit(self, action, done: str):
        if self.solving:
            self.message = "busy: solving"
            self._status()
            return
        with self.lock:
            try:
                self.message = done if action() is not False else "nothing to do"
            except (PinreconError, OSError) as exc:
                self.message = f"error: {exc}"
            self.show(self.frame)

    def _reload(self):
        from .. import load_keyframes, load_result

        s = self.session
        kf = load_keyframes(self.kf_path.value)
        res = load_result(self.npz_path.value)
        self.session = Session(s.figure, s.tracks, s.camera, kf, result=res, fps_out=s.fps_out, weights=s.weights,
                               floor=s.floor, options=s.options)

    def _key_index(self) -> int:
        v = self.key_list.value
        if not v.startswith("#"):
            raise PinreconError("no keyframe selected")
        return int(v[1:].split(" ")[0])

    def _goto_key(self):
        try:
            k = self.session.keyframes[self._key_index()]
        except PinreconError as exc:
            self.message = str(exc)
            return self._status()
        self.frame_slider.value = k.frame * self.session.factor
        self.show(k.frame * self.session.factor)

    def _sync_joint(self):
        s = self.session
        name = self.joint.value
        if name not in s.one_dof_joints():
            return
        _, vs = s.figure.joint_slices(name)
        lo, hi = s.figure.lower_v[vs.start], s.figure.upper_v[vs.start]
        lo = float(lo) if np.isfinite(lo) else -np.pi
        hi = float(hi) if np.isfinite(hi) else np.pi
        self.joint_slider.min, self.joint_slider.max = round(lo, 2) - 0.01, round(hi, 2) + 0.01
        self.joint_slider.value = round(s.joint_value(self.frame, name), 2)

    def _start_play(self):
        def loop():
            s = self.session
            step = max(1, int(round(s.fps / 15)))
            while self.play.value:
                t0 = time.perf_counter()
                f = (self.frame + step) % s.n_frames
                self.frame_slider.value = f
                self.show(f)
                time.sleep(max(0.0, step / s.fps - (time.perf_counter() - t0)))

        threading.Thread(target=loop, daemon=True).start()

    def _start_solve(self):
        if self.solving:
            return
        self.solving = True
        self.solve_button.disabled = True
        self.progress.visible = True
        self.progress.value = 0.0
        self.message = "solving ..."
        self._status()
        threading.Thread(target=self._solve, daemon=True).start()

    def _solve(self):
        s = self.session

        def progress(stage, rep):
            share = rep.iteration / (rep.iteration + 8.0)
            self.progress.value = float(40.0 * share if stage == "window" else 40.0 + 59.0 * share)
            self.message = f"solving ({stage}): iteration {rep.iteration}, cost {rep.cost:.6g}"
            self._status()

        try:
            with self.lock:
                rep = s.solve(progress)
            self.last_solve = str(rep)
            self.message = "solved"
        except PinreconError as exc:
            self.message = f"error: {exc}"
        finally:
            self.solving = False
            self.progress.value = 100.0
            self.progress.visible = False
            self.solve_button.disabled = False
            self.show(self.frame)

    # ------------------------------------------------------------------ drawing
    def _status(self):
        s = self.session
        _, err = s.reprojection_px()
        pending = s.dirty_frames
        lines = [
            f"**{s.n_frames} frames** at {s.fps:g} fps · **{len(s.keyframes)} keyframes** · "
            f"mean reprojection error **{np.nanmean(err):.2f} px**" if np.isfinite(err).any() else
            f"**{s.n_frames} frames** · **{len(s.keyframes)} keyframes**",
            f"frame {self.frame}: error {err[self.frame]:.2f} px" if np.isfinite(err[self.frame]) else f"frame {self.frame}",
            f"needs a solve (frames {pending[0]}-{pending[1]})" if pending else "solved: up to date",
        ]
        unsure = s.uncertain_spans()
        if unsure:
            here = [c for a, b, c in unsure if a <= self.frame < b]
            lines.append(f"uncertain depth (purple on the timeline): {len(unsure)} spans"
                         + (f"; here: {', '.join(here)}" if here else ""))
        if self.last_solve:
            lines.append(f"last solve: {self.last_solve}")
        if self.message:
            lines.append(f"*{self.message}*")
        self.status.content = "  \n".join(lines)

    def show(self, frame: int):
        """Draw ``frame``: the 3D figure, the keyed points, the drag handle, the camera
        view, the timeline, the keyframe list and the status."""
        with self.lock:
            s = self.session
            self.frame = f = int(np.clip(frame, 0, s.n_frames - 1))
            P = s.keypoints3d[f]
            self.bones.points = np.stack([P[[a for a, _ in self.edges]], P[[b for _, b in self.edges]]], axis=1)
            self.joints.points = P
            keyed = [n for k in s.keyframes if k.frame * s.factor == f and k.points is not None for n in k.points]
            if keyed:
                self.keyed.points = np.array([p for k in s.keyframes if k.frame * s.factor == f and k.points is not None
                                              for p in k.points.values()])
            self.keyed.visible = bool(keyed)
            self.drag.position = tuple(P[self.names.index(self.point.value)])
            uv, err = s.reprojection_px()
            obs_row = f // s.factor if f % s.factor == 0 else None
            tracks_uv = (s.tracks.select(self.track_names).points[obs_row] if obs_row is not None
                         else np.full((len(self.track_names), 2), np.nan))
            c = np.nanmean(tracks_uv, axis=0) if np.isfinite(tracks_uv).any() else np.nanmean(uv[f], axis=0)
            h = self.view_half
            self.view_img.image = image_view(tracks_uv, uv[f], self.track_names, self.edges_tracked,
                                             bounds=(c[0] - 1.33 * h, c[1] - h, c[0] + 1.33 * h, c[1] + h),
                                             keyed=np.array([n in keyed for n in self.track_names]))
            self.timeline_img.image = timeline(err, f, keyframes=s.keyframe_frames(), pending=s.dirty_frames,
                                               uncertain=[(a, b) for a, b, _ in s.uncertain_spans()])
            opts = [f"#{i} frame {k.frame * s.factor}: {k.kind} " + ", ".join(list(k.points or k.joints)[:3])
                    + (" ..." if len(k.points or k.joints) > 3 else "") for i, k in enumerate(s.keyframes)] or ["(none)"]
            if list(self.key_list.options) != opts:
                cur = self.key_list.value
                self.key_list.options = opts
                self.key_list.value = cur if cur in opts else opts[-1]
            self.undo_button.disabled = not s.can_undo
            self.redo_button.disabled = not s.can_redo
            if self.joint.value in s.one_dof_joints():
                self.joint_slider.value = round(s.joint_value(f, self.joint.value), 2)
            self._status()

    def stop(self):
        self.play.value = False
        self.server.stop()


def serve(session: Session, *, host="127.0.0.1", port=8080, open_browser=True, block=True, **kwargs) -> Workbench:
    """Start the workbench for ``session``, print its address; with ``block`` wait until
    Ctrl-C."""
    import sys

    wb = Workbench(session, host=host, port=port, **kwargs)
    print(f"pinrecon workbench: {wb.url}  (Ctrl-C to stop)", file=sys.stderr, flush=True)
    if open_browser:
        import webbrowser

        webbrowser.open(wb.url)
    if block:
        try:
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            wb.stop()
    return wb


def edit_from_args(args, figure=None, weights: dict | None = None) -> int:
    """``pinrecon edit``: load the inputs (and a result NPZ) and serve the workbench with
    ``Weights(**weights)`` (the command line's, :func:`pinrecon.cli.pose_prior_weights`).

    ``figure``: a function of the tracks giving the ``--figure`` (None: the result's own).
    With ``--result`` the result's own figure and fitted camera are used unless ``--figure``
    or ``--camera`` is given, which is said on stderr. Without a result the first solve is
    :func:`pinrecon.reconstruct` with the command's inputs and ``reconstruct``'s defaults
    (``--camera auto`` included), and the workbench opens on its figure and camera."""
    import sys

    from .. import Weights, load_keyframes, load_result, load_tracks, reconstruct
    from ..io.calibration import load_camera
    from ..starts.camera_auto import DEFAULT_FOV_DEG, AutoCamera

    result = load_result(args.result) if args.result else None
    tracks = load_tracks(args.tracks, fps=args.fps, person=getattr(args, "person", None),
                         layout=getattr(args, "layout", None))
    given = figure(tracks) if callable(figure) else figure
    if given is None:
        if result is None or result.figure is None:
            raise PinreconError("pinrecon edit: give --figure (or a --result NPZ that embeds its figure)")
        given = result.figure
    elif result is not None and result.figure is not None:
        print(f"pinrecon edit: --figure {getattr(args, 'figure', '')} overrides the result's own figure (its fitted "
              "lengths); leave --figure out to edit on the result's", file=sys.stderr)
    spec = getattr(args, "camera", None)
    auto = spec is not None and spec.split(":")[0] == "auto"
    if spec is None or (auto and result is not None):
        if result is None or result.camera is None:
            raise PinreconError("pinrecon edit: give --camera (a calibration file or auto) or a --result NPZ")
        camera = result.camera  # the result's own (fitted) camera
    elif auto:
        proj = spec.split(":", 1)[1] if ":" in spec else "perspective"
        fov = getattr(args, "fov", None)
        camera = AutoCamera(getattr(args, "image_size", None), proj, DEFAULT_FOV_DEG if fov is None else fov)
    else:
        camera = load_camera(spec)
        if result is not None:
            print(f"pinrecon edit: --camera {spec} overrides the result's own camera", file=sys.stderr)
    keys = load_keyframes(args.keyframes) if args.keyframes else None
    w = Weights(**(weights or {}))
    if result is None:  # the first solve is reconstruct's, with its defaults
        print("pinrecon edit: solving once (as pinrecon reconstruct would) before serving ...", file=sys.stderr,
              flush=True)
        result = reconstruct(given, tracks, camera, keys, fps_out=args.fps_out, weights=w,
                             floor=getattr(args, "floor", None))
        given, camera = result.figure, result.camera
    session = Session(given, tracks, camera, keys, result=result, fps_out=args.fps_out, weights=w,
                      floor=getattr(args, "floor", None))
    out = Path(args.out)
    serve(session, host=args.host, port=args.port, open_browser=not args.no_browser, out_dir=out,
          keyframes_path=args.keyframes_out or out / "keyframes.json", result_path=args.result_out or out / "result.npz")
    return 0
