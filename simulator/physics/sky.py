"""Sky geometry and LWIR sky radiance (numpy only): sun position (NREL SPA via pvlib), cloud cover field, thermal sky.

Directions are unit vectors in the world frame (ENU, +z up). The visible sky colour comes from
Mitsuba's Hosek-Wilkie ``sunsky`` and is built in simulator.render.renderer; everything here is
renderer-free so labels and thermal solves can use the same sky the renderer draws.
"""
from __future__ import annotations

import datetime as dt

import numpy as np

from scenes.schema import Atmosphere, Clouds, Sky, Sun
from simulator.physics import atmosphere as lwir_atmosphere
from simulator.physics import thermal
from simulator.seeding import rng_for

LAPSE_RATE_K_PER_M = 0.0065


def solar_elevation_azimuth_deg(when_utc: dt.datetime, latitude_deg: float, longitude_deg: float, *,
                                altitude_m: float = 0.0, pressure_pa: float = 101325.0,
                                temperature_c: float = 12.0) -> tuple[float, float]:
    """Apparent (refracted) solar elevation and azimuth (clockwise from north) in degrees, from
    NREL's Solar Position Algorithm (Reda & Andreas 2004, +-0.0003 deg) as implemented by pvlib."""
    import pandas as pd
    from pvlib.solarposition import get_solarposition

    stamp = pd.Timestamp(when_utc)
    stamp = stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")
    pos = get_solarposition(pd.DatetimeIndex([stamp]), latitude_deg, longitude_deg, altitude=altitude_m,
                            pressure=pressure_pa, method="nrel_numpy", temperature=temperature_c)
    return float(pos["apparent_elevation"].iloc[0]), float(pos["azimuth"].iloc[0]) % 360.0


def sun_elevation_azimuth_deg(sun: Sun) -> tuple[float, float]:
    if sun.elevation_deg is not None and sun.azimuth_deg is not None:
        return sun.elevation_deg, sun.azimuth_deg
    if sun.datetime_utc is None or sun.latitude_deg is None or sun.longitude_deg is None:  # the schema sets them
        raise ValueError("sun: give elevation_deg and azimuth_deg, or datetime_utc, latitude_deg and longitude_deg")
    return solar_elevation_azimuth_deg(sun.datetime_utc, sun.latitude_deg, sun.longitude_deg)


def direction_from_elevation_azimuth(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """Unit vector in ENU for an elevation and a compass azimuth (0 = north = +y, 90 = east = +x)."""
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    return np.array([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)])


def elevation_rad(directions: np.ndarray) -> np.ndarray:
    return np.arcsin(np.clip(directions[..., 2], -1.0, 1.0))


#: the cover's rise from 0 to 1 above the coverage threshold, in standard deviations of the fractal field
DEFAULT_EDGE_WIDTH_SD = 1.2


class CloudField:
    """A seeded, periodic fractal cover field on the cloud plane; coverage(dirs) in [0, 1]."""

    _GRID = 512

    def __init__(self, clouds: Clouds, seed: int):
        self.clouds = clouds
        rng = rng_for(seed, "clouds")
        freq = np.fft.fftfreq(self._GRID)
        fx, fy = np.meshgrid(freq, freq)
        radius = np.hypot(fx, fy)
        radius[0, 0] = 1.0
        spectrum = (rng.standard_normal((self._GRID, self._GRID)) + 1j * rng.standard_normal((self._GRID, self._GRID)))
        field = np.real(np.fft.ifft2(spectrum / radius ** 2.2))
        field = (field - field.mean()) / field.std()
        threshold = np.quantile(field, 1.0 - clouds.coverage) if clouds.coverage > 0 else np.inf
        edge = clouds.edge_width_sd if clouds.edge_width_sd is not None else DEFAULT_EDGE_WIDTH_SD
        self._density = np.clip((field - threshold) / edge, 0.0, 1.0) if clouds.coverage < 1 else np.ones_like(field)
        self._period_m = clouds.altitude_m * np.tan(np.radians(clouds.scale_deg)) * 16.0

    def coverage(self, directions: np.ndarray) -> np.ndarray:
        up = directions[..., 2]
        safe_up = np.maximum(up, 1e-3)
        x = directions[..., 0] / safe_up * self.clouds.altitude_m
        y = directions[..., 1] / safe_up * self.clouds.altitude_m
        gx = (x / self._period_m * self._GRID) % self._GRID
        gy = (y / self._period_m * self._GRID) % self._GRID
        i0, j0 = np.floor(gx).astype(int), np.floor(gy).astype(int)
        fx, fy = gx - i0, gy - j0
        i1, j1 = (i0 + 1) % self._GRID, (j0 + 1) % self._GRID
        d = self._density
        val = (d[j0, i0] * (1 - fx) * (1 - fy) + d[j0, i1] * fx * (1 - fy)
               + d[j1, i0] * (1 - fx) * fy + d[j1, i1] * fx * fy)
        fade = np.clip(up / 0.05, 0.0, 1.0)
        return np.where(up > 0, val * fade, 0.0)


