"""Generic properties of EVERY registered degradation, driven by a per-name case table.

The guard test fails when a registered name has no case here (or a case names nothing).
"""
from __future__ import annotations

import math
import random
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import pytest
import torch

import degradations
from degradations import REGISTRY, DegradationError
from tests.degradations.conftest import (
    SR,
    audio,
    iq,
    moving_clip,
    rgb_clip,
    spec_db,
    target_mask,
    thermal_clip,
)


def _psnr_rgb(x, y):
    mse = np.mean((x.astype(np.float64) - y.astype(np.float64)) ** 2)
    return 200.0 if mse == 0 else 10 * math.log10(255.0**2 / mse)


def _neg_mse(x, y):
    return -float(np.mean(np.abs(x.astype(np.complex128) - y.astype(np.complex128)) ** 2))


def _si_snr(x, y):
    """Scale-invariant SNR (complex-safe): y projected on x; the rest is distortion."""
    x = x.astype(np.complex128)
    y = y.astype(np.complex128)
    a = np.vdot(x, y) / np.vdot(x, x)
    e = y - a * x
    pe = np.mean(np.abs(e) ** 2)
    return 200.0 if pe == 0 else min(200.0, 10 * math.log10(np.mean(np.abs(a * x) ** 2) / pe))


def _neg_freq_error(x, y):
    """Minus the mean frequency error (cycles/sample) of y relative to x, from lag-1 phase increments."""
    z = y.astype(np.complex128) * np.conj(x.astype(np.complex128))
    return -abs(float(np.angle(np.sum(z[1:] * np.conj(z[:-1])))) / (2 * np.pi))


@dataclass
class Case:
    make: Callable[[], np.ndarray]
    metric: Callable[[np.ndarray, np.ndarray], float] | None  # quality: must fall with severity
    meta: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)
    random: bool = True
    why_not_monotonic: str = ""
    n_seeds: int = 1  # severity ordering averaged over this many seeds


MASK = target_mask()
BG = np.random.default_rng(9).normal(size=3000).astype(np.float32)
AMETA = {"sample_rate_hz": SR}
V = dict(make=rgb_clip, metric=_psnr_rgb)
TH = dict(make=thermal_clip, metric=_neg_mse, meta={"thermal_mask": MASK})
AU = dict(make=audio, metric=_si_snr, meta=AMETA)
IQ = dict(make=iq, metric=_si_snr, meta={"sample_rate_hz": 1e6})
SP = dict(make=spec_db, metric=_neg_mse)

CASES: dict[str, Case] = {
    "audio.white_noise": Case(**AU),
    "audio.pink_noise": Case(**AU),
    "audio.brown_noise": Case(**AU),
    "audio.preset_white_10db": Case(**{**AU, "metric": None}, why_not_monotonic="fixed 10 dB protocol"),
    "audio.preset_library_default": Case(**{**AU, "metric": None}, params={"p": 1.0},
                                         why_not_monotonic="SNR drawn U(5, 40) dB, severity only switches it on"),
    "audio.background": Case(make=audio, metric=_si_snr, meta={**AMETA, "background": BG}),
    "audio.wind": Case(**AU),
    "audio.gain_clip": Case(**AU, random=False),
    "audio.bandlimit": Case(**AU, random=False),
    "audio.dropout": Case(**AU),
    "video.gaussian_noise": Case(**V),
    "video.shot_noise": Case(**V),
    "video.impulse_noise": Case(**V),
    "video.motion_blur": Case(**V),
    "video.defocus_blur": Case(**V, random=False),
    "video.low_light": Case(**V),
    "video.fog": Case(**V, random=False),
    "video.smoke": Case(**V),
    "video.rain": Case(**V),
    "video.jpeg": Case(**V, random=False),
    "video.block_compression": Case(**V, random=False),
    "video.resolution_drop": Case(**V, random=False),
    "video.frame_drop": Case(**V),
    "video.frame_freeze": Case(**V),
    "video.sun_glare": Case(**V),
    "video.lens_dirt": Case(**V),
    "video.decoy_bird": Case(**V),
    "thermal.crossover": Case(**TH, random=False),
    "thermal.netd_noise": Case(**TH),
    "thermal.fixed_pattern": Case(**TH),
    "thermal.dead_pixels": Case(**TH),
    "thermal.agc_saturation": Case(**TH),
    "thermal.blur_halo": Case(**TH, random=False),
    "thermal.quantize_8bit": Case(**TH, random=False),
    "thermal.decoy_bird": Case(**TH),
    "rf.awgn": Case(**IQ),
    "rf.wifi_burst": Case(**IQ),
    "rf.freq_offset": Case(**{**IQ, "metric": _neg_freq_error}),
    "rf.fading": Case(**IQ),
    "rf.iq_imbalance": Case(**IQ, random=False),
    "rf.adc": Case(**IQ, random=False),
    "rf.link_silence": Case(**IQ),
    "rf.spec_pink_noise": Case(**SP),
    "rf.spec_time_mask": Case(**SP),
    "rf.spec_freq_mask": Case(**SP),
    "rf.spec_interference": Case(**SP),
    "rf.spec_link_silence": Case(**SP, random=False),
    "crossmodal.dropout": Case(**V, random=False, why_not_monotonic="binary: any severity > 0 removes the stream"),
    "crossmodal.desync": Case(**{**V, "meta": {"fps": 30.0}}),
    "crossmodal.misalignment": Case(**{**V, "params": {"stream": "rgb"}}),
    "crossmodal.frame_rate_mismatch": Case(**V),
}
# crossmodal.dropout has no quality ordering
CASES["crossmodal.dropout"].metric = None
# retiming needs a clip where showing the wrong frame errs in proportion to the time error
CASES["crossmodal.desync"].make = moving_clip
CASES["crossmodal.frame_rate_mismatch"].make = moving_clip
# block fading is random per seed (a Rayleigh draw can beat a Rician one): monotonic on average
CASES["rf.fading"].n_seeds = 24

