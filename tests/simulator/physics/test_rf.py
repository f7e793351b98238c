"""RF synthesis: noise floor and SNR, path loss, hop channels, OFDM bandwidth, bad input, determinism."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.signal import welch

from simulator.physics import rf
from simulator.physics.timeline import TargetTrack
from simulator.seeding import rng_for

STARTS = np.arange(4) * 0.25


def _timeline(range_m: float | None, kind: str = "quadcopter"):
    t = np.arange(0.0, 1.2, 1.0 / 28)
    targets = []
    if range_m is not None:
        pos = np.tile([0.0, range_m, 0.0], (t.size, 1))
        zeros = np.zeros(t.size)
        targets.append(TargetTrack(1, "d", kind, 0.45, pos, np.zeros_like(pos), np.tile(np.eye(3), (t.size, 1, 1)),
                                   np.full((t.size, 4), 5000.0), zeros, zeros, n_blades=2))
    return SimpleNamespace(times_s=t, targets=targets, microphone_position_m=np.zeros((t.size, 3)))


QUIET = dict(wifi_rx_dbm=None, bluetooth_rx_dbm=None, capture_samples=112 * 200)


def test_noise_floor_is_ktb_plus_noise_figure():
    cfg = rf.RFConfig(**QUIET)
    # by hand: 10 log10(1.380649e-23 * 290 * 20e6 * 1e3) + 6 = -94.965 dBm
    assert cfg.noise_dbm == pytest.approx(-94.965, abs=0.002)
    cap = rf.synthesize_rf(_timeline(None), 3, STARTS, config=cfg, clip_duration_s=1.0)
    measured = 10 * np.log10(np.mean(np.abs(cap.iq.astype(np.complex128)) ** 2))
    assert measured == pytest.approx(cfg.noise_dbm, abs=0.05)
    cell_mean = 10 * np.log10(np.mean(10 ** (cap.spectrogram_dbm / 10)))
    assert cell_mean == pytest.approx(cfg.noise_per_bin_dbm, abs=0.1)
    assert not cap.link_active.any() and not cap.observable.any()


def test_realised_snr_matches_link_budget():
    cfg = rf.RFConfig(**QUIET, control_eirp_dbm=-200.0, video_duty=1.0)
    range_m = 800.0
    cap = rf.synthesize_rf(_timeline(range_m), 4, STARTS, config=cfg, clip_duration_s=1.0)
    fspl = 20 * np.log10(4 * np.pi * range_m * 2.44e9 / 299_792_458.0)        # 98.25 dB
    expected = 23.0 - fspl - cfg.noise_dbm
    assert np.allclose(cap.realised_snr_db, expected, atol=0.2)
    assert np.allclose(cap.video_snr_db, expected + 10 * np.log10(2.0), atol=1e-6)   # 10 of 20 MHz
    assert cap.observable.all()


def test_path_loss_six_db_per_doubling_and_bad_range():
    loss = rf.free_space_path_loss_db(np.array([100.0, 200.0, 400.0]), 2.44e9)
    assert np.allclose(np.diff(loss), 20 * np.log10(2.0))
    with pytest.raises(ValueError, match="range_m"):
        rf.free_space_path_loss_db(-1.0, 2.44e9)


def test_sample_rate_below_twice_band_is_rejected():
    with pytest.raises(ValueError, match="sample_rate_hz"):
        rf.RFConfig(sample_rate_hz=10e6)
    with pytest.raises(ValueError, match="capture_start_s"):
        rf.synthesize_rf(_timeline(None), 0, np.array([-0.25]), config=rf.RFConfig(**QUIET))


def test_hop_bursts_occupy_the_declared_channels():
    cfg = rf.RFConfig(**QUIET, video_eirp_dbm=-200.0)
    starts = np.arange(12) * 0.25
    cap = rf.synthesize_rf(_timeline(300.0), 5, starts, config=cfg, clip_duration_s=3.0)
    spec = cap.spectrogram_dbm                                   # (S, freq rows, time cols)
    strong = spec > cfg.noise_per_bin_dbm + 20.0
    row_hz = (np.arange(rf.SPECTROGRAM_PX)[::-1] - rf.SPECTROGRAM_PX / 2 + 0.5) * cfg.bin_hz
    rows = np.nonzero(strong.any(axis=(0, 2)))[0]
    channels = np.asarray(cfg.control_channels_hz)
    dist = np.min(np.abs(row_hz[rows, None] - channels[None, :]), axis=1)
    assert rows.size > 0
    assert np.all(dist <= cfg.control_bandwidth_hz / 2 + 2 * cfg.bin_hz)   # nothing between/off the channels
    # every burst (one per strong time column) is centred on a declared channel
    power = np.where(strong, 10 ** (spec / 10), 0.0)
    seg_idx, col_idx = np.nonzero(strong.any(axis=1))
    cols = power[seg_idx, :, col_idx]                                       # (bursty columns, rows)
    centroid = cols @ row_hz / cols.sum(axis=1)
    # a 10 us column holds ~10 FSK symbols (+-250 kHz deviation): allow that plus one bin; spacing is 2 MHz
    assert np.all(np.min(np.abs(centroid[:, None] - channels[None, :]), axis=1) < 0.25e6 + cfg.bin_hz)
    hit = [np.any(strong[:, np.abs(row_hz - c) < cfg.bin_hz, :]) for c in channels]
    assert all(hit)                                                         # every declared channel is used
    duty = strong.any(axis=1).mean()
    assert 0.3 < duty < 0.7                                                 # 0.25 ms bursts every 0.5 ms
    silent = rf.synthesize_rf(_timeline(300.0), 5, starts, config=cfg, rf_silent=True, clip_duration_s=3.0)
    assert not (silent.spectrogram_dbm > cfg.noise_per_bin_dbm + 20.0).any()
    assert not silent.observable.any()


def test_ofdm_occupied_bandwidth_within_ten_percent():
    fs = 20e6
    sig, gate = rf.ofdm_bursts(rng_for(0, "rf", 99), np.zeros(2), 64_000, fs, 1e6, 10e6, 1.0, (1e-3, 2e-3))
    assert gate.all()
    f, psd = welch(sig[0], fs=fs, nperseg=2048, return_onesided=False)
    order = np.argsort(f)
    f, psd = f[order], psd[order]
    cdf = np.cumsum(psd) / np.sum(psd)
    occupied = f[np.searchsorted(cdf, 0.995)] - f[np.searchsorted(cdf, 0.005)]
    assert abs(occupied - 10e6) / 10e6 < 0.10
    centre = np.sum(f * psd) / np.sum(psd)
    assert abs(centre - 1e6) < 0.2e6
    assert np.mean(np.abs(sig) ** 2) == pytest.approx(1.0, rel=0.02)


def test_same_seed_same_bytes_different_seed_differs():
    cfg = rf.RFConfig(capture_samples=112 * 100)
    a = rf.synthesize_rf(_timeline(250.0), 7, STARTS, config=cfg, clip_duration_s=1.0)
    b = rf.synthesize_rf(_timeline(250.0), 7, STARTS, config=cfg, clip_duration_s=1.0)
    c = rf.synthesize_rf(_timeline(250.0), 8, STARTS, config=cfg, clip_duration_s=1.0)
    assert a.iq.tobytes() == b.iq.tobytes()
    assert a.spectrogram_dbm.tobytes() == b.spectrogram_dbm.tobytes()
    assert not np.array_equal(a.iq, c.iq)
    assert a.iq.dtype == np.complex64
