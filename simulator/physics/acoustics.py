"""Audio on the scenario timeline: source signatures, outdoor propagation and ambient beds.

Everything is pressure in pascals at the microphone (mono, 44.1 kHz by default). Sources are
synthesised on their own clock (emission time) and reach the microphone through
:func:`retarded_time` (propagation delay and Doppler), spherical spreading (1/r re 1 m) and
ISO 9613-1 atmospheric absorption applied as a time-varying STFT-domain gain. Ambient beds (wind,
traffic, rain, birdsong) are synthesised directly at the microphone. All draws come from
``rng_for(seed, "acoustics", ...)`` with one index per source, so adding a source never changes
another one. See docs/AUDIO_RF.md for the models and their parameters.
"""
from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.fft as sfft
from numpy.lib.stride_tricks import sliding_window_view
from pydantic import BaseModel, ConfigDict, Field, model_validator

from scenes.kinds import DRONE_KINDS
from scenes.kinds import DRONE_SIZE_M as _REFERENCE_SIZE_M
from simulator.seeding import rng_for

AUDIO_SAMPLE_RATE_HZ = 44_100
AUDIO_BAND_HZ = 16_000.0          # highest frequency any model synthesises; fs must be >= 2x this
P_REF_PA = 20e-6                  # reference pressure of dB SPL
FULL_SCALE_PA = 1.0               # WAV sample 1.0 == 1 Pa (94 dB SPL)
MIN_RANGE_M = 1.0                 # source levels are quoted at 1 m; closer is clamped
ABSORPTION_FRAME = 2048           # STFT frame (46 ms at 44.1 kHz) for the absorption filter
ABSORPTION_HOP = ABSORPTION_FRAME // 2
_GRID_STEP_S = 1e-3               # emission-time grid used to invert t = tau + r(tau)/c
AMBIENT_SOURCE_INDEX = 1000       # rng index base of ambient beds (targets use 0, 1, ...)
MOTOR_POLE_PAIRS = 7              # 12N14P outrunner: electrical frequency = 7 x shaft rate
N_BLADE_HARMONICS = 10
MAX_BLADE_HARMONICS = 30          # cap of the randomised line count (synthesis cost ~ lines)

# relative source levels at 1 m (dB SPL, unweighted) for the reference size: they fix the tonal /
# broadband balance; the absolute level comes from the sound power (sound_power_dba); docs/AUDIO_RF.md
_TONAL_DB_1M = {"quadcopter": 78.0, "hexacopter": 81.0, "fixed_wing": 80.0}
_BROADBAND_DB_1M = {"quadcopter": 72.0, "hexacopter": 75.0, "fixed_wing": 74.0}
BROADBAND_SHAPE = (300.0, 6000.0, -3.0)   # rotor broadband: band edges (Hz) and tilt (dB/octave)
BPF_MODULATION = 0.3                      # broadband amplitude modulation at the blade-passing frequency


@dataclass(frozen=True)
class RotorNoise:
    """Rotor-noise parameters that physics leaves open. The defaults are the model before issue 24
    (clean coherent lines 6 dB over one stationary broadband); :func:`draw_rotor_noise` randomises them
    over documented ranges (docs/AUDIO_RF.md), which is what :func:`synthesize_target` uses by default."""

    harmonic_decay: float = 0.8             # blade-passing line amplitude ~ k^-decay
    harmonic_top_hz: float | None = None    # lines up to this frequency (None: N_BLADE_HARMONICS lines)
    broadband_offset_db: float | None = None  # broadband minus tonal at 1 m (None: the kind's 78/72 dB table)
    broadband_shape: tuple[float, float, float] = BROADBAND_SHAPE
    bpf_modulation: float = BPF_MODULATION
    imbalance: float = 0.18                 # shaft-rate line, re the first BPF line's amplitude
    motor_lines: tuple[float, float] = (0.25, 0.12)   # lines at 1x and 2x the electrical frequency
    pole_pairs: int = MOTOR_POLE_PAIRS
    pwm_hz: float | None = None             # ESC PWM switching frequency (a steady whine), None = off
    pwm_level: float = 0.0                  # its amplitude re the first BPF line
    amplitude_fluctuation_db: float = 0.0   # slow log-normal level fluctuation (turbulent propagation, manoeuvres)
    amplitude_fluctuation_hz: float = 1.0   # its corner frequency


LEGACY_ROTOR_NOISE = RotorNoise()
# ranges of draw_rotor_noise (uniform unless said): see docs/AUDIO_RF.md "Rotor noise (issue 24)"
ROTOR_NOISE_RANGES = {
    "harmonic_decay": (0.3, 1.2), "harmonic_top_hz": (3000.0, 10000.0), "broadband_offset_db": (10.0, 20.0),
    "broadband_low_hz": (100.0, 400.0), "broadband_high_hz": (15000.0, 20000.0), "broadband_tilt_db": (-4.0, -1.5),
    "bpf_modulation": (0.1, 0.6), "imbalance": (0.02, 0.15), "motor_line": (0.02, 0.15),
    "pwm_hz": (8000.0, 12000.0, 16000.0), "pwm_level": (0.0, 0.08), "amplitude_fluctuation_db": (1.0, 4.0),
    "amplitude_fluctuation_hz": (0.3, 3.0),
}


def merged_ranges(base: dict, overrides: dict | None, field_name: str) -> dict:
    """``base`` ranges with ``overrides`` applied: only (low, high) spans of existing keys can be
    replaced, low <= high; a bad entry raises a ValueError naming ``field_name.key``. The draws keep
    their order, so replacing a span moves only the values drawn from it."""
    if not overrides:
        return base
    out = dict(base)
    for key, span in overrides.items():
        if key not in base or len(base[key]) != 2 or isinstance(base[key][0], int) and isinstance(base[key][1], int):
            spans = sorted(k for k, v in base.items() if len(v) == 2 and not all(isinstance(x, int) for x in v))
            raise ValueError(f"{field_name}.{key}: not a drawn span; expected one of {spans}")
        lo, hi = (float(x) for x in span) if len(span) == 2 else (np.nan, np.nan)
        if not (np.isfinite(lo) and np.isfinite(hi)) or lo > hi:
            raise ValueError(f"{field_name}.{key}: need (low, high) with low <= high, got {tuple(span)}")
        out[key] = (lo, hi)
    return out


def draw_rotor_noise(rng: np.random.Generator, ranges: dict | None = None) -> RotorNoise:
    """Rotor-noise parameters drawn from ``ROTOR_NOISE_RANGES`` (domain randomisation, per drone);
    ``ranges`` replaces some of its spans (:func:`merged_ranges`; same draws in the same order)."""
    r = merged_ranges(ROTOR_NOISE_RANGES, ranges, "rotor_noise")

    def u(name: str) -> float:
        return float(rng.uniform(r[name][0], r[name][1]))

    decay, top, offset = u("harmonic_decay"), u("harmonic_top_hz"), u("broadband_offset_db")
    shape = (u("broadband_low_hz"), u("broadband_high_hz"), u("broadband_tilt_db"))
    bpf_mod, imbalance = u("bpf_modulation"), u("imbalance")
    motor = (u("motor_line"), u("motor_line"))
    pole_pairs = int(rng.choice([6, 7]))
    pwm = float(rng.choice(r["pwm_hz"])) if rng.random() < 0.5 else None
    pwm_level = u("pwm_level")
    fluct_db, fluct_hz = u("amplitude_fluctuation_db"), u("amplitude_fluctuation_hz")
    return RotorNoise(harmonic_decay=decay, harmonic_top_hz=top, broadband_offset_db=offset, broadband_shape=shape,
                      bpf_modulation=bpf_mod, imbalance=imbalance, motor_lines=motor, pole_pairs=pole_pairs,
                      pwm_hz=pwm, pwm_level=pwm_level if pwm else 0.0, amplitude_fluctuation_db=fluct_db,
                      amplitude_fluctuation_hz=fluct_hz)

SPHERE_DB = 10.0 * np.log10(4.0 * np.pi)  # L_p(1 m) = L_W - 10.99 dB in free field (sphere of 1 m^2 x 4 pi)
# mass from overall span (kg): multirotor 0.75 kg at 0.45 m (a C1-class folding quad), fixed wing 1.2 kg at 1.5 m
_MASS_REFERENCE = {"quadcopter": (0.45, 0.75), "hexacopter": (0.45, 0.75), "fixed_wing": (1.5, 1.2)}
# EU 2019/945 Part 15: max L_WA (dB) for C1 and C2 below 900 g, by time since entry into force (0, 2, 4 years);
# C2 from 900 g to 4 kg: limit + 18.5 lg(m / 900 g). None above 4 kg (not in the open-category classes).
EU_LWA_LIMIT_DB = (85.0, 83.0, 81.0)
EU_C2_SLOPE_DB = 18.5
SOUND_POWER_PHASE = 1                     # default level: the 2-year curve 83 + 18.5 lg(m / 0.9 kg)
# directivity about the body's up axis, phi = angle below the rotor plane; power shapes (normalised to a
# unit sphere average): tonal 0.35 + sin^2(2 phi) (lobes ~45 deg off the rotor plane), broadband 1 + 0.5 sin^2 phi
TONAL_DIRECTIVITY = (0.35, 1.0)
BROADBAND_DIRECTIVITY = (1.0, 0.5)
GEOMETRY_STEP = 64                        # samples between evaluations of emission geometry (1.5 ms)
DEFAULT_GROUND_FACTOR = 0.5               # ISO 9613-2 G of a mixed site (grass and hard surfaces)
OCTAVE_BANDS_HZ = (63.0, 125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0, 8000.0)
BIRD_CALL_DB_1M = 80.0
BIRD_WINGBEAT_DB_1M = 55.0
AIRLINER_DB_1M = 140.0


def _check_nonnegative(name: str, values: np.ndarray) -> None:
    values = np.asarray(values)
    if values.size and (not np.all(np.isfinite(values)) or np.min(values) < 0):
        raise ValueError(f"{name} must be finite and >= 0, got min {np.nanmin(values):.6g}")


