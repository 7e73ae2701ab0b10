"""pinrecon batch: each clip's result equals a single ``pinrecon reconstruct`` of it (bit for
bit) whatever runs it (this process, a process pool, a Dask LocalCluster, a Dask scheduler
on loopback); finished clips are skipped and incomplete ones redone; a failing clip is
recorded and the others go on. Clips are 40 frames of the CMU walk, tracked synthetically."""

from __future__ import annotations

import argparse
import asyncio
import csv
import json
import os
import shutil
import sys
import threading

import numpy as np
import pytest

from pinrecon.batch import Clip, clip_is_done, discover, run_batch
from pinrecon.cli import main
from pinrecon.errors import InputError

# quick solves: the rest start, no floor, 15 iterations (the batch takes reconstruct's options as given)
SOLVE = ["--figure", "human", "--seed", "rest", "--floor", "none", "--max-iterations", "15"]
CLIPS = {"walk_a": (0, 80, 2), "walk_b": (60, 140, 2), "walk_c": (100, 140, 1)}  # (first, stop, step) of 120 fps


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A folder of three 40-frame tracks files (different spans and rates of the walk) and the
    camera beside them (a JSON that is not tracks: discovery must leave it out)."""
    from pinrecon.synthetic import bundled_motion, coco_body_tracks, perspective_side_camera

    root = tmp_path_factory.mktemp("batch_in")
    bfig, q, fps = bundled_motion("walk")
    cam = perspective_side_camera(q[:140], 45.0, distance_m=6.0, f_px=1100.0, center=(640.0, 360.0))
    for i, (name, (a, b, step)) in enumerate(CLIPS.items()):
        tracks, _ = coco_body_tracks(bfig, q[a:b:step], cam, fps=fps / step, noise_px=2.0, seed=i)
        tracks.save(root / f"{name}.json")
    cam.save(root / "camera.json")
    return root


def _npz(path) -> dict:
    """A result NPZ's arrays; the stage reports without their wall-clock seconds, and without
    the run's wall time (``run_time_s``): what differs from run to run."""
    with np.load(path) as d:
        out = {k: d[k] for k in d.files if k != "run_time_s"}  # the whole run's wall time, as the seconds
    if "stages" in out:
        stages = [{k: v for k, v in st.items() if k != "seconds"} for st in json.loads(str(out["stages"]))]
        out["stages"] = np.array(json.dumps(stages))
    return out


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f") for k in a)


def _summary(out) -> dict:
    with open(out / "summary.csv", newline="") as f:
        return {r["clip"]: r for r in csv.DictReader(f)}


@pytest.fixture(scope="module")
def reference(inputs, tmp_path_factory):
    """Each clip through a single ``pinrecon reconstruct``."""
    out = tmp_path_factory.mktemp("batch_ref")
    ref = {}
    for name in CLIPS:
        assert main(["reconstruct", "--tracks", str(inputs / f"{name}.json"), "--camera", str(inputs / "camera.json"),
                     "--out", str(out / f"{name}.npz"), "--quiet", *SOLVE]) == 0
        ref[name] = _npz(out / f"{name}.npz")
    return ref


@pytest.fixture(scope="module")
def serial(inputs, tmp_path_factory):
    """The batch run in this process (--jobs 1), with the stick strips."""
    out = tmp_path_factory.mktemp("batch_serial")
    assert main(["batch", str(inputs), "--out", str(out), "--camera", str(inputs / "camera.json"), "--jobs", "1",
                 "--quiet", *SOLVE]) == 0
    return out


def _assert_equal_to(out, reference):
    for name, ref in reference.items():
        assert _same(_npz(out / name / "result.npz"), ref), name


def test_each_clip_equals_a_single_reconstruct(serial, reference):
    _assert_equal_to(serial, reference)
    rows = _summary(serial)
    assert set(rows) == set(CLIPS)  # the camera JSON beside the tracks is no clip
    for name, ref in reference.items():
        r = rows[name]
        assert r["status"] == "ok" and r["ran"] == "now" and r["error"] == ""
        assert int(r["frames"]) == len(ref["times"]) == 40
        assert float(r["reprojection_px"]) == pytest.approx(np.nanmean(ref["reprojection_error_px"]), abs=1e-4)
        for f in ("result.bvh", "result.csv", "result.trc", "summary.txt", "log.txt", "strip.png", "done.json"):
            assert (serial / name / f).is_file(), f
    page = (serial / "summary.html").read_text()
    assert all(f'<img src="{n}/strip.png"' in page for n in CLIPS)


