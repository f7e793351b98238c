"""scenes.kinds is the one table of target kinds, drone sizes and size spans: the schema, the assets,
the scene samplers and acoustics agree with it, and no other module gives a drone kind a size or a
size span of its own."""
from __future__ import annotations

import ast
from pathlib import Path
from typing import get_args

from scenes import assets
from scenes.kinds import DISTRACTOR_KINDS, DRONE_KINDS, DRONE_SIZE_M, TARGET_KINDS, TARGET_SIZE_RANGE_M
from scenes.schema import TargetKind

ROOT = Path(__file__).resolve().parents[2]


def test_the_kind_lists_agree():
    assert TARGET_KINDS == get_args(TargetKind) == assets.KINDS
    assert set(DRONE_KINDS) <= set(TARGET_KINDS) and set(DRONE_SIZE_M) == set(DRONE_KINDS)
    assert DRONE_SIZE_M["hexacopter"] == 0.9


def test_acoustics_and_the_sampler_read_the_table():
    from scenes import sampling
    from simulator.dataset import config, trident
    from simulator.physics import rf
    from simulator.physics.acoustics import sources as acoustics

    assert acoustics._REFERENCE_SIZE_M is DRONE_SIZE_M
    assert acoustics.DRONE_KINDS is rf.DRONE_KINDS is config.DRONE_KINDS is trident.DRONE_KINDS is DRONE_KINDS
    assert sampling.TARGET_SIZE_RANGE_M is TARGET_SIZE_RANGE_M and config.DRONE_SIZE_M is DRONE_SIZE_M
    assert DISTRACTOR_KINDS == ("bird", "airliner", "helicopter")


def _is_size(x: ast.expr) -> bool:
    """A float constant between 5 cm and 5 m (a size, not a level in dB or a temperature)."""
    return isinstance(x, ast.Constant) and isinstance(x.value, float) and 0.05 <= x.value <= 5.0


def _is_size_span(x: ast.expr) -> bool:
    """A (low, high) pair of sizes."""
    return isinstance(x, (ast.Tuple, ast.List)) and len(x.elts) == 2 and all(_is_size(e) for e in x.elts)


def _size_entries(tree: ast.AST) -> list[tuple[int, str, ast.expr]]:
    """(line, kind, value) of every drone-kind entry that gives a size: in any dict literal a size; in a
    dict literal bound to a name with "size" in it (``X_SIZE_M = {...}``, a ``drone_size_m`` field) also a
    size span (a mass reference such as acoustics' (0.45 m, 0.75 kg) is not a span)."""
    spans = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and isinstance(node.value, ast.Dict):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names = [t.id if isinstance(t, ast.Name) else t.attr if isinstance(t, ast.Attribute) else ""
                     for t in targets]
            if any("size" in n.lower() for n in names):
                spans.add(id(node.value))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Dict):
            for k, v in zip(node.keys, node.values):
                if isinstance(k, ast.Constant) and k.value in DRONE_KINDS and (
                        _is_size(v) or (id(node) in spans and _is_size_span(v))):
                    found.append((node.lineno, k.value, v))
    return found


def test_no_other_module_gives_a_drone_kind_a_size():
    """A drone kind given a size (or, in a size table, a size span) anywhere but scenes/kinds.py is a
    second table of sizes."""
    found = []
    for pkg in ("scenes", "simulator", "evids", "harness", "degradations"):
        for path in sorted((ROOT / pkg).rglob("*.py")):
            if path == ROOT / "scenes" / "kinds.py":
                continue
            for line, kind, value in _size_entries(ast.parse(path.read_text())):
                found.append(f"{path.relative_to(ROOT)}:{line} {kind}={ast.unparse(value)}")
    assert found == []


def test_the_size_check_finds_a_span_table():
    """The scan above catches the span tables TRIDENT and the sim2real audio config had, and a size."""
    for source in ('_DRONE_SIZE_M = {"quadcopter": (0.3, 0.6), "hexacopter": (0.6, 1.1)}',
                   'drone_size_m: dict = {"quadcopter": (0.12, 0.5)}', 'x = f({"hexacopter": 0.9})'):
        assert _size_entries(ast.parse(source)), source
    for source in ('_MASS_REFERENCE = {"quadcopter": (0.45, 0.75)}', 'LEVEL_SIZE_DB = {"quadcopter": (72.0, 80.0)}'):
        assert not _size_entries(ast.parse(source)), source