def check_sample_rate(sample_rate_hz: float, highest_band_hz: float = AUDIO_BAND_HZ) -> None:
    """Reject a sample rate that cannot carry the highest synthesised band (Nyquist)."""
    if not sample_rate_hz >= 2.0 * highest_band_hz:
        raise ValueError(f"sample_rate_hz must be >= 2 x highest band ({2 * highest_band_hz:.0f} Hz), got "
                         f"{sample_rate_hz}")


def db_spl_to_pa(level_db: float) -> float:
    return P_REF_PA * 10.0 ** (level_db / 20.0)


def pa_to_db_spl(rms_pa: np.ndarray | float) -> np.ndarray:
    return 20.0 * np.log10(np.maximum(np.asarray(rms_pa, dtype=np.float64), 1e-12) / P_REF_PA)


# --------------------------------------------------------------------------------------------
# Atmosphere
# --------------------------------------------------------------------------------------------

def speed_of_sound_mps(air_temperature_k: float) -> float:
    """Ideal-gas speed of sound in dry air, 331.3 m/s at 273.15 K."""
    if not air_temperature_k > 0:
        raise ValueError(f"air_temperature_k must be > 0, got {air_temperature_k}")
    return 331.3 * float(np.sqrt(air_temperature_k / 273.15))


def iso9613_absorption_db_per_m(frequency_hz: np.ndarray | float, air_temperature_k: float,
                                relative_humidity: float, pressure_pa: float = 101_325.0) -> np.ndarray:
    """Pure-tone atmospheric absorption coefficient (dB/m), ISO 9613-1:1993 equations (1)-(5).

    ``relative_humidity`` is a fraction (0-1) as in the scenario schema.
    """
    f = np.asarray(frequency_hz, dtype=np.float64)
    _check_nonnegative("frequency_hz", f)
    if not 0.0 <= relative_humidity <= 1.0:
        raise ValueError(f"relative_humidity must be a fraction in [0, 1], got {relative_humidity}")
    if not pressure_pa > 0:
        raise ValueError(f"pressure_pa must be > 0, got {pressure_pa}")
    t = float(air_temperature_k)
    if not t > 0:
        raise ValueError(f"air_temperature_k must be > 0, got {t}")
    pr_kpa, t0, t01 = 101.325, 293.15, 273.16
    pa_rel = (pressure_pa / 1000.0) / pr_kpa
    c_exp = -6.8346 * (t01 / t) ** 1.261 + 4.6151
    h = 100.0 * relative_humidity * 10.0 ** c_exp / pa_rel          # molar concentration of water vapour, %
    fr_o = pa_rel * (24.0 + 4.04e4 * h * (0.02 + h) / (0.391 + h))
    fr_n = pa_rel * (t / t0) ** -0.5 * (9.0 + 280.0 * h * np.exp(-4.170 * ((t / t0) ** (-1.0 / 3.0) - 1.0)))
    return 8.686 * f ** 2 * (
        1.84e-11 / pa_rel * (t / t0) ** 0.5
        + (t / t0) ** -2.5 * (0.01275 * np.exp(-2239.1 / t) / (fr_o + f ** 2 / fr_o)
                              + 0.1068 * np.exp(-3352.0 / t) / (fr_n + f ** 2 / fr_n)))


def a_weighting_db(frequency_hz: np.ndarray | float) -> np.ndarray:
    """IEC 61672-1 A-weighting (dB): 20 lg R_A(f) + 2.00, R_A = 12194^2 f^4 / ((f^2 + 20.6^2)
    sqrt((f^2 + 107.7^2)(f^2 + 737.9^2)) (f^2 + 12194^2))."""
    f2 = np.asarray(frequency_hz, dtype=np.float64) ** 2
    ra = 12194.0 ** 2 * f2 ** 2 / ((f2 + 20.6 ** 2) * np.sqrt((f2 + 107.7 ** 2) * (f2 + 737.9 ** 2))
                                   * (f2 + 12194.0 ** 2))
    return 20.0 * np.log10(np.maximum(ra, 1e-30)) + 2.00


def drone_mass_kg(kind: str, size_m: float) -> float:
    """Take-off mass from overall span, m ~ span^3 (0.75 kg at 0.45 m for multirotors, 1.2 kg at 1.5 m wings)."""
    if kind not in _MASS_REFERENCE:
        raise ValueError(f"kind: no mass model for {kind!r}")
    span, mass = _MASS_REFERENCE[kind]
    return mass * (size_m / span) ** 3


def eu_class(mass_kg: float) -> str:
    """EU 2019/945 open-category class by mass alone: C0 < 250 g, C1 < 900 g, C2 < 4 kg, else 'none'."""
    return "C0" if mass_kg < 0.25 else "C1" if mass_kg < 0.9 else "C2" if mass_kg < 4.0 else "none"


def eu_sound_power_limit_db(mass_kg: float, phase: int = 0) -> float | None:
    """Maximum L_WA of EU 2019/945 Part 15 (C1/C2), ``phase`` 0/1/2 = at entry, +2 years, +4 years.

    85/83/81 dB below 900 g (C1 and C2), + 18.5 lg(m / 900 g) from 900 g to 4 kg; None for C0 (no
    limit) and above 4 kg.
    """
    if phase not in (0, 1, 2):
        raise ValueError(f"phase must be 0, 1 or 2, got {phase}")
    cls = eu_class(mass_kg)
    if cls in ("C0", "none"):
        return None
    base = EU_LWA_LIMIT_DB[phase]
    return base if mass_kg < 0.9 else base + EU_C2_SLOPE_DB * np.log10(mass_kg / 0.9)


def sound_power_dba(kind: str, size_m: float) -> float:
    """Default A-weighted sound power L_WA at hover: 83 + 18.5 lg(m / 0.9 kg) (the EU 2-year limit
    curve extended to all masses), never above the class limit at entry into force."""
    mass = drone_mass_kg(kind, size_m)
    level = EU_LWA_LIMIT_DB[SOUND_POWER_PHASE] + EU_C2_SLOPE_DB * np.log10(mass / 0.9)
    cap = eu_sound_power_limit_db(mass, 0)
    return float(level if cap is None else min(level, cap))


def _directivity_power(sin_below: np.ndarray, shape: tuple[float, float], kind: str) -> np.ndarray:
    """Power directivity (unit sphere average) from sin(angle below the rotor plane)."""
    base, depth = shape
    u2 = np.clip(np.asarray(sin_below, dtype=np.float64) ** 2, 0.0, 1.0)
    if kind == "tonal":                        # base + depth sin^2(2 phi); sphere mean of sin^2(2 phi) = 8/15
        return (base + depth * 4.0 * u2 * (1.0 - u2)) / (base + depth * 8.0 / 15.0)
    return (base + depth * u2) / (base + depth / 3.0)   # sphere mean of sin^2 phi = 1/3


