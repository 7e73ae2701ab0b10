"""Write ``src/pinrecon/datasets/registry.txt`` from a local data folder.

Each line is ``name sha256 url``: ``name`` is the file's path inside the folder (the folder is
laid out like the project's shared data), ``url`` the file's upstream address at a pinned commit
(``-`` where the file has none: a transcription or a file derived by the project's scripts,
available from ``PINRECON_DATA`` only). Run from the repository root::

    python tools/make_registry.py /path/to/shared/data

Sources and commits are the ones each folder's SOURCES.md gives.
"""

from __future__ import annotations

import argparse
import hashlib
import re
import sys
from pathlib import Path
from urllib.parse import quote

GH = "https://raw.githubusercontent.com"
POSE2SIM = f"{GH}/perfanalytics/pose2sim/a948c205cfe4ea5c22d6941929e8efaba591a59d/Pose2Sim"
BALANCING = f"{POSE2SIM}/S00_Demo_Session/S00_P00_SingleParticipant/S00_P00_T01_BalancingTrial"
FAIRMOTION = f"{GH}/facebookresearch/fairmotion/e400e564deac93bb74ffecd9c366d76b3406e217/tests/data"
MOTION_VIEWER = f"{GH}/chrystianosaraujo/motion-viewer/6d7ca60c300f123528be0fd0939cf7a584a13f65/data"
BVH11 = f"{GH}/yuki-koyama/bvh11/c9072174fe89e0bf9776a092179b464ea39975e5/resources"
ICLONE = f"{GH}/DragonForgedTheArtist/IClone-CMU-Mocap/79529f962ade3274163af53cd92179cee2ed9407"
MMPOSE = f"{GH}/open-mmlab/mmpose/759b39c13fea6ba094afc1fa932f51dc1b11cbf9/tests/data"

