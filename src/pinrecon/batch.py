"""Many clips, one command: ``pinrecon batch`` as a library.

Find the clips in a list of inputs (:func:`discover`), run each one with the same
reconstruction as ``pinrecon reconstruct`` (:func:`run_clip`), on this process, a local
process pool or a Dask cluster (:func:`run_batch`), and write the summary table
(``summary.csv``, ``summary.html``)::

    from pinrecon.batch import discover, run_batch

    clips = discover(["trials/", "extra/walk.json", "manifest.csv"])
    report = run_batch(clips, options, "out", jobs=2)   # options: reconstruct's, an argparse Namespace
    print(report.failed, "failed")

Each clip writes ``OUT/<clip>/``: ``result.npz``, ``result.bvh``, ``result.csv``,
``result.trc``, ``summary.txt``, ``log.txt``, ``strip.png`` (with the viz extra) and, last and
atomically, ``done.json`` (its summary row and every file's size). A clip whose ``done.json``
is there, lists files that are all there at their size, and was made with the same options is
skipped (``redo=True`` runs it again), so a killed batch loses only the clips in flight. A clip
that fails writes ``failed.json`` with its one-line error (and the traceback in ``log.txt``);
the batch goes on, and the next run tries it again.

Every clip runs with one BLAS/OpenMP thread whatever runs it (:data:`THREADS`), so the
results are the same, bit for bit, in this process, a process pool or a Dask worker; the
parallelism is the clips.
"""

from __future__ import annotations

import copy
import csv
import glob
import hashlib
import html
import io
import json
import sys
import time
import traceback
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from .errors import InputError, PinreconError
from .io.atomic import atomic_write_text

__all__ = ["Clip", "BatchReport", "discover", "read_manifest", "run_clip", "run_batch", "clip_is_done",
           "write_summary", "SUMMARY_COLUMNS", "VIDEO_SUFFIXES", "THREADS"]

#: BLAS/OpenMP threads of every clip's solve (the same everywhere, so the results are), and its
#: video's detector's
THREADS = 1
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg")
TRACKS_SUFFIXES = (".json", ".npz")
MANIFEST_COLUMNS = ("input", "name", "camera", "keyframes", "figure", "fps")
#: the columns of summary.csv, in order
SUMMARY_COLUMNS = ("clip", "status", "ran", "frames", "time_s", "reprojection_px", "flagged_spans", "warnings",
                   "error", "worker_peak_mb", "input")
DONE, FAILED = "done.json", "failed.json"
#: options that do not change a clip's result (left out of its fingerprint)
_NOT_RESULT = {"out", "quiet", "jobs", "scheduler", "redo", "no_pictures", "inputs", "func", "command", "stability"}


@dataclass(frozen=True)
class Clip:
    """One clip: its output folder's name, what it is (``tracks``: a tracks file or a detector
    folder; ``video``), its input path, and the options a manifest gave it (None: the batch's)."""

    name: str
    kind: str
    path: str
    camera: str | None = None
    keyframes: str | None = None
    figure: str | None = None
    fps: float | None = None


@dataclass
class BatchReport:
    """What a batch did: one summary row per clip (:data:`SUMMARY_COLUMNS`), in the clips'
    order, and where the summary went."""

    rows: list[dict] = field(default_factory=list)
    out: Path | None = None

    @property
    def failed(self) -> int:
        return sum(r["status"] == "failed" for r in self.rows)

    @property
    def ran(self) -> int:
        return sum(r["ran"] == "now" for r in self.rows)


# ---------------------------------------------------------------------------------- discovery
def _is_pinrecon_tracks(data) -> bool:
    return isinstance(data, dict) and {"fps", "names", "points"} <= set(data)


def _looks_like_tracks(path: Path) -> bool:
    """A JSON or NPZ in a folder of inputs is a clip when it reads as tracks (pinrecon's, COCO,
    MMPose, an OpenPose frame): camera, keyframes and other JSON files beside them are not."""
    from .tracks import guess_tracks_format

    if path.suffix.lower() == ".npz":
        return True
    fmt = guess_tracks_format(path)
    if fmt != "json":
        return True
    try:
        return _is_pinrecon_tracks(json.loads(path.read_text()))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return False