def rotor_directivity(emission_dir: np.ndarray, body_up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Amplitude factors (tonal, broadband) for unit emission directions (N, 3) and body up axes (N, 3)."""
    d = np.asarray(emission_dir, dtype=np.float64)
    d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
    sin_below = -np.sum(d * np.asarray(body_up, dtype=np.float64), axis=-1)
    return (np.sqrt(_directivity_power(sin_below, TONAL_DIRECTIVITY, "tonal")),
            np.sqrt(_directivity_power(sin_below, BROADBAND_DIRECTIVITY, "broadband")))


def iso9613_ground_attenuation_db(source_height_m: np.ndarray | float, receiver_height_m: float,
                                  horizontal_range_m: np.ndarray | float, ground_factor: float) -> np.ndarray:
    """ISO 9613-2:1996 ground attenuation A_gr = A_s + A_r + A_m (dB) per octave band 63 Hz-8 kHz.

    Table 3: source/receiver regions -1.5 (63 Hz), -1.5 + G a'(h) / b'(h) / c'(h) / d'(h) (125 Hz
    -1 kHz), -1.5 (1 - G) (2-8 kHz); middle region -3q (63 Hz), -3q (1 - G) otherwise, q = 0 for
    d_p <= 30 (h_s + h_r) else 1 - 30 (h_s + h_r) / d_p. One G for all three regions. Negative =
    gain (a hard ground adds the reflection: -3 dB). Returns (..., 8).
    """
    if not 0.0 <= ground_factor <= 1.0:
        raise ValueError(f"ground_factor must be in [0, 1], got {ground_factor}")
    hs = np.maximum(np.asarray(source_height_m, dtype=np.float64), 0.0)
    dp = np.maximum(np.asarray(horizontal_range_m, dtype=np.float64), 0.0)
    hs, dp = np.broadcast_arrays(hs, dp)
    hr = max(float(receiver_height_m), 0.0)
    g = float(ground_factor)
    near = 1.0 - np.exp(-dp / 50.0)

    def region(h):
        a = (1.5 + 3.0 * np.exp(-0.12 * (h - 5.0) ** 2) * near + 5.7 * np.exp(-0.09 * h ** 2)
             * (1 - np.exp(-2.8e-6 * dp ** 2)))
        b = 1.5 + 8.6 * np.exp(-0.09 * h ** 2) * near
        c = 1.5 + 14.0 * np.exp(-0.46 * h ** 2) * near
        d = 1.5 + 5.0 * np.exp(-0.9 * h ** 2) * near
        hi = np.full_like(h, -1.5 * (1 - g))
        return np.stack([np.full_like(h, -1.5), -1.5 + g * a, -1.5 + g * b, -1.5 + g * c, -1.5 + g * d, hi, hi, hi], -1)

    q = np.where(dp <= 30.0 * (hs + hr), 0.0, 1.0 - 30.0 * (hs + hr) / np.maximum(dp, 1e-9))
    middle = np.stack([-3.0 * q] + [-3.0 * q * (1 - g)] * 7, -1)
    return region(hs) + region(np.full_like(hs, hr)) + middle


def _octave_interp(freqs_hz: np.ndarray, band_values: np.ndarray) -> np.ndarray:
    """Per-frequency values from octave-band values (..., 8), linear in log f, held beyond the ends."""
    x = np.log2(np.maximum(freqs_hz, 1.0) / 1000.0)
    xp = np.log2(np.asarray(OCTAVE_BANDS_HZ) / 1000.0)
    flat = band_values.reshape(-1, band_values.shape[-1])
    out = np.stack([np.interp(x, xp, row) for row in flat])
    return out.reshape(*band_values.shape[:-1], freqs_hz.size)


# --------------------------------------------------------------------------------------------
# Propagation
# --------------------------------------------------------------------------------------------

@dataclass
class Retarded:
    """Emission time ``tau_s`` of the sound heard at each microphone sample, its rate and range."""

    tau_s: np.ndarray        # (N,) emission time
    dtau_dt: np.ndarray      # (N,) = 1 / (1 + dr/dtau / c): the Doppler factor f_rx / f_src
    range_m: np.ndarray      # (N,) source-microphone distance at emission


def _extrapolated(times_s: np.ndarray, frame_times_s: np.ndarray, values: np.ndarray,
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
    src = _extrapolated(grid, frame_t, pos, vel)
    mic_g = _extrapolated(grid, frame_t, mic, np.zeros_like(mic))
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
    _check_nonnegative("range_m", range_m)
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


# --------------------------------------------------------------------------------------------
# Sources (pressure at 1 m, evaluated on the microphone clock through tau(t))
# --------------------------------------------------------------------------------------------

def _shaped_gain(f_hz: np.ndarray, low_hz: float, high_hz: float, slope_db_per_octave: float = 0.0) -> np.ndarray:
    """Amplitude response of :func:`_shaped_noise`: 2nd-order high-pass, 4th-order low-pass, tilt."""
    f_safe = np.maximum(np.asarray(f_hz, dtype=np.float64), 1e-3)
    hp = (f_safe / low_hz) ** 2 / (1.0 + (f_safe / low_hz) ** 2) if low_hz > 0 else np.ones_like(f_safe)
    lp = 1.0 / (1.0 + (f_safe / high_hz) ** 4)
    tilt = (f_safe / max(low_hz, 1.0)) ** (slope_db_per_octave / 6.0206)
    return hp * lp * np.minimum(tilt, 1e3)


def _shaped_noise(rng: np.random.Generator, n: int, sample_rate_hz: float, low_hz: float, high_hz: float,
                  slope_db_per_octave: float = 0.0) -> np.ndarray:
    """Unit-RMS Gaussian noise band-passed (smooth 2nd-order edges) with an optional spectral tilt."""
    n_fft = sfft.next_fast_len(n, real=True)
    white = rng.standard_normal(n_fft)
    f = np.fft.rfftfreq(n_fft, 1.0 / sample_rate_hz)
    shaped = sfft.irfft(sfft.rfft(white) * _shaped_gain(f, low_hz, high_hz, slope_db_per_octave), n=n_fft)[:n]
    rms = np.sqrt(np.mean(shaped ** 2))
    return shaped / max(rms, 1e-30)


def _smooth_random(rng: np.random.Generator, n: int, sample_rate_hz: float, corner_hz: float) -> np.ndarray:
    """Zero-mean, unit-RMS noise low-passed at corner_hz (slow modulations: gusts, traffic)."""
    step = max(1, int(sample_rate_hz / (20.0 * corner_hz)))
    coarse = _shaped_noise(rng, n // step + 4, sample_rate_hz / step, 0.0, corner_hz)
    return np.interp(np.arange(n) / step, np.arange(coarse.size), coarse)


def _source_noise(rng: np.random.Generator, retarded: Retarded, sample_rate_hz: float, low_hz: float,
                  high_hz: float, slope_db_per_octave: float = 0.0) -> np.ndarray:
    """Shaped noise generated on the emission clock and resampled along tau(t) (Doppler, delay)."""
    t0 = float(retarded.tau_s[0])
    m = int(np.ceil((float(retarded.tau_s[-1]) - t0) * sample_rate_hz)) + 3
    src = _shaped_noise(rng, m, sample_rate_hz, low_hz, high_hz, slope_db_per_octave)
    return np.interp((retarded.tau_s - t0) * sample_rate_hz, np.arange(m), src)


def _harmonic_poly(z: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """Re(sum_p coeffs[..., p] z^p) by Horner's rule (z on the unit circle, complex64)."""
    acc = np.broadcast_to(coeffs[:, -1:], z.shape).astype(np.complex64)
    for p in range(coeffs.shape[1] - 2, -1, -1):
        np.multiply(acc, z, out=acc)
        if np.any(coeffs[:, p]):
            acc += coeffs[:, p:p + 1]
    return acc.real


def rotor_signature(rpm: np.ndarray, n_blades: int, retarded: Retarded, sample_rate_hz: float,
                    rng: np.random.Generator, tonal_db_1m: float, broadband_db_1m: float,
                    hover_rpm: float, *, sound_power_dba: float | None = None,
                    tonal_gain: np.ndarray | None = None, broadband_gain: np.ndarray | None = None,
                    noise: RotorNoise = LEGACY_ROTOR_NOISE) -> np.ndarray:
    """Pressure at 1 m of a set of rotors heard through ``retarded`` (microphone clock).

    ``rpm`` (R, N) is each rotor's speed at the emission time of every microphone sample. Each
    rotor gives blade-passing harmonics k x rpm/60 x n_blades (k = 1..10, amplitude ~ k^-0.8), a
    shaft-rate imbalance line and motor electrical lines at 7 and 14 x the shaft rate; rotors with
    slightly different RPM beat. Broadband turbulence is shaped noise modulated at the BPF.
    Tonal pressure scales with thrust (rpm^2), broadband with rpm^2.5 (acoustic power ~ rpm^4 / rpm^5).

    ``sound_power_dba`` (L_WA at hover) rescales both parts together (keeping their ratio) so the
    A-weighted level at 1 m, averaged over the sphere, is L_WA - 10 log10(4 pi) at ``hover_rpm``;
    ``tonal_gain``/``broadband_gain`` (N,) are the directivity amplitude factors per sample.
    ``noise`` sets what physics leaves open (line count and decay, broadband level and shape, BPF
    modulation, imbalance, motor lines, ESC PWM whine); the default is the pre-issue-24 model.
    """
    rpm = np.atleast_2d(np.asarray(rpm, dtype=np.float64))
    if rpm.size and np.min(rpm) < 0:
        raise ValueError(f"rotor_rpm must be >= 0, got min {np.min(rpm):.6g}")
    if n_blades < 1:
        raise ValueError(f"n_blades must be >= 1, got {n_blades}")
    n_rotors, n = rpm.shape
    shaft_hz_rx = rpm / 60.0 * retarded.dtau_dt[None, :]             # received shaft rate (Doppler)
    phase = 2 * np.pi * np.cumsum(shaft_hz_rx, axis=1) / sample_rate_hz
    phase += rng.uniform(0, 2 * np.pi, size=(n_rotors, 1))
    phase32 = np.mod(phase, 2 * np.pi).astype(np.float32)
    z = np.empty(phase32.shape, dtype=np.complex64)
    z.real = np.cos(phase32)
    z.imag = np.sin(phase32)
    if noise.harmonic_top_hz is None:
        n_harm = N_BLADE_HARMONICS
    else:
        n_harm = int(np.clip(noise.harmonic_top_hz / max(n_blades * hover_rpm / 60.0, 1.0), 1, MAX_BLADE_HARMONICS))
    pp = int(noise.pole_pairs)
    max_power = max(n_blades * n_harm, 2 * pp)
    coeffs = np.zeros((n_rotors, max_power + 1), dtype=np.complex128)
    k = np.arange(1, n_harm + 1)
    blade_amp = k ** -noise.harmonic_decay * 10 ** (rng.normal(0.0, 1.5, size=(n_rotors, k.size)) / 20)
    coeffs[:, n_blades * k] = blade_amp * np.exp(1j * rng.uniform(0, 2 * np.pi, size=(n_rotors, k.size)))
    coeffs[:, 1] += noise.imbalance * np.exp(1j * rng.uniform(0, 2 * np.pi, size=n_rotors))   # imbalance
    coeffs[:, pp] += noise.motor_lines[0] * np.exp(1j * rng.uniform(0, 2 * np.pi, size=n_rotors))
    coeffs[:, 2 * pp] += noise.motor_lines[1] * np.exp(1j * rng.uniform(0, 2 * np.pi, size=n_rotors))
    # rms of sum_p |c_p| cos(.) per rotor = sqrt(sum |c|^2 / 2); scale so all rotors together give tonal_db_1m
    per_rotor_rms = np.sqrt(np.sum(np.abs(coeffs) ** 2, axis=1) / 2)
    pwm_amp = noise.pwm_level / max(float(np.sqrt(np.sum(np.abs(coeffs[0]) ** 2) / 2)), 1e-30)
    coeffs *= db_spl_to_pa(tonal_db_1m) / np.sqrt(n_rotors) / per_rotor_rms[:, None]
    pwm_pa = pwm_amp * db_spl_to_pa(tonal_db_1m) / np.sqrt(n_rotors)
    if noise.broadband_offset_db is not None:
        broadband_db_1m = tonal_db_1m + noise.broadband_offset_db
    broadband_pa = db_spl_to_pa(broadband_db_1m)
    pwm_hz = noise.pwm_hz if noise.pwm_hz is not None else 0.0
    pwm_on = noise.pwm_hz is not None and pwm_pa > 0 and pwm_hz < 0.45 * sample_rate_hz
    if sound_power_dba is not None:
        extra = n_rotors * pwm_pa ** 2 / 2 * 10 ** (float(a_weighting_db(pwm_hz)) / 10) if pwm_on else 0.0
        scale = _sound_power_scale(coeffs, broadband_pa, n_blades, hover_rpm, sound_power_dba,
                                   noise.broadband_shape, noise.bpf_modulation, extra)
        coeffs *= scale
        broadband_pa *= scale
        pwm_pa *= scale
    # only powers of z that lie below Nyquist at the highest shaft rate are kept
    max_shaft_hz = float(np.max(shaft_hz_rx)) if n else 0.0
    if max_shaft_hz > 0:
        keep = np.arange(max_power + 1) * max_shaft_hz < 0.45 * sample_rate_hz
        coeffs[:, ~keep] = 0
    thrust = (rpm / max(hover_rpm, 1e-9)) ** 2
    tonal = np.sum(_harmonic_poly(z, coeffs.astype(np.complex64)) * thrust, axis=0, dtype=np.float64)
    hiss = _source_noise(rng, retarded, sample_rate_hz, *noise.broadband_shape)
    bpf_mod = 1.0 + noise.bpf_modulation * np.real(z[0] ** n_blades)
    broadband = hiss * bpf_mod * np.mean(thrust, axis=0) ** 1.25 * broadband_pa
    if pwm_on:                          # ESC switching whine: fixed frequency, every rotor, random phases
        phases = np.asarray(rng.uniform(0, 2 * np.pi, size=n_rotors))
        tonal = tonal + pwm_pa * np.sum(np.cos(2 * np.pi * pwm_hz * retarded.tau_s[None, :] + phases[:, None]),
                                        axis=0)
    if tonal_gain is not None:
        tonal = tonal * tonal_gain
    if broadband_gain is not None:
        broadband = broadband * broadband_gain
    return tonal + broadband


def _sound_power_scale(coeffs: np.ndarray, broadband_pa: float, n_blades: int, hover_rpm: float,
                       sound_power_dba: float, broadband_shape: tuple[float, float, float] = BROADBAND_SHAPE,
                       bpf_modulation: float = BPF_MODULATION, extra_tonal_ms: float = 0.0) -> float:
    """Amplitude factor that gives A-weighted mean square (L_WA - 10 lg 4 pi at 1 m) at hover.

    Tonal: sum over lines |c_p|^2 / 2 x A(p f_shaft)^2. Broadband: rms^2 x (1 + m^2 / 2) (BPF
    modulation) x the A-weighted share of its spectrum (evaluated on a 1 Hz grid).
    """
    shaft_hz = hover_rpm / 60.0
    powers = np.arange(coeffs.shape[1])
    a_lin = 10 ** (a_weighting_db(np.maximum(powers * shaft_hz, 1e-3)) / 10)
    tonal_ms = float(np.sum(np.abs(coeffs) ** 2 / 2 * a_lin[None, :])) + extra_tonal_ms
    f = np.arange(1.0, AUDIO_BAND_HZ)
    shape = _shaped_gain(f, *broadband_shape) ** 2
    share = float(np.sum(shape * 10 ** (a_weighting_db(f) / 10)) / np.sum(shape))
    broad_ms = broadband_pa ** 2 * (1 + bpf_modulation ** 2 / 2) * share
    target_ms = db_spl_to_pa(sound_power_dba - SPHERE_DB) ** 2
    return float(np.sqrt(target_ms / max(tonal_ms + broad_ms, 1e-300)))


def _chirp_events(rng: np.random.Generator, n: int, sample_rate_hz: float, rate_per_s: float,
                  f_range_hz: tuple[float, float], dur_range_s: tuple[float, float]) -> np.ndarray:
    """Poisson-timed frequency-swept calls with a 2nd harmonic and a Hann envelope (unit peak)."""
    out = np.zeros(n)
    count = rng.poisson(rate_per_s * n / sample_rate_hz)
    starts = rng.integers(0, max(n, 1), size=count)
    durations = rng.uniform(*dur_range_s, size=count)
    f_start = rng.uniform(*f_range_hz, size=count)
    f_end = f_start * rng.uniform(0.7, 1.4, size=count)
    trill_hz = rng.uniform(10.0, 40.0, size=count)
    for s0, dur, fa, fb, tr in zip(starts, durations, f_start, f_end, trill_hz):
        m = int(dur * sample_rate_hz)
        stop = min(n, s0 + m)
        t = np.arange(stop - s0) / sample_rate_hz
        inst = fa + (fb - fa) * t / dur + 0.08 * fa * np.sin(2 * np.pi * tr * t)
        ph = 2 * np.pi * np.cumsum(inst) / sample_rate_hz
        env = np.sin(np.pi * np.arange(stop - s0) / max(m, 1)) ** 2
        out[s0:stop] += env * (np.sin(ph) + 0.3 * np.sin(2 * ph))
    return out


def bird_signature(wingbeat_hz: float, retarded: Retarded, sample_rate_hz: float,
                   rng: np.random.Generator) -> np.ndarray:
    """Pressure at 1 m of a bird: low-frequency wing-beat thumps at wingbeat_hz plus sporadic calls."""
    if not wingbeat_hz > 0:
        raise ValueError(f"wingbeat_hz must be > 0, got {wingbeat_hz}")
    flap = 2 * np.pi * wingbeat_hz * retarded.tau_s
    thump = _source_noise(rng, retarded, sample_rate_hz, 40.0, 400.0) * np.maximum(np.sin(flap), 0.0) ** 4
    thump *= db_spl_to_pa(BIRD_WINGBEAT_DB_1M) / max(float(np.sqrt(np.mean(thump ** 2))), 1e-30)
    t0 = float(retarded.tau_s[0])
    m = int(np.ceil((float(retarded.tau_s[-1]) - t0) * sample_rate_hz)) + 3
    calls_src = _chirp_events(rng, m, sample_rate_hz, 0.8, (2000.0, 5000.0), (0.08, 0.25))
    calls = np.interp((retarded.tau_s - t0) * sample_rate_hz, np.arange(m), calls_src)
    return thump + calls * db_spl_to_pa(BIRD_CALL_DB_1M) * np.sqrt(2)


def airliner_signature(retarded: Retarded, sample_rate_hz: float, rng: np.random.Generator) -> np.ndarray:
    """Pressure at 1 m of a jet airliner: low-frequency broadband jet noise (peak ~100-300 Hz)."""
    jet = _source_noise(rng, retarded, sample_rate_hz, 60.0, 400.0, -2.0)
    return jet * db_spl_to_pa(AIRLINER_DB_1M)


# Helicopter (light turbine helicopter). What is known, and used as such: the main rotor is governed
# (constant rpm), its blade-passing frequency BPF = blades x rpm / 60 is 12-30 Hz for light helicopters
# (2 blades at ~400 rpm: R44, Bell 206; 3 at ~390: AS350; 4 at ~395: EC135, A109, Bell 429); the tail
# rotor is geared to it (4.5-6.5 x the main shaft rate, 2-4 blades: BPF 50-170 Hz); thickness/loading
# noise is a low-frequency pulse train at the BPF, blade slap (blade-vortex interaction) sharp broadband
# pulses at the BPF, and the rotor's broadband self-noise is amplitude-modulated at the BPF ('swish');
# the turboshaft's compressor adds tones at several kHz. A ~300 m flyover is 80-90 dB(A). What is not
# known per helicopter (levels of the parts, pulse widths, modulation depth, turbine tones) is drawn from
# HELICOPTER_RANGES (domain randomisation; the envelope-modulation depth at the BPF, 15-24 dB over the
# modulation floor in every band up to 14 kHz, and the tones at 6-12 kHz were read off the calibration
# half of the Svanström recordings: docs/SIM2REAL_AUDIO.md).
HELICOPTER_DB_1M = 126.0          # overall unweighted level at 1 m of the sum of the parts below
HELICOPTER_MAIN_RPM = (330.0, 420.0)   # governed main-rotor speed when no track gives it
HELICOPTER_RANGES = {"main_blades": (2, 3, 3, 4, 4), "tail_ratio": (4.5, 6.5), "tail_blades": (2, 4),
                     "thump_ms": (2.0, 6.0), "thump_db": (-18.0, -2.0), "slap_ms": (0.15, 0.6),
                     "slap_db": (-22.0, -4.0), "swish_width": (0.08, 0.25), "swish_depth": (0.1, 1.3),
                     "broadband_low_hz": (200.0, 400.0), "broadband_tilt_db": (-8.0, -6.0),
                     "tip_noise_db": (-22.0, -10.0), "tail_db": (-20.0, -10.0),
                     "turbine_tones": (1, 3), "turbine_hz": (6000.0, 12000.0), "turbine_db": (-30.0, -16.0),
                     "turbine_noise_db": (-26.0, -14.0), "tail_peak_harmonic": (1.0, 1.0),
                     "level_fluctuation_db": (0.0, 0.0), "level_fluctuation_hz": (0.3, 1.0),
                     "band_high_hz": (AUDIO_BAND_HZ, AUDIO_BAND_HZ)}


def _periodic_pulses(phase: np.ndarray, width: float, jitter: np.ndarray | None = None) -> np.ndarray:
    """Gaussian pulses (std ``width`` periods) at every integer of ``phase`` (cycles), optionally each
    pass scaled by ``jitter[pass]``."""
    frac = phase - np.floor(phase + 0.5)                     # periods to the nearest pass
    pulses = np.exp(-0.5 * (frac / width) ** 2)
    if jitter is not None:
        passes = np.floor(phase + 0.5).astype(np.int64)
        pulses = pulses * jitter[passes - passes.min()]
    return pulses


def helicopter_signature(retarded: Retarded, sample_rate_hz: float, rng: np.random.Generator, *,
                         main_rpm: np.ndarray | float | None = None, main_blades: int | None = None,
                         ranges: dict | None = None) -> np.ndarray:
    """Pressure at 1 m of a helicopter (emission clock through ``retarded``), parts drawn from
    ``HELICOPTER_RANGES``.

    ``main_rpm`` (scalar or per microphone sample) and ``main_blades`` come from the target's rotor
    (scene schema) when given, else they are drawn (``HELICOPTER_MAIN_RPM``, 2-4 blades). Parts, each
    scaled re the rotor broadband: rotor broadband from 200-400 Hz to the upper edge ``band_high_hz`` (module:
    16 kHz; above it clamped to 0.45 fs) (tilt -8..-6 dB/octave) and blade-tip self-noise 2 kHz to that edge
    (-1 dB/octave, -22..-10 dB), both with an exponential 'swish'
    envelope at the BPF; thickness/loading thump (2-6 ms pulses at the BPF, per-pass
    jitter); blade slap (0.15-0.6 ms pulses); tail-rotor lines k x its BPF (k^-1); turbine: 1-3
    wandering compressor tones at 6-12 kHz and noise from 1 kHz to the same edge. The sum is scaled to HELICOPTER_DB_1M.
    ``ranges`` replaces some (low, high) spans of ``HELICOPTER_RANGES`` (:func:`merged_ranges`).
    """
    r = merged_ranges(HELICOPTER_RANGES, ranges, "helicopter")
    u = lambda name: float(rng.uniform(r[name][0], r[name][1]))  # noqa: E731
    drawn_rpm, drawn_blades = float(rng.uniform(*HELICOPTER_MAIN_RPM)), int(rng.choice(r["main_blades"]))
    blades = drawn_blades if main_blades is None else int(main_blades)   # drawn anyway: later draws stay put
    if blades < 1:
        raise ValueError(f"main_blades must be >= 1, got {blades}")
    rpm = np.broadcast_to(np.asarray(drawn_rpm if main_rpm is None else main_rpm, dtype=np.float64),
                          retarded.tau_s.shape)
    _check_nonnegative("main_rpm", rpm)
    tau = retarded.tau_s - float(retarded.tau_s[0])
    dtau = np.diff(tau, prepend=tau[0])
    shaft_cycles = np.cumsum(rpm / 60.0 * dtau) + rng.uniform()          # main shaft revolutions (emission clock)
    phase = blades * shaft_cycles                                        # blade passes
    tail_phase = u("tail_ratio") * int(rng.choice(r["tail_blades"])) * shaft_cycles
    n_pass = int(np.ceil(phase.max() - phase.min())) + 3
    jitter = 10 ** (rng.normal(0.0, 2.0, size=n_pass) / 20)
    bpf = float(np.median(rpm)) / 60.0 * blades
    thump = _periodic_pulses(phase, u("thump_ms") / 1000.0 * bpf, jitter)
    slap = _periodic_pulses(phase, u("slap_ms") / 1000.0 * bpf, jitter[::-1])
    swish = np.exp(u("swish_depth") * _periodic_pulses(phase, u("swish_width")))
    # upper edge of the broadband parts (rotor, tip, turbine noise): nothing in the sources stops at 16 kHz; the
    # module's span (16, 16) kHz draws nothing and keeps every output; above 16 kHz it is clamped to 0.45 fs
    edge_lo, edge_hi = (float(x) for x in r["band_high_hz"])
    high = edge_lo if edge_lo == edge_hi else float(rng.uniform(edge_lo, edge_hi))
    if high > AUDIO_BAND_HZ:
        high = max(AUDIO_BAND_HZ, min(high, 0.45 * sample_rate_hz))
    broad = _source_noise(rng, retarded, sample_rate_hz, u("broadband_low_hz"), high, u("broadband_tilt_db")) * swish
    tip = _source_noise(rng, retarded, sample_rate_hz, 2000.0, high, -1.0) * swish
    k = np.arange(1, 16)
    tail_phases = rng.uniform(0, 2 * np.pi, size=(k.size, 1))
    turbine = np.zeros(tau.size)
    for _ in range(int(rng.integers(int(r["turbine_tones"][0]), int(r["turbine_tones"][1]) + 1))):
        f_t = u("turbine_hz") * (1 + 0.005 * _smooth_random(rng, tau.size, sample_rate_hz, 0.3))
        turbine += np.cos(2 * np.pi * np.cumsum(f_t) / sample_rate_hz + rng.uniform(0, 2 * np.pi))
    turbine_noise = _source_noise(rng, retarded, sample_rate_hz, 1000.0, high, -2.0)
    levels = [u(name) for name in ("tip_noise_db", "thump_db", "slap_db", "tail_db", "turbine_db", "turbine_noise_db")]
    # tail-rotor lines ~ k^-1 above its strongest harmonic, rising as (k / peak)^2 below it (peak 1: k^-1 from
    # the first line); drawn last, so a span of (1, 1) leaves every other draw and the lines as before
    peak = u("tail_peak_harmonic")
    weights = k ** -1.0 * np.minimum(1.0, k / peak) ** 2
    tail = np.sum(weights[:, None] * np.cos(2 * np.pi * k[:, None] * tail_phase[None, :] + tail_phases), axis=0)
    parts = [(broad, 0.0), (tip, levels[0]), (thump - thump.mean(), levels[1]), (slap - slap.mean(), levels[2]),
             (tail, levels[3]), (turbine, levels[4]), (turbine_noise, levels[5])]
    total = np.zeros(tau.size)
    for x, db in parts:
        total += x / max(float(np.sqrt(np.mean(x ** 2))), 1e-30) * 10 ** (db / 20)
    return total * db_spl_to_pa(HELICOPTER_DB_1M) / max(float(np.sqrt(np.mean(total ** 2))), 1e-30)


def target_source_levels(kind: str, size_m: float) -> tuple[float, float]:
    """(tonal, broadband) unweighted dB SPL at 1 m of a drone kind, +20 log10 of size / reference size.

    Their difference sets the spectral balance; :func:`synthesize_target` rescales both to the
    drone's sound power (:func:`sound_power_dba`)."""
    gain = 20.0 * np.log10(size_m / _REFERENCE_SIZE_M[kind])
    return _TONAL_DB_1M[kind] + gain, _BROADBAND_DB_1M[kind] + gain


def _emission_geometry(track, frame_times_s: np.ndarray, tau_s: np.ndarray, mic_position_m: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-sample source position and body up axis at the emission time, and the microphone position."""
    frame_t = np.asarray(frame_times_s, dtype=np.float64)
    pos = _extrapolated(tau_s, frame_t, np.asarray(track.position_m, dtype=np.float64),
                        np.asarray(track.velocity_mps, dtype=np.float64))
    mic = np.broadcast_to(np.asarray(mic_position_m, dtype=np.float64).reshape(-1, 3), (frame_t.size, 3))
    mic_at = np.stack([np.interp(tau_s, frame_t, mic[:, k]) for k in range(3)], -1)
    rotation = getattr(track, "rotation", None)
    if rotation is None:
        up = np.tile([0.0, 0.0, 1.0], (tau_s.size, 1))
    else:
        frame = np.clip(np.round(np.interp(tau_s, frame_t, np.arange(frame_t.size))).astype(int), 0, frame_t.size - 1)
        up = np.asarray(rotation, dtype=np.float64)[:, :, 2][frame]
    return pos, up, mic_at


def synthesize_target(track, frame_times_s: np.ndarray, mic_position_m: np.ndarray, n_samples: int,
                      sample_rate_hz: float, air_temperature_k: float, relative_humidity: float,
                      rng: np.random.Generator, wingbeat_hz: float = 4.0, *, ground_factor: float | None = None,
                      sound_power_db: float | None = None, directivity: bool = True,
                      rotor_noise: RotorNoise | None = None, rotor_noise_ranges: dict | None = None,
                      helicopter_ranges: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Received pressure (Pa) of one ``TargetTrack`` at the microphone, and its range per sample.

    Drones radiate their hover sound power ``sound_power_db`` (L_WA; default :func:`sound_power_dba`
    of kind and size) with the rotor directivity about the body's up axis; ``ground_factor`` (ISO
    9613-2 G, None = free field) adds the ground effect with heights above z = 0. ``rotor_noise``
    None draws the open rotor-noise parameters from ``rng`` (:func:`draw_rotor_noise`); pass
    ``LEGACY_ROTOR_NOISE`` for the clean pre-issue-24 rotor model; ``rotor_noise_ranges`` and
    ``helicopter_ranges`` replace spans of ``ROTOR_NOISE_RANGES`` / ``HELICOPTER_RANGES`` (None: the
    module's ranges, byte-identical to before they existed). A ``kind`` "helicopter" track
    (built by hand: the scenario schema has no helicopter target yet) uses :func:`helicopter_signature`.
    """
    from simulator.physics.timeline import rotor_hover_rpm

    check_sample_rate(sample_rate_hz)
    if n_samples < 1:
        raise ValueError(f"n_samples must be >= 1, got {n_samples}")
    c = speed_of_sound_mps(air_temperature_k)
    rx_t = np.arange(n_samples) / sample_rate_hz + float(frame_times_s[0])
    ret = retarded_time(rx_t, frame_times_s, track.position_m, track.velocity_mps, mic_position_m, c)
    # geometry changes slowly: evaluate it every GEOMETRY_STEP samples and interpolate
    coarse = np.unique(np.append(np.arange(0, n_samples, GEOMETRY_STEP), n_samples - 1))
    pos_c, up_c, mic_c = _emission_geometry(track, frame_times_s, ret.tau_s[coarse], mic_position_m)
    samples = np.arange(n_samples)
    fluctuation = None
    if track.kind in DRONE_KINDS:
        noise = draw_rotor_noise(rng, rotor_noise_ranges) if rotor_noise is None else rotor_noise
        rpm_frames = np.asarray(track.rotor_rpm, dtype=np.float64)
        _check_nonnegative("rotor_rpm", rpm_frames)
        rpm = np.stack([np.interp(ret.tau_s, frame_times_s, rpm_frames[:, r]) for r in range(rpm_frames.shape[1])])
        tonal_db, broad_db = target_source_levels(track.kind, track.size_m)
        power = sound_power_dba(track.kind, track.size_m) if sound_power_db is None else float(sound_power_db)
        gains = (None, None)
        if directivity:
            gains = tuple(np.interp(samples, coarse, g) for g in rotor_directivity(mic_c - pos_c, up_c))
        hover = getattr(track, "hover_rpm", None) or rotor_hover_rpm(track.kind, track.size_m)
        src = rotor_signature(rpm, max(int(track.n_blades), 1), ret, sample_rate_hz, rng, tonal_db, broad_db,
                              hover, sound_power_dba=power,
                              tonal_gain=gains[0], broadband_gain=gains[1], noise=noise)
        if noise.amplitude_fluctuation_db > 0:
            fluctuation = _level_fluctuation(rng, n_samples, sample_rate_hz, noise.amplitude_fluctuation_db,
                                             noise.amplitude_fluctuation_hz)
    elif track.kind == "bird":
        src = bird_signature(wingbeat_hz, ret, sample_rate_hz, rng)
    elif track.kind == "airliner":
        src = airliner_signature(ret, sample_rate_hz, rng)
    elif track.kind == "helicopter":
        rpm_frames = np.asarray(track.rotor_rpm, dtype=np.float64).reshape(len(frame_times_s), -1)
        main_rpm = np.interp(ret.tau_s, frame_times_s, rpm_frames[:, 0]) if rpm_frames.size else None
        src = helicopter_signature(ret, sample_rate_hz, rng, main_rpm=main_rpm,
                                   main_blades=getattr(track, "n_blades", None) if rpm_frames.size else None,
                                   ranges=helicopter_ranges)
        # turbulent propagation over 50-300 m (and the pilot's collective) make the received level wander; the
        # module's span (0, 0) draws nothing, so every helicopter output stays as it was without it
        spans = merged_ranges(HELICOPTER_RANGES, helicopter_ranges, "helicopter")
        if spans["level_fluctuation_db"][1] > 0:
            std_db = float(rng.uniform(*spans["level_fluctuation_db"]))
            corner_hz = float(rng.uniform(*spans["level_fluctuation_hz"]))
            fluctuation = _level_fluctuation(rng, n_samples, sample_rate_hz, std_db, corner_hz)
    else:
        raise ValueError(f"kind: unknown target kind {track.kind!r}")
    ground = {}
    if ground_factor is not None:
        ground = {"ground_factor": ground_factor, "source_height_m": np.interp(samples, coarse, pos_c[:, 2]),
                  "receiver_height_m": float(np.mean(mic_c[:, 2])),
                  "horizontal_range_m": np.interp(samples, coarse, np.linalg.norm((pos_c - mic_c)[:, :2], axis=-1))}
    received = propagate(src, ret.range_m, sample_rate_hz, air_temperature_k, relative_humidity, **ground)
    if fluctuation is not None:
        received = received * fluctuation
    return received, ret.range_m


def _level_fluctuation(rng: np.random.Generator, n: int, sample_rate_hz: float, std_db: float, corner_hz: float
                       ) -> np.ndarray:
    """Slow log-normal gain (std ``std_db`` of the level, low-passed at ``corner_hz``), unit mean square so the
    sound power stays calibrated: turbulent propagation and manoeuvres make real drone levels wander."""
    g = 10.0 ** (std_db * _smooth_random(rng, n, sample_rate_hz, corner_hz) / 20.0)
    return g / max(float(np.sqrt(np.mean(g ** 2))), 1e-30)


# --------------------------------------------------------------------------------------------
# Ambient beds
# --------------------------------------------------------------------------------------------

class Ambience(BaseModel):
    """Ambient sound beds at the microphone; levels are dB SPL (RMS over the clip), None = off."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    wind_db: float | None = Field(default=45.0, ge=0.0, le=110.0)
    gust_depth: float = Field(default=0.6, ge=0.0, le=1.0, description="0 steady, 1 strongly gusty")
    traffic_db: float | None = Field(default=None, ge=0.0, le=110.0)
    rain_db: float | None = Field(default=None, ge=0.0, le=110.0)
    birdsong_db: float | None = Field(default=None, ge=0.0, le=110.0)
    residual_db: float | None = Field(default=None, ge=0.0, le=110.0, description=(
        "distant mixed outdoor sound (far traffic, industry, people): broadband 50 Hz-10 kHz"))
    rustle_db: float | None = Field(default=None, ge=0.0, le=110.0, description="leaves and grass moved by the wind")
    aircraft_db: float | None = Field(default=None, ge=0.0, le=110.0, description="a distant aircraft passing")


OPTIONAL_BEDS = ("traffic", "rain", "birdsong", "residual", "rustle", "aircraft")
_Span = tuple[float, float]


class AmbienceDistribution(BaseModel):
    """Where each clip's :class:`Ambience` is drawn from (domain randomisation): spans (low, high) of
    dB SPL drawn uniformly, and for every optional bed the probability that it is on. The one home of
    the ambience mix: TRIDENT scene distributions and the sim2real audio clips both draw through
    :func:`draw_ambience`. The defaults are the sim2real fit (levels read off the calibration half of
    the Svanström recordings, docs/SIM2REAL_AUDIO.md); a bed with probability 0 takes no draws."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    wind_db: _Span = (16.0, 34.0)          # 24-42 until 2026-12-03: backgrounds 7-10 dB too loud at 50-160 Hz
    gust_depth: _Span = (0.5, 1.0)
    traffic_probability: float = Field(default=0.4, ge=0.0, le=1.0)
    traffic_db: _Span = (30.0, 46.0)
    rain_probability: float = Field(default=0.15, ge=0.0, le=1.0)
    rain_db: _Span = (32.0, 46.0)
    birdsong_probability: float = Field(default=0.4, ge=0.0, le=1.0)
    birdsong_db: _Span = (22.0, 36.0)
    residual_probability: float = Field(default=1.0, ge=0.0, le=1.0)
    residual_db: _Span = (20.0, 34.0)
    rustle_probability: float = Field(default=0.5, ge=0.0, le=1.0)
    rustle_db: _Span = (18.0, 32.0)
    aircraft_probability: float = Field(default=0.2, ge=0.0, le=1.0)
    aircraft_db: _Span = (35.0, 52.0)

    @model_validator(mode="after")
    def _spans(self) -> AmbienceDistribution:
        for name, value in self.model_dump().items():
            if isinstance(value, tuple) and value[0] > value[1]:
                raise ValueError(f"{name}: low {value[0]} exceeds high {value[1]}")
        return self


def draw_ambience(rng: np.random.Generator, dist: AmbienceDistribution) -> Ambience:
    """One clip's beds from ``dist``: wind level and gust depth, then per optional bed (in OPTIONAL_BEDS
    order) on/off and a level (both drawn whenever its probability is > 0, so the draws do not depend
    on the outcome). Levels rounded to 0.1 dB."""
    amb: dict[str, float | None] = {"wind_db": round(float(rng.uniform(*dist.wind_db)), 1),
                                    "gust_depth": round(float(rng.uniform(*dist.gust_depth)), 2)}
    for bed in OPTIONAL_BEDS:
        p = getattr(dist, f"{bed}_probability")
        if p <= 0:
            continue
        on = rng.random() < p
        level = float(rng.uniform(*getattr(dist, f"{bed}_db")))
        amb[f"{bed}_db"] = round(level, 1) if on else None
    return Ambience.model_validate(amb)


def _scale_to(x: np.ndarray, level_db: float) -> np.ndarray:
    return x * db_spl_to_pa(level_db) / max(float(np.sqrt(np.mean(x ** 2))), 1e-30)


def wind_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float, gust_depth: float, *,
             high_hz: float = 500.0, tilt_db_per_octave: float = -6.0) -> np.ndarray:
    """Wind on the microphone: red-tilted low-frequency noise (15 Hz-``high_hz``, ``tilt_db_per_octave``)
    with slow gust envelope (~0.3 Hz)."""
    base = _shaped_noise(rng, n, sample_rate_hz, 15.0, high_hz, tilt_db_per_octave)
    gust = np.exp(gust_depth * 1.2 * _smooth_random(rng, n, sample_rate_hz, 0.3))
    return _scale_to(base * gust, level_db)


def drifting_broadband_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float,
                           band_hz: tuple[float, float], tilt_db_per_octave: float) -> np.ndarray:
    """A flat, line-free broadband bed (distant road traffic, wind in foliage): noise over ``band_hz`` (the
    top clamped to 0.45 fs) with ``tilt_db_per_octave``, under a slow 3 dB level drift (~0.2 Hz)."""
    base = _shaped_noise(rng, n, sample_rate_hz, band_hz[0], min(band_hz[1], 0.45 * sample_rate_hz), tilt_db_per_octave)
    drift = 10 ** (3.0 * _smooth_random(rng, n, sample_rate_hz, 0.2) / 20)
    return _scale_to(base * drift, level_db)


