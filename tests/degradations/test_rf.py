"""RF: realised SNR on I/Q and on spectrograms (linear power), IQ imbalance image, ADC."""
from __future__ import annotations

import numpy as np
import pytest

import degradations
from tests.degradations.conftest import iq, spec_db


@pytest.mark.parametrize("snr_db", [-10.0, 0.0, 10.0, 25.0])
def test_awgn_realised_snr(snr_db):
    x = iq()
    y, info = degradations.apply("rf.awgn", x, seed=2, snr_db=snr_db, return_info=True)
    n = (y - x).astype(np.complex128)
    measured = 10 * np.log10(np.mean(np.abs(x) ** 2) / np.mean(np.abs(n) ** 2))
    assert abs(measured - snr_db) < 0.5 and abs(info["realised_snr_db"] - measured) < 1e-3
    assert abs(np.mean(n.real**2) - np.mean(n.imag**2)) < 0.1 * np.mean(np.abs(n) ** 2)  # circular


@pytest.mark.parametrize("snr_db", [-5.0, 0.0, 10.0])
def test_spec_pink_noise_realised_snr_in_linear_power(snr_db):
    x = spec_db()
    y = degradations.apply("rf.spec_pink_noise", x, seed=1, snr_db=snr_db)
    px, py = 10 ** (x.astype(np.float64) / 10), 10 ** (y.astype(np.float64) / 10)
    measured = 10 * np.log10(px.mean() / (py - px).mean())
    assert abs(measured - snr_db) < 0.5
    rows = (py - px).mean(axis=1)
    assert rows[:8].mean() > 4 * rows[-8:].mean()  # pink: more power in low-frequency rows


def test_wifi_burst_is_gated_and_at_sir():
    x = iq()
    y = degradations.apply("rf.wifi_burst", x, seed=3, duty=0.25, sir_db=0.0)
    d = np.abs(y - x) > 0
    assert 0.2 < d.mean() < 0.3
    p_i = np.mean(np.abs((y - x)[d]) ** 2)
    assert 10 * np.log10(np.mean(np.abs(x) ** 2) / p_i) == pytest.approx(0.0, abs=0.5)


def test_iq_imbalance_creates_image_tone():
    n = np.arange(4096)
    x = np.exp(2j * np.pi * (400 / 4096) * n).astype(np.complex64)
    y = degradations.apply("rf.iq_imbalance", x, seed=0, amp_db=1.0, phase_deg=5.0)
    s = np.abs(np.fft.fft(y)) / n.size
    k = 400
    assert s[k] > 0.9 and 1e-3 < s[-k] < 0.1  # image at -f


def test_adc_levels_and_freq_offset_value():
    x = iq()
    y = degradations.apply("rf.adc", x, seed=0, bits=3, clip_rms=2.0)
    assert len(np.unique(y.real)) <= 8
    _, info = degradations.apply("rf.freq_offset", x, seed=0, offset_norm=0.01, drift_norm=0.0,
                                 meta={"sample_rate_hz": 1e6}, return_info=True)
    assert abs(info["params"]["offset_hz"]) == pytest.approx(1e4)


def test_fading_channel_has_unit_average_power():
    from degradations.rf import Fading
    f = Fading(k_factor=0.0, delay_spread=2.0)
    powers = [np.sum(np.abs(f.taps(f.sample_params(np.random.default_rng(s)))) ** 2) for s in range(400)]
    assert np.mean(powers) == pytest.approx(1.0, abs=0.12)
