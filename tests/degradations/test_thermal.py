"""Thermal: crossover vs NETD, fixed pattern is static and columnar, AGC range compression."""
from __future__ import annotations

import numpy as np
import pytest

import degradations
from degradations.thermal import NETD_K, contrast_k, ring_masks
from tests.degradations.conftest import target_mask, thermal_clip


def _contrast(x):
    m = np.broadcast_to(target_mask(), x.shape)
    return contrast_k(x.astype(np.float64), m, ring_masks(m, 5))


def test_crossover_strength_one_leaves_contrast_below_netd():
    x = thermal_clip()
    assert np.all(np.abs(_contrast(x)) > 1.5)
    y = degradations.apply("thermal.crossover", x, seed=0, strength=1.0, meta={"thermal_mask": target_mask()})
    assert np.all(np.abs(_contrast(y)) < NETD_K)
    # background untouched
    assert np.array_equal(y[:, ~target_mask()], x[:, ~target_mask()])


@pytest.mark.parametrize("strength", [0.25, 0.5, 0.75])
def test_crossover_scales_contrast(strength):
    x = thermal_clip()
    y, info = degradations.apply("thermal.crossover", x, seed=0, strength=strength,
                                 meta={"thermal_mask": target_mask()}, return_info=True)
    np.testing.assert_allclose(_contrast(y), (1 - strength) * _contrast(x), atol=1e-3)
    np.testing.assert_allclose(info["contrast_k_after"], _contrast(y), atol=1e-6)


def test_crossover_rejects_bad_strength():
    with pytest.raises(ValueError, match="strength"):
        degradations.apply("thermal.crossover", thermal_clip(), seed=0, strength=1.5,
                           meta={"thermal_mask": target_mask()})


def test_netd_noise_std_in_kelvin():
    x = np.full((4, 64, 80), 290.0, np.float32)
    y = degradations.apply("thermal.netd_noise", x, seed=0, netd_k=0.05)
    assert np.std(y - x) == pytest.approx(0.05, rel=0.05)


def test_fixed_pattern_is_static_and_mostly_columnar():
    x = np.full((3, 64, 80), 300.0, np.float32)
    y = degradations.apply("thermal.fixed_pattern", x, seed=0, gain_std=0.0, offset_std_k=0.4)
    assert np.array_equal(y[0], y[1])
    d = y[0] - x[0]
    col_var = np.var(d.mean(axis=0))
    row_var = np.var(d.mean(axis=1))
    assert col_var > 2 * row_var
    # gain acts around ref_k: no effect there
    z = np.full((1, 8, 8), 293.15, np.float32)
    assert np.allclose(degradations.apply("thermal.fixed_pattern", z, seed=0, gain_std=0.08, offset_std_k=0.0), z,
                       atol=1e-4)


def test_agc_hot_object_compresses_range():
    x = thermal_clip()
    y = degradations.apply("thermal.agc_saturation", x, seed=0, hot_k=600.0)
    levels = np.unique(y[0][~np.isclose(y[0], y[0].max())])
    assert len(levels) < 5  # the 2 K target and 0.3 K texture collapse into a few 8-bit levels
    assert y.max() >= 600.0 - 1e-3


def test_quantize_8bit_level_count():
    y = degradations.apply("thermal.quantize_8bit", thermal_clip(), seed=0, bits=4)
    assert all(len(np.unique(f)) <= 16 for f in y)


def test_dead_pixels_fraction():
    x = thermal_clip()
    y = degradations.apply("thermal.dead_pixels", x, seed=0, fraction=0.01)
    assert np.mean(y[0] != x[0]) == pytest.approx(0.01, abs=0.004)
    assert np.array_equal(y[0] != x[0], y[1] != x[1])  # static positions