def calls_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float,
              start_hz: tuple[float, float]) -> np.ndarray:
    """High-frequency calls (insects, small birds): Poisson chirps at 6 per second, 0.05-0.4 s long, starting
    in ``start_hz`` (the top clamped to 0.4 fs), at ``level_db`` dB SPL; zeros when no call falls in the clip."""
    calls = _chirp_events(rng, n, sample_rate_hz, 6.0, (start_hz[0], min(start_hz[1], 0.4 * sample_rate_hz)),
                          (0.05, 0.4))
    return _scale_to(calls, level_db) if np.any(calls) else calls


def traffic_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float) -> np.ndarray:
    """Road traffic at 50-500 m: tyre/road and engine noise 40 Hz-2.5 kHz (the EN 1793-3 normalised
    traffic spectrum peaks near 1 kHz A-weighted, i.e. roughly flat unweighted up to ~1 kHz), with
    vehicles passing (bell-shaped swells)."""
    base = _shaped_noise(rng, n, sample_rate_hz, 40.0, 2500.0, -1.5)
    t = np.arange(n) / sample_rate_hz
    duration = n / sample_rate_hz
    passes = rng.uniform(-2.0, duration + 2.0, size=max(1, rng.poisson(0.5 * duration)))
    widths = rng.uniform(1.5, 4.0, size=passes.size)
    swell = 0.4 + np.sum(np.exp(-0.5 * ((t[None, :] - passes[:, None]) / widths[:, None]) ** 2), axis=0) \
        if passes.size < 64 else np.ones(n)
    return _scale_to(base * swell, level_db)