NAMES = sorted(REGISTRY)


def run(name, x, seed=0, severity=3.0, **kw):
    c = CASES[name]
    return degradations.apply(name, x, seed=seed, severity=severity, meta=c.meta, **{**c.params, **kw})


def test_registry_guard_every_name_has_a_case():
    assert sorted(CASES) == NAMES, (
        f"missing cases: {sorted(set(REGISTRY) - set(CASES))}; stale: {sorted(set(CASES) - set(REGISTRY))}")


def test_names_are_namespaced():
    for name in NAMES:
        assert name.split(".")[0] in {"audio", "video", "thermal", "rf", "crossmodal"}, name


@pytest.mark.parametrize("name", NAMES)
def test_same_seed_identical_and_shape_dtype_kept(name):
    x = CASES[name].make()
    a, b = run(name, x, seed=7), run(name, x, seed=7)
    assert a.shape == x.shape and a.dtype == x.dtype
    assert np.array_equal(a, b, equal_nan=True)


@pytest.mark.parametrize("name", [n for n in NAMES if CASES[n].random])
def test_different_seed_differs(name):
    x = CASES[name].make()
    a = run(name, x, seed=0)
    assert any(not np.array_equal(a, run(name, x, seed=s)) for s in range(1, 6))


@pytest.mark.parametrize("name", [n for n in NAMES if not CASES[n].random])
def test_deterministic_ones_ignore_seed(name):
    x = CASES[name].make()
    assert np.array_equal(run(name, x, seed=0), run(name, x, seed=123))


@pytest.mark.parametrize("name", NAMES)
def test_severity_zero_is_identity_and_params_json(name):
    import json
    x = CASES[name].make()
    y, info = run(name, x, severity=0.0, return_info=True)
    assert np.array_equal(y, x)
    _, info = run(name, x, severity=2.5, return_info=True)
    json.dumps(info["params"])  # params are JSON-serialisable


@pytest.mark.parametrize("name", [n for n in NAMES if CASES[n].metric is not None])
def test_severity_monotonic(name):
    c = CASES[name]
    x = c.make()
    q = [float(np.mean([c.metric(x, run(name, x, seed=11 + k, severity=s)) for k in range(c.n_seeds)]))
         for s in (1, 2, 3, 4, 5)]
    for lo, hi in zip(q, q[1:]):
        assert hi <= lo + 1e-6 * max(1.0, abs(lo)), (name, q)
    assert q[-1] < q[0], (name, q)


@pytest.mark.parametrize("name", NAMES)
def test_torch_roundtrip_matches_numpy(name):
    x = CASES[name].make()
    t = torch.from_numpy(x.copy())
    y = run(name, t, seed=5)
    assert isinstance(y, torch.Tensor) and y.dtype == t.dtype and tuple(y.shape) == x.shape
    assert np.array_equal(y.numpy(), run(name, x, seed=5), equal_nan=True)


