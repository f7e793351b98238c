"""Trajectory kinds -> position as a function of time (metres, seconds). Pure numpy."""
from __future__ import annotations

import math

import numpy as np

from scenes.schema import Flyby, Hover, Orbit, Waypoints

GRAVITY_MPS2 = 9.81


def min_orbit_radius_m(speed_mps: float, max_bank_deg: float) -> float:
    """Smallest radius of a level coordinated turn at ``speed_mps`` whose bank arctan(v^2 / (g r))
    stays within ``max_bank_deg``: v^2 / (g tan(max_bank))."""
    if not 0.0 < max_bank_deg < 90.0:
        raise ValueError(f"max_bank_deg must be in (0, 90), got {max_bank_deg!r}")
    return speed_mps ** 2 / (GRAVITY_MPS2 * math.tan(math.radians(max_bank_deg)))


def _catmull_rom(points: np.ndarray, samples_per_segment: int = 64) -> np.ndarray:
    padded = np.vstack([2 * points[0] - points[1], points, 2 * points[-1] - points[-2]])
    t = np.linspace(0.0, 1.0, samples_per_segment, endpoint=False)[:, None]
    out = []
    for i in range(1, len(padded) - 2):
        p0, p1, p2, p3 = padded[i - 1], padded[i], padded[i + 1], padded[i + 2]
        out.append(0.5 * ((2 * p1) + (-p0 + p2) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t ** 2
                          + (-p0 + 3 * p1 - 3 * p2 + p3) * t ** 3))
    out.append(points[-1][None, :])
    return np.vstack(out)


def _waypoints(traj: Waypoints, times_s: np.ndarray) -> np.ndarray:
    pts = np.asarray(traj.points_m, dtype=np.float64)
    if traj.loop:
        pts = np.vstack([pts, pts[:1]])
    curve = _catmull_rom(pts)
    seg = np.linalg.norm(np.diff(curve, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    dist = traj.speed_mps * times_s
    dist = np.mod(dist, arc[-1]) if traj.loop else np.minimum(dist, arc[-1])
    pos = np.stack([np.interp(dist, arc, curve[:, k]) for k in range(3)], axis=-1)
    before = dist < 0
    if np.any(before):
        tangent = (curve[1] - curve[0]) / max(seg[0], 1e-12)
        pos[before] = curve[0] + dist[before, None] * tangent
    return pos


def _hover(traj: Hover, times_s: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Sum of three incommensurate sinusoids per axis; amplitude drift_m (RMS about drift_m / 2)."""
    periods = traj.drift_period_s * np.array([1.0, 1.618, 2.718])
    phases = rng.uniform(0, 2 * np.pi, size=(3, 3))
    amps = traj.drift_m * np.array([0.5, 0.3, 0.2]) * np.array([[1.0], [1.0], [0.4]])
    offset = np.zeros((times_s.size, 3))
    for axis in range(3):
        for k in range(3):
            offset[:, axis] += amps[axis, k] * np.sin(2 * np.pi * times_s / periods[k] + phases[axis, k])
    return np.asarray(traj.center_m) + offset


def _orbit(traj: Orbit, times_s: np.ndarray) -> np.ndarray:
    sign = -1.0 if traj.clockwise else 1.0
    angle = np.radians(traj.start_angle_deg) + sign * traj.speed_mps / traj.radius_m * times_s
    c = np.asarray(traj.center_m)
    return np.stack([c[0] + traj.radius_m * np.cos(angle), c[1] + traj.radius_m * np.sin(angle),
                     np.full_like(angle, c[2])], axis=-1)


def _flyby(traj: Flyby, times_s: np.ndarray) -> np.ndarray:
    return np.asarray(traj.start_m) + np.outer(times_s, np.asarray(traj.velocity_mps))


def positions_m(traj, times_s: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(T, 3) positions at times_s. ``rng`` is used only by stochastic kinds (hover)."""
    times_s = np.asarray(times_s, dtype=np.float64)
    if isinstance(traj, Waypoints):
        return _waypoints(traj, times_s)
    if isinstance(traj, Hover):
        return _hover(traj, times_s, rng)
    if isinstance(traj, Orbit):
        return _orbit(traj, times_s)
    if isinstance(traj, Flyby):
        return _flyby(traj, times_s)
    raise TypeError(f"unknown trajectory type {type(traj).__name__}")