def _is_detector_folder(path: Path) -> bool:
    """A folder of per-frame OpenPose JSON files (one clip), not a folder of clips."""
    frames = sorted(path.glob("*.json"))
    if not frames:
        return False
    try:
        data = json.loads(frames[0].read_text())
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return False
    return isinstance(data, dict) and "people" in data and "points" not in data


def _clip_of(path: Path, explicit: bool) -> Clip | None:
    """The clip an input path is, or None (not an input: skipped inside a folder)."""
    suffix = path.suffix.lower()
    if path.is_dir():
        return Clip(path.name, "tracks", str(path)) if _is_detector_folder(path) else None
    if suffix in VIDEO_SUFFIXES:
        return Clip(path.stem, "video", str(path))
    if suffix in TRACKS_SUFFIXES and (explicit or _looks_like_tracks(path)):
        return Clip(path.stem, "tracks", str(path))
    return None


def _expand(text: str) -> list[Clip]:
    if any(c in text for c in "*?["):
        matches = sorted(glob.glob(text, recursive=True))
        if not matches:
            raise InputError("no file or folder matches this pattern", file=text, field="INPUT")
        return [c for m in matches for c in _expand_path(Path(m), explicit=False)]
    path = Path(text)
    if not path.exists():
        raise InputError("no such file or folder", file=text, field="INPUT")
    return _expand_path(path, explicit=True)


def _expand_path(path: Path, explicit: bool) -> list[Clip]:
    if path.is_file() and path.suffix.lower() == ".csv":
        return read_manifest(path)
    clip = _clip_of(path, explicit)
    if clip is not None:
        return [clip]
    if path.is_dir():  # a folder of clips: its files and detector folders (not deeper)
        found = [c for child in sorted(path.iterdir()) if not child.name.startswith(".")
                 for c in [_clip_of(child, explicit=False)] if c is not None]
        if explicit and not found:
            raise InputError("holds no clips (tracks JSON/NPZ, OpenPose folders, videos, a CSV manifest)",
                             file=path, field="INPUT")
        return found
    if explicit:
        raise InputError(f"not a clip: give tracks (.json, .npz), an OpenPose folder, a video "
                         f"({', '.join(VIDEO_SUFFIXES)}), a folder of them, a glob or a CSV manifest",
                         file=path, field="INPUT")
    return []


def read_manifest(path) -> list[Clip]:
    """The clips of a CSV manifest: a header row naming ``input`` (a tracks file, detector
    folder or video; relative paths from the manifest's folder) and any of ``name`` (the
    output folder; default the input's name), ``camera``, ``keyframes``, ``figure``, ``fps``
    (that clip's options; an empty cell takes the batch's)."""
    path = Path(path)
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"cannot read the manifest: {exc}", file=path) from None
    cols = [c.strip() for c in (rows[0].keys() if rows else [])]
    unknown = [c for c in cols if c not in MANIFEST_COLUMNS]
    if unknown or (rows and "input" not in cols):
        raise InputError(f"unknown or missing columns ({', '.join(unknown) or 'no input'}): the columns are "
                         f"{', '.join(MANIFEST_COLUMNS)} (input required)", file=path, field="header")
    base, clips = path.parent, []
    for i, raw in enumerate(rows, start=2):
        row = {k.strip(): (v or "").strip() for k, v in raw.items() if k is not None}

        def rel(key):
            v = row.get(key, "")
            return None if not v else str(v if Path(v).is_absolute() or key == "figure" and v == "human"
                                          else base / v)

        where = f"{path}, line {i}"
        if not row.get("input"):
            raise InputError("empty input", file=where, field="input")
        inp = Path(rel("input"))
        if not inp.exists():
            raise InputError(f"no such file or folder {inp}", file=where, field="input")
        clip = _clip_of(inp, explicit=True)
        if clip is None:
            raise InputError("not a clip (tracks .json/.npz, an OpenPose folder or a video)", file=where,
                             field="input")
        try:
            fps = float(row["fps"]) if row.get("fps") else None
        except ValueError:
            raise InputError(f"expected a number, got {row['fps']!r}", file=where, field="fps") from None
        clips.append(Clip(row.get("name") or clip.name, clip.kind, clip.path, rel("camera"), rel("keyframes"),
                          rel("figure"), fps))
    return clips