# (regular expression on the name, function of the match giving the URL)
RULES = [
    (r"mocap/cmu-mb_(\d\d)_(\d\d)\.bvh", lambda m: f"{MOTION_VIEWER}/{m[1]}/{m[1]}_{m[2]}.bvh"),
    (r"(mocap|project-test-data)/cmu-max_131_03\.bvh", lambda m: f"{BVH11}/131_03.bvh"),
    (r"(mocap|project-test-data)/cmu-asf_01\.asf", lambda m: f"{FAIRMOTION}/01.asf"),
    (r"mocap/cmu-asf_01_01\.amc", lambda m: f"{FAIRMOTION}/01_01.amc"),
    (r"cmu-iclone/(\d{3})_(\d\d)\.bvh", lambda m: f"{ICLONE}/All_BVH/subjects/{m[1]}/{m[1]}_{m[2]}.bvh"),
    (r"cmu-iclone/cmu_index\.csv", lambda m: f"{ICLONE}/{quote('CMU data.csv')}"),
    (r"pose2sim-balancing/calibration/(.+)", lambda m: f"{POSE2SIM}/S00_Demo_Session/S00_Calibration/{m[1]}"),
    (r"pose2sim-balancing/LICENSE", lambda m: f"{GH}/perfanalytics/pose2sim/a948c205cfe4ea5c22d6941929e8efaba591a59d/LICENSE"),
    (r"pose2sim-balancing/(.+)", lambda m: f"{BALANCING}/{m[1]}"),
    (r"project-test-data/calibration/pose2sim/Calib_scene\.toml",
     lambda m: f"{GH}/perfanalytics/pose2sim/eca02292824733f9dcd17b99d0e8723d1c23190c/Pose2Sim/Demo_SinglePerson/calibration/Calib_scene.toml"),
    (r"project-test-data/calibration/pose2sim/static_trial/(S00_P00_T00_StaticTrial_0-12\.trc)",
     lambda m: f"{POSE2SIM}/S00_Demo_Session/S00_P00_SingleParticipant/S00_P00_T00_StaticTrial/pose-3d/{m[1]}"),
    (r"project-test-data/calibration/pose2sim/static_trial/Static_cam_0(\d)\.00000\.json",
     lambda m: f"{POSE2SIM}/S00_Demo_Session/S00_P00_SingleParticipant/S00_P00_T00_StaticTrial/pose/cam0{m[1]}_json/Static_cam_0{m[1]}.00000.json"),
    (r"project-test-data/calibration/pose2sim/(Calib_qualisys\.toml|Calib\.qca\.txt)",
     lambda m: f"{POSE2SIM}/S00_Demo_Session/S00_Calibration/{m[1]}"),
    (r"project-test-data/calibration/sports2d/Calib_demo\.toml",
     lambda m: f"{GH}/davidpagnon/Sports2D/158e5e2d1eb2675c81c31f39a8708b5ab3efd6f6/Sports2D/Demo/Calib_demo.toml"),
    (r"project-test-data/calibration/opencv/out_camera_data\.yml",
     lambda m: f"{GH}/opencv/opencv/061729292049567c28bc9a2b8bcbe662a1b52614/samples/cpp/tutorial_code/calib3d/camera_calibration/out_camera_data.yml"),
    (r"project-test-data/calibration/opencv/tutorial_camera_charuco\.yml",
     lambda m: f"{GH}/opencv/opencv/10afafbf8b533e0d2ab18b1181aab3545437faae/samples/data/aruco/tutorial_camera_charuco.yml"),
    (r"project-test-data/detectors/pose2sim_body25b_multi/(.+)",
     lambda m: f"{POSE2SIM}/S00_Demo_Session/S00_P01_MultiParticipants/S00_P01_T02_Participants1-2/pose/cam01_json/{m[1]}"),
    (r"project-test-data/detectors/pose2sim_halpe26/(.+)",
     lambda m: f"{GH}/perfanalytics/pose2sim/ae80676f107d8317f6510ee993316014b5a6e810/Pose2Sim/S00_Demo_BatchSession/S00_P00_SingleParticipant/S00_P00_T01_BalancingTrial/pose/cam03/{m[1]}"),
    (r"project-test-data/detectors/spin_body25/im1010_openpose\.json",
     lambda m: f"{GH}/nkolot/SPIN/277892a91e74af004c74457cd294bd102972f9b0/examples/im1010_openpose.json"),
    (r"project-test-data/detectors/prohmr_body25/(.+)",
     lambda m: f"{GH}/nkolot/ProHMR/3b1a9926f97ba1c77f1cb97151da2a59d2f16d11/example_data/keypoints/{m[1]}"),
    (r"project-test-data/detectors/mmpose_coco17_dataset\.json", lambda m: f"{MMPOSE}/coco/test_coco.json"),
    (r"project-test-data/detectors/mmpose_coco_person_boxes\.json", lambda m: f"{MMPOSE}/coco/test_coco_det_AP_H_56.json"),
    (r"project-test-data/detectors/mmpose_halpe136_dataset\.json", lambda m: f"{MMPOSE}/halpe/test_halpe.json"),
    (r"project-test-data/detectors/mmpose_crowdpose14_dataset\.json", lambda m: f"{MMPOSE}/crowdpose/test_crowdpose.json"),
    (r"project-test-data/detectors/cocoapi_fakekeypoints100_results\.json",
     lambda m: f"{GH}/cocodataset/cocoapi/8c9bcc3cf640524c4c20a9c40e89cb6a2f2fa0e9/results/person_keypoints_val2014_fakekeypoints100_results.json"),
]
SKIP = {"SOURCES.md", "README.md"}


def url_for(name: str) -> str:
    for pattern, url in RULES:
        m = re.fullmatch(pattern, name)
        if m:
            return url(m)
    return "-"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder", type=Path)
    ap.add_argument("--out", type=Path, default=Path("src/pinrecon/datasets/registry.txt"))
    a = ap.parse_args(argv)
    lines = []
    for path in sorted(p for p in a.folder.rglob("*") if p.is_file() and p.name not in SKIP):
        name = path.relative_to(a.folder).as_posix()
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        lines.append(f"{name} {digest} {url_for(name)}")
    a.out.write_text(
        "# pinrecon's third-party data: name (path in a PINRECON_DATA folder), sha256, upstream URL\n"
        "# ('-': no upstream file; PINRECON_DATA only). Written by tools/make_registry.py.\n"
        + "\n".join(lines) + "\n"
    )
    print(f"{len(lines)} files, {sum(1 for l in lines if l.endswith(' -'))} without a URL -> {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
