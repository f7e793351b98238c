"""Surface temperatures of terrain (ground covers, tree canopies, buildings, masts) relative to air.

A linearised surface energy balance (Monteith & Unsworth, *Principles of Environmental Physics*,
4th ed. 2013, ch. 13-16; Oke, *Boundary Layer Climates*, 1987, ch. 1-2):

    h (T_s - T_air) = a_s K_down - eps (1 - eps_sky) sigma T_air^4

- K_down: global horizontal irradiance of the clear sky, Haurwitz (1945):
  1098 sin(el) exp(-0.057 / sin(el)) W m^-2, reduced by cloud cover c with Kasten & Czeplak (1980):
  x (1 - 0.75 c^3.4).
- eps_sky: clear-sky effective emissivity of Brutsaert (1975), 1.24 (e / T)^(1/7) with the vapour
  pressure e in hPa, raised by cloud to eps_sky + (1 - eps_sky) c (an overcast base radiates as a
  blackbody near air temperature).
- h: an effective heat-transfer coefficient per surface (convection, evapotranspiration, storage),
  one in sunshine and one at night (scenes.terrain_assets), blended over the first 10 degrees of sun
  elevation. This is a quasi-steady balance: no thermal inertia (the afternoon lag of soil and
  buildings is not modelled).
Pure numpy.
"""
from __future__ import annotations

import math

import numpy as np

from scenes.terrain_assets import TerrainAsset

STEFAN_BOLTZMANN = 5.670374419e-8
SOLAR_BLEND_DEG = 10.0


def clear_sky_ghi_w_m2(sun_elevation_deg: float) -> float:
    """Global horizontal irradiance of a clear sky, Haurwitz (1945); 0 with the sun below the horizon."""
    s = math.sin(math.radians(sun_elevation_deg))
    if s <= 0.0:
        return 0.0
    return 1098.0 * s * math.exp(-0.057 / s)


def cloud_factor(cloud_cover: float) -> float:
    """Kasten & Czeplak (1980): global irradiance under cloud cover c (0-1) relative to clear sky."""
    return 1.0 - 0.75 * float(cloud_cover) ** 3.4


def sky_emissivity(air_temperature_k: float, relative_humidity: float, cloud_cover: float = 0.0) -> float:
    """Effective longwave emissivity of the sky: Brutsaert (1975) clear sky, cloud-filled by c."""
    t_c = air_temperature_k - 273.15
    e_hpa = relative_humidity * 6.1094 * math.exp(17.625 * t_c / (t_c + 243.04))   # Magnus (Alduchov & Eskridge 1996)
    clear = 1.24 * (max(e_hpa, 1e-6) / air_temperature_k) ** (1.0 / 7.0)
    clear = min(clear, 1.0)
    return clear + (1.0 - clear) * float(cloud_cover)


def surface_offset_k(asset: TerrainAsset, sun_elevation_deg: float, air_temperature_k: float,
                     relative_humidity: float, cloud_cover: float = 0.0, emissivity: float | None = None) -> float:
    """T_surface - T_air (K) of a horizontal surface of this asset in the quasi-steady balance."""
    eps = asset.emissivity if emissivity is None else float(emissivity)
    if eps < 0.0 or eps > 1.0:
        raise ValueError(f"emissivity must lie in [0, 1], got {eps}")
    shortwave = asset.solar_absorptivity * clear_sky_ghi_w_m2(sun_elevation_deg) * cloud_factor(cloud_cover)
    longwave = eps * (1.0 - sky_emissivity(air_temperature_k, relative_humidity, cloud_cover)) \
        * STEFAN_BOLTZMANN * air_temperature_k ** 4
    day = float(np.clip(sun_elevation_deg / SOLAR_BLEND_DEG, 0.0, 1.0))
    h = asset.h_night_w_m2k + (asset.h_day_w_m2k - asset.h_night_w_m2k) * day
    return (shortwave - longwave) / h
