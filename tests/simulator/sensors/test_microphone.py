"""Recording chain: capsule response, AGC, self-noise, clipping, quantisation; determinism."""
from __future__ import annotations

import numpy as np
import pytest

from simulator.sensors import microphone as mic

FS = 44_100


def test_disabled_chain_is_pressure_over_full_scale():
    x = 0.01 * np.sin(np.arange(1000) / 5.0)
    y = mic.record(x, FS, seed=1, full_scale_pa=0.1, config=mic.RecorderConfig(enabled=False))
    assert y.dtype == np.float32 and np.allclose(y, x / 0.1, atol=1e-7)


def test_response_corners_by_hand():
    f = np.array([100.0, 1000.0, 8000.0, 80_000.0])
    r = mic.microphone_response_db(f, highpass_hz=100.0, lowpass_hz=8000.0, presence_db=0.0, presence_hz=3000.0)
    # 2nd-order Butterworth magnitude: |H|^2 = (f/fc)^4 / (1 + (f/fc)^4) -> -3.01 dB at the corner
    assert r[0] == pytest.approx(-3.01, abs=0.01) and r[2] == pytest.approx(-3.01, abs=0.01)
    assert r[1] == pytest.approx(-10 * np.log10(1 + 0.1 ** 4) - 10 * np.log10(1 + (1000 / 8000) ** 4), abs=1e-9)
    assert r[3] == pytest.approx(-40.0, abs=0.01)              # a decade above: 10 lg(1 + 10^4)
    lift = mic.microphone_response_db(np.array([3000.0]), 10.0, 20000.0, 4.0, 3000.0)
    assert lift[0] == pytest.approx(4.0, abs=0.01)


def test_deterministic_per_seed_and_index():
    x = 0.02 * np.random.default_rng(0).standard_normal(FS)
    a = mic.record(x, FS, seed=3, index=1)
    assert a.tobytes() == mic.record(x, FS, seed=3, index=1).tobytes()
    assert a.tobytes() != mic.record(x, FS, seed=4, index=1).tobytes()
    assert a.tobytes() != mic.record(x, FS, seed=3, index=2).tobytes()


def _flat(**kw) -> mic.RecorderConfig:
    base = {"highpass_hz": (20.0, 20.0), "lowpass_hz": (20000.0, 20000.0), "presence_db": (0.0, 0.0),
                "self_noise_dbfs": (-140.0, -140.0), "input_gain_db": (0.0, 0.0), "bit_depth": 32}
    return mic.RecorderConfig(**{**base, **kw})


def test_agc_steers_to_target_within_its_gain_limits():
    t = np.arange(4 * FS) / FS
    tone = np.sin(2 * np.pi * 1000 * t) * np.sqrt(2)           # rms 1 before scaling
    cfg = _flat(agc_target_dbfs=(-20.0, -20.0), agc_release_s=(0.5, 0.5), agc_max_gain_db=10.0)
    loud = mic.record(tone * 10 ** (-24 / 20), FS, seed=0, full_scale_pa=1.0, config=cfg)
    level = 20 * np.log10(np.sqrt(np.mean(loud[2 * FS:].astype(np.float64) ** 2)))
    assert level == pytest.approx(-20.0, abs=0.3)              # -24 dBFS raised 4 dB (< max gain) to the target
    hot = mic.record(tone * 10 ** (-8 / 20), FS, seed=0, full_scale_pa=1.0, config=cfg)
    level_h = 20 * np.log10(np.sqrt(np.mean(hot[2 * FS:].astype(np.float64) ** 2)))
    assert level_h == pytest.approx(-20.0, abs=0.3)            # -8 dBFS lowered 12 dB
    quiet = mic.record(tone * 10 ** (-50 / 20), FS, seed=0, full_scale_pa=1.0, config=cfg)
    level_q = 20 * np.log10(np.sqrt(np.mean(quiet[2 * FS:].astype(np.float64) ** 2)))
    assert level_q == pytest.approx(-50.0 + cfg.agc_max_gain_db, abs=0.3)


