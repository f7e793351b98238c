"""Sources: rotor lines, Doppler, bad input, sound power and directivity, drawn rotor noise and its
spans, the helicopter."""
from __future__ import annotations

import numpy as np
import pytest

from simulator.physics import acoustics as ac
from simulator.physics.timeline import TargetTrack
from simulator.seeding import rng_for
from tests.simulator.physics.acoustics.helpers import (
    FS,
    MIC,
    _a_level_db,
    _fibonacci_sphere,
    _hover_track,
    _peak_hz,
    _track,
)


@pytest.mark.parametrize("rpm", [6000.0, 5130.0])
def test_blade_passing_peak_within_one_bin(rpm):
    track, t = _track([0.0, 60.0, 20.0], [0.0, 0.0, 0.0], rpm=rpm, duration_s=2.0)
    # the clean-line model: drawn rotor noise puts the broadband 10-20 dB over the lines (checked elsewhere)
    x, _ = ac.synthesize_target(track, t, MIC, 2 * FS, FS, 288.15, 0.5, rng_for(1, "acoustics", 0),
                                rotor_noise=ac.LEGACY_ROTOR_NOISE)
    expected = rpm / 60.0 * 2
    peak, bin_hz = _peak_hz(x, 0.6 * expected, 1.4 * expected)
    assert abs(peak - expected) <= bin_hz


@pytest.mark.parametrize("speed_mps", [25.0, -25.0])  # + approaching, - receding
def test_doppler_sign_and_size(speed_mps):
    # flying along the line through the microphone: radial speed is exactly |v|
    start = [0.0, 400.0, 1.5] if speed_mps > 0 else [0.0, 50.0, 1.5]
    track, t = _track(start, [0.0, -speed_mps, 0.0], rpm=6000.0, duration_s=4.0)
    x, _ = ac.synthesize_target(track, t, MIC, 4 * FS, FS, 293.15, 0.5, rng_for(2, "acoustics", 0),
                                rotor_noise=ac.LEGACY_ROTOR_NOISE)
    c = ac.speed_of_sound_mps(293.15)
    f_src = 6000.0 / 60.0 * 2 * 4            # 4th BPF harmonic, 800 Hz: finer relative resolution
    expected = f_src * c / (c - speed_mps)
    seg = x[2 * FS: 4 * FS]
    peak, _ = _peak_hz(seg, f_src * 0.85, f_src * 1.15)
    assert np.sign(peak - f_src) == np.sign(speed_mps)
    assert abs(peak - expected) < 0.6           # shift is ~62 Hz; 0.5 Hz bins (unpadded)


