"""LWIR (8-14 um) band radiometry: Planck band radiance, its inverse, surface radiance and its solve.

Sky and path radiance come from simulator.physics.atmosphere (LOWTRAN7 tables).

Pure numpy + colour-science; no renderer import. Radiances are in W sr^-1 m^-2 (band-integrated).
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

# NumPy >= 2.0 names it trapezoid, 1.24-1.26 (allowed by pyproject) trapz: the same rule
_trapezoid = getattr(np, "trapezoid", None) or np.trapz  # type: ignore[attr-defined]  # noqa: NPY201 (numpy < 2: only trapz)

BAND_LOW_M = 8e-6
BAND_HIGH_M = 14e-6
_TABLE_T_MIN_K = 100.0
_TABLE_T_MAX_K = 1500.0
_TABLE_STEP_K = 0.05
# the table below, precomputed (simulator/physics/make_planck_table.py); equal to _planck_band's (tested)
PLANCK_TABLE_PATH = Path(__file__).resolve().parent / "data" / "planck_lwir_8_14um.npy"
BT_GRID_POINTS = 4096       # brightness_temperature_f32: interpolation nodes over each frame's radiance range


def _planck_band(temperatures_k: np.ndarray, n_wavelengths: int = 601) -> np.ndarray:
    print_options = np.get_printoptions()
    import colour

    # colour-science 0.4.x sets numpy's legacy (1.13) print mode at import, which changes repr() of
    # numpy floats and so the bytes of every CSV written later in the process: undo it
    np.set_printoptions(**print_options)

    wavelengths_m = np.linspace(BAND_LOW_M, BAND_HIGH_M, n_wavelengths)
    temps = np.atleast_1d(np.asarray(temperatures_k, dtype=np.float64))
    out = np.empty_like(temps)
    for start in range(0, temps.size, 2048):
        block = temps[start:start + 2048]
        spectral = np.asarray(colour.colorimetry.planck_law(wavelengths_m[:, None], block[None, :]))
        out[start:start + 2048] = _trapezoid(spectral.reshape(n_wavelengths, block.size), wavelengths_m, axis=0)
    return out


def table_temperatures() -> np.ndarray:
    """The Planck table's temperature grid (K): 100-1500 K in 0.05 K steps."""
    return np.arange(_TABLE_T_MIN_K, _TABLE_T_MAX_K + _TABLE_STEP_K / 2, _TABLE_STEP_K)


def compute_table() -> tuple[np.ndarray, np.ndarray]:
    """(temperatures, band radiances) computed from Planck's law (~3-5 s; ``_table`` loads it)."""
    temps = table_temperatures()
    return temps, _planck_band(temps)


@lru_cache(maxsize=1)
def _table() -> tuple[np.ndarray, np.ndarray]:
    """The shipped table (PLANCK_TABLE_PATH, ~1 ms to load), or computed if it is missing or does
    not fit the grid (then ~3-5 s per process)."""
    temps = table_temperatures()
    try:
        radiances = np.load(PLANCK_TABLE_PATH, allow_pickle=False)
    except OSError:
        return compute_table()
    if radiances.shape != temps.shape or radiances.dtype != np.float64:
        return compute_table()
    radiances.setflags(write=False)
    return temps, radiances


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


def brightness_temperature_f32(radiance: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """``brightness_temperature`` of a float32 frame, in float32, in a time independent of the
    pixels' order: the table is first interpolated onto BT_GRID_POINTS radiances equally spaced in
    log radiance over the frame's [min, max], then every pixel is interpolated linearly on that grid
    by index (no binary search: ``np.interp``'s search costs 5-10x more on a noisy frame than on a
    smooth one). Differs from ``brightness_temperature`` by < 1e-4 K over a 240-330 K frame and
    < 3e-3 K over a 100-1500 K one (tested), against a 0.05 K table step and ~0.05 K sensor noise.
    Radiances outside the table are clamped to it, as ``np.interp`` does."""
    x = np.asarray(radiance, dtype=np.float32)
    temps, radiances = _table()
    lo = min(max(float(x.min()), float(radiances[0])), float(radiances[-1]))
    hi = max(min(float(x.max()), float(radiances[-1])), lo)
    out = np.clip(x, np.float32(lo), np.float32(hi), out=out)
    log_lo, log_hi = float(np.log(np.float32(lo))), float(np.log(np.float32(hi)))
    if not log_hi > log_lo:                                          # flat (or out-of-range) frame
        out[...] = np.float32(np.interp(lo, radiances, temps))
        return out
    grid = np.exp(np.linspace(log_lo, log_hi, BT_GRID_POINTS))
    nodes = np.interp(grid, radiances, temps).astype(np.float32)
    slopes = np.append(np.diff(nodes), np.float32(0.0))              # per grid cell; the last: x == hi
    np.log(out, out=out)
    out -= np.float32(log_lo)
    out *= np.float32((BT_GRID_POINTS - 1) / (log_hi - log_lo))
    np.clip(out, np.float32(0.0), np.float32(BT_GRID_POINTS - 1), out=out)
    index = out.astype(np.intp)
    out -= index                                                     # fraction within the cell
    out *= slopes.take(index)
    out += nodes.take(index)
    return out


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