def test_resume_skips_finished_and_redoes_incomplete(serial, inputs, reference, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(serial, out)
    (out / "walk_b" / "done.json").unlink()  # killed before its marker
    bvh = out / "walk_c" / "result.bvh"
    bvh.write_text(bvh.read_text()[:100])  # a file cut short under its marker
    kept = (out / "walk_a" / "result.npz").stat().st_mtime_ns
    assert clip_is_done(out / "walk_a") and not clip_is_done(out / "walk_b") and not clip_is_done(out / "walk_c")
    assert main(["batch", str(inputs), "--out", str(out), "--camera", str(inputs / "camera.json"), "--jobs", "1",
                 "--quiet", "--no-pictures", *SOLVE]) == 0
    rows = _summary(out)
    assert {n: r["ran"] for n, r in rows.items()} == {"walk_a": "earlier", "walk_b": "now", "walk_c": "now"}
    assert (out / "walk_a" / "result.npz").stat().st_mtime_ns == kept
    _assert_equal_to(out, reference)
    # other options make other results: nothing is skipped then; --redo runs finished clips again
    assert main(["batch", str(inputs / "walk_a.json"), "--out", str(out), "--camera", str(inputs / "camera.json"),
                 "--jobs", "1", "--quiet", "--no-pictures", *SOLVE, "--max-iterations", "3"]) == 0
    assert _summary(out)["walk_a"]["ran"] == "now"
    assert not _same(_npz(out / "walk_a" / "result.npz"), reference["walk_a"])
    assert main(["batch", str(inputs / "walk_a.json"), "--out", str(out), "--camera", str(inputs / "camera.json"),
                 "--jobs", "1", "--quiet", "--no-pictures", "--redo", *SOLVE]) == 0
    assert _summary(out)["walk_a"]["ran"] == "now"
    assert _same(_npz(out / "walk_a" / "result.npz"), reference["walk_a"])
    # a changed input file (here only its modification time) runs its clip again
    tracks = inputs / "walk_a.json"
    st = tracks.stat()
    again = ["batch", str(tracks), "--out", str(out), "--camera", str(inputs / "camera.json"), "--jobs", "1",
             "--quiet", "--no-pictures", *SOLVE]
    assert main(again) == 0 and _summary(out)["walk_a"]["ran"] == "earlier"
    os.utime(tracks, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))
    try:
        assert main(again) == 0 and _summary(out)["walk_a"]["ran"] == "now"
    finally:
        os.utime(tracks, ns=(st.st_atime_ns, st.st_mtime_ns))


def test_a_failing_clip_is_recorded_and_the_rest_go_on(inputs, reference, tmp_path, capsys):
    src = tmp_path / "in"
    src.mkdir()
    shutil.copy(inputs / "walk_a.json", src / "walk_a.json")
    (src / "bad.json").write_text(json.dumps({"fps": 30, "names": ["tail"], "points": [[[1.0, 2.0]]] * 5}))
    (src / "clip.mp4").write_bytes(b"")
    out = tmp_path / "out"
    rc = main(["batch", str(src), "--out", str(out), "--camera", str(inputs / "camera.json"), "--jobs", "1",
               "--no-pictures", *SOLVE])
    assert rc == 2  # two clips failed
    rows = _summary(out)
    assert rows["walk_a"]["status"] == "ok"
    _assert_equal_to(out, {"walk_a": reference["walk_a"]})
    assert rows["bad"]["status"] == "failed" and "'tail'" in rows["bad"]["error"] and "\n" not in rows["bad"]["error"]
    assert not (out / "bad" / "done.json").exists() and (out / "bad" / "failed.json").exists()
    assert "Traceback" in (out / "bad" / "log.txt").read_text()
    assert rows["clip"]["status"] == "failed" and "clip.mp4" in rows["clip"]["error"]  # no video in that file
    err = capsys.readouterr().err
    assert "3 clips, 3 run now, 2 failed" in err and "bad: " in err
    assert "failed" in (out / "summary.html").read_text()


def test_two_workers_equal_one(inputs, serial, reference, tmp_path):
    out = tmp_path / "out"
    assert main(["batch", str(inputs / "*.json"), "--out", str(out), "--camera", str(inputs / "camera.json"),
                 "--jobs", "2", "--quiet", "--no-pictures", *SOLVE]) == 0
    _assert_equal_to(out, reference)
    assert {r["status"] for r in _summary(out).values()} == {"ok"}


def test_local_dask_equals_them(inputs, reference, tmp_path):
    pytest.importorskip("dask.distributed")
    out = tmp_path / "out"
    assert main(["batch", str(inputs), "--out", str(out), "--camera", str(inputs / "camera.json"), "--jobs", "2",
                 "--scheduler", "local-dask", "--quiet", "--no-pictures", *SOLVE]) == 0
    _assert_equal_to(out, reference)


