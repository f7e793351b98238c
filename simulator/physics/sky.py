"""Sky geometry and LWIR sky radiance (numpy only): sun position, cloud cover field, thermal sky.

Directions are unit vectors in the world frame (ENU, +z up). The visible sky colour comes from
Mitsuba's Hosek-Wilkie ``sunsky`` and is built in simulator.render.renderer; everything here is
renderer-free so labels and thermal solves can use the same sky the renderer draws.
"""
from __future__ import annotations

import datetime as dt

import numpy as np

from scenes.schema import Atmosphere, Clouds, Sky, Sun
from simulator.physics import thermal
from simulator.seeding import rng_for

LAPSE_RATE_K_PER_M = 0.0065


def solar_elevation_azimuth_deg(when_utc: dt.datetime, latitude_deg: float, longitude_deg: float) -> tuple[float, float]:
    """Solar elevation and azimuth (clockwise from north), NOAA's low-precision algorithm (~0.1 deg)."""
    if when_utc.tzinfo is not None:
        when_utc = when_utc.astimezone(dt.timezone.utc).replace(tzinfo=None)
    day_of_year = when_utc.timetuple().tm_yday
    hours = when_utc.hour + when_utc.minute / 60 + when_utc.second / 3600
    gamma = 2 * np.pi / 365 * (day_of_year - 1 + (hours - 12) / 24)
    eqtime = 229.18 * (0.000075 + 0.001868 * np.cos(gamma) - 0.032077 * np.sin(gamma)
                       - 0.014615 * np.cos(2 * gamma) - 0.040849 * np.sin(2 * gamma))
    decl = (0.006918 - 0.399912 * np.cos(gamma) + 0.070257 * np.sin(gamma) - 0.006758 * np.cos(2 * gamma)
            + 0.000907 * np.sin(2 * gamma) - 0.002697 * np.cos(3 * gamma) + 0.00148 * np.sin(3 * gamma))
    true_solar_min = hours * 60 + eqtime + 4 * longitude_deg
    hour_angle = np.radians(true_solar_min / 4 - 180)
    lat = np.radians(latitude_deg)
    cos_zenith = np.sin(lat) * np.sin(decl) + np.cos(lat) * np.cos(decl) * np.cos(hour_angle)
    zenith = np.arccos(np.clip(cos_zenith, -1, 1))
    azimuth = np.degrees(np.arctan2(np.sin(hour_angle), np.cos(hour_angle) * np.sin(lat) - np.tan(decl) * np.cos(lat))) + 180
    return float(90 - np.degrees(zenith)), float(azimuth % 360)


def sun_elevation_azimuth_deg(sun: Sun) -> tuple[float, float]:
    if sun.elevation_deg is not None and sun.azimuth_deg is not None:
        return sun.elevation_deg, sun.azimuth_deg
    return solar_elevation_azimuth_deg(sun.datetime_utc, sun.latitude_deg, sun.longitude_deg)


def direction_from_elevation_azimuth(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """Unit vector in ENU for an elevation and a compass azimuth (0 = north = +y, 90 = east = +x)."""
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    return np.array([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)])


def elevation_rad(directions: np.ndarray) -> np.ndarray:
    return np.arcsin(np.clip(directions[..., 2], -1.0, 1.0))


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
        self._density = np.clip((field - threshold) / 1.2, 0.0, 1.0) if clouds.coverage < 1 else np.ones_like(field)
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
    """At-sensor LWIR radiance for any direction: clear sky (elevation-dependent emissivity),
    optional clouds (near-blackbodies at the lapse-rate temperature of their altitude), and the
    ground (at air temperature) below the horizon."""

    def __init__(self, sky: Sky, atmosphere: Atmosphere, seed: int):
        self.atmosphere = atmosphere
        self.eps_zenith = thermal.zenith_emissivity(atmosphere.relative_humidity)
        self.air_radiance = float(thermal.band_radiance(atmosphere.air_temperature_k))
        self.clouds = CloudField(sky.clouds, seed) if sky.clouds is not None and sky.clouds.coverage > 0 else None
        if self.clouds is not None:
            cloud_t = atmosphere.air_temperature_k - LAPSE_RATE_K_PER_M * sky.clouds.altitude_m
            self.cloud_radiance = float(thermal.band_radiance(cloud_t))

    def radiance(self, directions: np.ndarray) -> np.ndarray:
        el = elevation_rad(directions)
        clear = thermal.sky_emissivity(el, self.eps_zenith) * self.air_radiance
        if self.clouds is None:
            return clear
        cover = self.clouds.coverage(directions)
        return (1 - cover) * clear + cover * np.maximum(clear, self.cloud_radiance)

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
