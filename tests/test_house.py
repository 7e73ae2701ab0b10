"""The house stays livable: no import circle in src/pinrecon, no module importing another
module's private ``_name``, no source file over 700 lines, and the layers of
docs/architecture.md hold (nothing imports a layer above it).

The import graph is built from the source with ``ast`` (nothing is imported or run);
imports inside functions count too: a circle is a circle however late it closes.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PKG = SRC / "pinrecon"
MAX_LINES = 700


def _modules() -> dict[str, Path]:
    mods = {}
    for path in PKG.rglob("*.py"):
        rel = path.relative_to(SRC).with_suffix("")
        name = ".".join(rel.parts)
        if name.endswith(".__init__"):
            name = name[: -len(".__init__")]
        mods[name] = path
    return mods


MODS = _modules()


def _is_pkg(name: str) -> bool:
    return MODS[name].name == "__init__.py"


def _resolve(cur: str, level: int, module: str | None) -> str | None:
    if level == 0:
        return module
    base = cur.split(".") if _is_pkg(cur) else cur.split(".")[:-1]
    base = base[: len(base) - (level - 1)]
    return ".".join(base + ([module] if module else []))


def _imports(name: str) -> tuple[set[str], list[str]]:
    """Modules of the package that ``name`` imports, and the private names it takes."""
    tree = ast.parse(MODS[name].read_text())
    deps, private = set(), []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            tgt = _resolve(name, node.level, node.module)
            if not tgt or not tgt.startswith("pinrecon"):
                continue
            for alias in node.names:
                sub = f"{tgt}.{alias.name}"
                if sub in MODS:
                    deps.add(sub)
                elif tgt in MODS:
                    deps.add(tgt)
                    if alias.name.startswith("_") and not alias.name.startswith("__") and tgt != name:
                        private.append(f"{name} imports {tgt}.{alias.name}")
        elif isinstance(node, ast.Import):
            deps.update(a.name for a in node.names if a.name in MODS)
    # a package re-exporting its children, or a child importing its parent's face, is no circle
    deps = {d for d in deps if d != name and not (_is_pkg(name) and d.startswith(name + "."))}
    deps = {d for d in deps if not (_is_pkg(d) and name.startswith(d + "."))}
    return deps, private


GRAPH = {m: _imports(m)[0] for m in MODS}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return out


def test_the_checker_sees_a_circle():
    """The cycle finder itself: a made-up graph with one circle and one chain."""
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert _cycles(g) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_circle():
    assert _cycles(GRAPH) == []


def test_no_private_imports_across_modules():
    private = [p for m in MODS for p in _imports(m)[1]]
    assert private == []


@pytest.mark.parametrize("name", sorted(MODS))
def test_file_size(name):
    n = MODS[name].read_text().count("\n")
    assert n <= MAX_LINES, f"{MODS[name]} has {n} lines: it holds two ideas"


# The layers of docs/architecture.md, lowest first. A module may import its own layer and
# the layers below it, never one above.
LAYERS = [
    ("base", ["pinrecon.errors", "pinrecon.processes", "pinrecon._resources", "pinrecon.rotations", "pinrecon.io", "pinrecon.io.atomic",
              "pinrecon.io.jsonfile", "pinrecon.io.fields", "pinrecon.io.track_arrays", "pinrecon.kinematics", "pinrecon.datasets"]),
    ("domain", ["pinrecon.anatomy", "pinrecon.figure_files", "pinrecon.figure", "pinrecon.figure_bvh", "pinrecon.cameras", "pinrecon.floor", "pinrecon.tracks", "pinrecon.lifted", "pinrecon.lifter", "pinrecon.layouts",
                "pinrecon.proportions", "pinrecon.io.bvh_format", "pinrecon.io.bvh_urdf", "pinrecon.io.bvh",
                "pinrecon.io.coco", "pinrecon.io.openpose", "pinrecon.io.openpose_json", "pinrecon.io.mmpose",
                "pinrecon.io.people", "pinrecon.io.detections", "pinrecon.io.asf", "pinrecon.joint_limits",
                "pinrecon.io.tracks_json", "pinrecon.io.calibration", "pinrecon.io.results", "pinrecon.io.trc",
                "pinrecon.video", "pinrecon.io.amc", "pinrecon.io.lifters", "pinrecon.io.motion"]),
    ("rows and solver", ["pinrecon.rows", "pinrecon.weights", "pinrecon.banded", "pinrecon.solver"]),
    ("problem", ["pinrecon.views", "pinrecon.problem", "pinrecon.contact", "pinrecon.identifiability"]),
    ("starts", ["pinrecon.starts", "pinrecon.planarity"]),
    ("result", ["pinrecon.result"]),
    ("pipeline", ["pinrecon.reconstruct", "pinrecon.stages", "pinrecon.synthetic", "pinrecon.faults", "pinrecon.metrics",
                  "pinrecon.windowed", "pinrecon.unfamiliar", "pinrecon.prior_yield", "pinrecon.stability"]),
    ("exports and pictures", ["pinrecon.io.bvh_export", "pinrecon.io.csv_export", "pinrecon.viz"]),
    ("arguments and batches", ["pinrecon.arguments", "pinrecon.batch"]),
    ("applications", ["pinrecon.cli", "pinrecon.commands", "pinrecon.demo", "pinrecon.workbench", "pinrecon"]),
]


# these names stand for the package's __init__ alone, not for every module below it
EXACT = {"pinrecon", "pinrecon.io"}


def _layer(mod: str) -> int | None:
    best, best_len = None, -1
    for i, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            if (mod == p or (p not in EXACT and mod.startswith(p + "."))) and len(p) > best_len:
                best, best_len = i, len(p)
    return best


def test_every_module_has_a_layer():
    assert [m for m in MODS if _layer(m) is None] == []


def test_imports_point_down_the_layers():
    up = []
    for m, deps in GRAPH.items():
        for d in deps:
            if _layer(d) > _layer(m):
                up.append(f"{m} ({LAYERS[_layer(m)][0]}) imports {d} ({LAYERS[_layer(d)][0]})")
    assert up == []


def test_reconstruct_reads_as_a_list_of_stages():
    """``reconstruct()`` stays short (issue G3: under 60 lines, its docstring included): the
    stages it runs are listed in :data:`pinrecon.stages.STAGES`, not written out in it."""
    import inspect
    import sys

    import pinrecon  # noqa: F401 - the module, which the function of the same name shadows

    lines, _ = inspect.getsourcelines(sys.modules["pinrecon.reconstruct"].reconstruct)
    assert len(lines) < 60, f"reconstruct() has {len(lines)} lines"


def test_the_controller_imports_every_module_with_a_warning_category():
    """``pytest -n``'s controller imports the modules of pinrecon's warning categories first
    (``conftest.WARNING_MODULES``; rebuilding a worker's warning imports its category's module, in
    one thread per worker, and two at once deadlocked): every class that derives from a
    ``Warning`` is in one of them."""
    from conftest import WARNING_MODULES

    found = set()
    for name, path in MODS.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef) and any(
                    getattr(b, "id", getattr(b, "attr", "")).endswith("Warning") for b in node.bases):
                found.add(name)
    assert found and found <= set(WARNING_MODULES), sorted(found)