def test_a_dask_scheduler_on_loopback(inputs, reference, tmp_path):
    """A Scheduler and a Worker started here, on 127.0.0.1; the batch given its address."""
    distributed = pytest.importorskip("dask.distributed")
    loop = asyncio.new_event_loop()
    thread = threading.Thread(target=loop.run_forever, daemon=True)
    thread.start()

    async def up():
        s = await distributed.Scheduler(host="127.0.0.1", port=0, dashboard=False)
        w = await distributed.Worker(s.address, nthreads=1, host="127.0.0.1")
        return s, w

    async def down(s, w):
        await w.close()
        await s.close()

    s, w = asyncio.run_coroutine_threadsafe(up(), loop).result(60)
    try:
        assert s.address.startswith("tcp://127.0.0.1:")
        from pinrecon.commands.batch import register

        sub = argparse.ArgumentParser().add_subparsers()
        register(sub)
        args = sub.choices["batch"].parse_args([str(inputs), "--out", str(tmp_path), "--camera",
                                                str(inputs / "camera.json"), *SOLVE])
        options = argparse.Namespace(**{k: v for k, v in vars(args).items() if k not in ("inputs", "out", "func")})
        report = run_batch(discover([inputs]), options, tmp_path / "out", scheduler=s.address, pictures=False,
                           quiet=True)
        assert report.failed == 0 and report.ran == len(CLIPS)
        _assert_equal_to(tmp_path / "out", reference)
    finally:
        asyncio.run_coroutine_threadsafe(down(s, w), loop).result(60)
        loop.call_soon_threadsafe(loop.stop)
        thread.join(10)


def test_discovery_and_manifest(inputs, tmp_path):
    man = tmp_path / "clips.csv"
    man.write_text(f"input,name,fps,camera\n{inputs / 'walk_a.json'},first,,\n{inputs / 'walk_b.json'},,30,"
                   f"{inputs / 'camera.json'}\n")
    clips = discover([man, str(inputs / "walk_c.json")])
    assert [c.name for c in clips] == ["first", "walk_b", "walk_c"]
    assert clips[1] == Clip("walk_b", "tracks", str(inputs / "walk_b.json"), str(inputs / "camera.json"), None, None,
                            30.0)
    assert [c.name for c in discover([str(inputs / "walk_*.json")])] == list(CLIPS)
    pose = tmp_path / "trials" / "trial1_json"  # an OpenPose folder: one clip, not a folder of clips
    pose.mkdir(parents=True)
    for t in range(3):
        (pose / f"trial1_{t:012d}_keypoints.json").write_text(json.dumps({"version": 1.3, "people": []}))
    (tmp_path / "trials" / "notes").mkdir()
    assert discover([tmp_path / "trials"]) == [Clip("trial1_json", "tracks", str(pose))]
    assert discover([pose]) == [Clip("trial1_json", "tracks", str(pose))]
    (tmp_path / "walk_a.json").write_text("{}")
    with pytest.raises(InputError, match="two clips would write walk_a/"):
        discover([inputs, tmp_path / "walk_a.json"])
    (tmp_path / "bad.csv").write_text("input,colour\nx,red\n")
    with pytest.raises(InputError, match="the columns are input, name, camera"):
        discover([tmp_path / "bad.csv"])
    with pytest.raises(InputError, match="no such file or folder"):
        discover([tmp_path / "nothing.json"])


def test_without_dask_one_clear_error(inputs, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    rc = main(["batch", str(inputs / "walk_a.json"), "--out", str(tmp_path), "--camera", str(inputs / "camera.json"),
               "--scheduler", "local-dask", "--quiet", *SOLVE])
    assert rc == 2
    assert "pip install 'pinrecon[batch]'" in capsys.readouterr().err


def test_a_video_clip_goes_through_the_video_tracker(inputs, reference, tmp_path, monkeypatch):
    """A video clip is tracked by pinrecon.video.track_video (here a stand-in returning the
    walk's tracks, so the result must equal that clip's single reconstruct) and solved from
    the tracks file it writes."""
    import types

    from pinrecon.tracks import load_tracks

    seen = []

    def track_video(path, *, fps=None, threads=None):
        seen.append((path, threads))
        return load_tracks(inputs / "walk_a.json")

    fake = types.SimpleNamespace(track_video=track_video,
                                 video_info=lambda path, fps=None: types.SimpleNamespace(width=1280, height=720))
    monkeypatch.setitem(sys.modules, "pinrecon.video", fake)
    (tmp_path / "walk_a.mp4").write_bytes(b"")
    out = tmp_path / "out"
    assert main(["batch", str(tmp_path / "walk_a.mp4"), "--out", str(out), "--camera", str(inputs / "camera.json"),
                 "--jobs", "1", "--quiet", "--no-pictures", *SOLVE]) == 0
    assert seen == [(str(tmp_path / "walk_a.mp4"), 1)]  # one detector thread a clip: the workers share the cores
    assert (out / "walk_a" / "tracks.json").is_file()
    _assert_equal_to(out, {"walk_a": reference["walk_a"]})


def test_a_dead_worker_is_a_failed_row():
    """A task whose worker died (BrokenProcessPool, Dask's KilledWorker) is that clip's failure."""
    from concurrent.futures import Future
    from concurrent.futures.process import BrokenProcessPool

    from pinrecon.batch import SUMMARY_COLUMNS, _row_of

    f = Future()
    f.set_exception(BrokenProcessPool("A process in the process pool was terminated abruptly"))
    row = _row_of(f, Clip("walk_a", "tracks", "walk_a.json"))
    assert set(row) == set(SUMMARY_COLUMNS)
    assert row["status"] == "failed" and row["error"].startswith("the worker running this clip died: BrokenProcessPool")