class ThermalSky:
    """At-sensor LWIR radiance for any direction: the clear sky of the scene's LOWTRAN7 atmosphere
    (simulator.physics.atmosphere), optional clouds, and the ground (at air temperature) below the horizon.

    A cloud is a blackbody at the lapse-rate temperature of its base altitude, weighted by the
    cover field (its optical thickness proxy, 0-1), seen through the slant path below it:
    L = (1 - c) L_clear + c (tau_base L(T_cloud) + L_path,base).
    """

    def __init__(self, sky: Sky, atmosphere: Atmosphere, seed: int):
        self.atmosphere = atmosphere
        self.lwir = lwir_atmosphere.for_scene(atmosphere)
        self.air_radiance = self.lwir.air_radiance
        clouds = sky.clouds
        self.clouds = CloudField(clouds, seed) if clouds is not None and clouds.coverage > 0 else None
        if self.clouds is not None and clouds is not None:
            self.cloud_altitude_m = clouds.altitude_m
            cloud_t = atmosphere.air_temperature_k - LAPSE_RATE_K_PER_M * clouds.altitude_m
            self.cloud_radiance = float(thermal.band_radiance(cloud_t))

    def clear_radiance(self, directions: np.ndarray) -> np.ndarray:
        return self.lwir.sky_radiance(elevation_rad(directions))

    def cloud_base_radiance(self, elevation: np.ndarray) -> np.ndarray:
        """Radiance of an opaque cloud base seen at these elevations (through the air below it)."""
        sin_el = np.maximum(np.sin(elevation), 1e-3)
        range_m = self.cloud_altitude_m / sin_el
        return (self.lwir.transmission(range_m, elevation) * self.cloud_radiance
                + self.lwir.path_radiance(range_m, elevation))

    def radiance(self, directions: np.ndarray) -> np.ndarray:
        el = elevation_rad(directions)
        clear = self.lwir.sky_radiance(el)
        if self.clouds is None:
            return clear
        cover = self.clouds.coverage(directions)
        flat_el = el.ravel()
        up = flat_el > 0
        base = np.full(flat_el.shape, self.air_radiance)
        base[up] = self.cloud_base_radiance(flat_el[up])
        return (1 - cover) * clear + cover * base.reshape(el.shape)

    def reflected_radiance(self) -> float:
        """Radiance a diffuse surface of random orientation reflects: half the cosine-weighted
        upper hemisphere of sky, half the ground at air temperature (a documented approximation)."""
        n = 64
        elev = (np.arange(n) + 0.5) / n * (np.pi / 2)
        az = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
        el_g, az_g = np.meshgrid(elev, az, indexing="ij")
        dirs = np.stack([np.cos(el_g) * np.sin(az_g), np.cos(el_g) * np.cos(az_g), np.sin(el_g)], -1)
        weights = np.sin(el_g) * np.cos(el_g)
        sky_avg = float(np.sum(self.radiance(dirs) * weights) / np.sum(weights))
        return 0.5 * sky_avg + 0.5 * self.air_radiance
