import numpy as np
import pytest

from simulator.physics import thermal

REFERENCE_W_SR_M2 = {220: 10.8, 260: 27.4, 288: 45.4, 300: 54.9, 320: 73.2}


@pytest.mark.parametrize("temperature_k,expected", sorted(REFERENCE_W_SR_M2.items()))
def test_band_radiance_matches_reference_within_one_percent(temperature_k, expected):
    assert thermal.band_radiance(temperature_k) == pytest.approx(expected, rel=0.01)


def test_band_radiance_derivative_at_300k():
    assert thermal.band_radiance_derivative(300.0) == pytest.approx(0.84, abs=0.01)


def test_brightness_temperature_inverts_band_radiance():
    temps = np.array([210.0, 255.5, 288.0, 310.25, 400.0])
    assert np.allclose(thermal.brightness_temperature(thermal.band_radiance(temps)), temps, atol=1e-3)


def test_low_emissivity_metal_looks_colder_than_air_under_cold_sky():
    sky = thermal.band_radiance(220.0)
    metal = thermal.surface_radiance(288.0, 0.1, sky)
    assert thermal.brightness_temperature(metal) < 288.0 - 30


def test_temperature_solve_round_trips():
    reflected = thermal.band_radiance(250.0)
    radiance = thermal.surface_radiance(301.0, 0.7, reflected)
    assert thermal.temperature_for_surface_radiance(float(radiance), 0.7, reflected) == pytest.approx(301.0, abs=1e-3)


def test_out_of_range_temperature_is_rejected():
    with pytest.raises(ValueError, match="temperature_k"):
        thermal.band_radiance(50.0)


def test_visible_extinction_is_koschmieder():
    assert thermal.visible_extinction_per_m(3912.0) == pytest.approx(1e-3)
