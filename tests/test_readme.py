"""Every command and code block of the README runs as written, against the data pinrecon
fetches (``PINRECON_DATA`` or the cache).

A block's kind is the HTML comment on the line before it (``<!-- readme-test: KIND -->``),
``fast`` when there is none:

* ``fast``: run in the test command;
* ``slow``: run with ``PINRECON_SLOW=1`` (``.ci/run``), skipped otherwise with the reason;
* ``expected-to-land COMMAND``: a command being built on another branch; skipped, loudly,
  while ``pinrecon COMMAND`` does not exist, and failed then with ``PINRECON_EXPECT_LANDED=1``;
* ``no-run (why)``: not run (a server that runs until stopped), the reason printed.

``pip install ".[EXTRAS]" && ...``: the package under test is already installed, so the
install is not repeated; the extras it names must exist in pyproject.toml. The line running
the test suite itself is not run inside it.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REPO

README = REPO / "README.md"
FENCE = re.compile(r"^```(\w+)\s*$")
KIND = re.compile(r"^<!--\s*readme-test:\s*(.+?)\s*-->\s*$")
PIP = re.compile(r'^pip install "\.\[([\w,]+)\]"\s*(?:&&\s*(.*))?$')
LONG = 1200  # seconds a slow block may take


def readme_blocks(text: str | None = None) -> list[dict]:
    """The README's fenced bash and python blocks: language, code, kind, line number."""
    lines = (README.read_text() if text is None else text).splitlines()
    out, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if m:
            j = i + 1
            while not lines[j].startswith("```"):
                j += 1
            prev = next((lines[k] for k in range(i - 1, -1, -1) if lines[k].strip()), "")
            k = KIND.match(prev)
            out.append({"lang": m.group(1), "code": "\n".join(lines[i + 1:j]), "kind": k.group(1) if k else "fast",
                        "line": i + 1})
            i = j
        i += 1
    return [b for b in out if b["lang"] in ("bash", "python")]


def _extras() -> set[str]:
    import tomllib

    return set(tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["optional-dependencies"])


def _commands() -> set[str]:
    from pinrecon.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    return set(sub.choices)


def _runnable_bash(code: str, landing: bool) -> str:
    """The block's lines with the install step dropped (its extras checked) and the test
    suite's own command left out."""
    known, lines = _extras(), []
    for line in code.splitlines():
        m = PIP.match(line.strip())
        if m:
            extras = set(m.group(1).split(","))
            missing = extras - known
            if missing and not landing:
                pytest.fail(f"README line {line!r}: no extra {sorted(missing)} in pyproject.toml")
            line = m.group(2) or ""
        if "python -m pytest" in line:
            continue  # the suite itself: this test is part of it
        lines.append(line)
    return "\n".join(lines)


def _env(tmp_path: Path) -> dict:
    """PATH with a ``pinrecon`` that runs this interpreter's pinrecon (the tree under test)."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir(exist_ok=True)
    shim = bin_dir / "pinrecon"
    shim.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m pinrecon.cli "$@"\n')
    shim.chmod(0o755)
    env = dict(os.environ)
    env["PATH"] = f"{bin_dir}{os.pathsep}{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO / "src"), env.get("PYTHONPATH", "")) if p)
    env.setdefault("OMP_NUM_THREADS", "1")
    env["MPLBACKEND"] = "Agg"
    return env


BLOCKS = readme_blocks()


def test_the_readme_is_short_and_has_no_history():
    text = README.read_text()
    assert len(text.splitlines()) <= 300
    # a hash has letters and digits (the CMU grant number EIA-0196217 is not one)
    assert not re.search(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b", text), "a commit hash"
    assert not re.search(r"\bissue\s+#?\d+", text, re.IGNORECASE), "an issue number"
    assert not re.search(r"\bbefore\b", text), "history ('before')"


def test_the_parser_reads_kinds():
    text = "a\n<!-- readme-test: slow -->\n```bash\necho 1\n```\n\n```python\nprint(2)\n```\n```text\nx\n```\n"
    got = readme_blocks(text)
    assert [(b["lang"], b["kind"], b["code"]) for b in got] == [("bash", "slow", "echo 1"), ("python", "fast", "print(2)")]


def test_every_readme_block_has_a_known_kind():
    for b in BLOCKS:
        assert b["kind"].split()[0] in ("fast", "slow", "expected-to-land", "no-run"), b


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """One folder for every block, in the README's order, as a user working through it."""
    return tmp_path_factory.mktemp("readme")


@pytest.mark.parametrize("block", BLOCKS, ids=[f"line{b['line']}-{b['kind'].split()[0]}" for b in BLOCKS])
def test_readme_block_runs_as_written(block, workdir):
    tmp_path = workdir
    kind = block["kind"].split()
    if kind[0] == "no-run":
        pytest.skip(f"README line {block['line']}: not run: {' '.join(kind[1:])}")
    if kind[0] == "slow" and os.environ.get("PINRECON_SLOW") != "1":
        pytest.skip(f"README line {block['line']}: a long block: set PINRECON_SLOW=1 to run it (.ci/run does)")
    landing = kind[0] == "expected-to-land"
    if landing:
        command = kind[1]
        if command not in _commands():
            why = (f"EXPECTED TO LAND: README line {block['line']} uses `pinrecon {command}`, which this tree does "
                   "not have yet")
            if os.environ.get("PINRECON_EXPECT_LANDED") == "1":
                pytest.fail(why)
            pytest.skip(why)
        if os.environ.get("PINRECON_SLOW") != "1":
            pytest.skip(f"README line {block['line']}: `pinrecon {command}` is long: set PINRECON_SLOW=1 to run it")
    env = _env(tmp_path)
    if block["lang"] == "bash":
        cmd = ["bash", "-euo", "pipefail", "-c", _runnable_bash(block["code"], landing)]
    else:
        cmd = [sys.executable, "-c", block["code"]]
    run = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=LONG)
    assert run.returncode == 0, f"README line {block['line']} failed:\n{run.stdout[-2000:]}\n{run.stderr[-4000:]}"
    assert "Traceback" not in run.stderr
