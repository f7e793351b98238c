"""Propagation: spherical spreading plus ISO 9613-1 absorption, and the ISO 9613-2 ground effect on a tone."""
from __future__ import annotations

import numpy as np
import pytest

from simulator.physics import acoustics as ac
from tests.simulator.physics.acoustics.helpers import FS


@pytest.mark.parametrize("freq_hz", [2000.0, 6000.0])
def test_level_falls_6db_per_doubling_plus_absorption(freq_hz):
    n = FS
    tone = np.sin(2 * np.pi * freq_hz * np.arange(n) / FS)
    levels = []
    for r in (300.0, 600.0):
        y = ac.propagate(tone, np.full(n, r), FS, 293.15, 0.7)
        levels.append(10 * np.log10(np.mean(y[FS // 4: -FS // 4] ** 2)))
    alpha = float(ac.iso9613_absorption_db_per_m(freq_hz, 293.15, 0.7))
    expected = 20 * np.log10(2.0) + alpha * 300.0
    assert alpha * 300.0 > 2.0                  # absorption matters at these ranges
    assert abs((levels[0] - levels[1]) - expected) < 0.05


def test_ground_effect_sign_and_size_on_a_tone():
    n = FS
    tone = np.sin(2 * np.pi * 500.0 * np.arange(n) / FS)
    kw = {"source_height_m": np.full(n, 50.0), "receiver_height_m": 1.5, "horizontal_range_m": np.full(n, 200.0)}
    free = ac.propagate(tone, np.full(n, 206.2), FS, 293.15, 0.7)
    hard = ac.propagate(tone, np.full(n, 206.2), FS, 293.15, 0.7, ground_factor=0.0, **kw)
    soft = ac.propagate(tone, np.full(n, 206.2), FS, 293.15, 0.7, ground_factor=1.0, **kw)
    lvl = {k: 10 * np.log10(np.mean(v[FS // 4: -FS // 4] ** 2))
           for k, v in (("free", free), ("hard", hard), ("soft", soft))}
    assert lvl["hard"] - lvl["free"] == pytest.approx(3.0, abs=0.05)          # reflection adds 3 dB
    expected_soft = -14.0 * np.exp(-0.46 * 2.25) * (1 - np.exp(-4.0))         # 500 Hz over porous ground
    assert lvl["soft"] - lvl["free"] == pytest.approx(expected_soft, abs=0.05)
    assert lvl["soft"] < lvl["free"] < lvl["hard"]
