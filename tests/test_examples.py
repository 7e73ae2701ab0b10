"""Every example runs as it is and prints what it says it shows.

Registry-driven: each ``examples/NN_*.py`` is found, checked for the shape every
example shares (docstring, ``__main__`` guard, ``--out`` and ``--quick``, a line in
``examples/README.md``) and run with ``--quick --out tmp_path`` in a subprocess.
Examples listed in ``CHECKS`` also get assertions on the numbers they print.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((REPO / "examples").glob("[0-9][0-9]_*.py"))
NUMBER = r"([-+]?\d+(?:\.\d+)?)"


def number(out: str, label: str) -> float:
    """The number printed right after ``label`` (a regular expression)."""
    m = re.search(label + r"\s*" + NUMBER, out)
    assert m, f"{label!r} not printed:\n{out}"
    return float(m.group(1))


def check_01(out):
    rows = dict(re.findall(r"^(\S.*?)\s+(?:[-+]\d\.\d+|keyed)\s+[-+]\d\.\d+\s+([AB?])$", out, re.M))
    assert rows["no constraint, start near B"] == "B"
    assert rows["no constraint, start near A"] == "A"  # the start decides
    assert rows["neighbours keyed, no smoothing"] == "A"
    constrained = ("joint limit", "smoothing over neighbours", "approximate keyframe", "confident keyframe")
    for case in constrained:
        (pose,) = [p for label, p in rows.items() if label.startswith(case)]
        assert pose == "B", (case, out)


def check_02(out):
    assert number(out, "mean per-joint error:") < 30.0
    assert number(out, "reprojection error:") < 2.0


def check_03(out):
    m = re.search(rf"total turn: clip {NUMBER} deg, reconstruction {NUMBER} deg", out)
    assert m and float(m.group(1)) > 600 and abs(float(m.group(2)) - float(m.group(1))) < 30, out
    assert number(out, "largest turn between keyframes:") < 180
    assert number(out, "mean per-joint error:") < 40.0


def check_04(out):
    assert re.search(r"at 30 fps -> result: \d+ frames at 120 fps", out), out
    assert number(out, r"mean per-joint error, all \d+ frames:") < 30.0
    assert number(out, "frames in between:") < 30.0


def check_05(out):
    rows = ("raw markers", "linear interpolation", "fitted figure")
    table = {
        label: [None if c == "n/a" else float(c) for c in cells.split()]
        for label, cells in re.findall(rf"^({'|'.join(rows)})\s+(.*)$", out, re.M)
    }
    (raw_out, raw_in), (_, lin_in), (fit_out, fit_in) = (table[k] for k in rows)
    assert raw_in is None  # nothing was measured in the gap
    assert fit_out < 0.6 * raw_out  # the fit smooths the noise
    assert fit_in < 50.0 and lin_in is not None


def check_06(out):
    for side in ("left", "right"):
        assert f"{side} leg: hinge = knee" in out, out
    errors_pct = re.findall(rf"(?:thigh|shank): [\d.]+ m, clip [\d.]+ m \({NUMBER} %\)", out)
    assert len(errors_pct) == 4 and all(abs(float(e)) < 5.0 for e in errors_pct), out
    assert "hinges:" in out and "links:" in out


#: example number -> checks of its printed numbers
CHECKS = {"01": check_01, "02": check_02, "03": check_03, "04": check_04, "05": check_05, "06": check_06}


def test_examples_are_found():
    assert len(EXAMPLES) >= 6
    assert set(CHECKS) <= {p.stem[:2] for p in EXAMPLES}, "a check whose example is gone"


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_shape(path):
    text = path.read_text()
    doc = ast.get_docstring(ast.parse(text))
    assert doc and "--quick" in doc, "the module docstring says what it shows and how to run it"
    assert 'if __name__ == "__main__":' in text
    assert '"--out"' in text and '"--quick"' in text
    assert len(text.splitlines()) <= 130
    readme = (REPO / "examples" / "README.md").read_text()
    assert f"`{path.name}`" in readme, "one line per example in examples/README.md"


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_runs(path, tmp_path):
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO / "src"), env.get("PYTHONPATH")]))
    out_dir = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, str(path), "--quick", "--out", str(out_dir)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    out = proc.stdout
    assert re.search(r"\d", out), "an example prints its numbers"
    for line in re.findall(r"^wrote (.+)$", out, re.M):
        for p in map(Path, line.split(" and ")):
            assert p.is_file() and p.stat().st_size > 0, p
            assert p.resolve().is_relative_to(out_dir.resolve()), f"{p} is outside --out"
    check = CHECKS.get(path.stem[:2])
    if check is not None:
        check(out)