def rain_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float) -> np.ndarray:
    """Rain: Poisson drop impacts (~1500 /s), each a 1-4 ms decaying high-passed noise burst."""
    from scipy.signal import fftconvolve

    count = rng.poisson(1500.0 * n / sample_rate_hz)
    impulses = np.zeros(n)
    np.add.at(impulses, rng.integers(0, n, size=count), rng.exponential(1.0, size=count))
    k = int(0.004 * sample_rate_hz)
    kernel = _shaped_noise(rng, k, sample_rate_hz, 1500.0, 12000.0) * np.exp(-np.arange(k) / (0.0015 * sample_rate_hz))
    hiss = 0.3 * _shaped_noise(rng, n, sample_rate_hz, 2000.0, 10000.0)
    return _scale_to(fftconvolve(impulses, kernel)[:n] + hiss * np.std(impulses) * np.sqrt(k) * 0.05, level_db)


def birdsong_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float) -> np.ndarray:
    """Background birdsong: several birds' Poisson-timed chirps and trills, 2-7 kHz."""
    calls = _chirp_events(rng, n, sample_rate_hz, 4.0, (2000.0, 7000.0), (0.05, 0.4))
    if not np.any(calls):
        return np.zeros(n)
    return _scale_to(calls, level_db)


def residual_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float) -> np.ndarray:
    """Residual outdoor sound (ISO 1996-2 'residual sound': what remains without specific sources):
    broadband 50 Hz-10 kHz with a drawn tilt of -9..-6 dB/octave and a slow drift (4 dB std, 0.3 Hz)."""
    tilt = float(rng.uniform(-9.0, -6.0))
    base = _shaped_noise(rng, n, sample_rate_hz, 50.0, 10000.0, tilt)
    drift = 10 ** (4.0 * _smooth_random(rng, n, sample_rate_hz, 0.3) / 20)
    return _scale_to(base * drift, level_db)