@pytest.mark.parametrize("name", NAMES)
def test_batch_items_independent_and_item0_equals_single(name):
    x = CASES[name].make()
    xb = np.stack([x, x])
    yb = run(name, xb, seed=3)
    assert yb.shape == xb.shape
    assert np.array_equal(yb[0], run(name, x, seed=3), equal_nan=True)
    if CASES[name].random and name not in ("audio.preset_library_default",):
        # the two identical inputs get independent draws
        assert any(not np.array_equal(run(name, np.stack([x, x]), seed=s)[0], run(name, np.stack([x, x]), seed=s)[1])
                   for s in range(3))


def test_no_global_random_state_touched():
    np_state = np.random.get_state()[1].copy()
    py_state = random.getstate()
    for name in NAMES:
        run(name, CASES[name].make(), seed=1)
    assert np.array_equal(np.random.get_state()[1], np_state)
    assert random.getstate() == py_state


def test_continuous_severity_interpolates_table():
    from degradations.base import interpolate_level
    table = (0.08, 0.12, 0.18, 0.26, 0.38)
    assert interpolate_level(table, 0.0, 2.5) == pytest.approx(0.15)
    assert interpolate_level(table, 0.0, 0.5) == pytest.approx(0.04)
    assert interpolate_level((20, 15, 10, 5, 0), math.inf, 0.5) == pytest.approx(20 + 20 * math.log10(2))
    assert interpolate_level(table, 0.0, 5.0) == pytest.approx(0.38)


def test_imagenet_c_tables():
    p = REGISTRY["video.gaussian_noise"](severity=1).sample_params(np.random.default_rng(0))
    assert p["sigma"] == pytest.approx(0.08)
    p = REGISTRY["video.jpeg"](severity=5).sample_params(np.random.default_rng(0))
    assert p["quality"] == 7


@pytest.mark.parametrize("bad, msg", [
    (dict(severity=6), "severity"),
    (dict(severity=2, sigmaa=0.1), "sigmaa"),
    (dict(sigma="x"), "sigma"),
    (dict(temporal="sometimes"), "temporal"),
])
def test_bad_parameters_name_the_parameter(bad, msg):
    with pytest.raises(DegradationError, match=msg):
        degradations.apply("video.gaussian_noise", rgb_clip(), seed=0, **bad)


def test_bad_inputs_are_rejected_with_messages():
    with pytest.raises(DegradationError, match="unknown degradation"):
        degradations.apply("video.gausian_noise", rgb_clip(), seed=0)
    with pytest.raises(DegradationError, match="ndim"):
        degradations.apply("audio.white_noise", np.zeros((2, 2, 2, 2), np.float32), seed=0)
    with pytest.raises(DegradationError, match="sample_rate_hz"):
        degradations.apply("audio.bandlimit", audio(), seed=0)
    with pytest.raises(DegradationError, match="seed"):
        degradations.apply("audio.white_noise", audio(), seed=-1)
    with pytest.raises(DegradationError, match="thermal_mask"):
        degradations.apply("thermal.crossover", thermal_clip(), seed=0)


def test_static_vs_per_frame_noise():
    x = np.full((3, 16, 16, 3), 0.5, np.float32)
    st = degradations.apply("video.gaussian_noise", x, seed=0, severity=3, temporal="static")
    pf = degradations.apply("video.gaussian_noise", x, seed=0, severity=3, temporal="per_frame")
    assert np.array_equal(st[0], st[1]) and np.array_equal(st[1], st[2])
    assert not np.array_equal(pf[0], pf[1])
    flat = np.full((3, 32, 40, 3), 180, np.uint8)
    dirt = degradations.apply("video.lens_dirt", flat, seed=0, severity=5)
    assert np.array_equal(dirt[0], dirt[1]) and not np.array_equal(dirt[0], flat[0])  # same spots every frame


def test_fast_normal_statistics_and_uint8_path_matches_float_path():
    from degradations.base import fast_normal
    z = fast_normal(np.random.default_rng(0), (200_000,))
    assert abs(z.mean()) < 0.01 and abs(z.std() - 1.0) < 0.01 and abs(np.mean(z**4) - 3.0) < 0.1
    x = rgb_clip()
    yu = degradations.apply("video.gaussian_noise", x, seed=2, sigma=0.1)
    yf = degradations.apply("video.gaussian_noise", x.astype(np.float32) / 255, seed=2, sigma=0.1)
    assert np.max(np.abs(yu.astype(np.float64) - yf * 255)) <= 0.51


def test_block_dct_roundtrip_is_exact_without_quantisation():
    from degradations.video import BlockCompression
    x = np.random.default_rng(0).random((16, 24, 3)).astype(np.float32)
    rec = BlockCompression(qscale=1.0)._code(x, np.full((8, 8), 1e-7, np.float32))
    assert np.max(np.abs(rec - x)) < 1e-4
