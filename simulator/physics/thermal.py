"""LWIR (8-14 um) band radiometry: Planck band radiance, its inverse, surface radiance and its solve.

Sky and path radiance come from simulator.physics.atmosphere (LOWTRAN7 tables).

Pure numpy + colour-science; no renderer import. Radiances are in W sr^-1 m^-2 (band-integrated).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

# NumPy >= 2.0 names it trapezoid, 1.24-1.26 (allowed by pyproject) trapz: the same rule
_trapezoid = getattr(np, "trapezoid", None) or np.trapz  # type: ignore[attr-defined]  # noqa: NPY201 (numpy < 2: only trapz)

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
        out[start:start + 2048] = _trapezoid(spectral.reshape(n_wavelengths, block.size), wavelengths_m, axis=0)
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


def visible_extinction_per_m(visibility_m: float) -> float:
    """Koschmieder: beta = 3.912 / V for a 2 % contrast threshold (the visible haze)."""
    return 3.912 / float(visibility_m)


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