def test_clipping_and_16_bit_quantisation():
    x = 5.0 * np.sin(np.arange(FS) / 3.0)
    y = mic.record(x, FS, seed=0, full_scale_pa=1.0, config=_flat(agc=False, bit_depth=16))
    assert np.max(np.abs(y)) <= 1.0 and np.max(np.abs(y)) == pytest.approx(1.0)
    steps = y.astype(np.float64) * 32767
    assert np.allclose(steps, np.round(steps), atol=1e-3)


def test_bad_span_names_the_field():
    with pytest.raises(ValueError, match="agc_target_dbfs"):
        mic.RecorderConfig(agc_target_dbfs=(-10.0, -30.0))


def test_codec_band_limit_by_hand_and_in_the_chain():
    f = np.array([1000.0, 15_700.0, 15_850.0, 16_000.0, 19_000.0])
    r = mic.codec_response_db(f, cutoff_hz=16_000.0, edge_hz=300.0, floor_db=-70.0)
    assert r[0] == 0.0 and r[1] == pytest.approx(0.0, abs=1e-9)             # below the edge: untouched
    floor = 10 ** (-70 / 20)
    assert r[2] == pytest.approx(20 * np.log10(floor + (1 - floor) * 0.5), abs=1e-9)   # mid-edge: half amplitude
    assert r[3] == pytest.approx(-70.0, abs=1e-9) and r[4] == pytest.approx(-70.0, abs=1e-9)
    x = 0.02 * np.random.default_rng(1).standard_normal(FS)
    on = mic.record(x, FS, seed=2, full_scale_pa=1.0, config=_flat(agc=False, codec_probability=1.0,
                                                                   codec_cutoff_hz=(12_000.0, 12_000.0)))
    off = mic.record(x, FS, seed=2, full_scale_pa=1.0, config=_flat(agc=False, codec_probability=0.0))
    spec_on, spec_off = (np.abs(np.fft.rfft(y.astype(np.float64))) ** 2 for y in (on, off))
    fr = np.fft.rfftfreq(FS, 1 / FS)
    above, below = (fr > 13_000) & (fr < 20_000), (fr > 2_000) & (fr < 10_000)
    assert 10 * np.log10(spec_on[above].sum() / spec_off[above].sum()) < -40     # cut (16-bit floor remains)
    assert 10 * np.log10(spec_on[below].sum() / spec_off[below].sum()) == pytest.approx(0.0, abs=0.1)
    with pytest.raises(ValueError, match="codec_cutoff_hz"):
        mic.RecorderConfig(codec_cutoff_hz=(50.0, 60.0))


def test_gate_lowers_only_what_falls_under_its_threshold():
    t = np.arange(2 * FS) / FS
    tone = np.sin(2 * np.pi * 1000 * t) * np.sqrt(2)                     # rms 1
    quiet = tone * 10 ** (-50 / 20) * (t >= 1.0) + tone * 10 ** (-20 / 20) * (t < 1.0)
    g = mic.gate_gain(quiet, FS, threshold_dbfs=-40.0, ratio=3.0, range_db=-15.0, release_s=0.05)
    assert 20 * np.log10(g[int(0.9 * FS)]) == pytest.approx(0.0, abs=1e-6)    # -20 dBFS: over the threshold
    assert 20 * np.log10(g[int(1.9 * FS)]) == pytest.approx(-15.0, abs=0.05)  # -50: 2 x 10 dB = 20, held at range
    soft = mic.gate_gain(tone * 10 ** (-45 / 20), FS, threshold_dbfs=-40.0, ratio=2.0, range_db=-30.0, release_s=0.05)
    assert 20 * np.log10(soft[FS]) == pytest.approx(-5.0, abs=0.05)            # (ratio - 1) x 5 dB under
    cfg = _flat(agc=False, gate_probability=1.0, gate_threshold_dbfs=(-40.0, -40.0), gate_ratio=(3.0, 3.0),
                gate_range_db=(-15.0, -15.0), gate_release_s=(0.05, 0.05))
    y = mic.record(quiet, FS, seed=0, full_scale_pa=1.0, config=cfg)
    tail = 20 * np.log10(np.sqrt(np.mean(y[int(1.5 * FS):].astype(np.float64) ** 2)))
    assert tail == pytest.approx(-65.0, abs=0.3)


