"""Terrain surface temperatures: hand-computed irradiance, cloud and sky-emissivity values, signs."""
import math

import pytest

from scenes.terrain_assets import TERRAIN_ASSETS
from simulator.physics.terrain_thermal import clear_sky_ghi_w_m2, cloud_factor, sky_emissivity, surface_offset_k


def test_haurwitz_and_kasten_czeplak_values():
    assert clear_sky_ghi_w_m2(90.0) == pytest.approx(1098.0 * math.exp(-0.057))   # 1037.2
    assert clear_sky_ghi_w_m2(30.0) == pytest.approx(549.0 * math.exp(-0.114))
    assert clear_sky_ghi_w_m2(-5.0) == 0.0
    assert cloud_factor(0.0) == 1.0 and cloud_factor(1.0) == pytest.approx(0.25)


def test_brutsaert_sky_emissivity():
    # 288.15 K, RH 0.5: e = 0.5 * 17.04 hPa = 8.52 hPa -> 1.24 (8.52 / 288.15)^(1/7) = 0.748
    assert sky_emissivity(288.15, 0.5) == pytest.approx(0.748, abs=0.002)
    assert sky_emissivity(288.15, 0.5, cloud_cover=1.0) == 1.0


def test_day_warm_night_cold_overcast_night_at_air():
    grass, asphalt, trees = TERRAIN_ASSETS["grass"], TERRAIN_ASSETS["asphalt"], TERRAIN_ASSETS["deciduous"]
    noon = surface_offset_k(grass, 50.0, 293.0, 0.5)
    assert 3.0 < noon < 10.0
    assert surface_offset_k(asphalt, 50.0, 293.0, 0.5) > noon > surface_offset_k(trees, 50.0, 293.0, 0.5) > 0
    assert -6.0 < surface_offset_k(grass, -10.0, 293.0, 0.5) < -2.0     # clear-night radiative cooling
    assert surface_offset_k(grass, -10.0, 293.0, 0.5, cloud_cover=1.0) == pytest.approx(0.0)
    # a lower emissivity loses less longwave at night
    assert surface_offset_k(grass, -10.0, 293.0, 0.5, emissivity=0.5) > surface_offset_k(grass, -10.0, 293.0, 0.5)
    with pytest.raises(ValueError, match="emissivity"):
        surface_offset_k(grass, 10.0, 293.0, 0.5, emissivity=-0.1)
