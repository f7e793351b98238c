"""The layout stays true: every import between our packages points down the layer order of
docs/ARCHITECTURE.md (lazy imports inside functions included), and no two layers import each other."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("scenes", "simulator", "degradations", "evids", "harness")

# Layer -> the layers it may import (besides itself). Order of the docs' data-flow picture.
ALLOWED: dict[str, set[str]] = {
    "scenes": set(),
    "degradations": {"scenes"},   # only scenes.errors / scenes.yaml_safe (bounded YAML), lazily
    "simulator.seeding": {"scenes"},
    "simulator.files": {"scenes"},
    "simulator.jobs": {"scenes", "simulator.files"},  # the one executor (process pools, Ray); files: pid_running
    "simulator.physics": {"scenes", "simulator.seeding", "simulator.files"},  # files: the LOWTRAN table script
    "simulator.sensors": {"scenes", "simulator.seeding", "simulator.physics"},
    "simulator.render": {"scenes", "simulator.seeding", "simulator.physics", "simulator.sensors"},
    "simulator.formats": {"scenes", "simulator.seeding", "simulator.files", "simulator.physics", "simulator.sensors"},
    "simulator.dataset": {"scenes", "degradations", "simulator.seeding", "simulator.files", "simulator.jobs",
                          "simulator.physics",
                          "simulator.sensors", "simulator.render", "simulator.formats"},
    "simulator": set(),
    "evids": {"scenes"},
    "harness.runfolder": {"scenes", "simulator.files", "evids"},
    "harness.report": {"scenes", "simulator.files", "evids", "harness.runfolder"},
    "harness.experiments": {"scenes", "degradations", "simulator.seeding", "simulator.files", "simulator.jobs",
                            "simulator.physics",
                            "simulator.sensors", "simulator.formats", "simulator.dataset", "evids",
                            "harness.runfolder", "harness.report"},
    "harness.cli": {"scenes", "degradations", "simulator.seeding", "simulator.files", "simulator.jobs",
                    "simulator.physics",
                    "simulator.sensors", "simulator.render", "simulator.formats", "simulator.dataset", "evids",
                    "harness.runfolder", "harness.report", "harness.experiments"},
    "harness": set(),
}


def layer_of(module: str) -> str:
    parts = module.split(".")
    top = parts[0]
    if top in ("scenes", "degradations"):
        return top
    if top == "simulator":
        return "simulator" if len(parts) == 1 else f"simulator.{parts[1]}"
    if top == "evids":  # the evidential library: one layer, below the product
        return "evids"
    if top == "harness":  # the product: harnesses, report, run folders, the CLI
        return "harness" if len(parts) == 1 else f"harness.{parts[1]}"
    raise ValueError(module)


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def our_imports(path: Path, source: str | None = None, me: str | None = None) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text() if source is None else source, filename=str(path))
    me = me or module_name(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                names = [".".join(base + ([node.module] if node.module else []))]
            else:
                names = [node.module or ""]
            # `from simulator import physics` imports the sub-package physics
            names = [f"{n}.{a.name}" if n in PACKAGES or n == "simulator" else n for n in names for a in node.names]
        else:
            continue
        found += [(node.lineno, n) for n in names if n.split(".")[0] in PACKAGES]
    return found


def package_files() -> list[Path]:
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


def test_every_layer_is_known():
    for path in package_files():
        assert layer_of(module_name(path)) in ALLOWED, path


def violations(path: Path, source: str | None = None, me: str | None = None) -> list[str]:
    mine = layer_of(me or module_name(path))
    bad = []
    for lineno, target in our_imports(path, source, me):
        theirs = layer_of(target)
        if theirs != mine and theirs not in ALLOWED[mine]:
            bad.append(f"{path.name}:{lineno} imports {target} ({mine} -> {theirs})")
    return bad


@pytest.mark.parametrize("path", package_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_point_down(path: Path):
    bad = violations(path)
    assert not bad, "upward or sideways imports:\n" + "\n".join(bad)


def test_no_cycles_between_layers():
    edges = {(layer_of(module_name(p)), layer_of(t)) for p in package_files() for _, t in our_imports(p)}
    cycles = sorted((a, b) for a, b in edges if a < b and (b, a) in edges)
    assert not cycles, f"layers importing each other: {cycles}"


def test_the_checker_catches_upward_imports():
    """The rules bite: each of these (lazy, relative or plain) is refused; a downward import passes."""
    cases = {
        ("scenes.loader", "scenes/loader.py"): "from evids.errors import UserInputError\n",
        ("harness.report.html",
         "harness/report/html.py"): "def f():\n    from harness.experiments.runner import write_json\n",
        ("simulator.formats.native", "simulator/formats/native.py"): "from ..render import renderer\n",
        ("simulator.physics.sky", "simulator/physics/sky.py"): "from simulator import dataset\n",
        ("degradations.video", "degradations/video.py"): "import simulator.formats.native\n",
        # the library never reaches up into the product around it
        ("evids.fusion", "evids/fusion.py"): "def f():\n    from harness.runfolder import create_run_folder\n",
        ("evids.metrics.calibration", "evids/metrics/calibration.py"): "import harness.report\n",
    }
    for (me, rel), source in cases.items():
        assert violations(ROOT / rel, source, me), (me, source)
    assert not violations(ROOT / "simulator/dataset/sequence.py", "from simulator.render.labels import x\n",
                          "simulator.dataset.sequence")