def rustle_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float) -> np.ndarray:
    """Vegetation moved by the wind: 400 Hz-10 kHz noise, -6..-3 dB/octave, in gust-driven bursts
    (the envelope of low-passed noise at ~0.5 Hz) with fast leaf flutter (~8 Hz)."""
    base = _shaped_noise(rng, n, sample_rate_hz, 400.0, 10000.0, float(rng.uniform(-6.0, -3.0)))
    gust = np.exp(1.2 * _smooth_random(rng, n, sample_rate_hz, 0.5)) ** 1.5
    flutter = 1.0 + 0.4 * _smooth_random(rng, n, sample_rate_hz, 8.0)
    return _scale_to(base * gust * np.abs(flutter), level_db)


def aircraft_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, level_db: float) -> np.ndarray:
    """A distant aircraft: broadband 50 Hz-2 kHz (high frequencies absorbed over kilometres) with a slow
    bell-shaped swell centred somewhere in (or near) the clip."""
    base = _shaped_noise(rng, n, sample_rate_hz, 50.0, float(rng.uniform(800.0, 2500.0)), -2.0)
    t = np.arange(n) / sample_rate_hz
    duration = n / sample_rate_hz
    centre, width = rng.uniform(-0.3, 1.3) * duration, rng.uniform(4.0, 15.0)
    return _scale_to(base * (0.3 + np.exp(-0.5 * ((t - centre) / width) ** 2)), level_db)


