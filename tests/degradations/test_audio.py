"""Audio: realised SNR measured from the added noise power; presets; band-limiting."""
from __future__ import annotations

import numpy as np
import pytest

import degradations
from tests.degradations.conftest import SR, audio


def realised_snr_db(x, y):
    n = y.astype(np.float64) - x.astype(np.float64)
    return 10 * np.log10(np.mean(x.astype(np.float64) ** 2) / np.mean(n**2))


@pytest.mark.parametrize("name", ["audio.white_noise", "audio.pink_noise", "audio.brown_noise", "audio.wind",
                                  "audio.background"])
@pytest.mark.parametrize("snr_db", [-5.0, 0.0, 10.0, 30.0])
def test_realised_snr_within_half_db(name, snr_db):
    x = audio()
    meta = {"sample_rate_hz": SR, "background": np.random.default_rng(1).normal(size=1000)}
    y, info = degradations.apply(name, x, seed=4, snr_db=snr_db, meta=meta, return_info=True)
    measured = realised_snr_db(x, y)
    assert abs(measured - snr_db) < 0.5
    assert abs(info["realised_snr_db"] - measured) < 1e-3


def test_snr_reference_is_whole_segment_rms_including_silence():
    x = audio()
    x[: x.size // 2] = 0.0  # half silence: RMS over the whole segment, so noise is sigma = rms(x)/10^(snr/20)
    y = degradations.apply("audio.white_noise", x, seed=0, snr_db=10.0)
    noise_rms = np.sqrt(np.mean((y - x).astype(np.float64) ** 2))
    assert noise_rms == pytest.approx(np.sqrt(np.mean(x.astype(np.float64) ** 2)) / 10 ** 0.5, rel=1e-4)
    # meta['signal_rms'] overrides the reference (clip-level RMS for per-segment use)
    y2 = degradations.apply("audio.white_noise", x, seed=0, snr_db=10.0, meta={"signal_rms": 1.0})
    assert np.sqrt(np.mean((y2 - x).astype(np.float64) ** 2)) == pytest.approx(10 ** -0.5, rel=1e-4)


def test_pink_noise_spectrum_slope_is_minus_3db_per_octave():
    x = np.zeros(2**16, np.float32) + 1.0  # constant signal: the added noise is y - x
    n = degradations.apply("audio.pink_noise", x, seed=0, snr_db=0.0) - x
    p = np.abs(np.fft.rfft(n)) ** 2
    f = np.arange(p.size)

    def band(lo):
        return p[(f >= lo) & (f < 2 * lo)].mean()

    slope = 10 * np.log10(band(4000) / band(2000))
    assert slope == pytest.approx(-3.01, abs=0.5)


def test_preset_white_10db_and_library_default():
    x = audio()
    y = degradations.apply("audio.preset_white_10db", x, seed=0, severity=1)
    assert realised_snr_db(x, y) == pytest.approx(10.0, abs=0.01)
    snrs, applied = [], []
    for s in range(200):
        _, info = degradations.apply("audio.preset_library_default", x, seed=s, severity=1, return_info=True)
        snrs.append(info["params"]["snr_db"])
        applied.append(info["params"]["applied"])
    assert 5.0 <= min(snrs) and max(snrs) <= 40.0
    assert 0.35 < np.mean(applied) < 0.65  # p = 0.5 like audiomentations' default


def test_bandlimit_removes_out_of_band_energy():
    t = np.arange(SR // 4) / SR
    x = (np.sin(2 * np.pi * 1000 * t) + np.sin(2 * np.pi * 6000 * t)).astype(np.float32)
    y = degradations.apply("audio.bandlimit", x, seed=0, low_cut_hz=300.0, high_cut_hz=2500.0,
                           meta={"sample_rate_hz": SR})
    spec = np.abs(np.fft.rfft(y)) / (x.size / 2)

    def k(hz):
        return int(round(hz * x.size / SR))

    assert spec[k(1000)] > 0.9 and spec[k(6000)] < 0.01


def test_gain_clip_and_dropout_fraction():
    x = audio()
    y = degradations.apply("audio.gain_clip", x, seed=0, gain_db=20.0)
    assert np.max(np.abs(y)) == pytest.approx(1.0) and np.mean(np.abs(y) == 1.0) > 0.3
    y = degradations.apply("audio.dropout", x, seed=0, drop_fraction=0.3, meta={"sample_rate_hz": SR})
    assert np.mean(y == 0) == pytest.approx(0.3, abs=0.03)


def test_white_noise_is_gaussian_white_and_exactly_at_the_snr():
    from scipy import stats

    x = np.zeros(44100, np.float32)
    x[::2] = 1.0                                                   # RMS 1/sqrt(2)
    y, info = degradations.apply("audio.white_noise", x, seed=3, snr_db=6.0, return_info=True)
    n = (y - x).astype(np.float64)
    assert info["realised_snr_db"] == pytest.approx(6.0, abs=1e-4)
    z = n / n.std()
    assert stats.kstest(z, "norm").pvalue > 1e-3 and abs(stats.kurtosis(z)) < 0.1
    assert abs(np.corrcoef(z[:-1], z[1:])[0, 1]) < 0.02             # white: no lag-1 correlation


def test_mean_power_of_real_and_complex_items():
    from degradations.base import _mean_power

    a = np.array([1.0, -2.0, 3.0])
    c = np.array([1 + 1j, 2 - 1j], np.complex64)
    assert _mean_power(a) == pytest.approx(14 / 3) and _mean_power(c) == pytest.approx(3.5)
    assert _mean_power(a.reshape(3, 1)[::2]) == pytest.approx(5.0)