def discover(inputs) -> list[Clip]:
    """The clips of ``inputs`` (paths or globs: tracks files, OpenPose folders, videos, folders
    of them, CSV manifests), in order. Two clips with one name is an error naming both (give
    one a ``name`` in a manifest)."""
    clips = [c for text in inputs for c in _expand(str(text))]
    seen: dict[str, Clip] = {}
    for c in clips:
        if c.name in seen and seen[c.name].path != c.path:
            raise InputError(f"two clips would write {c.name}/: {seen[c.name].path} and {c.path} (give them "
                             "names in a CSV manifest)", field="INPUT")
        seen.setdefault(c.name, c)
    unique = list({c.name: c for c in reversed(clips)}.values())[::-1]  # first mention wins, order kept
    if not unique:
        raise InputError("no clips found", field="INPUT")
    return unique


# ---------------------------------------------------------------------------------- one clip
def clip_options(clip: Clip, options):
    """The reconstruct namespace of one clip: the batch's options with the clip's input and
    the manifest's per-clip values."""
    a = copy.copy(options)
    a.tracks = [clip.path]
    if clip.camera:
        a.camera = [clip.camera]
    if clip.keyframes:
        a.keyframes = clip.keyframes
    if clip.figure:
        a.figure = clip.figure
    if clip.fps is not None:
        a.fps = clip.fps
    a.quiet, a.stability = True, None
    return a


def _stamp(path) -> list:
    """Size and modification time of a file (of each file in a folder): a changed input
    changes the clip's fingerprint."""
    p = Path(path)
    try:
        files = sorted(f for f in p.iterdir() if f.is_file()) if p.is_dir() else [p]
        return [[f.name, f.stat().st_size, f.stat().st_mtime_ns] for f in files]
    except OSError:
        return []


def fingerprint(clip: Clip, options) -> str:
    """A hash of everything that decides a clip's result: its options, and the paths, sizes
    and modification times of its input, camera, keyframes and figure files."""
    a = vars(clip_options(clip, options))
    keep = {k: a[k] for k in sorted(a) if k not in _NOT_RESULT}
    files = [clip.path, *(a.get("camera") or []), a.get("keyframes"), a.get("figure")]
    keep["_files"] = [_stamp(f) for f in files if f and Path(f).exists()]
    return hashlib.sha256(json.dumps(keep, sort_keys=True, default=str).encode()).hexdigest()[:16]


