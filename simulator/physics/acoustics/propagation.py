"""Outdoor propagation of a source to the microphone: the retarded time t = tau + r(tau)/c (delay and
Doppler), spherical spreading, ISO 9613-1 absorption and the ISO 9613-2 ground effect applied as a
time-varying STFT-domain gain."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft
from numpy.lib.stride_tricks import sliding_window_view

from simulator.physics.acoustics.levels import (
    OCTAVE_BANDS_HZ,
    check_nonnegative,
    check_sample_rate,
    iso9613_absorption_db_per_m,
    iso9613_ground_attenuation_db,
)

MIN_RANGE_M = 1.0                 # source levels are quoted at 1 m; closer is clamped
ABSORPTION_FRAME = 2048           # STFT frame (46 ms at 44.1 kHz) for the absorption filter
ABSORPTION_HOP = ABSORPTION_FRAME // 2
_GRID_STEP_S = 1e-3               # emission-time grid used to invert t = tau + r(tau)/c


@dataclass
class Retarded:
    """Emission time ``tau_s`` of the sound heard at each microphone sample, its rate and range."""

    tau_s: np.ndarray        # (N,) emission time
    dtau_dt: np.ndarray      # (N,) = 1 / (1 + dr/dtau / c): the Doppler factor f_rx / f_src
    range_m: np.ndarray      # (N,) source-microphone distance at emission


def extrapolated(times_s: np.ndarray, frame_times_s: np.ndarray, values: np.ndarray,
                  rates: np.ndarray) -> np.ndarray:
    """Per-axis linear interpolation inside the frame range, linear extrapolation outside it."""
    out = np.stack([np.interp(times_s, frame_times_s, values[:, k]) for k in range(values.shape[1])], -1)
    before, after = times_s < frame_times_s[0], times_s > frame_times_s[-1]
    out[before] = values[0] + (times_s[before] - frame_times_s[0])[:, None] * rates[0]
    out[after] = values[-1] + (times_s[after] - frame_times_s[-1])[:, None] * rates[-1]
    return out


def retarded_time(rx_times_s: np.ndarray, frame_times_s: np.ndarray, source_position_m: np.ndarray,
                  source_velocity_mps: np.ndarray, mic_position_m: np.ndarray,
                  speed_of_sound: float) -> Retarded:
    """Solve t = tau + r(tau)/c for every microphone time t (source positions per frame).

    The source is extrapolated with its first/last velocity outside the frame range (sound heard
    at t = 0 left the source before the first frame). The microphone is taken at its position at
    the emission time (it is static or slow in every scenario).
    """
    rx = np.asarray(rx_times_s, dtype=np.float64)
    frame_t = np.asarray(frame_times_s, dtype=np.float64)
    pos = np.asarray(source_position_m, dtype=np.float64).reshape(-1, 3)
    vel = np.asarray(source_velocity_mps, dtype=np.float64).reshape(-1, 3)
    mic = np.broadcast_to(np.asarray(mic_position_m, dtype=np.float64).reshape(-1, 3), pos.shape)
    if frame_t.size == 1:  # a single frame: static extrapolation with its velocity
        frame_t = np.array([frame_t[0], frame_t[0] + 1.0])
        pos = np.vstack([pos, pos + vel])
        vel = np.vstack([vel, vel])
        mic = np.vstack([mic, mic])
    if not speed_of_sound > 0:
        raise ValueError(f"speed_of_sound must be > 0, got {speed_of_sound}")
    max_speed = float(np.max(np.linalg.norm(vel, axis=-1)))
    if max_speed >= speed_of_sound:
        raise ValueError(f"source_velocity_mps: {max_speed:.1f} m/s is at or above the speed of sound")
    max_delay = float(np.max(np.linalg.norm(pos - mic, axis=-1))) / speed_of_sound
    lo = rx[0] - (max_delay + 1.0) / (1.0 - max_speed / speed_of_sound)
    hi = rx[-1] + 0.1
    grid = np.arange(lo, hi + _GRID_STEP_S, _GRID_STEP_S)
    src = extrapolated(grid, frame_t, pos, vel)
    mic_g = extrapolated(grid, frame_t, mic, np.zeros_like(mic))
    rng_m = np.linalg.norm(src - mic_g, axis=-1)
    arrival = grid + rng_m / speed_of_sound
    if np.any(np.diff(arrival) <= 0):
        raise ValueError("source_velocity_mps: the source approaches at or above the speed of sound")
    if rx[0] < arrival[0] or rx[-1] > arrival[-1]:
        raise ValueError("rx_times_s fall outside the emission grid (source too far away)")
    tau = np.interp(rx, arrival, grid)
    rate = np.gradient(grid, arrival)            # d tau / d t on the grid
    return Retarded(tau_s=tau, dtau_dt=np.interp(rx, arrival, rate), range_m=np.interp(tau, grid, rng_m))


def _absorption_filter(x: np.ndarray, range_m: np.ndarray, sample_rate_hz: float,
                       air_temperature_k: float, relative_humidity: float,
                       ground: tuple[np.ndarray, float, np.ndarray, float] | None = None) -> np.ndarray:
    """Time-varying ISO 9613-1 absorption (and ISO 9613-2 ground effect): per-STFT-frame gain
    10^(-(alpha(f) r + A_gr(f)) / 20).

    ``ground`` = (source height per sample, receiver height, horizontal range per sample, G).
    sqrt-Hann analysis and synthesis windows at 50 % overlap reconstruct exactly with unit gain.
    """
    n = x.size
    frame, hop = ABSORPTION_FRAME, ABSORPTION_HOP
    padded = np.pad(x, (frame, frame + (-n) % hop))
    window = np.sqrt(0.5 - 0.5 * np.cos(2 * np.pi * np.arange(frame) / frame))
    frames = sliding_window_view(padded, frame)[::hop]
    spec = sfft.rfft(frames * window, axis=-1)
    freqs = np.fft.rfftfreq(frame, 1.0 / sample_rate_hz)
    alpha = iso9613_absorption_db_per_m(freqs, air_temperature_k, relative_humidity)
    centre = np.clip(np.arange(frames.shape[0]) * hop + frame // 2 - frame, 0, n - 1)
    loss_db = np.outer(range_m[centre], alpha)
    if ground is not None:
        hs, hr, dp, g = ground
        loss_db += _octave_interp(freqs, iso9613_ground_attenuation_db(hs[centre], hr, dp[centre], g))
    gain = 10.0 ** (-loss_db / 20.0)
    out_frames = sfft.irfft(spec * gain, n=frame, axis=-1) * window
    total = np.zeros(padded.size, dtype=np.float64)
    blocks = total.reshape(-1, hop)
    blocks[: out_frames.shape[0]] += out_frames[:, :hop]
    blocks[1: out_frames.shape[0] + 1] += out_frames[:, hop:]
    return total[frame: frame + n]


def propagate(source_at_1m_pa: np.ndarray, range_m: np.ndarray, sample_rate_hz: float,
              air_temperature_k: float, relative_humidity: float, *, ground_factor: float | None = None,
              source_height_m: np.ndarray | None = None, receiver_height_m: float = 1.5,
              horizontal_range_m: np.ndarray | None = None) -> np.ndarray:
    """Spherical spreading (1/r re 1 m, range clamped to >= 1 m), ISO 9613-1 absorption and, when
    ``ground_factor`` is given, the ISO 9613-2 ground attenuation for the per-sample source height
    and horizontal range (receiver height fixed).

    ``source_at_1m_pa`` is already on the microphone clock (delay and Doppler applied); ``range_m``
    is the per-sample range at emission.
    """
    range_m = np.asarray(range_m, dtype=np.float64)
    check_nonnegative("range_m", range_m)
    check_sample_rate(sample_rate_hz)
    x = np.asarray(source_at_1m_pa, dtype=np.float64)
    r = np.maximum(range_m, MIN_RANGE_M)
    ground = None
    if ground_factor is not None:
        if source_height_m is None or horizontal_range_m is None:
            raise ValueError("ground_factor needs source_height_m and horizontal_range_m per sample")
        hs = np.broadcast_to(np.asarray(source_height_m, dtype=np.float64), r.shape)
        dp = np.broadcast_to(np.asarray(horizontal_range_m, dtype=np.float64), r.shape)
        iso9613_ground_attenuation_db(0.0, receiver_height_m, 0.0, ground_factor)     # validates G
        ground = (hs, float(receiver_height_m), dp, float(ground_factor))
    return _absorption_filter(x / r, r, sample_rate_hz, air_temperature_k, relative_humidity, ground)


def _octave_interp(freqs_hz: np.ndarray, band_values: np.ndarray) -> np.ndarray:
    """Per-frequency values from octave-band values (..., 8), linear in log f, held beyond the ends."""
    x = np.log2(np.maximum(freqs_hz, 1.0) / 1000.0)
    xp = np.log2(np.asarray(OCTAVE_BANDS_HZ) / 1000.0)
    flat = band_values.reshape(-1, band_values.shape[-1])
    out = np.stack([np.interp(x, xp, row) for row in flat])
    return out.reshape(*band_values.shape[:-1], freqs_hz.size)