# Tonal machinery (issue 24, sixth pass): the Ambience beds above are all broadband, but outdoor
# backgrounds often hold steady tones: mains-powered machinery hums at the mains frequency and its
# harmonics (50 Hz in Europe; transformers radiate mostly at twice it, 100 Hz, from magnetostriction),
# fans and pumps at their blade-passing frequency, idling or cruising engines at their firing frequency
# (4-stroke: rpm / 60 x cylinders / 2, e.g. 4 cylinders at 2000-3000 rpm: 67-100 Hz) and harmonics.
# Not part of Ambience / AmbienceDistribution (whose dumps are hashed into TRIDENT manifests); the
# sim2real audio clips draw it through MachineryDistribution (docs/SIM2REAL_AUDIO.md, sixth pass).
MACHINERY_SOURCE_INDEX = AMBIENT_SOURCE_INDEX + 7   # rng index of the machinery bed (after the other beds)
MAX_MACHINERY_HARMONICS = 8
# the sim2real audio clips' own beds (harness/experiments/sim2real/audio.py), after the machinery bed
MIC_WIND_SOURCE_INDEX = AMBIENT_SOURCE_INDEX + 8    # flow noise on the microphone (seventh pass)
BROADBAND_SOURCE_INDEX = AMBIENT_SOURCE_INDEX + 9   # flat, line-free broadband background bed (ninth pass)
CALLS_SOURCE_INDEX = AMBIENT_SOURCE_INDEX + 10      # high-frequency calls (insects, small birds; ninth pass)
RESONANCE_SOURCE_INDEX = AMBIENT_SOURCE_INDEX + 11  # per-clip spectral resonances (recorder, mount; tenth pass)



def peaking_filter(x: np.ndarray, sample_rate_hz: float, centre_hz: float, gain_db: float, q: float) -> np.ndarray:
    """One resonance: ``x + (10^(gain_db/20) - 1) * bandpass(x)`` with the 2nd-order band-pass of
    ``scipy.signal.iirpeak`` (centre ``centre_hz``, quality factor ``q``: -3 dB bandwidth centre / q).

    iirpeak's band-pass is (1 - A(z)) / 2 with A an all-pass, so the sum is the Regalia-Mitra peaking
    equaliser: exactly ``gain_db`` at the centre (the band-pass there is 1 at zero phase), 0 dB at DC
    and Nyquist, never under 0 dB for a positive gain (no dips beside the peak). Causal (``lfilter``),
    not zero-phase: a resonance of a housing or a mount is causal and minimum-phase, and ``filtfilt``
    would square the band-pass (a narrower peak than ``q`` says) at twice the cost. Pure: float64 out,
    ``x`` untouched."""
    from scipy.signal import iirpeak, lfilter

    x = np.asarray(x, dtype=np.float64)
    if not 0.0 < centre_hz < 0.5 * sample_rate_hz:
        raise ValueError(f"centre_hz: must lie in (0, {0.5 * sample_rate_hz}) Hz, got {centre_hz}")
    if q <= 0:
        raise ValueError(f"q: must be > 0, got {q}")
    b, a = iirpeak(centre_hz, q, fs=sample_rate_hz)
    return x + (10.0 ** (gain_db / 20.0) - 1.0) * lfilter(b, a, x)


def resonances(x: np.ndarray, sample_rate_hz: float, peaks: list[tuple[float, float, float]]) -> np.ndarray:
    """``x`` through one :func:`peaking_filter` per ``(centre_hz, gain_db, q)`` in ``peaks``, then scaled
    back to the RMS of ``x`` (a recorder's gain is not a class cue: only the shape changes). No peaks:
    ``x`` as float64, byte for byte."""
    x = np.asarray(x, dtype=np.float64)
    y = x
    for centre_hz, gain_db, q in peaks:
        y = peaking_filter(y, sample_rate_hz, centre_hz, gain_db, q)
    if not peaks:
        return x
    rms_in, rms_out = np.sqrt(np.mean(x ** 2)), np.sqrt(np.mean(y ** 2))
    return y * (rms_in / rms_out) if rms_out > 0 else y

class Machinery(BaseModel):
    """One clip's tonal machinery bed: harmonics k x ``fundamental_hz`` (k = 1..len(harmonic_db)) at
    ``harmonic_db`` re the strongest, the sum at ``level_db`` dB SPL; the speed wanders slowly
    (relative std ``wander``, ~5 s correlation)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    level_db: float = Field(ge=0.0, le=110.0)
    fundamental_hz: float = Field(gt=0.0, le=2000.0)
    harmonic_db: tuple[float, ...] = Field(min_length=1, max_length=MAX_MACHINERY_HARMONICS)
    wander: float = Field(default=0.0, ge=0.0, le=0.1)


class MachineryDistribution(BaseModel):
    """Where a clip's :class:`Machinery` bed is drawn from: on with ``probability``; then with
    ``mains_probability`` a hum at exactly ``mains_hz`` with ``mains_harmonics`` harmonics and no wander,
    else a machine at a fundamental drawn log-uniformly from ``fundamental_hz`` with ``harmonics``
    harmonics and a drawn ``wander``. Per-harmonic levels: -``harmonic_slope_db`` x log2(k) plus a
    Gaussian of std ``harmonic_spread_db`` (then re the strongest). Spans are (low, high)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    probability: float = Field(default=0.5, ge=0.0, le=1.0)
    level_db: _Span = (20.0, 34.0)
    mains_probability: float = Field(default=0.3, ge=0.0, le=1.0)
    mains_hz: float = Field(default=50.0, gt=0.0)
    mains_harmonics: tuple[int, int] = (4, 8)
    fundamental_hz: _Span = (60.0, 260.0)
    harmonics: tuple[int, int] = (1, 4)
    harmonic_slope_db: float = Field(default=3.0, ge=0.0)
    harmonic_spread_db: float = Field(default=5.0, ge=0.0)
    wander: _Span = (0.0, 0.01)

    @model_validator(mode="after")
    def _spans(self) -> MachineryDistribution:
        for name in ("level_db", "mains_harmonics", "fundamental_hz", "harmonics", "wander"):
            lo, hi = getattr(self, name)
            if lo > hi:
                raise ValueError(f"{name}: low {lo} exceeds high {hi}")
        for name in ("mains_harmonics", "harmonics"):
            lo, hi = getattr(self, name)
            if lo < 1 or hi > MAX_MACHINERY_HARMONICS:
                raise ValueError(f"{name}: need 1 <= low <= high <= {MAX_MACHINERY_HARMONICS}, got {(lo, hi)}")
        if self.fundamental_hz[0] <= 0:
            raise ValueError(f"fundamental_hz: must be > 0, got {self.fundamental_hz[0]}")
        return self