def clip_is_done(folder, fp: str | None = None) -> dict | None:
    """The summary row recorded in ``folder/done.json`` when the clip is complete (the marker
    reads, every file it lists is there at its size, and, given ``fp``, it was made with those
    options); else None."""
    folder = Path(folder)
    try:
        done = json.loads((folder / DONE).read_text())
        files = done["files"]
        row = done["row"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if fp is not None and done.get("fingerprint") != fp:
        return None
    for name, size in files.items():
        p = folder / name
        if not p.is_file() or p.stat().st_size != size:
            return None
    return row


def _peak_mb() -> float:
    import resource

    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return round(rss / (1024 * 1024 if sys.platform == "darwin" else 1024), 1)


def _one_line(exc: BaseException) -> str:
    text = str(exc) if isinstance(exc, PinreconError) else f"{type(exc).__name__}: {exc}"
    return " ".join(text.split())[:500]


def _video_tracks(clip: Clip, a, folder: Path) -> None:
    """Track a video clip as ``pinrecon track`` does (:func:`pinrecon.video.track_video`, the
    ``video`` extra) into ``folder/tracks.json`` and point ``a`` at it, as ``pinrecon video``
    does: the tracks' own frame rate, ``--camera auto`` unless a camera was given, the video's
    frame size for it. The detector runs on :data:`THREADS` threads, as the solve: the batch's
    workers share the cores clip by clip."""
    from .video import track_video as track
    from .video import video_info as info_of

    info = info_of(clip.path, fps=a.fps)
    tracks = track(clip.path, fps=a.fps, threads=THREADS)
    if not tracks.observed.any():
        raise InputError("the tracker found no person in any frame", file=clip.path)
    out = folder / "tracks.json"
    tracks.save(out)
    a.tracks, a.fps = [str(out)], None
    if not a.camera:
        a.camera = ["auto"]
    if any(c.split(":")[0] == "auto" for c in a.camera) and a.image_size is None:
        a.image_size = [float(info.width), float(info.height)]


def run_clip(clip: Clip, options, out_dir, pictures: bool = True) -> dict:
    """Reconstruct one clip into ``out_dir/<clip.name>/`` and return its summary row; a
    failure is a row with status ``failed`` and the one-line error (nothing raised). The
    same code whatever runs it: this process, a pool worker or a Dask worker."""
    from threadpoolctl import threadpool_limits

    folder = Path(out_dir) / clip.name
    folder.mkdir(parents=True, exist_ok=True)
    for stale in (DONE, FAILED):
        (folder / stale).unlink(missing_ok=True)
    for tmp in folder.glob(".*.tmp*"):  # half-written files of a run killed in flight
        tmp.unlink(missing_ok=True)
    row = {"clip": clip.name, "status": "failed", "ran": "now", "frames": "", "time_s": "", "reprojection_px": "",
           "flagged_spans": "", "warnings": "", "error": "", "worker_peak_mb": "", "input": clip.path}
    log = [f"pinrecon batch: clip {clip.name} from {clip.path}"]
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught, threadpool_limits(limits=THREADS):
        warnings.simplefilter("always")
        try:
            files = _reconstruct_clip(clip, options, folder, pictures, log)
            row["status"] = "ok"
        except Exception as exc:  # noqa: BLE001 - any failure is this clip's, the batch goes on
            row["error"] = _one_line(exc)
            log += ["error: " + row["error"], "", traceback.format_exc()]
            files = None
    said = list(dict.fromkeys(" ".join(str(w.message).split()) for w in caught))
    row["warnings"] = len(said)
    row["time_s"] = round(time.perf_counter() - t0, 3)
    row["worker_peak_mb"] = _peak_mb()
    log += [f"warning: {w}" for w in said]
    if files is not None:
        row.update(files.pop("_row"))
    log.append(f"{row['status']} in {row['time_s']} s")
    atomic_write_text(folder / "log.txt", "\n".join(log) + "\n")
    if files is None:
        atomic_write_text(folder / FAILED, json.dumps({"row": row}, indent=1))
        return row
    files["log.txt"] = (folder / "log.txt").stat().st_size
    done = {"row": row, "files": files, "fingerprint": fingerprint(clip, options)}
    atomic_write_text(folder / DONE, json.dumps(done, indent=1))  # last: the clip is complete
    return row


def _reconstruct_clip(clip: Clip, options, folder: Path, pictures: bool, log: list) -> dict:
    import numpy as np

    from .arguments import reconstruct_from_args
    from .io.bvh_export import export_result
    from .result import uncertain_limb_spans

    a = clip_options(clip, options)
    if not a.figure:
        raise InputError("no figure: give --figure, or a figure column in the manifest", field="--figure")
    written = []
    if clip.kind == "video":
        _video_tracks(clip, a, folder)
        written.append(folder / "tracks.json")
    if not a.camera:
        raise InputError("no camera: give --camera, or a camera column in the manifest", field="--camera")
    res = reconstruct_from_args(a)
    npz = folder / "result.npz"
    res.save(npz)
    written += [npz] + export_result(npz, bvh=folder / "result.bvh", csv=folder / "result.csv",
                                    trc=folder / "result.trc")
    if pictures:
        written += _strip(res, folder, log)
    summary = res.summary()
    atomic_write_text(folder / "summary.txt", summary + "\n")
    written.append(folder / "summary.txt")
    log += ["", summary, ""] + [f"wrote {p.name}" for p in written]
    err = res.reprojection_error_px
    mean = float(np.nanmean(err)) if np.any(np.isfinite(err)) else float("nan")
    files = {Path(p).name: Path(p).stat().st_size for p in written}
    files["_row"] = {"frames": len(res.times), "reprojection_px": round(mean, 4),
                     "flagged_spans": len(uncertain_limb_spans(res.extras))}
    return files


def _strip(res, folder: Path, log: list) -> list[Path]:
    """The clip's stick strip (the viz extra); without matplotlib, a line in the log."""
    try:
        from .viz import plot_stick_strip

        fig = plot_stick_strip(res, out=folder / "strip.png")
    except ImportError as exc:
        log.append(f"no stick strip: {exc}")
        return []
    del fig
    return [folder / "strip.png"]


# ---------------------------------------------------------------------------------- many clips
def _pool_init() -> None:
    """A pool worker's start: warnings said once, on the clip's log, never on the terminal."""
    warnings.simplefilter("ignore")


class _Bar:
    """A progress bar over clips on stderr: a live line on a terminal, a line per clip otherwise."""

    def __init__(self, total: int, done: int, quiet: bool):
        self.total, self.done, self.failed, self.quiet = total, done, 0, quiet
        self.t0, self.tty, self.ran = time.perf_counter(), sys.stderr.isatty(), 0
        self.show("")

    def step(self, row: dict) -> None:
        self.done += 1
        self.ran += 1
        self.failed += row["status"] == "failed"
        self.show(f"{row['clip']}: {row['status']}" + (f" ({row['error']})" if row["error"] else ""))

    def show(self, last: str) -> None:
        if self.quiet:
            return
        width = 24
        full = int(width * self.done / max(self.total, 1))
        elapsed = time.perf_counter() - self.t0
        eta = f", about {elapsed / self.ran * (self.total - self.done):.0f}s left" if self.ran else ""
        line = (f"[{'#' * full}{'.' * (width - full)}] {self.done}/{self.total} clips, {self.failed} failed, "
                f"{elapsed:.0f}s{eta}")
        if self.tty:
            print("\r" + line[:78].ljust(78), end="" if self.done < self.total else "\n", file=sys.stderr,
                  flush=True)
        elif last or self.done == 0:
            last = last if len(last) < 120 else last[:117] + "..."
            print(line + (f"  {last}" if last else ""), file=sys.stderr, flush=True)


def run_batch(clips, options, out_dir, *, jobs: int | None = None, scheduler: str | None = None,
              redo: bool = False, pictures: bool = True, quiet: bool = False) -> BatchReport:
    """Run every clip not already done into ``out_dir`` and write ``summary.csv`` and
    ``summary.html`` there.

    ``options``: reconstruct's options (an ``argparse.Namespace`` of
    :func:`pinrecon.arguments.add_reconstruct_options`), the same for every clip but for a
    manifest's columns. ``jobs``: worker processes (default every core; 1 runs here, one
    clip after another). ``scheduler``: ``"local-dask"`` (a ``dask.distributed`` LocalCluster
    of ``jobs`` workers, started here) or a Dask scheduler's address (its workers must import
    pinrecon and see the files); needs the ``batch`` extra. ``redo``: run finished clips again.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows: dict[str, dict] = {}
    todo = []
    for clip in clips:
        row = None if redo else clip_is_done(out / clip.name, fingerprint(clip, options))
        if row is not None:
            rows[clip.name] = {**row, "ran": "earlier"}
        else:
            todo.append(clip)
    bar = _Bar(len(clips), len(clips) - len(todo), quiet)
    from .windowed import usable_cpus  # the solver's modules load when there is work

    jobs = max(1, min(jobs or usable_cpus(), len(todo) or 1))
    try:
        for row in _execute(todo, options, out, jobs, scheduler, pictures):
            rows[row["clip"]] = row
            bar.step(row)
    finally:
        report = BatchReport([rows[c.name] for c in clips if c.name in rows], out)
        write_summary(report.rows, out)
    return report


def _execute(todo, options, out: Path, jobs: int, scheduler: str | None, pictures: bool):
    """Rows of the clips ``todo`` as they finish, run here, on a process pool or on Dask."""
    if not todo:
        return
    if scheduler:
        yield from _on_dask(todo, options, out, jobs, scheduler, pictures)
    elif jobs == 1:
        for clip in todo:
            yield run_clip(clip, options, out, pictures)
    else:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor, as_completed

        ctx = multiprocessing.get_context("spawn")  # no threads (or a progress line) forked into the workers
        pool = ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=_pool_init)
        try:
            futures = {pool.submit(run_clip, clip, options, out, pictures): clip for clip in todo}
            for f in as_completed(futures):
                yield _row_of(f, futures[f])
        finally:  # interrupted: the clips not started are dropped, not run
            pool.shutdown(wait=True, cancel_futures=True)


def _row_of(future, clip: Clip) -> dict:
    """A finished task's row; a worker that died with its clip (killed, out of memory) makes
    a failed row, and the batch goes on."""
    try:
        return future.result()
    except Exception as exc:  # noqa: BLE001 - the worker's end, not the clip's error
        return {"clip": clip.name, "status": "failed", "ran": "now", "frames": "", "time_s": "",
                "reprojection_px": "", "flagged_spans": "", "warnings": "", "worker_peak_mb": "", "input": clip.path,
                "error": "the worker running this clip died: " + _one_line(exc)}


def _on_dask(todo, options, out: Path, jobs: int, scheduler: str, pictures: bool):
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        from .viz import MissingDependencyError

        raise MissingDependencyError("--scheduler needs dask.distributed; install the 'batch' extra: "
                                     "pip install 'pinrecon[batch]'") from None
    cluster = None
    if scheduler == "local-dask":
        cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"cannot reach the Dask scheduler: {exc}", field="--scheduler") from None
    try:
        futures = {client.submit(run_clip, clip, options, str(out), pictures, key=f"pinrecon-batch-{clip.name}-"
                                 f"{fingerprint(clip, options)}", pure=False): clip for clip in todo}
        for f in as_completed(futures):
            yield _row_of(f, futures[f])
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


# ---------------------------------------------------------------------------------- summary
def write_summary(rows, out_dir) -> list[Path]:
    """``summary.csv`` and ``summary.html`` of the rows (:data:`SUMMARY_COLUMNS`) in
    ``out_dir``, atomically; the HTML links each clip's folder files and stick strip."""
    out = Path(out_dir)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=SUMMARY_COLUMNS, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    atomic_write_text(out / "summary.csv", buf.getvalue())
    atomic_write_text(out / "summary.html", _html(rows, out))
    return [out / "summary.csv", out / "summary.html"]


def _html(rows, out: Path) -> str:
    e = html.escape
    head = "".join(f"<th>{e(c)}</th>" for c in ("picture",) + SUMMARY_COLUMNS)
    body = []
    for r in rows:
        name = r["clip"]
        strip = out / name / "strip.png"
        pic = (f'<a href="{e(name)}/strip.png"><img src="{e(name)}/strip.png" height="60"></a>' if strip.is_file()
               else "")
        cells = [f'<a href="{e(name)}/summary.txt">{e(name)}</a>' if r["status"] == "ok" else
                 f'<a href="{e(name)}/log.txt">{e(name)}</a>']
        cells += [e(str(r.get(c, ""))) for c in SUMMARY_COLUMNS[1:]]
        cls = ' class="failed"' if r["status"] == "failed" else ""
        body.append(f"<tr{cls}><td>{pic}</td>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
    failed = sum(r["status"] == "failed" for r in rows)
    return (
        "<!doctype html><html><head><meta charset='utf-8'><title>pinrecon batch</title><style>"
        "body{font-family:sans-serif}table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 6px;"
        "font-size:13px}tr.failed{background:#fdd}</style></head><body>"
        f"<h1>pinrecon batch: {len(rows)} clips, {failed} failed</h1>"
        f"<table><tr>{head}</tr>{''.join(body)}</table></body></html>\n"
    )
