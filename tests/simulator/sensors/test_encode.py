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


def test_rgb_to_srgb8_table_equals_the_curve_at_every_step_and_on_specials():
    from simulator.sensors.encode import _srgb8_curve, _srgb8_tables

    _, last_of_base = _srgb8_tables()
    bucket_last = (np.arange(1 << 16, dtype=np.int64) << 16) + 0xFFFF
    steps = last_of_base[last_of_base != bucket_last].astype(np.int64)
    assert len(steps) == 255                       # one step per code 1..255 within [0, 1]
    near = (steps[:, None] + np.arange(-3, 4)[None, :]).ravel().astype(np.uint32)
    edges = (np.arange(1 << 16, dtype=np.int64) << 16)
    edges = np.concatenate([edges, edges + 0xFFFF]).astype(np.uint32)
    with np.errstate(invalid="ignore"):
        for bits in (near, edges):
            x = bits.view(np.float32)
            assert np.array_equal(rgb_to_srgb8(x), _srgb8_curve(x))
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.uniform(-1.0, 2.0, 100_000), rng.uniform(0.0, 0.004, 100_000),
                        [np.inf, -np.inf, -0.0, 0.0, 1.0, 3e38, -3e38, 1e-45]]).astype(np.float32)
    assert np.array_equal(rgb_to_srgb8(x.reshape(-1, 1, 1)), _srgb8_curve(x.reshape(-1, 1, 1)))
    strided = rng.uniform(0.0, 1.0, (16, 20, 4)).astype(np.float32)[:, ::2, :3]   # not contiguous
    assert np.array_equal(rgb_to_srgb8(strided), _srgb8_curve(strided))