def draw_machinery(rng: np.random.Generator, dist: MachineryDistribution) -> Machinery | None:
    """One clip's machinery bed from ``dist`` (None: off). Nothing is drawn when ``dist.probability`` is 0;
    otherwise always the same number of draws (on/off, kind, level, fundamental, count, wander and
    MAX_MACHINERY_HARMONICS harmonic levels), so the outcome never shifts later draws."""
    if dist.probability <= 0:
        return None
    on, mains = rng.random() < dist.probability, rng.random() < dist.mains_probability
    level = float(rng.uniform(*dist.level_db))
    f0 = float(np.exp(rng.uniform(np.log(dist.fundamental_hz[0]), np.log(dist.fundamental_hz[1]))))
    count = int(rng.integers(*(dist.mains_harmonics if mains else dist.harmonics), endpoint=True))
    wander = float(rng.uniform(*dist.wander))
    k = np.arange(1, MAX_MACHINERY_HARMONICS + 1)
    rel = -dist.harmonic_slope_db * np.log2(k) + rng.normal(0.0, dist.harmonic_spread_db, size=k.size)
    if not on:
        return None
    rel = rel[:count] - rel[:count].max()
    return Machinery(level_db=round(level, 1), fundamental_hz=dist.mains_hz if mains else round(f0, 2),
                     harmonic_db=tuple(round(float(x), 1) for x in rel), wander=0.0 if mains else round(wander, 4))


def machinery_bed(rng: np.random.Generator, n: int, sample_rate_hz: float, machinery: Machinery) -> np.ndarray:
    """The tonal bed of ``machinery`` at the microphone (Pa): harmonics with random phases on one slowly
    wandering speed (low-passed at 0.2 Hz), a slow level drift (1 dB std, 0.3 Hz); harmonics above the
    Nyquist frequency are dropped."""
    check_sample_rate(sample_rate_hz)
    speed = 1.0 + machinery.wander * _smooth_random(rng, n, sample_rate_hz, 0.2)
    cycles = np.cumsum(machinery.fundamental_hz * speed) / sample_rate_hz
    phases = rng.uniform(0.0, 2 * np.pi, size=len(machinery.harmonic_db))
    x = np.zeros(n)
    for k, (db, phi) in enumerate(zip(machinery.harmonic_db, phases), start=1):
        if k * machinery.fundamental_hz * (1.0 + 4.0 * machinery.wander) < 0.5 * sample_rate_hz:
            x += 10 ** (db / 20) * np.cos(2 * np.pi * k * cycles + phi)
    drift = 10 ** (1.0 * _smooth_random(rng, n, sample_rate_hz, 0.3) / 20)
    return _scale_to(x * drift, machinery.level_db)


def synthesize_ambience(ambience: Ambience, n_samples: int, sample_rate_hz: float, seed: int,
                        *indices: int) -> dict[str, np.ndarray]:
    """Each enabled bed (Pa at the microphone), from its own rng stream (seed, acoustics, *indices, 1000+k)."""
    check_sample_rate(sample_rate_hz)
    beds: dict[str, np.ndarray] = {}
    if ambience.wind_db is not None:
        beds["wind"] = wind_bed(rng_for(seed, "acoustics", *indices, AMBIENT_SOURCE_INDEX), n_samples,
                                sample_rate_hz, ambience.wind_db, ambience.gust_depth)
    if ambience.traffic_db is not None:
        beds["traffic"] = traffic_bed(rng_for(seed, "acoustics", *indices, AMBIENT_SOURCE_INDEX + 1), n_samples,
                                      sample_rate_hz, ambience.traffic_db)
    if ambience.rain_db is not None:
        beds["rain"] = rain_bed(rng_for(seed, "acoustics", *indices, AMBIENT_SOURCE_INDEX + 2), n_samples,
                                sample_rate_hz, ambience.rain_db)
    if ambience.birdsong_db is not None:
        beds["birdsong"] = birdsong_bed(rng_for(seed, "acoustics", *indices, AMBIENT_SOURCE_INDEX + 3), n_samples,
                                        sample_rate_hz, ambience.birdsong_db)
    for k, (name, maker) in enumerate((("residual", residual_bed), ("rustle", rustle_bed), ("aircraft", aircraft_bed))):
        level = getattr(ambience, f"{name}_db")
        if level is not None:
            beds[name] = maker(rng_for(seed, "acoustics", *indices, AMBIENT_SOURCE_INDEX + 4 + k), n_samples,
                               sample_rate_hz, level)
    return beds


# --------------------------------------------------------------------------------------------
# Scene-level synthesis and output
# --------------------------------------------------------------------------------------------

@dataclass
class AudioScene:
    """Microphone pressure (Pa) of a scenario: the mix and every component kept separately."""

    sample_rate_hz: float
    mix_pa: np.ndarray                                   # (N,) float32
    targets_pa: dict[str, np.ndarray] = field(default_factory=dict)   # target name -> (N,) float32
    target_range_m: dict[str, np.ndarray] = field(default_factory=dict)
    ambience_pa: dict[str, np.ndarray] = field(default_factory=dict)  # bed name -> (N,) float32
    sound_power_dba: dict[str, float] = field(default_factory=dict)   # drone name -> L_WA at hover used

    @property
    def n_samples(self) -> int:
        return int(self.mix_pa.size)


def synthesize_audio(timeline, seed: int, *, ambience: Ambience | None = None, duration_s: float | None = None,
                     sample_rate_hz: float = AUDIO_SAMPLE_RATE_HZ, stream_indices: tuple[int, ...] = (),
                     ground_factor: float | None = DEFAULT_GROUND_FACTOR,
                     sound_power_db: dict[str, float] | None = None, rotor_noise_ranges: dict | None = None,
                     helicopter_ranges: dict | None = None) -> AudioScene:
    """Audio of every timeline target plus ambient beds at the microphone (the camera rig).

    Target i draws from ``rng_for(seed, "acoustics", *stream_indices, i)``; beds from index 1000+k.
    ``duration_s`` defaults to the timeline span plus one frame. ``ground_factor`` is the ISO 9613-2
    G of the ground (0 hard, 1 porous, None = free field); ``sound_power_db`` overrides the L_WA
    of drones by target name; ``rotor_noise_ranges`` / ``helicopter_ranges`` replace spans of the
    drawn source parameters (:func:`merged_ranges`; None keeps the module's ranges).
    """
    check_sample_rate(sample_rate_hz)
    times = np.asarray(timeline.times_s, dtype=np.float64)
    if duration_s is None:
        step = float(times[1] - times[0]) if times.size > 1 else 1.0 / timeline.scenario.frame_rate_hz
        duration_s = float(times[-1] - times[0]) + step
    if not duration_s > 0:
        raise ValueError(f"duration_s must be > 0, got {duration_s}")
    n = round(duration_s * sample_rate_hz)
    atm = timeline.scenario.atmosphere
    wingbeats = {t.name: t.wingbeat_hz for t in timeline.scenario.targets}
    mic = np.asarray(timeline.microphone_position_m, dtype=np.float64)
    mix = np.zeros(n)
    scene = AudioScene(sample_rate_hz=float(sample_rate_hz), mix_pa=np.zeros(0, np.float32))
    for index, track in enumerate(timeline.targets):
        rng = rng_for(seed, "acoustics", *stream_indices, index)
        power = (sound_power_db or {}).get(track.name)
        received, range_m = synthesize_target(track, times, mic, n, sample_rate_hz, atm.air_temperature_k,
                                              atm.relative_humidity, rng, wingbeats.get(track.name, 4.0),
                                              ground_factor=ground_factor, sound_power_db=power,
                                              rotor_noise_ranges=rotor_noise_ranges,
                                              helicopter_ranges=helicopter_ranges)
        if track.kind in DRONE_KINDS:
            scene.sound_power_dba[track.name] = (power if power is not None
                                                 else sound_power_dba(track.kind, track.size_m))
        mix += received
        scene.targets_pa[track.name] = received.astype(np.float32)
        scene.target_range_m[track.name] = range_m.astype(np.float32)
    for name, bed in synthesize_ambience(ambience or Ambience(), n, sample_rate_hz, seed, *stream_indices).items():
        mix += bed
        scene.ambience_pa[name] = bed.astype(np.float32)
    scene.mix_pa = mix.astype(np.float32)
    return scene


def write_wav(path: str | Path, pressure_pa: np.ndarray, sample_rate_hz: float = AUDIO_SAMPLE_RATE_HZ,
              full_scale_pa: float = FULL_SCALE_PA) -> Path:
    """Mono 32-bit float WAV with sample = pressure / full_scale_pa (1.0 == 1 Pa by default)."""
    import soundfile

    check_sample_rate(sample_rate_hz)
    if not full_scale_pa > 0:
        raise ValueError(f"full_scale_pa must be > 0, got {full_scale_pa}")
    path = Path(path)
    data = (np.asarray(pressure_pa, dtype=np.float64) / full_scale_pa).astype(np.float32)
    buffer = io.BytesIO()
    soundfile.write(buffer, data, int(sample_rate_hz), subtype="FLOAT", format="WAV")
    path.write_bytes(_zero_peak_timestamp(buffer.getvalue()))
    return path


def _zero_peak_timestamp(wav: bytes) -> bytes:
    """libsndfile stamps float WAVs' PEAK chunk with the wall-clock time; zero it for byte-identical files."""
    out = bytearray(wav)
    pos = 12                                              # after 'RIFF' <size> 'WAVE'
    while pos + 8 <= len(out):
        chunk_id, size = bytes(out[pos:pos + 4]), int.from_bytes(out[pos + 4:pos + 8], "little")
        if chunk_id == b"PEAK" and size >= 8:
            out[pos + 12:pos + 16] = b"\0\0\0\0"          # version (4 bytes), then timestamp (4 bytes)
            break
        pos += 8 + size + (size & 1)
    return bytes(out)


def band_level_db(x_pa: np.ndarray, sample_rate_hz: float, low_hz: float, high_hz: float,
                  segment_samples: int) -> np.ndarray:
    """Per-segment band-limited RMS level (dB SPL) from an FFT of each segment (last partial dropped)."""
    x = np.asarray(x_pa, dtype=np.float64)
    n_seg = x.size // segment_samples
    segs = x[: n_seg * segment_samples].reshape(n_seg, segment_samples)
    spec = np.abs(sfft.rfft(segs, axis=-1)) ** 2
    f = np.fft.rfftfreq(segment_samples, 1.0 / sample_rate_hz)
    band = (f >= low_hz) & (f <= high_hz)
    power = 2.0 * np.sum(spec[:, band], axis=-1) / segment_samples ** 2
    return 10.0 * np.log10(np.maximum(power, 1e-30) / P_REF_PA ** 2)
