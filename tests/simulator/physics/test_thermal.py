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


def test_the_shipped_planck_table_equals_the_computed_one():
    thermal._table.cache_clear()
    temps, loaded = thermal._table()
    assert thermal.PLANCK_TABLE_PATH.is_file() and not loaded.flags.writeable
    ref_temps, computed = thermal.compute_table()
    assert np.array_equal(temps, ref_temps)
    # equal to the last ulp or two: the lowest numpy allowed (1.24) rounds the band integral 1 ulp apart
    # (5.6e-16 relative, measured); runs read the shipped table, so their bytes do not depend on it
    np.testing.assert_allclose(loaded, computed, rtol=1e-14, atol=0)


def test_a_missing_or_misfit_planck_table_is_computed(tmp_path, monkeypatch):
    for content in (None, np.zeros(7)):
        path = tmp_path / "t.npy"
        if content is not None:
            np.save(path, content)
        monkeypatch.setattr(thermal, "PLANCK_TABLE_PATH", path)
        monkeypatch.setattr(thermal, "compute_table", lambda: ("computed", None))
        thermal._table.cache_clear()
        assert thermal._table()[0] == "computed"
    thermal._table.cache_clear()


@pytest.mark.parametrize("lo_k, hi_k, noise_k, tol_k", [(240.0, 330.0, 0.3, 1e-4), (100.0, 1500.0, 0.0, 3e-3)])
def test_brightness_temperature_f32_matches_the_table_inversion(lo_k, hi_k, noise_k, tol_k):
    rng = np.random.default_rng(3)
    kelvin = rng.uniform(lo_k, hi_k, (97, 131)) + noise_k * rng.standard_normal((97, 131))
    kelvin = np.clip(kelvin, 100.0, 1500.0)
    kelvin[0, :3] = (lo_k, hi_k, 0.5 * (lo_k + hi_k))
    radiance = thermal.band_radiance(kelvin).astype(np.float32)
    fast = thermal.brightness_temperature_f32(radiance)
    exact = thermal.brightness_temperature(radiance)
    assert fast.dtype == np.float32 and fast.shape == radiance.shape
    assert np.abs(fast - exact).max() < tol_k


def test_brightness_temperature_f32_of_a_flat_frame_and_into_a_buffer():
    radiance = np.full((5, 6), float(thermal.band_radiance(290.0)), np.float32)
    out = np.empty((5, 6), np.float32)
    assert thermal.brightness_temperature_f32(radiance, out=out) is out
    assert np.allclose(out, thermal.brightness_temperature(radiance), atol=1e-4)
    radiance[0, 0] = np.nextafter(radiance[0, 0], np.float32(np.inf))     # one ulp apart: still "flat"
    assert np.allclose(thermal.brightness_temperature_f32(radiance), 290.0, atol=1e-3)


def test_computing_the_planck_table_leaves_numpy_print_options_alone():
    """colour-science sets numpy's legacy print mode at import (repr(np.float64(0.1)) becomes
    '0.10000000000000001'), which changed CSV bytes depending on whether a run had computed the table."""
    import subprocess
    import sys

    code = ("import numpy as np; from simulator.physics import thermal; thermal._planck_band(np.array([300.0]));"
            "print(repr(float(np.float64(0.1))), np.get_printoptions()['legacy'], [np.float64(0.1)])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out[0] == "0.1" and out[1] == "False" and "0.10000000000000001" not in " ".join(out)
