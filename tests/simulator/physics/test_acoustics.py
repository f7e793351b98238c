"""Audio synthesis: rotor lines, Doppler, spreading + ISO 9613-1 absorption, bad input, determinism."""
from __future__ import annotations

import numpy as np
import pytest

from simulator.physics import acoustics as ac
from simulator.physics.timeline import TargetTrack
from simulator.seeding import rng_for

FS = ac.AUDIO_SAMPLE_RATE_HZ
MIC = np.array([0.0, 0.0, 1.5])


def _track(position_m, velocity_mps, rpm=6000.0, duration_s=3.0, kind="quadcopter", n_rotors=4, fps=28.0):
    t = np.arange(0.0, duration_s + 1.0 / fps, 1.0 / fps)
    pos = np.asarray(position_m, float) + np.outer(t, np.asarray(velocity_mps, float))
    vel = np.tile(np.asarray(velocity_mps, float), (t.size, 1))
    zeros = np.zeros(t.size)
    track = TargetTrack(target_id=1, name="d", kind=kind, size_m=0.45, position_m=pos, velocity_mps=vel,
                        rotation=np.tile(np.eye(3), (t.size, 1, 1)), rotor_rpm=np.full((t.size, n_rotors), rpm),
                        rotor_angle_rad=zeros, flap_phase_rad=zeros, n_blades=2)
    return track, t


def _peak_hz(x: np.ndarray, lo: float, hi: float, pad: int = 8) -> tuple[float, float]:
    """Frequency of the largest spectral line in [lo, hi] (zero-padded FFT) and the unpadded bin width."""
    n = x.size
    spec = np.abs(np.fft.rfft(x * np.hanning(n), n * pad))
    f = np.fft.rfftfreq(n * pad, 1.0 / FS)
    band = (f >= lo) & (f <= hi)
    return float(f[band][np.argmax(spec[band])]), FS / n


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


