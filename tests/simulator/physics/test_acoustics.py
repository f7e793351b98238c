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
    x, _ = ac.synthesize_target(track, t, MIC, 2 * FS, FS, 288.15, 0.5, rng_for(1, "acoustics", 0))
    expected = rpm / 60.0 * 2
    peak, bin_hz = _peak_hz(x, 0.6 * expected, 1.4 * expected)
    assert abs(peak - expected) <= bin_hz


@pytest.mark.parametrize("speed_mps", [25.0, -25.0])  # + approaching, - receding
def test_doppler_sign_and_size(speed_mps):
    # flying along the line through the microphone: radial speed is exactly |v|
    start = [0.0, 400.0, 1.5] if speed_mps > 0 else [0.0, 50.0, 1.5]
    track, t = _track(start, [0.0, -speed_mps, 0.0], rpm=6000.0, duration_s=4.0)
    x, _ = ac.synthesize_target(track, t, MIC, 4 * FS, FS, 293.15, 0.5, rng_for(2, "acoustics", 0))
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
