"""simulator.seeding: every random stream id is registered once in STREAMS, and no code draws from
an unregistered stream (an rng_for name that is not there, or a literal id in SeedSequence([seed, id]))."""
from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

from simulator.seeding import STREAMS, rng_for

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("scenes", "simulator", "evids", "harness", "degradations")


def _calls(name: str):
    """(where, call node) of every call of ``name`` (a plain or attribute call) in our packages."""
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
                if isinstance(node, ast.Call):
                    f = node.func
                    called = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)
                    if called == name:
                        yield f"{path.relative_to(ROOT)}:{node.lineno}", node


def test_stream_ids_are_unique_integers():
    ids = list(STREAMS.values())
    assert all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in ids)
    assert len(set(ids)) == len(ids), f"duplicate stream ids: {STREAMS}"


def test_every_rng_for_stream_name_is_registered():
    names = [(where, call.args[1].value) for where, call in _calls("rng_for")
             if len(call.args) > 1 and isinstance(call.args[1], ast.Constant)]
    assert names, "the scan found no rng_for call: it is looking in the wrong place"
    assert [(w, n) for w, n in names if n not in STREAMS] == []


def test_no_seed_sequence_uses_a_literal_stream_id():
    """SeedSequence([seed, <id>, ...]) takes its id from STREAMS, never from a number at the call."""
    found, literal = 0, []
    for where, call in _calls("SeedSequence"):
        if where.startswith("simulator/seeding.py") or not call.args or not isinstance(call.args[0], ast.List):
            continue
        found += 1
        items = call.args[0].elts
        if len(items) > 1 and isinstance(items[1], ast.Constant) and isinstance(items[1].value, int):
            literal.append(where)
    assert found, "the scan found no SeedSequence call: it is looking in the wrong place"
    assert literal == []


def test_registered_ids_kept_the_values_their_outputs_were_made_with():
    """Moving a literal id into STREAMS must not change it (every seeded output would change)."""
    assert (STREAMS["fusion_init"], STREAMS["detection"], STREAMS["clip_split"]) == (99, 1600, 0x5B117)
    a = rng_for(7, "detection", 3).integers(0, 2**31)
    b = np.random.default_rng(np.random.SeedSequence([7, 1600, 3])).integers(0, 2**31)
    assert a == b
