"""LWIR (8-14 um) band radiometry: Planck band radiance, its inverse, sky brightness and path.

Pure numpy + colour-science; no renderer import. Radiances are in W sr^-1 m^-2 (band-integrated).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

BAND_LOW_M = 8e-6
BAND_HIGH_M = 14e-6
_TABLE_T_MIN_K = 100.0
_TABLE_T_MAX_K = 1500.0
_TABLE_STEP_K = 0.05


def _planck_band(temperatures_k: np.ndarray, n_wavelengths: int = 601) -> np.ndarray:
    import colour

    wavelengths_m = np.linspace(BAND_LOW_M, BAND_HIGH_M, n_wavelengths)
    temps = np.atleast_1d(np.asarray(temperatures_k, dtype=np.float64))
    out = np.empty_like(temps)
    for start in range(0, temps.size, 2048):
        block = temps[start:start + 2048]
        spectral = np.asarray(colour.colorimetry.planck_law(wavelengths_m[:, None], block[None, :]))
        out[start:start + 2048] = np.trapezoid(spectral.reshape(n_wavelengths, block.size), wavelengths_m, axis=0)
    return out


@lru_cache(maxsize=1)
def _table() -> tuple[np.ndarray, np.ndarray]:
    temps = np.arange(_TABLE_T_MIN_K, _TABLE_T_MAX_K + _TABLE_STEP_K / 2, _TABLE_STEP_K)
    return temps, _planck_band(temps)


def band_radiance(temperature_k: np.ndarray | float) -> np.ndarray:
    """Blackbody radiance integrated over 8-14 um at temperature_k (W sr^-1 m^-2)."""
    temps, radiances = _table()
    t = np.asarray(temperature_k, dtype=np.float64)
    if np.any((t < _TABLE_T_MIN_K) | (t > _TABLE_T_MAX_K)):
        raise ValueError(f"temperature_k must lie in [{_TABLE_T_MIN_K}, {_TABLE_T_MAX_K}] K, got {t.min()}..{t.max()}")
    return np.interp(t, temps, radiances)


def brightness_temperature(radiance: np.ndarray | float) -> np.ndarray:
    """Inverse of band_radiance: the blackbody temperature (K) with this band radiance."""
    temps, radiances = _table()
    return np.interp(np.asarray(radiance, dtype=np.float64), radiances, temps)


def band_radiance_derivative(temperature_k: float) -> float:
    """dL/dT of the band radiance (W sr^-1 m^-2 K^-1), by a central difference."""
    return float((band_radiance(temperature_k + 0.05) - band_radiance(temperature_k - 0.05)) / 0.1)


def zenith_emissivity(relative_humidity: float) -> float:
    """Clear-sky zenith emissivity in the 8-14 um window from relative humidity (0-1).

    A documented, simple preset: 0.12 in very dry air rising to 0.32 at saturation, so that
    typical mid-latitude air (RH 0.4) gives the reference value 0.2.
    """
    return 0.12 + 0.2 * float(np.clip(relative_humidity, 0.0, 1.0))


def sky_emissivity(elevation_rad: np.ndarray, eps_zenith: float) -> np.ndarray:
    """eps(theta) = 1 - (1 - eps_zenith)^(1/cos theta), theta from zenith; 1 at and below the horizon."""
    cos_theta = np.sin(np.asarray(elevation_rad, dtype=np.float64))
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        eps = 1.0 - (1.0 - eps_zenith) ** (1.0 / np.maximum(cos_theta, 1e-9))
    return np.where(cos_theta > 1e-9, eps, 1.0)


def clear_sky_radiance(elevation_rad: np.ndarray, air_temperature_k: float, eps_zenith: float) -> np.ndarray:
    """Sky band radiance seen along a line of sight at this elevation (ground at air temperature below)."""
    return sky_emissivity(elevation_rad, eps_zenith) * band_radiance(air_temperature_k)


def lwir_extinction_per_m(visibility_m: float, relative_humidity: float) -> float:
    """LWIR extinction coefficient beta (1/m): water-vapour continuum plus haze/fog scattering.

    Vapour term 0.05-0.25 /km rising with humidity; aerosol term from the visible extinction
    (Koschmieder 3.912 / V) scaled by 0.1 for 10 um, which only matters in fog (V < 2 km).
    """
    vapour = (0.05 + 0.2 * float(np.clip(relative_humidity, 0, 1))) / 1000.0
    aerosol = 0.1 * 3.912 / float(visibility_m)
    return vapour + aerosol


def visible_extinction_per_m(visibility_m: float) -> float:
    """Koschmieder: beta = 3.912 / V for a 2 % contrast threshold."""
    return 3.912 / float(visibility_m)


def transmission(range_m: np.ndarray | float, extinction_per_m: float) -> np.ndarray:
    """tau(R) = exp(-beta R)."""
    return np.exp(-extinction_per_m * np.asarray(range_m, dtype=np.float64))


def at_sensor_radiance(target_radiance: np.ndarray, range_m: np.ndarray | float, extinction_per_m: float,
                       air_temperature_k: float) -> np.ndarray:
    """L_sensor = tau L_target + (1 - tau) L(T_air)."""
    tau = transmission(range_m, extinction_per_m)
    return tau * target_radiance + (1.0 - tau) * band_radiance(air_temperature_k)


def surface_radiance(temperature_k: np.ndarray | float, emissivity: float, reflected_radiance: float) -> np.ndarray:
    """L = eps L(T) + (1 - eps) L_reflected."""
    return emissivity * band_radiance(temperature_k) + (1.0 - emissivity) * reflected_radiance


def temperature_for_surface_radiance(radiance: float, emissivity: float, reflected_radiance: float) -> float:
    """Solve eps L(T) + (1 - eps) L_refl = radiance for T (the physical crossover temperature)."""
    if emissivity <= 0:
        raise ValueError(f"emissivity must be > 0 to solve for a temperature, got {emissivity}")
    needed = (radiance - (1.0 - emissivity) * reflected_radiance) / emissivity
    temps, radiances = _table()
    if needed < radiances[0] or needed > radiances[-1]:
        raise ValueError(
            f"no temperature in [{_TABLE_T_MIN_K}, {_TABLE_T_MAX_K}] K gives radiance {radiance:.3f} "
            f"with emissivity {emissivity} (reflected {reflected_radiance:.3f})"
        )
    return float(np.interp(needed, radiances, temps))
