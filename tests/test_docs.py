"""The docs site: mkdocs.yml's pages exist, and the API reference covers every public name
(pinrecon.__all__ and every public module, a package's modules through its own entry).
``mkdocs build --strict`` itself runs in .ci/run."""

from __future__ import annotations

import pkgutil
import re

import pinrecon
from conftest import REPO

DOCS = REPO / "docs"


def _directives() -> set[str]:
    return {m for p in (DOCS / "reference").glob("*.md") for m in re.findall(r"^::: ([\w.]+)", p.read_text(), re.M)}


def test_every_page_in_the_nav_exists():
    nav = re.findall(r":\s*([\w/.-]+\.md)\s*$", (REPO / "mkdocs.yml").read_text(), re.M)
    assert nav and [p for p in nav if not (DOCS / p).is_file()] == []


def test_the_reference_lists_every_name_of_pinrecon_all():
    text = (DOCS / "reference" / "pinrecon.md").read_text()
    listed = set(re.findall(r"^\s+- (\w+)$", text, re.M))
    assert set(pinrecon.__all__) <= listed


def test_the_reference_covers_every_public_module():
    shown = _directives() - {"pinrecon"}  # the package page lists pinrecon.__all__, not its modules
    public = [m.name for m in pkgutil.walk_packages(pinrecon.__path__, "pinrecon.")
              if not any(part.startswith("_") for part in m.name.split("."))]
    # a package's entry shows its modules (show_submodules in mkdocs.yml)
    missing = [m for m in public if not any(m == s or m.startswith(s + ".") for s in shown)]
    assert missing == []
