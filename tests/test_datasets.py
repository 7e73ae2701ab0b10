"""Third-party data through ``pinrecon.datasets``: the registry against the files, the checks a
user relies on (a corrupted file is refused, a missing one is named with its URL and
PINRECON_DATA), and no third-party data file in the repository."""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPO, data_file

from pinrecon import datasets
from pinrecon.datasets import DatasetError

# Extensions of data files that, in this repository, are third-party by nature (motion capture,
# markers, video) and may never be committed.
DATA_EXTENSIONS = (".bvh", ".amc", ".asf", ".c3d", ".trc", ".mp4", ".avi", ".mov", ".mkv", ".npy")


def _git_files() -> list[str]:
    out = subprocess.run(["git", "-C", str(REPO), "ls-files"], capture_output=True, text=True, check=False)
    if out.returncode != 0:
        pytest.skip("not a git checkout")
    return out.stdout.splitlines()


def test_no_third_party_data_file_is_committed():
    files = _git_files()
    by_ext = [f for f in files if f.lower().endswith(DATA_EXTENSIONS)]
    assert by_ext == []
    # nor any file whose bytes are a registered third-party file, wherever it sits
    sizes = {}
    for f in files:
        p = REPO / f
        if p.is_file():
            sizes.setdefault(p.stat().st_size, []).append(p)
    registered = {e.sha256 for e in datasets.registry().values()}
    copies = []
    for f in files:
        p = REPO / f
        if p.is_file() and p.stat().st_size > 200 and hashlib.sha256(p.read_bytes()).hexdigest() in registered:
            copies.append(f)
    assert copies == []


def test_registry_names_are_paths_and_hashes_are_sha256():
    reg = datasets.registry()
    assert len(reg) > 500
    for name, e in reg.items():
        assert not name.startswith("/") and ".." not in name.split("/")
        assert re.fullmatch(r"[0-9a-f]{64}", e.sha256)
        assert e.url is None or re.fullmatch(r"https?://\S+", e.url)
    # the published sources are pinned: every GitHub URL names a 40-hex commit
    for e in reg.values():
        if e.url and "githubusercontent" in e.url:
            assert re.search(r"/[0-9a-f]{40}/", e.url), e.url


def test_every_registered_file_matches_its_hash_in_the_data_folder():
    root = datasets.data_root()
    if root is None:
        pytest.skip("PINRECON_DATA is not set: no local data folder to check the registry against")
    for name, e in datasets.registry().items():
        path = root / name
        assert path.is_file(), name
        assert hashlib.sha256(path.read_bytes()).hexdigest() == e.sha256, name


def test_every_file_of_the_data_folder_is_registered():
    root = datasets.data_root()
    if root is None:
        pytest.skip("PINRECON_DATA is not set")
    on_disk = {p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file()}
    docs = {n for n in on_disk if n.rsplit("/", 1)[-1] in ("SOURCES.md", "README.md")}
    assert on_disk - docs == set(datasets.registry())


def test_fetch_from_the_data_folder_checks_the_hash(tmp_path, monkeypatch):
    walk = data_file("mocap/cmu-mb_02_01.bvh")
    good = tmp_path / "mocap" / "cmu-mb_02_01.bvh"
    good.parent.mkdir()
    shutil.copy(walk, good)
    monkeypatch.setenv("PINRECON_DATA", str(tmp_path))
    assert datasets.fetch("mocap/cmu-mb_02_01.bvh") == good
    data = bytearray(good.read_bytes())
    data[1000] ^= 1  # one bit
    good.write_bytes(bytes(data))
    with pytest.raises(DatasetError, match=r"does not match the registry's sha256.*corrupted"):
        datasets.fetch("mocap/cmu-mb_02_01.bvh")


def test_a_file_missing_from_the_data_folder_is_named_with_its_url(tmp_path, monkeypatch):
    monkeypatch.setenv("PINRECON_DATA", str(tmp_path))
    with pytest.raises(DatasetError) as info:
        datasets.fetch("mocap/cmu-mb_09_01.bvh")
    msg = str(info.value)
    assert "mocap/cmu-mb_09_01.bvh" in msg and "PINRECON_DATA" in msg
    assert "https://raw.githubusercontent.com/chrystianosaraujo/motion-viewer/" in msg
    assert "\n" not in msg


