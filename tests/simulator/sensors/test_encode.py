"""Sensor encodings against their references."""
import numpy as np
import pytest

from simulator.sensors.encode import rgb_to_srgb8


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_rgb_to_srgb8_equals_colour_science_cctf_encoding(dtype):
    import colour

    rng = np.random.default_rng(0)
    rgb = np.concatenate([rng.uniform(-0.1, 1.2, 30_000), rng.uniform(0.0, 0.01, 10_000),
                          [0.0, 0.0031308, 0.00313, 0.0031309, 1.0, 1.5, -2.0]]).astype(dtype).reshape(-1, 1, 1)
    rgb = np.repeat(rgb, 3, axis=-1)
    expected = np.rint(np.asarray(colour.cctf_encoding(np.clip(rgb, 0.0, 1.0), function="sRGB")) * 255.0)
    out = rgb_to_srgb8(rgb)
    assert out.dtype == np.uint8 and out.shape == rgb.shape
    assert np.array_equal(out, expected.astype(np.uint8))