@pytest.mark.parametrize("freq_hz", [2000.0, 6000.0])
def test_level_falls_6db_per_doubling_plus_absorption(freq_hz):
    n = FS
    tone = np.sin(2 * np.pi * freq_hz * np.arange(n) / FS)
    levels = []
    for r in (300.0, 600.0):
        y = ac.propagate(tone, np.full(n, r), FS, 293.15, 0.7)
        levels.append(10 * np.log10(np.mean(y[FS // 4: -FS // 4] ** 2)))
    alpha = float(ac.iso9613_absorption_db_per_m(freq_hz, 293.15, 0.7))
    expected = 20 * np.log10(2.0) + alpha * 300.0
    assert alpha * 300.0 > 2.0                  # absorption matters at these ranges
    assert abs((levels[0] - levels[1]) - expected) < 0.05


@pytest.mark.parametrize("temp_c,rh,freq_hz,table_db_per_km", [
    # ISO 9613-2 Table 2 (computed with ISO 9613-1 at exact mid-band frequencies, 101.325 kPa)
    (20.0, 0.70, 1000.0, 5.0), (20.0, 0.70, 10 ** 3.3, 9.0), (20.0, 0.70, 10 ** 3.6, 22.9),
    (20.0, 0.70, 10 ** 3.9, 76.6), (10.0, 0.70, 1000.0, 3.7), (10.0, 0.70, 10 ** 3.6, 32.8),
    (15.0, 0.20, 1000.0, 8.2), (15.0, 0.20, 10 ** 3.6, 88.8), (15.0, 0.50, 10 ** 2.7, 2.2),
])
def test_iso9613_absorption_matches_table(temp_c, rh, freq_hz, table_db_per_km):
    alpha_km = 1000 * float(ac.iso9613_absorption_db_per_m(freq_hz, 273.15 + temp_c, rh))
    assert abs(alpha_km - table_db_per_km) <= max(0.051, 0.004 * table_db_per_km)


def test_speed_of_sound():
    assert ac.speed_of_sound_mps(273.15) == pytest.approx(331.3)
    assert ac.speed_of_sound_mps(293.15) == pytest.approx(343.2, abs=0.1)


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


def test_ambience_levels_determinism_and_stream_independence():
    n = FS // 2
    amb = ac.Ambience(wind_db=50.0, traffic_db=45.0, rain_db=None, birdsong_db=40.0)
    a = ac.synthesize_ambience(amb, n, FS, 11)
    b = ac.synthesize_ambience(amb, n, FS, 11)
    c = ac.synthesize_ambience(amb, n, FS, 12)
    with_rain = ac.synthesize_ambience(amb.model_copy(update={"rain_db": 55.0}), n, FS, 11)
    for name in a:
        assert a[name].tobytes() == b[name].tobytes()
        assert not np.array_equal(a[name], c[name])
        assert np.array_equal(a[name], with_rain[name])       # adding a bed shifts no other bed
    assert ac.pa_to_db_spl(np.sqrt(np.mean(a["wind"] ** 2))) == pytest.approx(50.0, abs=1e-6)
    assert ac.pa_to_db_spl(np.sqrt(np.mean(with_rain["rain"] ** 2))) == pytest.approx(55.0, abs=1e-6)


def test_wav_round_trip(tmp_path):
    import soundfile

    x = (0.01 * np.sin(np.arange(4410) / 7.0)).astype(np.float32)
    path = ac.write_wav(tmp_path / "a.wav", x, FS, full_scale_pa=0.1)
    y, rate = soundfile.read(str(path), dtype="float32")
    assert rate == FS and np.allclose(y, x / 0.1, atol=1e-7)
    raw = path.read_bytes()
    peak = raw.find(b"PEAK")
    assert peak > 0 and raw[peak + 12:peak + 16] == b"\0\0\0\0"      # no wall-clock stamp: byte-identical files


# --------------------------------------------------------------------------------------------
# Calibrated sources: A-weighting, EU class limits, sound power, directivity, ISO 9613-2 ground
# --------------------------------------------------------------------------------------------

def _a_level_db(x: np.ndarray) -> float:
    spec = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(x.size, 1.0 / FS)
    weights = 10 ** (ac.a_weighting_db(np.maximum(f, 1.0)) / 10)
    return float(10 * np.log10(2 * np.sum(spec * weights) / x.size ** 2 / ac.P_REF_PA ** 2))


def test_a_weighting_matches_iec_61672_table():
    # IEC 61672-1 Table 3 values at the exact base-10 band frequencies 10^(n/10) Hz (31.5 Hz = 10^1.5)
    for n, a in [(15, -39.4), (18, -26.2), (20, -19.1), (24, -8.6), (30, 0.0), (33, 1.2), (36, 1.0), (39, -1.1),
                 (40, -2.5)]:
        assert float(ac.a_weighting_db(10 ** (n / 10))) == pytest.approx(a, abs=0.05)


def test_eu_class_limits_by_mass():
    assert ac.eu_class(0.249) == "C0" and ac.eu_class(0.5) == "C1" and ac.eu_class(2.0) == "C2"
    assert [ac.eu_sound_power_limit_db(0.5, p) for p in (0, 1, 2)] == [85.0, 83.0, 81.0]
    # C2 at 2 kg, +4 years: 81 + 18.5 lg(2000 / 900) = 87.42 dB
    assert ac.eu_sound_power_limit_db(2.0, 2) == pytest.approx(87.416, abs=0.001)
    assert ac.eu_sound_power_limit_db(0.2) is None and ac.eu_sound_power_limit_db(6.0) is None
    with pytest.raises(ValueError, match="phase"):
        ac.eu_sound_power_limit_db(0.5, 3)


def test_default_sound_power_of_the_reference_quad():
    # 0.45 m quad: 0.75 kg (C1), 83 + 18.5 lg(0.75 / 0.9) = 81.54 dB L_WA -> 70.55 dBA at 1 m (free field)
    assert ac.drone_mass_kg("quadcopter", 0.45) == pytest.approx(0.75)
    lwa = ac.sound_power_dba("quadcopter", 0.45)
    assert lwa == pytest.approx(81.535, abs=0.01)
    assert 70.0 <= lwa - ac.SPHERE_DB <= 74.0
    for size in (0.2, 0.3, 0.45, 0.5):                     # never above the class limit at entry into force
        m = ac.drone_mass_kg("quadcopter", size)
        cap = ac.eu_sound_power_limit_db(m, 0)
        assert cap is None or ac.sound_power_dba("quadcopter", size) <= cap


def _fibonacci_sphere(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5 ** 0.5) * i
    return np.stack([np.sqrt(1 - z ** 2) * np.cos(phi), np.sqrt(1 - z ** 2) * np.sin(phi), z], -1)


def _hover_track(kind: str, size_m: float, position_m, rpm_factor: float = 1.0, duration_s: float = 0.6):
    from simulator.physics.timeline import rotor_hover_rpm

    t = np.arange(0.0, duration_s, 1.0 / 28)
    pos = np.tile(np.asarray(position_m, float), (t.size, 1))
    n_rotors = 6 if kind == "hexacopter" else 4
    rpm = np.full((t.size, n_rotors), rpm_factor * rotor_hover_rpm(kind, size_m))
    zeros = np.zeros(t.size)
    return TargetTrack(1, "d", kind, size_m, pos, np.zeros_like(pos), np.tile(np.eye(3), (t.size, 1, 1)), rpm,
                       zeros, zeros, n_blades=2), t


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


def test_directivity_is_power_normalised_and_shaped():
    d = _fibonacci_sphere(4000)
    up = np.tile([0.0, 0.0, 1.0], (d.shape[0], 1))
    tonal, broad = ac.rotor_directivity(d, up)
    assert np.mean(tonal ** 2) == pytest.approx(1.0, abs=0.01)
    assert np.mean(broad ** 2) == pytest.approx(1.0, abs=0.01)
    in_plane, below45, below = ac.rotor_directivity(np.array([[1.0, 0, 0], [1.0, 0, -1.0], [0, 0, -1.0]]), up[:3])[0]
    assert below45 > in_plane and below45 > below                 # tonal lobe 45 deg off the rotor plane
    assert 20 * np.log10(below45 / in_plane) == pytest.approx(10 * np.log10(1.35 / 0.35), abs=1e-9)


def test_level_rises_with_rpm_of_the_flight_state():
    mic = np.array([0.0, 0.0, 1.5])
    levels = {}
    for factor in (1.0, 1.1):
        track, t = _hover_track("quadcopter", 0.45, [0.0, 20.0, 10.0], rpm_factor=factor)
        x, _ = ac.synthesize_target(track, t, mic, FS // 2, FS, 293.15, 0.7, rng_for(4, "acoustics", 0))
        levels[factor] = _a_level_db(x[FS // 20:])
    # tonal pressure ~ rpm^2 (+1.66 dB), broadband ~ rpm^2.5 (+2.07 dB), lines move up the A-curve
    assert 1.5 < levels[1.1] - levels[1.0] < 3.0


def test_iso9613_ground_attenuation_hand_values():
    bands = ac.iso9613_ground_attenuation_db(50.0, 1.5, 200.0, 0.0)
    assert np.allclose(bands, -3.0)                               # hard ground, q = 0: +3 dB everywhere
    soft = ac.iso9613_ground_attenuation_db(50.0, 1.5, 200.0, 1.0)
    # 500 Hz, receiver region: -1.5 + 1.5 + 14 exp(-0.46 x 1.5^2)(1 - exp(-4)); source region (50 m): 0
    c_r = 14.0 * np.exp(-0.46 * 2.25) * (1 - np.exp(-4.0))
    assert soft[3] == pytest.approx(c_r, abs=1e-9)
    assert soft[0] == pytest.approx(-3.0) and np.allclose(soft[5:], 0.0)
    # far (q > 0): the middle region adds -3q (1 - G); d = 2000 m, hs + hr = 51.5 m: q = 1 - 1545 / 2000
    mixed = ac.iso9613_ground_attenuation_db(50.0, 1.5, 2000.0, 0.5)
    assert mixed[6] == pytest.approx(-1.5 * 0.5 * 2 - 3 * (1 - 1545 / 2000) * 0.5, abs=1e-9)
    with pytest.raises(ValueError, match="ground_factor"):
        ac.iso9613_ground_attenuation_db(50.0, 1.5, 200.0, 1.5)


def test_ground_effect_sign_and_size_on_a_tone():
    n = FS
    tone = np.sin(2 * np.pi * 500.0 * np.arange(n) / FS)
    kw = {"source_height_m": np.full(n, 50.0), "receiver_height_m": 1.5, "horizontal_range_m": np.full(n, 200.0)}
    free = ac.propagate(tone, np.full(n, 206.2), FS, 293.15, 0.7)
    hard = ac.propagate(tone, np.full(n, 206.2), FS, 293.15, 0.7, ground_factor=0.0, **kw)
    soft = ac.propagate(tone, np.full(n, 206.2), FS, 293.15, 0.7, ground_factor=1.0, **kw)
    lvl = {k: 10 * np.log10(np.mean(v[FS // 4: -FS // 4] ** 2))
           for k, v in (("free", free), ("hard", hard), ("soft", soft))}
    assert lvl["hard"] - lvl["free"] == pytest.approx(3.0, abs=0.05)          # reflection adds 3 dB
    expected_soft = -14.0 * np.exp(-0.46 * 2.25) * (1 - np.exp(-4.0))         # 500 Hz over porous ground
    assert lvl["soft"] - lvl["free"] == pytest.approx(expected_soft, abs=0.05)
    assert lvl["soft"] < lvl["free"] < lvl["hard"]


def test_scene_audio_is_deterministic_and_reports_sound_power():
    from scenes.loader import load_scenario
    from simulator.physics.timeline import build_timeline

    tl = build_timeline(load_scenario("clear_day_quad"), 0, n_frames=15)
    a = ac.synthesize_audio(tl, 5, duration_s=0.5)
    b = ac.synthesize_audio(tl, 5, duration_s=0.5)
    assert a.mix_pa.tobytes() == b.mix_pa.tobytes()
    name = tl.targets[0].name
    assert a.sound_power_dba[name] == pytest.approx(ac.sound_power_dba(tl.targets[0].kind, tl.targets[0].size_m))
    louder = ac.synthesize_audio(tl, 5, duration_s=0.5, sound_power_db={name: a.sound_power_dba[name] + 6.0})
    ratio = np.sqrt(np.mean(louder.targets_pa[name] ** 2) / np.mean(a.targets_pa[name] ** 2))
    assert 20 * np.log10(ratio) == pytest.approx(6.0, abs=0.01)


# --------------------------------------------------------------------------------------------
# Issue 24: drawn rotor noise, helicopter, outdoor beds, per-rotor RPM fluctuation
# --------------------------------------------------------------------------------------------

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


def test_ambience_draws_skip_beds_that_are_never_on():
    base = ac.AmbienceDistribution(rustle_probability=0.0, aircraft_probability=0.0)
    a = ac.draw_ambience(np.random.default_rng(5), base)
    assert a.rustle_db is None and a.aircraft_db is None and 16.0 <= a.wind_db <= 34.0
    # a bed with probability 0 takes no draws: appending one at the end leaves the others' draws alone
    with_rustle = ac.draw_ambience(np.random.default_rng(5), base.model_copy(update={"rustle_probability": 1.0}))
    assert with_rustle.rustle_db is not None
    assert (with_rustle.wind_db, with_rustle.traffic_db, with_rustle.residual_db) == (a.wind_db, a.traffic_db,
                                                                                      a.residual_db)
    with pytest.raises(ValueError, match="rain_db: low 50.0 exceeds high 40.0"):
        ac.AmbienceDistribution(rain_db=(50.0, 40.0))


def test_outdoor_beds_levels_and_independence():
    n = FS
    amb = ac.Ambience(wind_db=40.0, residual_db=42.0, rustle_db=35.0, aircraft_db=45.0)
    a = ac.synthesize_ambience(amb, n, FS, 5)
    without = ac.synthesize_ambience(amb.model_copy(update={"rustle_db": None}), n, FS, 5)
    for name, level in (("residual", 42.0), ("rustle", 35.0), ("aircraft", 45.0)):
        assert ac.pa_to_db_spl(np.sqrt(np.mean(a[name] ** 2))) == pytest.approx(level, abs=1e-6)
    for name in without:
        assert np.array_equal(a[name], without[name])          # removing a bed shifts no other bed
    spec = np.abs(np.fft.rfft(a["residual"])) ** 2
    f = np.fft.rfftfreq(n, 1 / FS)
    centres = 1000.0 * 10 ** (np.arange(-13, 11) / 10)          # 1/3-octave bands 50 Hz-10 kHz
    bands = np.array([spec[(f >= c * 10 ** -0.05) & (f < c * 10 ** 0.05)].sum() for c in centres])
    one_k = 10 * np.log10(bands[13] / bands.max())
    assert one_k > -20.0      # no hole at 0.6-1.6 kHz (the wind bed alone is ~35 dB down there)


def test_rotor_rpm_fluctuation_is_zero_sum_and_correlated():
    from simulator.physics.timeline import RPM_FLUCTUATION_STD, rotor_rpm_fluctuation

    f = rotor_rpm_fluctuation(rng_for(1, "rotor_detune", 0), 20_000, 4, 30.0)
    assert np.allclose(f.mean(axis=1), 1.0)
    std = float(np.std(f - 1.0))
    assert RPM_FLUCTUATION_STD[0] * 0.8 <= std <= RPM_FLUCTUATION_STD[1] * 1.2
    x = f[:, 0] - 1.0
    lag1 = float(np.corrcoef(x[:-1], x[1:])[0, 1])
    assert lag1 > 0.5                                           # a Gauss-Markov process, not white jitter
    assert np.array_equal(rotor_rpm_fluctuation(rng_for(1, "rotor_detune", 0), 10, 1, 30.0), np.ones((10, 1)))


# --------------------------------------------------------------------------------------------
# Issue 24, fourth pass: spans of the drawn source parameters replaced per call
# --------------------------------------------------------------------------------------------

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


def test_machinery_bed_has_its_harmonics_at_their_levels_and_its_level():
    m = ac.Machinery(level_db=40.0, fundamental_hz=120.0, harmonic_db=(0.0, -6.0, -12.0))
    x = ac.machinery_bed(rng_for(2, "acoustics", ac.MACHINERY_SOURCE_INDEX), 4 * FS, FS, m)
    assert ac.pa_to_db_spl(np.sqrt(np.mean(x ** 2))) == pytest.approx(40.0, abs=1e-6)
    spec = np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2
    f = np.fft.rfftfreq(x.size, 1.0 / FS)
    line = [10 * np.log10(spec[(f > k * 120.0 - 3) & (f < k * 120.0 + 3)].max()) for k in (1, 2, 3, 4)]
    assert line[1] - line[0] == pytest.approx(-6.0, abs=1.5) and line[2] - line[0] == pytest.approx(-12.0, abs=1.5)
    assert line[3] < line[0] - 40                                      # no 4th harmonic was asked for
    between = 10 * np.log10(np.median(spec[(f > 150) & (f < 210)]))
    assert line[0] - between > 40                                      # lines, not noise
    # a wandering machine spreads its line: less of the first harmonic's power in its +-3 Hz bin
    wandering = ac.machinery_bed(rng_for(2, "acoustics", ac.MACHINERY_SOURCE_INDEX), 4 * FS, FS,
                                 m.model_copy(update={"wander": 0.05}))
    ws = np.abs(np.fft.rfft(wandering * np.hanning(x.size))) ** 2
    peak = lambda s: s[(f > 117) & (f < 123)].sum() / s[(f > 60) & (f < 180)].sum()  # noqa: E731
    assert peak(spec) > 0.95 and peak(ws) < 0.5


def test_machinery_draws_mains_hum_or_a_machine_and_a_fixed_number_of_draws():
    never = ac.MachineryDistribution(probability=0.0)
    rng = np.random.default_rng(3)
    assert ac.draw_machinery(rng, never) is None
    assert rng.random() == np.random.default_rng(3).random()            # probability 0 takes no draws
    mains = ac.MachineryDistribution(probability=1.0, mains_probability=1.0, mains_harmonics=(3, 5))
    for seed in range(5):
        m = ac.draw_machinery(np.random.default_rng(seed), mains)
        assert m.fundamental_hz == 50.0 and m.wander == 0.0 and 3 <= len(m.harmonic_db) <= 5
        assert max(m.harmonic_db) == 0.0
    machine = ac.MachineryDistribution(probability=1.0, mains_probability=0.0, fundamental_hz=(80.0, 90.0),
                                       harmonics=(2, 2), wander=(0.01, 0.01))
    m = ac.draw_machinery(np.random.default_rng(4), machine)
    assert 80.0 <= m.fundamental_hz <= 90.0 and len(m.harmonic_db) == 2 and m.wander == 0.01
    # on or off, the same number of draws: what is drawn after the bed does not depend on the outcome
    off = machine.model_copy(update={"probability": 1e-12})
    a, b = np.random.default_rng(6), np.random.default_rng(6)
    assert ac.draw_machinery(a, off) is None and ac.draw_machinery(b, machine) is not None
    assert a.random() == b.random()
    with pytest.raises(ValueError, match="harmonics"):
        ac.MachineryDistribution(harmonics=(0, 3))
    with pytest.raises(ValueError, match="level_db: low 30.0 exceeds high 20.0"):
        ac.MachineryDistribution(level_db=(30.0, 20.0))


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


def test_wind_bed_band_edge_and_tilt():
    """The defaults (15-500 Hz, -6 dB/octave) are the bed of before, byte-identical; a 200 Hz edge and -9
    dB/octave put ~9 dB per octave between the 40 and 80 Hz octaves and nothing above the edge."""
    n = 4 * FS
    default = ac.wind_bed(rng_for(1, "acoustics", 0), n, FS, 60.0, 0.0)
    explicit = ac.wind_bed(rng_for(1, "acoustics", 0), n, FS, 60.0, 0.0, high_hz=500.0, tilt_db_per_octave=-6.0)
    assert default.tobytes() == explicit.tobytes()
    steep = ac.wind_bed(rng_for(1, "acoustics", 0), n, FS, 60.0, 0.0, high_hz=200.0, tilt_db_per_octave=-9.0)
    assert float(ac.pa_to_db_spl(np.sqrt(np.mean(steep ** 2)))) == pytest.approx(60.0, abs=0.01)
    spec = np.abs(np.fft.rfft(steep)) ** 2
    f = np.fft.rfftfreq(n, 1.0 / FS)
    octave = lambda lo: 10 * np.log10(spec[(f >= lo) & (f < 2 * lo)].sum() / lo)   # noqa: E731  (per Hz)
    assert octave(40.0) - octave(80.0) == pytest.approx(9.0, abs=1.5)
    assert spec[f > 400].sum() < 1e-4 * spec.sum()


def test_helicopter_band_edge_above_16_khz_follows_the_low_pass_gain():
    """``band_high_hz`` (module span (16, 16) kHz: nothing drawn, byte-identical) is the upper edge of the
    helicopter's broadband parts. With only the rotor broadband on and no swish, the same white-noise draws
    are shaped by the 4th-order low-pass of ``_shaped_gain``, so the 17-19 kHz band gains, re the 2-4 kHz band,
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

    lp = lambda edge: 1.0 / (1.0 + (f / edge) ** 4)            # noqa: E731 (amplitude, as _shaped_gain)
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


def test_sim2real_bed_streams_follow_the_ambient_beds():
    """The sim2real clips' own bed streams sit after the ambient beds and the machinery bed, one index each."""
    indices = [ac.MACHINERY_SOURCE_INDEX, ac.MIC_WIND_SOURCE_INDEX, ac.BROADBAND_SOURCE_INDEX, ac.CALLS_SOURCE_INDEX,
               ac.RESONANCE_SOURCE_INDEX]
    assert indices == list(range(ac.AMBIENT_SOURCE_INDEX + 7, ac.AMBIENT_SOURCE_INDEX + 12))


def test_drifting_broadband_bed_level_band_and_flatness():
    """At its level (RMS), little beyond its (2nd-order) band edges, and flat (0 dB/octave): equal power per Hz in
    two octaves inside the band."""
    n = 4 * FS
    bed = ac.drifting_broadband_bed(rng_for(2, "acoustics", 0), n, FS, 40.0, (200.0, 4000.0), 0.0)
    assert float(ac.pa_to_db_spl(np.sqrt(np.mean(bed ** 2)))) == pytest.approx(40.0, abs=0.01)
    spec = np.abs(np.fft.rfft(bed)) ** 2
    f = np.fft.rfftfreq(n, 1.0 / FS)
    inside = spec[(f >= 200.0) & (f <= 4000.0)].sum()
    assert spec[(f < 50.0) | (f > 16000.0)].sum() < 0.01 * inside     # two octaves beyond each edge
    per_hz = lambda lo: spec[(f >= lo) & (f < 2 * lo)].sum() / lo   # noqa: E731
    assert 10 * np.log10(per_hz(400.0) / per_hz(1600.0)) == pytest.approx(0.0, abs=1.5)


def test_calls_bed_level_and_band():
    """Calls at their level (RMS), their energy above half the start band's lower edge."""
    n = 4 * FS
    calls = ac.calls_bed(rng_for(3, "acoustics", 0), n, FS, 30.0, (4000.0, 10000.0))
    assert np.any(calls)
    assert float(ac.pa_to_db_spl(np.sqrt(np.mean(calls ** 2)))) == pytest.approx(30.0, abs=0.01)
    spec = np.abs(np.fft.rfft(calls)) ** 2
    f = np.fft.rfftfreq(n, 1.0 / FS)
    assert spec[f < 2000.0].sum() < 0.05 * spec.sum()


def _gain_db(f_hz: float, centre_hz: float, gain_db: float, q: float) -> float:
    """Steady-state gain of ac.peaking_filter for a sine at f_hz (the first half second, the filter's
    start-up, left out)."""
    t = np.arange(2 * FS) / FS
    x = np.sin(2 * np.pi * f_hz * t)
    y = ac.peaking_filter(x, FS, centre_hz, gain_db, q)
    return float(20 * np.log10(np.sqrt(np.mean(y[FS // 2:] ** 2)) / np.sqrt(np.mean(x[FS // 2:] ** 2))))


@pytest.mark.parametrize("centre_hz, gain_db, q", [(1000.0, 10.0, 3.0), (300.0, 6.0, 1.5), (6000.0, 14.0, 5.0)])
def test_peaking_filter_gain_at_centre_and_far_from_it(centre_hz, gain_db, q):
    """At the centre the band-pass of iirpeak is 1 at zero phase, so the gain is gain_db exactly; what is left is
    the 1.5 s window holding a non-integer number of periods (< 0.01 dB at >= 300 Hz). Off the centre the
    band-pass is at most 1 / (q |r - 1/r|), r = f / centre (2nd-order band-pass), so the gain lies between
    0 dB (the Regalia-Mitra form never cuts for G > 1) and 20 log10(1 + (G - 1) / (q |r - 1/r|)): at r = 3 and
    1/10 under 2.3 / 0.7 dB for these three, at r = 1/100 under 0.07 dB, i.e. about 0 dB far from the peak."""
    assert _gain_db(centre_hz, centre_hz, gain_db, q) == pytest.approx(gain_db, abs=0.01)
    g = 10 ** (gain_db / 20)
    for r in (0.01, 0.1, 3.0):
        bound = 20 * np.log10(1 + (g - 1) / (q * abs(r - 1 / r)))
        measured = _gain_db(r * centre_hz, centre_hz, gain_db, q)
        assert -1e-6 < measured <= bound + 0.01, (r, measured, bound)
    assert 20 * np.log10(1 + (g - 1) / (q * abs(0.01 - 100))) < 0.07


def test_resonances_keep_the_rms_and_no_peaks_keep_the_bytes():
    x = np.random.default_rng(4).standard_normal(FS)
    y = ac.resonances(x, FS, [(500.0, 12.0, 2.0), (3000.0, 8.0, 4.0)])
    assert np.sqrt(np.mean(y ** 2)) == pytest.approx(np.sqrt(np.mean(x ** 2)), rel=1e-12)
    spec_x, spec_y = np.abs(np.fft.rfft(x)) ** 2, np.abs(np.fft.rfft(y)) ** 2
    f = np.fft.rfftfreq(x.size, 1.0 / FS)
    band = (f > 450) & (f < 550)
    assert spec_y[band].sum() / spec_y.sum() > 2.0 * spec_x[band].sum() / spec_x.sum()   # energy moved into the peak
    assert ac.resonances(x, FS, []).tobytes() == x.tobytes()
    with pytest.raises(ValueError, match="centre_hz"):
        ac.peaking_filter(x, FS, 0.6 * FS, 6.0, 2.0)
    with pytest.raises(ValueError, match="q"):
        ac.peaking_filter(x, FS, 1000.0, 6.0, 0.0)
