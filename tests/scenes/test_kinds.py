"""scenes.kinds is the one table of target kinds and drone sizes: the schema, the assets, the scene
sampler and acoustics agree with it, and no other module gives a drone kind a size of its own."""
from __future__ import annotations

import ast
from pathlib import Path
from typing import get_args

from scenes import assets
from scenes.kinds import DRONE_KINDS, DRONE_SIZE_M, TARGET_KINDS
from scenes.schema import TargetKind

ROOT = Path(__file__).resolve().parents[2]


def test_the_kind_lists_agree():
    assert TARGET_KINDS == get_args(TargetKind) == assets.KINDS
    assert set(DRONE_KINDS) <= set(TARGET_KINDS) and set(DRONE_SIZE_M) == set(DRONE_KINDS)
    assert DRONE_SIZE_M["hexacopter"] == 0.9


def test_acoustics_and_the_sampler_read_the_table():
    from simulator.dataset import config
    from simulator.physics import acoustics, rf

    assert acoustics._REFERENCE_SIZE_M is DRONE_SIZE_M
    assert acoustics.DRONE_KINDS is rf.DRONE_KINDS is config.DRONE_KINDS is DRONE_KINDS


def test_no_other_module_gives_a_drone_kind_a_size():
    """A dict literal mapping a drone kind to a number between 5 cm and 5 m (a size, not a level in
    dB or a temperature) anywhere but scenes/kinds.py is a second table of sizes."""
    found = []
    for pkg in ("scenes", "simulator", "evids", "harness", "degradations"):
        for path in sorted((ROOT / pkg).rglob("*.py")):
            if path == ROOT / "scenes" / "kinds.py":
                continue
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Dict):
                    for k, v in zip(node.keys, node.values):
                        if (isinstance(k, ast.Constant) and k.value in DRONE_KINDS and isinstance(v, ast.Constant)
                                and isinstance(v.value, float) and 0.05 <= v.value <= 5.0):
                            found.append(f"{path.relative_to(ROOT)}:{node.lineno} {k.value}={v.value}")
    assert found == []