def _two_level(loud_dbfs: float, quiet_dbfs: float, seconds: float, period_s: float = 1.0) -> np.ndarray:
    """A 1 kHz tone (RMS 1 before scaling) switching every half period between two levels (dBFS)."""
    t = np.arange(round(seconds * FS)) / FS
    loud = (t % period_s) < period_s / 2
    level = np.where(loud, 10 ** (loud_dbfs / 20), 10 ** (quiet_dbfs / 20))
    return np.sqrt(2) * np.sin(2 * np.pi * 1000 * t) * level


def _block_db(y: np.ndarray, block: int) -> np.ndarray:
    n = y.size // block
    return 10 * np.log10(np.mean(y[: n * block].astype(np.float64).reshape(n, block) ** 2, axis=1))


def test_agc_mean_detector_puts_the_mean_block_level_on_the_target():
    """A tone alternating 0.5 s at -30 and 0.5 s at -50 dBFS, target -25, release 5 s (the gain ripples by about
    +-1 dB over a period): the 'mean' detector follows the mean block level in dB (-40), so the gain settles near
    +15 dB and the output's 50 ms levels average the target (-25: -15 and -35 dBFS); the 'peak' detector follows
    the loud half (-30 after its 50 ms attack), so the gain sits near +5 dB and the output's mean level is the
    target minus half the 20 dB swing (-35, its loud half at the target)."""
    x = _two_level(-30.0, -50.0, 30.0)
    block = round(mic.AGC_BLOCK_S * FS)
    settled = slice(20 * FS, 30 * FS)                  # 10 whole periods after 4 release time constants
    mean = x * mic.agc_gain(x, FS, -25.0, 0.05, 5.0, -40.0, 40.0, detector="mean")
    peak = x * mic.agc_gain(x, FS, -25.0, 0.05, 5.0, -40.0, 40.0, detector="peak")
    assert np.mean(_block_db(mean[settled], block)) == pytest.approx(-25.0, abs=0.3)
    assert np.mean(_block_db(peak[settled], block)) == pytest.approx(-35.0, abs=0.6)
    assert np.median(_block_db(peak[settled], block)[::20]) == pytest.approx(-25.0, abs=0.6)   # loud halves
    assert np.array_equal(peak, x * mic.agc_gain(x, FS, -25.0, 0.05, 5.0, -40.0, 40.0))       # peak: the default
    steady = np.sqrt(2) * np.sin(2 * np.pi * 1000 * np.arange(4 * FS) / FS) * 10 ** (-40 / 20)
    for detector in ("mean", "peak"):                  # a steady tone: both put it on the target
        y = steady * mic.agc_gain(steady, FS, -25.0, 0.05, 1.0, -40.0, 40.0, detector=detector)
        assert 20 * np.log10(np.sqrt(np.mean(y[2 * FS:] ** 2))) == pytest.approx(-25.0, abs=0.05)
    with pytest.raises(ValueError, match="detector"):
        mic.agc_gain(steady, FS, -25.0, 0.05, 1.0, -40.0, 40.0, detector="rms")


def test_agc_detector_is_opt_in_and_left_out_of_dumps_while_unset():
    """Unset (None) the recorder keeps the peak detector byte for byte and its dump (hashed into TRIDENT
    manifests) has no ``agc_detector`` key; 'mean' is dumped and changes the recording; a bad value names the
    field."""
    assert "agc_detector" not in mic.RecorderConfig().model_dump()
    assert mic.RecorderConfig(agc_detector="mean").model_dump()["agc_detector"] == "mean"
    again = mic.RecorderConfig.model_validate(mic.RecorderConfig(agc_detector="mean").model_dump())
    assert again.agc_detector == "mean"
    x = _two_level(-20.0, -45.0, 4.0) * 0.1
    default = mic.record(x, FS, seed=2, full_scale_pa=0.1)
    assert default.tobytes() == mic.record(x, FS, seed=2, full_scale_pa=0.1,
                                           config=mic.RecorderConfig(agc_detector="peak")).tobytes()
    assert default.tobytes() != mic.record(x, FS, seed=2, full_scale_pa=0.1,
                                           config=mic.RecorderConfig(agc_detector="mean")).tobytes()
    with pytest.raises(ValueError, match="agc_detector"):
        mic.RecorderConfig(agc_detector="rms")
