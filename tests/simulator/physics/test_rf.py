"""RF synthesis: noise floor, link budget, hop statistics per capture, spectrogram vs ground truth,
OFDM bandwidth, LoRa time on air, bad input, determinism."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.signal import welch

from simulator.physics import rf, rf_links
from simulator.physics.timeline import TargetTrack
from simulator.seeding import rng_for

STARTS = np.arange(4) * 0.25


def _timeline(range_m: float | None, kind: str = "quadcopter", height_m: float = 1.5, duration_s: float = 1.2):
    t = np.arange(0.0, duration_s, 1.0 / 28)
    targets = []
    if range_m is not None:
        pos = np.tile([0.0, range_m, height_m], (t.size, 1))
        zeros = np.zeros(t.size)
        targets.append(TargetTrack(1, "d", kind, 0.45, pos, np.zeros_like(pos), np.tile(np.eye(3), (t.size, 1, 1)),
                                   np.full((t.size, 4), 5000.0), zeros, zeros, n_blades=2))
    mic = np.tile([0.0, 0.0, 1.5], (t.size, 1))
    return SimpleNamespace(times_s=t, targets=targets, microphone_position_m=mic)


QUIET = {"wifi_rx_dbm": None, "bluetooth_rx_dbm": None, "capture_samples": 112 * 200}
IDEAL = {"propagation": "free_space", "fading": "none", "rx_antenna": "isotropic"}
VIDEO_2440 = rf_links.OfdmPreset(name="v", role="video", tx_power_dbm=23.0, tx_antenna="isotropic", bandwidth_hz=9e6,
                                 subcarrier_spacing_hz=15e3, channel_centres_hz=(2440e6,), duty=1.0,
                                 burst_range_s=(2e-3, 3e-3))


def test_noise_floor_is_ktb_plus_noise_figure():
    cfg = rf.RFConfig(**QUIET)
    # by hand: 10 log10(1.380649e-23 * 290 * 20e6 * 1e3) + 6 = -94.965 dBm
    assert cfg.noise_dbm == pytest.approx(-94.965, abs=0.002)
    cap = rf.synthesize_rf(_timeline(None), 3, STARTS, config=cfg, clip_duration_s=1.0)
    measured = 10 * np.log10(np.mean(np.abs(cap.iq.astype(np.complex128)) ** 2))
    assert measured == pytest.approx(cfg.noise_dbm, abs=0.05)
    cell_mean = 10 * np.log10(np.mean(10 ** (cap.spectrogram_dbm / 10)))
    assert cell_mean == pytest.approx(cfg.noise_per_bin_dbm, abs=0.1)
    assert not cap.link_active.any() and not cap.observable.any() and not cap.annotations


def test_realised_snr_matches_link_budget():
    cfg = rf.RFConfig(**QUIET, **IDEAL, links=(VIDEO_2440,))
    range_m = 800.0
    cap = rf.synthesize_rf(_timeline(range_m), 4, STARTS, config=cfg, clip_duration_s=1.0)
    fspl = 20 * np.log10(4 * np.pi * range_m * 2.44e9 / 299_792_458.0)        # 98.25 dB
    expected = 23.0 - fspl - cfg.noise_dbm
    assert np.allclose(cap.realised_snr_db, expected, atol=0.2)
    assert np.allclose(cap.video_snr_db, expected + 10 * np.log10(20 / 9), atol=1e-6)   # 9 of 20 MHz
    assert np.allclose(cap.link_rx_dbm, 23.0 - fspl, atol=1e-6)
    assert cap.observable.all() and np.all(cap.control_snr_db == -np.inf)
    # vertical half-wave dipoles at both ends, broadside (same height): +2 x 2.15 dB
    dip = rf.RFConfig(**QUIET, propagation="free_space", fading="none", rx_antenna="dipole",
                      links=(VIDEO_2440.model_copy(update={"tx_antenna": "dipole"}),))
    cap_d = rf.synthesize_rf(_timeline(range_m), 4, STARTS, config=dip, clip_duration_s=1.0)
    assert np.allclose(cap_d.link_rx_dbm - cap.link_rx_dbm, 2 * 10 * np.log10(1.640922), atol=1e-3)


def test_lora_time_on_air_by_hand():
    # SF6 / 812.5 kHz: symbol 78.77 us; payload 8 + ceil((64 - 24 + 28 - 20) / 24) x 7 = 22; (14 + 6.25 + 22) symbols
    assert rf_links.lora_time_on_air_s(6, 812.5e3, 8, 14, 3) == pytest.approx(42.25 * 64 / 812.5e3, rel=1e-12)
    # SF5: 8 + ceil(52 / 20) x 6 = 26; (12 + 6.25 + 26) x 39.38 us = 1.743 ms, inside the 2 ms period of 500 Hz
    assert rf_links.lora_time_on_air_s(5, 812.5e3, 8, 12, 2) == pytest.approx(44.25 * 32 / 812.5e3, rel=1e-12)
    for name in ("elrs_like_500hz", "elrs_like_250hz", "elrs_like_50hz", "frsky_like"):
        preset = rf_links.LINK_PRESETS[name]
        assert preset.packet_s < 1.0 / preset.packet_rate_hz          # a packet fits its period
    with pytest.raises(ValueError, match="spreading_factor"):
        rf_links.lora_time_on_air_s(13, 812.5e3, 8, 12, 2)


def test_channel_plan_and_visible_fraction():
    elrs = rf_links.LINK_PRESETS["elrs_like_250hz"]
    assert elrs.channels_hz[0] == 2400.4e6 and elrs.n_channels == 80
    assert elrs.channels_hz[-1] == pytest.approx(2479.4e6)
    cfg = rf.RFConfig()
    # +-9 MHz passband around 2440 MHz holds the 18 channel centres 2431.4 ... 2448.4 MHz
    assert cfg.fhss_visible_fraction(elrs) == pytest.approx(18 / 80)


def _window_counts(preset, starts, window_s, lo, hi, seed):
    sched = rf_links.fhss_schedule(preset, rng_for(seed, "rf", 9001), float(starts.max()) + 1.0)
    visible = (sched.centre_hz >= lo) & (sched.centre_hz <= hi)
    return np.array([int(np.sum(visible[idx])) for idx in rf_links.bursts_in_windows(sched, starts, window_s)])


@pytest.mark.parametrize("packets_per_hop", [1, 4])
def test_hop_statistics_per_capture_match_analytic(packets_per_hop):
    cfg = rf.RFConfig()
    lo, hi = cfg.passband_hz
    preset = rf_links.LINK_PRESETS["elrs_like_250hz"].model_copy(update={"packets_per_hop": packets_per_hop})
    p = cfg.fhss_visible_fraction(preset)
    # random capture times over many clips: the receiver clock is independent of the link's
    counts = np.concatenate([_window_counts(preset, np.sort(rng_for(k, "rf", 9000).uniform(0, 60, 500)),
                                            cfg.capture_s, lo, hi, k) for k in range(8)])
    exp = rf_links.expected_fhss_counts(preset, cfg.capture_s, p)
    n = counts.size
    # mean (T + L) R p = (2.52 + 3.33) ms x 250 /s x 18/80 = 0.329 holds for any hop interval
    assert exp["mean"] == pytest.approx((cfg.capture_s + preset.packet_s) * 250 * 18 / 80)
    assert abs(counts.mean() - exp["mean"]) < 4 * counts.std() / np.sqrt(n) * (2.0 if packets_per_hop > 1 else 1.0)
    assert np.mean(counts <= 1) > 0.75                         # most captures hold 0 or 1 control burst
    if packets_per_hop == 1:
        for key, observed in (("p0", np.mean(counts == 0)), ("p1", np.mean(counts == 1)),
                              ("p2plus", np.mean(counts >= 2))):
            sigma = np.sqrt(exp[key] * (1 - exp[key]) / n)
            assert abs(observed - exp[key]) < 4 * sigma + 1e-3, key


def test_receiver_sees_exactly_the_scheduled_bursts():
    cfg = rf.RFConfig(wifi_rx_dbm=None, bluetooth_rx_dbm=None, links=("elrs_like_500hz",))
    starts = np.arange(16) * 0.25
    cap = rf.synthesize_rf(_timeline(300.0, duration_s=4.2), 5, starts, config=cfg, clip_duration_s=4.0)
    counts = cap.bursts_per_capture["d/elrs_like_500hz"]
    assert len(cap.annotations) == counts.sum() > 0
    spec = cap.spectrogram_dbm                                   # (S, freq rows, time cols)
    strong = spec > cfg.noise_per_bin_dbm + 20.0
    row_hz = cfg.center_frequency_hz + (np.arange(rf.SPECTROGRAM_PX)[::-1] - rf.SPECTROGRAM_PX / 2 + 0.5) * cfg.bin_hz
    expected = np.zeros_like(strong)
    col_s = cfg.capture_s / rf.SPECTROGRAM_PX
    n = cfg.capture_samples
    for a in cap.annotations:
        s, first = divmod(a["core:sample_start"], n)
        c0, c1 = int(first / n * rf.SPECTROGRAM_PX), int(np.ceil((first + a["core:sample_count"]) / n
                                                                 * rf.SPECTROGRAM_PX))
        # chirp edges splatter a little in 22.5 us frames: allow 4 bins (0.7 MHz) around the band, 1 column
        rows = (row_hz >= a["core:freq_lower_edge"] - 4 * cfg.bin_hz) & (row_hz <= a["core:freq_upper_edge"] + 4
                                                                         * cfg.bin_hz)
        expected[s][np.ix_(rows, np.arange(max(c0 - 1, 0), min(c1 + 1, rf.SPECTROGRAM_PX)))] = True
        inner = (row_hz > a["core:freq_lower_edge"] + cfg.bin_hz) & (row_hz < a["core:freq_upper_edge"] - cfg.bin_hz)
        cols = np.arange(c0 + 1, c1 - 1)
        block = strong[s][np.ix_(inner, cols)]
        assert block.any(axis=0).all() and block.any(axis=1).all()   # a chirp sweeps the band in every column
    assert not (strong & ~expected).any()                        # and nothing else is
    assert col_s == pytest.approx(22.5e-6)
    silent = rf.synthesize_rf(_timeline(300.0, duration_s=4.2), 5, starts, config=cfg, rf_silent=True,
                              clip_duration_s=4.0)
    assert not (silent.spectrogram_dbm > cfg.noise_per_bin_dbm + 20.0).any()
    assert not silent.observable.any() and not silent.annotations


def test_observability_follows_bursts_in_capture():
    cfg = rf.RFConfig(**QUIET, links=("elrs_like_250hz",))
    starts = np.arange(40) * 0.25
    cap = rf.synthesize_rf(_timeline(200.0, duration_s=10.2), 2, starts, config=cfg, clip_duration_s=10.0)
    counts = cap.bursts_per_capture["d/elrs_like_250hz"]
    assert np.array_equal(cap.observable, counts > 0)            # 200 m: every received burst is far above 0 dB
    assert 0 < cap.observable.mean() < 0.8
    far = rf.synthesize_rf(_timeline(2e6, duration_s=10.2), 2, starts, config=cfg, clip_duration_s=10.0)
    assert np.array_equal(far.bursts_per_capture["d/elrs_like_250hz"], counts)   # same hops, same seed
    assert not far.observable.any()                              # 2000 km: all below the noise


def test_bluetooth_background_hops_on_its_channels_only():
    cfg = rf.RFConfig(wifi_rx_dbm=None, bluetooth_rx_dbm=-60.0)
    cap = rf.synthesize_rf(_timeline(None, duration_s=10.2), 3, np.arange(40) * 0.25, config=cfg, clip_duration_s=10.0)
    strong = cap.spectrogram_dbm > cfg.noise_per_bin_dbm + 20.0
    row_hz = cfg.center_frequency_hz + (np.arange(rf.SPECTROGRAM_PX)[::-1] - rf.SPECTROGRAM_PX / 2 + 0.5) * cfg.bin_hz
    rows = np.nonzero(strong.any(axis=(0, 2)))[0]
    assert rows.size > 0
    channels = 2402e6 + 1e6 * np.arange(79)
    # GFSK at 1 Msym/s occupies about +-0.75 MHz around its channel centre
    assert np.all(np.min(np.abs(row_hz[rows, None] - channels[None, :]), axis=1) < 0.75e6 + cfg.bin_hz)
    # 366 us packets in 30 % of 625 us slots, 18 of 79 channels in the window: bursty, mostly empty captures
    busy = strong.any(axis=(1, 2)).mean()
    assert 0.1 < busy < 0.6
    assert not cap.link_active.any() and not cap.annotations              # an interferer, not a drone link


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
    assert np.mean(np.abs(sig) ** 2) == pytest.approx(1.0, rel=0.02)


def test_lte_like_ofdm_has_15_khz_subcarriers_and_clipped_band():
    fs = 20e6
    sig, frac = rf.ofdm_waveform(rng_for(0, "rf", 98), 1, 1427 * 40, fs, 0.0, 9e6, 15e3, 144 / 2048, 9e6)
    assert frac == 1.0 and np.mean(np.abs(sig) ** 2) == pytest.approx(1.0, rel=0.02)
    body = sig[0, 32:32 + 1333]                      # one symbol: FFT window 32 samples into the CP (past the taper)
    spec = np.abs(np.fft.fft(body)) ** 2
    used = np.nonzero(spec > 1e-3 * spec.max())[0]
    assert used.size == 600                                      # 600 x 15.004 kHz = 9 MHz, DC null
    assert fs / 1333 == pytest.approx(15e3, rel=3e-4)
    # a 40 MHz link seen through a +-9 MHz passband keeps 1200 of 2400 subcarriers: half the power
    wide, frac40 = rf.ofdm_waveform(rng_for(0, "rf", 97), 1, 1427 * 20, fs, 0.0, 36e6, 15e3, 144 / 2048, 9e6)
    assert frac40 == pytest.approx(0.5, abs=0.01)
    assert np.mean(np.abs(wide) ** 2) == pytest.approx(frac40, rel=0.03)


def test_bad_input_names_the_field():
    with pytest.raises(ValueError, match="links"):
        rf.RFConfig(links=("no_such_link",))
    with pytest.raises(ValueError, match="capture_start_s"):
        rf.synthesize_rf(_timeline(None), 0, np.array([-0.25]), config=rf.RFConfig(**QUIET))
    with pytest.warns(DeprecationWarning, match="control_channels_hz"):
        legacy = rf.RFConfig.model_validate({"control_channels_hz": [1e6], "sample_rate_hz": 20e6})
    assert legacy.links == rf.RFConfig().links


def test_sigmf_metadata_describes_captures_and_bursts():
    cfg = rf.RFConfig(**QUIET)
    cap = rf.synthesize_rf(_timeline(150.0), 1, STARTS, config=cfg, clip_duration_s=1.0)
    meta = cap.sigmf_metadata()
    assert meta["global"]["core:sample_rate"] == 20e6 and meta["global"]["core:datatype"] == "cf32_le"
    assert [c["core:sample_start"] for c in meta["captures"]] == [0, 22_400, 44_800, 67_200]
    assert [c["evids:start_s"] for c in meta["captures"]] == STARTS.tolist()
    total = cap.iq.size
    for a in meta["annotations"]:
        assert 0 <= a["core:sample_start"] < a["core:sample_start"] + a["core:sample_count"] <= total
        assert 2431e6 <= a["core:freq_lower_edge"] < a["core:freq_upper_edge"] <= 2449e6


def test_sigmf_metadata_validates_against_the_sigmf_schema():
    sigmf = pytest.importorskip("sigmf")
    from sigmf import validate

    cap = rf.synthesize_rf(_timeline(150.0), 1, STARTS, config=rf.RFConfig(**QUIET), clip_duration_s=1.0)
    meta = cap.sigmf_metadata()
    meta["global"]["core:version"] = sigmf.__version__
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")                      # undeclared extensions warn in sigmf 1.x
        validate.validate(meta)


def test_same_seed_same_bytes_different_seed_differs():
    cfg = rf.RFConfig(capture_samples=112 * 100)
    a = rf.synthesize_rf(_timeline(250.0), 7, STARTS, config=cfg, clip_duration_s=1.0)
    b = rf.synthesize_rf(_timeline(250.0), 7, STARTS, config=cfg, clip_duration_s=1.0)
    c = rf.synthesize_rf(_timeline(250.0), 8, STARTS, config=cfg, clip_duration_s=1.0)
    assert a.iq.tobytes() == b.iq.tobytes()
    assert a.spectrogram_dbm.tobytes() == b.spectrogram_dbm.tobytes()
    assert a.annotations == b.annotations
    assert not np.array_equal(a.iq, c.iq)
    assert a.iq.dtype == np.complex64
    # the channel model draws from its own stream: switching fading off keeps every hop and burst time
    d = rf.synthesize_rf(_timeline(250.0), 7, STARTS, config=cfg.model_copy(update={"fading": "none"}),
                         clip_duration_s=1.0)
    assert [x["core:sample_start"] for x in d.annotations] == [x["core:sample_start"] for x in a.annotations]
