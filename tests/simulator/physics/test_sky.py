import datetime as dt

import numpy as np
import pytest

from scenes.schema import Atmosphere, Clouds, Sky, Sun
from simulator.physics import thermal
from simulator.physics.sky import ThermalSky, solar_elevation_azimuth_deg, sun_elevation_azimuth_deg


def test_solar_position_reproduces_the_nrel_spa_reference_example():
    """Reda & Andreas (2004) worked example: 2003-10-17 12:30:30 MST (UTC-7), Golden CO, 1830.14 m,
    820 mbar, 11 C: topocentric zenith 50.11162 deg (incl. refraction), azimuth 194.34024 deg."""
    el, az = solar_elevation_azimuth_deg(dt.datetime(2003, 10, 17, 19, 30, 30), 39.742476, -105.1786,
                                         altitude_m=1830.14, pressure_pa=82000.0, temperature_c=11.0)
    assert 90.0 - el == pytest.approx(50.11162, abs=2e-4)
    assert az == pytest.approx(194.34024, abs=2e-4)


def test_solar_position_agrees_with_pvlib_directly_and_accepts_aware_times():
    import pandas as pd
    from pvlib.solarposition import get_solarposition

    when = dt.datetime(2026, 6, 21, 4, 0, tzinfo=dt.timezone(dt.timedelta(hours=2)))
    ref = get_solarposition(pd.DatetimeIndex([pd.Timestamp("2026-06-21 02:00", tz="UTC")]), 52.0, 13.4,
                            method="nrel_numpy")
    el, az = solar_elevation_azimuth_deg(when, 52.0, 13.4)
    assert el == pytest.approx(float(ref["apparent_elevation"].iloc[0]), abs=1e-9)
    assert az == pytest.approx(float(ref["azimuth"].iloc[0]), abs=1e-9)
    assert sun_elevation_azimuth_deg(Sun(elevation_deg=12.0, azimuth_deg=100.0)) == (12.0, 100.0)


def _dirs(elevation_deg: np.ndarray) -> np.ndarray:
    el = np.radians(elevation_deg)
    return np.stack([np.zeros_like(el), np.cos(el), np.sin(el)], -1)


def test_clear_thermal_sky_follows_the_atmosphere_and_ground_below():
    sky = ThermalSky(Sky(), Atmosphere(air_temperature_k=288.2, absolute_humidity_g_m3=5.9, model="us_standard",
                                       visibility_m=1e9), seed=0)
    bt = thermal.brightness_temperature(sky.radiance(_dirs(np.array([90.0, 5.0, -5.0]))))
    assert bt[0] == pytest.approx(222.8, abs=1.0) and bt[1] == pytest.approx(269.1, abs=1.0)
    assert bt[2] == pytest.approx(288.2, abs=0.01)


def test_cloud_base_is_warmer_than_clear_sky_and_colder_than_air():
    clouds = Sky(clouds=Clouds(coverage=1.0, altitude_m=2000.0))
    sky = ThermalSky(clouds, Atmosphere(air_temperature_k=288.0, relative_humidity=0.5), seed=3)
    el = np.array([11.0, 30.0, 90.0])
    clear = sky.clear_radiance(_dirs(el))
    overcast = sky.radiance(_dirs(el))
    cloud_k = 288.0 - 0.0065 * 2000.0
    assert np.all(overcast > clear)
    assert np.all(thermal.brightness_temperature(overcast) < 288.0)
    # straight up through ~2 km of air the cloud base looks within a few K of its own temperature
    assert thermal.brightness_temperature(overcast[2]) == pytest.approx(cloud_k, abs=4.0)


def test_cloud_edge_width_softens_the_cover_and_keeps_the_default():
    """edge_width_sd: unset is the former 1.2 (the same field byte for byte, and left out of the dump); a wider
    edge keeps the covered area (the same threshold) but turns hard 0/1 cover into partial cover."""
    from simulator.physics.sky import DEFAULT_EDGE_WIDTH_SD, CloudField

    unset = CloudField(Clouds(coverage=0.3), seed=5)._density
    assert np.array_equal(unset, CloudField(Clouds(coverage=0.3, edge_width_sd=DEFAULT_EDGE_WIDTH_SD), seed=5)._density)
    assert "edge_width_sd" not in Clouds(coverage=0.3).model_dump()
    soft = CloudField(Clouds(coverage=0.3, edge_width_sd=4.0), seed=5)._density
    assert np.array_equal(unset > 0, soft > 0)                                   # the same clouds
    assert np.mean(soft[soft > 0] >= 1.0) < 0.5 * np.mean(unset[unset > 0] >= 1.0)   # fewer opaque cores
    with pytest.raises(ValueError, match="edge_width_sd"):
        Clouds(coverage=0.3, edge_width_sd=0.0)
