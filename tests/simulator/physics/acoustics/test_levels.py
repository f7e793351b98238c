"""Levels and standards: ISO 9613-1 absorption and 9613-2 ground attenuation, speed of sound,
A-weighting, EU class limits and sound power, rotor directivity."""
from __future__ import annotations

import numpy as np
import pytest

from simulator.physics import acoustics as ac
from tests.simulator.physics.acoustics.helpers import _fibonacci_sphere


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


def test_directivity_is_power_normalised_and_shaped():
    d = _fibonacci_sphere(4000)
    up = np.tile([0.0, 0.0, 1.0], (d.shape[0], 1))
    tonal, broad = ac.rotor_directivity(d, up)
    assert np.mean(tonal ** 2) == pytest.approx(1.0, abs=0.01)
    assert np.mean(broad ** 2) == pytest.approx(1.0, abs=0.01)
    in_plane, below45, below = ac.rotor_directivity(np.array([[1.0, 0, 0], [1.0, 0, -1.0], [0, 0, -1.0]]), up[:3])[0]
    assert below45 > in_plane and below45 > below                 # tonal lobe 45 deg off the rotor plane
    assert 20 * np.log10(below45 / in_plane) == pytest.approx(10 * np.log10(1.35 / 0.35), abs=1e-9)


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
