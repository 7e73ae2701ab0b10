"""Regenerate the README's pictures from `pinrecon demo`.

    python docs/make_images.py

runs the demo into a temporary folder and copies its figure-9-style joint-angle plot and
its stick-figure strip into docs/images/.
"""

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

here = Path(__file__).resolve().parent
with tempfile.TemporaryDirectory() as tmp:
    subprocess.run([sys.executable, "-m", "pinrecon.cli", "demo", "--out", tmp, "--quiet"], check=True)
    (here / "images").mkdir(exist_ok=True)
    for name in ("joint_angles.png", "stick_strip.png"):
        shutil.copy(Path(tmp) / name, here / "images" / f"demo_{name}")
        print(here / "images" / f"demo_{name}")