def test_offline_without_data_folder_fails_with_one_line(tmp_path):
    """No PINRECON_DATA, an empty cache and no network: the demo stops at once with one line
    naming the dataset, its URL and PINRECON_DATA (a subprocess whose proxy points nowhere)."""
    env = {k: v for k, v in os.environ.items() if k != "PINRECON_DATA"}
    env.update(PINRECON_CACHE=str(tmp_path / "cache"), HTTPS_PROXY="http://127.0.0.1:9",
               HTTP_PROXY="http://127.0.0.1:9", https_proxy="http://127.0.0.1:9", http_proxy="http://127.0.0.1:9")
    out = subprocess.run([sys.executable, "-m", "pinrecon.cli", "demo", "--out", str(tmp_path / "demo")],
                         capture_output=True, text=True, env=env, timeout=120, check=False)
    assert out.returncode == 2
    err = [line for line in out.stderr.splitlines() if line.startswith("pinrecon: error:")]
    assert len(err) == 1, out.stderr
    assert "mocap/cmu-mb_02_01.bvh" in err[0] and "PINRECON_DATA" in err[0] and "https://" in err[0]
    assert "Traceback" not in out.stderr
    assert not (tmp_path / "demo").exists()


def test_cache_holds_a_checked_download(tmp_path, monkeypatch):
    """A file already in the cache (as a download leaves it) is used after its hash check."""
    src = data_file("project-test-data/cmu-asf_01.asf")
    monkeypatch.delenv("PINRECON_DATA", raising=False)
    monkeypatch.setenv("PINRECON_CACHE", str(tmp_path))
    dst = tmp_path / "project-test-data" / "cmu-asf_01.asf"
    dst.parent.mkdir(parents=True)
    shutil.copy(src, dst)
    assert datasets.fetch("project-test-data/cmu-asf_01.asf") == dst
    dst.write_bytes(b"not an asf")
    with pytest.raises(DatasetError, match="corrupted"):
        datasets.fetch("project-test-data/cmu-asf_01.asf")


def test_names_clips_and_folders():
    assert "mocap/cmu-mb_05_02.bvh" in datasets.names("mocap/")
    assert len(datasets.names("cmu-iclone/")) == 62  # 61 clips and their index
    assert datasets.clip("walk") == data_file("mocap/cmu-mb_02_01.bvh")
    assert datasets.clip("cmu-mb_05_02.bvh") == data_file("mocap/cmu-mb_05_02.bvh")
    with pytest.raises(DatasetError, match="short names are"):
        datasets.clip("moonwalk")
    with pytest.raises(DatasetError, match="not a registered dataset file; did you mean mocap/cmu-mb_09_01.bvh"):
        datasets.fetch("cmu-mb_09_01.bvh")


def test_cmu_trial_as_published():
    asf, amc = datasets.cmu("01_01")
    assert asf.name.endswith(".asf") and amc.name.endswith(".amc")
    with pytest.raises(DatasetError, match="named like '02_01'"):
        datasets.cmu("walk")


def test_derived_detector_files_are_remade_by_the_tool(tmp_path):
    """The detector fixtures the project derives from real ones are what
    tools/make_derived_detectors.py writes from the registered sources, byte for byte."""
    src = tmp_path / "src"
    for name in datasets.names("project-test-data/detectors/"):
        rel = name[len("project-test-data/detectors/"):]
        if rel.split("/")[0] in ("pose2sim_halpe26", "spin_body25", "prohmr_body25"):
            (src / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(data_file(name), src / rel)
    out = tmp_path / "out"
    subprocess.run([sys.executable, str(REPO / "tools" / "make_derived_detectors.py"), str(src), str(out)], check=True)
    made = {p.relative_to(out).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest() for p in out.rglob("*") if p.is_file()}
    assert len(made) == 7
    reg = datasets.registry()
    for rel, digest in made.items():
        assert reg[f"project-test-data/detectors/{rel}"].sha256 == digest, rel
        assert reg[f"project-test-data/detectors/{rel}"].url is None