def test_bad_input_names_the_field():
    with pytest.raises(ValueError, match="range_m"):
        ac.propagate(np.zeros(100), np.full(100, -5.0), FS, 288.0, 0.5)
    track, t = _track([0.0, 60.0, 20.0], [0.0, 0.0, 0.0], rpm=-100.0, duration_s=0.5)
    with pytest.raises(ValueError, match="rotor_rpm"):
        ac.synthesize_target(track, t, MIC, FS // 2, FS, 288.0, 0.5, rng_for(0, "acoustics", 0))
    with pytest.raises(ValueError, match="sample_rate_hz"):
        ac.synthesize_target(track, t, MIC, 8000, 16_000, 288.0, 0.5, rng_for(0, "acoustics", 0))
    with pytest.raises(ValueError, match="relative_humidity"):
        ac.iso9613_absorption_db_per_m(1000.0, 288.0, 50.0)


@pytest.mark.parametrize("kind,size_m,noise", [("quadcopter", 0.45, "legacy"), ("hexacopter", 0.8, "legacy"),
                                                ("quadcopter", 0.3, 5), ("quadcopter", 0.45, 6)])
def test_sound_power_from_sphere_average_within_1_db(kind, size_m, noise):
    """Legacy rotor model: calibration and a tonal-dominated directivity; drawn rotor-noise parameters
    (one set per case, every direction): the calibration holds whatever the balance and shape."""
    mic = np.array([0.0, 0.0, 1.5])
    rotor_noise = ac.LEGACY_ROTOR_NOISE if noise == "legacy" else ac.draw_rotor_noise(rng_for(noise, "acoustics", 99))
    levels = []
    for k, d in enumerate(_fibonacci_sphere(16)):
        track, t = _hover_track(kind, size_m, mic + 10.0 * d)
        x, _ = ac.synthesize_target(track, t, mic, FS // 2, FS, 293.15, 0.7, rng_for(k, "acoustics", 0),
                                    rotor_noise=rotor_noise)
        levels.append(_a_level_db(x[FS // 20:]))
    levels = np.array(levels)
    lwa = 10 * np.log10(np.mean(10 ** (levels / 10))) + 20 * np.log10(10.0) + ac.SPHERE_DB
    assert abs(lwa - ac.sound_power_dba(kind, size_m)) < 1.0
    if noise == "legacy":
        assert levels.max() - levels.min() > 2.0                  # directivity: not omnidirectional


def test_level_rises_with_rpm_of_the_flight_state():
    mic = np.array([0.0, 0.0, 1.5])
    levels = {}
    for factor in (1.0, 1.1):
        track, t = _hover_track("quadcopter", 0.45, [0.0, 20.0, 10.0], rpm_factor=factor)
        x, _ = ac.synthesize_target(track, t, mic, FS // 2, FS, 293.15, 0.7, rng_for(4, "acoustics", 0))
        levels[factor] = _a_level_db(x[FS // 20:])
    # tonal pressure ~ rpm^2 (+1.66 dB), broadband ~ rpm^2.5 (+2.07 dB), lines move up the A-curve
    assert 1.5 < levels[1.1] - levels[1.0] < 3.0


def test_drawn_rotor_noise_stays_in_its_documented_ranges():
    r = ac.ROTOR_NOISE_RANGES
    for k in range(50):
        n = ac.draw_rotor_noise(rng_for(k, "acoustics", 7))
        assert r["harmonic_decay"][0] <= n.harmonic_decay <= r["harmonic_decay"][1]
        assert r["broadband_offset_db"][0] <= n.broadband_offset_db <= r["broadband_offset_db"][1]
        assert r["broadband_low_hz"][0] <= n.broadband_shape[0] <= r["broadband_low_hz"][1]
        assert r["broadband_tilt_db"][0] <= n.broadband_shape[2] <= r["broadband_tilt_db"][1]
        assert n.pwm_hz is None or n.pwm_hz in r["pwm_hz"]
        assert n.pole_pairs in (6, 7)


def test_pwm_whine_line_at_its_frequency():
    track, t = _track([0.0, 20.0, 10.0], [0.0, 0.0, 0.0], rpm=6000.0, duration_s=1.0)
    noise = ac.RotorNoise(pwm_hz=8000.0, pwm_level=0.5)
    x, _ = ac.synthesize_target(track, t, MIC, FS, FS, 293.15, 0.7, rng_for(1, "acoustics", 0), rotor_noise=noise)
    peak, bin_hz = _peak_hz(x, 7500.0, 8500.0)
    assert abs(peak - 8000.0) <= bin_hz


def test_helicopter_level_low_frequency_weight_and_blade_passing_modulation():
    n = 2 * FS
    t = np.arange(n) / FS
    ret = ac.Retarded(tau_s=t, dtau_dt=np.ones(n), range_m=np.ones(n))
    x = ac.helicopter_signature(ret, FS, rng_for(3, "acoustics", 0), main_rpm=390.0, main_blades=3)
    assert ac.pa_to_db_spl(np.sqrt(np.mean(x ** 2))) == pytest.approx(ac.HELICOPTER_DB_1M, abs=1e-6)
    spec = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(n, 1 / FS)
    assert spec[f < 1000].sum() > 3 * spec[f > 4000].sum()     # rotor noise is low-frequency weighted
    # the envelope of the 2-8 kHz band (blade slap, swish) beats at BPF = 3 x 390 / 60 = 19.5 Hz
    band = np.fft.irfft(np.fft.rfft(x) * ((f > 2000) & (f < 8000)), n)
    env = (band ** 2)[: n // 441 * 441].reshape(-1, 441).mean(axis=1)          # 10 ms blocks: 100 Hz
    mod = np.abs(np.fft.rfft(env - env.mean())) ** 2
    fm = np.fft.rfftfreq(env.size, 0.01)
    keep = (fm > 5) & (fm < 45)
    assert fm[keep][np.argmax(mod[keep])] == pytest.approx(19.5, abs=0.5)
    y = ac.helicopter_signature(ret, FS, rng_for(3, "acoustics", 0), main_rpm=390.0, main_blades=3)
    assert x.tobytes() == y.tobytes()
    with pytest.raises(ValueError, match="main_rpm"):
        ac.helicopter_signature(ret, FS, rng_for(3, "acoustics", 0), main_rpm=-1.0)


def test_replaced_rotor_span_moves_only_its_own_draw_by_the_linear_map():
    base = ac.draw_rotor_noise(rng_for(4, "acoustics", 7))
    assert ac.draw_rotor_noise(rng_for(4, "acoustics", 7), None) == base          # None: the module's ranges
    moved = ac.draw_rotor_noise(rng_for(4, "acoustics", 7), {"broadband_low_hz": (30.0, 120.0)})
    # rng.uniform(lo, hi) = lo + (hi - lo) u with the same u: 100-400 Hz -> 30-120 Hz is x' = 30 + 0.3 (x - 100)
    assert moved.broadband_shape[0] == pytest.approx(30.0 + 0.3 * (base.broadband_shape[0] - 100.0), rel=1e-12)
    assert moved.broadband_shape[1:] == base.broadband_shape[1:]
    assert (moved.harmonic_decay, moved.broadband_offset_db, moved.pwm_hz, moved.pole_pairs) == (
        base.harmonic_decay, base.broadband_offset_db, base.pwm_hz, base.pole_pairs)


@pytest.mark.parametrize("over, match", [({"colour": (1.0, 2.0)}, "rotor_noise.colour"),
                                         ({"pwm_hz": (8000.0, 9000.0)}, "rotor_noise.pwm_hz"),
                                         ({"imbalance": (0.2, 0.1)}, "rotor_noise.imbalance"),
                                         ({"harmonic_decay": (0.5,)}, "rotor_noise.harmonic_decay")])
def test_bad_rotor_span_is_named(over, match):
    with pytest.raises(ValueError, match=match):
        ac.draw_rotor_noise(rng_for(4, "acoustics", 7), over)


def test_helicopter_spans_replaced_keep_the_level_and_name_a_bad_key():
    n = FS
    t = np.arange(n) / FS
    ret = ac.Retarded(tau_s=t, dtau_dt=np.ones(n), range_m=np.ones(n))
    x = ac.helicopter_signature(ret, FS, rng_for(3, "acoustics", 0), main_rpm=390.0, main_blades=3)
    same = ac.helicopter_signature(ret, FS, rng_for(3, "acoustics", 0), main_rpm=390.0, main_blades=3, ranges={})
    assert x.tobytes() == same.tobytes()
    y = ac.helicopter_signature(ret, FS, rng_for(3, "acoustics", 0), main_rpm=390.0, main_blades=3,
                                ranges={"turbine_hz": (9000.0, 9000.0), "turbine_db": (0.0, 0.0)})
    assert ac.pa_to_db_spl(np.sqrt(np.mean(y ** 2))) == pytest.approx(ac.HELICOPTER_DB_1M, abs=1e-6)
    peak, bin_hz = _peak_hz(y, 5000.0, 14000.0)
    assert abs(peak - 9000.0) <= 0.02 * 9000.0 + bin_hz         # the tone wanders (0.5 % std, slow)
    for bad, match in (({"tail_blades": (2.0, 3.0)}, "helicopter.tail_blades"),
                       ({"tip_noise_db": (-6.0, -16.0)}, "helicopter.tip_noise_db")):
        with pytest.raises(ValueError, match=match):
            ac.helicopter_signature(ret, FS, rng_for(3, "acoustics", 0), ranges=bad)


def test_lower_rotor_broadband_edge_raises_the_low_bands_measured():
    """A 30 Hz instead of 300 Hz broadband edge (same draws otherwise): the 40-80 Hz band (under the
    first blade-passing line, BPF = 2 x 6000 / 60 = 200 Hz) rises against 2-4 kHz. With a 2nd-order
    high-pass and the tilt referenced to the edge, the broadband alone gains ~20 lg(0.87 / 0.04) ~ 27 dB at
    60 Hz relative to the 2-4 kHz band less the tilt's 3 dB/oct x 3.3 oct; assert > 10 dB."""
    track, t = _track([0.0, 20.0, 10.0], [0.0, 0.0, 0.0], rpm=6000.0, duration_s=1.0)

    def ratio_db(low_hz: float) -> float:
        over = {"broadband_low_hz": (low_hz, low_hz), "broadband_tilt_db": (-3.0, -3.0)}
        x, _ = ac.synthesize_target(track, t, MIC, FS, FS, 293.15, 0.7, rng_for(1, "acoustics", 0),
                                    rotor_noise_ranges=over)
        spec = np.abs(np.fft.rfft(x)) ** 2
        f = np.fft.rfftfreq(x.size, 1 / FS)
        return 10 * np.log10(spec[(f > 40) & (f < 80)].sum() / spec[(f > 2000) & (f < 4000)].sum())

    assert ratio_db(30.0) - ratio_db(300.0) > 10.0


def test_retuned_rotors_move_the_blade_passing_line_and_keep_the_sound_power():
    """A quad retuned to hover at 0.8 x the size law (timeline.retuned_rotors) has its blade-passing line
    at 0.8 x the law's and, its thrust reference following, the same sound power; scaling the rotor
    speeds without recording the hover rpm would read as a lighter flight state (~2 dB quieter)."""
    import dataclasses

    from simulator.physics.timeline import retuned_rotors, rotor_hover_rpm

    mic = np.array([0.0, 0.0, 1.5])
    law = rotor_hover_rpm("quadcopter", 0.45)
    track, t = _hover_track("quadcopter", 0.45, [0.0, 10.0, 6.0], duration_s=1.2)
    tuned = retuned_rotors(track, 0.8 * law)
    stale = dataclasses.replace(tuned, hover_rpm=None)
    out = {}
    for name, tr in (("law", track), ("tuned", tuned), ("stale", stale)):
        x, _ = ac.synthesize_target(tr, t, mic, FS, FS, 293.15, 0.7, rng_for(2, "acoustics", 0),
                                    rotor_noise=ac.LEGACY_ROTOR_NOISE)
        spec = np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2
        f = np.fft.rfftfreq(x.size, 1.0 / FS)
        band = (f > 100) & (f < 260)
        out[name] = (f[band][np.argmax(spec[band])], _a_level_db(x[FS // 20:]))
    bpf = 2 * law / 60.0
    assert out["law"][0] == pytest.approx(bpf, rel=0.03)
    assert out["tuned"][0] == pytest.approx(0.8 * bpf, rel=0.03)
    assert abs(out["tuned"][1] - out["law"][1]) < 1.0
    assert out["law"][1] - out["stale"][1] > 1.5


def test_helicopter_tail_lines_peak_at_the_drawn_harmonic():
    """``tail_peak_harmonic`` moves the strongest tail-rotor line from the first harmonic (k^-1, the module
    default (1, 1), byte-identical) to the drawn one; the lines below it rise as (k / peak)^2."""
    n = 2 * FS
    ret = ac.Retarded(tau_s=np.arange(n) / FS, dtau_dt=np.ones(n), range_m=np.ones(n))
    quiet = {k: (-80.0, -80.0) for k in ("tip_noise_db", "thump_db", "slap_db", "turbine_db", "turbine_noise_db")}
    spans = {**quiet, "tail_db": (20.0, 20.0), "tail_ratio": (5.0, 5.0)}

    def heli(extra):
        return ac.helicopter_signature(ret, FS, rng_for(4, "acoustics", 0), main_rpm=390.0, main_blades=3,
                                       ranges={**spans, **extra})

    default, first, third = heli({}), heli({"tail_peak_harmonic": (1.0, 1.0)}), heli({"tail_peak_harmonic": (3.0, 3.0)})
    assert default.tobytes() == first.tobytes()
    bpf, _ = _peak_hz(first, 40.0, 200.0)                       # k^-1: the fundamental is the strongest line
    f = np.fft.rfftfreq(n, 1.0 / FS)

    def line_db(x, k):
        spec = np.abs(np.fft.rfft(x * np.hanning(n))) ** 2
        return 10 * np.log10(spec[np.abs(f - k * bpf) < 2.0].max())

    assert line_db(first, 3) - line_db(first, 1) == pytest.approx(-20 * np.log10(3), abs=1.5)
    assert line_db(third, 3) - line_db(third, 1) == pytest.approx(20 * np.log10(3), abs=1.5)
    assert line_db(third, 2) - line_db(third, 1) == pytest.approx(20 * np.log10(2), abs=1.5)


def _levels_100ms_db(x: np.ndarray) -> np.ndarray:
    hop = FS // 10
    return 10 * np.log10(np.mean(x[: x.size // hop * hop].reshape(-1, hop) ** 2, axis=1))


def test_helicopter_level_fluctuation_drawn_only_when_asked_and_keeps_the_mean_power():
    """``level_fluctuation_db`` (module span (0, 0): nothing drawn, byte-identical) makes the received level
    of a hovering helicopter wander by about the drawn std (100 ms levels; the steady source's own 100 ms
    levels vary by < 1 dB) without changing its mean-square pressure (unit mean-square gain)."""
    t = np.arange(0.0, 8.0 + 1.0 / 25.0, 1.0 / 25.0)
    pos = np.tile([0.0, 150.0, 60.0], (t.size, 1))
    track = TargetTrack(1, "h", "helicopter", 12.0, pos, np.zeros_like(pos), np.tile(np.eye(3), (t.size, 1, 1)),
                        np.full((t.size, 1), 390.0), np.zeros(t.size), np.zeros(t.size), n_blades=3)
    n = 8 * FS

    def heli(ranges):
        x, _ = ac.synthesize_target(track, t, MIC, n, FS, 288.15, 0.6, rng_for(5, "acoustics", 0),
                                    helicopter_ranges=ranges)
        return x

    steady, explicit = heli(None), heli({"level_fluctuation_db": (0.0, 0.0)})
    assert steady.tobytes() == explicit.tobytes()
    wander = heli({"level_fluctuation_db": (4.0, 4.0), "level_fluctuation_hz": (1.0, 1.0)})
    assert np.std(_levels_100ms_db(steady)) < 1.0
    assert 2.5 < np.std(_levels_100ms_db(wander)) < 5.0
    assert 10 * np.log10(np.mean(wander ** 2) / np.mean(steady ** 2)) == pytest.approx(0.0, abs=1.5)


def test_helicopter_band_edge_above_16_khz_follows_the_low_pass_gain():
    """``band_high_hz`` (module span (16, 16) kHz: nothing drawn, byte-identical) is the upper edge of the
    helicopter's broadband parts. With only the rotor broadband on and no swish, the same white-noise draws
    are shaped by the 4th-order low-pass of ``shaped_gain``, so the 17-19 kHz band gains, re the 2-4 kHz band,
    the ratio of the two low-pass powers there (hand check at 18 kHz: 20 log10 of 1 / (1 + (18/16)^4) = -8.3 dB
    against 1 / (1 + (18/20)^4) = -4.4 dB, so about +3.9 dB); the total stays at HELICOPTER_DB_1M; an edge above
    0.45 fs is clamped to it."""
    n = 2 * FS
    ret = ac.Retarded(tau_s=np.arange(n) / FS, dtau_dt=np.ones(n), range_m=np.ones(n))
    quiet = {k: (-200.0, -200.0) for k in ("tip_noise_db", "thump_db", "slap_db", "tail_db", "turbine_db",
                                           "turbine_noise_db")}
    spans = {**quiet, "swish_depth": (0.0, 0.0), "broadband_tilt_db": (-6.0, -6.0), "broadband_low_hz": (300.0, 300.0)}

    def heli(extra):
        return ac.helicopter_signature(ret, FS, rng_for(6, "acoustics", 0), main_rpm=390.0, main_blades=3,
                                       ranges={**spans, **extra})

    default, explicit = heli({}), heli({"band_high_hz": (16000.0, 16000.0)})
    assert default.tobytes() == explicit.tobytes()
    wide = heli({"band_high_hz": (20000.0, 20000.0)})
    assert ac.pa_to_db_spl(np.sqrt(np.mean(wide ** 2))) == pytest.approx(ac.HELICOPTER_DB_1M, abs=1e-6)
    f = np.fft.rfftfreq(n, 1.0 / FS)
    hi, lo = (f > 17000) & (f < 19000), (f > 2000) & (f < 4000)

    def rel_db(x):
        p = np.abs(np.fft.rfft(x)) ** 2
        return 10 * np.log10(p[hi].sum() / p[lo].sum())

    lp = lambda edge: 1.0 / (1.0 + (f / edge) ** 4)            # noqa: E731 (amplitude, as shaped_gain)
    gain16, gain20 = lp(16000.0), lp(20000.0)
    # white noise through the same tilt: the band ratio moves by the ratio of the low-pass powers
    tilt_w = f[hi] ** (-6.0 / 6.0206 * 2)
    expected = 10 * np.log10(np.sum(tilt_w * gain20[hi] ** 2) / np.sum(tilt_w * gain16[hi] ** 2))
    expected -= 10 * np.log10(np.sum(f[lo] ** (-6.0 / 6.0206 * 2) * gain20[lo] ** 2)
                              / np.sum(f[lo] ** (-6.0 / 6.0206 * 2) * gain16[lo] ** 2))
    assert 3.4 < expected < 4.4
    assert rel_db(wide) - rel_db(default) == pytest.approx(expected, abs=0.5)
    clamped = heli({"band_high_hz": (30000.0, 30000.0)})
    assert clamped.tobytes() == heli({"band_high_hz": (0.45 * FS, 0.45 * FS)}).tobytes()
