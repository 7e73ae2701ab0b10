"""A command's outputs are checked before the work and committed all or none
(pinrecon.io.atomic.Outputs): an unwritable output fails fast with one line naming it and
leaves nothing behind; a failure while writing leaves every earlier file as it was."""

from __future__ import annotations

import json
import os
import time

import numpy as np
import pytest

from pinrecon.cli import main
from pinrecon.errors import InputError
from pinrecon.io.atomic import Outputs, atomic_write_text

STICK_URDF = """<robot name="stick"><link name="base"/><link name="arm"/>
<joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0 0.5 0"/>
<axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="0" velocity="0"/></joint></robot>"""
KEYPOINTS = {"keypoints": {"a": {"frame": "arm", "offset": [0.0, 0.3, 0.0]},
                           "b": {"frame": "arm", "offset": [0.0, 0.5, 0.0]},
                           "c": {"frame": "base", "offset": [0.1, 0.0, 0.0]}}}
CAMERA = {"model": "orthographic", "R": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "scale": 300.0, "center": [640.0, 360.0]}



@pytest.fixture
def readonly(tmp_path):
    """A folder nobody may write in: a chmod 555 one, or for root (who ignores permissions)
    the kernel's /sys."""
    if not (hasattr(os, "geteuid") and os.geteuid() == 0):
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        yield ro
        ro.chmod(0o755)
        return
    import tempfile
    from pathlib import Path

    try:
        fd, name = tempfile.mkstemp(dir="/sys")
    except OSError:
        yield Path("/sys")
        return
    os.close(fd)
    os.unlink(name)
    pytest.skip("running as root with no folder that refuses writes")


@pytest.fixture
def inputs(tmp_path):
    d = tmp_path / "in"
    d.mkdir()
    (d / "stick.urdf").write_text(STICK_URDF)
    (d / "kp.json").write_text(json.dumps(KEYPOINTS))
    (d / "camera.json").write_text(json.dumps(CAMERA))
    pts = [[[640 + 10 * t, 360 - 90], [640 + 10 * t, 360 - 150], [670, 360]] for t in range(6)]
    (d / "tracks.json").write_text(json.dumps({"fps": 25.0, "names": ["a", "b", "c"], "points": pts}))
    return d


def _argv(d, out, *more):
    return ["reconstruct", "--figure", str(d / "stick.urdf"), "--keypoints", str(d / "kp.json"), "--tracks",
            str(d / "tracks.json"), "--camera", str(d / "camera.json"), "--out", str(out), "--quiet",
            "--max-iterations", "3", *more]


def _files(root):
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


def _run(argv, capsys):
    t0 = time.perf_counter()
    rc = main(argv)
    err = capsys.readouterr().err
    return rc, err, time.perf_counter() - t0


def test_a_good_run_writes_every_output(inputs, tmp_path, capsys):
    out = tmp_path / "ok" / "deeper" / "result.npz"
    rc, err, _ = _run(_argv(inputs, out, "--save-camera", str(tmp_path / "ok" / "camera.json")), capsys)
    assert rc == 0, err
    assert out.is_file() and (tmp_path / "ok" / "camera.json").is_file()
    assert not [p for p in (tmp_path / "ok").rglob(".*")]  # no temporary left


def test_read_only_folder(inputs, readonly, capsys):
    before = sorted(readonly.iterdir())
    rc, err, seconds = _run(_argv(inputs, readonly / "result.npz"), capsys)
    assert rc == 2 and seconds < 2.0
    assert err.count("\n") == 1 and str(readonly / "result.npz") in err and "--out" in err
    assert sorted(readonly.iterdir()) == before


def test_parent_is_a_file(inputs, tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    before = _files(tmp_path)
    rc, err, seconds = _run(_argv(inputs, tmp_path / "afile" / "sub" / "result.npz"), capsys)
    assert rc == 2 and seconds < 2.0 and err.count("\n") == 1
    assert "afile" in err and "is a file" in err
    assert _files(tmp_path) == before


def test_second_output_unwritable_writes_nothing(inputs, tmp_path, readonly, capsys):
    ok = tmp_path / "ok"
    ok.mkdir()
    (ok / "result.npz").write_bytes(b"an earlier result")
    before = sorted(readonly.iterdir())
    rc, err, seconds = _run(_argv(inputs, ok / "result.npz", "--save-camera", str(readonly / "camera.json")), capsys)
    assert rc == 2 and seconds < 2.0 and err.count("\n") == 1
    assert str(readonly / "camera.json") in err and "--save-camera" in err
    assert (ok / "result.npz").read_bytes() == b"an earlier result"  # untouched
    assert _files(ok) == ["result.npz"] and sorted(readonly.iterdir()) == before


def test_export_second_output_unwritable(tmp_path, capsys):
    from pinrecon import Figure
    from pinrecon.figure import parse_keypoint_entries
    from pinrecon.result import Result

    fig = Figure.from_urdf_string(STICK_URDF, parse_keypoint_entries(KEYPOINTS["keypoints"]))
    res = tmp_path / "r.npz"
    Result.from_motion(fig, np.tile(fig.neutral(), (4, 1)), 25.0).save(res)
    (tmp_path / "blocker").write_text("x")
    rc, err, seconds = _run(["export", str(res), "--bvh", str(tmp_path / "m.bvh"), "--csv",
                             str(tmp_path / "blocker" / "m.csv")], capsys)
    assert rc == 2 and seconds < 2.0 and "--csv" in err and not (tmp_path / "m.bvh").exists()


def test_commit_is_all_or_none(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "new" / "b.txt"
    a.write_text("old")
    outs = Outputs([a, b])
    outs.check()
    with pytest.raises(RuntimeError):
        with outs.commit():
            atomic_write_text(a, "new")
            atomic_write_text(b, "new")
            raise RuntimeError("the work failed after writing")
    assert a.read_text() == "old" and not (tmp_path / "new").exists()
    assert _files(tmp_path) == ["a.txt"]
    with Outputs([a, b]).commit():
        atomic_write_text(a, "new")
        atomic_write_text(b, "new")
    assert a.read_text() == "new" and b.read_text() == "new" and _files(tmp_path) == ["a.txt", "new", "new/b.txt"]


def test_check_names_the_path(tmp_path):
    (tmp_path / "d").mkdir()
    with pytest.raises(InputError, match="is a folder"):
        Outputs([tmp_path / "d"]).check()
    with pytest.raises(InputError, match="two outputs"):
        Outputs(fields={"--out": tmp_path / "x.npz", "--bvh": tmp_path / "x.npz"}).check()


def test_plot_folder_that_is_a_file(tmp_path, capsys):
    (tmp_path / "pictures").write_text("x")
    rc, err, seconds = _run(["plot", str(tmp_path / "missing.npz"), "--out", str(tmp_path / "pictures")], capsys)
    assert rc == 2 and seconds < 2.0 and err.count("\n") == 1 and "is a file, not a folder" in err
    assert (tmp_path / "pictures").read_text() == "x"
