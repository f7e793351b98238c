"""The acoustics package's layout: imports between its modules point one way (levels <- propagation <-
sources <- mix; the beds and filters never import the sources), and every re-exported name resolves."""
from __future__ import annotations

import ast
from pathlib import Path

import simulator.physics.acoustics as ac

PACKAGE = Path(ac.__file__).parent
PREFIX = "simulator.physics.acoustics."
# module -> the package modules it may import
ALLOWED = {
    "levels": set(),
    "signals": set(),
    "filters": set(),
    "propagation": {"levels"},
    "sources": {"levels", "signals", "propagation"},
    "ambience": {"levels", "signals"},
    "mix": {"levels", "sources", "ambience"},
}


def _imports(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        assert not (isinstance(node, ast.ImportFrom) and node.level), f"{path.name}: relative import"
        found |= {n[len(PREFIX):].split(".")[0] for n in names if n.startswith(PREFIX)}
    return found


def test_imports_inside_the_package_point_one_way():
    modules = {p.stem for p in PACKAGE.glob("*.py")} - {"__init__"}
    assert modules == set(ALLOWED)
    for name in modules:
        assert _imports(PACKAGE / f"{name}.py") <= ALLOWED[name], name


def test_every_reexported_name_resolves_once():
    assert len(ac.__all__) == len(set(ac.__all__))
    for name in ac.__all__:
        assert getattr(ac, name) is not None, name
