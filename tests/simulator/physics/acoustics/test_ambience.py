"""Ambient beds: levels, determinism and stream independence, the drawn mix, machinery, the sim2real
beds and their stream indices."""
from __future__ import annotations

import numpy as np
import pytest

from simulator.physics import acoustics as ac
from simulator.seeding import rng_for
from tests.simulator.physics.acoustics.helpers import FS


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


def _third_octave_db(x: np.ndarray, centres: list[float]) -> np.ndarray:
    spec = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(x.size, 1 / FS)
    return np.array([10 * np.log10(spec[(f >= c * 10 ** -0.05) & (f < c * 10 ** 0.05)].sum()) for c in centres])


def test_bed_shapes_default_is_the_module_and_set_the_traffic_and_residual_spectra():
    """``BedShapes()`` and None synthesise the same samples; a fitted shape changes only the traffic and
    residual beds, keeps their levels and their draws (the rng left in the same state), and gives the
    spectra it names: traffic band levels falling with frequency at a -5.5 dB/octave PSD tilt (rising to 1 kHz
    at the module's -1.5), the residual bed's 50 Hz band further under its 100 Hz band with a 100 Hz lower edge."""
    n = 2 * FS
    amb = ac.Ambience(wind_db=40.0, traffic_db=50.0, birdsong_db=35.0, residual_db=45.0, rustle_db=35.0)
    plain = ac.synthesize_ambience(amb, n, FS, 7)
    same = ac.synthesize_ambience(amb, n, FS, 7, shapes=ac.BedShapes())
    fitted = ac.synthesize_ambience(amb, n, FS, 7, shapes=ac.BedShapes(traffic_band_hz=(100.0, 5000.0),
                                                                        traffic_tilt_db=-5.5, residual_low_hz=100.0))
    for name in plain:
        assert plain[name].tobytes() == same[name].tobytes()
        assert np.array_equal(plain[name], fitted[name]) == (name not in ("traffic", "residual")), name
    for name, level in (("traffic", 50.0), ("residual", 45.0)):
        assert ac.pa_to_db_spl(np.sqrt(np.mean(fitted[name] ** 2))) == pytest.approx(level, abs=1e-6)
    octaves = [250.0, 500.0, 1000.0, 2000.0]              # 1/3-octave bands one octave apart
    old = np.diff(_third_octave_db(plain["traffic"], octaves))
    new = np.diff(_third_octave_db(fitted["traffic"], octaves))
    assert np.all(old[:2] > 0.0)                           # the module's traffic band levels rise to 1 kHz
    assert np.all((new > -4.0) & (new < -1.0))             # the fitted ones fall by 1-4 dB per octave
    low = _third_octave_db(plain["residual"], [50.0, 100.0])
    low_fit = _third_octave_db(fitted["residual"], [50.0, 100.0])
    assert low_fit[1] - low_fit[0] > low[1] - low[0] + 3.0  # 50 Hz at least 3 dB further under 100 Hz
    for bed, kwargs in ((ac.traffic_bed, {"band_hz": (100.0, 5000.0), "tilt_db_per_octave": -5.5}),
                        (ac.residual_bed, {"low_hz": 100.0, "tilt_db": (-3.0, -1.0)})):
        a, b = np.random.default_rng(4), np.random.default_rng(4)
        bed(a, FS, FS, 40.0)
        bed(b, FS, FS, 40.0, **kwargs)
        assert a.random() == b.random(), bed.__name__          # the same draws whatever the shape
    with pytest.raises(ValueError, match="residual_tilt_db: low -3.0 exceeds high -6.0"):
        ac.BedShapes(residual_tilt_db=(-3.0, -6.0))
    with pytest.raises(ValueError, match="traffic_band_hz"):
        ac.BedShapes(traffic_band_hz=(0.0, 2500.0))
